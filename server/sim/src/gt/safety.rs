//! The safety layer (docs/design.md, "Safety layer"): an override of the acceleration a
//! `gt` car's game decided, outside the games (their action grid stays as it is). It owns
//! which cars count as ahead of the AV (the car ahead in every lane its body is in or its
//! lane change goes to, and cars cutting in: changing into one of those lanes or moving
//! sideways into one), RSS's safe longitudinal distance to each (Shalev-Shwartz et al.
//! 2017, "On a Formal Model of Safe and Scalable Self-driving Cars", Definition 1) and the
//! cap on the acceleration that keeps it, and the emergency braking, harder than the
//! games' a_min, when a collision is otherwise certain. `driver::plan` applies it after
//! the games decide and before the MPC plans; it only ever lowers the acceleration.

use serde::{Deserialize, Serialize};

use super::merge;
use crate::road::LaneId;
use crate::scene::{Car, Scene, VehicleId};

/// The constants of the safety layer.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SafetyParams {
    /// Whether the layer acts. true; false is the AV before issue 24 (the games' own
    /// acceleration, never below their a_min), for comparisons.
    pub enabled: bool,
    /// rho, the AV's response time of RSS (s): how long the acceleration it picks holds
    /// before it brakes. 0.1: the control period, after which it decides again (its
    /// commands act at once).
    pub response_time: f64,
    /// a_min,brake of RSS (m/s^2): the braking the AV counts on after the response time,
    /// at most `emergency_brake`. 8: its emergency braking, which it applies when the car
    /// ahead brakes so that the games' a_min would not stop it. (6 would be the hardest
    /// braking of the other cars, and acts in the paper's Scenario B: docs/design.md.)
    pub brake: f64,
    /// a_max,brake of RSS (m/s^2): the hardest the car ahead may brake. 6: IDM's limit
    /// and a wreck's braking, the hardest of this world (a learner's continuous actions
    /// span the same 6).
    pub lead_brake: f64,
    /// The hardest the AV brakes when a collision is otherwise certain (m/s^2). 8, chosen
    /// here: about 0.8 g, a passenger car's full braking on dry asphalt and a usual
    /// a_max,brake of RSS; the vehicle model has no friction limit on a_x.
    pub emergency_brake: f64,
    /// The bumper-to-bumper gap (m) RSS's distance is stretched by, and emergency braking
    /// stops short by. 1, chosen here.
    pub margin: f64,
    /// A car whose body, moving sideways at its lateral speed, reaches into one of the
    /// AV's lanes within this time (s) counts as in that lane. 1, chosen here: a quarter of
    /// a lane change, which crosses the line after 2 s. A car moving sideways towards the
    /// centre of its own target lane (settling into it) is projected no farther than it.
    pub cut_in_time: f64,
    /// mu of RSS's lateral safe distance (m): a car in a lane the AV leaves stops counting
    /// once the AV's body is this far beside its body (as far as that reaches within
    /// `cut_in_time`), even before the AV is out of the lane. 0.5, chosen here: an eighth
    /// of a lane, more than the driver model's overshoot of a steady preview point.
    pub lateral_margin: f64,
    /// The hardest braking (m/s^2) a gap may ask of anyone (the AV behind the car ahead,
    /// the car behind the AV) for the AV to start a lane change into it on the open road
    /// (`gap_braking`). 2: MOBIL's b_safe, the braking a lane change may impose on the new
    /// follower (`IdmParams::max_imposed_braking`), so the AV asks no more than the
    /// traffic does. Out of an ending lane the bound is the games' firmest braking (-a_min)
    /// instead (`driver::gap_open`). A change under way is given up when its gap asks more
    /// than -a_min and the lane it leaves asks less.
    pub gap_braking: f64,
    /// RSS's response time (s) of the car behind the gap the AV starts a lane change into
    /// on the open road: the AV enters only where that car, holding its command (if it
    /// speeds up) this long and then braking at `lead_brake`, stays `margin` behind the AV
    /// braking as hard; at equal speeds that is this time headway, behind a slower car
    /// less. 1: the responsibility rule's response time (`world::BLAME_RESPONSE_TIME`), so
    /// the AV enters no gap that rule would call too close and be at fault for.
    pub follower_response: f64,
}

