//! Who is at fault in a collision (docs/design.md, "Collision attribution"): the car that
//! changed lanes into the other's space, else the car behind, which struck the other.
//! Attribution reads only what the world keeps of each car as it collides: the lane it is
//! in, since when, the lane it is changing to and its lateral speed. Learners, IDM cars and
//! the AV are judged alike, so a learner's crashes are told apart from the AV's.

use serde::{Deserialize, Serialize};

use crate::road::LaneId;
use crate::scene::VehicleId;

/// A car that entered the other's lane this recently (s) changed lanes into occupied
/// space. 2, chosen here: the two-second rule of following distance, the headway a
/// driver behind is owed before it must answer for the gap.
pub const CUT_IN_WINDOW: f64 = 2.0;

/// A car between lanes moving sideways towards the other's lane faster than this (m/s)
/// is changing lanes into it, whatever its target lane (a learner's continuous actions
/// steer without one). 0.2, chosen here: a lane keeper's residual sway is under 0.05 m/s
/// (docs/parameters.md, "K_s"), a 4 s lane change peaks at 1.9 m/s.
pub const DRIFT_SPEED: f64 = 0.2;

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
    /// Who is at fault.
    pub at_fault: AtFault,
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
        match self.at_fault {
            AtFault::Rear => id == self.rear,
            AtFault::Front => id == self.front,
            AtFault::Both => id == self.rear || id == self.front,
        }
    }
}

/// The lane nearest a car's centre at the last control instant and when it entered it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LaneEntry {
    /// The lane.
    pub lane: LaneId,
    /// When (simulated s) the car entered it; `None`: it started there.
    pub at: Option<f64>,
}

/// One car as it collides, as attribution reads it.
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

/// Who is at fault when `rear` and `front` collide at `time`.
pub(super) fn at_fault(rear: &Approach, front: &Approach, time: f64) -> AtFault {
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

    fn cruising(lane: u32, d: f64) -> Approach {
        Approach { lane: LaneId(lane), entered: None, target_lane: LaneId(lane), d, lateral_speed: 0.0 }
    }

    #[test]
    fn the_car_behind_is_at_fault_in_a_rear_end() {
        assert_eq!(at_fault(&cruising(0, 0.0), &cruising(0, 0.0), 10.0), AtFault::Rear);
        // A car that changed lanes long before is a car in the lane.
        let settled = Approach { entered: Some(5.0), ..cruising(0, 0.0) };
        assert_eq!(at_fault(&cruising(0, 0.0), &settled, 7.5), AtFault::Rear);
    }

    #[test]
    fn a_car_cutting_in_is_at_fault() {
        let (rear, front) = (cruising(0, 0.0), cruising(1, -4.0));
        // Changing lanes, still in its own lane by position.
        let changing = Approach { target_lane: LaneId(0), d: -2.5, lateral_speed: 1.2, ..front };
        assert_eq!(at_fault(&rear, &changing, 10.0), AtFault::Front);
        // Just across the line.
        let entered = Approach { lane: LaneId(0), entered: Some(9.0), d: -1.5, ..changing };
        assert_eq!(at_fault(&rear, &entered, 10.0), AtFault::Front);
        assert_eq!(at_fault(&entered, &rear, 10.0), AtFault::Rear, "the same car cutting in from behind");
        // Drifting in without a target lane (a learner's continuous actions).
        let drifting = Approach { d: -2.5, lateral_speed: 0.5, ..front };
        assert_eq!(at_fault(&rear, &drifting, 10.0), AtFault::Front);
        assert_eq!(at_fault(&rear, &Approach { lateral_speed: 0.1, ..drifting }, 10.0), AtFault::Rear);
        // Drifting away is not cutting in.
        assert_eq!(at_fault(&rear, &Approach { lateral_speed: -0.5, ..drifting }, 10.0), AtFault::Rear);
    }

    #[test]
    fn two_cars_changing_into_each_others_space_are_both_at_fault() {
        let left = Approach { target_lane: LaneId(1), d: -1.5, lateral_speed: -1.0, ..cruising(0, 0.0) };
        let right = Approach { target_lane: LaneId(0), d: -2.5, lateral_speed: 1.0, ..cruising(1, -4.0) };
        assert_eq!(at_fault(&left, &right, 10.0), AtFault::Both);
        // Into the same lane from both sides: the later arrival took the space.
        let first = Approach { lane: LaneId(1), entered: Some(9.0), ..cruising(1, -4.0) };
        let second = Approach { lane: LaneId(1), entered: Some(9.5), ..cruising(1, -4.0) };
        assert_eq!(at_fault(&first, &second, 10.0), AtFault::Front);
        assert_eq!(at_fault(&second, &first, 10.0), AtFault::Rear);
    }

    #[test]
    fn other_and_fault_of_each_car() {
        let (a, b, c) = (VehicleId(3), VehicleId(7), VehicleId(9));
        let collision = Collision { rear: a, front: b, at_fault: AtFault::Front };
        assert_eq!((collision.other(a), collision.other(b), collision.other(c)), (Some(b), Some(a), None));
        assert!(!collision.is_at_fault(a) && collision.is_at_fault(b) && !collision.is_at_fault(c));
        let both = Collision { at_fault: AtFault::Both, ..collision };
        assert!(both.is_at_fault(a) && both.is_at_fault(b));
    }
}
