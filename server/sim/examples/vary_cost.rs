//! What a client's worst `[vary]` costs the server: an inline scenario whose draw always
//! places its last car on the one before it, so every reset draws until it gives up.
//! Timings are printed, not asserted (this machine's, in CPU time of one thread):
//!
//! `cargo run --release -p arena-sim --example vary_cost [-- CARS]`
//!
//! Three files: CARS cars in four lanes (2000 by default); the 1 MiB bound of an inline
//! scenario (`arena_protocol::bounds::MAX_SCENARIO_TEXT_BYTES`) filled with cars; and
//! that bound holding as many cars as a scenario may have (`MAX_VEHICLES`), padded with a
//! lane list the parser must keep. docs/parameters.md, "Scenario bounds", has the figures.

use std::fmt::Write;
use std::time::Instant;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use arena_sim::{MAX_VEHICLES, Scenario};

/// The protocol's bound on an inline scenario's text.
const TEXT_BOUND: usize = 1 << 20;

/// `cars` cars 10 m apart in four lanes, the last drawn onto the one before it.
fn scenario(cars: usize, pad_to: usize) -> String {
    let mut text = String::from("name = \"vary-cost\"\n[sim]\nstep_dt = 0.1\n[road]\nlanes = 4\n");
    let length = 20_000.max(100 + 10 * cars / 4);
    writeln!(text, "speed_limits = [30.0, 30.0, 30.0, 30.0]\nsections = [{{ length = {length}.0 }}]").unwrap();
    let place = |k: usize| (k % 4, 10.0 + 10.0 * (k / 4) as f64);
    for k in 0..cars {
        let (lane, s) = place(k);
        let driver = if k == 0 { "agent" } else { "idm" };
        writeln!(
            text,
            "[[vehicle]]\nname = \"c{k}\"\nlane = {lane}\ns = {s}\nspeed = 20.0\ndriver = {{ kind = \"{driver}\" }}"
        )
        .unwrap();
    }
    let (lane, s) = place(cars - 2);
    writeln!(text, "[vary]\n\"vehicle.c{}.lane\" = {{ choose = [{lane}] }}", cars - 1).unwrap();
    writeln!(text, "\"vehicle.c{}.s\" = {{ range = [{s}, {}] }}", cars - 1, s + 0.5).unwrap();
    if text.len() < pad_to {
        // Padding the parser keeps (a comment it would drop): traffic of no cars in a long
        // list of lanes.
        text.push_str("[traffic]\ncount = 0\nspeed = [20.0, 25.0]\nlanes = [0");
        while text.len() + 3 < pad_to {
            text.push_str(",1");
        }
        text.push_str("]\n");
    }
    text
}

fn cpu_seconds() -> f64 {
    // Process CPU time, so a busy machine shows what the work costs, not the wait.
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let fields: Vec<&str> = stat.rsplit(')').next().unwrap_or("").split_whitespace().collect();
    let ticks = |i: usize| fields.get(i).and_then(|f| f.parse::<f64>().ok()).unwrap_or(0.0);
    (ticks(11) + ticks(12)) / 100.0
}

fn measure(label: &str, text: &str) {
    let (wall, cpu) = (Instant::now(), cpu_seconds());
    let created = Scenario::parse("vary-cost.toml", text, &[]);
    println!(
        "{label}: {} KiB; create {:.3} s wall, {:.2} CPU-s: {}",
        text.len() / 1024,
        wall.elapsed().as_secs_f64(),
        cpu_seconds() - cpu,
        created.as_ref().map_or_else(|e| format!("refused: {e}"), |s| format!("{} cars", s.vehicles.len()))
    );
    let Ok(scenario) = created else { return };
    let (wall, cpu) = (Instant::now(), cpu_seconds());
    let episode = scenario.episode(&mut ChaCha8Rng::seed_from_u64(1), &[]);
    println!(
        "{label}: reset {:.3} s wall, {:.2} CPU-s: {}",
        wall.elapsed().as_secs_f64(),
        cpu_seconds() - cpu,
        episode.map_or_else(|e| format!("refused: {e}"), |_| "drawn".into())
    );
}

fn main() {
    let cars = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(2000);
    measure(&format!("{cars} cars"), &scenario(cars, 0));
    let mut most = cars;
    while scenario(most * 2, 0).len() <= TEXT_BOUND && most < (1 << 20) {
        most *= 2;
    }
    // As many cars as 1 MiB holds, and as a scenario may have.
    let (mut low, mut high) = (most, most * 2);
    while high - low > 1 {
        let mid = (low + high) / 2;
        if scenario(mid, 0).len() <= TEXT_BOUND { low = mid } else { high = mid }
    }
    measure(&format!("1 MiB, {low} cars"), &scenario(low, TEXT_BOUND));
    let most = low.min(MAX_VEHICLES);
    measure(&format!("1 MiB, {most} cars"), &scenario(most, TEXT_BOUND));
}