impl Default for SafetyParams {
    fn default() -> Self {
        SafetyParams {
            enabled: true,
            response_time: 0.1,
            brake: 8.0,
            lead_brake: 6.0,
            emergency_brake: 8.0,
            margin: 1.0,
            cut_in_time: 1.0,
            lateral_margin: 0.5,
            gap_braking: 2.0,
            follower_response: 1.0,
        }
    }
}

/// Why the layer lowered the acceleration, and to what.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SafetyOverride {
    /// The acceleration it applies (m/s^2).
    pub accel: f64,
    /// What the game decided (m/s^2).
    pub decided: f64,
    /// The car it keeps its distance to.
    pub car: VehicleId,
    /// Whether it brakes harder than the games' a_min (an emergency).
    pub emergency: bool,
}

/// What the AV does this period, as `driver::plan` decided it before the layer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intent {
    /// The lane it is in or changing to.
    pub target: LaneId,
    /// The full-width duration of its lane change (s): `LANE_CHANGE_DURATION`, or shorter
    /// out of an ending lane (`merge`).
    pub pace: f64,
    /// How long after its quintic path the MPC-driven car gets there (s): `merge`'s
    /// measured response lag.
    pub lag: f64,
    /// The game's acceleration (m/s^2).
    pub accel: f64,
    /// The games' hardest braking, -a_min (m/s^2): the layer brakes harder only in an
    /// emergency.
    pub firm: f64,
    /// How long the command takes from the game's acceleration down to -`firm` at the
    /// jerk bound (s; 0 without it): braking that starts as a ramp covers, until it is
    /// full, about what holding the acceleration half that time would.
    pub ramp_time: f64,
}

/// Distance (m) covered and speed (m/s) reached in `t` s from `speed` at `accel`, stopping
/// at 0 (cars do not reverse).
fn travel(speed: f64, accel: f64, t: f64) -> (f64, f64) {
    if accel < 0.0 && speed + accel * t < 0.0 {
        return (speed * speed / (-2.0 * accel), 0.0);
    }
    (speed * t + 0.5 * accel * t * t, speed + accel * t)
}

/// How a car moves: holding `accel` for `hold` s from `speed`, then braking at `brake`
/// (> 0) to a stop.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Braking {
    speed: f64,
    accel: f64,
    hold: f64,
    brake: f64,
}

impl Braking {
    /// Distance covered after `t` s (m).
    fn distance(&self, t: f64) -> f64 {
        if t <= self.hold {
            return travel(self.speed, self.accel, t).0;
        }
        let (held, speed) = travel(self.speed, self.accel, self.hold);
        held + travel(speed, -self.brake, t - self.hold).0
    }

    /// Speed after the hold (m/s).
    fn after_hold(&self) -> f64 {
        travel(self.speed, self.accel, self.hold).1
    }

    /// When it has stopped (s from now; infinite if it never brakes).
    fn stops(&self) -> f64 {
        if self.accel < 0.0 && self.speed + self.accel * self.hold <= 0.0 {
            return self.speed / -self.accel;
        }
        self.hold + self.after_hold() / self.brake
    }
}

/// The least bumper gap (m) over the next `horizon` s between a car moving as `rear` and
/// one `gap` m ahead of it braking from `lead_speed` at `lead_brake` (>= 0) to a stop.
/// The gap is piecewise quadratic in time: its least is at an end of a piece (the hold's
/// end, a stop, the horizon) or where the two speeds meet.
fn least_gap(rear: Braking, lead_speed: f64, lead_brake: f64, gap: f64, horizon: f64) -> f64 {
    let lead = |t: f64| travel(lead_speed, -lead_brake, t).0;
    let at = |t: f64| gap + lead(t) - rear.distance(t);
    let lead_stops = if lead_brake > 0.0 { lead_speed / lead_brake } else { f64::INFINITY };
    // Speeds meet during the hold: v + a t = u - b_lead t; after it: v_h - b (t - h) = u - b_lead t.
    let during = (lead_speed - rear.speed) / (rear.accel + lead_brake);
    let after = (rear.after_hold() + rear.brake * rear.hold - lead_speed) / (rear.brake - lead_brake);
    [0.0, rear.hold, rear.stops(), lead_stops, during, after, horizon]
        .into_iter()
        .filter(|t| t.is_finite() && *t >= 0.0 && *t <= horizon)
        .map(at)
        .fold(f64::INFINITY, f64::min)
}

