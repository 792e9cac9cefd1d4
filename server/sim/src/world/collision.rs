//! Who is at fault in a collision (docs/design.md, "Collision attribution"), by a
//! responsibility rule in the spirit of RSS (Shalev-Shwartz et al. 2017, "On a Formal
//! Model of Safe and Scalable Self-driving Cars"): the car that was not keeping a safe
//! distance when the danger arose: when the two cars first came to share a lane. A car
//! whose body reaches into a lane is the lane's entrant; it answers for the gap it left
//! the car then behind it there, if that gap was under RSS's safe longitudinal distance
//! (`safe_gap`) as it entered (it cut in too close), until the gap is safe or
//! `ESTABLISH_TIME` has passed. Otherwise the car behind answers for keeping its
//! distance, to a car that entered safely (and that it then closed on, however it did:
//! accelerating into the gap it had given included) as to any car in its lane; a car
//! standing still is not at fault when struck.
//!
//! Attribution reads only what the world keeps of each car: the lanes its body is in,
//! since when, and, for each, the gap and speeds to the car then behind it there
//! (`Occupancy`, noted at every control instant). Learners, IDM cars and the AV are
//! judged alike, so a learner's crashes are told apart from the AV's.
//!
//! The rule used before it, a lane changer at fault for its whole crossing and for
//! `CUT_IN_WINDOW` after its centre entered the lane (`entry_rule`), is kept beside it
//! (`Collision::entry_rule`), so that reports can show both.

use serde::{Deserialize, Serialize};

use crate::road::{LaneId, Road};
use crate::scene::VehicleId;

/// Under the lane-entry rule (`Collision::entry_rule`): a car that entered the other's
/// lane this recently (s) changed lanes into occupied space. 2, chosen here: the
/// two-second rule of following distance, the headway a driver behind is owed before it
/// must answer for the gap.
pub const CUT_IN_WINDOW: f64 = 2.0;

/// Under the lane-entry rule (`Collision::entry_rule`): a car between lanes moving
/// sideways towards the other's lane faster than this (m/s) is changing lanes into it,
/// whatever its target lane (a learner's continuous actions steer without one). 0.2,
/// chosen here: a lane keeper's residual sway is under 0.05 m/s (docs/parameters.md,
/// "K_s"), a 4 s lane change peaks at 1.9 m/s.
pub const DRIFT_SPEED: f64 = 0.2;

/// rho of RSS's safe distance for attribution (s): how long the car behind may take to
/// answer a car entering ahead of it, holding its acceleration, before it brakes. 1,
/// chosen here: a driver's brake reaction time to an expected event (0.7-1.5 s in
/// human-factors studies); a learner or IDM car decides at 10 Hz, so it is generous to
/// the car behind. At equal speeds the safe gap is then one second of driving: the 30-45
/// m an AV enters ahead of a car at 25-30 m/s is safe, and a car that closes it is at fault.
pub const BLAME_RESPONSE_TIME: f64 = 1.0;

/// a_min,brake and a_max,brake of RSS's safe distance for attribution (m/s^2): the
/// braking the car behind counts on after the response time, and the hardest the car
/// ahead may brake. 6, chosen here: IDM's `accel_limit`, a wreck's braking and a
/// learner's continuous range, the hardest any car of this world brakes but for the AV's
/// emergency braking (its last resort). RSS's usual a_min,brake 4 < a_max,brake 8 would
/// call a 2 s headway at 25 m/s unsafe and put nearly every cut-in on the changer, as
/// the lane-entry rule did.
pub const BLAME_BRAKE: f64 = 6.0;

/// How long (s) after its body first reached into a lane a car that cut in too close
/// answers for the gap behind it at most (it is then established in the lane, and the
/// car behind answers). 3, chosen here: the car behind's response time (1 s,
/// `BLAME_RESPONSE_TIME`) and 2 s of braking at `BLAME_BRAKE`, which open 12 m on a car
/// at its speed: RSS's proper response to an unsafe gap, which a car behind that is still
/// too close by then did not make. A gap found safe at a control instant before that
/// establishes the entrant at once.
pub const ESTABLISH_TIME: f64 = 3.0;

