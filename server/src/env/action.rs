//! Learners' actions: their spaces, their checks, and how they drive a vehicle.
//! `meta` is highway-env's DiscreteMetaAction (lane left, idle, lane right, faster,
//! slower; target speeds 20/25/30 m/s); `continuous` gives the driver model its inputs
//! directly: an acceleration and a preview point relative to the current lane's centre,
//! each normalised to [-1, 1] as highway-env's ContinuousAction is (learners do best on
//! a symmetric unit box): 1 is the acceleration bound and one lane width to the left.

use arena_protocol::{
    Action, ActionType, DType, ErrorCode, META_FASTER, META_IDLE, META_LANE_LEFT, META_LANE_RIGHT, META_SLOWER, Space,
};

use arena_sim::dynamics::Command;
use arena_sim::road::LaneChange;
use arena_sim::road::{LaneId, Road};
use arena_sim::world::{AgentCommand, VehicleId, World};

/// The target speeds `faster` and `slower` step through (m/s): highway-env's
/// `MDPVehicle.DEFAULT_TARGET_SPEEDS`.
pub const TARGET_SPEEDS: [f64; 3] = [20.0, 25.0, 30.0];

/// The acceleration (m/s^2) a continuous action of 1 asks for: highway-env's
/// ContinuousAction range, [-6, 6] m/s^2 (its ACCELERATION_RANGE).
pub const CONTINUOUS_ACCEL_SCALE: f64 = 6.0;

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
pub fn meta_mask(road: &Road, target_lane: LaneId, target_speed: f64, s: f64) -> [bool; 5] {
    let lane = i64::from(target_lane.0);
    let open = |lane: i64| road.has_lane(lane) && road.lane_end(LaneId(lane as u32)) > s;
    let speed = speed_index(target_speed);
    let mut mask = [false; 5];
    mask[META_LANE_LEFT as usize] = open(lane - 1);
    mask[META_IDLE as usize] = true;
    mask[META_LANE_RIGHT as usize] = open(lane + 1);
    mask[META_FASTER as usize] = speed + 1 < TARGET_SPEEDS.len();
    mask[META_SLOWER as usize] = speed > 0;
    mask
}

fn speed_index(target: f64) -> usize {
    (0..TARGET_SPEEDS.len())
        .min_by(|&a, &b| (TARGET_SPEEDS[a] - target).abs().total_cmp(&(TARGET_SPEEDS[b] - target).abs()))
        .unwrap_or(0)
}

/// The meta action closest to an acceleration and a lane change (sigma -1 = left).
pub fn meta_equivalent(accel: f64, change: LaneChange) -> u32 {
    match change {
        LaneChange::Left => META_LANE_LEFT,
        LaneChange::Right => META_LANE_RIGHT,
        LaneChange::Keep if accel > 0.5 => META_FASTER,
        LaneChange::Keep if accel < -0.5 => META_SLOWER,
        LaneChange::Keep => META_IDLE,
    }
}

/// Drives `id` with `action`; a missing action keeps the lane and the speed.
pub fn apply(world: &mut World, id: VehicleId, action: Option<&Action>, kind: ActionType) {
    match (kind, action) {
        (ActionType::Meta, action) => {
            world.command_agent(id, AgentCommand::Track);
            let Some(&Action::Meta(choice)) = action else { return };
            let vehicle = world.vehicle(id);
            let mask = meta_mask(world.road(), vehicle.target_lane, vehicle.target_speed, vehicle.state.s);
            if !mask[choice as usize] {
                return;
            }
            let (lane, speed) = (vehicle.target_lane.0, speed_index(vehicle.target_speed));
            match choice {
                META_LANE_LEFT => world.change_lane(id, LaneId(lane - 1)),
                META_LANE_RIGHT => world.change_lane(id, LaneId(lane + 1)),
                META_FASTER => world.set_target_speed(id, TARGET_SPEEDS[speed + 1]),
                META_SLOWER => world.set_target_speed(id, TARGET_SPEEDS[speed - 1]),
                _ => {}
            }
        }
        (ActionType::Continuous, action) => {
            let lane = world.current_lane(id);
            let centre = world.road().lane_center(lane);
            let [accel, offset] = match action {
                Some(&Action::Continuous(values)) => values.map(f64::from),
                _ => [0.0, 0.0],
            };
            let command =
                Command { accel: accel * CONTINUOUS_ACCEL_SCALE, preview: centre + offset * world.road().lane_width() };
            world.set_target_lane(id, lane);
            world.command_agent(id, AgentCommand::Direct(command));
        }
    }
}