/// The bumper gap (m) to keep to a car `gap` m ahead: the margin, or, already within it
/// (a car that just cut in, or one beside that pulls ahead), the gap as it is: no
/// response undoes the present, and one pulling away leaves nothing to answer.
fn kept(gap: f64, params: &SafetyParams) -> f64 {
    params.margin.min(gap)
}

/// The largest acceleration in [`floor`, `accel`] that a car at `speed` may hold for the
/// response time and, braking at a_min,brake after it, still keep `kept` to a car `gap`
/// m ahead at `lead_speed` braking at a_max,brake, over the next `horizon` s: RSS's safe
/// distance (Definition 1) as the least gap over time. `floor` when none does.
pub fn safe_accel(
    speed: f64,
    accel: f64,
    floor: f64,
    (lead_speed, gap, horizon): (f64, f64, f64),
    params: &SafetyParams,
) -> f64 {
    largest(accel, floor, |a| {
        let rear = Braking { speed, accel: a, hold: params.response_time, brake: params.brake };
        least_gap(rear, lead_speed, params.lead_brake, gap, horizon) >= kept(gap, params)
    })
}

/// The largest acceleration in [`floor`, `accel`] that a car at `speed` may hold for
/// `hold` s and, braking at -`floor` (the games' firmest) after it, still stop `standoff`
/// short of a car `gap` m ahead at `lead_speed` that holds its braking `lead_brake` (>= 0),
/// over the next `horizon` s. RSS's distance counts on the AV's emergency braking, so
/// alone it answers a car ahead that brakes hard now only once the games' firmest no
/// longer suffices (a spawned queue braking at 6 m/s^2 met at -6.2 two seconds later);
/// this answers it while the firmest still does. `floor` when none does.
pub fn anticipating_accel(
    speed: f64,
    (accel, floor, hold): (f64, f64, f64),
    (lead_speed, lead_brake, gap, horizon): (f64, f64, f64, f64),
    params: &SafetyParams,
) -> f64 {
    largest(accel, floor, |a| {
        let rear = Braking { speed, accel: a, hold, brake: -floor };
        least_gap(rear, lead_speed, lead_brake, gap, horizon) >= standoff(gap, params)
    })
}

/// The largest acceleration in [`floor`, `accel`] that `keeps`; `floor` when none does.
/// Every instant's gap shrinks as the acceleration grows: bisection finds it.
fn largest(accel: f64, floor: f64, keeps: impl Fn(f64) -> bool) -> f64 {
    if accel <= floor || keeps(accel) {
        return accel.max(floor);
    }
    if !keeps(floor) {
        return floor;
    }
    super::bisect(floor, accel, keeps).0
}

/// How far short of a car `gap` m ahead emergency braking stops: the margin, but at most
/// half the gap left. Within the margin RSS's proper response is braking at a_min,brake
/// (the games' firmest); giving up none of a gap already short (`kept`) made a car
/// creeping up a queue stop at 8 m/s^2 for a few centimetres.
fn standoff(gap: f64, params: &SafetyParams) -> f64 {
    params.margin.min(gap / 2.0)
}

/// The braking (m/s^2, more than `firm`, at most the emergency braking) that keeps a car
/// at `speed` `standoff` short of a car `gap` m ahead at `lead_speed` holding its braking
/// `lead_brake` (>= 0) over the next `horizon` s, if braking at `firm` would not.
pub fn emergency_brake(
    speed: f64,
    firm: f64,
    (lead_speed, lead_brake, gap, horizon): (f64, f64, f64, f64),
    params: &SafetyParams,
) -> Option<f64> {
    let short = |brake: f64| {
        let rear = Braking { speed, accel: -brake, hold: 0.0, brake };
        least_gap(rear, lead_speed, lead_brake, gap, horizon) < standoff(gap, params)
    };
    if !short(firm) {
        return None;
    }
    if short(params.emergency_brake) {
        return Some(params.emergency_brake);
    }
    Some(super::bisect(firm, params.emergency_brake, short).1)
}

