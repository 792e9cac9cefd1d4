//! Learners' actions: their spaces, their checks, and how they drive a vehicle.
//! `meta` is highway-env's DiscreteMetaAction: lane left and right change the target
//! lane, `faster` and `slower` step the target speed along a ladder from 0 to the lane's
//! limit in `TARGET_SPEED_STEP`s (low enough to yield and to stop before a lane end),
//! `idle` keeps it; an action that cannot act (no lane there, top of the ladder) is a
//! no-op, and the infos say so. `continuous` gives the driver model its inputs
//! directly: an acceleration and a preview point relative to the current lane's centre,
//! each normalised to [-1, 1] as highway-env's ContinuousAction is (learners do best on
//! a symmetric unit box): 1 is `CONTINUOUS_ACCEL_SCALE` and one lane width to the left;
//! the world keeps the speed within [0, limit x `LEARNER_SPEED_FACTOR`].

use arena_protocol::{
    Action, ActionType, DType, ErrorCode, META_FASTER, META_IDLE, META_LANE_LEFT, META_LANE_RIGHT, META_SLOWER, Space,
};

use arena_sim::dynamics::Command;
use arena_sim::gt::Decision;
use arena_sim::road::{LaneChange, LaneId, Road};
use arena_sim::traffic::IdmParams;
use arena_sim::world::{AgentCommand, VehicleId, World};

/// The rungs of the target-speed ladder of `faster` and `slower` (m/s): 0, 5, 10, ... up
/// to the lane's limit (which is a rung too). highway-env spaces its target speeds 5 m/s
/// apart (20, 25, 30 on highway-v0); the ladder continues down to a stop.
pub const TARGET_SPEED_STEP: f64 = 5.0;

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

/// The next rung of the ladder above `speed` (capped at `limit`).
fn rung_above(speed: f64, limit: f64) -> f64 {
    (((speed + 1e-6) / TARGET_SPEED_STEP).floor() * TARGET_SPEED_STEP + TARGET_SPEED_STEP).min(limit)
}

/// The next rung of the ladder below `speed` (at least 0).
fn rung_below(speed: f64) -> f64 {
    (((speed - 1e-6) / TARGET_SPEED_STEP).ceil() * TARGET_SPEED_STEP - TARGET_SPEED_STEP).max(0.0)
}

/// Which meta actions make a difference now: indexed by `META_*`. `limit` is the speed
/// limit of the target lane.
pub fn meta_mask(road: &Road, target_lane: LaneId, target_speed: f64, s: f64) -> [bool; 5] {
    let lane = i64::from(target_lane.0);
    let open = |lane: i64| road.has_lane(lane) && road.lane_end(LaneId(lane as u32)) > s;
    let limit = road.speed_limit(target_lane);
    let mut mask = [false; 5];
    mask[META_LANE_LEFT as usize] = open(lane - 1);
    mask[META_IDLE as usize] = true;
    mask[META_LANE_RIGHT as usize] = open(lane + 1);
    mask[META_FASTER as usize] = target_speed < limit - 1e-6;
    mask[META_SLOWER as usize] = target_speed > 1e-6;
    mask
}

/// The meta action that best reproduces `decision` (the expert's command) for a vehicle
/// at `speed` aiming for `target_speed` with speed limit `limit`: its lane change if it
/// makes one and `mask` allows it, else whichever of idle, faster and slower makes the
/// speed controller's acceleration closest to the decided one (idle on a tie).
pub fn meta_equivalent(decision: &Decision, mask: [bool; 5], speed: f64, target_speed: f64, limit: f64) -> u32 {
    let turn = match decision.lane_change {
        LaneChange::Left => Some(META_LANE_LEFT),
        LaneChange::Right => Some(META_LANE_RIGHT),
        LaneChange::Keep => None,
    };
    if let Some(turn) = turn.filter(|&turn| mask[turn as usize]) {
        return turn;
    }
    let idm = IdmParams::default();
    let controlled =
        |target: f64| ((target - speed) / idm.speed_time_constant).clamp(-idm.accel_limit, idm.accel_limit);
    let candidates = [
        (META_IDLE, target_speed),
        (META_FASTER, rung_above(target_speed, limit)),
        (META_SLOWER, rung_below(target_speed)),
    ];
    candidates
        .into_iter()
        .filter(|&(action, _)| mask[action as usize])
        .map(|(action, target)| (action, (controlled(target) - decision.accel).abs()))
        .fold((META_IDLE, f64::INFINITY), |best, next| if next.1 < best.1 { next } else { best })
        .0
}

