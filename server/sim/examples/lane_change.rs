//! Prints how a 4 m lane change settles for each style and speed (the table in
//! docs/parameters.md): `cargo run --release -p arena-server --example lane_change`

use arena_sim::dynamics::{Style, lane_change_response};

fn main() {
    println!("| style | speed (m/s) | settling time to ±0.2 m (s) | overshoot (m) |");
    println!("|---|---|---|---|");
    for style in Style::ALL {
        for speed in [15.0, 20.0, 30.0] {
            let response = lane_change_response(style, speed, 4.0, 4.0, 0.2, 15.0, 0.01);
            println!("| {} | {speed:.0} | {:.2} | {:.3} |", style.name(), response.settling_time, response.overshoot);
        }
    }
    let step = lane_change_response(Style::Conservative, 30.0, 4.0, 1e-3, 0.2, 15.0, 0.01);
    println!(
        "\nWithout a path (Y_p stepped 4 m), conservative at 30 m/s: settles at {:.2} s, overshoot {:.3} m",
        step.settling_time, step.overshoot
    );
}
