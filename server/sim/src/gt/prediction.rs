//! Predicted motion over the decision horizon: where each car of a game will be at the
//! sample instants if it drives an acceleration (reached from its last command at the
//! jerk bound, `jerk::AccelRamp`, then held; speed kept within its bounds), and where
//! the ego car will be sideways if it changes lanes (along the same quintic path the
//! world's drivers preview). The costs of eq. (9)–(14) are averaged over these samples.

use serde::{Deserialize, Serialize};

use super::jerk::AccelRamp;
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

/// Distance covered and speed reached after `t` seconds along `ramp` from `speed`, with
/// the speed held within `bounds` while the acceleration pushes past one (as `advance`).
/// A step is `advance` at `ramp.to`.
pub fn advance_ramp(speed: f64, ramp: AccelRamp, bounds: SpeedBounds, t: f64) -> (f64, f64) {
    advance_ramp_from(speed, ramp, bounds, t, &mut None)
}

/// `advance_ramp`, remembering in `ramp_end` where the whole ramp ends (it is the same for
/// every `t` past the ramp), so that several instants of one ramp integrate it once.
fn advance_ramp_from(
    speed: f64,
    ramp: AccelRamp,
    bounds: SpeedBounds,
    t: f64,
    ramp_end: &mut Option<(f64, f64)>,
) -> (f64, f64) {
    let rise = ramp.duration().min(t);
    if rise <= 0.0 {
        return advance(speed, ramp.to, bounds, t);
    }
    if t <= rise {
        return advance_jerk(speed, ramp.from, ramp.jerk(), rise, bounds);
    }
    let (ds, v) = *ramp_end.get_or_insert_with(|| advance_jerk(speed, ramp.from, ramp.jerk(), rise, bounds));
    let (rest, v) = advance(v, ramp.to, bounds, t - rise);
    (ds + rest, v)
}

/// Distance and speed after `t` seconds from `speed` at acceleration `accel` + `jerk` * time
/// (`jerk` != 0), each stretch in which the acceleration keeps its sign held at the bound
/// it pushes towards, as `advance` holds its speed.
fn advance_jerk(speed: f64, accel: f64, jerk: f64, t: f64, bounds: SpeedBounds) -> (f64, f64) {
    let turn = -accel / jerk;
    let stretches = if turn > 0.0 && turn < t { [(0.0, turn), (turn, t)] } else { [(0.0, t), (t, t)] };
    let (mut ds, mut v) = (0.0, speed);
    for (start, end) in stretches {
        let h = end - start;
        if h <= 0.0 {
            continue;
        }
        let a = accel + jerk * start;
        let speed_at = |tau: f64| v + a * tau + 0.5 * jerk * tau * tau;
        let distance_at = |tau: f64| v * tau + 0.5 * a * tau * tau + jerk * tau * tau * tau / 6.0;
        // The sign the acceleration keeps over the stretch, from its midpoint.
        let rising = a + jerk * 0.5 * h > 0.0;
        let limit = if rising { bounds.max.max(v) } else { bounds.min.min(v) };
        let past = |tau: f64| if rising { speed_at(tau) > limit } else { speed_at(tau) < limit };
        if !past(h) {
            (ds, v) = (ds + distance_at(h), speed_at(h));
            continue;
        }
        // The speed is monotonic over the stretch: the instant it reaches the bound.
        let (mut low, mut high) = (0.0, h);
        for _ in 0..60 {
            let mid = 0.5 * (low + high);
            if past(mid) { high = mid } else { low = mid }
        }
        (ds, v) = (ds + distance_at(low) + limit * (h - low), limit);
    }
    (ds, v)
}

/// The predicted samples of one car driving `ramp` from `now`, moving sideways along
/// `path` (time measured from `path.start` = 0 at now) or holding its offset, written to
/// `out`, one per sample instant (`out` holds as many).
pub fn predict(
    params: &PredictionParams,
    now: Kinematics,
    ramp: AccelRamp,
    bounds: SpeedBounds,
    path: Option<&LateralPath>,
    out: &mut [Kinematics],
) {
    let mut ramp_end = None;
    for (t, out) in params.times().zip(out) {
        let (ds, speed) = advance_ramp_from(now.speed, ramp, bounds, t, &mut ramp_end);
        let d = path.map_or(now.d, |p| p.offset_at(t));
        *out = Kinematics { s: now.s + ds, d, speed };
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
        let mut out = vec![Kinematics::default(); params.samples];
        let now = Kinematics { s: 10.0, d: 0.0, speed: 20.0 };
        predict(&params, now, AccelRamp::step(0.0), BOUNDS, Some(&path), &mut out);
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
    fn a_ramp_covers_the_integral_of_its_acceleration() {
        // From -1 to +2 m/s^2 at 2.5 m/s^3: 1.2 s of ramp, then held. Against a fine sum
        // of a(t) dt.
        let ramp = AccelRamp { from: -1.0, to: 2.0, rate: 2.5 };
        let (dt, t) = (1e-5, 3.0);
        let (mut s, mut v) = (0.0, 20.0);
        for k in 0..(t / dt) as usize {
            let a = ramp.at((k as f64 + 0.5) * dt);
            s += v * dt + 0.5 * a * dt * dt;
            v += a * dt;
        }
        let (ds, speed) = advance_ramp(20.0, ramp, BOUNDS, t);
        assert!((ds - s).abs() < 1e-6 && (speed - v).abs() < 1e-6, "{ds} {speed} against {s} {v}");
        assert!((speed - (20.0 - 1.0 * 1.2 + 0.5 * 2.5 * 1.44 + 2.0 * 1.8)).abs() < 1e-9);
        // A step is `advance`, bit for bit.
        assert_eq!(advance_ramp(20.0, AccelRamp::step(1.5), BOUNDS, 2.0), advance(20.0, 1.5, BOUNDS, 2.0));
    }

    #[test]
    fn a_ramp_stops_at_the_speed_bounds_and_leaves_them_when_it_turns() {
        // Braking from 2 m/s down towards -4: the car stops and stays stopped.
        let brake = AccelRamp { from: 0.0, to: -4.0, rate: 2.5 };
        let (ds, v) = advance_ramp(2.0, brake, BOUNDS, 5.0);
        assert_eq!(v, 0.0);
        // Stops while the ramp is still rising: 2 = 1.25 t^2, t = 1.265 s.
        let stop = (2.0f64 / 1.25).sqrt();
        assert!((ds - (2.0 * stop - 2.5 * stop.powi(3) / 6.0)).abs() < 1e-9, "{ds}");
        // Pushing against v_max, then turning: held at 25 m/s, then slowing once a < 0.
        let turn = AccelRamp { from: 1.0, to: -1.0, rate: 2.5 };
        let (ds, v) = advance_ramp(24.99, turn, BOUNDS, 0.8);
        assert!((v - (25.0 - 0.5 * 2.5 * 0.4 * 0.4)).abs() < 1e-9, "{v}");
        assert!(ds < 25.0 * 0.8);
    }

    #[test]
    fn feasible_accel_keeps_the_speed_within_bounds_for_one_period() {
        assert_eq!(feasible_accel(3.0, 24.9, BOUNDS, 0.1), (25.0 - 24.9) / 0.1);
        assert_eq!(feasible_accel(-4.0, 0.2, BOUNDS, 0.1), -2.0);
        assert_eq!(feasible_accel(1.0, 20.0, BOUNDS, 0.1), 1.0);
        assert_eq!(feasible_accel(1.0, 26.0, BOUNDS, 0.1), 0.0);
    }
}
