//! Jerk, the rate of change of the longitudinal acceleration, as the AV's smoothness is
//! measured (docs/design.md, "Jerk"): commanded, between control periods, and the
//! model's own, per physics step. Pure functions for the env and the tests; the bound
//! itself is the AV's (`gt::JerkParams`).

/// Commanded jerk (m/s^3): the change of the commanded acceleration from the control
/// period before (`previous`, m/s^2) to this one (`accel`), over the period `control_dt`.
pub fn commanded_jerk(previous: f64, accel: f64, control_dt: f64) -> f64 {
    (accel - previous) / control_dt
}

/// The model's longitudinal jerk over one physics step (m/s^3): the change of its
/// longitudinal acceleration (v_x' of eq. 2, `VehicleState::longitudinal_accel`, as
/// `Vehicle::longitudinal_accel` records it each step) from the step before (`previous`)
/// to this one, over the step `physics_dt`.
pub fn longitudinal_jerk(previous: f64, accel: f64, physics_dt: f64) -> f64 {
    (accel - previous) / physics_dt
}

/// The p95 and the largest of a set of jerk magnitudes, as `arena eval` and the examples
/// report a policy's.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JerkSummary {
    /// How many values.
    pub count: usize,
    /// The 95th percentile of |jerk| (m/s^3), nearest rank: the smallest value that at
    /// least 95 % of the values do not exceed. 0 for none.
    pub p95: f64,
    /// The largest |jerk| (m/s^3). 0 for none.
    pub max: f64,
}

impl JerkSummary {
    /// The summary of `jerks` (m/s^3, either sign).
    pub fn of(jerks: impl IntoIterator<Item = f64>) -> JerkSummary {
        let mut magnitudes: Vec<f64> = jerks.into_iter().map(f64::abs).collect();
        magnitudes.sort_by(f64::total_cmp);
        let count = magnitudes.len();
        if count == 0 {
            return JerkSummary::default();
        }
        let rank = (0.95 * count as f64).ceil() as usize;
        JerkSummary { count, p95: magnitudes[rank.clamp(1, count) - 1], max: magnitudes[count - 1] }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::VehicleState;

    #[test]
    fn jerk_is_the_change_of_acceleration_over_the_interval() {
        assert!((commanded_jerk(0.5, 0.75, 0.1) - 2.5).abs() < 1e-12);
        assert!((longitudinal_jerk(1.0, 0.9, 0.01) + 10.0).abs() < 1e-9);
    }

    #[test]
    fn the_models_longitudinal_acceleration_is_eq_2s() {
        // v_x' = v_y r + a_x, and a standing car braking does not roll back.
        let turning = VehicleState { vx: 20.0, vy: 0.5, yaw_rate: 0.2, ..VehicleState::default() };
        assert!((turning.longitudinal_accel(1.0) - 1.1).abs() < 1e-12);
        assert_eq!(VehicleState::cruising(0.0, 0.0, 0.0).longitudinal_accel(-2.0), 0.0);
        assert_eq!(VehicleState::cruising(0.0, 0.0, 0.0).longitudinal_accel(1.0), 1.0);
    }

    #[test]
    fn the_summary_takes_magnitudes_and_the_nearest_rank() {
        // 20 values 1..=20, half of them negative: p95 is the 19th, max the 20th.
        let jerks = (1..=20).map(|k| if k % 2 == 0 { -f64::from(k) } else { f64::from(k) });
        assert_eq!(JerkSummary::of(jerks), JerkSummary { count: 20, p95: 19.0, max: 20.0 });
        assert_eq!(JerkSummary::of([3.0]), JerkSummary { count: 1, p95: 3.0, max: 3.0 });
        assert_eq!(JerkSummary::of([]), JerkSummary::default());
    }
}
