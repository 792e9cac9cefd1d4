//! Background traffic: the Intelligent Driver Model for speed and MOBIL for lane
//! changes, with highway-env's default constants so `highway.toml` can be compared with
//! highway-v0, and highway-env's speed controller for learners' meta actions. These
//! drivers read the `Scene` and decide what to do; the driver + bicycle model of
//! `dynamics` does the steering, along a `LateralPath` to the chosen lane.

use serde::{Deserialize, Serialize};

use crate::road::{LaneChange, LaneId};
use crate::scene::{Car as SceneCar, Lead, Scene, Status, VehicleId};

/// IDM and MOBIL constants. Defaults are highway-env's `IDMVehicle` (1.x).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct IdmParams {
    /// a_max, maximum comfortable acceleration (m/s^2). highway-env COMFORT_ACC_MAX: 3.
    pub max_accel: f64,
    /// b, comfortable deceleration (m/s^2). highway-env -COMFORT_ACC_MIN: 5.
    pub comfortable_decel: f64,
    /// s0 less one body length: the jam gap bumper to bumper (m). highway-env
    /// DISTANCE_WANTED is 5 + the vehicle length, measured centre to centre; the length
    /// comes from `VehicleParams` (`jam_distance`).
    pub jam_gap: f64,
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
    /// Time constant of the proportional speed controller of learners' meta actions (s).
    /// highway-env ControlledVehicle KP_A = 1/0.6.
    pub speed_time_constant: f64,
}

impl IdmParams {
    /// highway-env's constants (the default).
    pub const HIGHWAY_ENV: IdmParams = IdmParams {
        max_accel: 3.0,
        comfortable_decel: 5.0,
        jam_gap: 5.0,
        time_headway: 1.5,
        exponent: 4.0,
        accel_limit: 6.0,
        politeness: 0.0,
        lane_change_gain: 0.2,
        max_imposed_braking: 2.0,
        lane_change_period: 1.0,
        speed_time_constant: 0.6,
    };

    /// s0 of IDM, centre to centre, for cars `length` long (m).
    pub fn jam_distance(&self, length: f64) -> f64 {
        self.jam_gap + length
    }
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

/// IDM's desired gap s* (centre to centre, m) of a car at `speed` behind one at
/// `leader_speed`; cars are `length` long.
fn desired_gap(params: &IdmParams, length: f64, speed: f64, leader_speed: f64) -> f64 {
    let approach = speed - leader_speed;
    params.jam_distance(length)
        + speed * params.time_headway
        + speed * approach / (2.0 * (params.max_accel * params.comfortable_decel).sqrt())
}

/// The IDM acceleration of `ego` behind `leader` (none: free road), clipped to the limit;
/// cars are `length` long.
fn idm_accel(params: &IdmParams, length: f64, ego: Car, leader: Option<Car>) -> f64 {
    let free = 1.0 - (ego.speed.max(0.0) / ego.target_speed.max(1e-3)).powf(params.exponent);
    let interaction = leader.map_or(0.0, |leader| {
        let gap = (leader.s - ego.s).max(1e-3);
        (desired_gap(params, length, ego.speed, leader.speed) / gap).powi(2)
    });
    (params.max_accel * (free - interaction)).clamp(-params.accel_limit, params.accel_limit)
}

/// The cars around a candidate lane: the nearest ahead and behind.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Gap {
    /// The nearest car ahead, if any (a lane end counts as a stopped car).
    pub leader: Option<Car>,
    /// The nearest car behind, if any.
    pub follower: Option<Car>,
}