/// A car slower than this (m/s) stands still, and is not at fault when it is struck
/// (nuPlan's at-fault classes: a collision while stopped is not the ego's fault). 0.1,
/// chosen here: well under any car's speed in motion, above the model's creep as a
/// braked car comes to rest.
pub const STANDSTILL_SPEED: f64 = 0.1;

/// Which of the two cars of a collision is at fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum AtFault {
    /// The car behind: it struck a car in its lane, or changed lanes into it.
    Rear,
    /// The car ahead: it changed lanes into the rear car's space.
    Front,
    /// Both changed lanes into each other's space at once.
    Both,
}

/// A collision found in a tick: the two cars and who is at fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Collision {
    /// The vehicle behind (smaller s).
    pub rear: VehicleId,
    /// The vehicle ahead.
    pub front: VehicleId,
    /// Who is at fault (the responsibility rule of docs/design.md, "Collision attribution").
    pub at_fault: AtFault,
    /// Who is at fault under the lane-entry rule used up to this change (2 s after
    /// entering), kept to compare.
    pub entry_rule: AtFault,
}

impl Collision {
    /// The other car of this collision, if `id` is in it.
    pub fn other(&self, id: VehicleId) -> Option<VehicleId> {
        match id {
            _ if id == self.rear => Some(self.front),
            _ if id == self.front => Some(self.rear),
            _ => None,
        }
    }

    /// Whether `id` is in this collision and at fault for it.
    pub fn is_at_fault(&self, id: VehicleId) -> bool {
        self.at_fault.names(id, self)
    }

    /// Whether `id` is in this collision and at fault for it under the lane-entry rule.
    pub fn is_at_fault_by_entry_rule(&self, id: VehicleId) -> bool {
        self.entry_rule.names(id, self)
    }
}

impl AtFault {
    /// Whether this verdict on `collision` puts `id` at fault.
    fn names(self, id: VehicleId, collision: &Collision) -> bool {
        match self {
            AtFault::Rear => id == collision.rear,
            AtFault::Front => id == collision.front,
            AtFault::Both => id == collision.rear || id == collision.front,
        }
    }
}

/// The lane nearest a car's centre at the last control instant and when it entered it
/// (what the lane-entry rule reads).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LaneEntry {
    /// The lane.
    pub lane: LaneId,
    /// When (simulated s) the car entered it; `None`: it started there.
    pub at: Option<f64>,
}

/// A lane a car's body is in at the last control instant, since when, and the gap it
/// left the car behind it there as it came in.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Occupancy {
    /// The lane.
    pub lane: LaneId,
    /// When (simulated s) its body first reached into the lane; `None`: it started there.
    pub since: Option<f64>,
    /// The car nearest behind it in the lane then, and the gap; `None`: it started there,
    /// or no car was behind it in the lane.
    pub behind: Option<EntryGap>,
}

/// The car behind a car entering a lane, as it entered: what says whether it cut in too
/// close.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EntryGap {
    /// The car behind.
    pub rear: VehicleId,
    /// Bumper-to-bumper gap (m) along the road; negative: the two side by side.
    pub gap: f64,
    /// The entering car's speed (m/s).
    pub speed: f64,
    /// The car behind's speed (m/s).
    pub rear_speed: f64,
    /// The car behind's longitudinal acceleration (m/s^2).
    pub rear_accel: f64,
    /// The first control instant (simulated s), from the entry on, at which the gap to
    /// `rear` was safe (`safe_gap`) or `rear` no longer behind it in the lane: from then
    /// on the entering car is established in front of it. Equal to the entry's time: the
    /// gap was safe as it entered. `None`: not yet, it cut in too close.
    pub established: Option<f64>,
}

impl EntryGap {
    /// Whether the gap was under RSS's safe distance as the car entered: it cut in too close.
    pub fn too_close(&self) -> bool {
        self.gap < safe_gap(self.rear_speed, self.rear_accel, self.speed)
    }
}

