//! The constants of eq. (1)-(8): the vehicle of Table II (with the body size collisions
//! use and the guards the model needs at a standstill), the driving styles, and the
//! preview driver of Table I with the K_s schedule chosen here. Each field gives its
//! unit, value and source (docs/parameters.md lists them).

use serde::{Deserialize, Serialize};

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
