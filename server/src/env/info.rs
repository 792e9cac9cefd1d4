//! The info phase of a step: every agent's info in the one schema of
//! `arena_protocol::info` (the same keys, types and order on reset and on every step;
//! docs/protocol.md), built here and nowhere else; then the keys an option turns on, on
//! every step while it is on: what the built-in AV would do (`expert`) and the
//! game-theoretic cars' solver counts (`diagnostics`).

use arena_protocol::info::{self as key, DIAGNOSTIC_COUNTS};
use arena_protocol::{ActionType, EndReason, Info, InfoValue, MetaAction};

use arena_sim::Decision;
use arena_sim::{Driver, Game, GtMemory, Status, VehicleId, World};

use super::action;
use super::episode::Figures;
use super::simulate::StepCost;

/// What the step did to one agent, beyond its vehicle's state.
pub struct Outcome<'a> {
    /// The step's cost; `None` on reset.
    pub cost: Option<&'a StepCost>,
    /// Whether its action acted.
    pub applied: bool,
    /// Why its episode ended, or `Running`.
    pub end: EndReason,
    /// Its episode's figures (zero until it ended).
    pub figures: Figures,
}

impl Outcome<'_> {
    /// A reset's: nothing happened yet.
    pub fn start() -> Outcome<'static> {
        Outcome { cost: None, applied: true, end: EndReason::Running, figures: Figures::default() }
    }
}

/// The `SCHEMA` part of vehicle `id`'s info, in its order.
pub fn info(world: &World, id: VehicleId, outcome: &Outcome) -> Info {
    let vehicle = world.vehicle(id);
    let cost = outcome.cost.copied().unwrap_or_default();
    let f = &outcome.figures;
    let collision = world.collision_of(id);
    let collision_with = collision.and_then(|c| c.other(id)).map_or(-1, |other| i64::from(other.0));
    let at_fault = collision.is_some_and(|c| c.is_at_fault(id));
    let values = [
        (key::SPEED, InfoValue::F64(vehicle.state.vx)),
        (key::LANE, InfoValue::I64(i64::from(world.road().nearest_lane(vehicle.state.d).0))),
        (key::S, InfoValue::F64(vehicle.state.s)),
        (key::CRASHED, InfoValue::Bool(vehicle.status == Status::Crashed)),
        (key::OFF_ROAD, InfoValue::Bool(vehicle.status == Status::OffRoad)),
        (key::COST, InfoValue::F64(cost.weighted)),
        (key::COST_SAFETY, InfoValue::F64(cost.components.safety)),
        (key::COST_COMFORT, InfoValue::F64(cost.components.comfort)),
        (key::COST_EFFICIENCY, InfoValue::F64(cost.components.efficiency)),
        (key::ACTION_APPLIED, InfoValue::Bool(outcome.applied)),
        (key::END_REASON, InfoValue::I64(outcome.end.code())),
        (key::COLLISION_WITH, InfoValue::I64(collision_with)),
        (key::AT_FAULT, InfoValue::I64(i64::from(at_fault))),
        (key::EPISODE_DONE, InfoValue::Bool(f.done)),
        (key::EPISODE_SUCCESS, InfoValue::Bool(f.success)),
        (key::EPISODE_RETURN, InfoValue::F64(f.total_reward)),
        (key::EPISODE_LENGTH, InfoValue::I64(i64::from(f.length))),
        (key::EPISODE_MEAN_SPEED, InfoValue::F64(f.mean_speed)),
        (key::EPISODE_MIN_GAP, InfoValue::F64(f.min_gap)),
        (key::EPISODE_MIN_TTC, InfoValue::F64(f.min_ttc)),
        (key::EPISODE_RMS_SAFETY, InfoValue::F64(f.rms.safety)),
        (key::EPISODE_RMS_COMFORT, InfoValue::F64(f.rms.comfort)),
        (key::EPISODE_RMS_EFFICIENCY, InfoValue::F64(f.rms.efficiency)),
        (key::EPISODE_T_C, InfoValue::F64(f.t_c)),
        (key::EPISODE_P95_JERK, InfoValue::F64(f.p95_jerk)),
        (key::EPISODE_MAX_JERK, InfoValue::F64(f.max_jerk)),
    ];
    let mut info = Info { values: Vec::with_capacity(ENTRIES) };
    for (name, value) in values {
        info.push(name, value);
    }
    info
}

/// The keys of `asked` (the env's `info_keys`) if each is one its infos have: the
/// schema's, the expert's with `expert`, a game-theoretic car's counts (`gt.<car>.<count>`)
/// with `diagnostics`; else what is wrong with the first that is not.
pub fn kept_keys(asked: &[String], expert: bool, diagnostics: bool) -> Result<Vec<String>, String> {
    let schema = || key::SCHEMA.iter().map(|(name, _)| *name).collect::<Vec<_>>().join(", ");
    for asked in asked {
        let in_schema = key::SCHEMA.iter().any(|(name, _)| name == asked);
        let of_expert = key::EXPERT.iter().any(|(name, _)| name == asked);
        let of_diagnostics = asked
            .strip_prefix("gt.")
            .and_then(|rest| rest.rsplit_once('.'))
            .is_some_and(|(car, count)| !car.is_empty() && DIAGNOSTIC_COUNTS.contains(&count));
        if in_schema || (of_expert && expert) || (of_diagnostics && diagnostics) {
            continue;
        }
        return Err(if of_expert {
            format!("info_keys: '{asked}' is in infos only with the `expert` option; give expert= too, or leave it out")
        } else if of_diagnostics {
            format!("info_keys: '{asked}' is in infos only with `diagnostics`; turn it on, or leave the key out")
        } else {
            format!("info_keys: no info key '{asked}'; the keys are {}", schema())
        });
    }
    Ok(asked.to_vec())
}