/// The lanes car `me` takes up: the one it is in, the one its lane change goes to, and any
/// other its body reaches into.
fn lanes_taken(scene: &Scene, me: &Car, target: LaneId) -> Vec<LaneId> {
    let road = &scene.road;
    let reach = (road.lane_width() + scene.vehicle.width) / 2.0;
    let mut lanes = vec![me.lane, target];
    lanes.extend(
        (0..road.lane_count() as u32).map(LaneId).filter(|&lane| (me.state.d - road.lane_center(lane)).abs() < reach),
    );
    lanes.sort();
    lanes.dedup();
    lanes
}

/// Whether `other` is in one of `lanes`, is changing into one, or its body reaches into
/// one within the cut-in time at its lateral speed.
fn in_lanes(scene: &Scene, other: &Car, lanes: &[LaneId], params: &SafetyParams) -> bool {
    lanes.contains(&other.target_lane) || in_lanes_by_body(scene, other, lanes, params)
}

/// Whether `other` is in one of `lanes` by position, or its body reaches into one within
/// the cut-in time at its lateral speed: for the lanes the AV leaves, which it shares
/// for less than a lane change, a car two lanes over that has only decided to change into
/// one is not there yet.
fn in_lanes_by_body(scene: &Scene, other: &Car, lanes: &[LaneId], params: &SafetyParams) -> bool {
    if lanes.contains(&other.lane) {
        return true;
    }
    let road = &scene.road;
    let (now, later) = reach(scene, other, params);
    let half = scene.vehicle.width / 2.0;
    let (low, high) = (now.min(later) - half, now.max(later) + half);
    let half_lane = road.lane_width() / 2.0;
    lanes.iter().any(|&lane| {
        let centre = road.lane_center(lane);
        low < centre + half_lane && high > centre - half_lane
    })
}

/// Whether car `other` is beside car `me`, not ahead: level with it along the road, its
/// body (as far as it reaches within the cut-in time) more than `lateral_margin` beside
/// `me`'s. No braking answers a car beside (at -8 m/s^2 the AV only fell back level with a
/// slower one); a lane change towards it is given up instead (`driver::gives_up`).
fn beside(scene: &Scene, me: &Car, other: &Car, params: &SafetyParams) -> bool {
    let (now, later) = reach(scene, other, params);
    let apart = (now - me.state.d).abs().min((later - me.state.d).abs());
    other.state.s - me.state.s < scene.vehicle.length && apart >= scene.vehicle.width + params.lateral_margin
}

/// Where car `other`'s centre is sideways now and where it gets within the cut-in time at
/// its lateral speed (`settling` into its target lane).
fn reach(scene: &Scene, other: &Car, params: &SafetyParams) -> (f64, f64) {
    let state = &other.state;
    let lateral_speed = state.vx * state.heading.sin() + state.vy * state.heading.cos();
    let target = scene.road.lane_center(other.target_lane);
    (state.d, settling(state.d + lateral_speed * params.cut_in_time, state.d, target))
}

/// Where a car at offset `now` moving sideways reaches `later` when it aims at `centre`
/// (its target lane's): settling into its lane it stops at the centre; moving away from
/// it (drifting, or a learner's steering) it goes on. Relative to its own lane, not the
/// AV's: a car finishing a change next to the AV is not cutting in.
fn settling(later: f64, now: f64, centre: f64) -> f64 {
    let towards = (centre - now) * (later - now) > 0.0;
    if towards && (later - now).abs() > (centre - now).abs() { centre } else { later }
}

/// The braking (m/s^2) a car at `speed`, holding `accel` for the response time, needs to
/// keep `kept` behind a car `gap` m ahead at `lead_speed` holding its braking `lead_brake`
/// (>= 0): 0 if it need not brake, infinite if not even the emergency braking does.
pub(super) fn braking_needed(
    (speed, accel): (f64, f64),
    (lead_speed, lead_brake, gap): (f64, f64, f64),
    params: &SafetyParams,
) -> f64 {
    let keeps = |brake: f64| {
        let rear = Braking { speed, accel, hold: params.response_time, brake };
        least_gap(rear, lead_speed, lead_brake, gap, f64::INFINITY) >= kept(gap, params)
    };
    let brake = |brake: f64| keeps(brake.max(1e-9));
    if brake(0.0) {
        return 0.0;
    }
    if !brake(params.emergency_brake) {
        return f64::INFINITY;
    }
    super::bisect(0.0, params.emergency_brake, |b| !brake(b)).1
}

