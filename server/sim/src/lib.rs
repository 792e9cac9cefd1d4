//! The highway-arena simulation: a multi-lane highway whose vehicles follow the
//! integrated driver + bicycle model of Hang et al. (paper §III), the drivers that steer
//! them (IDM + MOBIL traffic, learners' commands, the paper's game-theoretic AV), and
//! the scenario files that set a world up. No networking here: the env and its Zenoh
//! server (`arena-server`) and the paper harness (`arena-paper`) build on this crate.
//!
//! The modules follow the data, one concern each:
//! `road` -> `dynamics` -> `scene` -> `traffic` / `gt` -> `world` -> `preset` -> `scenario`.
#![warn(missing_docs)]

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
pub use dynamics::{
    Command, DriverParams, JerkSummary, LANE_CHANGE_BOUNDS, LANE_CHANGE_DURATION, LaneChangeBounds, LaneChangeResponse,
    LateralPath, MAX_STATE_MAGNITUDE, RK4_CHECK_SPEEDS, Style, VehicleParams, VehicleState, commanded_jerk,
    cruising_modes, lane_change_response, lane_change_trajectory, lateral_modes, longitudinal_jerk, rk4_growth,
};
pub use gt::{
    AdjacentLateral, CostComponents, CostParams, CostWeights, Decision, DecisionParams, Diagnostics, Explanation,
    FieldParams, Game, GameExplained, GameParams, GtDriver, GtParams, GtStep, InteractionParams, JerkParams,
    Kinematics, MergeParams, Mpc, MpcError, MpcParams, MpcSolution, PredictionParams, SafetyOverride, SafetyParams,
    SideExplained, StyleProfile, expert_decision, explain, plan, plan_motion, stage_cost,
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
    AgentCommand, AtFault, CUT_IN_WINDOW, Collision, DRIFT_SPEED, Driver, Ending, LEARNER_SPEED_FACTOR, LaneEntry,
    RngState, StateError, Vehicle, World, WorldParams, WorldState, beside_decisions,
};
