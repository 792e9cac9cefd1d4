//! What agents see: highway-env's Kinematics observation adapted to the Frenet frame.
//! Row 0 is the agent itself, the next rows the nearest vehicles by distance along the
//! road, each [presence, s, d, v_s, v_d, cos h, sin h]; other vehicles are relative to
//! the agent. Every feature is normalised and clipped into [-1, 1], float32. The state
//! is the same features, absolute, for every vehicle of the scenario in a fixed order.
//! Both are flat vectors (rows one after another): a 2-D matrix with negative entries
//! looks like an image to PettingZoo's checks and to image-aware policies, and MLP
//! policies flatten it anyway; reshape to (rows, 7) to get the matrix back.

use arena_protocol::{ActionType, DType, Observation, ObservationKind, Space, Tensor, TensorData};

use super::action::meta_mask;
use arena_sim::Road;
use arena_sim::Scenario;
use arena_sim::VehicleState;
use arena_sim::World;
use arena_sim::{Scene, VehicleId};

/// Rows of the kinematics matrix: the agent and its nearest neighbours.
pub const KINEMATICS_VEHICLES: usize = 5;
/// Columns: presence, s, d, v_s, v_d, cos h, sin h.
pub const KINEMATICS_FEATURES: usize = 7;

/// Longitudinal range (m) a vehicle is seen within and normalised by.
pub(super) const SIGHT: f64 = 100.0;
/// Speed normalisation (m/s): highway-env's MAX_SPEED.
const MAX_SPEED: f64 = 40.0;

fn unit_box(shape: Vec<u32>) -> Space {
    let n = shape.iter().product::<u32>() as usize;
    Space::Box { low: vec![-1.0; n], high: vec![1.0; n], shape, dtype: DType::F32 }
}

/// The observation space of every agent.
pub fn space(kind: ObservationKind, _scenario: &Scenario) -> Space {
    let kinematics = unit_box(vec![(KINEMATICS_VEHICLES * KINEMATICS_FEATURES) as u32]);
    match kind {
        ObservationKind::Kinematics => kinematics,
        ObservationKind::KinematicsWithMask => Space::Dict(vec![
            (
                "action_mask".to_string(),
                Space::Box { low: vec![0.0; 5], high: vec![1.0; 5], shape: vec![5], dtype: DType::I8 },
            ),
            ("observation".to_string(), kinematics),
        ]),
    }
}

/// The state space: one row per vehicle the scenario can hold.
pub fn state_space(scenario: &Scenario) -> Space {
    unit_box(vec![(vehicle_count(scenario) * KINEMATICS_FEATURES) as u32])
}

fn vehicle_count(scenario: &Scenario) -> usize {
    scenario.vehicles.len() + scenario.traffic.as_ref().map_or(0, |t| t.count as usize)
}

/// One row: `state`'s features, relative to `origin` (the observing agent) if given.
fn features(road: &Road, state: &VehicleState, origin: Option<&VehicleState>) -> [f32; KINEMATICS_FEATURES] {
    let (sin, cos) = state.heading.sin_cos();
    let (v_s, v_d) = (state.vx * cos - state.vy * sin, state.vx * sin + state.vy * cos);
    let width = road.lane_width() * road.lane_count() as f64;
    let (mut s, mut d, mut vs, mut vd) = (state.s / road.length(), state.d / width, v_s / MAX_SPEED, v_d / MAX_SPEED);
    if let Some(o) = origin {
        let (osin, ocos) = o.heading.sin_cos();
        s = (state.s - o.s) / SIGHT;
        d = (state.d - o.d) / width;
        vs = (v_s - (o.vx * ocos - o.vy * osin)) / MAX_SPEED;
        vd = (v_d - (o.vx * osin + o.vy * ocos)) / MAX_SPEED;
    }
    [1.0, s, d, vs, vd, cos, sin].map(|x| x.clamp(-1.0, 1.0) as f32)
}