/// RSS's safe longitudinal distance (Definition 1, m) from a car at `rear_speed` with
/// `rear_accel` to a car ahead at `front_speed`: the gap after which the car behind,
/// holding its acceleration (if positive) for `BLAME_RESPONSE_TIME` and braking at
/// `BLAME_BRAKE` after, stops no farther than the car ahead braking at `BLAME_BRAKE`.
pub fn safe_gap(rear_speed: f64, rear_accel: f64, front_speed: f64) -> f64 {
    let (rho, brake) = (BLAME_RESPONSE_TIME, BLAME_BRAKE);
    let (v, a, u) = (rear_speed.max(0.0), rear_accel.max(0.0), front_speed.max(0.0));
    let after = v + a * rho;
    (v * rho + a * rho * rho / 2.0 + (after * after - u * u) / (2.0 * brake)).max(0.0)
}

/// The lanes a body at (`s`, `d`) reaching `reach` m to either side of its centre is in,
/// by lane (a lane that has ended at `s` is none; the first three a body across more).
pub fn lanes_reached(road: &Road, s: f64, d: f64, reach: f64) -> [Option<LaneId>; 3] {
    let (width, count) = (road.lane_width(), road.lane_count() as f64);
    let half = width / 2.0;
    // Lane k's centre is at -k * width: the candidates, one more on either side so that
    // rounding never drops one, then the exact test. Enough for any reach, at most
    // 5 + 2 * reach / width of them, never a loop over every lane.
    let low = ((-d - half - reach) / width).floor().clamp(0.0, count);
    let high = ((-d + half + reach) / width).ceil().clamp(0.0, count);
    let reached = (low as u32..high as u32)
        .map(LaneId)
        .filter(|&lane| (d - road.lane_center(lane)).abs() < half + reach && s <= road.lane_end(lane));
    let mut lanes = [None; 3];
    for (slot, lane) in lanes.iter_mut().zip(reached) {
        *slot = Some(lane);
    }
    lanes
}

/// One car as it collides, as the responsibility rule reads it.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Party {
    /// The car.
    pub id: VehicleId,
    /// Its speed along its heading (m/s).
    pub speed: f64,
    /// The lanes its body is in, each with when and how it came in.
    pub lanes: Vec<Occupancy>,
}

/// Who is at fault when `rear` and `front` collide at `time`, by the responsibility rule.
/// The danger arose when they first came to share a lane (of the lanes both are in now,
/// the one whose later entry of the two is earliest; every such lane if several): the
/// front car is at fault if it entered there then, too close to the rear car, and is not
/// yet established (it cut in too close); the rear car if it entered there then, or the
/// front car did not cut in too close on it; both if both. A car standing still
/// (`STANDSTILL_SPEED`) is not at fault when the other moves.
pub(super) fn at_fault(rear: &Party, front: &Party, time: f64) -> AtFault {
    let since = |o: &Occupancy| o.since.unwrap_or(f64::NEG_INFINITY);
    // Each lane both are in, with the rear car's and the front car's notes of it.
    let shared = || {
        front
            .lanes
            .iter()
            .filter_map(|theirs| rear.lanes.iter().find(|o| o.lane == theirs.lane).map(|mine| (mine, theirs)))
    };
    let first = shared().map(|(mine, theirs)| since(mine).max(since(theirs))).fold(f64::INFINITY, f64::min);
    let (mut rear_fault, mut front_fault) = (first == f64::INFINITY, false);
    for (mine, theirs) in shared().filter(|&(mine, theirs)| since(mine).max(since(theirs)) == first) {
        let rear_entered = mine.since.is_some() && since(mine) == first;
        let front_entered = theirs.since.is_some() && since(theirs) == first;
        let cut_in = front_entered && cut_in_on(theirs, rear.id, time);
        front_fault |= cut_in;
        rear_fault |= rear_entered || !cut_in;
    }
    let standing = |party: &Party| party.speed.abs() < STANDSTILL_SPEED;
    if standing(rear) && !standing(front) {
        (rear_fault, front_fault) = (false, true);
    }
    match (rear_fault, front_fault) {
        (true, true) => AtFault::Both,
        (false, true) => AtFault::Front,
        _ => AtFault::Rear,
    }
}

/// Whether a car in `occupancy` cut in too close on `rear` there and still answers for it
/// at `time`.
fn cut_in_on(occupancy: &Occupancy, rear: VehicleId, time: f64) -> bool {
    let Some(since) = occupancy.since else { return false };
    occupancy.behind.is_some_and(|gap| gap.rear == rear && gap.established.is_none() && time - since < ESTABLISH_TIME)
}

