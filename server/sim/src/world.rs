//! The world: a road, the vehicles on it and their drivers, as plain state
//! (`WorldState`) beside what its scenario fixes, and what a driver decides from it. A
//! `Stepper` (world/stepper.rs) advances it one fixed physics step at a time: keep the
//! vehicles sorted along the road, let the drivers decide (at the control rate, from one
//! `Scene` of the world as it was at the start of the period), integrate the dynamics,
//! detect collisions. Drivers decide in two rounds: everyone but the game-theoretic
//! followers, then those followers, who answer their leaders' decisions of this period.
//! Results depend on roles, never on the order of vehicles in a file, nor on the stepper
//! (its threads, its clock, the decisions it made ahead). Neighbour queries and collision
//! checks use sorted orders, so a tick costs O(n) for n vehicles.

use std::sync::atomic::{AtomicU64, Ordering};

use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::dynamics::{self, Command, DriverParams, LateralPath, Style, VehicleParams, VehicleState};
use crate::gt::{self, Game, GtMemory, GtParams, GtSetup, GtStep};
use crate::road::{LaneChange, LaneId, Road};
use crate::scene::{Car, DriverKind, Role, Scene};

mod clock;
mod collision;
mod pool;
mod state;
mod stepper;
use crate::traffic::{self, IdmDecision, IdmParams};
use collision::{Approach, Party, safe_gap};
pub use collision::{
    AtFault, BLAME_BRAKE, BLAME_RESPONSE_TIME, CUT_IN_WINDOW, Collision, DRIFT_SPEED, ESTABLISH_TIME, EntryGap,
    LaneEntry, Occupancy, STANDSTILL_SPEED,
};
pub use pool::beside_decisions;
pub use state::{RngState, StateError, WorldState, rng_position};
pub use stepper::Stepper;

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

/// What a `gt` car is made to do in place of part of its own step: an evaluation hook
/// (`World::force`), for asking what would have happened had the AV acted otherwise (the
/// stress suite replays a collision with the car at fault forced to abort its lane change,
/// and again forced to brake). Its driver still decides every period as it would, from
/// the same scene and memory; the world applies the forced part in place of the
/// decision's. Never set by a scenario, an env or a client.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Forced {
    /// Steer back to (or stay in) this lane: the decision's lane changes and steering are
    /// replaced by a path from where the car is to the lane's centre, at a lane change's
    /// pace (`LANE_CHANGE_DURATION` per lane width, at least half of it), which the car
    /// previews as IDM cars do. Its acceleration stays its own.
    ReturnToLane(LaneId),
    /// Brake at this acceleration (m/s^2, negative) until stopped, from the start of each
    /// period: the decision's acceleration is replaced. Its lane changes and steering stay
    /// its own.
    Brake(f64),
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
    /// The paper's game-theoretic AV (`gt`): its memory. Its game, role and constants
    /// (`GtSetup`) the world keeps beside its state (`World::gt_setup`).
    Gt(Box<GtMemory>),
}

/// What a learner last asked its vehicle to do.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum AgentCommand {
    /// Track the vehicle's target speed and target lane (meta actions).
    Track,
    /// Apply this acceleration and preview point directly (continuous actions).
    Direct(Command),
}

/// What a scenario fixes of a vehicle: its name, its style and Table I's parameters for
/// it. The world keeps it beside its state (`World::setup`); it never changes there.
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleSetup {
    /// Name from the scenario file (unique in a world).
    pub name: String,
    /// Driving style (Table I for steering; Table III for costs).
    pub style: Style,
    /// Table I's parameters for `style`, from which the world prepares the vehicle's
    /// physics step when it is added.
    pub driver_params: DriverParams,
}

impl VehicleSetup {
    /// Vehicle `name` driving in `style`, with Table I's parameters for it.
    pub fn new(name: &str, style: Style) -> VehicleSetup {
        VehicleSetup { name: name.to_string(), style, driver_params: DriverParams::for_style(style) }
    }
}

