//! The paper's integrated driver + bicycle model, eq. (1)–(8): its parameters (Tables I
//! and II), the state derivative, fixed-step RK4 integration, and the linearisation and
//! exact discretisation of eq. (22)–(24) that the MPC plans with.
//!
//! Vehicles move in the road's Frenet frame: `s` along the reference line, `d` to its
//! left, `heading` relative to the tangent. On a straight road (curvature 0) this is
//! exactly eq. (6) with X = s, Y = d; on an arc the kinematics gain the usual
//! `1 / (1 - curvature * d)` factor, so the driver of eq. (1) previews the lane, not the
//! global Y axis (docs/design.md, "Frenet frame").

use std::ops::{Add, Mul};

use nalgebra::{SMatrix, SVector};
use serde::{Deserialize, Serialize};

mod fleet;
mod lanes;

pub use fleet::Fleet;
use lanes::Lanes;

/// Number of states: [vx, vy, r, heading, s, d, steer, steer_rate] (eq. 8's x).
pub const STATES: usize = 8;
/// Number of inputs: [a_x, Y_p].
pub const INPUTS: usize = 2;

/// The vehicle of Table II plus the body size used for collisions.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct VehicleParams {
    /// m, mass (kg). Table II: 1300.
    pub mass: f64,
    /// I_z, yaw moment of inertia (kg m^2). Table II: 2500.
    pub yaw_inertia: f64,
    /// l_f, CoG to front axle (m). Table II: 1.25.
    pub front_axle: f64,
    /// l_r, CoG to rear axle (m). Table II: 1.32.
    pub rear_axle: f64,
    /// k_f, front cornering stiffness (N/rad). Table II: 35000.
    pub front_stiffness: f64,
    /// k_r, rear cornering stiffness (N/rad). Table II: 38000.
    pub rear_stiffness: f64,
    /// Body length (m). 5.0, highway-env's `Vehicle.LENGTH`.
    pub length: f64,
    /// Body width (m). 2.0, highway-env's `Vehicle.WIDTH`.
    pub width: f64,
    /// Below this speed (m/s) the slip angles divide by it instead of v_x and the tyre
    /// forces fade out linearly, so a standing car neither divides by zero nor creeps
    /// sideways. 1.0, chosen here.
    pub low_speed_guard: f64,
    /// The largest road-wheel angle delta (rad) the steering reaches: 0.6 (34 degrees),
    /// a passenger car's lock. The paper's runs never come near it; a car that steers
    /// for a preview point while standing does.
    pub max_steer: f64,
}

impl Default for VehicleParams {
    fn default() -> Self {
        VehicleParams {
            mass: 1300.0,
            yaw_inertia: 2500.0,
            front_axle: 1.25,
            rear_axle: 1.32,
            front_stiffness: 35000.0,
            rear_stiffness: 38000.0,
            length: 5.0,
            width: 2.0,
            low_speed_guard: 1.0,
            max_steer: 0.6,
        }
    }
}

impl VehicleParams {
    /// Wheelbase L = l_f + l_r (m).
    pub fn wheelbase(&self) -> f64 {
        self.front_axle + self.rear_axle
    }

    /// Understeer gradient K_us = m/L (l_r/k_f - l_f/k_r) (rad s^2/m) of the linear
    /// bicycle model that eq. (2)–(5) reduce to for small angles.
    pub fn understeer_gradient(&self) -> f64 {
        self.mass / self.wheelbase() * (self.rear_axle / self.front_stiffness - self.front_axle / self.rear_stiffness)
    }
}

/// A driving style of Table I (driver) and Table III (cost weights, see `gt`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Style {
    /// Fast reactions, long preview, high gain.
    Aggressive,
    /// Between the other two.
    Normal,
    /// Slow reactions, short preview, low gain.
    Conservative,
}

impl Style {
    /// All styles, in the paper's column order.
    pub const ALL: [Style; 3] = [Style::Aggressive, Style::Normal, Style::Conservative];

