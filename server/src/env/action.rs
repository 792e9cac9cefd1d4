//! Learners' actions: their spaces, their checks, and how they drive a vehicle.
//! `meta` is highway-env's DiscreteMetaAction (lane left, idle, lane right, faster,
//! slower; target speeds 20/25/30 m/s); `continuous` gives the driver model its inputs
//! directly: an acceleration and a preview point relative to the current lane's centre,
//! each normalised to [-1, 1] as highway-env's ContinuousAction is (learners do best on
//! a symmetric unit box): 1 is the acceleration bound and one lane width to the left.

use arena_protocol::{Action, ActionType, DType, ErrorCode, Space};

use crate::road::LaneId;
use crate::world::{AgentCommand, Driver, VehicleId, World};

/// The target speeds `faster` and `slower` step through (m/s): highway-env's
/// `MDPVehicle.DEFAULT_TARGET_SPEEDS`.
pub const TARGET_SPEEDS: [f64; 3] = [20.0, 25.0, 30.0];

const LANE_LEFT: u32 = 0;
const LANE_RIGHT: u32 = 2;
const FASTER: u32 = 3;
const SLOWER: u32 = 4;

/// The action space of an agent driving with `kind`.
pub fn space(kind: ActionType) -> Space {
    match kind {
        ActionType::Meta => Space::Discrete { n: 5, start: 0 },
        ActionType::Continuous => {
            Space::Box { low: vec![-1.0; 2], high: vec![1.0; 2], shape: vec![2], dtype: DType::F32 }
        }
    }
}

/// Refuses an action of the wrong type, out of its space, or not finite.
pub fn check(action: &Action, kind: ActionType) -> Result<(), (ErrorCode, String)> {
    match (action, kind) {
        (Action::Meta(_), ActionType::Meta) | (Action::Continuous(_), ActionType::Continuous) => {
            space(kind).contains_action(action).map_err(|message| (ErrorCode::InvalidAction, message))
        }
        (_, expected) => {
            Err((ErrorCode::WrongActionType, format!("this agent takes {expected:?} actions, got {action:?}")))
        }
    }
}

/// Which meta actions make a difference now: [left, idle, right, faster, slower].
pub fn meta_mask(world: &World, id: VehicleId) -> [bool; 5] {
    let vehicle = world.vehicle(id);
    let lane = vehicle.target_lane.0 as i64;
    let open = |lane: i64| world.road.has_lane(lane) && world.road.lane_end(LaneId(lane as u32)) > vehicle.state.s;
    let speed = speed_index(vehicle.target_speed);
    [open(lane - 1), true, open(lane + 1), speed + 1 < TARGET_SPEEDS.len(), speed > 0]
}

fn speed_index(target: f64) -> usize {
    (0..TARGET_SPEEDS.len())
        .min_by(|&a, &b| (TARGET_SPEEDS[a] - target).abs().total_cmp(&(TARGET_SPEEDS[b] - target).abs()))
        .unwrap_or(0)
}

/// The meta action closest to an acceleration and a lane change (sigma -1 = left).
pub fn meta_equivalent(accel: f64, sigma: i8) -> u32 {
    match sigma {
        -1 => LANE_LEFT,
        1 => LANE_RIGHT,
        _ if accel > 0.5 => FASTER,
        _ if accel < -0.5 => SLOWER,
        _ => 1,
    }
}

/// Drives `id` with `action`; a missing action keeps the lane and the speed.
pub fn apply(world: &mut World, id: VehicleId, action: Option<&Action>, kind: ActionType) {
    match (kind, action) {
        (ActionType::Meta, action) => {
            world.vehicle_mut(id).driver = Driver::Agent(AgentCommand::Track);
            let Some(&Action::Meta(choice)) = action else { return };
            let mask = meta_mask(world, id);
            if !mask[choice as usize] {
                return;
            }
            let vehicle = world.vehicle(id);
            let (lane, speed) = (vehicle.target_lane.0, speed_index(vehicle.target_speed));
            match choice {
                LANE_LEFT => world.change_lane(id, LaneId(lane - 1)),
                LANE_RIGHT => world.change_lane(id, LaneId(lane + 1)),
                FASTER => world.vehicle_mut(id).target_speed = TARGET_SPEEDS[speed + 1],
                SLOWER => world.vehicle_mut(id).target_speed = TARGET_SPEEDS[speed - 1],
                _ => {}
            }
        }
        (ActionType::Continuous, action) => {
            let lane = world.current_lane(id);
            let centre = world.road.lane_center(lane);
            let [accel, offset] = match action {
                Some(&Action::Continuous(values)) => values.map(f64::from),
                _ => [0.0, 0.0],
            };
            let accel = accel * world.idm.accel_limit;
            let command = crate::dynamics::Command { accel, preview: centre + offset * world.road.lane_width() };
            let vehicle = world.vehicle_mut(id);
            vehicle.target_lane = lane;
            vehicle.driver = Driver::Agent(AgentCommand::Direct(command));
        }
    }
}
