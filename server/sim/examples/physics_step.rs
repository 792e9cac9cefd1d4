//! The physics-step study of docs/parameters.md ("Physics step"): how large an RK4 step
//! eq. (1)-(8) can take before lane changes stop meeting the bounds the dynamics tests
//! hold them to (`dynamics::LANE_CHANGE_BOUNDS`), or the integration goes unstable.
//! `cargo run --release -p arena-sim --example physics_step`
//!
//! For every step that divides highway.toml's control period and env step, it prints:
//! 1. each style's lane change at 15-30 m/s, left and right: settling time, overshoot,
//!    whether the bounds hold, and the largest distance (in d) from the same manoeuvre
//!    integrated with a step of about 1 ms;
//! 2. linear stability (`dynamics::rk4_growth`): how much more RK4 amplifies each mode of
//!    the closed loop of a car cruising at 0.5-36 m/s than the exact flow does; above 1
//!    a mode grows every step however small it starts; the lateral modes' own growth, and
//!    the fastest mode;
//! 3. highway.toml itself for ten seeds x 40 s: crashes, cars off the road, non-finite states;
//! 4. the cost: vehicle-substeps per simulated second of highway.toml.

use arena_sim::Status;
use arena_sim::analysis::{
    LANE_CHANGE_BOUNDS, RK4_CHECK_SPEEDS, cruising_modes, lane_change_trajectory, lateral_modes, rk4_growth,
};
use arena_sim::{BUILTIN_SCENARIOS, Scenario};
use arena_sim::{DriverParams, LANE_CHANGE_DURATION, Style};

/// Candidate physics steps (s); the ones that do not divide the control period are skipped.
const CANDIDATES: [f64; 8] = [0.005, 0.01, 0.02, 0.025, 0.1 / 3.0, 0.04, 0.05, 0.1];
/// RK4 counts as stable while no mode grows by more than this factor per step beyond
/// the exact flow's growth (the slack is the finite differences' rounding).
const STABLE: f64 = 1.0 + 1e-6;
/// The reference trajectory's step is the candidate divided into this many (s) or less.
const REFERENCE_STEP: f64 = 0.001;
/// highway.toml, at physics step `physics_dt` if given, with the learner's car driven by
/// IDM + MOBIL if `idm_ego` (left to itself it holds 25 m/s into slower cars ahead).
fn highway(physics_dt: Option<f64>, idm_ego: bool) -> Scenario {
    let (_, file, text) =
        BUILTIN_SCENARIOS.iter().find(|(name, ..)| *name == "highway").expect("highway.toml is built in");
    let mut overrides: Vec<_> =
        physics_dt.map(|dt| ("sim.physics_dt".to_string(), toml::Value::Float(dt))).into_iter().collect();
    if idm_ego {
        overrides.push(("vehicle.ego_0.driver".to_string(), toml::Value::Table(toml::toml! { kind = "idm" })));
    }
    Scenario::parse(file, text, &overrides).expect("highway.toml is valid")
}

/// Whether `dt` divides `period` into a whole number of steps.
fn divides(dt: f64, period: f64) -> bool {
    let n = period / dt;
    (n - n.round()).abs() < 1e-9
}

/// The largest |d - d_ref| over the manoeuvre, d_ref integrated with dt / n, n whole.
fn deviation(style: Style, speed: f64, width: f64, dt: f64) -> f64 {
    let bounds = LANE_CHANGE_BOUNDS;
    let n = (dt / REFERENCE_STEP).ceil() as usize;
    let coarse = lane_change_trajectory(style, speed, width, LANE_CHANGE_DURATION, bounds.horizon, dt);
    let fine = lane_change_trajectory(style, speed, width, LANE_CHANGE_DURATION, bounds.horizon, dt / n as f64);
    coarse.iter().enumerate().map(|(k, state)| (state.d - fine[(k + 1) * n - 1].d).abs()).fold(0.0, f64::max)
}