/// One car as it collides, as the lane-entry rule reads it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Approach {
    /// The lane nearest its centre.
    pub lane: LaneId,
    /// When (simulated s) it entered that lane; `None`: it started there.
    pub entered: Option<f64>,
    /// The lane it is in or changing to.
    pub target_lane: LaneId,
    /// Its offset across the road (m, + to the left).
    pub d: f64,
    /// Its lateral speed (m/s, + to the left).
    pub lateral_speed: f64,
}

/// Who is at fault when `rear` and `front` collide at `time` under the lane-entry rule
/// (the rule before the responsibility rule): the car that changed lanes into the
/// other's space, else the car behind.
pub(super) fn entry_rule(rear: &Approach, front: &Approach, time: f64) -> AtFault {
    match (cuts_in(front, rear, time), cuts_in(rear, front, time)) {
        (true, false) => AtFault::Front,
        (true, true) => AtFault::Both,
        (false, _) => AtFault::Rear,
    }
}

/// Whether `car` changed lanes into `other`'s space: it entered `other`'s lane less than
/// `CUT_IN_WINDOW` ago and after `other` did, or it is in another lane and changing to
/// `other`'s, by its target lane or by its lateral speed.
fn cuts_in(car: &Approach, other: &Approach, time: f64) -> bool {
    if car.lane == other.lane {
        let recent = car.entered.is_some_and(|t| time - t < CUT_IN_WINDOW);
        let later = match (car.entered, other.entered) {
            (Some(mine), Some(theirs)) => mine > theirs,
            (Some(_), None) => true,
            (None, _) => false,
        };
        return recent && later;
    }
    let towards = (other.d - car.d).signum();
    car.target_lane == other.lane || car.lateral_speed * towards > DRIFT_SPEED
}

#[cfg(test)]
mod tests {
    use super::*;

    const REAR: VehicleId = VehicleId(0);
    const FRONT: VehicleId = VehicleId(1);

    /// Lane entry rule: a car cruising on `lane` since the start, centred at `d`.
    fn cruising(lane: u32, d: f64) -> Approach {
        Approach { lane: LaneId(lane), entered: None, target_lane: LaneId(lane), d, lateral_speed: 0.0 }
    }

    /// Responsibility rule: car `id` at `speed` in `lanes`.
    fn party(id: VehicleId, speed: f64, lanes: &[Occupancy]) -> Party {
        Party { id, speed, lanes: lanes.to_vec() }
    }

    /// In `lane` since the start.
    fn started(lane: u32) -> Occupancy {
        Occupancy { lane: LaneId(lane), since: None, behind: None }
    }

    /// Into `lane` at `since`, `gap` m ahead of `REAR`, at `speed` with REAR at
    /// `rear_speed`, established as the world notes it (at once if the gap was safe).
    fn entered(lane: u32, since: f64, gap: f64, speed: f64, rear_speed: f64) -> Occupancy {
        let mut entry = EntryGap { rear: REAR, gap, speed, rear_speed, rear_accel: 0.0, established: None };
        entry.established = (!entry.too_close()).then_some(since);
        Occupancy { lane: LaneId(lane), since: Some(since), behind: Some(entry) }
    }

    #[test]
    fn safe_gap_is_rss_definition_1_with_this_worlds_brakes() {
        // Equal speeds: one response time of driving.
        assert!((safe_gap(25.0, 0.0, 25.0) - 25.0).abs() < 1e-12);
        // By hand: 30 * 1 + 2 * 1 / 2 + (32^2 - 20^2) / 12 = 31 + 52 = 83.
        assert!((safe_gap(30.0, 2.0, 20.0) - 83.0).abs() < 1e-12);
        // Braking behind counts as holding its speed; a car standing behind needs none.
        assert_eq!(safe_gap(25.0, -3.0, 25.0), safe_gap(25.0, 0.0, 25.0));
        assert_eq!(safe_gap(0.0, 0.0, 10.0), 0.0);
    }