/// How near the end of the lane it is in a car at `s` is: 0 with the end out of sight
/// (beyond `SIGHT`, or a lane that runs to the road's end far ahead), rising to 1 at the
/// end. It is the own row's s (observation version 2; version 1 had 0 there): without
/// it an agent cannot tell a lane that ends from one that goes on, and a policy can
/// only spread its lane change thinly over every step (docs/scenarios.md, "Decision rate").
fn lane_end_nearness(road: &Road, lane: arena_sim::LaneId, s: f64) -> f32 {
    (1.0 - (road.lane_end(lane) - s) / SIGHT).clamp(0.0, 1.0) as f32
}

/// The agent's own row (absolute, with s the nearness of its lane's end), then the
/// nearest cars on the road within sight, by distance along the road (ties by id), found
/// through the scene's index.
pub fn kinematics(scene: &Scene, id: VehicleId) -> Tensor {
    let me = scene.car(id);
    let mut data = Vec::with_capacity(KINEMATICS_VEHICLES * KINEMATICS_FEATURES);
    let mut own = features(&scene.road, &me.state, None);
    own[1] = lane_end_nearness(&scene.road, me.lane, me.state.s);
    data.extend(own);
    for other in nearest::<{ KINEMATICS_VEHICLES - 1 }>(scene, id, me.state.s).into_iter().flatten() {
        data.extend(features(&scene.road, &scene.car(other).state, Some(&me.state)));
    }
    data.resize(KINEMATICS_VEHICLES * KINEMATICS_FEATURES, 0.0);
    Tensor { shape: vec![(KINEMATICS_VEHICLES * KINEMATICS_FEATURES) as u32], data: TensorData::F32(data) }
}

/// The K cars nearest to `s` along the road within sight, other than `id`, nearest first
/// (ties by id): kept sorted in a K-slot array as the scene's index yields them, so
/// observing allocates nothing for it.
pub(super) fn nearest<const K: usize>(scene: &Scene, id: VehicleId, s: f64) -> [Option<VehicleId>; K] {
    let mut slots: [Option<(f64, VehicleId)>; K] = [None; K];
    let closer = |a: (f64, VehicleId), b: (f64, VehicleId)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).is_lt();
    for car in scene.around(s, SIGHT).filter(|car| car.id != id) {
        let mut candidate = ((car.state.s - s).abs(), car.id);
        for slot in &mut slots {
            match slot {
                Some(held) if !closer(candidate, *held) => {}
                _ => match slot.replace(candidate) {
                    Some(displaced) => candidate = displaced,
                    None => break,
                },
            }
        }
    }
    slots.map(|slot| slot.map(|(_, id)| id))
}

/// What agent `id` observes; `scene` must be the world as it is now (`World::scene`).
pub fn observe(kind: ObservationKind, scene: &Scene, id: VehicleId, action: ActionType) -> Observation {
    let matrix = kinematics(scene, id);
    match kind {
        ObservationKind::Kinematics => Observation::Tensor(matrix),
        ObservationKind::KinematicsWithMask => {
            let mask = match action {
                ActionType::Meta => {
                    let car = scene.car(id);
                    meta_mask(&scene.road, car.target_lane, car.target_speed, car.state.s).map(i8::from).to_vec()
                }
                ActionType::Continuous => vec![1; 5],
            };
            let mask = Tensor { shape: vec![5], data: TensorData::I8(mask) };
            Observation::Dict(vec![("action_mask".to_string(), mask), ("observation".to_string(), matrix)])
        }
    }
}

pub fn state(world: &World, scenario: &Scenario) -> Observation {
    let rows = vehicle_count(scenario);
    let mut data = Vec::with_capacity(rows * KINEMATICS_FEATURES);
    for vehicle in world.vehicles().iter().take(rows) {
        if vehicle.on_road() {
            data.extend(features(world.road(), &vehicle.state, None));
        } else {
            data.extend([0.0; KINEMATICS_FEATURES]);
        }
    }
    data.resize(rows * KINEMATICS_FEATURES, 0.0);
    Observation::Tensor(Tensor { shape: vec![(rows * KINEMATICS_FEATURES) as u32], data: TensorData::F32(data) })
}