/// Applies `action` (none: the default, idle or zero) to agent `id`; returns whether it
/// acted (false for a meta action that can do nothing now).
pub fn apply(world: &mut World, id: VehicleId, action: Option<&Action>, kind: ActionType) -> bool {
    match (kind, action) {
        (ActionType::Meta, action) => {
            world.command_agent(id, AgentCommand::Track);
            let Some(&Action::Meta(choice)) = action else { return true };
            let vehicle = world.vehicle(id);
            let (lane, target) = (vehicle.target_lane, vehicle.target_speed);
            let mask = meta_mask(world.road(), lane, target, vehicle.state.s);
            if !mask[choice as usize] {
                return choice == META_IDLE;
            }
            let limit = world.road().speed_limit(lane);
            match choice {
                META_LANE_LEFT => world.change_lane(id, LaneId(lane.0 - 1)),
                META_LANE_RIGHT => world.change_lane(id, LaneId(lane.0 + 1)),
                META_FASTER => world.set_target_speed(id, rung_above(target, limit)),
                META_SLOWER => world.set_target_speed(id, rung_below(target)),
                _ => {}
            }
            true
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
            true
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ladder_steps_five_metres_per_second_from_a_stop_to_the_limit() {
        assert_eq!((rung_above(20.0, 25.0), rung_above(22.0, 25.0), rung_above(25.0, 25.0)), (25.0, 25.0, 25.0));
        assert_eq!((rung_above(0.0, 30.0), rung_above(27.0, 28.0)), (5.0, 28.0));
        assert_eq!((rung_below(20.0), rung_below(22.0), rung_below(5.0), rung_below(0.0)), (15.0, 20.0, 0.0, 0.0));
        let road = Road::straight(100.0, 2, 4.0, 25.0);
        let mask = |target| meta_mask(&road, LaneId(0), target, 0.0);
        assert_eq!(mask(25.0), [false, true, true, false, true]);
        assert_eq!(mask(0.0), [false, true, true, true, false]);
    }

    #[test]
    fn the_meta_expert_is_the_action_whose_speed_control_comes_closest() {
        let decision = |accel, lane_change| Decision { accel, lane_change, ..Decision::default() };
        let all = [true; 5];
        // At 20 m/s aiming for 20: idle gives 0, faster +6 (clamped), slower -6.
        assert_eq!(meta_equivalent(&decision(-0.5, LaneChange::Keep), all, 20.0, 20.0, 25.0), META_IDLE);
        assert_eq!(meta_equivalent(&decision(-4.0, LaneChange::Keep), all, 20.0, 20.0, 25.0), META_SLOWER);
        assert_eq!(meta_equivalent(&decision(5.0, LaneChange::Keep), all, 20.0, 20.0, 25.0), META_FASTER);
        // Aiming for 25 at 20 the controller would push +6; for +2, slowing the target to
        // 20 (controller: 0) comes closer.
        assert_eq!(meta_equivalent(&decision(2.0, LaneChange::Keep), all, 20.0, 25.0, 25.0), META_SLOWER);
        assert_eq!(meta_equivalent(&decision(0.0, LaneChange::Left), all, 20.0, 20.0, 25.0), META_LANE_LEFT);
        // A lane change the mask forbids falls back to the speed.
        let no_left = [false, true, true, true, true];
        assert_eq!(meta_equivalent(&decision(5.0, LaneChange::Left), no_left, 20.0, 20.0, 25.0), META_FASTER);
    }
}