    /// The lowercase name used in scenario files and reports.
    pub fn name(self) -> &'static str {
        match self {
            Style::Aggressive => "aggressive",
            Style::Normal => "normal",
            Style::Conservative => "conservative",
        }
    }
}

/// The preview driver of eq. (1), Table I.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DriverParams {
    /// T_d, the driver's physical delay (s). Table I.
    pub delay: f64,
    /// T_p, the preview time (s). Table I.
    pub preview_time: f64,
    /// G_s, the steering proportional gain. Table I.
    pub steering_gain: f64,
    /// a, the damping-rate factor of eq. (1). Table I.
    pub damping: f64,
    /// K_0 in K_s = K_0 * (v_ref / v_x), the steering ratio at `reference_speed`
    /// (rad/m). 0.05, chosen here (the paper leaves K_s open; docs/parameters.md).
    pub steering_ratio: f64,
    /// v_ref of the K_s schedule (m/s). 20, chosen here.
    pub reference_speed: f64,
}

impl DriverParams {
    /// Table I's column for `style`, with the K_s schedule chosen here.
    pub fn for_style(style: Style) -> DriverParams {
        let (delay, preview_time, steering_gain, damping) = match style {
            Style::Aggressive => (0.14, 1.02, 0.84, 0.24),
            Style::Normal => (0.18, 0.94, 0.75, 0.23),
            Style::Conservative => (0.24, 0.83, 0.62, 0.22),
        };
        DriverParams { delay, preview_time, steering_gain, damping, steering_ratio: 0.05, reference_speed: 20.0 }
    }

    /// K_s at speed `vx`: the closed loop's gain grows with vx^2, so K_s falls with vx
    /// to keep every style settling without oscillation from 15 to 30 m/s.
    pub fn steering_ratio_at(&self, vx: f64) -> f64 {
        self.steering_ratio * self.reference_speed / vx
    }
}

impl Default for DriverParams {
    fn default() -> Self {
        DriverParams::for_style(Style::Normal)
    }
}

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

type Vector8 = [f64; STATES];

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
type StateLanes<const N: usize> = [Lanes<N>; STATES];

fn lanes_of(x: &Vector8) -> StateLanes<1> {
    x.map(|value| Lanes([value]))
}

fn array_of(x: &StateLanes<1>) -> Vector8 {
    x.map(|lane| lane.0[0])
}

/// The constants of f for N vehicles and their drivers, with reciprocals taken once:
/// f is evaluated four times per RK4 step, and divisions were most of its cost.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Model<const N: usize> {
    front_axle: Lanes<N>,
    rear_axle: Lanes<N>,
    front_stiffness: Lanes<N>,
    rear_stiffness: Lanes<N>,
    inv_mass: Lanes<N>,
    inv_inertia: Lanes<N>,
    guard: Lanes<N>,
    inv_guard: Lanes<N>,
    max_steer: Lanes<N>,
    preview_time: Lanes<N>,
    /// 1 / (a T_d) and 1 / (a T_d^2) of eq. (1).
    rate_gain: Lanes<N>,
    angle_gain: Lanes<N>,
    /// K_0 v_ref G_s / (a T_d^2): eq. (1)'s preview gain times v_x, as K_s = K_0 v_ref / v_x.
    preview_gain: Lanes<N>,
}

impl Model<1> {
    fn new(vehicle: &VehicleParams, driver: &DriverParams) -> Model<1> {
        let DriverParams { delay, preview_time, steering_gain, damping, steering_ratio, reference_speed } = *driver;
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
            preview_gain: lane(steering_ratio * reference_speed * steering_gain / (damping * delay * delay)),
        }
    }
}