/// MOBIL: the incentive of moving `ego` from `current` to `target`, or `None` when the
/// change is unsafe (the new follower would brake harder than b_safe, or the cars would
/// overlap). The caller changes lanes when the incentive exceeds `lane_change_gain`.
fn mobil_incentive(params: &IdmParams, ego: Car, length: f64, current: Gap, target: Gap) -> Option<f64> {
    let overlaps = |other: Option<Car>| other.is_some_and(|other| (other.s - ego.s).abs() < length);
    if overlaps(target.leader) || overlaps(target.follower) {
        return None;
    }
    let new_follower_gain = match target.follower {
        Some(follower) => {
            let after = idm_accel(params, length, follower, Some(ego));
            if after < -params.max_imposed_braking {
                return None;
            }
            after - idm_accel(params, length, follower, target.leader)
        }
        None => 0.0,
    };
    let old_follower_gain = current.follower.map_or(0.0, |follower| {
        idm_accel(params, length, follower, current.leader) - idm_accel(params, length, follower, Some(ego))
    });
    let own_gain = idm_accel(params, length, ego, target.leader) - idm_accel(params, length, ego, current.leader);
    Some(own_gain + params.politeness * (new_follower_gain + old_follower_gain))
}

/// What an IDM + MOBIL car does in the coming control period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdmDecision {
    /// Its acceleration (m/s^2).
    pub accel: f64,
    /// A lane change MOBIL starts now.
    pub change_to: Option<LaneId>,
    /// Whether MOBIL was consulted (it is, once per `lane_change_period`).
    pub consulted: bool,
}

impl Car {
    fn of(car: &SceneCar) -> Car {
        Car { s: car.state.s, speed: car.speed(), target_speed: car.target_speed }
    }

    fn lead(lead: Lead) -> Car {
        Car { s: lead.s, speed: lead.speed, target_speed: lead.speed }
    }
}

/// The car ahead (or the lane's end) and the car behind position `s` in `lane`.
fn gap(scene: &Scene, lane: LaneId, s: f64, id: VehicleId) -> Gap {
    Gap { leader: scene.leader(lane, s, &[id]).map(Car::lead), follower: scene.behind(lane, s, &[id]).map(Car::of) }
}

/// The IDM + MOBIL driver of car `id`: MOBIL if `may_change_lanes` (its last lane
/// change is done and `lane_change_period` has passed since MOBIL was last consulted)
/// and it is in its target lane, then IDM behind the nearest leader of every lane it
/// occupies.
pub fn decide(params: &IdmParams, scene: &Scene, id: VehicleId, may_change_lanes: bool) -> IdmDecision {
    let car = scene.car(id);
    let consulted = may_change_lanes && car.target_lane == car.lane;
    let change_to = if consulted { mobil(params, scene, car) } else { yield_lane(params, scene, car) };
    let length = scene.vehicle.length;
    let ego = Car::of(car);
    let mut accel = idm_accel(params, length, ego, gap(scene, car.lane, ego.s, id).leader);
    let target = change_to.unwrap_or(car.target_lane);
    if target != car.lane {
        accel = accel.min(idm_accel(params, length, ego, gap(scene, target, ego.s, id).leader));
    }
    IdmDecision { accel, change_to, consulted }
}

/// MOBIL over both neighbouring lanes: the one with the largest incentive above the
/// threshold, if any, among those `Road::worth_entering`.
fn mobil(params: &IdmParams, scene: &Scene, car: &SceneCar) -> Option<LaneId> {
    let ego = Car::of(car);
    let here = gap(scene, car.lane, ego.s, car.id);
    let mut best: Option<(f64, LaneId)> = None;
    for side in [LaneChange::Left, LaneChange::Right] {
        let Some(lane) = scene.lane_beside(car.lane, side) else { continue };
        if !scene.road.worth_entering(car.lane, lane) {
            continue;
        }
        let there = gap(scene, lane, ego.s, car.id);
        let incentive = mobil_incentive(params, ego, scene.vehicle.length, here, there);
        if let Some(incentive) = incentive.filter(|&g| g >= params.lane_change_gain)
            && best.is_none_or(|(g, _)| incentive > g)
        {
            best = Some((incentive, lane));
        }
    }
    best.map(|(_, lane)| lane)
}

