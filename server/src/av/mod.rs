//! The paper's game-theoretic autonomous vehicle (§IV–V): driving styles (Tables I, III),
//! lane-change costs (eq. 9–14) on predicted motion, Nash and Stackelberg games (eq.
//! 15–18), the potential field (eq. 19–21) and the Delta-u MPC (eq. 22–29, clarabel).
//!
//! A vehicle whose driver is `Driver::Gt` runs [`drive`] every control period. The env
//! asks two questions of any vehicle, learner or not: [`stage_cost`] (eq. 10–14 in its
//! current situation) and [`expert_decision`] (what this AV would decide in its place).
//!
//! One concern per file: `styles` (Table III), `costs` (eq. 9–14), `prediction` (motion
//! over the decision horizon), `games` (eq. 15–18), `field` (eq. 19–21), `mpc` (eq.
//! 22–29), `driver` (reading the world, the follower role, the fallback).
//!
//! ```
//! use arena_server::av::{Game, expert_decision, stage_cost};
//! use arena_server::scenario::builtin;
//!
//! let world = builtin("overtake").unwrap().unwrap().build(0);
//! let ec = world.find("ec_0").unwrap();
//! let decision = expert_decision(&world, ec, Game::Stackelberg);
//! assert!((-1..=1).contains(&decision.sigma));
//! let j = stage_cost(&world, ec).weighted(world.vehicle(ec).style);
//! assert!(j.is_finite() && j >= 0.0);
//! ```

mod costs;
mod driver;
mod field;
mod games;
mod mpc;
mod prediction;
mod styles;

pub use costs::{CostComponents, CostParams};
pub use driver::{
    AvParams, Diagnostics, GtDriver, GtParams, GtStep, Role, drive, expert_decision, plan, plan_motion, situation,
    stage_cost,
};
pub use field::{Field, FieldParams, Line, Obstacle};
pub use games::{
    Adjacent, Decision, DecisionParams, Game, GameParams, LaneOption, PayoffTable, Player, Profile, SideGame, Situation,
};
pub use mpc::{Mpc, MpcError, MpcParams, MpcProblem, MpcSolution, Qp};
pub use prediction::{Kinematics, PredictionParams, SpeedBounds};
pub use styles::{CostWeights, StyleProfile};

#[cfg(test)]
mod tests;
