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
use crate::scenario::Scenario;
use crate::world::{VehicleId, World};

/// Rows of the kinematics matrix: the agent and its nearest neighbours.
pub const KINEMATICS_VEHICLES: usize = 5;
/// Columns: presence, s, d, v_s, v_d, cos h, sin h.
pub const KINEMATICS_FEATURES: usize = 7;

/// Longitudinal range (m) a vehicle is seen within and normalised by.
const SIGHT: f64 = 100.0;
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

fn features(world: &World, id: VehicleId, origin: Option<VehicleId>) -> [f32; KINEMATICS_FEATURES] {
    let vehicle = world.vehicle(id);
    let state = &vehicle.state;
    let (sin, cos) = state.heading.sin_cos();
    let (v_s, v_d) = (state.vx * cos - state.vy * sin, state.vx * sin + state.vy * cos);
    let width = world.road.lane_width() * world.road.lane_count() as f64;
    let (mut s, mut d, mut vs, mut vd) =
        (state.s / world.road.length(), state.d / width, v_s / MAX_SPEED, v_d / MAX_SPEED);
    if let Some(origin) = origin.filter(|&o| o != id) {
        let o = &world.vehicle(origin).state;
        let (osin, ocos) = o.heading.sin_cos();
        s = (state.s - o.s) / SIGHT;
        d = (state.d - o.d) / width;
        vs = (v_s - (o.vx * ocos - o.vy * osin)) / MAX_SPEED;
        vd = (v_d - (o.vx * osin + o.vy * ocos)) / MAX_SPEED;
    } else if origin.is_some() {
        s = 0.0;
    }
    [1.0, s, d, vs, vd, cos, sin].map(|x| x.clamp(-1.0, 1.0) as f32)
}

/// The kinematics matrix of agent `id`, flattened row by row.
pub fn kinematics(world: &World, id: VehicleId) -> Tensor {
    let me = world.vehicle(id).state.s;
    let mut near: Vec<(f64, u32)> = world
        .vehicles
        .iter()
        .enumerate()
        .filter(|&(i, v)| i as u32 != id.0 && v.on_road() && (v.state.s - me).abs() <= SIGHT)
        .map(|(i, v)| ((v.state.s - me).abs(), i as u32))
        .collect();
    near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut data = Vec::with_capacity(KINEMATICS_VEHICLES * KINEMATICS_FEATURES);
    data.extend(features(world, id, Some(id)));
    for &(_, other) in near.iter().take(KINEMATICS_VEHICLES - 1) {
        data.extend(features(world, VehicleId(other), Some(id)));
    }
    data.resize(KINEMATICS_VEHICLES * KINEMATICS_FEATURES, 0.0);
    Tensor { shape: vec![(KINEMATICS_VEHICLES * KINEMATICS_FEATURES) as u32], data: TensorData::F32(data) }
}

/// What agent `id` observes.
pub fn observe(kind: ObservationKind, world: &World, id: VehicleId, action: ActionType) -> Observation {
    let matrix = kinematics(world, id);
    match kind {
        ObservationKind::Kinematics => Observation::Tensor(matrix),
        ObservationKind::KinematicsWithMask => {
            let mask = match action {
                ActionType::Meta => meta_mask(world, id).map(i8::from).to_vec(),
                ActionType::Continuous => vec![1; 5],
            };
            let mask = Tensor { shape: vec![5], data: TensorData::I8(mask) };
            Observation::Dict(vec![("action_mask".to_string(), mask), ("observation".to_string(), matrix)])
        }
    }
}

/// Every vehicle's absolute features, rows in vehicle order; vehicles gone are zeros.
pub fn state(world: &World, scenario: &Scenario) -> Observation {
    let rows = vehicle_count(scenario);
    let mut data = Vec::with_capacity(rows * KINEMATICS_FEATURES);
    for (i, vehicle) in world.vehicles.iter().enumerate().take(rows) {
        if vehicle.on_road() {
            data.extend(features(world, VehicleId(i as u32), None));
        } else {
            data.extend([0.0; KINEMATICS_FEATURES]);
        }
    }
    data.resize(rows * KINEMATICS_FEATURES, 0.0);
    Observation::Tensor(Tensor { shape: vec![(rows * KINEMATICS_FEATURES) as u32], data: TensorData::F32(data) })
}
