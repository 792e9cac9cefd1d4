//! The world: a road, the vehicles on it and their drivers, advanced one fixed physics
//! step at a time. `World::tick` runs its stages in order: keep the vehicles sorted
//! along the road, let the drivers decide (at the control rate, from one `Scene` of the
//! world as it was at the start of the period), integrate the dynamics, detect
//! collisions. Drivers decide in two rounds: everyone but the game-theoretic followers,
//! then those followers, who answer their leaders' decisions of this period. Results
//! depend on roles, never on the order of vehicles in a file. Neighbour queries and
//! collision checks use sorted orders, so a tick costs O(n) for n vehicles. A server may
//! make the next control instant's decisions while it waits for the learners' actions
//! (`decide_ahead`); the tick takes them only if nothing they read has changed.

use std::sync::OnceLock;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::dynamics::{self, Command, DriverParams, LateralPath, Style, VehicleParams, VehicleState};
use crate::gt::{self, GtDriver, GtParams, GtStep};
use crate::road::{LaneChange, LaneId, Road};
use crate::scene::{Car, DriverKind, Role, Scene};

mod collision;
mod state;
use crate::traffic::{self, IdmDecision, IdmParams};
use collision::Approach;
pub use collision::{AtFault, CUT_IN_WINDOW, Collision, DRIFT_SPEED, LaneEntry};
pub use state::{RngState, StateError, WorldState};

pub use crate::scene::{Status, VehicleId};

/// How a vehicle stopped driving (`World::ending`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Ending {
    /// It collided.
    Collision,
    /// It drove past the end of its lane.
    LaneEnd,
    /// It left the road over an edge.
    OffRoad,
    /// It reached the end of the road.
    RoadEnd,
}

/// Timing of the simulation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WorldParams {
    /// Physics step (s). 0.01, chosen here (docs/design.md, "Timing": 100 Hz).
    pub physics_dt: f64,
    /// Drivers decide every this many seconds (s). 0.1, chosen here (docs/design.md, "Timing": 10 Hz).
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
    /// The paper's game-theoretic AV (`gt`): its game, role, constants and memory.
    Gt(Box<GtDriver>),
}

/// What a learner last asked its vehicle to do.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum AgentCommand {
    /// Track the vehicle's target speed and target lane (meta actions).
    Track,
    /// Apply this acceleration and preview point directly (continuous actions).
    Direct(Command),
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
    /// Table I's parameters for `style`; fixed once the vehicle is in a world, which
    /// prepares its physics step from them then.
    pub driver_params: DriverParams,
    /// Who drives.
    pub driver: Driver,
    /// The lane the vehicle is in or changing to.
    pub target_lane: LaneId,
    /// The lateral path the driver previews.
    pub path: LateralPath,
    /// Speed the driver aims for (m/s).
    pub target_speed: f64,
    /// The command of the current control period. A `gt` car's acceleration ramps to
    /// `command.accel` over the period from `ramp_from` (docs/design.md, "Jerk").
    pub command: Command,
    /// Where the acceleration of a ramped command starts (m/s^2): the last period's
    /// command; `None`: `command.accel` applies from the period's start.
    #[serde(default)]
    pub ramp_from: Option<f64>,
    /// The model's longitudinal acceleration at the start of the last physics step (m/s^2):
    /// v_x' of eq. (2) under the acceleration that step applied (`VehicleState::longitudinal_accel`).
    #[serde(default)]
    pub longitudinal_accel: f64,
    /// Driving, crashed, off road or gone.
    pub status: Status,
    /// Simulated time of the last MOBIL consultation (s).
    pub last_lane_decision: f64,
    /// The lane it was in at the last control instant, and since when (`collision`).
    pub lane_entry: LaneEntry,
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
            ramp_from: None,
            longitudinal_accel: 0.0,
            status: Status::Driving,
            last_lane_decision: f64::NEG_INFINITY,
            lane_entry: LaneEntry { lane, at: None },
        }
    }

    /// Whether the vehicle still takes part in traffic (driving, or crashed and in the way).
    pub fn on_road(&self) -> bool {
        matches!(self.status, Status::Driving | Status::Crashed)
    }

    fn driver_kind(&self) -> DriverKind {
        match &self.driver {
            Driver::Agent(_) => DriverKind::Agent,
            Driver::Idm => DriverKind::Idm,
            Driver::Gt(gt) => DriverKind::Gt(gt.role),
        }
    }
}

/// How far above its lane's speed limit a learner's continuous actions may take it:
/// 1.2, chosen here (room to overtake, no runaway: unclamped, holding +0.5 reached 75 m/s).
pub const LEARNER_SPEED_FACTOR: f64 = 1.2;

/// What one driver decided for the coming control period.
#[derive(Debug, Clone, PartialEq)]
enum Decision {
    /// Apply this acceleration (learners, and vehicles that no longer drive).
    Accel(f64),
    /// IDM + MOBIL.
    Idm(IdmDecision),
    /// The game-theoretic AV.
    Gt(Box<GtStep>),
}