/// Keeps only `kept`'s keys of `info`, in its own order (`None` keeps all).
pub fn keep(info: &mut Info, kept: Option<&[String]>) {
    if let Some(kept) = kept {
        info.values.retain(|(name, _)| kept.contains(name));
    }
}

/// More than the entries of any info (the schema, the expert's keys, a few cars'
/// diagnostics), so an info is allocated once.
const ENTRIES: usize = key::SCHEMA.len() + key::EXPERT.len() + 2 * DIAGNOSTIC_COUNTS.len();

/// The expert's keys: its action in the agent's own space, its acceleration and its σ.
/// An agent whose episode ended gets the neutral ones (idle, or zeros).
pub fn add_expert(info: &mut Info, action: ActionType, expert: Option<(Decision, InfoValue)>) {
    let (decision, action) = expert.unwrap_or_else(|| {
        let idle = match action {
            ActionType::Meta => InfoValue::I64(i64::from(MetaAction::Idle.code())),
            ActionType::Continuous => InfoValue::F64s(vec![0.0, 0.0]),
        };
        (Decision::default(), idle)
    });
    info.push(key::EXPERT_ACTION, action);
    info.push(key::EXPERT_ACCEL, InfoValue::F64(decision.accel));
    info.push(key::EXPERT_SIGMA, InfoValue::I64(i64::from(decision.lane_change.sigma())));
}

/// What the built-in AV does in agent `id`'s place next, as the agent's own action: for
/// a meta agent the meta action that best reproduces the AV's decision; for a continuous
/// one the AV's whole command (its acceleration and the preview point its MPC plans,
/// relative to the current lane). When the AV drives the vehicle (the env's `policy`),
/// that is the driver's own next action, planned from a copy of its memory: the world's
/// next control period plans the same from the same scene, so the label is what it
/// does; its meta labels are chosen against `ladder`, the target speed a learner playing
/// them would have, which they then move (the AV keeps no such ladder). Otherwise it is
/// planned with the memory the AV would have had in this place.
pub fn expert(
    world: &mut World,
    id: VehicleId,
    kind: ActionType,
    (game, memory): (Game, &mut GtMemory),
    ladder: &mut f64,
) -> (Decision, InfoValue) {
    if let Driver::Gt(driving) = &world.vehicle(id).driver {
        *memory = (**driving).clone();
        let command = world.expert_command(id, game, memory);
        return match kind {
            ActionType::Meta => {
                let meta = meta_label(world, id, &memory.decision, *ladder);
                let limit = world.road().speed_limit(world.vehicle(id).target_lane);
                *ladder = action::target_after(meta, *ladder, limit);
                (memory.decision, InfoValue::I64(i64::from(meta.code())))
            }
            ActionType::Continuous => (memory.decision, continuous_label(world, id, command)),
        };
    }
    match kind {
        ActionType::Meta => {
            let decision = world.expert_decision(id, game);
            let meta = meta_label(world, id, &decision, world.vehicle(id).target_speed);
            (decision, InfoValue::I64(i64::from(meta.code())))
        }
        ActionType::Continuous => {
            let command = world.expert_command(id, game, memory);
            (memory.decision, continuous_label(world, id, command))
        }
    }
}

/// The meta action that best reproduces `decision` for vehicle `id` now, aiming for `target`.
fn meta_label(world: &World, id: VehicleId, decision: &Decision, target: f64) -> MetaAction {
    let vehicle = world.vehicle(id);
    let (lane, s) = (vehicle.target_lane, vehicle.state.s);
    let mask = action::meta_mask(world.road(), lane, target, s);
    let limit = world.road().speed_limit(lane);
    action::meta_equivalent(decision, mask, world.idm(), vehicle.state.vx, target, limit)
}

/// `command` as a continuous action of vehicle `id` now: normalised, relative to its lane.
fn continuous_label(world: &World, id: VehicleId, command: arena_sim::Command) -> InfoValue {
    let road = world.road();
    let centre = road.lane_center(world.current_lane(id));
    let accel = (command.accel / action::CONTINUOUS_ACCEL_SCALE).clamp(-1.0, 1.0);
    let offset = ((command.preview - centre) / road.lane_width()).clamp(-1.0, 1.0);
    InfoValue::F64s(vec![accel, offset])
}

/// Every game-theoretic car's solver counts since the episode began, keyed
/// `gt.<car>.<count>`, cars in the world's order (named ones by name, then traffic). No
/// timings: infos are bit-reproducible, so decision times live in the benchmarks
/// (docs/performance.md).
pub fn add_diagnostics(info: &mut Info, world: &World) {
    for (vehicle, setup) in world.vehicles().iter().zip(world.setups()) {
        let Driver::Gt(gt) = &vehicle.driver else { continue };
        let d = &gt.diagnostics;
        let counts = [
            i64::from(d.plans),
            i64::from(d.iterations),
            i64::try_from(d.iterations_total).unwrap_or(i64::MAX),
            i64::from(d.fallbacks),
            i64::from(d.inexact),
        ];
        for (count, value) in DIAGNOSTIC_COUNTS.into_iter().zip(counts) {
            info.values.push((format!("gt.{}.{count}", setup.name), InfoValue::I64(value)));
        }
    }
}
