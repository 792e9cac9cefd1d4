//! highway-gt.toml with an IDM car in the learner's place, and who is at fault in each
//! of its collisions as the world attributes them (`Collision::at_fault`, docs/design.md
//! "Collision attribution"): shared by `examples/highway_gt_safety.rs` (the benchmark) and
//! `tests/highway_gt_safety.rs` (a subset of its seeds), and by the stress suite
//! (`support/stress.rs`), which builds its episodes' worlds as `world` does.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use arena_sim::{AtFault, Collision, Driver, DriverSpec, Scenario, VehicleId, World, builtin_scenario};

/// One collision of a run, as it was at the tick it happened.
#[derive(Debug, Clone, PartialEq)]
pub struct Crash {
    /// Simulated time (s).
    pub time: f64,
    /// The two cars and who is at fault, as the world found them.
    pub collision: Collision,
    /// Names of rear and front.
    pub names: [String; 2],
    /// Speeds of rear and front along the lane (m/s).
    pub speeds: [f64; 2],
    /// Drivers of rear and front: `idm`, `gt` or `agent`.
    pub drivers: [&'static str; 2],
}

impl Crash {
    fn gt(&self) -> [bool; 2] {
        self.drivers.map(|d| d == "gt")
    }

    /// Who is at fault.
    pub fn fault(&self) -> AtFault {
        self.collision.at_fault
    }

    /// Whether a game-theoretic car is at fault.
    pub fn gt_at_fault(&self) -> bool {
        self.gt_under(self.fault())
    }

    /// Whether a game-theoretic car is at fault under the lane-entry rule
    /// (`Collision::entry_rule`, the rule before issue 43).
    pub fn gt_at_fault_by_entry_rule(&self) -> bool {
        self.gt_under(self.collision.entry_rule)
    }

    fn gt_under(&self, fault: AtFault) -> bool {
        let [rear, front] = self.gt();
        match fault {
            AtFault::Rear => rear,
            AtFault::Front => front,
            AtFault::Both => rear || front,
        }
    }

    /// Whether a game-theoretic car took part.
    pub fn involves_gt(&self) -> bool {
        self.gt().contains(&true)
    }
}

/// highway-gt.toml with its learner's car (ego_0) driven by IDM + MOBIL.
pub fn scenario() -> Scenario {
    idm_learners(builtin_scenario("highway-gt").expect("highway-gt is built in").expect("it validates"))
}

/// `scenario` with IDM + MOBIL driving every learner's car.
pub fn idm_learners(mut scenario: Scenario) -> Scenario {
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
    let episode = scenario.episode(&mut draws, &[]);
    episode.unwrap_or_else(|e| panic!("{} draws valid episodes: {e}", scenario.name)).build(world_seed)
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
    for (i, vehicle) in world.vehicles().iter().enumerate() {
        let id = VehicleId(i as u32);
        let setup = world.setup(id).clone();
        match world.gt_setup(id) {
            Some(&gt) => {
                let mut gt = gt;
                gt.params.safety.enabled = enabled;
                copy.add_gt(setup, vehicle.clone(), gt)
            }
            None => copy.add(setup, vehicle.clone()),
        };
    }
    copy
}

/// The first `seconds` of `world`, on one decision thread.
pub fn run_world(mut world: World, seconds: f64) -> Run {
    let mut stepper = arena_sim::Stepper::new();
    stepper.set_decision_threads(1);
    let ticks = (seconds / world.params().physics_dt).round() as u64;
    let mut crashes = Vec::new();
    for _ in 0..ticks {
        let seen = world.collisions().len();
        stepper.tick(&mut world);
        for &collision in &world.collisions()[seen..] {
            let (rear, front) = (world.vehicle(collision.rear), world.vehicle(collision.front));
            crashes.push(Crash {
                time: world.time(),
                collision,
                names: [collision.rear, collision.front].map(|id| world.name(id).to_string()),
                speeds: [rear.state.lane_speed(), front.state.lane_speed()],
                drivers: [driver_name(&rear.driver), driver_name(&front.driver)],
            });
        }
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