/// The simulated world. Its fields are private so its invariants hold: every vehicle is
/// in the sorted orders, and the scene is the world as of the last control instant.
#[derive(Debug, Clone, PartialEq)]
pub struct World {
    /// The road, the vehicle body and the cars as drivers last saw them.
    scene: Scene,
    /// Every vehicle, indexed by `VehicleId`.
    vehicles: Vec<Vehicle>,
    params: WorldParams,
    idm: IdmParams,
    time: f64,
    ticks: u64,
    /// The tick the scene was taken at.
    scene_tick: Option<u64>,
    collisions: Vec<Collision>,
    /// The world's only source of randomness, seeded at creation.
    rng: ChaCha8Rng,
    /// Vehicles by s, kept sorted every tick for the collision sweep.
    order: Vec<u32>,
    /// Each vehicle's s by id, refreshed every tick: the sort and the sweep read these
    /// 8 bytes per vehicle rather than a whole `Vehicle` each.
    positions: Vec<f64>,
    /// Scratch of `decide`: one decision per vehicle.
    decisions: Vec<Decision>,
    /// Threads for the game-theoretic cars' decisions (`set_decision_threads`).
    decision_threads: usize,
    /// Each vehicle's model constants over one physics step, by id, prepared when it is
    /// added (five divisions each): its body and driver parameters never change after.
    steppers: Vec<dynamics::Stepper>,
    /// Scratch of `integrate`: the vehicles that move this step, and their ids.
    fleet: dynamics::Fleet,
    moving: Vec<u32>,
    /// Whether each game-theoretic decision is explained (`set_explain`); never read by a
    /// decision.
    explain: bool,
    /// The decisions explained since `take_explanations` last emptied it.
    explanations: Vec<gt::Explanation>,
    /// Wall time spent deciding, per vehicle (`clock_decisions`).
    clock: DecisionClock,
    /// The coming control instant's decisions, made early (`decide_ahead`).
    ahead: Ahead,
}

/// Decisions made ahead of their control instant (`World::decide_ahead`), by vehicle,
/// with the tick they are for. Not state: a world's copy, its snapshot and its equality
/// ignore them, since they are what that tick would decide anyway.
#[derive(Debug, Default)]
struct Ahead(Option<(u64, Decided)>);

/// Decisions of one control instant, by vehicle (`None`: not decided there), with the
/// wall time each took.
type Decided = Vec<Option<(Decision, Duration)>>;

impl Ahead {
    /// The decisions made for tick `ticks`, if any; none are kept after.
    fn take_for(&mut self, ticks: u64) -> Option<Decided> {
        self.0.take().filter(|(tick, _)| *tick == ticks).map(|(_, decided)| decided)
    }
}

impl Clone for Ahead {
    fn clone(&self) -> Ahead {
        Ahead(None)
    }
}

impl PartialEq for Ahead {
    fn eq(&self, _: &Ahead) -> bool {
        true
    }
}

/// Wall time each vehicle's driver spent deciding: since it was last taken, a
/// measurement for a compute budget (`arena eval`); in its last parallel decision, the
/// order the next ones are taken in. Never read by a decision, so two worlds in the same
/// state are equal whatever their clocks read.
#[derive(Debug, Clone, Default)]
struct DecisionClock {
    on: bool,
    spent: Vec<Duration>,
    last: Vec<Duration>,
}

impl PartialEq for DecisionClock {
    fn eq(&self, _: &DecisionClock) -> bool {
        true
    }
}

impl World {
    /// An empty world on `road`, its randomness seeded with `seed`.
    pub fn new(road: Road, params: WorldParams, seed: u64) -> World {
        World {
            scene: Scene::new(road, VehicleParams::default(), params.control_dt),
            vehicles: Vec::new(),
            params,
            idm: IdmParams::default(),
            time: 0.0,
            ticks: 0,
            scene_tick: None,
            collisions: Vec::new(),
            rng: ChaCha8Rng::seed_from_u64(seed),
            order: Vec::new(),
            positions: Vec::new(),
            decisions: Vec::new(),
            decision_threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
            steppers: Vec::new(),
            fleet: dynamics::Fleet::default(),
            moving: Vec::new(),
            explain: false,
            explanations: Vec::new(),
            clock: DecisionClock::default(),
            ahead: Ahead::default(),
        }
    }

    /// Adds a vehicle and returns its id.
    pub fn add(&mut self, vehicle: Vehicle) -> VehicleId {
        let (body, dt) = (&self.scene.vehicle, self.params.physics_dt);
        self.steppers.push(dynamics::Stepper::new(body, &vehicle.driver_params, dt));
        self.order.push(self.vehicles.len() as u32);
        self.vehicles.push(vehicle);
        self.sort_along_road();
        self.scene_tick = None;
        self.ahead = Ahead::default();
        VehicleId(self.vehicles.len() as u32 - 1)
    }

    /// The road.
    pub fn road(&self) -> &Road {
        &self.scene.road
    }

    /// Body and tyres, shared by every vehicle (Table II).
    pub fn vehicle_params(&self) -> &VehicleParams {
        &self.scene.vehicle
    }

    /// Timing.
    pub fn params(&self) -> &WorldParams {
        &self.params
    }

