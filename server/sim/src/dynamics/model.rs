//! f(x, u) of eq. (1)-(8): the tyre forces (eq. 4-5), the body (eq. 2-3), its pose in
//! the lane's Frenet frame (eq. 6) and the preview driver (eq. 1), written once over
//! `Lanes<N>` so one vehicle and a block of them compute the same bits. The constants
//! are prepared once per driver (`Model`), as f runs four times per RK4 step.

use super::lanes::{self, Lanes};
use super::params::{DriverParams, VehicleParams, steering_schedule};
use super::state::{Command, StateLanes, Vector8, array_of, lanes_of};

/// The constants of f for N vehicles and their drivers, with reciprocals taken once:
/// f is evaluated four times per RK4 step, and divisions were most of its cost.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct Model<const N: usize> {
    front_axle: Lanes<N>,
    rear_axle: Lanes<N>,
    front_stiffness: Lanes<N>,
    rear_stiffness: Lanes<N>,
    inv_mass: Lanes<N>,
    inv_inertia: Lanes<N>,
    guard: Lanes<N>,
    inv_guard: Lanes<N>,
    /// The steering lock, which `integrate::step_lanes` holds the wheels to.
    pub(super) max_steer: Lanes<N>,
    preview_time: Lanes<N>,
    /// 1 / (a T_d) and 1 / (a T_d^2) of eq. (1).
    rate_gain: Lanes<N>,
    angle_gain: Lanes<N>,
    /// K_0 v_ref^(3/2) G_s / (a T_d^2): eq. (1)'s preview gain times v_x^(3/2), as K_s = K_0 (v_ref / v_x)^(3/2).
    preview_gain: Lanes<N>,
    /// 1 / v_ref, below which speed the schedule falls as 1 / v_x (`steering_schedule`).
    inv_reference_speed: Lanes<N>,
}

impl Model<1> {
    pub(super) fn new(vehicle: &VehicleParams, driver: &DriverParams) -> Model<1> {
        let DriverParams { delay, preview_time, steering_gain, damping, .. } = *driver;
        let lane = |value: f64| Lanes([value]);
        Model {
            front_axle: lane(vehicle.front_axle),
            rear_axle: lane(vehicle.rear_axle),
            front_stiffness: lane(vehicle.front_stiffness),
            rear_stiffness: lane(vehicle.rear_stiffness),
            inv_mass: lane(1.0 / vehicle.mass),
            inv_inertia: lane(1.0 / vehicle.yaw_inertia),
            guard: lane(vehicle.low_speed_guard),
            inv_guard: lane(1.0 / vehicle.low_speed_guard),
            max_steer: lane(vehicle.max_steer),
            preview_time: lane(preview_time),
            rate_gain: lane(1.0 / (damping * delay)),
            angle_gain: lane(1.0 / (damping * delay * delay)),
            preview_gain: lane(driver.steering_ratio_scale() * steering_gain / (damping * delay * delay)),
            inv_reference_speed: lane(1.0 / driver.reference_speed),
        }
    }
}

impl<const N: usize> Model<N> {
    fn fields_mut(&mut self) -> [&mut Lanes<N>; 14] {
        [
            &mut self.front_axle,
            &mut self.rear_axle,
            &mut self.front_stiffness,
            &mut self.rear_stiffness,
            &mut self.inv_mass,
            &mut self.inv_inertia,
            &mut self.guard,
            &mut self.inv_guard,
            &mut self.max_steer,
            &mut self.preview_time,
            &mut self.rate_gain,
            &mut self.angle_gain,
            &mut self.preview_gain,
            &mut self.inv_reference_speed,
        ]
    }

    /// Every lane holds the constants of `one`.
    pub(super) fn splat(one: &Model<1>) -> Model<N> {
        let mut model = Model::default();
        let mut one = *one;
        for (field, value) in model.fields_mut().into_iter().zip(one.fields_mut()) {
            *field = Lanes::splat(value.0[0]);
        }
        model
    }

    /// Lanes `from..from + N` of a model of more vehicles.
    #[inline(always)]
    pub(super) fn part<const WIDE: usize>(wide: &Model<WIDE>, from: usize) -> Model<N> {
        let mut model = Model::default();
        let mut wide = *wide;
        for (field, value) in model.fields_mut().into_iter().zip(wide.fields_mut()) {
            *field = Lanes::part(value, from);
        }
        model
    }

    /// Lane `lane` takes the constants of `one`.
    pub(super) fn set_lane(&mut self, lane: usize, one: &Model<1>) {
        let mut one = *one;
        for (field, value) in self.fields_mut().into_iter().zip(one.fields_mut()) {
            field.0[lane] = value.0[0];
        }
    }
}

/// Tyre forces of eq. (4)–(5), faded out below the low-speed guard; also 1 / v_x guarded.
#[inline(always)]
pub(super) fn lateral_forces<const N: usize>(x: &StateLanes<N>, model: &Model<N>) -> (Lanes<N>, Lanes<N>, Lanes<N>) {
    let [vx, vy, r, _, _, _, steer, _] = *x;
    let inv_speed = Lanes::splat(1.0) / vx.max(model.guard);
    let fade = (vx * model.inv_guard).clamp(Lanes::splat(0.0), Lanes::splat(1.0));
    let front_slip = -steer + (vy + model.front_axle * r) * inv_speed; // eq. (5)
    let rear_slip = (vy - model.rear_axle * r) * inv_speed; // eq. (5)
    (-model.front_stiffness * front_slip * fade, -model.rear_stiffness * rear_slip * fade, inv_speed) // eq. (4)
}

