//! The world: a road, the vehicles on it and their drivers, advanced one fixed physics
//! step at a time. `World::tick` runs its stages in order: keep the vehicles sorted
//! along the road, let the drivers decide (at the control rate), integrate the dynamics,
//! detect collisions. Neighbour queries and collision checks use the sorted order, so a
//! tick costs O(n) for n vehicles rather than O(n^2).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::dynamics::{self, Command, DriverParams, LateralPath, Style, VehicleParams, VehicleState};
use crate::road::{LaneId, Road};
use crate::traffic::{self, Car, Gap, IdmParams};

/// Index of a vehicle in its world.
#[repr(transparent)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct VehicleId(pub u32);

/// Timing of the simulation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WorldParams {
    /// Physics step (s). 0.01, chosen here (DESIGN.md: 100 Hz).
    pub physics_dt: f64,
    /// Drivers decide every this many seconds (s). 0.1, chosen here (DESIGN.md: 10 Hz).
    pub control_dt: f64,
}

impl Default for WorldParams {
    fn default() -> Self {
        WorldParams { physics_dt: 0.01, control_dt: 0.1 }
    }
}

impl WorldParams {
    /// Physics steps per control period.
    pub fn substeps_per_control(&self) -> u64 {
        ((self.control_dt / self.physics_dt).round() as u64).max(1)
    }
}

/// Who drives a vehicle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Driver {
    /// A learner outside the process, through the env's actions.
    Agent(AgentCommand),
    /// IDM + MOBIL background traffic.
    Idm,
    /// The paper's game-theoretic AV (`av`): its game, role, constants and memory.
    Gt(Box<crate::av::GtDriver>),
}

/// What a learner last asked its vehicle to do.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum AgentCommand {
    /// Track the vehicle's target speed and target lane (meta actions).
    Track,
    /// Apply this acceleration and preview point directly (continuous actions).
    Direct(Command),
}

/// Whether a vehicle is still driving.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Status {
    /// On the road and driving.
    Driving,
    /// Hit another vehicle; it brakes to a stop and stays as an obstacle.
    Crashed,
    /// Left the paved road (past a lane end or over an edge).
    OffRoad,
    /// Reached the end of the road and left the world.
    Exited,
}

/// One vehicle: its state, its driver and what the driver is doing.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Vehicle {
    /// Name from the scenario file (unique in a world).
    pub name: String,
    /// The 8 states of eq. (8).
    pub state: VehicleState,
    /// Driving style (Table I for steering; Table III for costs).
    pub style: Style,
    /// Table I's parameters for `style`.
    pub driver_params: DriverParams,
    /// Who drives.
    pub driver: Driver,
    /// The lane the vehicle is in or changing to.
    pub target_lane: LaneId,
    /// The lateral path the driver previews.
    pub path: LateralPath,
    /// Speed the driver aims for (m/s).
    pub target_speed: f64,
    /// The command applied during the current control period.
    pub command: Command,
    /// Driving, crashed, off road or gone.
    pub status: Status,
    /// Simulated time of the last MOBIL consultation (s).
    pub last_lane_decision: f64,
}

impl Vehicle {
    /// A vehicle cruising along `lane` at `speed`.
    pub fn new(name: &str, road: &Road, lane: LaneId, s: f64, speed: f64, style: Style, driver: Driver) -> Vehicle {
        let d = road.lane_center(lane);
        Vehicle {
            name: name.to_string(),
            state: VehicleState::cruising(s, d, speed),
            style,
            driver_params: DriverParams::for_style(style),
            driver,
            target_lane: lane,
            path: LateralPath::hold(d),
            target_speed: speed,
            command: Command { accel: 0.0, preview: d },
            status: Status::Driving,
            last_lane_decision: f64::NEG_INFINITY,
        }
    }

    /// Whether the vehicle still takes part in traffic (driving, or crashed and in the way).
    pub fn on_road(&self) -> bool {
        matches!(self.status, Status::Driving | Status::Crashed)
    }

    fn as_car(&self) -> Car {
        Car { s: self.state.s, speed: self.state.lane_speed(), target_speed: self.target_speed }
    }
}

/// A collision found in the last tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Collision {
    /// The vehicle behind (smaller s).
    pub rear: VehicleId,
    /// The vehicle ahead.
    pub front: VehicleId,
}

