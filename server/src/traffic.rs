//! Background traffic: the Intelligent Driver Model for speed and MOBIL for lane
//! changes, with highway-env's default constants so `highway.toml` can be compared with
//! highway-v0. These drivers decide what to do; the driver + bicycle model of `dynamics`
//! does the steering, along a `LateralPath` to the chosen lane.

use serde::{Deserialize, Serialize};

/// IDM and MOBIL constants. Defaults are highway-env's `IDMVehicle` (1.x).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct IdmParams {
    /// a_max, maximum comfortable acceleration (m/s^2). highway-env COMFORT_ACC_MAX: 3.
    pub max_accel: f64,
    /// b, comfortable deceleration (m/s^2). highway-env -COMFORT_ACC_MIN: 5.
    pub comfortable_decel: f64,
    /// s0, jam distance measured centre to centre (m). highway-env DISTANCE_WANTED:
    /// 5 + vehicle length 5 = 10.
    pub jam_distance: f64,
    /// T, desired time headway (s). highway-env TIME_WANTED: 1.5.
    pub time_headway: f64,
    /// delta, the free-road exponent. highway-env DELTA: 4.
    pub exponent: f64,
    /// Bound on |a_x| a background car may command (m/s^2). highway-env ACC_MAX: 6.
    pub accel_limit: f64,
    /// p, MOBIL politeness. highway-env POLITENESS: 0.
    pub politeness: f64,
    /// a_th, MOBIL's minimum acceleration gain to change lanes (m/s^2).
    /// highway-env LANE_CHANGE_MIN_ACC_GAIN: 0.2.
    pub lane_change_gain: f64,
    /// b_safe, the largest braking a lane change may impose on the new follower (m/s^2).
    /// highway-env LANE_CHANGE_MAX_BRAKING_IMPOSED: 2.
    pub max_imposed_braking: f64,
    /// How often MOBIL is consulted (s). highway-env LANE_CHANGE_DELAY: 1.
    pub lane_change_period: f64,
    /// Duration of the quintic lateral path of one lane change (s). 4, chosen here
    /// (DESIGN.md: a 4 s path settles every style at 15–30 m/s).
    pub lane_change_duration: f64,
}

impl IdmParams {
    /// highway-env's constants (the default).
    pub const HIGHWAY_ENV: IdmParams = IdmParams {
        max_accel: 3.0,
        comfortable_decel: 5.0,
        jam_distance: 10.0,
        time_headway: 1.5,
        exponent: 4.0,
        accel_limit: 6.0,
        politeness: 0.0,
        lane_change_gain: 0.2,
        max_imposed_braking: 2.0,
        lane_change_period: 1.0,
        lane_change_duration: 4.0,
    };
}

impl Default for IdmParams {
    fn default() -> Self {
        IdmParams::HIGHWAY_ENV
    }
}

/// What IDM needs to know of a car: where it is, how fast it goes and wants to go.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Car {
    /// Position along the road (m).
    pub s: f64,
    /// Speed along the road (m/s).
    pub speed: f64,
    /// The speed its driver aims for (m/s).
    pub target_speed: f64,
}

/// The IDM acceleration of `ego` behind `leader` (none: free road), clipped to the limit.
pub fn idm_accel(params: &IdmParams, ego: Car, leader: Option<Car>) -> f64 {
    let free = 1.0 - (ego.speed.max(0.0) / ego.target_speed.max(1e-3)).powf(params.exponent);
    let interaction = leader.map_or(0.0, |leader| {
        let gap = (leader.s - ego.s).max(1e-3);
        let approach = ego.speed - leader.speed;
        let desired = params.jam_distance
            + ego.speed * params.time_headway
            + ego.speed * approach / (2.0 * (params.max_accel * params.comfortable_decel).sqrt());
        (desired / gap).powi(2)
    });
    (params.max_accel * (free - interaction)).clamp(-params.accel_limit, params.accel_limit)
}

