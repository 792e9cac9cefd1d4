//! Rewards and infos. An agent's reward for a step is minus the paper's cost J (eq. 9,
//! with its own style's Table III weights) averaged over the step's control periods,
//! minus a penalty the step it crashes: the yardstick the built-in AV decides by. Infos
//! carry the three cost components so learners can be compared on each.

use arena_protocol::{Info, InfoValue};

use arena_sim::gt::{CostComponents, stage_cost};
use arena_sim::world::{Status, VehicleId, World};

/// Subtracted from the reward on the step an agent crashes. Chosen here to exceed what
/// J reaches in ordinary driving, so that no cost saved is worth a collision.
pub const COLLISION_PENALTY: f64 = 1.0e4;

/// The mean cost components of one agent over one env step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepCost {
    /// Mean of the three components.
    pub components: CostComponents,
    /// Mean of J = w . components with the agent's style weights.
    pub weighted: f64,
}

/// Advances the world by `step_dt` and returns each vehicle's mean cost over it,
/// sampled once per control period.
pub fn advance(world: &mut World, vehicles: &[VehicleId], step_dt: f64) -> Vec<StepCost> {
    let per_control = world.params().substeps_per_control();
    let ticks = (step_dt / world.params().physics_dt).round() as u64;
    let mut sums = vec![StepCost::default(); vehicles.len()];
    let mut samples = 0u32;
    for tick in 0..ticks {
        world.tick();
        if (tick + 1).is_multiple_of(per_control) || tick + 1 == ticks {
            samples += 1;
            for (sum, &id) in sums.iter_mut().zip(vehicles) {
                if world.vehicle(id).status == Status::Driving {
                    let params = world.gt_params(id);
                    let cost = stage_cost(world.scene(), id, &params);
                    sum.components.safety += cost.safety;
                    sum.components.comfort += cost.comfort;
                    sum.components.efficiency += cost.efficiency;
                    sum.weighted += cost.weighted(world.vehicle(id).style);
                }
            }
        }
    }
    let n = f64::from(samples.max(1));
    sums.iter()
        .map(|sum| StepCost {
            components: CostComponents {
                safety: sum.components.safety / n,
                comfort: sum.components.comfort / n,
                efficiency: sum.components.efficiency / n,
            },
            weighted: sum.weighted / n,
        })
        .collect()
}

/// Facts about an agent's vehicle, and its step cost when there is one.
pub fn info(world: &World, id: VehicleId, cost: Option<&StepCost>) -> Info {
    let vehicle = world.vehicle(id);
    let mut values = vec![
        ("speed".to_string(), InfoValue::F64(vehicle.state.vx)),
        ("lane".to_string(), InfoValue::I64(world.road().nearest_lane(vehicle.state.d).0 as i64)),
        ("s".to_string(), InfoValue::F64(vehicle.state.s)),
        ("crashed".to_string(), InfoValue::Bool(vehicle.status == Status::Crashed)),
        ("off_road".to_string(), InfoValue::Bool(vehicle.status == Status::OffRoad)),
    ];
    if let Some(cost) = cost {
        values.push(("cost".to_string(), InfoValue::F64(cost.weighted)));
        values.push(("cost_safety".to_string(), InfoValue::F64(cost.components.safety)));
        values.push(("cost_comfort".to_string(), InfoValue::F64(cost.components.comfort)));
        values.push(("cost_efficiency".to_string(), InfoValue::F64(cost.components.efficiency)));
    }
    Info { values }
}
