//! The game-theoretic AV's per-decision cost on Scenario B's initial state (EC normal,
//! both adjacent cars `gt` followers): one Nash decision, one Stackelberg decision, one
//! MPC solve, and the whole per-tick AV step (read the world, decide, plan). Criterion
//! gives the means; a second pass times single calls and prints p50 / p99 / max, the
//! figures docs/performance.md records. Then the AV step in traffic: every gt car of
//! highway-gt.toml, planned from the world as it is every second from 5 to 24 s (issue
//! 25's target: p50 about 20 us on one core), and the whole highway-gt world on one
//! and on two decision threads (ms per simulated second: the mean that throughput follows),
//! with a digest of the worlds' final states: two builds that print the same digest
//! simulated the same bits.
//!
//! Run: `cargo bench -p arena-paper --bench gt`; `-- tails`, `-- traffic` or `-- world`
//! runs that section alone.

use std::hash::Hasher;
use std::hint::black_box;
use std::time::{Duration, Instant};

use arena_paper::{PaperOptions, PaperScenario, world};
use arena_sim::Driver;
use arena_sim::Style;
use arena_sim::analysis::{Mpc, plan_motion};
use arena_sim::{Game, GtMemory, GtParams, GtSetup, expert_decision, plan};
use arena_sim::{Scene, VehicleId, World, builtin_scenario};
use criterion::Criterion;

/// arena-server's allocator (its `transport::memory`), so the figures are the server's.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// A gt car's driver: its setup and its memory.
type Gt = (GtSetup, GtMemory);

/// Vehicle `id`'s driver, if the AV drives it.
fn gt_of(world: &World, id: VehicleId) -> Option<Gt> {
    match (world.gt_setup(id), &world.vehicle(id).driver) {
        (Some(setup), Driver::Gt(memory)) => Some((*setup, GtMemory::clone(memory))),
        _ => None,
    }
}

/// Scenario B's initial scene, EC's id and its driver.
fn scenario_b(game: Game) -> (Scene, VehicleId, Gt) {
    let mut world =
        world(PaperScenario::B, Style::Normal, game, &PaperOptions::default()).expect("overtake.toml loads");
    let ec = world.find("ec_0").expect("overtake.toml has ec_0");
    let gt = gt_of(&world, ec).expect("the paper's EC is a gt car");
    (world.scene().clone(), ec, gt)
}

fn decision(scene: &Scene, ec: VehicleId, game: Game) -> f64 {
    let params = GtParams::default();
    expert_decision(scene, ec, game, &params).accel
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("gt");
    let (scene, ec, gt) = scenario_b(Game::Nash);
    group.bench_function("nash_decision", |b| b.iter(|| decision(black_box(&scene), ec, Game::Nash)));
    group.bench_function("stackelberg_decision", |b| b.iter(|| decision(black_box(&scene), ec, Game::Stackelberg)));
    let mut mpc = Mpc::new();
    let lane = scene.car(ec).target_lane;
    group.bench_function("mpc_solve", |b| {
        b.iter(|| plan_motion(black_box(&scene), ec, (&gt.0, &gt.1), 0.5, lane, Some(&mut mpc)).map(|s| s.preview))
    });
    let (scene, ec, gt) = scenario_b(Game::Stackelberg);
    group.bench_function("av_step", |b| b.iter(|| plan(black_box(&scene), ec, &gt.0, &gt.1, Some(&mut mpc)).command));
    group.finish();
}

/// Times `f` alone `n` times and prints the percentiles.
fn percentiles(name: &str, n: usize, mut f: impl FnMut()) {
    for _ in 0..n / 10 {
        f(); // warm up
    }
    let mut times: Vec<Duration> = (0..n)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed()
        })
        .collect();
    times.sort();
    let at = |q: f64| times[((n as f64 * q) as usize).min(n - 1)];
    let mean = times.iter().sum::<Duration>().as_secs_f64() / n as f64;
    println!(
        "{name:<22} mean {:>7.1} us  p50 {:>8.1} us  p99 {:>8.1} us  max {:>8.1} us  ({n} calls)",
        mean * 1e6,
        at(0.5).as_secs_f64() * 1e6,
        at(0.99).as_secs_f64() * 1e6,
        times[n - 1].as_secs_f64() * 1e6
    );
}