fn main() {
    let base = highway(None, false);
    let (control_dt, step_dt) = (base.world.control_dt, base.step_dt);
    let vehicles = base.build(0).vehicles().len();
    let bounds = LANE_CHANGE_BOUNDS;
    let steps: Vec<f64> =
        CANDIDATES.into_iter().filter(|&dt| divides(dt, control_dt) && divides(dt, step_dt)).collect();
    let skipped: Vec<String> =
        CANDIDATES.iter().filter(|dt| !steps.contains(dt)).map(|dt| format!("{:.1} ms", dt * 1e3)).collect();
    println!(
        "highway.toml: physics {:.1} ms, control {control_dt} s, env step {step_dt} s, {vehicles} vehicles",
        base.world.physics_dt * 1e3
    );
    println!("Bounds ({bounds:?}); steps that do not divide the control period, skipped: {}\n", skipped.join(", "));

    println!("## Lane changes (worse of left and right; deviation: max |d - d_ref| against a ~1 ms step)\n");
    println!("| dt (ms) | style | speed (m/s) | settling (s) | overshoot (m) | within bounds | max deviation (m) |");
    println!("|---:|---|---:|---:|---:|---|---:|");
    let mut summary = Vec::new();
    for &dt in &steps {
        let (mut all_hold, mut mirrored, mut worst_settling, mut worst_overshoot, mut worst_deviation) =
            (true, true, 0.0f64, 0.0f64, 0.0f64);
        for style in Style::ALL {
            for speed in bounds.speeds {
                let (left, right) = (bounds.response(style, speed, true, dt), bounds.response(style, speed, false, dt));
                mirrored &= left == right;
                let hold = bounds.hold(&left) && bounds.hold(&right);
                let settling = left.settling_time.max(right.settling_time);
                let overshoot = left.overshoot.max(right.overshoot);
                let dev = deviation(style, speed, bounds.width, dt).max(deviation(style, speed, -bounds.width, dt));
                println!(
                    "| {:.1} | {} | {speed:.0} | {settling:.2} | {overshoot:.3} | {} | {dev:.4} |",
                    dt * 1e3,
                    style.name(),
                    if hold { "yes" } else { "**no**" }
                );
                all_hold &= hold;
                worst_settling = worst_settling.max(settling);
                worst_overshoot = worst_overshoot.max(overshoot);
                worst_deviation = worst_deviation.max(dev);
            }
        }
        summary.push((dt, all_hold, mirrored, worst_settling, worst_overshoot, worst_deviation));
    }

    println!("\n## Stability: RK4's growth beyond the exact flow's (`dynamics::rk4_growth`), worst style, by speed\n");
    print!("| dt (ms) |");
    RK4_CHECK_SPEEDS.iter().for_each(|v| print!(" {v} m/s |"));
    println!("\n|---:|{}", "---:|".repeat(RK4_CHECK_SPEEDS.len()));
    let mut stable = Vec::new();
    for &dt in &steps {
        print!("| {:.1} |", dt * 1e3);
        let growth: Vec<f64> = RK4_CHECK_SPEEDS
            .iter()
            .map(|&v| Style::ALL.iter().map(|&style| rk4_growth(style, v, dt)).fold(0.0, f64::max))
            .collect();
        growth.iter().for_each(|&g| if g > STABLE { print!(" **{g:.3}** |") } else { print!(" {g:.3} |") });
        println!();
        stable.push(growth.iter().all(|&g| g <= STABLE));
    }
    println!(
        "\nThe model's own growth (largest Re lambda of the lateral modes, 1/s; positive: the exact flow grows, whatever the step):\n"
    );
    print!("| style |");
    RK4_CHECK_SPEEDS.iter().for_each(|v| print!(" {v} m/s |"));
    println!("\n|---|{}", "---:|".repeat(RK4_CHECK_SPEEDS.len()));
    for style in Style::ALL {
        print!("| {} |", style.name());
        for &v in &RK4_CHECK_SPEEDS {
            let re = lateral_modes(&DriverParams::for_style(style), v).iter().map(|l| l.re).fold(f64::MIN, f64::max);
            print!(" {re:+.3} |");
        }
        println!();
    }
    println!("\nThe fastest mode (most negative Re lambda of `cruising_modes`, 1/s), the one RK4 must hold:\n");
    print!("| style |");
    RK4_CHECK_SPEEDS.iter().for_each(|v| print!(" {v} m/s |"));
    println!("\n|---|{}", "---:|".repeat(RK4_CHECK_SPEEDS.len()));
    for style in Style::ALL {
        print!("| {} |", style.name());
        for &v in &RK4_CHECK_SPEEDS {
            print!(" {:.1} |", cruising_modes(style, v).iter().map(|l| l.re).fold(f64::MAX, f64::min));
        }
        println!();
    }

    println!("\n## highway.toml, seeds 0-9, 40 s each, every car IDM + MOBIL\n");
    println!("| dt (ms) | crashes | off road | non-finite states | slowest car (m/s) |");
    println!("|---:|---:|---:|---:|---:|");
    let mut world_ok = Vec::new();
    for &dt in &steps {
        let scenario = highway(Some(dt), true);
        let (mut crashed, mut off_road, mut non_finite, mut slowest) = (0, 0, 0, f64::INFINITY);
        for seed in 0..10 {
            let mut world = scenario.build(seed);
            for _ in 0..400 {
                world.advance(0.1);
                for v in world.vehicles().iter().filter(|v| v.status == Status::Driving) {
                    slowest = slowest.min(v.state.vx);
                }
            }
            crashed += world.vehicles().iter().filter(|v| v.status == Status::Crashed).count();
            off_road += world.vehicles().iter().filter(|v| v.status == Status::OffRoad).count();
            non_finite += world.vehicles().iter().filter(|v| !v.state.to_array().iter().all(|x| x.is_finite())).count();
        }
        println!("| {:.1} | {crashed} | {off_road} | {non_finite} | {slowest:.1} |", dt * 1e3);
        world_ok.push(crashed + off_road + non_finite == 0);
    }

    println!("\n## Summary\n");
    println!(
        "| dt (ms) | every lane change within bounds | right mirrors left | worst settling (s) | worst overshoot (m) | max deviation (m) | RK4 stable 0.5-36 m/s | highway.toml clean | vehicle-substeps per simulated s |"
    );
    println!("|---:|---|---|---:|---:|---:|---|---|---:|");
    for (i, &(dt, hold, mirrored, settling, overshoot, dev)) in summary.iter().enumerate() {
        let yes = |b: bool| if b { "yes" } else { "**no**" };
        println!(
            "| {:.1} | {} | {} | {settling:.2} | {overshoot:.3} | {dev:.4} | {} | {} | {:.0} |",
            dt * 1e3,
            yes(hold),
            yes(mirrored),
            yes(stable[i]),
            yes(world_ok[i]),
            vehicles as f64 / dt
        );
    }
    let best = summary
        .iter()
        .enumerate()
        .filter(|(i, s)| s.1 && stable[*i] && world_ok[*i])
        .map(|(_, s)| s.0)
        .fold(0.0, f64::max);
    println!("\nLargest step at which every check holds: {:.1} ms", best * 1e3);
}