impl<const N: usize> Model<N> {
    fn fields_mut(&mut self) -> [&mut Lanes<N>; 13] {
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
        ]
    }

    /// Every lane holds the constants of `one`.
    fn splat(one: &Model<1>) -> Model<N> {
        let mut model = Model::default();
        let mut one = *one;
        for (field, value) in model.fields_mut().into_iter().zip(one.fields_mut()) {
            *field = Lanes::splat(value.0[0]);
        }
        model
    }

    /// Lanes `from..from + N` of a model of more vehicles.
    #[inline(always)]
    fn part<const WIDE: usize>(wide: &Model<WIDE>, from: usize) -> Model<N> {
        let mut model = Model::default();
        let mut wide = *wide;
        for (field, value) in model.fields_mut().into_iter().zip(wide.fields_mut()) {
            *field = Lanes::part(value, from);
        }
        model
    }

    /// Lane `lane` takes the constants of `one`.
    fn set_lane(&mut self, lane: usize, one: &Model<1>) {
        let mut one = *one;
        for (field, value) in self.fields_mut().into_iter().zip(one.fields_mut()) {
            field.0[lane] = value.0[0];
        }
    }
}

/// Tyre forces of eq. (4)–(5), faded out below the low-speed guard; also 1 / v_x guarded.
#[inline(always)]
fn lateral_forces<const N: usize>(x: &StateLanes<N>, model: &Model<N>) -> (Lanes<N>, Lanes<N>, Lanes<N>) {
    let [vx, vy, r, _, _, _, steer, _] = *x;
    let inv_speed = Lanes::splat(1.0) / vx.max(model.guard);
    let fade = (vx * model.inv_guard).clamp(Lanes::splat(0.0), Lanes::splat(1.0));
    let front_slip = -steer + (vy + model.front_axle * r) * inv_speed; // eq. (5)
    let rear_slip = (vy - model.rear_axle * r) * inv_speed; // eq. (5)
    (-model.front_stiffness * front_slip * fade, -model.rear_stiffness * rear_slip * fade, inv_speed) // eq. (4)
}

/// Rows 1–3 of eq. (8) (eq. 2 with eq. 3): the body's speeds. A car does not reverse.
#[inline(always)]
fn body_derivative<const N: usize>(
    x: &StateLanes<N>,
    (front, rear): (Lanes<N>, Lanes<N>),
    cos_steer: Lanes<N>,
    accel: Lanes<N>,
    model: &Model<N>,
) -> [Lanes<N>; 3] {
    let [vx, vy, r, ..] = *x;
    let vx_dot = vy * r + accel;
    let stopped = lanes::mask(|i| vx.0[i] <= 0.0 && vx_dot.0[i] < 0.0);
    [
        Lanes::select(stopped, Lanes::splat(0.0), vx_dot),
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
    // eq. (1), with K_s = K_0 v_ref / v_x folded into preview_gain * inv_speed
    -steer_rate * model.rate_gain - steer * model.angle_gain + model.preview_gain * inv_speed * (preview - predicted)
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
struct Inputs<const N: usize> {
    accel: Lanes<N>,
    preview: Lanes<N>,
    curvature: Lanes<N>,
}

impl Inputs<1> {
    fn one(command: Command, curvature: f64) -> Inputs<1> {
        Inputs { accel: Lanes([command.accel]), preview: Lanes([command.preview]), curvature: Lanes([curvature]) }
    }
}

#[inline(always)]
fn derivative_at<const N: usize>(x: &StateLanes<N>, inputs: &Inputs<N>, model: &Model<N>) -> StateLanes<N> {
    let heading = lanes::sin_cos(x[3]);
    let (_, cos_steer) = lanes::sin_cos(x[6]);
    let (front, rear, inv_speed) = lateral_forces(x, model);
    let [vx_dot, vy_dot, r_dot] = body_derivative(x, (front, rear), cos_steer, inputs.accel, model);
    let [heading_dot, s_dot, d_dot] = pose_derivative(x, heading, inputs.curvature);
    let steer_accel = driver_derivative(x, inputs.preview, inv_speed, model);
    [vx_dot, vy_dot, r_dot, heading_dot, s_dot, d_dot, x[7], steer_accel]
}

/// The bicycle alone (eq. 2–6) with the steering angle held where it is.
pub fn fixed_steer_derivative(x: &Vector8, accel: f64, curvature: f64, vehicle: &VehicleParams) -> Vector8 {
    let model = Model::new(vehicle, &DriverParams::default());
    let inputs = Inputs::one(Command { accel, preview: 0.0 }, curvature);
    let mut dx = array_of(&derivative_at(&lanes_of(x), &inputs, &model));
    dx[6] = 0.0;
    dx[7] = 0.0;
    dx
}

/// A right-hand side x' = f(x) for `rk4`: any closure, or `Closed` (a trait, not a
/// closure, so that the world step's f is inlined into its vectorised caller).
pub trait Derivative<T> {
    /// f(x).
    fn at(&self, x: &[T; STATES]) -> [T; STATES];
}

impl<T, F: Fn(&[T; STATES]) -> [T; STATES]> Derivative<T> for F {
    #[inline(always)]
    fn at(&self, x: &[T; STATES]) -> [T; STATES] {
        self(x)
    }
}

/// f of eq. (7)-(8) for N vehicles under fixed inputs: the closed loop RK4 integrates.
struct Closed<'a, const N: usize> {
    inputs: &'a Inputs<N>,
    model: &'a Model<N>,
}

impl<const N: usize> Derivative<Lanes<N>> for Closed<'_, N> {
    #[inline(always)]
    fn at(&self, x: &StateLanes<N>) -> StateLanes<N> {
        derivative_at(x, self.inputs, self.model)
    }
}