    #[test]
    fn the_constants_are_those_docs_parameters_md_gives() {
        let doc = include_str!("../../../../docs/parameters.md");
        let rows = [
            ("BLAME_RESPONSE_TIME", BLAME_RESPONSE_TIME, "1 s"),
            ("BLAME_BRAKE", BLAME_BRAKE, "6 m/s²"),
            ("ESTABLISH_TIME", ESTABLISH_TIME, "3 s"),
            ("STANDSTILL_SPEED", STANDSTILL_SPEED, "0.1 m/s"),
            ("CUT_IN_WINDOW", CUT_IN_WINDOW, "2 s"),
            ("DRIFT_SPEED", DRIFT_SPEED, "0.2 m/s"),
        ];
        for (name, value, shown) in rows {
            let row = doc.lines().find(|line| line.contains(&format!("(`{name}`)")));
            let row = row.unwrap_or_else(|| panic!("no row for {name} in docs/parameters.md"));
            let number: f64 = shown.split(' ').next().unwrap().parse().unwrap();
            assert!(row.contains(&format!("| {shown} |")) && number == value, "{name} = {value}: {row}");
        }
    }

    #[test]
    fn a_body_is_in_every_lane_it_reaches_into() {
        let road = Road::straight(1000.0, 3, 4.0, 30.0);
        let lanes = |d: f64| lanes_reached(&road, 100.0, d, 1.0);
        assert_eq!(lanes(0.0), [Some(LaneId(0)), None, None]);
        // 1 m off centre the edge is on the line: not yet across.
        assert_eq!(lanes(-1.0), [Some(LaneId(0)), None, None]);
        assert_eq!(lanes(-1.2), [Some(LaneId(0)), Some(LaneId(1)), None]);
        assert_eq!(lanes(-6.5), [Some(LaneId(1)), Some(LaneId(2)), None]);
        // Past the road's left edge there is no lane, nor past its right edge.
        assert_eq!(lanes(2.5), [Some(LaneId(0)), None, None]);
        assert_eq!(lanes(-9.5), [Some(LaneId(2)), None, None]);
        assert_eq!(lanes(-20.0), [None; 3]);
        // Lanes narrower than the body: the first three it is across.
        let narrow = Road::straight(1000.0, 64, 0.5, 30.0);
        let first = (0..3).map(|k| Some(LaneId(10 + k))).collect::<Vec<_>>();
        assert_eq!(lanes_reached(&narrow, 100.0, -6.0, 1.0).to_vec(), first);
        // A lane that has ended is none.
        let ending = Road::new(
            crate::road::Pose { x: 0.0, y: 0.0, heading: 0.0 },
            vec![crate::road::Section::Straight { length: 500.0 }],
            4.0,
            vec![30.0, 30.0],
            &[(LaneId(1), 150.0)],
        );
        assert_eq!(lanes_reached(&ending, 100.0, -1.5, 1.0), [Some(LaneId(0)), Some(LaneId(1)), None]);
        assert_eq!(lanes_reached(&ending, 200.0, -1.5, 1.0), [Some(LaneId(0)), None, None]);
    }

    #[test]
    fn rear_end_in_lane() {
        // Both in lane 0 from the start: the car behind struck the car ahead.
        let (rear, front) = (party(REAR, 25.0, &[started(0)]), party(FRONT, 15.0, &[started(0)]));
        assert_eq!(at_fault(&rear, &front, 10.0), AtFault::Rear);
        assert_eq!(entry_rule(&cruising(0, 0.0), &cruising(0, 0.0), 10.0), AtFault::Rear);
        // A car that changed lanes long before is a car in the lane.
        let settled = party(FRONT, 15.0, &[entered(0, 4.0, 8.0, 25.0, 25.0)]);
        assert_eq!(at_fault(&rear, &settled, 10.0), AtFault::Rear);
        let old = Approach { entered: Some(5.0), ..cruising(0, 0.0) };
        assert_eq!(entry_rule(&cruising(0, 0.0), &old, 7.5), AtFault::Rear);
    }

