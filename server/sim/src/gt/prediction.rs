//! Predicted motion over the decision horizon: where each car of a game will be at the
//! sample instants if it holds an acceleration (speed kept within its bounds), and where
//! the ego car will be sideways if it changes lanes (along the same quintic path the
//! world's drivers preview). The costs of eq. (9)–(14) are averaged over these samples.

use serde::{Deserialize, Serialize};

use crate::dynamics::LateralPath;

/// A car at one instant, in the road's Frenet frame.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Kinematics {
    /// Position along the road (m).
    pub s: f64,
    /// Offset left of the reference line (m).
    pub d: f64,
    /// Speed along the road (m/s).
    pub speed: f64,
}

/// How far ahead the games look.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PredictionParams {
    /// Decision horizon (s): how far ahead a candidate's motion is predicted. 3, chosen
    /// here: long enough to see a gap open or close, short enough that holding one
    /// acceleration is still a fair guess.
    pub horizon: f64,
    /// Number of sample instants, evenly spaced over (0, horizon]. 6 (every 0.5 s).
    pub samples: usize,
}

impl Default for PredictionParams {
    fn default() -> Self {
        PredictionParams { horizon: 3.0, samples: 6 }
    }
}

impl PredictionParams {
    /// The sample instants (s from now).
    pub fn times(&self) -> impl Iterator<Item = f64> + '_ {
        let n = self.samples.max(1);
        (1..=n).map(move |k| self.horizon * k as f64 / n as f64)
    }
}

/// Peak lateral acceleration of one lane change of `width` along a quintic path of
/// `duration` T (m/s^2): 10 / sqrt(3) * width / T^2. This is a_y of eq. (13) for sigma != 0:
/// T = `LANE_CHANGE_DURATION`, or shorter for a change fitted to leave an ending lane in
/// time (`merge`).
pub fn lane_change_accel_over(width: f64, duration: f64) -> f64 {
    10.0 / 3f64.sqrt() * width.abs() / (duration * duration)
}

/// Speed bounds of eq. (15)'s constraints (m/s).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SpeedBounds {
    /// v_min.
    pub min: f64,
    /// v_max.
    pub max: f64,
}

/// Distance covered and speed reached after `t` seconds at acceleration `accel` from
/// `speed`, with the speed held within `bounds` once it reaches one.
#[inline]
pub fn advance(speed: f64, accel: f64, bounds: SpeedBounds, t: f64) -> (f64, f64) {
    let limit = if accel > 0.0 { bounds.max.max(speed) } else { bounds.min.min(speed) };
    if accel == 0.0 {
        return (speed * t, speed);
    }
    let reach = (limit - speed) / accel;
    if t <= reach {
        (speed * t + 0.5 * accel * t * t, speed + accel * t)
    } else {
        (speed * reach + 0.5 * accel * reach * reach + limit * (t - reach), limit)
    }
}

/// The predicted samples of one car holding `accel` from `now`, moving sideways along
/// `path` (time measured from `path.start` = 0 at now) or holding its offset.
pub fn predict(
    params: &PredictionParams,
    now: Kinematics,
    accel: f64,
    bounds: SpeedBounds,
    path: Option<&LateralPath>,
    out: &mut Vec<Kinematics>,
) {
    out.clear();
    for t in params.times() {
        let (ds, speed) = advance(now.speed, accel, bounds, t);
        let d = path.map_or(now.d, |p| p.offset_at(t));
        out.push(Kinematics { s: now.s + ds, d, speed });
    }
}

/// The acceleration a car can hold for one control period `dt` without leaving its
/// speed bounds: `accel` clipped so that v + a dt stays within them.
#[inline]
pub fn feasible_accel(accel: f64, speed: f64, bounds: SpeedBounds, dt: f64) -> f64 {
    let low = ((bounds.min - speed) / dt).min(0.0);
    let high = ((bounds.max - speed) / dt).max(0.0);
    accel.clamp(low, high)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::LANE_CHANGE_DURATION;

    const BOUNDS: SpeedBounds = SpeedBounds { min: 0.0, max: 25.0 };

    #[test]
    fn constant_acceleration_until_the_speed_limit() {
        // 20 m/s, +2 m/s^2: reaches 25 at 2.5 s, then cruises.
        let (ds, v) = advance(20.0, 2.0, BOUNDS, 2.0);
        assert!((ds - (40.0 + 4.0)).abs() < 1e-12 && (v - 24.0).abs() < 1e-12);
        let (ds, v) = advance(20.0, 2.0, BOUNDS, 3.0);
        assert!((ds - (20.0 * 2.5 + 0.5 * 2.0 * 6.25 + 25.0 * 0.5)).abs() < 1e-12 && v == 25.0);
        // Braking stops at v_min rather than reversing.
        let (ds, v) = advance(4.0, -4.0, BOUNDS, 3.0);
        assert!((ds - 2.0).abs() < 1e-12 && v == 0.0);
    }

    #[test]
    fn samples_follow_the_lane_change_path() {
        let params = PredictionParams::default();
        let path = LateralPath { from: 0.0, to: 4.0, start: 0.0, duration: LANE_CHANGE_DURATION };
        let mut out = Vec::new();
        predict(&params, Kinematics { s: 10.0, d: 0.0, speed: 20.0 }, 0.0, BOUNDS, Some(&path), &mut out);
        assert_eq!(out.len(), params.samples);
        assert!((out[1].s - 30.0).abs() < 1e-12 && (out[1].d - path.offset_at(1.0)).abs() < 1e-12);
        assert!(out.windows(2).all(|w| w[1].d > w[0].d));
        // The quintic's peak lateral acceleration, by finite differences.
        let h = 1e-3;
        let peak = (0..4000)
            .map(|k| k as f64 * 1e-3)
            .map(|t| (path.offset_at(t + h) - 2.0 * path.offset_at(t) + path.offset_at(t - h)).abs() / (h * h))
            .fold(0.0, f64::max);
        assert!((peak - lane_change_accel_over(4.0, LANE_CHANGE_DURATION)).abs() < 1e-3, "{peak}");
    }

    #[test]
    fn feasible_accel_keeps_the_speed_within_bounds_for_one_period() {
        assert_eq!(feasible_accel(3.0, 24.9, BOUNDS, 0.1), (25.0 - 24.9) / 0.1);
        assert_eq!(feasible_accel(-4.0, 0.2, BOUNDS, 0.1), -2.0);
        assert_eq!(feasible_accel(1.0, 20.0, BOUNDS, 0.1), 1.0);
        assert_eq!(feasible_accel(1.0, 26.0, BOUNDS, 0.1), 0.0);
    }
}
