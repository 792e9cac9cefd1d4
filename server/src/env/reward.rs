//! Rewards and infos (docs/rewards.md). An agent's reward for a step is the paper's cost
//! J (eq. 9, with its own style's Table III weights, averaged over the step's control
//! periods: the yardstick the built-in AV decides by) mapped into (0, 1] by
//! J_0 / (J_0 + J), as highway-env maps its rewards into [0, 1], times the share of its
//! aimed-for speed it drove (the paper's J charges nothing for standing still behind a
//! lane end or a slow car, and PPO learned to stop); the step it crashes
//! or leaves the road earns `RewardSpec::crash` (by default minus the episode length, so
//! any episode with a crash returns less than any without). Infos carry the raw cost and
//! its three components so learners can be compared on each.

use arena_protocol::{Info, InfoValue};

use arena_sim::gt::{CostComponents, stage_cost};
use arena_sim::scenario::RewardSpec;
use arena_sim::world::{Status, VehicleId, World};

/// The reward of one step: `spec.crash` (default: minus `max_cycles`) on the step the
/// agent crashes or leaves the road, else J_0 / (J_0 + J) times the step's mean speed
/// over `aim` (at most 1): in [0, 1].
pub fn reward(spec: &RewardSpec, max_cycles: u32, step: &StepCost, aim: f64, crashed_now: bool) -> f64 {
    if crashed_now {
        return spec.crash.unwrap_or(-f64::from(max_cycles));
    }
    if step.weighted.is_nan() {
        return 0.0;
    }
    let progress = if aim > 0.0 { (step.speed / aim).clamp(0.0, 1.0) } else { 1.0 };
    spec.cost_scale / (spec.cost_scale + step.weighted.max(0.0)) * progress
}

/// Why a vehicle's episode ended, for the `end_reason` info: `collision`, `lane_end`
/// (drove past the end of its lane), `off_road` (over the road's edge) or `road_end`
/// (reached the end of the road).
pub fn end_reason(world: &World, id: VehicleId) -> &'static str {
    let vehicle = world.vehicle(id);
    match vehicle.status {
        Status::Crashed => "collision",
        Status::Exited => "road_end",
        Status::OffRoad => {
            let road = world.road();
            let lane = road.nearest_lane(vehicle.state.d);
            let within = (vehicle.state.d - road.lane_center(lane)).abs() <= road.lane_width() / 2.0;
            if within && vehicle.state.s > road.lane_end(lane) { "lane_end" } else { "off_road" }
        }
        Status::Driving => "driving",
    }
}

/// The cost of one agent over one env step, sampled at the end of each control period
/// it was driving.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepCost {
    /// Mean of the three components.
    pub components: CostComponents,
    /// Mean of J = w . components with the agent's style weights.
    pub weighted: f64,
    /// Sum of the squares of each component's samples, for the episode's RMS.
    pub squares: CostComponents,
    /// How many samples.
    pub samples: u32,
    /// Mean speed along the lane (m/s) at the samples.
    pub speed: f64,
}

/// Advances the world by `step_dt` and writes into `costs` each vehicle's mean cost over
/// it, sampled once per control period (a buffer the caller keeps: steps allocate nothing
/// for it).
pub fn advance(world: &mut World, vehicles: &[VehicleId], step_dt: f64, costs: &mut Vec<StepCost>) {
    let per_control = world.params().substeps_per_control();
    let ticks = (step_dt / world.params().physics_dt).round() as u64;
    let sums = costs;
    sums.clear();
    sums.resize(vehicles.len(), StepCost::default());
    let mut samples = 0u32;
    for tick in 0..ticks {
        world.tick();
        if (tick + 1).is_multiple_of(per_control) || tick + 1 == ticks {
            samples += 1;
            for (sum, &id) in sums.iter_mut().zip(vehicles) {
                if world.vehicle(id).status == Status::Driving {
                    let params = world.gt_params(id);
                    let cost = stage_cost(world.scene(), id, &params);
                    sum.components = sum.components + cost;
                    sum.squares = sum.squares + cost.squared();
                    sum.samples += 1;
                    sum.speed += world.vehicle(id).state.lane_speed();
                    sum.weighted += cost.weighted(world.vehicle(id).style);
                }
            }
        }
    }
    let n = f64::from(samples.max(1));
    for sum in sums.iter_mut() {
        *sum = StepCost {
            components: CostComponents {
                safety: sum.components.safety / n,
                comfort: sum.components.comfort / n,
                efficiency: sum.components.efficiency / n,
            },
            weighted: sum.weighted / n,
            speed: sum.speed / n,
            ..*sum
        };
    }
}

/// More than the entries of any step's info (facts, costs, the episode's figures at its
/// end, the expert's action, diagnostics).
const INFO_ENTRIES: usize = 32;

/// Facts about an agent's vehicle, and its step cost when there is one.
pub fn info(world: &World, id: VehicleId, cost: Option<&StepCost>) -> Info {
    let vehicle = world.vehicle(id);
    // Room for every entry a step adds, so the list is allocated once.
    let mut values = Vec::with_capacity(INFO_ENTRIES);
    values.extend([
        ("speed".to_string(), InfoValue::F64(vehicle.state.vx)),
        ("lane".to_string(), InfoValue::I64(world.road().nearest_lane(vehicle.state.d).0 as i64)),
        ("s".to_string(), InfoValue::F64(vehicle.state.s)),
        ("crashed".to_string(), InfoValue::Bool(vehicle.status == Status::Crashed)),
        ("off_road".to_string(), InfoValue::Bool(vehicle.status == Status::OffRoad)),
    ]);
    if let Some(cost) = cost {
        values.push(("cost".to_string(), InfoValue::F64(cost.weighted)));
        values.push(("cost_safety".to_string(), InfoValue::F64(cost.components.safety)));
        values.push(("cost_comfort".to_string(), InfoValue::F64(cost.components.comfort)));
        values.push(("cost_efficiency".to_string(), InfoValue::F64(cost.components.efficiency)));
    }
    Info { values }
}
