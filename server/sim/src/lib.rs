//! The highway-arena simulation: a multi-lane highway whose vehicles follow the
//! integrated driver + bicycle model of Hang et al. (paper §III), the drivers that steer
//! them (IDM + MOBIL traffic, learners' commands, the paper's game-theoretic AV), and
//! the scenario files that set a world up. No networking here: the env and its Zenoh
//! server (`arena-server`) and the paper harness (`arena-paper`) build on this crate.
//!
//! The modules follow the data, one concern each:
//! `road` -> `dynamics` -> `scene` -> `traffic` / `gt` -> `world` -> `preset` -> `scenario`;
//! `counterfactual` replays worlds (was a collision avoidable, and by whom).
#![warn(missing_docs)]

mod counterfactual;
mod dynamics;
mod gt;
mod preset;
mod road;
mod scenario;
mod scene;
mod traffic;
mod world;

// The surface, by the module that owns each item. What is not here stays inside: the
// games, the field, the MPC's matrices, the integrator, IDM/MOBIL's internals.
pub use counterfactual::{
    Avoidability, Avoided, Crash, HORIZON, LEADS, LearnerCommand, PartyVerdict, REFERENCE_BRAKE, Recorder, Reference,
    Verdict, verdict,
};
pub use dynamics::{
    Command, DriverParams, FULL_PACE_SPEED, LANE_CHANGE_DURATION, LateralPath, MAX_STATE_MAGNITUDE, Style,
    VehicleParams, VehicleState,
};
pub use gt::{
    AdjacentLateral, CostComponents, CostParams, CostWeights, Decision, DecisionParams, Diagnostics, Explanation,
    FieldParams, Game, GameExplained, GameParams, GtMemory, GtParams, GtSetup, GtStep, InteractionParams, JerkParams,
    Kinematics, MergeParams, MpcParams, PredictionParams, SafetyOverride, SafetyParams, SideExplained, StyleProfile,
    expert_decision, explain, plan, stage_cost,
};
pub use preset::{BUILTIN_PRESETS, Preset, PresetError};
pub use road::{LaneChange, LaneId, NearbySections, Pose, Road, Section};
pub use scenario::{
    ActionKind, BUILTIN_SCENARIOS, DriverSpec, EPISODE_DRAWS, Goal, GtTraffic, MAX_CONTROL_PERIODS_PER_STEP,
    MAX_GT_CARS, MAX_GT_DECISIONS_PER_STEP, MAX_LEARNERS, MAX_PHYSICS_TICKS_PER_STEP, MAX_ROAD_EXTENT,
    MAX_ROAD_SECTIONS, MAX_SCENARIO_DEPTH, MAX_SPEED, MAX_VARY_KEYS, MAX_VEHICLES, RewardSpec, Scenario, ScenarioError,
    ScenarioErrorKind, TrafficSpec, VARY_DRAW_BUDGET_BYTES, Variation, VehicleSpec, builtin_scenario,
};
pub use scene::{Car, DriverKind, Lead, Role, Scene, Status, VehicleId};
pub use traffic::{IdmParams, speed_control};
pub use world::{
    AgentCommand, AtFault, BLAME_BRAKE, BLAME_RESPONSE_TIME, CUT_IN_WINDOW, Collision, DRIFT_SPEED, Driver,
    ESTABLISH_TIME, Ending, EntryGap, Forced, LEARNER_SPEED_FACTOR, LaneEntry, Occupancy, RngState, STANDSTILL_SPEED,
    StateError, Stepper, Vehicle, VehicleSetup, World, WorldParams, WorldState, beside_decisions, rng_position,
};

/// The model and the AV's planner taken apart, for the examples and benches that reproduce
/// the figures of docs/parameters.md, docs/design.md and docs/performance.md: the
/// linearised model's modes and RK4's growth over a step (eq. 1-8, 23), a lane change's
/// response and its bounds, jerk figures, and the MPC of eq. (18)-(22) on its own. No
/// layer above the simulation drives a world with them; they are the crate's surface so
/// that those figures come from the code the world runs.
pub mod analysis {
    pub use crate::dynamics::{
        JerkSummary, LANE_CHANGE_BOUNDS, LaneChangeBounds, LaneChangeResponse, RK4_CHECK_SPEEDS, commanded_jerk,
        cruising_modes, lane_change_response, lane_change_trajectory, lateral_modes, longitudinal_jerk, rk4_growth,
    };
    pub use crate::gt::{Mpc, MpcError, MpcSolution, plan_motion};
}