/// The simulated world.
#[derive(Debug, Clone, PartialEq)]
pub struct World {
    /// The road everyone drives on.
    pub road: Road,
    /// Every vehicle, indexed by `VehicleId`.
    pub vehicles: Vec<Vehicle>,
    /// Timing.
    pub params: WorldParams,
    /// Body and tyres, shared by every vehicle (Table II).
    pub vehicle_params: VehicleParams,
    /// Background drivers' constants.
    pub idm: IdmParams,
    /// Simulated time (s).
    pub time: f64,
    /// Physics steps taken.
    pub ticks: u64,
    /// Collisions that happened since the world began, in order.
    pub collisions: Vec<Collision>,
    /// The world's only source of randomness, seeded at creation.
    pub rng: ChaCha8Rng,
    order: Vec<u32>,
    lanes: LaneIndex,
}

impl World {
    /// An empty world on `road`, its randomness seeded with `seed`.
    pub fn new(road: Road, params: WorldParams, seed: u64) -> World {
        let lanes = LaneIndex { lanes: vec![Vec::new(); road.lane_count()] };
        World {
            road,
            vehicles: Vec::new(),
            params,
            vehicle_params: VehicleParams::default(),
            idm: IdmParams::default(),
            time: 0.0,
            ticks: 0,
            collisions: Vec::new(),
            rng: ChaCha8Rng::seed_from_u64(seed),
            order: Vec::new(),
            lanes,
        }
    }

    /// Adds a vehicle and returns its id.
    pub fn add(&mut self, vehicle: Vehicle) -> VehicleId {
        self.order.push(self.vehicles.len() as u32);
        self.vehicles.push(vehicle);
        self.sort_along_road();
        VehicleId(self.vehicles.len() as u32 - 1)
    }

    /// The vehicle with this id.
    pub fn vehicle(&self, id: VehicleId) -> &Vehicle {
        &self.vehicles[id.0 as usize]
    }

    /// The vehicle with this id, mutably (the env writes agents' commands through this).
    pub fn vehicle_mut(&mut self, id: VehicleId) -> &mut Vehicle {
        &mut self.vehicles[id.0 as usize]
    }

    /// Finds a vehicle by name.
    pub fn find(&self, name: &str) -> Option<VehicleId> {
        self.vehicles.iter().position(|v| v.name == name).map(|i| VehicleId(i as u32))
    }

    /// Simulated seconds per physics step.
    pub fn dt(&self) -> f64 {
        self.params.physics_dt
    }

    /// One physics step.
    pub fn tick(&mut self) {
        self.sort_along_road();
        if self.ticks.is_multiple_of(self.params.substeps_per_control()) {
            self.index_lanes();
            self.decide();
        }
        self.integrate();
        self.detect_collisions();
        self.ticks += 1;
        self.time = self.ticks as f64 * self.params.physics_dt;
    }

    /// Advances by whole control periods covering at least `seconds`.
    pub fn advance(&mut self, seconds: f64) {
        let steps = (seconds / self.params.physics_dt).round() as u64;
        for _ in 0..steps {
            self.tick();
        }
    }

    /// Starts a lane change of vehicle `id` to `lane` along a quintic path.
    pub fn change_lane(&mut self, id: VehicleId, lane: LaneId) {
        let (time, duration) = (self.time, self.idm.lane_change_duration);
        let to = self.road.lane_center(lane);
        let vehicle = self.vehicle_mut(id);
        let from = vehicle.path.offset_at(time);
        vehicle.target_lane = lane;
        vehicle.path = LateralPath { from, to, start: time, duration };
    }

    /// The lane a vehicle is in now (by its position), or its target lane off the lanes.
    pub fn current_lane(&self, id: VehicleId) -> LaneId {
        let vehicle = self.vehicle(id);
        self.road.lane_at(vehicle.state.s, vehicle.state.d).unwrap_or(vehicle.target_lane)
    }

    /// The nearest cars ahead of and behind position `s` in `lane`, other than `id`.
    /// A lane that ends counts as a stopped car just past its end.
    pub fn gap(&self, lane: LaneId, s: f64, id: VehicleId) -> Gap {
        let mut gap = self.lanes.gap(lane, s, id.0, &self.vehicles);
        let end = self.road.lane_end(lane);
        if end < self.road.length() && s < end + 1.0 {
            let wall = Car { s: end + self.vehicle_params.length / 2.0, speed: 0.0, target_speed: 0.0 };
            if gap.leader.is_none_or(|leader| leader.s > wall.s) {
                gap.leader = Some(wall);
            }
        }
        gap
    }

    /// Keeps `order` sorted by s: insertion sort, O(n) on the nearly sorted order of
    /// the last tick.
    fn sort_along_road(&mut self) {
        let vehicles = &self.vehicles;
        let order = &mut self.order;
        for i in 1..order.len() {
            let mut j = i;
            while j > 0 && vehicles[order[j - 1] as usize].state.s > vehicles[order[j] as usize].state.s {
                order.swap(j - 1, j);
                j -= 1;
            }
        }
    }

