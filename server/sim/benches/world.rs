//! Throughput of the world step in vehicle-substeps per second (one substep = one
//! vehicle advanced by one physics step, with its share of decisions, neighbour queries
//! and collision checks), for worlds of 10, 100 and 1000 IDM vehicles on highway.toml's
//! road and traffic, at the default 100 Hz physics and 10 Hz decisions.
//!
//! Run: `cargo bench -p arena-sim --bench world`

use arena_sim::{BUILTIN_SCENARIOS, Scenario};
use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};

fn world_of(vehicles: usize) -> arena_sim::World {
    let overrides = [
        // The default physics step (highway.toml itself runs at 1/30 s).
        ("sim.physics_dt".to_string(), toml::Value::Float(0.01)),
        ("traffic.count".to_string(), toml::Value::Integer(vehicles as i64 - 1)),
        ("vehicle.ego_0.driver".to_string(), toml::Value::Table(toml::toml! { kind = "idm" })),
        ("road.sections".to_string(), toml::Value::Array(vec![toml::Value::Table(toml::toml! { length = 100000.0 })])),
    ];
    let (_, file, text) = BUILTIN_SCENARIOS[2];
    let scenario = Scenario::parse(file, text, &overrides).expect("highway.toml with overrides is valid");
    let mut world = scenario.build(1);
    world.advance(5.0); // past the start-up transient
    world
}

fn world_step(c: &mut Criterion) {
    let mut group = c.benchmark_group("world_tick");
    for vehicles in [10, 100, 1000] {
        let start = world_of(vehicles);
        group.throughput(Throughput::Elements(vehicles as u64));
        group.bench_function(BenchmarkId::from_parameter(vehicles), |b| {
            b.iter_custom(|ticks| {
                // Restart every simulated minute so the traffic stays on the road and as
                // dense as it started; only the ticks are timed.
                let mut elapsed = Duration::ZERO;
                let mut left = ticks;
                while left > 0 {
                    let (mut world, mut stepper) = (start.clone(), arena_sim::Stepper::new());
                    let run = left.min(6000);
                    let clock = Instant::now();
                    for _ in 0..run {
                        stepper.tick(&mut world);
                    }
                    elapsed += clock.elapsed();
                    black_box(&world);
                    left -= run;
                }
                elapsed
            })
        });
    }
    group.finish();
}

criterion_group!(benches, world_step);
criterion_main!(benches);
