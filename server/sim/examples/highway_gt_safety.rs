//! The collision benchmark of issue 24: highway-gt.toml with an IDM car in the learner's
//! place, 40 s per seed over seeds 0..99 (or SEEDS from FIRST), every collision printed
//! with who is at fault as the world attributes it, under the responsibility rule and the
//! lane-entry rule before it (docs/design.md, "Collision attribution"), then the totals
//! (docs/design.md, "Safety layer"):
//!
//! `cargo run --release -p arena-sim --example highway_gt_safety [-- SEEDS [FIRST] [--no-safety] | -- --trace SEED CAR [FROM TO]]`
//!
//! `--no-safety` switches the game-theoretic cars' safety layer off (the AV before it).
//! `--trace` prints car CAR of episode SEED every control period from FROM to TO s: its
//! lane, speed and command, its `gt` decision, and the car ahead in each lane it is in or
//! going to.

#[path = "../tests/support/highway_gt.rs"]
mod highway_gt;

use arena_sim::{Driver, LaneId, VehicleId, World};

/// Simulated seconds per seed: highway-gt's 40 env steps of 1 s.
const SECONDS: f64 = 40.0;

/// The nearest car ahead of `id` in `lane` (its centre in the lane, or going to it): its
/// name, bumper gap (m) and speed (m/s).
fn ahead(world: &World, id: VehicleId, lane: LaneId) -> String {
    let me = world.vehicle(id);
    let length = world.vehicle_params().length;
    let found = world
        .vehicles()
        .iter()
        .enumerate()
        .filter(|&(i, v)| i != id.0 as usize && v.on_road() && v.state.s >= me.state.s)
        .filter(|&(i, v)| world.current_lane(VehicleId(i as u32)) == lane || v.target_lane == lane)
        .min_by(|a, b| a.1.state.s.total_cmp(&b.1.state.s));
    found.map_or("-".to_string(), |(i, v)| {
        format!(
            "{} gap {:.1} v {:.1} d {:+.2}",
            world.name(VehicleId(i as u32)),
            v.state.s - me.state.s - length,
            v.state.lane_speed(),
            v.state.d
        )
    })
}

fn trace(seed: u64, name: &str, from: f64, to: f64) {
    let scenario = highway_gt::scenario();
    let mut world = highway_gt::world(&scenario, seed);
    let mut stepper = arena_sim::Stepper::new();
    stepper.set_decision_threads(1);
    let id = world.find(name).expect("CAR: a vehicle's name (car0..car49, ego_0)");
    let substeps = world.params().substeps_per_control();
    while world.time() < to - 1e-9 {
        for _ in 0..substeps {
            stepper.tick(&mut world);
        }
        if world.time() < from - 1e-9 {
            continue;
        }
        let v = world.vehicle(id);
        let lane = world.current_lane(id);
        let decision = match &v.driver {
            Driver::Gt(gt) => format!("{:?} {:+.2}", gt.decision.lane_change, gt.decision.accel),
            _ => String::new(),
        };
        let mut line = format!(
            "t={:5.1} s={:7.1} d={:+.2} lane {} -> {} v={:5.2} a={:+.2} {decision} {:?} | ahead in {}: {}",
            world.time(),
            v.state.s,
            v.state.d,
            lane.0,
            v.target_lane.0,
            v.state.lane_speed(),
            v.command.accel,
            v.status,
            lane.0,
            ahead(&world, id, lane)
        );
        if v.target_lane != lane {
            line += &format!(" | in {}: {}", v.target_lane.0, ahead(&world, id, v.target_lane));
        }
        println!("{line}");
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let Some(at) = args.iter().position(|a| a == "--trace") {
        let arg = |k: usize| args.get(at + k).map(String::as_str);
        let seed: u64 = arg(1).and_then(|s| s.parse().ok()).expect("--trace SEED CAR [FROM TO]");
        let name = arg(2).expect("--trace SEED CAR [FROM TO]");
        let from: f64 = arg(3).map_or(0.0, |s| s.parse().expect("FROM: seconds"));
        let to: f64 = arg(4).map_or(SECONDS, |s| s.parse().expect("TO: seconds"));
        trace(seed, name, from, to);
        return;
    }
    let safety = !args.iter().any(|a| a == "--no-safety");
    let numbers: Vec<&String> = args.iter().filter(|a| !a.starts_with("--")).collect();
    let seeds: u64 = numbers.first().map_or(100, |n| n.parse().expect("SEEDS: a count"));
    let first: u64 = numbers.get(1).map_or(0, |n| n.parse().expect("FIRST: the first seed"));
    let scenario = highway_gt::scenario();
    println!(
        "highway-gt with an IDM ego, seeds {first}..{}, {SECONDS} s each, safety layer {}",
        (first + seeds).saturating_sub(1),
        if safety { "on" } else { "off" }
    );
    let (mut total, mut gt_fault, mut gt_fault_entry, mut gt_involved) = (0, 0, 0, 0);
    let (mut plans, mut overrides, mut emergencies) = (0, 0, 0);
    let mut failing = Vec::new();
    for seed in first..first + seeds {
        let world = highway_gt::with_safety(&highway_gt::world(&scenario, seed), safety);
        let run = highway_gt::run_world(world, SECONDS);
        plans += run.plans;
        overrides += run.overrides;
        emergencies += run.emergencies;
        let crashes = run.crashes;
        for c in &crashes {
            println!(
                "seed {seed:3} t={:5.2} {} ({}, {:.1} m/s) into {} ({}, {:.1} m/s): {:?} at fault{} \
                 (lane-entry rule: {:?}{})",
                c.time,
                c.names[0],
                c.drivers[0],
                c.speeds[0],
                c.names[1],
                c.drivers[1],
                c.speeds[1],
                c.fault(),
                if c.gt_at_fault() { " [gt]" } else { "" },
                c.collision.entry_rule,
                if c.gt_at_fault_by_entry_rule() { " [gt]" } else { "" }
            );
        }
        total += crashes.len();
        gt_fault += crashes.iter().filter(|c| c.gt_at_fault()).count();
        gt_fault_entry += crashes.iter().filter(|c| c.gt_at_fault_by_entry_rule()).count();
        gt_involved += crashes.iter().filter(|c| c.involves_gt()).count();
        if crashes.iter().any(|c| c.gt_at_fault()) {
            failing.push(seed);
        }
    }
    println!(
        "collisions {total}, with a gt car at fault {gt_fault} (lane-entry rule: {gt_fault_entry}), involving a gt \
         car {gt_involved}; seeds with a gt car at fault: {failing:?}"
    );
    let share = |n: u64| 100.0 * n as f64 / plans.max(1) as f64;
    println!(
        "gt plans {plans}: the safety layer lowered the acceleration in {overrides} ({:.2} %), \
         braking harder than the games' a_min in {emergencies} ({:.3} %)",
        share(overrides),
        share(emergencies)
    );
}
