//! Issue 24's collision test (docs/design.md, "Safety layer"): highway-gt.toml with an IDM
//! car in the learner's place, 40 s, on the seeds where a game-theoretic car caused a
//! collision before the safety layer (and seed 2, where one was traced): with it, none
//! does. The 100-seed run is the benchmark,
//! `cargo run --release -p arena-sim --example highway_gt_safety`.

// Shared with the benchmark example, which reads more of it.
#[path = "support/highway_gt.rs"]
#[allow(dead_code)]
mod highway_gt;

use highway_gt::{Crash, run_world, scenario, with_safety, world};

/// Episodes (`Env::reset(Some(seed))`) in which a `gt` car was at fault without the
/// layer, and seed 2.
const EPISODES: [u64; 3] = [2, 51, 53];
/// Worlds built straight from these seeds (`Scenario::build(seed)`) in which one was.
const BUILT: [u64; 2] = [44, 68];

fn at_fault(crashes: &[Crash]) -> Vec<String> {
    crashes
        .iter()
        .filter(|c| c.gt_at_fault())
        .map(|c| format!("t={:.2} {} into {} ({:?})", c.time, c.names[0], c.names[1], c.fault()))
        .collect()
}

#[test]
fn no_game_theoretic_car_causes_a_collision_in_highway_traffic() {
    let scenario = scenario();
    for seed in EPISODES {
        let run = run_world(world(&scenario, seed), 40.0);
        assert_eq!(at_fault(&run.crashes), Vec::<String>::new(), "episode {seed}");
    }
    for seed in BUILT {
        let run = run_world(scenario.build(seed), 40.0);
        assert_eq!(at_fault(&run.crashes), Vec::<String>::new(), "world {seed}");
    }
}

#[test]
fn without_the_safety_layer_a_game_theoretic_car_causes_one() {
    // Episode 51: car31 holds its speed through its lane change while the car ahead in
    // the lane it leaves brakes from 21 to 12 m/s, and runs into it after 2.1 s.
    let scenario = scenario();
    let run = run_world(with_safety(&world(&scenario, 51), false), 3.0);
    assert!(!at_fault(&run.crashes).is_empty(), "{:?}", run.crashes);
    let run = run_world(with_safety(&world(&scenario, 51), true), 3.0);
    assert!(run.crashes.is_empty(), "{:?}", run.crashes);
    assert!(run.emergencies > 0, "the layer braked harder than the games' a_min");
}