    /// Rebuilds the per-lane sorted lists: a vehicle is in its current lane and, while
    /// changing lanes, in its target lane too.
    fn index_lanes(&mut self) {
        for lane in &mut self.lanes.lanes {
            lane.clear();
        }
        for &index in &self.order {
            let vehicle = &self.vehicles[index as usize];
            if !vehicle.on_road() {
                continue;
            }
            let current = self.road.lane_at(vehicle.state.s, vehicle.state.d).unwrap_or(vehicle.target_lane);
            self.lanes.lanes[current.0 as usize].push((vehicle.state.s, index));
            if vehicle.target_lane != current {
                self.lanes.lanes[vehicle.target_lane.0 as usize].push((vehicle.state.s, index));
            }
        }
    }

    /// Every driver picks its command for the coming control period.
    fn decide(&mut self) {
        for index in 0..self.vehicles.len() {
            let id = VehicleId(index as u32);
            let vehicle = &self.vehicles[index];
            let accel = match (vehicle.status, &vehicle.driver) {
                (Status::Crashed, _) => -self.idm.accel_limit,
                (Status::OffRoad | Status::Exited, _) => 0.0,
                (Status::Driving, Driver::Agent(AgentCommand::Direct(command))) => command.accel,
                (Status::Driving, Driver::Agent(AgentCommand::Track)) => self.speed_control(id),
                (Status::Driving, Driver::Idm) => {
                    self.consider_lane_change(id);
                    self.idm_accel(id)
                }
                (Status::Driving, Driver::Gt(_)) => crate::av::drive(self, id),
            };
            self.vehicles[index].command.accel = accel;
        }
    }

    /// highway-env's proportional speed controller (KP_A = 1/0.6) for meta actions.
    fn speed_control(&self, id: VehicleId) -> f64 {
        let vehicle = self.vehicle(id);
        let limit = self.idm.accel_limit;
        ((vehicle.target_speed - vehicle.state.vx) / 0.6).clamp(-limit, limit)
    }

    /// IDM behind the nearest leader of every lane the vehicle occupies.
    fn idm_accel(&self, id: VehicleId) -> f64 {
        let vehicle = self.vehicle(id);
        let ego = vehicle.as_car();
        let mut accel = traffic::idm_accel(&self.idm, ego, self.gap(self.current_lane(id), ego.s, id).leader);
        if vehicle.target_lane != self.current_lane(id) {
            let leader = self.gap(vehicle.target_lane, ego.s, id).leader;
            accel = accel.min(traffic::idm_accel(&self.idm, ego, leader));
        }
        accel
    }

    /// MOBIL, once per lane-change period, for a vehicle not already changing lanes.
    fn consider_lane_change(&mut self, id: VehicleId) {
        let vehicle = self.vehicle(id);
        let current = self.current_lane(id);
        if self.time - vehicle.last_lane_decision < self.idm.lane_change_period - 1e-9
            || vehicle.target_lane != current
            || !vehicle.path.finished(self.time)
        {
            return;
        }
        let ego = vehicle.as_car();
        let here = self.gap(current, ego.s, id);
        let mut best: Option<(f64, LaneId)> = None;
        for side in [-1i64, 1] {
            let lane = current.0 as i64 + side;
            if !self.road.has_lane(lane) || self.road.lane_end(LaneId(lane as u32)) < ego.s + ego.speed * 2.0 {
                continue;
            }
            let lane = LaneId(lane as u32);
            let incentive =
                traffic::mobil_incentive(&self.idm, ego, self.vehicle_params.length, here, self.gap(lane, ego.s, id));
            if let Some(incentive) = incentive.filter(|&g| g >= self.idm.lane_change_gain)
                && best.is_none_or(|(g, _)| incentive > g)
            {
                best = Some((incentive, lane));
            }
        }
        self.vehicle_mut(id).last_lane_decision = self.time;
        if let Some((_, lane)) = best {
            self.change_lane(id, lane);
            self.lanes.insert(lane, ego.s, id.0);
        }
    }

