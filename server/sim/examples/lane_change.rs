//! Prints how a 4 m lane change settles for each style and speed at the default 10 ms
//! physics step (the table in docs/parameters.md, "Driver"), with the manoeuvre and bounds
//! of `dynamics::LANE_CHANGE_BOUNDS`: `cargo run --release -p arena-sim --example lane_change
//! [-- --csv FILE]`; `--csv` also writes every row (`style,speed,settling_time,overshoot`),
//! from which the doc's table is rendered (scripts/docs-tables).

use arena_sim::Style;
use arena_sim::analysis::{LANE_CHANGE_BOUNDS, lane_change_response};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let csv_path = args.iter().position(|a| a == "--csv").map(|k| args.get(k + 1).expect("--csv FILE").clone());
    let mut csv = String::from("style,speed,settling_time,overshoot\n");
    let (bounds, dt) = (LANE_CHANGE_BOUNDS, 0.01);
    println!("| style | speed (m/s) | settling time to ±{} m (s) | overshoot (m) |", bounds.band);
    println!("|---|---|---|---|");
    for style in Style::ALL {
        for speed in bounds.speeds {
            let response = bounds.response(style, speed, true, dt);
            println!("| {} | {speed:.0} | {:.2} | {:.3} |", style.name(), response.settling_time, response.overshoot);
            csv += &format!("{},{speed},{},{}\n", style.name(), response.settling_time, response.overshoot);
        }
    }
    let step = lane_change_response(Style::Conservative, 30.0, bounds.width, 1e-3, bounds.band, bounds.horizon, dt);
    println!(
        "\nWithout a path (Y_p stepped {} m), conservative at 30 m/s: settles at {:.2} s, overshoot {:.3} m",
        bounds.width, step.settling_time, step.overshoot
    );
    if let Some(path) = csv_path {
        std::fs::write(&path, csv).unwrap_or_else(|e| panic!("writing {path}: {e}"));
    }
}