    #[test]
    fn cut_in_too_close() {
        // Into lane 0 at 10 s 5 m ahead of a car at its speed of 25 m/s (safe: 25 m),
        // struck 1 s later, its centre across the line.
        let rear = party(REAR, 25.0, &[started(0)]);
        let front = party(FRONT, 20.0, &[entered(0, 10.0, 5.0, 25.0, 25.0)]);
        assert_eq!(at_fault(&rear, &front, 11.0), AtFault::Front);
        let changing = Approach { lane: LaneId(0), entered: Some(10.5), target_lane: LaneId(0), ..cruising(1, -1.5) };
        assert_eq!(entry_rule(&cruising(0, 0.0), &changing, 11.0), AtFault::Front);
        // Still mostly in its own lane, its body across the line: the same.
        let crossing = party(FRONT, 20.0, &[entered(0, 10.0, 5.0, 25.0, 25.0), started(1)]);
        assert_eq!(at_fault(&rear, &crossing, 10.5), AtFault::Front);
        // The same car cutting in from behind: the car behind is the one that moved in.
        let cutter = party(FRONT, 20.0, &[started(0)]);
        let from_behind = party(REAR, 25.0, &[Occupancy { behind: None, ..entered(0, 10.0, 5.0, 25.0, 25.0) }]);
        assert_eq!(at_fault(&from_behind, &cutter, 11.0), AtFault::Rear);
        // It answers while the gap stays unsafe, ESTABLISH_TIME at most.
        assert_eq!(at_fault(&rear, &front, 10.0 + ESTABLISH_TIME - 0.01), AtFault::Front);
        assert_eq!(at_fault(&rear, &front, 10.0 + ESTABLISH_TIME), AtFault::Rear);
        // Once the gap was safe at a control instant, the car behind answers for it.
        let mut established = entered(0, 10.0, 5.0, 25.0, 25.0);
        established.behind.as_mut().unwrap().established = Some(11.5);
        assert_eq!(at_fault(&rear, &party(FRONT, 20.0, &[established]), 12.0), AtFault::Rear);
        // It cut in on another car: this one was not behind it as it entered.
        let mut on_another = entered(0, 10.0, 5.0, 25.0, 25.0);
        on_another.behind.as_mut().unwrap().rear = VehicleId(7);
        assert_eq!(at_fault(&rear, &party(FRONT, 20.0, &[on_another]), 11.0), AtFault::Rear);
    }

    #[test]
    fn cut_in_with_a_safe_gap_then_the_rear_car_accelerates_into_it() {
        // Into lane 0 at 10 s 35 m ahead of a car at its speed of 25 m/s (safe: 25 m);
        // that car then accelerates at 4 m/s^2 and strikes it at 11.9 s, 1.3 s after the
        // changer's centre crossed the line. The old rule blamed the changer.
        let rear = party(REAR, 32.6, &[started(0)]);
        let front = party(FRONT, 25.0, &[entered(0, 10.0, 35.0, 25.0, 25.0), started(1)]);
        assert_eq!(at_fault(&rear, &front, 11.9), AtFault::Rear);
        let changer = Approach { lane: LaneId(0), entered: Some(10.6), target_lane: LaneId(0), ..cruising(1, -1.8) };
        assert_eq!(entry_rule(&cruising(0, 0.0), &changer, 11.9), AtFault::Front);
        // Had it been accelerating as the changer entered, the gap was not safe: 25 + 2 +
        // (29^2 - 25^2) / 12 = 45 m.
        let mut accelerating = entered(0, 10.0, 35.0, 25.0, 25.0);
        let gap = accelerating.behind.as_mut().unwrap();
        gap.rear_accel = 4.0;
        assert!(gap.too_close());
        gap.established = None;
        assert_eq!(at_fault(&rear, &party(FRONT, 25.0, &[accelerating, started(1)]), 11.9), AtFault::Front);
    }

