//! The state x and input u of eq. (7)-(8): as named fields (`VehicleState`, `Command`),
//! as the vector x the equations index, and as `StateLanes`, one `Lanes` per state, the
//! form the model and RK4 compute on for one vehicle or a block of them.

use serde::{Deserialize, Serialize};

use super::lanes::{self, Lanes};
use super::model::{Model, body_derivative, lateral_forces, longitudinal_derivative};
use super::params::{DriverParams, VehicleParams};

/// The largest size of any number of a restored state: a position, speed, angle, command
/// or time. Finite is not enough (a speed of 1e180 turns the dynamics to NaN within one
/// step); within it the dynamics stay finite over a step (fuzzed, server/tests/fuzz.rs),
/// and every state a world can step into lies far inside it (roads reach 1e6 m, speeds
/// 100 m/s, episodes 2^20 periods).
pub const MAX_STATE_MAGNITUDE: f64 = 1e9;

/// Whether `value` may be a number of a restored state (`MAX_STATE_MAGNITUDE`).
pub fn within_state(value: f64) -> bool {
    value.is_finite() && value.abs() <= MAX_STATE_MAGNITUDE
}

/// Number of states: [vx, vy, r, heading, s, d, steer, steer_rate] (eq. 8's x).
pub const STATES: usize = 8;
/// Number of inputs: [a_x, Y_p].
pub const INPUTS: usize = 2;

/// The 8 states of eq. (8), in the Frenet frame of the road.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct VehicleState {
    /// v_x, longitudinal speed in the body frame (m/s).
    pub vx: f64,
    /// v_y, lateral speed in the body frame (m/s).
    pub vy: f64,
    /// r, yaw rate (rad/s).
    pub yaw_rate: f64,
    /// phi, heading relative to the lane tangent (rad).
    pub heading: f64,
    /// s, distance along the reference line (m) (X of eq. 6 on a straight road).
    pub s: f64,
    /// d, offset left of the reference line (m) (Y of eq. 6 on a straight road).
    pub d: f64,
    /// delta_f, front wheel steering angle (rad).
    pub steer: f64,
    /// d(delta_f)/dt (rad/s).
    pub steer_rate: f64,
}

/// The inputs u of eq. (7): longitudinal acceleration and the preview point.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Command {
    /// a_x (m/s^2), eq. (3).
    pub accel: f64,
    /// Y_p, the lateral offset of the preview point (m), eq. (1).
    pub preview: f64,
}

pub(super) type Vector8 = [f64; STATES];

impl VehicleState {
    /// A car driving straight along its lane at `speed`.
    pub fn cruising(s: f64, d: f64, speed: f64) -> VehicleState {
        VehicleState { vx: speed, s, d, ..VehicleState::default() }
    }

    /// As the state vector x of eq. (8).
    pub fn to_array(&self) -> Vector8 {
        [self.vx, self.vy, self.yaw_rate, self.heading, self.s, self.d, self.steer, self.steer_rate]
    }

    /// From the state vector x of eq. (8).
    pub fn from_array(x: Vector8) -> VehicleState {
        let [vx, vy, yaw_rate, heading, s, d, steer, steer_rate] = x;
        VehicleState { vx, vy, yaw_rate, heading, s, d, steer, steer_rate }
    }

    /// Speed along the lane (m/s): the s-rate ignoring curvature.
    pub fn lane_speed(&self) -> f64 {
        // The world step's sin/cos: IDM reads this for every car it looks at, and libm's
        // was a tenth of a decision's time.
        let (sin, cos) = lanes::sin_cos(Lanes([self.heading]));
        self.vx * cos.0[0] - self.vy * sin.0[0]
    }

    /// Longitudinal acceleration in the body frame (m/s^2) under the applied acceleration
    /// `accel`: v_x' of eq. (2), v_y r + a_x (0 for a standing car it would roll back). A
    /// step of the command shows here whole, within one physics step.
    pub fn longitudinal_accel(&self, accel: f64) -> f64 {
        let lane = |value: f64| Lanes([value]);
        longitudinal_derivative(lane(self.vx), lane(self.vy), lane(self.yaw_rate), lane(accel)).0[0]
    }

    /// Lateral acceleration in the body frame (m/s^2): v_y' + v_x r.
    pub fn lateral_accel(&self, vehicle: &VehicleParams) -> f64 {
        let x = lanes_of(&self.to_array());
        let model = Model::new(vehicle, &DriverParams::default());
        let (front, rear, _) = lateral_forces(&x, &model);
        let (_, cos_steer) = lanes::sin_cos(x[6]);
        let dx = body_derivative(&x, (front, rear), cos_steer, Lanes([0.0]), &model);
        dx[1].0[0] + self.vx * self.yaw_rate
    }
}

/// The 8 states of eq. (8) for N vehicles: one `Lanes` per state.
pub(super) type StateLanes<const N: usize> = [Lanes<N>; STATES];

pub(super) fn lanes_of(x: &Vector8) -> StateLanes<1> {
    x.map(|value| Lanes([value]))
}

pub(super) fn array_of(x: &StateLanes<1>) -> Vector8 {
    x.map(|lane| lane.0[0])
}
