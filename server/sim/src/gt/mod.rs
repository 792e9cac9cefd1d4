//! The paper's game-theoretic autonomous vehicle (§IV–V): driving styles (Tables I, III),
//! lane-change costs (eq. 9–14) on predicted motion, Nash and Stackelberg games (eq.
//! 15–18), the potential field (eq. 19–21) and the Delta-u MPC (eq. 22–29, clarabel).
//!
//! A vehicle whose driver is `Driver::Gt` runs [`plan`] every control period: it reads
//! the world's `Scene` and returns a `GtStep` that the world applies. The env asks two
//! questions of any vehicle, learner or not: [`stage_cost`] (eq. 10–14 in its current
//! situation) and [`expert_decision`] (what this AV would decide in its place), each with
//! the vehicle's own constants (`World::gt_params`).
//!
//! One concern per file: `styles` (Table III), `costs` (eq. 9–14), `prediction` (motion
//! over the decision horizon), `games` (eq. 15–18), `field` (eq. 19–21), `mpc` (eq.
//! 22–29), `merge` (lane changes out of an ending lane that complete), `safety` (the
//! override of the games' acceleration that keeps a safe distance), `jerk` (the jerk
//! bound: accelerations reached along a ramp), `driver` (reading the scene, the follower
//! role, the command, the fallback).
//!
//! ```
//! use arena_sim::{Game, expert_decision, stage_cost};
//! use arena_sim::builtin_scenario;
//!
//! let mut world = builtin_scenario("overtake").unwrap().unwrap().build(0);
//! let ec = world.find("ec_0").unwrap();
//! let params = world.gt_params(ec);
//! let decision = expert_decision(world.scene(), ec, Game::Stackelberg, &params);
//! assert!(decision.accel.is_finite());
//! let j = stage_cost(world.scene(), ec, &params).weighted(world.style(ec));
//! assert!(j.is_finite() && j >= 0.0);
//! ```

mod costs;
mod driver;
mod field;
mod games;
mod jerk;
mod merge;
mod mpc;
mod prediction;
mod safety;
mod styles;

// The surface: the driver, its constants, what it decides and reports, and the two
// questions the env asks. The games, the field and the MPC stay inside.
pub use costs::{CostComponents, CostParams};
pub use driver::{
    Diagnostics, Explanation, GtMemory, GtParams, GtSetup, GtStep, InteractionParams, expert_decision, explain, plan,
    plan_motion, stage_cost,
};
pub use field::FieldParams;
#[cfg(test)]
use games::Needs;
pub use games::{AdjacentLateral, Decision, DecisionParams, Game, GameExplained, GameParams, SideExplained};
pub use jerk::JerkParams;
pub use merge::MergeParams;
pub use mpc::{Mpc, MpcError, MpcParams, MpcSolution};
pub use prediction::{Kinematics, PredictionParams};
pub use safety::{SafetyOverride, SafetyParams};
pub use styles::{CostWeights, StyleProfile};

/// The bracket [low, high] around where `holds` turns false, from `low` (where it holds)
/// and `high` (where it does not), after 40 halvings: the searches of `merge` and
/// `safety` for the last value that still fits.
fn bisect(mut low: f64, mut high: f64, holds: impl Fn(f64) -> bool) -> (f64, f64) {
    for _ in 0..40 {
        let mid = 0.5 * (low + high);
        if holds(mid) { low = mid } else { high = mid }
    }
    (low, high)
}

#[cfg(test)]
mod tests;