/// One classical Runge–Kutta step of `dt` for any right-hand side, on one vehicle's
/// states (`f64`) or N vehicles' (`Lanes<N>`).
#[inline(always)]
pub fn rk4<T>(x: &[T; STATES], dt: f64, f: impl Derivative<T>) -> [T; STATES]
where
    T: Copy + From<f64> + Add<Output = T> + Mul<Output = T>,
{
    #[inline(always)]
    fn offset<T: Copy + From<f64> + Add<Output = T> + Mul<Output = T>>(
        x: &[T; STATES],
        k: &[T; STATES],
        h: f64,
    ) -> [T; STATES] {
        let mut y = *x;
        for (y, k) in y.iter_mut().zip(k) {
            *y = *y + T::from(h) * *k;
        }
        y
    }
    // k1 + 2 k2 + 2 k3 + k4 summed as each k comes (the same order, so the same bits),
    // which keeps fewer of them alive at once.
    let (half, sixth, two) = (dt * 0.5, dt * (1.0 / 6.0), T::from(2.0));
    let k = f.at(x);
    let mut sum = k;
    let k = f.at(&offset(x, &k, half));
    sum.iter_mut().zip(&k).for_each(|(sum, k)| *sum = *sum + two * *k);
    let k = f.at(&offset(x, &k, half));
    sum.iter_mut().zip(&k).for_each(|(sum, k)| *sum = *sum + two * *k);
    let k = f.at(&offset(x, &k, dt));
    sum.iter_mut().zip(&k).for_each(|(sum, k)| *sum = *sum + *k);
    offset(x, &sum, sixth)
}

/// One RK4 step of eq. (7)-(8) for N vehicles, then the limits the model does not
/// enforce itself: a car does not reverse, and the steering stops at its lock.
#[inline(always)]
fn step_lanes<const N: usize>(x: &StateLanes<N>, inputs: &Inputs<N>, model: &Model<N>, dt: f64) -> StateLanes<N> {
    let mut next = rk4(x, dt, Closed { inputs, model });
    let zero = Lanes::splat(0.0);
    next[0] = Lanes::select(next[0].lt(zero), zero, next[0]);
    let locked = lanes::mask(|i| next[6].0[i].abs() > model.max_steer.0[i]);
    next[6] = Lanes::select(locked, next[6].clamp(-model.max_steer, model.max_steer), next[6]);
    next[7] = Lanes::select(locked, zero, next[7]);
    next
}

