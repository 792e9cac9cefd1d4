//! An env stepped in process the way `clients/python/bench.py` steps it through Python
//! (idle actions, one episode after another, seeds 0, 1, ...): milliseconds of server
//! work per step, per reset and per episode's first step, without the round trip.
//! Subtracted from bench.py's figure it gives what the transport and the client add.
//!
//! Run: `cargo run --release -p arena-server --example env_rate [SCENARIO] [EPISODES]`
//! (default highway-gt, 40 episodes).

use std::time::Instant;

use arena_protocol::{CreateOptions, ResetOptions};
use arena_server::env::Env;

fn main() {
    let mut args = std::env::args().skip(1);
    let name = args.next().unwrap_or_else(|| "highway-gt".to_string());
    let episodes: u64 = match args.next().map(|text| text.parse()) {
        None => 40,
        Some(Ok(n)) if n > 0 => n,
        Some(_) => exit("EPISODES must be a whole number above 0"),
    };
    let scenario = match arena_sim::builtin_scenario(&name) {
        Some(Ok(scenario)) => scenario,
        Some(Err(e)) => exit(&format!("scenario {name}: {e}")),
        None => exit(&format!("no built-in scenario named '{name}'; see scenarios/")),
    };
    let mut env = Env::new(scenario, &CreateOptions::default(), 0).unwrap_or_else(|e| exit(&e.message));
    let (mut steps, mut resetting, mut first, mut stepping) = (0u64, 0.0, 0.0, 0.0);
    for seed in 0..episodes {
        let started = Instant::now();
        env.reset(Some(seed), &ResetOptions::default()).unwrap_or_else(|e| exit(&e.message));
        resetting += started.elapsed().as_secs_f64();
        for k in 0.. {
            let started = Instant::now();
            let rows = env.step(&[]).unwrap_or_else(|e| exit(&e.message));
            let took = started.elapsed().as_secs_f64();
            stepping += took;
            if k == 0 {
                first += took;
            }
            steps += 1;
            if rows.iter().all(|row| row.terminated || row.truncated) {
                break;
            }
        }
    }
    let ms = |seconds: f64, n: u64| 1e3 * seconds / n as f64;
    println!("{name}, {episodes} episodes (seeds 0-{}), {steps} steps, idle actions, in process:", episodes - 1);
    println!("  step        {:.3} ms mean", ms(stepping, steps));
    println!("  first step  {:.3} ms mean (an episode's first)", ms(first, episodes));
    println!("  reset       {:.3} ms mean", ms(resetting, episodes));
    let dt = env.specs().dt;
    println!("  {:.0} simulated s per wall s, resets included", steps as f64 * dt / (stepping + resetting));
}

fn exit(message: &str) -> ! {
    eprintln!("env_rate: {message}");
    std::process::exit(2);
}
