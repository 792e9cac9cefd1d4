//! Feeds arbitrary text to the scenario loader (`Scenario::parse`), which reads every
//! scenario file a server is started with and every inline scenario a client sends in
//! `CreateEnv`. Holds: no panic, bad text is an error, and what validates also builds
//! (as the proptest in server/sim/src/scenario/tests.rs checks).
#![no_main]

use arena_sim::Scenario;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|text: &str| {
    if let Ok(scenario) = Scenario::parse("fuzz.toml", text, &[]) {
        let world = scenario.build(0);
        assert!(world.vehicles().len() >= scenario.vehicles.len());
    }
});