/// Speeds (m/s) at which `rk4_growth` is checked for a physics step: from below the 1 m/s
/// low-speed guard, where the tyres are stiffest (time constant about 18 ms), to the
/// learners' top speed on a 30 m/s lane (36).
pub const RK4_CHECK_SPEEDS: [f64; 14] = [0.5, 0.9, 1.0, 1.1, 1.5, 2.0, 3.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 36.0];

/// The modes (eigenvalues, 1/s) of the closed loop of eq. (7)-(8), driver and bicycle,
/// about a car of `style` cruising straight at `speed` on a straight lane. The Jacobian is
/// taken by central differences of `derivative`, so it includes the low-speed guard and
/// the tyre forces' fade below it (which `linearise` leaves out).
pub fn cruising_modes(style: Style, speed: f64) -> Vec<nalgebra::Complex<f64>> {
    let (vehicle, driver) = (VehicleParams::default(), DriverParams::for_style(style));
    let x0 = VehicleState::cruising(0.0, 0.0, speed).to_array();
    let jacobian = SMatrix::<f64, STATES, STATES>::from_fn(|i, j| {
        let h = 1e-7 * x0[j].abs().max(1.0);
        let (mut plus, mut minus) = (x0, x0);
        plus[j] += h;
        minus[j] -= h;
        let f = |x: &Vector8| derivative(x, Command::default(), 0.0, &vehicle, &driver)[i];
        (f(&plus) - f(&minus)) / (2.0 * h)
    });
    jacobian.complex_eigenvalues().iter().copied().collect()
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

/// Advances a vehicle by one physics step with the driver model closing the loop.
#[inline]
pub fn step(
    state: &VehicleState,
    command: Command,
    curvature: f64,
    dt: f64,
    vehicle: &VehicleParams,
    driver: &DriverParams,
) -> VehicleState {
    Stepper::new(vehicle, driver, dt).step(state, command, curvature)
}

/// `step` with the constants of f prepared once, for a world that steps many vehicles
/// of the same kind every tick (`Fleet` steps them in blocks).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stepper {
    model: Model<1>,
    dt: f64,
}

impl Stepper {
    /// Prepares the step of a `vehicle` with `driver` over `dt`.
    pub fn new(vehicle: &VehicleParams, driver: &DriverParams, dt: f64) -> Stepper {
        Stepper { model: Model::new(vehicle, driver), dt }
    }

    /// One RK4 step of eq. (7)-(8).
    #[inline]
    pub fn step(&self, state: &VehicleState, command: Command, curvature: f64) -> VehicleState {
        let inputs = Inputs::one(command, curvature);
        VehicleState::from_array(array_of(&step_lanes(&lanes_of(&state.to_array()), &inputs, &self.model, self.dt)))
    }
}

/// The continuous-time linearisation of eq. (22)–(23) around (x_t, u_t), plus the
/// affine term `f(x_t, u_t) - A x_t - B u_t` so the model stays exact at the point.
#[derive(Debug, Clone, PartialEq)]
pub struct Linearisation {
    /// A_t = df/dx.
    pub a: SMatrix<f64, STATES, STATES>,
    /// B_t = df/du, columns [a_x, Y_p].
    pub b: SMatrix<f64, STATES, INPUTS>,
    /// f(x_t, u_t) - A_t x_t - B_t u_t.
    pub offset: SVector<f64, STATES>,
}