/// What changes of one vehicle: its state, its driver and what the driver is doing.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Vehicle {
    /// The 8 states of eq. (8).
    pub state: VehicleState,
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
    /// The lane it was in at the last control instant, and since when (`collision`, the
    /// lane-entry rule).
    pub lane_entry: LaneEntry,
    /// The lanes its body was in at the last control instant, by lane, each with since
    /// when and the gap to the car then behind it there (`collision`, the responsibility
    /// rule).
    pub occupancy: Vec<Occupancy>,
}

impl Vehicle {
    /// A vehicle cruising along `lane` at `speed`.
    pub fn new(road: &Road, lane: LaneId, s: f64, speed: f64, driver: Driver) -> Vehicle {
        let d = road.lane_center(lane);
        Vehicle {
            state: VehicleState::cruising(s, d, speed),
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
            occupancy: {
                let mut occupancy = Vec::with_capacity(3);
                occupancy.push(Occupancy { lane, since: None, behind: None });
                occupancy
            },
        }
    }

    /// Whether the vehicle still takes part in traffic (driving, or crashed and in the way).
    pub fn on_road(&self) -> bool {
        matches!(self.status, Status::Driving | Status::Crashed)
    }
}

/// Who drives a vehicle whose driver is `driver`, with the setup `gt` if the AV drives it,
/// as the scene tells the other drivers.
fn driver_kind(driver: &Driver, gt: Option<&GtSetup>) -> DriverKind {
    match (driver, gt) {
        (Driver::Agent(_), _) => DriverKind::Agent,
        (Driver::Gt(_), Some(setup)) => DriverKind::Gt(setup.role),
        (Driver::Idm | Driver::Gt(_), _) => DriverKind::Idm,
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

/// The simulated world: the road and what a scenario fixes (bodies, timing, IDM's
/// constants, each vehicle's name, style and prepared physics step and, for a `gt` car,
/// its driver's game, role and constants), and its `WorldState`, everything that
/// changes as it runs. A `Stepper` advances it; the world itself holds no scratch, no
/// clock and no threads, so two worlds are the same world when their states are equal.
/// Its fields are private so its invariants hold: every vehicle is in the sorted order,
/// and a scene is read only when it is the world as of this tick.
#[derive(Debug, Clone)]
pub struct World {
    /// The road, the vehicle body and the cars as drivers last saw them: taken from the
    /// state when it is read (`scene`), a view of it, not state.
    scene: Scene,
    /// The tick `scene` was taken at, and an id no other scene taken in this process has
    /// (decisions made ahead from it name it); `None` once a vehicle changed since.
    scene_taken: Option<(u64, u64)>,
    params: WorldParams,
    idm: IdmParams,
    /// Each vehicle's model constants over one physics step, by id, prepared when it is
    /// added (five divisions each): its body and driver parameters never change after.
    steps: Vec<dynamics::VehicleStep>,
    /// Each vehicle's name, style and driver parameters, by id.
    setups: Vec<VehicleSetup>,
    /// Each `gt` car's game, role and constants, by id (`None` for every other vehicle):
    /// fixed once it is added, as `steps` are.
    gt_setups: Vec<Option<GtSetup>>,
    /// What each `gt` car is forced to do, by id (`force`; empty until a car is): an
    /// evaluation hook beside the state, not in it, so a snapshot does not carry it and
    /// `restore` keeps it.
    forced: Vec<Option<Forced>>,
    state: WorldState,
}

/// How many scenes have been taken in the process: each scene's id.
static SCENES: AtomicU64 = AtomicU64::new(0);

impl World {
    /// An empty world on `road`, its randomness seeded with `seed`.
    pub fn new(road: Road, params: WorldParams, seed: u64) -> World {
        World {
            scene: Scene::new(road, VehicleParams::default(), params.control_dt),
            scene_taken: None,
            params,
            idm: IdmParams::default(),
            steps: Vec::new(),
            setups: Vec::new(),
            gt_setups: Vec::new(),
            forced: Vec::new(),
            state: WorldState::new(seed),
        }
    }

    /// Adds `vehicle`, set up as `setup`, which a learner or IDM drives, and returns its
    /// id; a `gt` car joins with `add_gt`, which gives its driver a setup too.
    pub fn add(&mut self, setup: VehicleSetup, vehicle: Vehicle) -> VehicleId {
        assert!(!matches!(vehicle.driver, Driver::Gt(_)), "a gt car joins a world with add_gt");
        self.join(setup, vehicle, None)
    }

    /// Adds `vehicle`, set up as `setup`, which the game-theoretic AV drives as `gt` says,
    /// its memory fresh, and returns its id.
    pub fn add_gt(&mut self, setup: VehicleSetup, mut vehicle: Vehicle, gt: GtSetup) -> VehicleId {
        vehicle.driver = Driver::Gt(Box::default());
        self.join(setup, vehicle, Some(gt))
    }

    fn join(&mut self, setup: VehicleSetup, vehicle: Vehicle, gt: Option<GtSetup>) -> VehicleId {
        let (body, dt) = (&self.scene.vehicle, self.params.physics_dt);
        self.steps.push(dynamics::VehicleStep::new(body, &setup.driver_params, dt));
        self.setups.push(setup);
        self.gt_setups.push(gt);
        let state = &mut self.state;
        state.order.push(state.vehicles.len() as u32);
        state.vehicles.push(vehicle);
        state.sort_along_road(&mut Vec::new());
        self.scene_taken = None;
        VehicleId(self.state.vehicles.len() as u32 - 1)
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
        self.state.time
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
        &self.state.collisions
    }

    /// Vehicle `id`'s first collision, if it had one.
    pub fn collision_of(&self, id: VehicleId) -> Option<&Collision> {
        if self.vehicle(id).status != Status::Crashed {
            return None;
        }
        self.state.collisions.iter().find(|c| c.other(id).is_some())
    }

    /// Every vehicle, by id.
    pub fn vehicles(&self) -> &[Vehicle] {
        &self.state.vehicles
    }

    /// The vehicle with this id.
    pub fn vehicle(&self, id: VehicleId) -> &Vehicle {
        &self.state.vehicles[id.0 as usize]
    }

    /// Every vehicle's name, style and driver parameters, by id.
    pub fn setups(&self) -> &[VehicleSetup] {
        &self.setups
    }

    /// Vehicle `id`'s name, style and driver parameters.
    pub fn setup(&self, id: VehicleId) -> &VehicleSetup {
        &self.setups[id.0 as usize]
    }

    /// Vehicle `id`'s name (unique in the world).
    pub fn name(&self, id: VehicleId) -> &str {
        &self.setup(id).name
    }

    /// Vehicle `id`'s driving style.
    pub fn style(&self, id: VehicleId) -> Style {
        self.setup(id).style
    }

    /// Vehicle `id`'s driver parameters (Table I for its style).
    pub fn driver_params(&self, id: VehicleId) -> &DriverParams {
        &self.setup(id).driver_params
    }

    /// Every change to a vehicle between ticks comes through here: the scene drivers read
    /// and the decisions made ahead from it are then out of date.
    pub(crate) fn vehicle_mut(&mut self, id: VehicleId) -> &mut Vehicle {
        self.scene_taken = None;
        &mut self.state.vehicles[id.0 as usize]
    }

    pub(crate) fn rng(&mut self) -> &mut ChaCha8Rng {
        &mut self.state.rng
    }

    /// Finds a vehicle by name.
    pub fn find(&self, name: &str) -> Option<VehicleId> {
        self.setups.iter().position(|v| v.name == name).map(|i| VehicleId(i as u32))
    }

    /// The world as drivers see it, taken now if the last one is older than this tick.
    pub fn scene(&mut self) -> &Scene {
        if self.fresh_scene().is_none() {
            self.take_scene();
        }
        &self.scene
    }

    /// The id of the scene taken at this tick, if one was and no vehicle changed since.
    fn fresh_scene(&self) -> Option<u64> {
        self.scene_taken.filter(|&(tick, _)| tick == self.state.ticks).map(|(_, id)| id)
    }

    /// Vehicle `id`'s game, role and constants if the game-theoretic AV drives it.
    pub fn gt_setup(&self, id: VehicleId) -> Option<&GtSetup> {
        match self.vehicle(id).driver {
            Driver::Gt(_) => self.gt_setups[id.0 as usize].as_ref(),
            _ => None,
        }
    }

    /// The parameters the game-theoretic AV plans with for vehicle `id`: its own if it is
    /// a `gt` car, the defaults otherwise.
    pub fn gt_params(&self, id: VehicleId) -> GtParams {
        self.gt_setup(id).map_or_else(GtParams::default, |setup| setup.params)
    }

    /// Gives `gt` car `id`'s driver the constants `params` from now on (a fit, a
    /// comparison with a part switched off); the decisions made ahead are then out of date.
    pub fn set_gt_params(&mut self, id: VehicleId, params: GtParams) {
        let setup = self.gt_setups[id.0 as usize].as_mut().expect("set_gt_params of a gt car");
        setup.params = params;
        self.scene_taken = None;
    }

    /// Forces `gt` car `id` to do `forced` in place of part of its own step from the next
    /// control instant on, until `release`d (an evaluation hook, see `Forced`); it is not
    /// part of the world's state.
    pub fn force(&mut self, id: VehicleId, forced: Forced) {
        assert!(self.gt_setup(id).is_some(), "force a gt car, not '{}'", self.name(id));
        let n = self.state.vehicles.len();
        self.forced.resize(n, None);
        self.forced[id.0 as usize] = Some(forced);
    }

    /// Puts vehicle `id` under another driver from the next control instant on: a learner
    /// (`Driver::Agent`) or IDM + MOBIL with `gt` `None`, or the game-theoretic AV as `gt`
    /// says, its memory fresh (whatever memory `driver` carries); the car's style becomes
    /// `style` (Table I's steering, prepared as `add` prepares it, and Table III's costs).
    /// Its state, lane, path and target speed stay as they are, and so does its name. An
    /// evaluation hook, as `force` is (the counterfactual replays of `counterfactual` put a
    /// car of a collision under each reference driver in turn): no scenario, env or client
    /// changes who drives a car. A forced car is released.
    pub fn replace_driver(&mut self, id: VehicleId, driver: Driver, gt: Option<GtSetup>, style: Style) {
        let driver = match (driver, &gt) {
            (Driver::Gt(_), Some(_)) => Driver::Gt(Box::default()),
            (Driver::Gt(_), None) => panic!("a gt driver for '{}' needs its setup", self.name(id)),
            (_, Some(_)) => panic!("a setup for '{}' but no gt driver", self.name(id)),
            (driver, None) => driver,
        };
        let index = id.0 as usize;
        let setup = &mut self.setups[index];
        setup.style = style;
        setup.driver_params = DriverParams::for_style(style);
        self.steps[index] =
            dynamics::VehicleStep::new(&self.scene.vehicle, &setup.driver_params, self.params.physics_dt);
        self.gt_setups[index] = gt;
        self.release(id);
        self.vehicle_mut(id).driver = driver;
    }

    /// Lets vehicle `id`'s driver decide all of its step again.
    pub fn release(&mut self, id: VehicleId) {
        if let Some(forced) = self.forced.get_mut(id.0 as usize) {
            *forced = None;
        }
    }

    /// What vehicle `id` is forced to do, if anything (`force`).
    pub fn forced(&self, id: VehicleId) -> Option<Forced> {
        self.forced.get(id.0 as usize).copied().flatten()
    }

    /// The setup of vehicle `index`'s driver, the game-theoretic AV.
    fn gt_of(&self, index: usize) -> &GtSetup {
        self.gt_setups[index].as_ref().expect("a gt car has its setup")
    }

    /// Who drives vehicle `index`, as the scene tells the other drivers.
    fn driver_kind(&self, index: usize) -> DriverKind {
        driver_kind(&self.state.vehicles[index].driver, self.gt_setups[index].as_ref())
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
    /// MPC plans), playing `game` as a leader with its constants for `id` (`gt_params`),
    /// with the memory `expert` holds of its earlier periods there, which it then updates
    /// (its `decision` among them).
    /// In a place the AV does not drive, the lane change it makes is its own
    /// (`GtMemory::counterfactual_target`), not the vehicle's.
    pub fn expert_command(&mut self, id: VehicleId, game: Game, expert: &mut GtMemory) -> Command {
        let setup = GtSetup { game, role: Role::Leader, params: self.gt_params(id) };
        self.scene();
        let car = *self.scene.car(id);
        let beside = |lane: &LaneId| lane.0.abs_diff(car.lane.0) <= 1;
        let target = expert.counterfactual_target.filter(beside).unwrap_or(car.target_lane);
        let step = self.scene.with_target_lane(id, target, |scene| gt::plan(scene, id, &setup, expert, None));
        *expert = step.memory;
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

    /// Advances by the whole physics steps closest to `seconds`, with a stepper of its own
    /// for the call (the same bits as any other): code that ticks in a loop holds one.
    pub fn advance(&mut self, seconds: f64) {
        Stepper::new().advance(self, seconds);
    }

    /// Starts a lane change of vehicle `id` to `lane` along a quintic path.
    pub fn change_lane(&mut self, id: VehicleId, lane: LaneId) {
        let time = self.state.time;
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

    fn take_scene(&mut self) {
        let (setups, gt_setups) = (&self.setups, &self.gt_setups);
        let cars = self.state.vehicles.iter().enumerate().map(|(i, vehicle)| Car {
            id: VehicleId(i as u32),
            state: vehicle.state,
            style: setups[i].style,
            driver_params: setups[i].driver_params,
            lane: vehicle.target_lane,
            target_lane: vehicle.target_lane,
            target_speed: vehicle.target_speed,
            accel: vehicle.command.accel,
            preview: vehicle.command.preview,
            status: vehicle.status,
            driver: driver_kind(&vehicle.driver, gt_setups[i].as_ref()),
            decided: None,
        });
        self.scene.refresh(self.state.time, cars);
        self.scene_taken = Some((self.state.ticks, SCENES.fetch_add(1, Ordering::Relaxed)));
    }

    fn is_follower(&self, index: usize) -> bool {
        let vehicle = &self.state.vehicles[index];
        vehicle.status == Status::Driving && self.driver_kind(index) == DriverKind::Gt(Role::Follower)
    }

    fn is_gt(&self, index: usize) -> bool {
        matches!(self.state.vehicles[index].driver, Driver::Gt(_))
    }

    /// Vehicle `index`'s decision for the coming control period, from the scene (taken at
    /// this instant), its own vehicle and the clock of the world.
    fn decide_one(&self, index: usize) -> Decision {
        let id = VehicleId(index as u32);
        let vehicle = &self.state.vehicles[index];
        let (scene, time) = (&self.scene, self.state.time);
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
                let may_change_lanes = time - vehicle.last_lane_decision >= self.idm.lane_change_period - 1e-9
                    && vehicle.path.finished(time);
                Decision::Idm(traffic::decide(&self.idm, scene, id, may_change_lanes))
            }
            (Status::Driving, Driver::Gt(memory)) => {
                Decision::Gt(Box::new(gt::plan(scene, id, self.gt_of(index), memory, None)))
            }
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
                let decided = step.memory.decision;
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
                    self.vehicle_mut(id).last_lane_decision = self.state.time;
                }
                if let Some(lane) = idm.change_to {
                    self.change_lane(id, lane);
                }
                idm.accel
            }
            Decision::Gt(step) => {
                let GtStep { command, change_to, ramp, memory } = *step;
                let forced = self.forced(id);
                match forced {
                    Some(Forced::ReturnToLane(lane)) => self.return_to_lane(id, lane),
                    _ => {
                        if let Some(lane) = change_to {
                            self.change_lane(id, lane);
                        }
                    }
                }
                let accel = match forced {
                    Some(Forced::Brake(accel)) => self.braking(id, accel),
                    _ => {
                        ramp_from = ramp.then_some(previous);
                        command.accel
                    }
                };
                let vehicle = self.vehicle_mut(id);
                vehicle.command.preview = command.preview;
                vehicle.driver = Driver::Gt(Box::new(memory));
                accel
            }
        };
        let vehicle = &mut self.state.vehicles[id.0 as usize];
        vehicle.command.accel = accel;
        vehicle.ramp_from = ramp_from;
    }

    /// `Forced::ReturnToLane`: makes `lane` vehicle `id`'s target lane, along a path from
    /// where it is to the lane's centre at a lane change's pace, unless it is on one.
    fn return_to_lane(&mut self, id: VehicleId, lane: LaneId) {
        let (time, to, width) = (self.state.time, self.road().lane_center(lane), self.road().lane_width());
        let vehicle = self.vehicle_mut(id);
        if vehicle.target_lane == lane && vehicle.path.to == to {
            return;
        }
        let from = vehicle.state.d;
        let duration = dynamics::LANE_CHANGE_DURATION * ((to - from).abs() / width).clamp(0.5, 1.0);
        vehicle.target_lane = lane;
        vehicle.path = LateralPath { from, to, start: time, duration };
    }

    /// `Forced::Brake`: `accel`, held so that vehicle `id` stops rather than reverses
    /// within the coming control period.
    fn braking(&self, id: VehicleId, accel: f64) -> f64 {
        accel.max(-self.vehicle(id).state.vx.max(0.0) / self.params.control_dt)
    }

    /// Notes which vehicles entered another lane since the last control instant: the lane
    /// nearest each one's centre (the lane-entry rule), and the lanes its body is in (the
    /// responsibility rule). Each vehicle's notes are made from the positions and speeds
    /// of this instant alone, never from another's notes, so their order does not matter.
    fn note_lane_entries(&mut self) {
        let time = self.state.time;
        for (vehicle, car) in self.state.vehicles.iter_mut().zip(self.scene.cars()) {
            if car.lane != vehicle.lane_entry.lane {
                vehicle.lane_entry = LaneEntry { lane: car.lane, at: Some(time) };
            }
        }
        for index in 0..self.state.vehicles.len() {
            if !self.state.vehicles[index].on_road() {
                continue;
            }
            if let Some(now) = self.occupancy_now(index) {
                // In place: the notes keep room for three lanes, so a tick allocates nothing.
                let occupancy = &mut self.state.vehicles[index].occupancy;
                occupancy.clear();
                occupancy.extend(now.into_iter().flatten());
            }
        }
    }

    /// Vehicle `v` as the lane-entry rule reads it now.
    fn approach(&self, v: &Vehicle) -> Approach {
        let (state, road) = (&v.state, self.road());
        // As the scene reads the lane (`Scene::refresh`), so that entries compare.
        let lane = road.lane_at(state.s, state.d).unwrap_or(v.target_lane);
        let entered = if lane == v.lane_entry.lane { v.lane_entry.at } else { Some(self.state.time) };
        let lateral_speed = state.vx * state.heading.sin() + state.vy * state.heading.cos();
        Approach { lane, entered, target_lane: v.target_lane, d: state.d, lateral_speed }
    }

    /// Vehicle `index` as the responsibility rule reads it now.
    fn party(&self, index: usize) -> Party {
        let vehicle = &self.state.vehicles[index];
        let lanes = match self.occupancy_now(index) {
            Some(now) => now.into_iter().flatten().collect(),
            None => vehicle.occupancy.clone(),
        };
        Party { id: VehicleId(index as u32), speed: vehicle.state.vx, lanes }
    }

    /// The lanes a vehicle's body is in now: within half its width, and half its length
    /// turned by its heading, of its centre.
    fn lanes_of(&self, vehicle: &Vehicle) -> [Option<LaneId>; 3] {
        let (body, state) = (self.vehicle_params(), &vehicle.state);
        let reach = body.width / 2.0 + body.length / 2.0 * state.heading.sin().abs();
        collision::lanes_reached(self.road(), state.s, state.d, reach)
    }

    /// Vehicle `index`'s lanes now, each with since when and the gap to the car behind it
    /// there as it came in, if they differ from its notes: a lane it was not in at the
    /// last control instant is entered now, and a gap it left too close is re-measured
    /// (its car behind may have fallen back, or left the lane). `None`: as noted.
    fn occupancy_now(&self, index: usize) -> Option<[Option<Occupancy>; 3]> {
        let (vehicle, time) = (&self.state.vehicles[index], self.state.time);
        let lanes = self.lanes_of(vehicle);
        let noted = |lane: LaneId| vehicle.occupancy.iter().find(|o| o.lane == lane);
        let unsettled = |o: &Occupancy| {
            o.behind.is_some_and(|gap| gap.established.is_none())
                && o.since.is_some_and(|since| time - since < ESTABLISH_TIME)
        };
        let same = lanes.iter().flatten().count() == vehicle.occupancy.len()
            && lanes.iter().flatten().all(|&lane| noted(lane).is_some());
        if same && !vehicle.occupancy.iter().any(unsettled) {
            return None;
        }
        Some(lanes.map(|lane| {
            lane.map(|lane| match noted(lane) {
                Some(o) if unsettled(o) => {
                    Occupancy { behind: o.behind.map(|gap| self.settle(index, lane, gap)), ..*o }
                }
                Some(o) => *o,
                None => self.enter(index, lane),
            })
        }))
    }

    /// Vehicle `index` entering `lane` now: the car nearest behind it there, and the gap.
    fn enter(&self, index: usize, lane: LaneId) -> Occupancy {
        let (vehicles, time) = (&self.state.vehicles, self.state.time);
        let me = &vehicles[index];
        let behind = (0..vehicles.len())
            .filter(|&j| self.behind_in(j, index, lane))
            .max_by(|&a, &b| vehicles[a].state.s.total_cmp(&vehicles[b].state.s).then(a.cmp(&b)))
            .map(|j| {
                let rear = &vehicles[j];
                let mut gap = EntryGap {
                    rear: VehicleId(j as u32),
                    gap: me.state.s - rear.state.s - self.vehicle_params().length,
                    speed: me.state.vx,
                    rear_speed: rear.state.vx,
                    rear_accel: rear.longitudinal_accel,
                    established: None,
                };
                gap.established = (!gap.too_close()).then_some(time);
                gap
            });
        Occupancy { lane, since: Some(time), behind }
    }

    /// `gap`, left by vehicle `index` as it entered `lane`, re-measured now: established
    /// if the gap to its car behind is safe, or that car is no longer behind it there.
    fn settle(&self, index: usize, lane: LaneId, gap: EntryGap) -> EntryGap {
        let (vehicles, time) = (&self.state.vehicles, self.state.time);
        let (me, j) = (&vehicles[index], gap.rear.0 as usize);
        let safe = match vehicles.get(j) {
            Some(rear) if self.behind_in(j, index, lane) => {
                let now = me.state.s - rear.state.s - self.vehicle_params().length;
                now >= safe_gap(rear.state.vx, rear.longitudinal_accel, me.state.vx)
            }
            _ => true,
        };
        EntryGap { established: safe.then_some(time), ..gap }
    }

    /// Whether vehicle `j` is on the road behind vehicle `index` (by s, ties by id) with
    /// its body in `lane`.
    fn behind_in(&self, j: usize, index: usize, lane: LaneId) -> bool {
        let vehicles = &self.state.vehicles;
        let (rear, me) = (&vehicles[j], &vehicles[index]);
        let behind = rear.state.s < me.state.s || (rear.state.s == me.state.s && j < index);
        j != index && rear.on_road() && behind && self.lanes_of(rear).contains(&Some(lane))
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
