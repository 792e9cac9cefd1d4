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

use arena_protocol::{Action, ActionType, ErrorCode, MetaAction, Space};

use arena_sim::Command;
use arena_sim::Decision;
use arena_sim::{AgentCommand, VehicleId, World};
use arena_sim::{IdmParams, speed_control};
use arena_sim::{LaneChange, LaneId, Road};

/// Which meta actions can act now, indexed by `MetaAction::code`.
pub type MetaMask = [bool; MetaAction::ALL.len()];

/// The rungs of the target-speed ladder of `faster` and `slower` (m/s): 0, 5, 10, ... up
/// to the lane's limit (which is a rung too). highway-env spaces its target speeds 5 m/s
/// apart (20, 25, 30 on highway-v0); the ladder continues down to a stop.
pub const TARGET_SPEED_STEP: f64 = 5.0;

/// The acceleration (m/s^2) a continuous action of 1 asks for: highway-env's
/// ContinuousAction range, [-6, 6] m/s^2 (its ACCELERATION_RANGE).
pub const CONTINUOUS_ACCEL_SCALE: f64 = 6.0;

/// The action space of an agent driving with `kind`: the protocol's
/// (`ActionType::space`), which clients see in `EnvSpecs`.
pub fn space(kind: ActionType) -> Space {
    kind.space()
}

/// Refuses an action of the wrong type, out of its space, or not finite: the one check
/// an action gets (clients refuse only what the wire cannot carry).
pub fn check(action: &Action, kind: ActionType) -> Result<(), (ErrorCode, String)> {
    match (action, kind) {
        (Action::Meta(_), ActionType::Meta) | (Action::Continuous(_), ActionType::Continuous) => {
            kind.space().contains_action(action).map_err(|message| (ErrorCode::InvalidAction, message))
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

/// Which meta actions make a difference now for a vehicle at `s` aiming for
/// `target_speed` in `target_lane` (whose speed limit caps `faster`).
pub fn meta_mask(road: &Road, target_lane: LaneId, target_speed: f64, s: f64) -> MetaMask {
    let lane = i64::from(target_lane.0);
    let open = |lane: i64| road.has_lane(lane) && road.lane_end(LaneId(lane as u32)) > s;
    let limit = road.speed_limit(target_lane);
    MetaAction::ALL.map(|action| match action {
        MetaAction::LaneLeft => open(lane - 1),
        MetaAction::Idle => true,
        MetaAction::LaneRight => open(lane + 1),
        MetaAction::Faster => target_speed < limit - 1e-6,
        MetaAction::Slower => target_speed > 1e-6,
    })
}

fn allowed(mask: &MetaMask, action: MetaAction) -> bool {
    mask[action.code() as usize]
}

/// The meta action that best reproduces `decision` (the expert's command) for a vehicle
/// at `speed` aiming for `target_speed` with speed limit `limit`: its lane change if it
/// makes one and `mask` allows it, else whichever of idle, faster and slower makes the
/// speed controller's acceleration (`idm`'s, as the world runs it) closest to the decided
/// one (idle on a tie).
pub fn meta_equivalent(
    decision: &Decision,
    mask: MetaMask,
    idm: &IdmParams,
    speed: f64,
    target_speed: f64,
    limit: f64,
) -> MetaAction {
    let turn = match decision.lane_change {
        LaneChange::Left => Some(MetaAction::LaneLeft),
        LaneChange::Right => Some(MetaAction::LaneRight),
        LaneChange::Keep => None,
    };
    if let Some(turn) = turn.filter(|&turn| allowed(&mask, turn)) {
        return turn;
    }
    let candidates = [
        (MetaAction::Idle, target_speed),
        (MetaAction::Faster, rung_above(target_speed, limit)),
        (MetaAction::Slower, rung_below(target_speed)),
    ];
    candidates
        .into_iter()
        .filter(|&(action, _)| allowed(&mask, action))
        .map(|(action, target)| (action, (speed_control(idm, target, speed) - decision.accel).abs()))
        .fold((MetaAction::Idle, f64::INFINITY), |best, next| if next.1 < best.1 { next } else { best })
        .0
}

/// The target speed after meta action `action` from `target` (the lane's `limit` caps it).
pub fn target_after(action: MetaAction, target: f64, limit: f64) -> f64 {
    match action {
        MetaAction::Faster => rung_above(target, limit),
        MetaAction::Slower => rung_below(target),
        MetaAction::LaneLeft | MetaAction::Idle | MetaAction::LaneRight => target,
    }
}

/// Applies `action` (none: the default, idle or zero) to agent `id`; returns whether it
/// acted (false for a meta action that can do nothing now).
pub fn apply(world: &mut World, id: VehicleId, action: Option<&Action>, kind: ActionType) -> bool {
    match (kind, action) {
        (ActionType::Meta, action) => {
            world.command_agent(id, AgentCommand::Track);
            // `check` has refused codes outside the space.
            let Some(choice) = action.and_then(|action| match action {
                Action::Meta(code) => MetaAction::from_code(*code),
                Action::Continuous(_) => None,
            }) else {
                return true;
            };
            let vehicle = world.vehicle(id);
            let (lane, target) = (vehicle.target_lane, vehicle.target_speed);
            if !allowed(&meta_mask(world.road(), lane, target, vehicle.state.s), choice) {
                return choice == MetaAction::Idle;
            }
            let limit = world.road().speed_limit(lane);
            match choice {
                MetaAction::LaneLeft => world.change_lane(id, LaneId(lane.0 - 1)),
                MetaAction::LaneRight => world.change_lane(id, LaneId(lane.0 + 1)),
                MetaAction::Faster | MetaAction::Slower => {
                    world.set_target_speed(id, target_after(choice, target, limit))
                }
                MetaAction::Idle => {}
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
        use MetaAction::{Faster, Idle, LaneLeft, Slower};
        let decision = |accel, lane_change| Decision { accel, lane_change, ..Decision::default() };
        let all = [true; 5];
        let idm = IdmParams::default();
        let expert = |d: Decision, mask, target| meta_equivalent(&d, mask, &idm, 20.0, target, 25.0);
        // At 20 m/s aiming for 20: idle gives 0, faster +6 (clamped), slower -6.
        assert_eq!(expert(decision(-0.5, LaneChange::Keep), all, 20.0), Idle);
        assert_eq!(expert(decision(-4.0, LaneChange::Keep), all, 20.0), Slower);
        assert_eq!(expert(decision(5.0, LaneChange::Keep), all, 20.0), Faster);
        // Aiming for 25 at 20 the controller would push +6; for +2, slowing the target to
        // 20 (controller: 0) comes closer.
        assert_eq!(expert(decision(2.0, LaneChange::Keep), all, 25.0), Slower);
        assert_eq!(expert(decision(0.0, LaneChange::Left), all, 20.0), LaneLeft);
        // A lane change the mask forbids falls back to the speed.
        let no_left = [false, true, true, true, true];
        assert_eq!(expert(decision(5.0, LaneChange::Left), no_left, 20.0), Faster);
    }
}
