//! The paper's integrated driver + bicycle model, eq. (1)–(8): its parameters (Tables I
//! and II), the state derivative, fixed-step RK4 integration, and the linearisation and
//! exact discretisation of eq. (22)–(24) that the MPC plans with.
//!
//! Vehicles move in the road's Frenet frame: `s` along the reference line, `d` to its
//! left, `heading` relative to the tangent. On a straight road (curvature 0) this is
//! exactly eq. (6) with X = s, Y = d; on an arc the kinematics gain the usual
//! `1 / (1 - curvature * d)` factor, so the driver of eq. (1) previews the lane, not the
//! global Y axis (docs/design.md, "Frenet frame").
//!
//! One concern a file: `params` (Tables I and II), `state` (x and u of eq. 7-8), `model`
//! (f(x, u), eq. 1-8, written once over `lanes::Lanes`), `integrate` (RK4 and `VehicleStep`),
//! `fleet` (many vehicles a block at a time, the same bits), `linear` (eq. 22-24 for the
//! MPC), `path` (the quintic lateral path drivers preview), `physics_step` (what a
//! physics step must do well: settle a lane change, keep RK4 stable), and `jerk` (the
//! change of the longitudinal acceleration, as smoothness is measured).

mod fleet;
mod integrate;
mod jerk;
mod lanes;
mod linear;
mod model;
mod params;
mod path;
mod physics_step;
mod state;

pub use fleet::Fleet;
pub use integrate::VehicleStep;
#[cfg(test)]
pub(crate) use integrate::{rk4, step};
pub use jerk::{JerkSummary, commanded_jerk, longitudinal_jerk};
pub(crate) use lanes::{Lanes, mask};
pub use linear::linearise;
#[cfg(test)]
use model::{derivative, fixed_steer_derivative};
pub use params::{DriverParams, Style, VehicleParams};
pub use path::{FULL_PACE_SPEED, LANE_CHANGE_DURATION, LateralPath};
#[cfg(test)]
use physics_step::LATERAL_STATES;
pub use physics_step::{
    LANE_CHANGE_BOUNDS, LaneChangeBounds, LaneChangeResponse, RK4_CHECK_SPEEDS, cruising_modes, lane_change_response,
    lane_change_trajectory, lateral_modes, rk4_growth,
};
#[cfg(test)]
use state::INPUTS;
pub use state::{Command, MAX_STATE_MAGNITUDE, STATES, VehicleState, within_state};

#[cfg(test)]
mod tests;