/// The hardest braking (m/s^2) that car `id` being in `lane` now asks of anyone: of `id`,
/// to keep its distance behind the car ahead there, or of the car behind there, to keep
/// its distance behind `id` (each from its own speed and command, the car ahead holding
/// its braking). What a lane change into `lane` costs the traffic (`driver`).
pub(super) fn gap_braking(scene: &Scene, id: VehicleId, lane: LaneId, params: &SafetyParams) -> f64 {
    let me = scene.car(id);
    let length = scene.vehicle.length;
    let needed = |rear: &Car, front: &Car| {
        let gap = (front.state.s - rear.state.s - length).max(0.0);
        let lead = (front.speed().max(0.0), (-front.accel).max(0.0), gap);
        braking_needed((rear.speed().max(0.0), rear.accel), lead, params)
    };
    let ahead = scene.ahead(lane, me.state.s, &[id]).map_or(0.0, |front| needed(me, front));
    let behind = scene.behind(lane, me.state.s, &[id]).map_or(0.0, |rear| needed(rear, me));
    ahead.max(behind)
}

/// Whether the car behind car `id` in `lane`, if any, keeps RSS's distance to it with the
/// response time `follower_response`, both then braking at `lead_brake`.
pub(super) fn follower_keeps_distance(scene: &Scene, id: VehicleId, lane: LaneId, params: &SafetyParams) -> bool {
    let me = scene.car(id);
    scene.behind(lane, me.state.s, &[id]).is_none_or(|rear| {
        let gap = me.state.s - rear.state.s - scene.vehicle.length;
        let braking = Braking {
            speed: rear.speed().max(0.0),
            accel: rear.accel.max(0.0),
            hold: params.follower_response,
            brake: params.lead_brake,
        };
        gap > 0.0 && least_gap(braking, me.speed().max(0.0), params.lead_brake, gap, f64::INFINITY) >= params.margin
    })
}

/// Seconds until the body of car `me`, changing lanes at full-width duration `pace`, no
/// longer shares `lane` (which it leaves) with car `other` there: until it is out of the
/// lane (half a lane plus half a body across) or, sooner, `lateral_margin` clear of
/// `other`'s body where that reaches within the cut-in time (RSS's lateral safe
/// distance, Definition 6, with its margin mu: two cars apart sideways by more are not in
/// danger, however close along the road). What is left of the quintic path to there at
/// the phase the offset shows, plus the lag for the part still to go (as `merge` times a
/// crossing); 0 when it is there already.
fn time_clear_of(scene: &Scene, me: &Car, lane: LaneId, other: &Car, intent: &Intent, params: &SafetyParams) -> f64 {
    let road = &scene.road;
    let (width, body) = (road.lane_width(), scene.vehicle.width);
    let from = road.lane_center(lane);
    let away = match me.state.d - from {
        off if off.abs() > 1e-9 => off.signum(),
        _ => (road.lane_center(intent.target) - from).signum(),
    };
    let out = (width + body) / (2.0 * width);
    // The side of `other`'s reach nearest the AV, in lane widths from the lane's centre.
    let (now, later) = reach(scene, other, params);
    let nearest = away * (if away > 0.0 { now.max(later) } else { now.min(later) } - from) / width;
    let clear = out.min(nearest + (body + params.lateral_margin) / width);
    let done = (away * (me.state.d - from) / width).clamp(0.0, out);
    if done >= clear {
        return 0.0;
    }
    (merge::phase(clear) - merge::phase(done)) * intent.pace + intent.lag * (1.0 - done / clear)
}