    #[test]
    fn both_change_into_each_other() {
        // Lane 0's car moving right, lane 1's moving left, side by side: each body is in
        // the other's lane, each entered it beside the other.
        // At once: at the same control instant.
        let rear = party(REAR, 25.0, &[started(0), Occupancy { behind: None, ..entered(1, 10.0, -2.0, 25.0, 25.0) }]);
        let front = party(FRONT, 25.0, &[entered(0, 10.0, -2.0, 25.0, 25.0), started(1)]);
        assert_eq!(at_fault(&rear, &front, 10.5), AtFault::Both);
        // One first: it created the danger, the other moved sideways into a car already
        // across its line.
        let later = party(FRONT, 25.0, &[entered(0, 10.2, -2.0, 25.0, 25.0), started(1)]);
        assert_eq!(at_fault(&rear, &later, 10.5), AtFault::Rear);
        let left = Approach { target_lane: LaneId(1), d: -1.5, lateral_speed: -1.0, ..cruising(0, 0.0) };
        let right = Approach { target_lane: LaneId(0), d: -2.5, lateral_speed: 1.0, ..cruising(1, -4.0) };
        assert_eq!(entry_rule(&left, &right, 10.5), AtFault::Both);
        // Into the same lane from both sides: the later arrival took the space.
        let first = party(REAR, 25.0, &[Occupancy { behind: None, ..entered(1, 9.0, 0.0, 25.0, 25.0) }]);
        let second = party(FRONT, 25.0, &[entered(1, 9.5, 1.0, 25.0, 25.0)]);
        assert_eq!(at_fault(&first, &second, 10.0), AtFault::Front);
        let first = Approach { lane: LaneId(1), entered: Some(9.0), ..cruising(1, -4.0) };
        let second = Approach { lane: LaneId(1), entered: Some(9.5), ..cruising(1, -4.0) };
        assert_eq!(entry_rule(&first, &second, 10.0), AtFault::Front);
        assert_eq!(entry_rule(&second, &first, 10.0), AtFault::Rear);
    }

    #[test]
    fn two_cars_changing_lanes_one_behind_the_other() {
        // Both in lane 1, the rear car since 4.2 s behind the front car (in it since 2.4
        // s), both reach into lane 2 at 6.4 s, the front car 7.5 m ahead: the danger
        // arose in lane 1, where the rear car did not keep its distance.
        let lane1 = |since| Occupancy { lane: LaneId(1), since: Some(since), behind: None };
        let rear = party(REAR, 19.6, &[lane1(4.2), Occupancy { behind: None, ..entered(2, 6.4, 0.0, 19.0, 19.0) }]);
        let front = party(FRONT, 11.1, &[lane1(2.4), entered(2, 6.4, 7.5, 12.9, 19.3)]);
        assert_eq!(at_fault(&rear, &front, 7.4), AtFault::Rear);
        let (behind, ahead) = (Approach { entered: Some(4.3), ..cruising(1, -6.7) }, cruising(1, -6.6));
        let (behind, ahead) = (
            Approach { target_lane: LaneId(2), ..behind },
            Approach { entered: Some(2.4), target_lane: LaneId(2), ..ahead },
        );
        assert_eq!(entry_rule(&behind, &ahead, 7.4), AtFault::Rear);
        // The front car reaching into lane 2 from lane 1, 7.5 m ahead of a car there,
        // cut in too close; that car swerving into lane 1 after does not change it.
        let rear = party(REAR, 19.6, &[started(2), Occupancy { behind: None, ..entered(1, 6.6, 0.0, 19.0, 19.0) }]);
        let front = party(FRONT, 11.1, &[started(1), entered(2, 6.4, 7.5, 12.9, 19.3)]);
        assert_eq!(at_fault(&rear, &front, 7.4), AtFault::Front);
    }

    #[test]
    fn a_learner_drifting_without_a_target_lane() {
        // A learner's continuous actions: its target lane stays lane 1 while its body
        // reaches into lane 0 3 m ahead of a car there.
        let rear = party(REAR, 25.0, &[started(0)]);
        let drifting = party(FRONT, 25.0, &[entered(0, 10.0, 3.0, 25.0, 25.0), started(1)]);
        assert_eq!(at_fault(&rear, &drifting, 10.5), AtFault::Front);
        let fast = Approach { d: -2.5, lateral_speed: 0.5, ..cruising(1, -4.0) };
        assert_eq!(entry_rule(&cruising(0, 0.0), &fast, 10.5), AtFault::Front);
        // Drifting slowly (0.1 m/s) the old rule saw no lane change and blamed the car
        // behind; its body is in the lane all the same.
        let slow = Approach { lateral_speed: 0.1, ..fast };
        assert_eq!(entry_rule(&cruising(0, 0.0), &slow, 10.5), AtFault::Rear);
        // Drifting away from the lane it reached into: the car behind it there was given
        // a safe gap of 30 m, and struck it when it accelerated.
        let away = party(FRONT, 25.0, &[entered(0, 10.0, 30.0, 25.0, 25.0), started(1)]);
        assert_eq!(at_fault(&rear, &away, 12.0), AtFault::Rear);
        assert_eq!(entry_rule(&cruising(0, 0.0), &Approach { lateral_speed: -0.5, ..fast }, 12.0), AtFault::Rear);
    }