fn tails() {
    println!("\nsingle-call timings on Scenario B's initial state:");
    let n = 3000;
    let (scene, ec, gt) = scenario_b(Game::Nash);
    percentiles("nash_decision", n, || {
        black_box(decision(&scene, ec, Game::Nash));
    });
    percentiles("stackelberg_decision", n, || {
        black_box(decision(&scene, ec, Game::Stackelberg));
    });
    let mut mpc = Mpc::new();
    let lane = scene.car(ec).target_lane;
    percentiles("mpc_solve", n, || {
        let _ = black_box(plan_motion(&scene, ec, (&gt.0, &gt.1), 0.5, lane, Some(&mut mpc)));
    });
    let (scene, ec, gt) = scenario_b(Game::Stackelberg);
    percentiles("av_step (SE + MPC)", n, || {
        black_box(plan(&scene, ec, &gt.0, &gt.1, Some(&mut mpc)));
    });
    let (scene, ec, gt) = scenario_b(Game::Nash);
    percentiles("av_step (NE + MPC)", n, || {
        black_box(plan(&scene, ec, &gt.0, &gt.1, Some(&mut mpc)));
    });
}

/// highway-gt.toml's world of `seed` at every whole second from 5 to 24 s: its scene and
/// each gt car's id and driver.
fn highway_gt_scenes(seed: u64) -> Vec<(Scene, Vec<(VehicleId, Gt)>)> {
    let scenario = builtin_scenario("highway-gt").expect("highway-gt is built in").expect("it validates");
    let mut world = scenario.build(seed);
    let mut stepper = arena_sim::Stepper::new();
    stepper.set_decision_threads(1);
    let ticks_per_second = (1.0 / world.params().physics_dt).round() as usize;
    let mut scenes = Vec::new();
    for second in 1..=24 {
        for _ in 0..ticks_per_second {
            stepper.tick(&mut world);
        }
        if second < 5 {
            continue;
        }
        let cars = (0..world.vehicles().len() as u32)
            .map(VehicleId)
            .filter_map(|id| gt_of(&world, id).map(|gt| (id, gt)))
            .collect();
        scenes.push((world.scene().clone(), cars));
    }
    scenes
}

fn traffic() {
    println!(
        "
the AV step in traffic (highway-gt.toml, seed 0, every gt car at 5..24 s):"
    );
    let scenes = highway_gt_scenes(0);
    let cars: Vec<(&Scene, VehicleId, &Gt)> =
        scenes.iter().flat_map(|(scene, cars)| cars.iter().map(move |(id, gt)| (scene, *id, gt))).collect();
    let mut mpc = Mpc::new();
    let mut next = 0;
    percentiles("decision in traffic", 3000, || {
        let (scene, id, gt) = cars[next % cars.len()];
        next += 1;
        black_box(expert_decision(scene, id, gt.0.game, &gt.0.params));
    });
    percentiles("mpc in traffic", 3000, || {
        let (scene, id, gt) = cars[next % cars.len()];
        next += 1;
        let lane = scene.car(id).target_lane;
        let _ = black_box(plan_motion(scene, id, (&gt.0, &gt.1), gt.1.decision.accel, lane, Some(&mut mpc)));
    });
    percentiles("av_step in traffic", 3000, || {
        let (scene, id, gt) = cars[next % cars.len()];
        next += 1;
        black_box(plan(scene, id, &gt.0, &gt.1, Some(&mut mpc)));
    });
}

/// The whole highway-gt world (50 cars, 8 gt) on `threads` decision threads: wall ms per
/// simulated second over seconds 5..25 of seeds 0..3, the figure throughput follows (a
/// mean, where the single-call figures above are percentiles).
fn world_rate(threads: usize) {
    let scenario = builtin_scenario("highway-gt").expect("highway-gt is built in").expect("it validates");
    let mut elapsed = Duration::ZERO;
    let mut digest = std::hash::DefaultHasher::new();
    for seed in 0..3 {
        let mut world = scenario.build(seed);
        let mut stepper = arena_sim::Stepper::new();
        stepper.set_decision_threads(threads);
        stepper.advance(&mut world, 5.0);
        let start = Instant::now();
        stepper.advance(&mut world, 20.0);
        elapsed += start.elapsed();
        world.vehicles().iter().flat_map(|v| v.state.to_array()).for_each(|x| digest.write_u64(x.to_bits()));
    }
    let per_second = elapsed.as_secs_f64() * 1e3 / 60.0;
    let digest = digest.finish();
    println!(
        "world, {threads} thread(s)     {per_second:>7.2} ms per simulated s (highway-gt, seeds 0..3, 5..25 s), state digest {digest:016x}"
    );
}

/// The bench's filter (its first argument not an option), which picks the sections
/// after criterion's too: `world` times the whole world only.
fn filter() -> Option<String> {
    std::env::args().skip(1).find(|arg| !arg.starts_with('-'))
}

fn main() {
    let mut criterion = Criterion::default().configure_from_args();
    bench(&mut criterion);
    criterion.final_summary();
    let runs =
        |section: &str| filter().is_none_or(|f| !["tails", "traffic", "world"].contains(&f.as_str()) || f == section);
    if runs("tails") {
        tails();
    }
    if runs("traffic") {
        traffic();
    }
    if runs("world") {
        world_rate(1);
        world_rate(2);
    }
}