/// The acceleration the layer lets car `id` apply instead of the game's, when it is lower.
/// Every car ahead in a lane it takes up counts; one that is only in the lane it leaves,
/// until it has left it.
pub fn limit(scene: &Scene, id: VehicleId, intent: &Intent, params: &SafetyParams) -> Option<SafetyOverride> {
    if !params.enabled {
        return None;
    }
    let me = scene.car(id);
    let speed = me.speed().max(0.0);
    let taken = lanes_taken(scene, me, intent.target);
    let leaving: Vec<LaneId> = taken.iter().copied().filter(|&lane| lane != intent.target).collect();
    let length = scene.vehicle.length;
    // Farther ahead than this, even a stopped car is beyond RSS's distance and beyond
    // what the games' firmest braking needs after the early response's hold.
    let hold = params.response_time + intent.ramp_time / 2.0;
    let (_, fastest) = travel(speed, intent.accel.max(0.0), hold);
    let brake = params.brake.min(intent.firm);
    let range = speed * hold + fastest * fastest / (2.0 * brake) + params.margin + length;
    let mut lowest: Option<SafetyOverride> = None;
    for other in scene.around(me.state.s, range) {
        if other.id == id || other.state.s <= me.state.s {
            continue;
        }
        let horizon = if beside(scene, me, other, params) {
            continue;
        } else if in_lanes(scene, other, &[intent.target], params) {
            f64::INFINITY
        } else if in_lanes_by_body(scene, other, &leaving, params) {
            let shared = leaving.iter().filter(|&&lane| in_lanes_by_body(scene, other, &[lane], params));
            let until_clear =
                shared.map(|&lane| time_clear_of(scene, me, lane, other, intent, params)).fold(0.0, f64::max);
            if until_clear <= 0.0 {
                continue;
            }
            until_clear
        } else {
            continue;
        };
        let gap = (other.state.s - me.state.s - length).max(0.0);
        let lead_speed = other.speed().max(0.0);
        // Short of RSS's distance the AV brakes at most as the games may (RSS's proper
        // response); harder only if that would not stop it in time.
        let mut accel = safe_accel(speed, intent.accel, -intent.firm, (lead_speed, gap, horizon), params);
        let lead_brake = (-other.accel).max(0.0);
        let early = (intent.accel, -intent.firm, hold);
        accel = accel.min(anticipating_accel(speed, early, (lead_speed, lead_brake, gap, horizon), params));
        if let Some(brake) = emergency_brake(speed, intent.firm, (lead_speed, lead_brake, gap, horizon), params) {
            accel = accel.min(-brake);
        }
        // Cars do not reverse: no braking below a standstill over the period.
        let accel = accel.max(-speed / scene.control_dt);
        if accel < intent.accel && lowest.is_none_or(|low| accel < low.accel) {
            let emergency = accel < -intent.firm;
            lowest = Some(SafetyOverride { accel, decided: intent.accel, car: other.id, emergency });
        }
    }
    lowest
}

#[cfg(test)]
mod tests {
    use super::*;

    /// RSS's Definition 1, as the paper writes it: the distance after which the car behind,
    /// holding `accel` for rho and then braking at a_min,brake, stops no farther than the
    /// car ahead braking at a_max,brake.
    fn definition_1(speed: f64, accel: f64, lead_speed: f64, p: &SafetyParams) -> f64 {
        let rho = p.response_time;
        let after = speed + accel * rho;
        (speed * rho + accel * rho * rho / 2.0 + after * after / (2.0 * p.brake)
            - lead_speed * lead_speed / (2.0 * p.lead_brake))
            .max(0.0)
    }

    #[test]
    fn with_rss_brakes_the_safe_acceleration_holds_exactly_at_definition_1() {
        // RSS's usual a_min,brake 4 < a_max,brake 8: the least gap is where both have
        // stopped. By hand, v = 25, u = 20, a = 1, rho = 0.1: 2.5 + 0.005 + 25.1^2 / 8 -
        // 20^2 / 16 = 56.25625 m.
        let p = SafetyParams { brake: 4.0, lead_brake: 8.0, ..SafetyParams::default() };
        let d = definition_1(25.0, 1.0, 20.0, &p);
        assert!((d - 56.25625).abs() < 1e-9, "{d}");
        let at = |gap: f64| safe_accel(25.0, 1.0, -4.0, (20.0, gap, f64::INFINITY), &p);
        assert_eq!(at(d + p.margin + 1e-9), 1.0);
        let short = at(d + p.margin - 1.0);
        assert!(short < 1.0 && short > -4.0, "{short}");
        // Braking at the cap, the car is at RSS's distance again after rho (to 1e-6 m).
        let rear = Braking { speed: 25.0, accel: short, hold: p.response_time, brake: p.brake };
        let least = least_gap(rear, 20.0, p.lead_brake, d + p.margin - 1.0, f64::INFINITY);
        assert!((least - p.margin).abs() < 1e-6, "{least}");
    }

