//! highway-gt.toml with an IDM car in the learner's place, and who is at fault in each
//! of its collisions: shared by `examples/highway_gt_safety.rs` (the benchmark) and
//! `tests/highway_gt_safety.rs` (a subset of its seeds). `at_fault` is the one place the
//! blame is decided, until the world attributes collisions itself.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use arena_sim::{Driver, DriverSpec, LaneId, Scenario, VehicleId, World, builtin_scenario};

/// A lane change begun (or a lane line crossed) this recently (s) makes a collision with
/// a car in the lane it went into its fault. 3, chosen here: a 4 s change crosses the
/// line after 2 s and is centred 2 s later.
pub const CUT_IN_WINDOW: f64 = 3.0;

/// Who caused a collision.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// The car behind ran into the one ahead, which had not cut in on it.
    Rear,
    /// The car ahead cut in on the one behind.
    Front,
    /// Each had changed into the other's lane.
    Both,
}

/// One collision of a run, as it was at the tick it happened.
#[derive(Debug, Clone, PartialEq)]
pub struct Crash {
    /// Simulated time (s).
    pub time: f64,
    /// The car behind and the car ahead.
    pub rear: VehicleId,
    /// The car ahead.
    pub front: VehicleId,
    /// Names of rear and front.
    pub names: [String; 2],
    /// Speeds of rear and front along the lane (m/s).
    pub speeds: [f64; 2],
    /// Drivers of rear and front: `idm`, `gt` or `agent`.
    pub drivers: [&'static str; 2],
    /// Who caused it.
    pub fault: Fault,
}

impl Crash {
    fn gt(&self) -> [bool; 2] {
        self.drivers.map(|d| d == "gt")
    }

    /// Whether a game-theoretic car is at fault.
    pub fn gt_at_fault(&self) -> bool {
        let [rear, front] = self.gt();
        match self.fault {
            Fault::Rear => rear,
            Fault::Front => front,
            Fault::Both => rear || front,
        }
    }

    /// Whether a game-theoretic car took part.
    pub fn involves_gt(&self) -> bool {
        self.gt().contains(&true)
    }
}

/// The lane changes each car made lately: per vehicle, the last instant it was changing
/// (target lane != lane) or crossed a line, and into which lane.
#[derive(Debug, Clone, Default)]
pub struct Changes {
    lane: Vec<LaneId>,
    last: Vec<Option<(f64, LaneId)>>,
}

impl Changes {
    /// Notes where every vehicle is after a tick.
    pub fn observe(&mut self, world: &World) {
        let count = world.vehicles().len();
        if self.lane.len() != count {
            self.lane = (0..count).map(|i| world.current_lane(VehicleId(i as u32))).collect();
            self.last = vec![None; count];
        }
        for (i, vehicle) in world.vehicles().iter().enumerate() {
            let lane = world.current_lane(VehicleId(i as u32));
            if vehicle.target_lane != lane {
                self.last[i] = Some((world.time(), vehicle.target_lane));
            } else if lane != self.lane[i] {
                self.last[i] = Some((world.time(), lane));
            }
            self.lane[i] = lane;
        }
    }

    /// Whether car `a` changed into `b`'s lane (the lane `b` is in or going to) within
    /// `CUT_IN_WINDOW` before `time`.
    fn cut_in(&self, world: &World, a: VehicleId, b: VehicleId, time: f64) -> bool {
        let lanes = [world.current_lane(b), world.vehicle(b).target_lane];
        self.last[a.0 as usize].is_some_and(|(t, lane)| time - t <= CUT_IN_WINDOW && lanes.contains(&lane))
    }
}

/// Who caused the collision of `rear` into `front` now: a car that changed into the
/// other's lane within `CUT_IN_WINDOW`; otherwise the car behind.
pub fn at_fault(world: &World, changes: &Changes, rear: VehicleId, front: VehicleId) -> Fault {
    let time = world.time();
    match (changes.cut_in(world, rear, front, time), changes.cut_in(world, front, rear, time)) {
        (true, true) => Fault::Both,
        (false, true) => Fault::Front,
        _ => Fault::Rear,
    }
}

/// highway-gt.toml with its learner's car (ego_0) driven by IDM + MOBIL.
pub fn scenario() -> Scenario {
    let mut scenario = builtin_scenario("highway-gt").expect("highway-gt is built in").expect("it validates");
    for vehicle in &mut scenario.vehicles {
        if matches!(vehicle.driver, DriverSpec::Agent(_)) {
            vehicle.driver = DriverSpec::Idm;
        }
    }
    scenario
}

fn driver_name(driver: &Driver) -> &'static str {
    match driver {
        Driver::Agent(_) => "agent",
        Driver::Idm => "idm",
        Driver::Gt(_) => "gt",
    }
}

/// The world of episode `seed` as the env builds it (`Env::reset(Some(seed))`): the seed
/// seeds the seeds, whose first draw seeds the episode's draws and the world.
pub fn world(scenario: &Scenario, seed: u64) -> World {
    let world_seed = ChaCha8Rng::seed_from_u64(seed).next_u64();
    let mut draws = ChaCha8Rng::seed_from_u64(world_seed);
    scenario.episode(&mut draws, &[]).expect("highway-gt draws valid episodes").build(world_seed)
}

/// What a run of episode `seed` gave.
#[derive(Debug, Clone, Default)]
pub struct Run {
    /// Every collision, in order.
    pub crashes: Vec<Crash>,
    /// The game-theoretic cars' plans, those whose acceleration the safety layer lowered,
    /// and those of them that braked harder than the games' a_min.
    pub plans: u64,
    /// See `plans`.
    pub overrides: u64,
    /// See `plans`.
    pub emergencies: u64,
}

/// `world`, at time zero, with the safety layer of every game-theoretic car switched on
/// or off (`SafetyParams::enabled`): the same vehicles in the same order (the world's RNG,
/// which the copy does not share, only places the traffic).
pub fn with_safety(world: &World, enabled: bool) -> World {
    let mut copy = World::new(world.road().clone(), *world.params(), 0);
    for vehicle in world.vehicles() {
        let mut vehicle = vehicle.clone();
        if let Driver::Gt(gt) = &mut vehicle.driver {
            gt.params.safety.enabled = enabled;
        }
        copy.add(vehicle);
    }
    copy
}

/// The first `seconds` of `world`, on one decision thread.
pub fn run_world(mut world: World, seconds: f64) -> Run {
    world.set_decision_threads(1);
    let mut changes = Changes::default();
    changes.observe(&world);
    let ticks = (seconds / world.params().physics_dt).round() as u64;
    let mut crashes = Vec::new();
    for _ in 0..ticks {
        let seen = world.collisions().len();
        world.tick();
        for &collision in &world.collisions()[seen..] {
            let (rear, front) = (world.vehicle(collision.rear), world.vehicle(collision.front));
            crashes.push(Crash {
                time: world.time(),
                rear: collision.rear,
                front: collision.front,
                names: [rear.name.clone(), front.name.clone()],
                speeds: [rear.state.lane_speed(), front.state.lane_speed()],
                drivers: [driver_name(&rear.driver), driver_name(&front.driver)],
                fault: at_fault(&world, &changes, collision.rear, collision.front),
            });
        }
        changes.observe(&world);
    }
    let mut run = Run { crashes, ..Run::default() };
    for vehicle in world.vehicles() {
        if let Driver::Gt(gt) = &vehicle.driver {
            run.plans += u64::from(gt.diagnostics.plans);
            run.overrides += u64::from(gt.diagnostics.overrides);
            run.emergencies += u64::from(gt.diagnostics.emergencies);
        }
    }
    run
}