/// eq. (23): the analytic Jacobians of `derivative` (above the low-speed guard).
pub fn linearise(
    state: &VehicleState,
    command: Command,
    curvature: f64,
    vehicle: &VehicleParams,
    driver: &DriverParams,
) -> Linearisation {
    let x = state.to_array();
    let [vx, vy, r, heading, _, d, steer, _] = x;
    let VehicleParams {
        mass, yaw_inertia, front_axle: lf, rear_axle: lr, front_stiffness: kf, rear_stiffness: kr, ..
    } = *vehicle;
    let mut a = SMatrix::<f64, STATES, STATES>::zeros();
    let mut b = SMatrix::<f64, STATES, INPUTS>::zeros();
    let (front, ..) = lateral_forces(&lanes_of(&x), &Model::new(vehicle, driver));
    let front = front.0[0];
    let (sin_steer, cos_steer) = steer.sin_cos();

    // Tyre forces' partials over [vx, vy, r, steer].
    let front_d = [kf * (vy + lf * r) / (vx * vx), -kf / vx, -kf * lf / vx, kf];
    let rear_d = [kr * (vy - lr * r) / (vx * vx), -kr / vx, kr * lr / vx, 0.0];
    let columns = [0, 1, 2, 6];

    a[(0, 1)] = r;
    a[(0, 2)] = vy;
    b[(0, 0)] = 1.0;
    for (k, &col) in columns.iter().enumerate() {
        a[(1, col)] = (front_d[k] * cos_steer + rear_d[k]) / mass;
        a[(2, col)] = (lf * front_d[k] * cos_steer - lr * rear_d[k]) / yaw_inertia;
    }
    a[(1, 0)] -= r;
    a[(1, 2)] -= vx;
    a[(1, 6)] -= front * sin_steer / mass;
    a[(2, 6)] -= lf * front * sin_steer / yaw_inertia;

    let (sin, cos) = heading.sin_cos();
    let stretch = 1.0 - curvature * d;
    let s_dot = (vx * cos - vy * sin) / stretch;
    let s_dot_d = [cos / stretch, -sin / stretch, (-vx * sin - vy * cos) / stretch, s_dot * curvature / stretch];
    for (k, &col) in [0, 1, 3, 5].iter().enumerate() {
        a[(4, col)] = s_dot_d[k];
        a[(3, col)] = -curvature * s_dot_d[k];
    }
    a[(3, 2)] = 1.0;
    a[(5, 0)] = sin;
    a[(5, 1)] = cos;
    a[(5, 3)] = vx * cos - vy * sin;
    a[(6, 7)] = 1.0;

    let DriverParams { delay, preview_time, steering_gain, damping, .. } = *driver;
    let gain = steering_gain / (damping * delay * delay);
    let ratio = driver.steering_ratio_at(vx);
    let ratio_dvx = -ratio / vx;
    let error = command.preview - (d + preview_time * vx * heading);
    a[(7, 7)] = -1.0 / (damping * delay);
    a[(7, 6)] = -1.0 / (damping * delay * delay);
    a[(7, 5)] = -ratio * gain;
    a[(7, 3)] = -ratio * gain * preview_time * vx;
    a[(7, 0)] = gain * (ratio_dvx * error - ratio * preview_time * heading);
    b[(7, 1)] = ratio * gain;

    let f = SVector::from(derivative(&x, command, curvature, vehicle, driver));
    let offset = f - a * SVector::from(x) - b * SVector::from([command.accel, command.preview]);
    Linearisation { a, b, offset }
}

/// The discrete model of eq. (24): x(k+1) = A_k x(k) + B_k u(k) + c_k.
#[derive(Debug, Clone, PartialEq)]
pub struct Discretisation {
    /// A_k = e^(A_t dT).
    pub a: SMatrix<f64, STATES, STATES>,
    /// B_k = integral_0^dT e^(A_t tau) B_t dtau.
    pub b: SMatrix<f64, STATES, INPUTS>,
    /// The same integral applied to the affine term.
    pub offset: SVector<f64, STATES>,
}