    #[test]
    fn braking_harder_than_the_car_ahead_the_least_gap_comes_before_the_stop() {
        // The defaults, a_min,brake 8 > a_max,brake 6: the car behind becomes the slower
        // one before it stops, so Definition 1 (stopping points) asks too little. By hand,
        // v = 25, u = 20, a = 1: after rho at 25.1 m/s, 2.505 m on; the speeds meet 2.85 s
        // later (25.1 - 8 t = 19.4 - 6 t), when it has covered 2.505 + 25.1 * 2.85 - 4 *
        // 2.85^2 = 41.55 m and the car ahead 20 * 2.95 - 3 * 2.95^2 = 32.8925 m.
        let p = SafetyParams::default();
        assert_eq!((p.brake, p.lead_brake), (8.0, 6.0));
        let needed = 41.55 - 32.8925;
        let d = definition_1(25.0, 1.0, 20.0, &p);
        assert!((d - 8.547291666).abs() < 1e-6 && d < needed, "{d}");
        let rear = Braking { speed: 25.0, accel: 1.0, hold: p.response_time, brake: p.brake };
        let least = least_gap(rear, 20.0, p.lead_brake, needed + 5.0, f64::INFINITY);
        assert!((least - 5.0).abs() < 1e-9, "{least}");
        let at = |gap: f64| safe_accel(25.0, 1.0, -4.0, (20.0, gap, f64::INFINITY), &p);
        assert_eq!(at(needed + p.margin + 1e-9), 1.0);
        assert!(at(d + p.margin + 0.05) < 1.0);
    }

    #[test]
    fn a_car_ahead_only_until_the_lane_is_left_asks_less() {
        // 12 m behind a car 8 m/s slower: unsafe for good, safe for the 0.5 s it still
        // shares the lane.
        let p = SafetyParams::default();
        assert!(safe_accel(24.0, 2.0, -4.0, (16.0, 12.0, f64::INFINITY), &p) < 2.0);
        assert_eq!(safe_accel(24.0, 2.0, -4.0, (16.0, 12.0, 0.5), &p), 2.0);
    }

    #[test]
    fn emergency_braking_comes_only_when_the_games_braking_falls_short() {
        let p = SafetyParams::default();
        // 20 m behind a car as fast that brakes at 6: braking at 4 would hit it
        // (25^2 / 8 = 78 m against 20 + 52 m), at 8 or a little less it stops in time.
        let brake = emergency_brake(25.0, 4.0, (25.0, 6.0, 20.0, f64::INFINITY), &p).expect("an emergency");
        assert!(brake > 4.0 && brake < 8.0, "{brake}");
        let rear = Braking { speed: 25.0, accel: -brake, hold: 0.0, brake };
        assert!((least_gap(rear, 25.0, 6.0, 20.0, f64::INFINITY) - p.margin).abs() < 1e-6);
        // Holding its speed, the car ahead leaves room for braking at 4.
        assert_eq!(emergency_brake(25.0, 4.0, (25.0, 0.0, 20.0, f64::INFINITY), &p), None);
        // 5 m behind a wreck at 25 m/s: nothing stops in time; full braking.
        assert_eq!(emergency_brake(25.0, 4.0, (0.0, 0.0, 5.0, f64::INFINITY), &p), Some(8.0));
    }

    #[test]
    fn a_car_already_within_the_margin_that_pulls_away_asks_nothing() {
        // Paper-fit's conservative EC merging behind AC (Scenario A): at 6 m/s with AC
        // beside it, 0.3 m ahead bumper to bumper at 18 m/s. The gap only opens.
        let p = SafetyParams::default();
        assert_eq!(safe_accel(6.0, 0.25, -4.0, (18.0, 0.3, f64::INFINITY), &p), 0.25);
        assert_eq!(emergency_brake(6.0, 4.0, (18.0, 0.0, 0.3, f64::INFINITY), &p), None);
        // As slow as the AV, braking at 6, the same car closes the gap: brake.
        assert!(emergency_brake(6.0, 4.0, (6.0, 6.0, 0.3, f64::INFINITY), &p).is_some());
    }

    #[test]
    fn travel_stops_at_a_standstill() {
        assert_eq!(travel(10.0, -5.0, 4.0), (10.0, 0.0));
        assert_eq!(travel(10.0, 1.0, 2.0), (22.0, 12.0));
        let rear = Braking { speed: 10.0, accel: -20.0, hold: 1.0, brake: 8.0 };
        assert_eq!((rear.distance(3.0), rear.stops()), (2.5, 0.5));
    }
}
