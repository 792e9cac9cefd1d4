//! What a physics step dt must do well, and the checks that say so (docs/parameters.md,
//! "Physics step"): RK4 must not grow a mode of the closed loop that the model lets decay,
//! and a lane change must settle within bounds. The dynamics tests, the scenario tests
//! (every shipped file's dt) and `examples/physics_step.rs` all take them from here.

use nalgebra::SMatrix;

use super::integrate::VehicleStep;
use super::model::derivative;
use super::params::{DriverParams, Style, VehicleParams};
use super::path::{LANE_CHANGE_DURATION, LateralPath};
use super::state::{Command, STATES, Vector8, VehicleState};

/// Speeds (m/s) at which `rk4_growth` is checked for a physics step: from below the 1 m/s
/// low-speed guard, where the tyres are stiffest (time constant about 18 ms), to the
/// learners' top speed on a 30 m/s lane (36).
pub const RK4_CHECK_SPEEDS: [f64; 14] = [0.5, 0.9, 1.0, 1.1, 1.5, 2.0, 3.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 36.0];

/// The Jacobian of the closed loop of eq. (7)-(8), driver and bicycle, about a car with
/// `driver` cruising straight at `speed` on a straight lane, by central differences of
/// `derivative`: it includes the low-speed guard and the tyre forces' fade below it
/// (which `linearise` leaves out).
pub(super) fn cruising_jacobian(driver: &DriverParams, speed: f64) -> SMatrix<f64, STATES, STATES> {
    let vehicle = VehicleParams::default();
    let x0 = VehicleState::cruising(0.0, 0.0, speed).to_array();
    SMatrix::<f64, STATES, STATES>::from_fn(|i, j| {
        let h = 1e-7 * x0[j].abs().max(1.0);
        let (mut plus, mut minus) = (x0, x0);
        plus[j] += h;
        minus[j] -= h;
        let f = |x: &Vector8| derivative(x, Command::default(), 0.0, &vehicle, driver)[i];
        (f(&plus) - f(&minus)) / (2.0 * h)
    })
}

/// The modes (eigenvalues, 1/s) of the closed loop of eq. (7)-(8), driver and bicycle,
/// about a car of `style` cruising straight at `speed` on a straight lane
/// (`cruising_jacobian`).
pub fn cruising_modes(style: Style, speed: f64) -> Vec<nalgebra::Complex<f64>> {
    cruising_jacobian(&DriverParams::for_style(style), speed).complex_eigenvalues().iter().copied().collect()
}

/// The lateral states of x: v_y, r, heading, d, steer, steer rate (indices into eq. 8's x).
/// About straight cruising at zero acceleration they do not depend on v_x or s, so the
/// closed loop's modes are these six and the two integrators of v_x and s (both 0).
pub const LATERAL_STATES: [usize; 6] = [1, 2, 3, 5, 6, 7];

/// The six lateral modes (eigenvalues, 1/s) of the closed loop about a car with `driver`
/// cruising straight at `speed`: those of `cruising_jacobian`'s `LATERAL_STATES` block
/// (docs/parameters.md, "K_s"; `examples/stability.rs` prints them).
pub fn lateral_modes(driver: &DriverParams, speed: f64) -> Vec<nalgebra::Complex<f64>> {
    let jacobian = cruising_jacobian(driver, speed);
    let lateral = SMatrix::<f64, 6, 6>::from_fn(|i, j| jacobian[(LATERAL_STATES[i], LATERAL_STATES[j])]);
    lateral.complex_eigenvalues().iter().copied().collect()
}

/// How much more one RK4 step of `dt` amplifies the closed loop's modes at `speed` than
/// the exact flow does: the largest |R(lambda dt)| / max(1, |e^(lambda dt)|) over
/// `cruising_modes`, with R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24. Above 1, RK4 makes a
/// mode grow step after step that the model lets decay (RK4 is unstable at this step).
pub fn rk4_growth(style: Style, speed: f64, dt: f64) -> f64 {
    cruising_modes(style, speed)
        .iter()
        .map(|&lambda| {
            let z = lambda * dt;
            let r = 1.0 + z + z * z / 2.0 + z * z * z / 6.0 + z * z * z * z / 24.0;
            r.norm() / z.exp().norm().max(1.0)
        })
        .fold(0.0, f64::max)
}

/// How one lane change settles: the figures docs/parameters.md reports per style.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaneChangeResponse {
    /// Time from the start after which the car stays within `band` of the new lane (s).
    pub settling_time: f64,
    /// Largest excursion beyond the new lane's centre (m).
    pub overshoot: f64,
}

