//! The simulate phase of a step: the world advanced by one env step, tick by tick, with
//! each agent's cost (eq. 9-14) sampled at the end of every control period it drives, so
//! the reward and the infos read the step's mean cost and risk without another pass, and the
//! acceleration it was commanded in each period, for the episode's jerk; while recording,
//! a frame of the world at the end of each control period (`recording`).

use arena_sim::CostComponents;
use arena_sim::{Status, Stepper, VehicleId, World};

use super::recording::Recorder;
use super::risk;

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
    /// Mean risk at the samples (`risk::risk`, in [0, 1]).
    pub risk: f64,
}

/// Advances the world by `step_dt` and writes into `costs` each vehicle's mean cost over
/// it, and into `accels` the acceleration each was commanded in every control period
/// that ended while it drove (buffers the caller keeps: steps allocate nothing for them);
/// with a `recorder`, it notes every collision's tick and takes a frame where costs are
/// sampled.
pub fn advance(
    world: &mut World,
    stepper: &mut Stepper,
    vehicles: &[VehicleId],
    step_dt: f64,
    costs: &mut Vec<StepCost>,
    accels: &mut Vec<Vec<f64>>,
    mut recorder: Option<&mut Recorder>,
) {
    let per_control = world.params().substeps_per_control();
    let ticks = (step_dt / world.params().physics_dt).round() as u64;
    let sums = costs;
    sums.clear();
    sums.resize(vehicles.len(), StepCost::default());
    accels.resize_with(vehicles.len(), Vec::new);
    accels.iter_mut().for_each(Vec::clear);
    let mut samples = 0u32;
    for tick in 0..ticks {
        stepper.tick(world);
        if let Some(recorder) = recorder.as_deref_mut() {
            recorder.after_tick(world);
        }
        if (tick + 1).is_multiple_of(per_control) {
            for (commanded, &id) in accels.iter_mut().zip(vehicles) {
                let vehicle = world.vehicle(id);
                if vehicle.status == Status::Driving {
                    commanded.push(vehicle.command.accel);
                }
            }
        }
        if (tick + 1).is_multiple_of(per_control) || tick + 1 == ticks {
            if let Some(recorder) = recorder.as_deref_mut() {
                recorder.take_frame(world);
            }
            samples += 1;
            for (sum, &id) in sums.iter_mut().zip(vehicles) {
                if world.vehicle(id).status == Status::Driving {
                    sample(world, id, sum);
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
            risk: sum.risk / n,
            ..*sum
        };
    }
}

/// Adds vehicle `id`'s cost and speed now to `sum`.
fn sample(world: &mut World, id: VehicleId, sum: &mut StepCost) {
    let cost = world.stage_cost(id);
    let vehicle = world.vehicle(id);
    sum.components = sum.components + cost;
    sum.squares = sum.squares + cost.squared();
    sum.samples += 1;
    sum.speed += vehicle.state.lane_speed();
    sum.weighted += cost.weighted(world.style(id));
    sum.risk += risk::risk(world, id);
}