impl Linearisation {
    /// eq. (24), exactly: the exponential of the augmented matrix [[A, B, c], [0, 0, 0]] dT
    /// holds A_k, B_k and c_k in its top rows (zero-order hold on u).
    pub fn discretise(&self, dt: f64) -> Discretisation {
        const N: usize = STATES + INPUTS + 1;
        let mut augmented = SMatrix::<f64, N, N>::zeros();
        augmented.fixed_view_mut::<STATES, STATES>(0, 0).copy_from(&(self.a * dt));
        augmented.fixed_view_mut::<STATES, INPUTS>(0, STATES).copy_from(&(self.b * dt));
        augmented.fixed_view_mut::<STATES, 1>(0, STATES + INPUTS).copy_from(&(self.offset * dt));
        let exp = augmented.exp();
        Discretisation {
            a: exp.fixed_view::<STATES, STATES>(0, 0).into_owned(),
            b: exp.fixed_view::<STATES, INPUTS>(0, STATES).into_owned(),
            offset: exp.fixed_view::<STATES, 1>(0, STATES + INPUTS).into_owned(),
        }
    }
}

/// Duration of one lane change's lateral path (s), for every driver: IDM/MOBIL, learners'
/// meta actions, the game-theoretic AV's predictions and a scenario's start onto its lane.
/// 4, chosen here: a 4 s quintic settles every style within the bounds of
/// docs/parameters.md at 15-30 m/s.
pub const LANE_CHANGE_DURATION: f64 = 4.0;

/// A smooth lateral path from one offset to another (a quintic in time with zero
/// lateral speed and acceleration at both ends): the "consecutive preview points" of
/// §III-B. Drivers preview it `T_p` ahead rather than aiming at the final lane, which
/// with a constant K_s overshoots by metres (docs/design.md, "Preview path").
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LateralPath {
    /// Offset at the start (m).
    pub from: f64,
    /// Offset at the end (m).
    pub to: f64,
    /// Simulated time the path starts (s).
    pub start: f64,
    /// Duration (s).
    pub duration: f64,
}

impl LateralPath {
    /// A path that stays at `d`.
    pub fn hold(d: f64) -> LateralPath {
        LateralPath { from: d, to: d, start: 0.0, duration: 1.0 }
    }

    /// A lane change from offset `from` to `to` starting at `start`.
    pub fn lane_change(from: f64, to: f64, start: f64) -> LateralPath {
        LateralPath { from, to, start, duration: LANE_CHANGE_DURATION }
    }

    /// The path's offset at time `t` (m).
    pub fn offset_at(&self, t: f64) -> f64 {
        let u = ((t - self.start) / self.duration).clamp(0.0, 1.0);
        let blend = u * u * u * (10.0 - 15.0 * u + 6.0 * u * u);
        self.from + (self.to - self.from) * blend
    }

    /// The preview point Y_p for a driver at time `t` with preview time `T_p`.
    pub fn preview(&self, t: f64, preview_time: f64) -> f64 {
        self.offset_at(t + preview_time)
    }

    /// Whether the path has reached its end at time `t`.
    pub fn finished(&self, t: f64) -> bool {
        t >= self.start + self.duration
    }
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
        let width = if left { self.width } else { -self.width };
        lane_change_response(style, speed, width, LANE_CHANGE_DURATION, self.band, self.horizon, dt)
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
    let vehicle = VehicleParams::default();
    let driver = DriverParams::for_style(style);
    let path = LateralPath { from: 0.0, to: width, start: 0.0, duration: path_duration };
    let stepper = Stepper::new(&vehicle, &driver, dt);
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
    let (mut settling_time, mut overshoot) = (0.0, 0.0f64);
    for (k, state) in lane_change_trajectory(style, speed, width, path_duration, horizon, dt).iter().enumerate() {
        overshoot = overshoot.max((state.d - width) * width.signum());
        if (state.d - width).abs() > band {
            settling_time = (k + 1) as f64 * dt;
        }
    }
    LaneChangeResponse { settling_time, overshoot }
}

#[cfg(test)]
mod tests;