/// The lane change every physics step must carry out well, and the bounds it is held
/// to: the one place the dynamics tests, highway.toml's physics-step test and
/// `examples/physics_step.rs` take them from (docs/parameters.md, "Physics step").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaneChangeBounds {
    /// The lateral move (m): one lane of the shipped roads, 4.
    pub width: f64,
    /// Settled once the car stays within this of the new lane's centre (m): 0.2, chosen.
    pub band: f64,
    /// Simulated time per manoeuvre (s): 15, long enough to see any late swing.
    pub horizon: f64,
    /// The latest a lane change may settle (s): 8, twice the path's 4 s, chosen.
    pub max_settling_time: f64,
    /// Overshoot must stay below this (m): 0.5, chosen (the stepped preview makes 2).
    pub max_overshoot: f64,
    /// The speeds checked (m/s): the 15-30 m/s the K_s schedule was chosen for.
    pub speeds: [f64; 4],
}

/// The bounds the lane-change tests hold every style to.
pub const LANE_CHANGE_BOUNDS: LaneChangeBounds = LaneChangeBounds {
    width: 4.0,
    band: 0.2,
    horizon: 15.0,
    max_settling_time: 8.0,
    max_overshoot: 0.5,
    speeds: [15.0, 20.0, 25.0, 30.0],
};

impl LaneChangeBounds {
    /// A lane change of `style` at `speed` along the `LANE_CHANGE_DURATION` path, to the
    /// left (`left`) or to the right, integrated with physics step `dt`.
    pub fn response(&self, style: Style, speed: f64, left: bool, dt: f64) -> LaneChangeResponse {
        self.response_of(&DriverParams::for_style(style), speed, left, dt)
    }

    /// `response` for any driver (the K_s study of `examples/stability.rs` varies K_s).
    pub fn response_of(&self, driver: &DriverParams, speed: f64, left: bool, dt: f64) -> LaneChangeResponse {
        let width = if left { self.width } else { -self.width };
        let trajectory = lane_change_trajectory_of(driver, speed, width, LANE_CHANGE_DURATION, self.horizon, dt);
        measure(&trajectory, width, self.band, dt)
    }

    /// Whether a response keeps within the bounds.
    pub fn hold(&self, response: &LaneChangeResponse) -> bool {
        response.settling_time <= self.max_settling_time && response.overshoot < self.max_overshoot
    }
}

/// The states after each physics step (`dt`) of a `width` lane change at constant
/// `speed` along a `path_duration` quintic path, for `horizon` seconds: element k is the
/// state at time (k + 1) dt. The preview point is taken at the start of each step and
/// held over it, as `world` does.
pub fn lane_change_trajectory(
    style: Style,
    speed: f64,
    width: f64,
    path_duration: f64,
    horizon: f64,
    dt: f64,
) -> Vec<VehicleState> {
    lane_change_trajectory_of(&DriverParams::for_style(style), speed, width, path_duration, horizon, dt)
}

/// `lane_change_trajectory` for any driver.
pub fn lane_change_trajectory_of(
    driver: &DriverParams,
    speed: f64,
    width: f64,
    path_duration: f64,
    horizon: f64,
    dt: f64,
) -> Vec<VehicleState> {
    let vehicle = VehicleParams::default();
    let path = LateralPath { from: 0.0, to: width, start: 0.0, duration: path_duration };
    let stepper = VehicleStep::new(&vehicle, driver, dt);
    let mut state = VehicleState::cruising(0.0, 0.0, speed);
    let steps = (horizon / dt).round() as usize;
    (0..steps)
        .map(|k| {
            let command = Command { accel: 0.0, preview: path.preview(k as f64 * dt, driver.preview_time) };
            state = stepper.step(&state, command, 0.0);
            state
        })
        .collect()
}

/// Simulates a `width` lane change at constant `speed` along a `path_duration` quintic
/// path for `horizon` seconds (physics step `dt`) and measures how it settles.
pub fn lane_change_response(
    style: Style,
    speed: f64,
    width: f64,
    path_duration: f64,
    band: f64,
    horizon: f64,
    dt: f64,
) -> LaneChangeResponse {
    measure(&lane_change_trajectory(style, speed, width, path_duration, horizon, dt), width, band, dt)
}

/// How a `width` lane change's `trajectory` (states every `dt`) settles to within `band`.
fn measure(trajectory: &[VehicleState], width: f64, band: f64, dt: f64) -> LaneChangeResponse {
    let (mut settling_time, mut overshoot) = (0.0, 0.0f64);
    for (k, state) in trajectory.iter().enumerate() {
        overshoot = overshoot.max((state.d - width) * width.signum());
        if (state.d - width).abs() > band {
            settling_time = (k + 1) as f64 * dt;
        }
    }
    LaneChangeResponse { settling_time, overshoot }
}