/// The cars around a candidate lane: the nearest ahead and behind.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Gap {
    /// The nearest car ahead, if any (a lane end counts as a stopped car).
    pub leader: Option<Car>,
    /// The nearest car behind, if any.
    pub follower: Option<Car>,
}

/// MOBIL: the incentive of moving `ego` from `current` to `target`, or `None` when the
/// change is unsafe (the new follower would brake harder than b_safe, or the cars would
/// overlap). The caller changes lanes when the incentive exceeds `lane_change_gain`.
pub fn mobil_incentive(params: &IdmParams, ego: Car, length: f64, current: Gap, target: Gap) -> Option<f64> {
    let overlaps = |other: Option<Car>| other.is_some_and(|other| (other.s - ego.s).abs() < length);
    if overlaps(target.leader) || overlaps(target.follower) {
        return None;
    }
    let new_follower_gain = match target.follower {
        Some(follower) => {
            let after = idm_accel(params, follower, Some(ego));
            if after < -params.max_imposed_braking {
                return None;
            }
            after - idm_accel(params, follower, target.leader)
        }
        None => 0.0,
    };
    let old_follower_gain = current
        .follower
        .map_or(0.0, |follower| idm_accel(params, follower, current.leader) - idm_accel(params, follower, Some(ego)));
    let own_gain = idm_accel(params, ego, target.leader) - idm_accel(params, ego, current.leader);
    Some(own_gain + params.politeness * (new_follower_gain + old_follower_gain))
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: IdmParams = IdmParams::HIGHWAY_ENV;

    fn car(s: f64, speed: f64) -> Car {
        Car { s, speed, target_speed: 25.0 }
    }

    #[test]
    fn defaults_are_highway_envs() {
        // highway-env 1.x IDMVehicle: COMFORT_ACC_MAX, -COMFORT_ACC_MIN, DISTANCE_WANTED,
        // TIME_WANTED, DELTA, ACC_MAX, POLITENESS, LANE_CHANGE_MIN_ACC_GAIN,
        // LANE_CHANGE_MAX_BRAKING_IMPOSED, LANE_CHANGE_DELAY.
        let d = IdmParams::default();
        let values = [
            d.max_accel,
            d.comfortable_decel,
            d.jam_distance,
            d.time_headway,
            d.exponent,
            d.accel_limit,
            d.politeness,
            d.lane_change_gain,
            d.max_imposed_braking,
            d.lane_change_period,
        ];
        assert_eq!(values, [3.0, 5.0, 10.0, 1.5, 4.0, 6.0, 0.0, 0.2, 2.0, 1.0]);
    }

    #[test]
    fn idm_free_road_and_following() {
        assert!((idm_accel(&P, car(0.0, 0.0), None) - 3.0).abs() < 1e-12);
        assert!(idm_accel(&P, car(0.0, 25.0), None).abs() < 1e-12);
        // At the equilibrium gap s* behind an equally fast car, free and interaction cancel.
        let close = idm_accel(&P, car(0.0, 20.0), Some(car(25.0, 20.0)));
        assert!(close < -3.0, "{close}");
        assert_eq!(idm_accel(&P, car(0.0, 30.0), Some(car(10.5, 0.0))), -6.0);
    }

    #[test]
    fn mobil_changes_away_from_a_slow_leader_but_not_into_a_close_follower() {
        let ego = car(0.0, 25.0);
        let current = Gap { leader: Some(car(30.0, 10.0)), follower: None };
        let free = Gap::default();
        assert!(mobil_incentive(&P, ego, 5.0, current, free).unwrap() > P.lane_change_gain);
        let tailgater = Gap { leader: None, follower: Some(car(-12.0, 30.0)) };
        assert_eq!(mobil_incentive(&P, ego, 5.0, current, tailgater), None);
        let beside = Gap { leader: Some(car(3.0, 25.0)), follower: None };
        assert_eq!(mobil_incentive(&P, ego, 5.0, current, beside), None);
    }
}