    /// Integrates every vehicle on the road over one physics step.
    fn integrate(&mut self) {
        let (dt, time) = (self.params.physics_dt, self.time);
        for vehicle in &mut self.vehicles {
            if !vehicle.on_road() {
                continue;
            }
            if vehicle.status == Status::Crashed && vehicle.state.vx <= 0.0 {
                continue;
            }
            vehicle.command.preview = match vehicle.driver {
                Driver::Agent(AgentCommand::Direct(command)) => command.preview,
                Driver::Gt(_) => vehicle.command.preview,
                _ => vehicle.path.preview(time, vehicle.driver_params.preview_time),
            };
            let curvature = self.road.curvature(vehicle.state.s);
            let stepper = dynamics::Stepper::new(&self.vehicle_params, &vehicle.driver_params, dt);
            vehicle.state = stepper.step(&vehicle.state, vehicle.command, curvature);
            if vehicle.state.s > self.road.length() {
                vehicle.status = Status::Exited;
            } else if vehicle.status == Status::Driving && self.road.lane_at(vehicle.state.s, vehicle.state.d).is_none()
            {
                vehicle.status = Status::OffRoad;
            }
        }
    }

    /// Oriented-box overlap between vehicles close along the road (a sweep over the
    /// sorted order: only pairs nearer than one body diagonal in s are tested).
    fn detect_collisions(&mut self) {
        let reach = self.vehicle_params.length.hypot(self.vehicle_params.width);
        let mut found = Vec::new();
        for (k, &i) in self.order.iter().enumerate() {
            let a = &self.vehicles[i as usize];
            if !a.on_road() {
                continue;
            }
            for &j in &self.order[k + 1..] {
                let b = &self.vehicles[j as usize];
                if b.state.s - a.state.s > reach {
                    break;
                }
                let both_crashed = a.status == Status::Crashed && b.status == Status::Crashed;
                // A box reaches sideways at most half its width plus half its length times
                // |sin(heading)| <= |heading|: most neighbours in the next lane fail this.
                let lateral_reach = self.vehicle_params.width
                    + self.vehicle_params.length * (a.state.heading.abs() + b.state.heading.abs()) / 2.0;
                if b.on_road()
                    && !both_crashed
                    && (b.state.d - a.state.d).abs() <= lateral_reach
                    && self.boxes_overlap(a, b)
                {
                    found.push(Collision { rear: VehicleId(i), front: VehicleId(j) });
                }
            }
        }
        for collision in &found {
            self.vehicles[collision.rear.0 as usize].status = Status::Crashed;
            self.vehicles[collision.front.0 as usize].status = Status::Crashed;
        }
        self.collisions.extend(found);
    }

    fn boxes_overlap(&self, a: &Vehicle, b: &Vehicle) -> bool {
        let pa = self.road.to_global(a.state.s, a.state.d, a.state.heading);
        let pb = self.road.to_global(b.state.s, b.state.d, b.state.heading);
        let half = (self.vehicle_params.length / 2.0, self.vehicle_params.width / 2.0);
        oriented_boxes_overlap((pa.x, pa.y, pa.heading), (pb.x, pb.y, pb.heading), half)
    }
}

/// Separating-axis test for two equal rectangles given as (x, y, heading) with half
/// extents `half` = (half length, half width).
pub fn oriented_boxes_overlap(a: (f64, f64, f64), b: (f64, f64, f64), half: (f64, f64)) -> bool {
    let axes = |heading: f64| {
        let (sin, cos) = heading.sin_cos();
        [(cos, sin), (-sin, cos)]
    };
    let (axes_a, axes_b) = (axes(a.2), axes(b.2));
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let radius = |axis: (f64, f64), own: [(f64, f64); 2]| {
        half.0 * (own[0].0 * axis.0 + own[0].1 * axis.1).abs() + half.1 * (own[1].0 * axis.0 + own[1].1 * axis.1).abs()
    };
    axes_a.iter().chain(axes_b.iter()).all(|&axis| {
        let distance = (dx * axis.0 + dy * axis.1).abs();
        distance <= radius(axis, axes_a) + radius(axis, axes_b)
    })
}

/// Vehicles per lane sorted by s, rebuilt each control period.
#[derive(Debug, Clone, PartialEq, Default)]
struct LaneIndex {
    lanes: Vec<Vec<(f64, u32)>>,
}

impl LaneIndex {
    fn gap(&self, lane: LaneId, s: f64, exclude: u32, vehicles: &[Vehicle]) -> Gap {
        let list = &self.lanes[lane.0 as usize];
        let split = list.partition_point(|&(other, _)| other < s);
        let car = |&(_, index): &(f64, u32)| vehicles[index as usize].as_car();
        let leader = list[split..].iter().find(|&&(_, index)| index != exclude).map(car);
        let follower = list[..split].iter().rev().find(|&&(_, index)| index != exclude).map(car);
        Gap { leader, follower }
    }

    fn insert(&mut self, lane: LaneId, s: f64, index: u32) {
        let list = &mut self.lanes[lane.0 as usize];
        let at = list.partition_point(|&(other, _)| other < s);
        list.insert(at, (s, index));
    }
}

#[cfg(test)]
mod tests;
