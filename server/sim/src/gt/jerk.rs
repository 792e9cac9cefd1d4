//! Smooth driving (docs/design.md, "Jerk"): the AV's commanded acceleration changes by at
//! most `max_jerk` per second. The games choose a target acceleration, each candidate
//! reached from the last command along a ramp at the bound (`AccelRamp`); the predicted
//! motion and the costs of eq. (10)–(14) integrate that ramp, and the command of the
//! period is the ramp's first step, which the world ramps over the period. What the AV
//! predicts is what it does.
//!
//! Exempt (`Exemption`): the command of an aborted lane change (`merge`) and that of a
//! safety override (emergency braking) take their acceleration at once; the driver counts
//! every such command that leaves the bound (`Diagnostics::abort_jumps`,
//! `Diagnostics::emergency_jumps`).

use serde::{Deserialize, Serialize};

use super::prediction::SpeedBounds;

/// The jerk bound of the AV's commanded acceleration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct JerkParams {
    /// Whether the acceleration is ramped at `max_jerk` (in the games' predictions, their
    /// strategy sets and the command). true; false is the AV before issue 24: each
    /// candidate held from now, the command a step.
    pub enabled: bool,
    /// J_max (m/s^3): the most the commanded acceleration changes per second, up or down.
    /// 4, chosen within the 2.5–5 m/s^3 that ISO 15622 (adaptive cruise control) allows
    /// the jerk of automatic braking (2.5 at highway speeds, 5 at walking pace): the
    /// smallest of 2.5, 3, 4 and 5 under which the paper's qualitative results hold
    /// (docs/parameters.md, "Jerk"). 0.4 m/s^2 per 0.1 s control period.
    pub max_jerk: f64,
}

impl Default for JerkParams {
    fn default() -> Self {
        JerkParams { enabled: true, max_jerk: 4.0 }
    }
}

/// Why a command may leave the jerk bound.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exemption {
    /// A lane change under way was given up (`Decision::aborted`): braking back in the
    /// lane begins at once.
    Abort,
    /// The safety layer lowered the acceleration (`gt::safety`: a cap, or emergency
    /// braking), bypassing the ramp.
    Emergency,
}

/// An acceleration that goes from `from` towards `to` at `rate` and then holds `to`: how
/// a car drives a candidate of the games.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccelRamp {
    /// The acceleration now (m/s^2): the last command.
    pub from: f64,
    /// The target (m/s^2).
    pub to: f64,
    /// How fast it changes (m/s^3); infinite: a step.
    pub rate: f64,
}

impl AccelRamp {
    /// `accel` from now on.
    pub fn step(accel: f64) -> AccelRamp {
        AccelRamp { from: accel, to: accel, rate: f64::INFINITY }
    }

    /// How long it takes to reach `to` (s); 0 for a step.
    pub fn duration(&self) -> f64 {
        if self.from == self.to { 0.0 } else { (self.to - self.from).abs() / self.rate }
    }

    /// The acceleration `t` seconds from now (m/s^2).
    pub fn at(&self, t: f64) -> f64 {
        if t >= self.duration() { self.to } else { self.from + (self.to - self.from).signum() * self.rate * t }
    }

    /// The signed rate of its rise (m/s^3): 0 for a step.
    pub fn jerk(&self) -> f64 {
        if self.duration() == 0.0 { 0.0 } else { (self.to - self.from).signum() * self.rate }
    }
}

impl JerkParams {
    /// How a car whose last command was `from` reaches `to`.
    pub fn ramp(&self, from: f64, to: f64) -> AccelRamp {
        match self.enabled {
            true => AccelRamp { from, to, rate: self.max_jerk },
            false => AccelRamp::step(to),
        }
    }

    /// The accelerations (m/s^2) a car at `speed` may aim for so that, ramping back to 0
    /// at the bound, it comes to rest on the speed bound rather than past it:
    /// [-sqrt(2 J (v - v_min)), sqrt(2 J (v_max - v))], 0 on the bound or past it. The
    /// whole line when the ramp is off.
    pub fn envelope(&self, speed: f64, bounds: SpeedBounds) -> (f64, f64) {
        if !self.enabled {
            return (f64::NEG_INFINITY, f64::INFINITY);
        }
        let room = |gap: f64| (2.0 * self.max_jerk * gap.max(0.0)).sqrt();
        (-room(speed - bounds.min), room(bounds.max - speed))
    }

    /// The most the command may change over one control period `dt` (m/s^2).
    pub fn step_limit(&self, dt: f64) -> f64 {
        match self.enabled {
            true => self.max_jerk * dt,
            false => f64::INFINITY,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ramp_rises_at_its_rate_and_holds_its_target() {
        let up = AccelRamp { from: -1.0, to: 1.5, rate: 2.5 };
        assert_eq!(up.duration(), 1.0);
        assert_eq!([up.at(0.0), up.at(0.4), up.at(1.0), up.at(3.0)], [-1.0, 0.0, 1.5, 1.5]);
        assert_eq!(up.jerk(), 2.5);
        let down = AccelRamp { from: 2.0, to: -4.0, rate: 2.5 };
        assert_eq!((down.at(0.1), down.at(2.4), down.jerk()), (1.75, -4.0, -2.5));
        let step = AccelRamp::step(-3.0);
        assert_eq!((step.duration(), step.at(0.0), step.jerk()), (0.0, -3.0, 0.0));
    }

    #[test]
    fn the_command_of_a_period_moves_by_the_bound_times_the_period() {
        let jerk = JerkParams { max_jerk: 2.5, ..JerkParams::default() };
        let first = jerk.ramp(0.5, 3.0).at(0.1);
        assert_eq!(first, 0.75);
        assert_eq!(jerk.step_limit(0.1), 0.25);
        assert_eq!(jerk.ramp(0.5, 0.6).at(0.1), 0.6, "a target within reach is reached");
        let off = JerkParams { enabled: false, ..jerk };
        assert_eq!(off.ramp(0.5, 3.0).at(0.1), 3.0);
    }

    #[test]
    fn the_envelope_lets_a_car_settle_on_its_speed_bounds() {
        let jerk = JerkParams { max_jerk: 2.5, ..JerkParams::default() };
        let bounds = SpeedBounds { min: 0.0, max: 25.0 };
        // 0.8 m/s below the limit: ramping down from 2 m/s^2 at 2.5 m/s^3 gains 0.8 m/s.
        let (low, high) = jerk.envelope(24.2, bounds);
        assert!((high - 2.0).abs() < 1e-12 && (low + (5.0f64 * 24.2).sqrt()).abs() < 1e-12);
        assert_eq!(jerk.envelope(25.0, bounds).1, 0.0);
        assert_eq!(jerk.envelope(26.0, bounds).1, 0.0);
        assert_eq!(jerk.envelope(0.0, bounds).0, 0.0);
        let off = JerkParams { enabled: false, ..jerk };
        assert_eq!(off.envelope(25.0, bounds), (f64::NEG_INFINITY, f64::INFINITY));
    }
}