    #[test]
    fn a_car_hit_while_stopped_or_braking_for_a_stopped_car_ahead() {
        // Stopped in its lane, or braking for a stopped queue after changing into the
        // lane 1.5 s before with a safe 40 m: the car behind struck it. The old rule
        // blamed the car that had changed lanes, inside its 2 s.
        let rear = party(REAR, 20.0, &[started(0)]);
        assert_eq!(at_fault(&rear, &party(FRONT, 0.0, &[started(0)]), 10.0), AtFault::Rear);
        let braking = party(FRONT, 8.0, &[entered(0, 8.0, 40.0, 20.0, 20.0)]);
        assert_eq!(at_fault(&rear, &braking, 10.0), AtFault::Rear);
        let old = Approach { entered: Some(8.5), ..cruising(0, 0.0) };
        assert_eq!(entry_rule(&cruising(0, 0.0), &old, 10.0), AtFault::Front);
        // A car standing still is not at fault when struck: here by a car ahead of it
        // drifting back into its lane 1 m in front of it (a safe gap from a standing car).
        let standing = party(REAR, 0.0, &[started(0)]);
        let swerving = party(FRONT, 5.0, &[entered(0, 9.8, 1.0, 5.0, 0.0), started(1)]);
        assert_eq!(at_fault(&standing, &swerving, 10.0), AtFault::Front);
        let swerve = Approach { d: -2.5, lateral_speed: 0.5, ..cruising(1, -4.0) };
        assert_eq!(entry_rule(&cruising(0, 0.0), &swerve, 10.0), AtFault::Front);
    }

    #[test]
    fn a_changer_that_stalls_across_the_line() {
        // Its body reached into lane 0 60 m ahead of a car at 25 m/s, at 15 m/s (safe:
        // 25 + (625 - 225) / 12 = 58 m); it then stalled across the line, its centre
        // still in lane 1, and was struck 6 s later. The old rule blamed it for its whole
        // crossing.
        let rear = party(REAR, 22.0, &[started(0)]);
        let stalled = party(FRONT, 0.0, &[entered(0, 10.0, 60.0, 15.0, 25.0), started(1)]);
        assert_eq!(at_fault(&rear, &stalled, 16.0), AtFault::Rear);
        let across = Approach { target_lane: LaneId(0), d: -2.6, ..cruising(1, -4.0) };
        assert_eq!(entry_rule(&cruising(0, 0.0), &across, 16.0), AtFault::Front);
        // Entered 6 m ahead of the car (too close) and stalled: it answers.
        let cut = party(FRONT, 0.0, &[entered(0, 10.0, 6.0, 15.0, 25.0), started(1)]);
        assert_eq!(at_fault(&rear, &cut, 11.5), AtFault::Front);
        assert_eq!(entry_rule(&cruising(0, 0.0), &across, 11.5), AtFault::Front);
    }

    #[test]
    fn other_and_fault_of_each_car() {
        let (a, b, c) = (VehicleId(3), VehicleId(7), VehicleId(9));
        let collision = Collision { rear: a, front: b, at_fault: AtFault::Front, entry_rule: AtFault::Rear };
        assert_eq!((collision.other(a), collision.other(b), collision.other(c)), (Some(b), Some(a), None));
        assert!(!collision.is_at_fault(a) && collision.is_at_fault(b) && !collision.is_at_fault(c));
        assert!(collision.is_at_fault_by_entry_rule(a) && !collision.is_at_fault_by_entry_rule(b));
        let both = Collision { at_fault: AtFault::Both, ..collision };
        assert!(both.is_at_fault(a) && both.is_at_fault(b));
    }
}