    /// Background drivers' constants.
    pub fn idm(&self) -> &IdmParams {
        &self.idm
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Why vehicle `id` no longer drives, if it does not: a collision, driving past the
    /// end of its lane, over the road's edge, or off the road's end. The env reports it
    /// (`end_reason`), and the benchmarks without a server read it here.
    pub fn ending(&self, id: VehicleId) -> Option<Ending> {
        let vehicle = self.vehicle(id);
        match vehicle.status {
            Status::Driving => None,
            Status::Crashed => Some(Ending::Collision),
            Status::Exited => Some(Ending::RoadEnd),
            Status::OffRoad => {
                let road = self.road();
                let lane = road.nearest_lane(vehicle.state.d);
                let within = (vehicle.state.d - road.lane_center(lane)).abs() <= road.lane_width() / 2.0;
                Some(if within && vehicle.state.s > road.lane_end(lane) { Ending::LaneEnd } else { Ending::OffRoad })
            }
        }
    }

    /// Collisions that happened since the world began, in order.
    pub fn collisions(&self) -> &[Collision] {
        &self.collisions
    }

    /// Vehicle `id`'s first collision, if it had one.
    pub fn collision_of(&self, id: VehicleId) -> Option<&Collision> {
        if self.vehicle(id).status != Status::Crashed {
            return None;
        }
        self.collisions.iter().find(|c| c.other(id).is_some())
    }

    /// Every vehicle, by id.
    pub fn vehicles(&self) -> &[Vehicle] {
        &self.vehicles
    }

    /// The vehicle with this id.
    pub fn vehicle(&self, id: VehicleId) -> &Vehicle {
        &self.vehicles[id.0 as usize]
    }

    /// Every change to a vehicle between ticks comes through here: the scene drivers read
    /// and the decisions made ahead from it are then out of date.
    pub(crate) fn vehicle_mut(&mut self, id: VehicleId) -> &mut Vehicle {
        self.scene_tick = None;
        self.ahead = Ahead::default();
        &mut self.vehicles[id.0 as usize]
    }

    pub(crate) fn rng(&mut self) -> &mut ChaCha8Rng {
        &mut self.rng
    }

    /// Finds a vehicle by name.
    pub fn find(&self, name: &str) -> Option<VehicleId> {
        self.vehicles.iter().position(|v| v.name == name).map(|i| VehicleId(i as u32))
    }

    /// The world as drivers see it, taken now if the last one is older than this tick.
    pub fn scene(&mut self) -> &Scene {
        if self.scene_tick != Some(self.ticks) {
            self.take_scene();
        }
        &self.scene
    }

    /// The scene as of the last control instant (or the last `scene()` call).
    pub fn last_scene(&self) -> &Scene {
        &self.scene
    }

    /// The parameters the game-theoretic AV plans with for vehicle `id`: its own if it is
    /// a `gt` car, the defaults otherwise.
    pub fn gt_params(&self, id: VehicleId) -> GtParams {
        match &self.vehicle(id).driver {
            Driver::Gt(gt) => gt.params,
            _ => GtParams::default(),
        }
    }

    /// Vehicle `id`'s stage cost now (eq. 10-14), with the game-theoretic AV's constants
    /// for it (`gt_params`): the yardstick learners are rewarded and compared by.
    pub fn stage_cost(&mut self, id: VehicleId) -> gt::CostComponents {
        let params = self.gt_params(id);
        gt::stage_cost(self.scene(), id, &params)
    }

    /// What the game-theoretic AV, playing `game` as a leader with its constants for `id`,
    /// would decide in `id`'s place now (one period's game, no memory).
    pub fn expert_decision(&mut self, id: VehicleId, game: gt::Game) -> gt::Decision {
        let params = self.gt_params(id);
        gt::expert_decision(self.scene(), id, game, &params)
    }

    /// The AV's command in `id`'s place now (its acceleration and the preview point its
    /// MPC plans), with the memory `expert` holds of its earlier periods there, which it
    /// then updates (its `decision` among them).
    /// In a place the AV does not drive, the lane change it makes is its own
    /// (`GtDriver::counterfactual_target`), not the vehicle's.
    pub fn expert_command(&mut self, id: VehicleId, expert: &mut GtDriver) -> Command {
        self.scene();
        let car = *self.scene.car(id);
        let beside = |lane: &LaneId| lane.0.abs_diff(car.lane.0) <= 1;
        let target = expert.counterfactual_target.filter(beside).unwrap_or(car.target_lane);
        let step = self.scene.with_target_lane(id, target, |scene| gt::plan(scene, id, expert, None));
        *expert = step.driver;
        if !matches!(self.vehicle(id).driver, Driver::Gt(_)) {
            expert.counterfactual_target = Some(step.change_to.unwrap_or(target));
        }
        step.command
    }

    /// A learner's command for the coming periods. Asking again for tracking, as every
    /// meta action does, changes nothing, so it keeps the scene and the decisions made
    /// ahead from it.
    pub fn command_agent(&mut self, id: VehicleId, command: AgentCommand) {
        if command == AgentCommand::Track && self.vehicle(id).driver == Driver::Agent(AgentCommand::Track) {
            return;
        }
        self.vehicle_mut(id).driver = Driver::Agent(command);
    }

    /// Sets the speed vehicle `id`'s driver aims for (m/s).
    pub fn set_target_speed(&mut self, id: VehicleId, speed: f64) {
        self.vehicle_mut(id).target_speed = speed;
    }

    /// Makes `lane` vehicle `id`'s target lane without a path to it (a learner's
    /// continuous actions steer it themselves).
    pub fn set_target_lane(&mut self, id: VehicleId, lane: LaneId) {
        self.vehicle_mut(id).target_lane = lane;
    }

    /// One physics step.
    pub fn tick(&mut self) {
        self.sort_along_road();
        if self.ticks.is_multiple_of(self.params.substeps_per_control()) {
            self.scene();
            self.note_lane_entries();
            self.decide();
        }
        self.integrate();
        self.detect_collisions();
        self.ticks += 1;
        self.time = self.ticks as f64 * self.params.physics_dt;
    }

    /// Advances by the whole physics steps closest to `seconds`.
    pub fn advance(&mut self, seconds: f64) {
        let steps = (seconds / self.params.physics_dt).round() as u64;
        for _ in 0..steps {
            self.tick();
        }
    }

    /// Starts a lane change of vehicle `id` to `lane` along a quintic path.
    pub fn change_lane(&mut self, id: VehicleId, lane: LaneId) {
        let time = self.time;
        let to = self.road().lane_center(lane);
        let vehicle = self.vehicle_mut(id);
        let from = vehicle.path.offset_at(time);
        vehicle.target_lane = lane;
        vehicle.path = LateralPath::lane_change(from, to, time);
    }

    /// The lane a vehicle is in now (by its position), or its target lane off the lanes.
    pub fn current_lane(&self, id: VehicleId) -> LaneId {
        let vehicle = self.vehicle(id);
        self.road().lane_at(vehicle.state.s, vehicle.state.d).unwrap_or(vehicle.target_lane)
    }

    /// Keeps `order` sorted by s: insertion sort, O(n) on the nearly sorted order of
    /// the last tick.
    fn sort_along_road(&mut self) {
        self.positions.clear();
        self.positions.extend(self.vehicles.iter().map(|vehicle| vehicle.state.s));
        let (positions, order) = (&self.positions, &mut self.order);
        for i in 1..order.len() {
            let mut j = i;
            while j > 0 && positions[order[j - 1] as usize] > positions[order[j] as usize] {
                order.swap(j - 1, j);
                j -= 1;
            }
        }
    }

    fn take_scene(&mut self) {
        let cars = self.vehicles.iter().enumerate().map(|(i, vehicle)| Car {
            id: VehicleId(i as u32),
            state: vehicle.state,
            style: vehicle.style,
            driver_params: vehicle.driver_params,
            lane: vehicle.target_lane,
            target_lane: vehicle.target_lane,
            target_speed: vehicle.target_speed,
            accel: vehicle.command.accel,
            preview: vehicle.command.preview,
            status: vehicle.status,
            driver: vehicle.driver_kind(),
            decided: None,
        });
        self.scene.refresh(self.time, cars);
        self.scene_tick = Some(self.ticks);
        self.ahead = Ahead::default();
    }

    /// Every driver picks its command for the coming control period from the scene:
    /// first everyone but the game-theoretic followers, then the followers, who read
    /// their leaders' decisions of this period. Then every decision is applied.
    fn decide(&mut self) {
        let mut decisions = std::mem::take(&mut self.decisions);
        decisions.clear();
        let threads = self.decision_threads;
        let mut leaders = match self.ahead.take_for(self.ticks) {
            Some(mut made) => {
                // Made ahead, perhaps not all of them (`decide_ahead` stops when asked): the
                // rest now.
                let missing = |world: &World, index: usize| {
                    !world.is_follower(index) && made.get(index).is_none_or(Option::is_none)
                };
                let rest = self.in_parallel(missing, threads, &|| false);
                for (slot, decided) in made.iter_mut().zip(rest) {
                    if slot.is_none() {
                        *slot = decided;
                    }
                }
                made
            }
            None => self.in_parallel(|world, index| !world.is_follower(index), threads, &|| false),
        };
        for index in 0..self.vehicles.len() {
            let decision = match leaders.get_mut(index).and_then(Option::take) {
                Some((decided, spent)) => self.clocked(index, decided, spent),
                None if self.is_follower(index) => Decision::Accel(0.0),
                None => self.decide_clocked(index),
            };
            if let Some((accel, change)) = self.announced(index, &decision) {
                self.scene.record_decision(VehicleId(index as u32), accel, change);
            }
            decisions.push(decision);
        }
        let mut followers = self.in_parallel(|world, index| world.is_follower(index), threads, &|| false);
        for (index, decision) in decisions.iter_mut().enumerate() {
            if let Some((decided, spent)) = followers.get_mut(index).and_then(Option::take) {
                *decision = self.clocked(index, decided, spent);
            } else if self.is_follower(index) {
                *decision = self.decide_clocked(index);
            }
        }
        if self.explain {
            self.explain_decisions(&decisions);
        }
        for (index, decision) in decisions.drain(..).enumerate() {
            self.apply(VehicleId(index as u32), decision);
        }
        self.decisions = decisions;
    }

    /// Makes the coming control instant's decisions now, while the world waits for its
    /// learners' actions (a server calls it once a step's reply is on its way), for every
    /// vehicle whose decision cannot read those actions: all but the learners and the
    /// game-theoretic followers, who read what the learners announce. They need the
    /// scene of this instant, taken already (an env samples its agents' costs from it at
    /// the end of each step); without it nothing is done.
    /// The instant's `tick` uses them when nothing they read has changed since: every
    /// change to a vehicle (`vehicle_mut`, `add`, `restore`) and every new scene discards
    /// them, and a decision reads only the scene, its own vehicle and the clock. So the
    /// world runs the same bits with or without them; a learner's action that changes its
    /// vehicle (a lane change, a new target speed or acceleration) only costs the work
    /// done ahead.
    /// It stops, keeping what it decided, when `stop` says so (the next request has come):
    /// the tick decides the rest.
    pub fn decide_ahead(&mut self, stop: &(dyn Fn() -> bool + Sync)) {
        let at_instant = self.ticks.is_multiple_of(self.params.substeps_per_control());
        let made = self.ahead.0.as_ref().is_some_and(|(tick, _)| *tick == self.ticks);
        if !at_instant || self.scene_tick != Some(self.ticks) || made {
            return;
        }
        let pick = |world: &World, index: usize| {
            !world.is_follower(index) && !matches!(world.vehicles[index].driver, Driver::Agent(_))
        };
        // IDM traffic alone decides in a few microseconds: not worth a buffer.
        let is_gt = |index: usize| matches!(self.vehicles[index].driver, Driver::Gt(_));
        if !(0..self.vehicles.len()).any(|index| is_gt(index) && pick(self, index)) {
            return;
        }
        // One thread fewer than a tick uses: the reply's way out and the client's way back
        // run meanwhile and need a core. On two cores, one period's decisions made in turn
        // fit within the round trip of a client in Python (docs/performance.md).
        let mut decided = self.in_parallel(pick, self.decision_threads - 1, stop);
        if decided.is_empty() {
            // In turn, the game-theoretic cars first: they are most of the work.
            let mut order: Vec<usize> = (0..self.vehicles.len()).filter(|&index| pick(self, index)).collect();
            order.sort_by_key(|&index| !is_gt(index));
            decided = vec![None; self.vehicles.len()];
            for index in order {
                if stop() {
                    break;
                }
                decided[index] = Some(self.decide_timed(index));
            }
        }
        self.ahead = Ahead(Some((self.ticks, decided)));
    }

    /// `decide_one`, its wall time added to the vehicle's clock when the clock is on.
    fn decide_clocked(&mut self, index: usize) -> Decision {
        let (decision, spent) = self.decide_timed(index);
        self.clocked(index, decision, spent)
    }

    /// `decide_one` and its wall time (zero, unmeasured, when the clock is off).
    fn decide_timed(&self, index: usize) -> (Decision, Duration) {
        if !self.clock.on {
            return (self.decide_one(index), Duration::ZERO);
        }
        let start = Instant::now();
        let decision = self.decide_one(index);
        (decision, start.elapsed())
    }

    /// Adds `spent` to vehicle `index`'s clock; returns `decision`.
    fn clocked(&mut self, index: usize, decision: Decision, spent: Duration) -> Decision {
        self.clock.last.resize(self.vehicles.len(), Duration::ZERO);
        self.clock.last[index] = spent;
        if self.clock.on {
            self.clock.spent.resize(self.vehicles.len(), Duration::ZERO);
            self.clock.spent[index] += spent;
        }
        decision
    }

    /// Measure the wall time each driver spends deciding from now on
    /// (`take_decision_time`), or stop. Off by default; the decisions are the same bits
    /// either way.
    pub fn clock_decisions(&mut self, on: bool) {
        self.clock.on = on;
        self.clock.spent.clear();
    }

    /// The wall time vehicle `id`'s driver spent deciding since the last call (zero
    /// unless `clock_decisions` is on).
    pub fn take_decision_time(&mut self, id: VehicleId) -> Duration {
        self.clock.spent.get_mut(id.0 as usize).map_or(Duration::ZERO, std::mem::take)
    }

    /// Explains the game-theoretic cars' `decisions` of this period from the scene they
    /// read and each driver's memory before it (`gt::explain`): the decisions do not
    /// change.
    fn explain_decisions(&mut self, decisions: &[Decision]) {
        for (index, decision) in decisions.iter().enumerate() {
            if let (Decision::Gt(step), Driver::Gt(gt)) = (decision, &self.vehicles[index].driver) {
                let explained = gt::explain(&self.scene, VehicleId(index as u32), gt, step);
                self.explanations.push(explained);
            }
        }
    }

    /// Explain every game-theoretic decision from now on (`take_explanations`), or stop.
    /// Off by default; the decisions are the same bits either way.
    pub fn set_explain(&mut self, on: bool) {
        self.explain = on;
        if !on {
            self.explanations.clear();
        }
    }

    /// The decisions explained since the last call, in time order, cars by id.
    pub fn take_explanations(&mut self) -> Vec<gt::Explanation> {
        std::mem::take(&mut self.explanations)
    }

    /// The decisions of the vehicles that `pick` selects, by vehicle, with the wall time
    /// each took: made on up to `threads` threads when two or more of them are
    /// game-theoretic cars (each decision reads the scene only, so the bits do not depend
    /// on the threads); empty otherwise, and the caller decides them in turn. No task starts
    /// once `stop` says so; those not started are `None`.
    fn in_parallel(
        &self,
        pick: impl Fn(&World, usize) -> bool + Sync,
        threads: usize,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Decided {
        if threads < 2 {
            return Vec::new();
        }
        let is_gt =
            |i: usize| self.vehicles[i].status == Status::Driving && matches!(self.vehicles[i].driver, Driver::Gt(_));
        // Counted before anything is collected: a world with fewer than two (IDM traffic)
        // allocates nothing here.
        let picked = |i: &usize| pick(self, *i);
        if (0..self.vehicles.len()).filter(|&i| is_gt(i)).filter(picked).nth(1).is_none() {
            return Vec::new();
        }
        let (mut gt, others): (Vec<usize>, Vec<usize>) =
            (0..self.vehicles.len()).filter(picked).partition(|&i| is_gt(i));
        // Every thread takes the next task when it is done with one: a game-theoretic car,
        // the cars slowest to decide last period first, then all the other vehicles at
        // once (IDM's decisions are cheap), so that no thread waits long for another's
        // last car.
        gt.sort_by_key(|&i| std::cmp::Reverse(self.clock.last.get(i).copied().unwrap_or_default()));
        let next = AtomicUsize::new(0);
        let decided: Vec<OnceLock<(Decision, Duration)>> = (0..self.vehicles.len()).map(|_| OnceLock::new()).collect();
        // The game-theoretic cars' times order the next period's tasks; the others' are
        // read only by a clock that is on.
        let decide = |index: usize, timed: bool| {
            let start = timed.then(Instant::now);
            let decision = self.decide_one(index);
            let _ = decided[index].set((decision, start.map_or(Duration::ZERO, |start| start.elapsed())));
        };
        let work = || {
            while !stop() {
                let task = next.fetch_add(1, Ordering::Relaxed);
                match gt.get(task) {
                    Some(&index) => decide(index, true),
                    None if task == gt.len() => others.iter().for_each(|&index| decide(index, self.clock.on)),
                    None => break,
                }
            }
        };
        // The calling thread decides too, beside helper threads: it does not sleep while
        // they wake. Within a pool (a batch env's worker), the helpers are that pool's;
        // otherwise the decision pool's, built once for the process (a thread spawned per
        // control period cost as much as a decision) with one thread fewer than the
        // cores, so no thread spins for work beside the two that decide. A panic in a
        // decision surfaces on this thread.
        let helpers = |pool: usize| threads.min(pool + 1).min(gt.len()) - 1;
        let count = Helpers::default();
        match decision_pool() {
            Some(pool) if rayon::current_thread_index().is_none() => {
                let helpers = helpers(pool.current_num_threads());
                pool.in_place_scope(|scope| alongside(scope, helpers, &work, &count));
                keep_warm(pool);
            }
            _ => {
                let helpers = helpers(rayon::current_num_threads().saturating_sub(1));
                rayon::in_place_scope(|scope| alongside(scope, helpers, &work, &count));
            }
        }
        decided.into_iter().map(OnceLock::into_inner).collect()
    }

    /// How many threads the game-theoretic cars of one control period may decide on
    /// (default: the machine's cores; 1 decides them in turn). The results are the same
    /// bits either way.
    pub fn set_decision_threads(&mut self, threads: usize) {
        self.decision_threads = threads.max(1);
    }

    fn is_follower(&self, index: usize) -> bool {
        let vehicle = &self.vehicles[index];
        vehicle.status == Status::Driving && matches!(&vehicle.driver, Driver::Gt(gt) if gt.role == Role::Follower)
    }

    fn decide_one(&self, index: usize) -> Decision {
        let id = VehicleId(index as u32);
        let vehicle = &self.vehicles[index];
        let scene = &self.scene;
        match (vehicle.status, &vehicle.driver) {
            (Status::Crashed, _) => Decision::Accel(-self.idm.accel_limit),
            (Status::OffRoad | Status::Exited, _) => Decision::Accel(0.0),
            (Status::Driving, Driver::Agent(AgentCommand::Direct(command))) => {
                Decision::Accel(self.learner_accel(scene.car(id), command.accel))
            }
            (Status::Driving, Driver::Agent(AgentCommand::Track)) => {
                Decision::Accel(traffic::track_speed(&self.idm, scene.car(id)))
            }
            (Status::Driving, Driver::Idm) => {
                let may_change_lanes = self.time - vehicle.last_lane_decision >= self.idm.lane_change_period - 1e-9
                    && vehicle.path.finished(self.time);
                Decision::Idm(traffic::decide(&self.idm, scene, id, may_change_lanes))
            }
            (Status::Driving, Driver::Gt(gt)) => Decision::Gt(Box::new(gt::plan(scene, id, gt, None))),
        }
    }

    /// A learner's commanded acceleration, held so that its speed stays within
    /// [0, lane limit x `LEARNER_SPEED_FACTOR`] over the coming control period.
    fn learner_accel(&self, car: &Car, accel: f64) -> f64 {
        let dt = self.params.control_dt;
        let top = self.road().speed_limit(car.lane) * LEARNER_SPEED_FACTOR;
        let low = -car.state.vx.max(0.0) / dt;
        let high = (top - car.state.vx) / dt;
        accel.clamp(low, high.max(low))
    }

    /// What a leader or learner tells the followers it decided: its acceleration and
    /// the lane change it is making or starts now.
    fn announced(&self, index: usize, decision: &Decision) -> Option<(f64, LaneChange)> {
        let car = self.scene.car(VehicleId(index as u32));
        let under_way = car.lane_change();
        match (car.driver, decision) {
            (DriverKind::Agent, Decision::Accel(accel)) => Some((*accel, under_way)),
            (DriverKind::Gt(Role::Leader), Decision::Gt(step)) => {
                let decided = step.driver.decision;
                let change = if under_way != LaneChange::Keep { under_way } else { decided.lane_change };
                Some((decided.accel, change))
            }
            _ => None,
        }
    }

    fn apply(&mut self, id: VehicleId, decision: Decision) {
        let previous = self.vehicle(id).command.accel;
        let mut ramp_from = None;
        let accel = match decision {
            Decision::Accel(accel) => accel,
            Decision::Idm(idm) => {
                if idm.consulted {
                    self.vehicle_mut(id).last_lane_decision = self.time;
                }
                if let Some(lane) = idm.change_to {
                    self.change_lane(id, lane);
                }
                idm.accel
            }
            Decision::Gt(step) => {
                let GtStep { command, change_to, ramp, driver } = *step;
                if let Some(lane) = change_to {
                    self.change_lane(id, lane);
                }
                ramp_from = ramp.then_some(previous);
                let vehicle = self.vehicle_mut(id);
                vehicle.command.preview = command.preview;
                vehicle.driver = Driver::Gt(Box::new(driver));
                command.accel
            }
        };
        let vehicle = &mut self.vehicles[id.0 as usize];
        vehicle.command.accel = accel;
        vehicle.ramp_from = ramp_from;
    }

    /// Integrates every vehicle on the road over one physics step, all of them together
    /// (`dynamics::Fleet`).
    fn integrate(&mut self) {
        let time = self.time;
        // Which step of its control period this is: a ramped acceleration is a linear
        // blend reaching the command at the period's last step.
        let per_control = self.params.substeps_per_control();
        let phase = self.ticks % per_control + 1;
        let road = &self.scene.road;
        let (fleet, moving) = (&mut self.fleet, &mut self.moving);
        fleet.clear();
        moving.clear();
        for (index, vehicle) in self.vehicles.iter_mut().enumerate() {
            let stopped_wreck = vehicle.status == Status::Crashed && vehicle.state.vx <= 0.0;
            if !vehicle.on_road() || stopped_wreck {
                continue;
            }
            vehicle.command.preview = match vehicle.driver {
                Driver::Agent(AgentCommand::Direct(command)) => command.preview,
                Driver::Gt(_) => vehicle.command.preview,
                _ => vehicle.path.preview(time, vehicle.driver_params.preview_time),
            };
            let mut command = vehicle.command;
            if let Some(from) = vehicle.ramp_from.filter(|_| phase < per_control) {
                command.accel = from + (command.accel - from) * (phase as f64 / per_control as f64);
            }
            vehicle.longitudinal_accel = vehicle.state.longitudinal_accel(command.accel);
            fleet.push(index as u64, &self.steppers[index], &vehicle.state, command, road.curvature(vehicle.state.s));
            moving.push(index as u32);
        }
        fleet.step();
        for (k, &index) in moving.iter().enumerate() {
            let vehicle = &mut self.vehicles[index as usize];
            vehicle.state = fleet.state(k);
            self.positions[index as usize] = vehicle.state.s;
            if vehicle.state.s > road.length() {
                vehicle.status = Status::Exited;
            } else if vehicle.status == Status::Driving && road.lane_at(vehicle.state.s, vehicle.state.d).is_none() {
                vehicle.status = Status::OffRoad;
            }
        }
    }

    /// Notes which vehicles entered another lane since the last control instant.
    fn note_lane_entries(&mut self) {
        let time = self.time;
        for (vehicle, car) in self.vehicles.iter_mut().zip(self.scene.cars()) {
            if car.lane != vehicle.lane_entry.lane {
                vehicle.lane_entry = LaneEntry { lane: car.lane, at: Some(time) };
            }
        }
    }

    /// Oriented-box overlap between vehicles close along the road (a sweep over the
    /// sorted order: only pairs nearer than one body diagonal in s are tested).
    fn detect_collisions(&mut self) {
        let body = self.scene.vehicle;
        let reach = body.length.hypot(body.width);
        let mut found = Vec::new();
        let positions = &self.positions;
        for (k, &i) in self.order.iter().enumerate() {
            for &j in &self.order[k + 1..] {
                if positions[j as usize] - positions[i as usize] > reach {
                    break;
                }
                let (a, b) = (&self.vehicles[i as usize], &self.vehicles[j as usize]);
                let both_crashed = a.status == Status::Crashed && b.status == Status::Crashed;
                // A box reaches sideways at most half its width plus half its length times
                // |sin(heading)| <= |heading|: most neighbours in the next lane fail this.
                let lateral_reach = body.width + body.length * (a.state.heading.abs() + b.state.heading.abs()) / 2.0;
                if a.on_road()
                    && b.on_road()
                    && !both_crashed
                    && (b.state.d - a.state.d).abs() <= lateral_reach
                    && self.boxes_overlap(a, b)
                {
                    let at_fault = collision::at_fault(&self.approach(a), &self.approach(b), self.time);
                    found.push(Collision { rear: VehicleId(i), front: VehicleId(j), at_fault });
                }
            }
        }
        for collision in &found {
            self.vehicles[collision.rear.0 as usize].status = Status::Crashed;
            self.vehicles[collision.front.0 as usize].status = Status::Crashed;
        }
        self.collisions.extend(found);
    }

    /// Vehicle `v` as collision attribution reads it now.
    fn approach(&self, v: &Vehicle) -> Approach {
        let (state, road) = (&v.state, self.road());
        // As the scene reads the lane (`Scene::refresh`), so that entries compare.
        let lane = road.lane_at(state.s, state.d).unwrap_or(v.target_lane);
        let entered = if lane == v.lane_entry.lane { v.lane_entry.at } else { Some(self.time) };
        let lateral_speed = state.vx * state.heading.sin() + state.vy * state.heading.cos();
        Approach { lane, entered, target_lane: v.target_lane, d: state.d, lateral_speed }
    }

    fn boxes_overlap(&self, a: &Vehicle, b: &Vehicle) -> bool {
        let road = self.road();
        let pa = road.to_global(a.state.s, a.state.d, a.state.heading);
        let pb = road.to_global(b.state.s, b.state.d, b.state.heading);
        let body = self.vehicle_params();
        let half = (body.length / 2.0, body.width / 2.0);
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

#[cfg(test)]
mod tests;

/// The threads that help the calling thread decide a world's game-theoretic cars
/// (`World::in_parallel`): one fewer than the cores, built on first use; `None` on one
/// core or if the threads cannot be made (the cars are then decided in turn).
fn decision_pool() -> Option<&'static rayon::ThreadPool> {
    static POOL: OnceLock<Option<rayon::ThreadPool>> = OnceLock::new();
    POOL.get_or_init(|| {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let builder = rayon::ThreadPoolBuilder::new().num_threads(cores.checked_sub(1).filter(|&n| n > 0)?);
        builder.thread_name(|i| format!("decide-{i}")).build().ok()
    })
    .as_ref()
}

/// How many parallel sections have started in the process: a helper kept warm
/// (`keep_warm`) stops spinning when it changes.
static SECTIONS: AtomicU64 = AtomicU64::new(0);

/// How long a decision helper spins for the next control period's work before it may
/// sleep: 100 µs, several times the sequential part of a period (about 20 µs in
/// highway-gt). A sleeping rayon worker took about 25 µs to wake on this machine, once
/// per period, while the calling thread decided alone.
const WARM: Duration = Duration::from_micros(100);

/// Keeps each of `pool`'s threads busy spinning until the next parallel section starts or
/// `WARM` has passed, so that it takes that section's job at once rather than from sleep.
fn keep_warm(pool: &rayon::ThreadPool) {
    let section = SECTIONS.load(Ordering::Relaxed);
    for _ in 0..pool.current_num_threads() {
        pool.spawn(move || {
            let start = Instant::now();
            while SECTIONS.load(Ordering::Relaxed) == section && start.elapsed() < WARM {
                std::hint::spin_loop();
            }
        });
    }
}

/// Runs `job` on the decision pool's thread, which is still spinning from the last
/// control period and so starts it at once (`World::decide_ahead` while a reply
/// travels); here if the process has no pool (one core).
pub fn beside_decisions(job: impl FnOnce() + Send + 'static) {
    match decision_pool() {
        Some(pool) => {
            pool.spawn(job);
            // Ends the spin it would otherwise wait behind, once the job is there to take.
            SECTIONS.fetch_add(1, Ordering::Relaxed);
        }
        None => job(),
    }
}

/// How many of a parallel section's helper jobs started its work and how many left it.
#[derive(Default)]
struct Helpers {
    started: AtomicUsize,
    left: AtomicUsize,
}

/// Counts a helper out of a parallel section's work when dropped, on a panic too.
struct Leaving<'a>(&'a AtomicUsize);

impl Drop for Leaving<'_> {
    fn drop(&mut self) {
        self.0.fetch_add(1, Ordering::Release);
    }
}

/// Runs `work` on this thread and on `helpers` jobs of `scope`'s pool, and spins until
/// every helper that started has left it. rayon would otherwise park a calling thread
/// from outside the pool on a condition variable until its helpers' jobs end, and
/// waking it took about 25 µs on this machine, in every control period whose last
/// decision a helper made.
fn alongside<'scope>(
    scope: &rayon::Scope<'scope>,
    helpers: usize,
    work: &'scope (impl Fn() + Sync),
    count: &'scope Helpers,
) {
    for _ in 0..helpers {
        scope.spawn(move |_| {
            count.started.fetch_add(1, Ordering::AcqRel);
            // Dropped when the work ends or panics (the scope then carries the panic here).
            let _leaving = Leaving(&count.left);
            work();
        });
    }
    // Ends the spin of a helper kept warm (`keep_warm`) now that its job is queued: it
    // takes the job at once rather than looking for work before it is there.
    SECTIONS.fetch_add(1, Ordering::Relaxed);
    work();
    // A helper not started by now finds no task left and ends at once; the scope waits
    // for it.
    while count.left.load(Ordering::Acquire) < count.started.load(Ordering::Acquire) {
        std::hint::spin_loop();
    }
}