/// Row 1 of eq. (8) (eq. 2): v_x' = v_y r + a_x, the longitudinal acceleration; 0 for a
/// standing car it would roll back (a car does not reverse).
#[inline(always)]
pub(super) fn longitudinal_derivative<const N: usize>(
    vx: Lanes<N>,
    vy: Lanes<N>,
    r: Lanes<N>,
    accel: Lanes<N>,
) -> Lanes<N> {
    let vx_dot = vy * r + accel;
    let stopped = lanes::mask(|i| vx.0[i] <= 0.0 && vx_dot.0[i] < 0.0);
    Lanes::select(stopped, Lanes::splat(0.0), vx_dot)
}

/// Rows 1–3 of eq. (8) (eq. 2 with eq. 3): the body's speeds. A car does not reverse.
#[inline(always)]
pub(super) fn body_derivative<const N: usize>(
    x: &StateLanes<N>,
    (front, rear): (Lanes<N>, Lanes<N>),
    cos_steer: Lanes<N>,
    accel: Lanes<N>,
    model: &Model<N>,
) -> [Lanes<N>; 3] {
    let [vx, vy, r, ..] = *x;
    [
        longitudinal_derivative(vx, vy, r, accel),
        -vx * r + (front * cos_steer + rear) * model.inv_mass,
        (model.front_axle * front * cos_steer - model.rear_axle * rear) * model.inv_inertia,
    ]
}

/// Rows 4–6 of eq. (8) (eq. 6), written in the Frenet frame of a lane with `curvature`.
#[inline(always)]
fn pose_derivative<const N: usize>(
    x: &StateLanes<N>,
    (sin, cos): (Lanes<N>, Lanes<N>),
    curvature: Lanes<N>,
) -> [Lanes<N>; 3] {
    let [vx, vy, r, _, _, d, _, _] = *x;
    let along = vx * cos - vy * sin;
    // Dividing by 1 - 0 d gives `along` exactly: skipping it on straight lanes saves a
    // division and changes no bit.
    let straight = curvature.0.iter().all(|&k| k == 0.0);
    let s_dot = if straight { along } else { along / (Lanes::splat(1.0) - curvature * d) };
    [r - curvature * s_dot, s_dot, vx * sin + vy * cos]
}

/// Row 8 of eq. (8), taken from eq. (1) (docs/design.md, "Equation 1 against equation 8").
#[inline(always)]
fn driver_derivative<const N: usize>(
    x: &StateLanes<N>,
    preview: Lanes<N>,
    inv_speed: Lanes<N>,
    model: &Model<N>,
) -> Lanes<N> {
    let [vx, _, _, heading, _, d, steer, steer_rate] = *x;
    let predicted = d + model.preview_time * vx * heading;
    // eq. (1), with K_s = K_0 (v_ref / v_x)^(3/2) folded into preview_gain and the schedule
    let preview_gain = steering_schedule(model.preview_gain, inv_speed, model.inv_reference_speed);
    -steer_rate * model.rate_gain - steer * model.angle_gain + preview_gain * (preview - predicted)
}

/// f(x, u) of eq. (7)–(8) on a lane of the given curvature.
pub fn derivative(
    x: &Vector8,
    command: Command,
    curvature: f64,
    vehicle: &VehicleParams,
    driver: &DriverParams,
) -> Vector8 {
    array_of(&derivative_at(&lanes_of(x), &Inputs::one(command, curvature), &Model::new(vehicle, driver)))
}

/// What a vehicle's f reads besides its state and constants, for N vehicles.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct Inputs<const N: usize> {
    pub(super) accel: Lanes<N>,
    pub(super) preview: Lanes<N>,
    pub(super) curvature: Lanes<N>,
}

impl Inputs<1> {
    pub(super) fn one(command: Command, curvature: f64) -> Inputs<1> {
        Inputs { accel: Lanes([command.accel]), preview: Lanes([command.preview]), curvature: Lanes([curvature]) }
    }
}

#[inline(always)]
pub(super) fn derivative_at<const N: usize>(x: &StateLanes<N>, inputs: &Inputs<N>, model: &Model<N>) -> StateLanes<N> {
    let heading = lanes::sin_cos(x[3]);
    let (_, cos_steer) = lanes::sin_cos(x[6]);
    let (front, rear, inv_speed) = lateral_forces(x, model);
    let [vx_dot, vy_dot, r_dot] = body_derivative(x, (front, rear), cos_steer, inputs.accel, model);
    let [heading_dot, s_dot, d_dot] = pose_derivative(x, heading, inputs.curvature);
    let steer_accel = driver_derivative(x, inputs.preview, inv_speed, model);
    [vx_dot, vy_dot, r_dot, heading_dot, s_dot, d_dot, x[7], steer_accel]
}

/// The bicycle alone (eq. 2–6) with the steering angle held where it is.
#[cfg(test)]
pub fn fixed_steer_derivative(x: &Vector8, accel: f64, curvature: f64, vehicle: &VehicleParams) -> Vector8 {
    let model = Model::new(vehicle, &DriverParams::default());
    let inputs = Inputs::one(Command { accel, preview: 0.0 }, curvature);
    let mut dx = array_of(&derivative_at(&lanes_of(x), &inputs, &model));
    dx[6] = 0.0;
    dx[7] = 0.0;
    dx
}
