//! The constants of eq. (1)-(8): the vehicle of Table II (with the body size collisions
//! use and the guards the model needs at a standstill), the driving styles, and the
//! preview driver of Table I with the K_s schedule chosen here. Each field gives its
//! unit, value and source (docs/parameters.md lists them).

use serde::{Deserialize, Serialize};

use super::lanes::Lanes;

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
    /// K_0 in K_s = K_0 * (v_ref / v_x)^(3/2), the steering ratio at `reference_speed`
    /// (rad/m), one per style: 0.037 aggressive, 0.043 normal, 0.058 conservative, each the
    /// middle of the K_0 that keep the style's lateral modes at Re lambda <= -0.02 1/s from
    /// 1 to 40 m/s and its lane changes within `LANE_CHANGE_BOUNDS`. Chosen here (the paper
    /// leaves K_s open; docs/parameters.md, "K_s"; `examples/stability.rs`).
    pub steering_ratio: f64,
    /// v_ref of the K_s schedule (m/s). 20, chosen here.
    pub reference_speed: f64,
}

impl DriverParams {
    /// Table I's column for `style`, with the K_0 and v_ref of the K_s schedule chosen here.
    pub fn for_style(style: Style) -> DriverParams {
        let (delay, preview_time, steering_gain, damping, steering_ratio) = match style {
            Style::Aggressive => (0.14, 1.02, 0.84, 0.24, 0.037),
            Style::Normal => (0.18, 0.94, 0.75, 0.23, 0.043),
            Style::Conservative => (0.24, 0.83, 0.62, 0.22, 0.058),
        };
        DriverParams { delay, preview_time, steering_gain, damping, steering_ratio, reference_speed: 20.0 }
    }

    /// K_s at speed `vx`: K_0 (v_ref / v_x)^(3/2). The closed loop's gain grows with v_x^2
    /// (the displacement a steering angle makes), so the largest K_s that keeps it stable
    /// falls about as 1/v_x^2; the smallest that keeps a lane change within bounds falls
    /// only about as 1/v_x. The exponent 3/2 keeps each style between the two
    /// (docs/parameters.md, "K_s").
    /// Below v_ref it falls as 1 / v_x, as before the 3/2 was chosen: a steeper rise at
    /// low speed made the conservative EC of the paper's Scenario A, merging at 8 m/s,
    /// swing into AC (`arena paper`), and the 1 / v_x loop is stable there.
    pub fn steering_ratio_at(&self, vx: f64) -> f64 {
        let (scale, inv_ref) = (Lanes([self.steering_ratio_scale()]), Lanes([1.0 / self.reference_speed]));
        steering_schedule(scale, Lanes([1.0 / vx]), inv_ref).0[0]
    }

    /// dK_s/dv_x at speed `vx` (rad s/m^2), the slope of `steering_ratio_at`: -(3/2) K_s /
    /// v_x above v_ref, -K_s / v_x below.
    pub fn steering_ratio_slope_at(&self, vx: f64) -> f64 {
        let exponent = if vx >= self.reference_speed { 1.5 } else { 1.0 };
        -exponent * self.steering_ratio_at(vx) / vx
    }

    /// K_s v_x^(3/2) = K_0 v_ref^(3/2): the schedule's constant.
    pub(super) fn steering_ratio_scale(&self) -> f64 {
        self.steering_ratio * self.reference_speed * self.reference_speed.sqrt()
    }
}

/// The K_s schedule, once for one vehicle and a block of them: `scale` / v_x^(3/2) above
/// v_ref and `scale` / (v_x v_ref^(1/2)) below, with `scale`
/// `DriverParams::steering_ratio_scale` (or it times eq. (1)'s other constant factors),
/// `inv_speed` 1 / v_x and `inv_reference_speed` 1 / v_ref. A square root, not `powf`:
/// IEEE rounds it exactly, so the bits do not depend on the machine's libm.
#[inline(always)]
pub(super) fn steering_schedule<const N: usize>(
    scale: Lanes<N>,
    inv_speed: Lanes<N>,
    inv_reference_speed: Lanes<N>,
) -> Lanes<N> {
    scale * inv_speed * inv_speed.min(inv_reference_speed).map(f64::sqrt)
}

impl Default for DriverParams {
    fn default() -> Self {
        DriverParams::for_style(Style::Normal)
    }
}
