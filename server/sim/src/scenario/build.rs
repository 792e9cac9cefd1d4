//! A `Scenario` made into a `World` at time zero: the named vehicles, sorted by name so
//! nothing depends on the order of `[[vehicle]]` blocks, then the random traffic, placed
//! like highway-env's `Vehicle.create_random` from the world's seeded RNG.

use rand::RngExt;

use super::{DriverSpec, Scenario, TrafficSpec, VehicleSpec};
use crate::dynamics::LateralPath;
use crate::gt::{GtParams, GtSetup};
use crate::world::{AgentCommand, Driver, Vehicle, VehicleSetup, World};

impl Scenario {
    /// Builds the world at time zero; `seed` drives the random traffic. The named
    /// vehicles enter the world sorted by name, so nothing in it (ids, tie-breaks, the
    /// order of sums) depends on the order of `[[vehicle]]` blocks in the file.
    pub fn build(&self, seed: u64) -> World {
        let mut world = World::new(self.road.clone(), self.world, seed);
        let mut named: Vec<&VehicleSpec> = self.vehicles.iter().collect();
        named.sort_by(|a, b| a.name.cmp(&b.name));
        for spec in named {
            let driver = match spec.driver {
                DriverSpec::Agent(_) => Driver::Agent(AgentCommand::Track),
                DriverSpec::Idm | DriverSpec::Gt { .. } => Driver::Idm,
            };
            let setup = VehicleSetup::new(&spec.name, spec.style);
            let mut vehicle = Vehicle::new(&self.road, spec.lane, spec.s, spec.speed, driver);
            vehicle.state.d = spec.d;
            vehicle.path = LateralPath::lane_change(spec.d, self.road.lane_center(spec.lane), 0.0);
            vehicle.target_speed = spec.target_speed;
            match spec.driver {
                DriverSpec::Gt { game, role, params } => world.add_gt(setup, vehicle, GtSetup { game, role, params }),
                _ => world.add(setup, vehicle),
            };
        }
        if let Some(traffic) = &self.traffic {
            place_traffic(&mut world, traffic);
        }
        world
    }
}

/// Whether car `k` of `count` is one of `gt` game-theoretic ones spread evenly.
fn is_gt_car(k: u32, count: u32, gt: u32) -> bool {
    let share = |k: u64| k * u64::from(gt) / u64::from(count.max(1));
    share(u64::from(k) + 1) > share(u64::from(k))
}

/// highway-env's `create_random`: each car goes ahead of the frontmost one (named
/// vehicles included, or the traffic's `start`) by `TrafficSpec::spacing` x U(0.9, 1.1),
/// in a random lane.
fn place_traffic(world: &mut World, traffic: &TrafficSpec) {
    let lanes = world.road().lane_count();
    let named_front =
        world.vehicles().iter().map(|v| v.state.s).fold(None, |m: Option<f64>, s| Some(m.map_or(s, |m| m.max(s))));
    let mut front = traffic.start.or(named_front);
    let mut gt_placed = 0;
    for k in 0..traffic.count {
        let speed = world.rng().random_range(traffic.speed[0]..=traffic.speed[1]);
        let lane = traffic.lanes[world.rng().random_range(0..traffic.lanes.len())];
        let offset = traffic.spacing(speed, lanes);
        let s = front.unwrap_or(3.0 * offset) + offset * world.rng().random_range(0.9..1.1);
        front = Some(s);
        let name = format!("car{k}");
        let vehicle = Vehicle::new(world.road(), lane, s, speed, Driver::Idm);
        match &traffic.gt {
            Some(gt) if is_gt_car(k, traffic.count, gt.count) => {
                let (style, game) = gt.driver(gt_placed);
                gt_placed += 1;
                let setup = GtSetup { game, role: gt.role, params: GtParams::default() };
                world.add_gt(VehicleSetup::new(&name, style), vehicle, setup)
            }
            _ => world.add(VehicleSetup::new(&name, traffic.style), vehicle),
        };
    }
}