/// The lane car `car` returns to when another car is changing into the lane it is
/// changing into, from the lane on its other side, and is ahead of it (of two abreast, the
/// one with the larger id) by less than IDM's desired gap s*: the one behind gives way, so
/// the two do not meet side by side in the lane between them. MOBIL decides at the same
/// instant for every car, from where the others were, so each checked its own change
/// against a lane that was free. None while it is in its own lane or already across the
/// line. highway-env's `IDMVehicle.change_lane_policy` aborts the same way (it also
/// yields to a car ahead changing from its own lane, which it follows anyway).
fn yield_lane(params: &IdmParams, scene: &Scene, car: &SceneCar) -> Option<LaneId> {
    let (lane, target) = (car.lane, car.target_lane);
    if lane == target {
        return None;
    }
    let (s, speed, length) = (car.state.s, car.speed(), scene.vehicle.length);
    // No s* is longer than the one behind a standing car.
    let reach = desired_gap(params, length, speed, 0.0);
    let conflict = scene.around(s, reach).any(|other| {
        other.status == Status::Driving
            && other.target_lane == target
            && other.lane != target
            && other.lane != lane
            && (other.state.s, other.id) > (s, car.id)
            && other.state.s - s < desired_gap(params, length, speed, other.speed())
    });
    conflict.then_some(lane)
}

/// highway-env's proportional speed controller for learners' meta actions: towards the
/// target speed, within the acceleration limit.
pub fn track_speed(params: &IdmParams, car: &SceneCar) -> f64 {
    speed_control(params, car.target_speed, car.state.vx)
}

/// The acceleration `track_speed` commands at `speed` for `target_speed`.
pub fn speed_control(params: &IdmParams, target_speed: f64, speed: f64) -> f64 {
    let limit = params.accel_limit;
    ((target_speed - speed) / params.speed_time_constant).clamp(-limit, limit)
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: IdmParams = IdmParams::HIGHWAY_ENV;
    const LENGTH: f64 = 5.0;

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
            d.jam_gap,
            d.time_headway,
            d.exponent,
            d.accel_limit,
            d.politeness,
            d.lane_change_gain,
            d.max_imposed_braking,
            d.lane_change_period,
        ];
        assert_eq!(values, [3.0, 5.0, 5.0, 1.5, 4.0, 6.0, 0.0, 0.2, 2.0, 1.0]);
        assert_eq!(d.speed_time_constant, 0.6);
    }

    #[test]
    fn jam_distance_is_the_jam_gap_plus_the_body_length_of_the_vehicle_parameters() {
        // highway-env: DISTANCE_WANTED = 5 + Vehicle.LENGTH, with LENGTH = 5 and WIDTH = 2.
        let body = crate::dynamics::VehicleParams::default();
        assert_eq!((body.length, body.width), (5.0, 2.0));
        assert_eq!(P.jam_distance(body.length), 10.0);
        assert_eq!(P.jam_distance(7.0), 12.0);
    }

    #[test]
    fn idm_free_road_and_following() {
        assert!((idm_accel(&P, LENGTH, car(0.0, 0.0), None) - 3.0).abs() < 1e-12);
        assert!(idm_accel(&P, LENGTH, car(0.0, 25.0), None).abs() < 1e-12);
        // At the equilibrium gap s* behind an equally fast car, free and interaction cancel.
        let close = idm_accel(&P, LENGTH, car(0.0, 20.0), Some(car(25.0, 20.0)));
        assert!(close < -3.0, "{close}");
        assert_eq!(idm_accel(&P, LENGTH, car(0.0, 30.0), Some(car(10.5, 0.0))), -6.0);
    }

    #[test]
    fn mobil_changes_away_from_a_slow_leader_but_not_into_a_close_follower() {
        let ego = car(0.0, 25.0);
        let current = Gap { leader: Some(car(30.0, 10.0)), follower: None };
        let free = Gap::default();
        assert!(mobil_incentive(&P, ego, LENGTH, current, free).unwrap() > P.lane_change_gain);
        let tailgater = Gap { leader: None, follower: Some(car(-12.0, 30.0)) };
        assert_eq!(mobil_incentive(&P, ego, LENGTH, current, tailgater), None);
        let beside = Gap { leader: Some(car(3.0, 25.0)), follower: None };
        assert_eq!(mobil_incentive(&P, ego, LENGTH, current, beside), None);
    }
}
