//! The explain phase: with `CreateOptions::explain`, the world explains every
//! game-theoretic decision (`arena_sim::explain`, recomputed from the scene and memory the
//! decision read) and this module turns each into the protocol's `DecisionExplained`
//! (vehicle indices, paths in world coordinates) for the step reply. It also refuses, at
//! reset, a world whose explanations would not fit a reply.

use arena_protocol::{DecisionExplained, ErrorCode, ErrorReply, GameTable, GtRole, PathPoint};
use arena_sim::{Explanation, Game, Kinematics, Road, Role, SideExplained, Stepper, VehicleId, World};

use super::error;

/// The bytes explanations may add to one reply: three eighths of the message limit (a
/// recording may add half, the agents' rows have the rest; docs/reliability.md).
const MAX_EXPLAIN_BYTES: usize = arena_protocol::MAX_MESSAGE_BYTES / 8 * 3;

/// The most bytes one car's explanation can encode to, with `accels` values in each
/// player's acceleration grid and `samples` points per path: two sides of at most 2 x
/// `accels` rows (keep and change) by `accels` columns, two costs a cell, plus the
/// actions, the pruned flags and the paths.
pub(super) fn bytes_per_decision(accels: usize, samples: usize) -> usize {
    let (rows, cols) = (2 * accels, accels);
    let side = rows * cols * 2 * 9 + rows * 11 + cols * 9 + 64;
    2 * side + 2 * samples * 33 + 128
}

/// Refuses explaining a world whose decisions of one step (`periods` control periods)
/// could not fit a reply.
pub fn check_fits(world: &World, periods: usize) -> Result<(), ErrorReply> {
    let mut bytes = 0usize;
    for id in (0..world.vehicles().len()).map(|i| VehicleId(i as u32)) {
        if let Some(setup) = world.gt_setup(id) {
            let g = &setup.params.decision.game;
            let accels = ((g.accel_max - g.accel_min) / g.accel_step).round().max(0.0) as usize + 1;
            let samples = setup.params.decision.prediction.samples;
            bytes = bytes.saturating_add(bytes_per_decision(accels, samples).saturating_mul(periods));
        }
    }
    if bytes > MAX_EXPLAIN_BYTES {
        return Err(error(
            ErrorCode::InvalidScenario,
            format!(
                "explain: the game-theoretic cars' decisions of one step may take {bytes} bytes, more than the \
                 {MAX_EXPLAIN_BYTES} explanations may add to a reply; use fewer game-theoretic cars, a coarser \
                 decision.game.accel_step or a shorter sim.step_dt"
            ),
        ));
    }
    Ok(())
}

/// The stepper's explanations since the last call, for a step reply.
pub fn take(stepper: &mut Stepper, road: &Road) -> Vec<DecisionExplained> {
    let explanations = stepper.take_explanations();
    explanations.iter().map(|e| explained(road, e)).collect()
}

fn explained(road: &Road, e: &Explanation) -> DecisionExplained {
    let played = &e.played;
    let tables: Vec<GameTable> = played
        .sides
        .iter()
        .zip(e.adjacent)
        .filter_map(|(side, adjacent)| Some(table(side.as_ref()?, adjacent.map(|id| id.0))))
        .collect();
    // The chosen side's index among the sides played.
    let chosen = played.chosen.map(|at| played.sides[..at].iter().filter(|s| s.is_some()).count() as u32);
    let follows = e.ec != e.vehicle;
    let from_table = played.chosen.and_then(|at| played.sides[at].as_ref()).map(|side| match follows {
        true => side.ac_actions[side.col],
        false => side.ec_actions[side.row].0,
    });
    // What the games chose, as the driver took it: before the safety layer lowered it;
    // after a fallback, the driver keeps no trace of it and the table says.
    let games_accel = match (e.safety, e.fallback) {
        (Some(limited), _) => limited.decided,
        (None, true) => from_table.unwrap_or(e.decision.accel),
        (None, false) => e.decision.accel,
    };
    DecisionExplained {
        time: e.time,
        vehicle: e.vehicle.0,
        game: match e.game {
            Game::Nash => arena_protocol::Game::Nash,
            Game::Stackelberg => arena_protocol::Game::Stackelberg,
        },
        role: match e.role {
            Role::Leader => GtRole::Leader,
            Role::Follower => GtRole::Follower,
        },
        ec: e.ec.0,
        tables,
        chosen,
        games_accel,
        accel: e.decision.accel,
        sigma: e.decision.lane_change.sigma(),
        safety: e.safety.is_some(),
        fallback: e.fallback,
        planned: path(road, &played.planned, &played.times),
        predicted: path(road, &played.predicted, &played.times),
    }
}

fn table(side: &SideExplained, adjacent: Option<u32>) -> GameTable {
    GameTable {
        side: side.side,
        adjacent,
        ec_actions: side.ec_actions.clone(),
        ac_actions: side.ac_actions.clone(),
        ec_costs: side.ec.clone(),
        ac_costs: side.ac.clone(),
        pruned: side.pruned.clone(),
        row: side.row as u32,
        col: side.col as u32,
        exact: side.exact,
        cost: side.cost,
    }
}

fn path(road: &Road, samples: &[Kinematics], times: &[f64]) -> Vec<PathPoint> {
    samples
        .iter()
        .zip(times)
        .map(|(k, &t)| {
            let pose = road.to_global(k.s, k.d, 0.0);
            PathPoint { t, x: pose.x, y: pose.y, speed: k.speed }
        })
        .collect()
}
