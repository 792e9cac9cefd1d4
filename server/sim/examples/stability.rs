//! The stability study of docs/parameters.md ("K_s"): the lateral modes of the closed loop
//! of eq. (1)-(8), driver and bicycle, about a car cruising straight at 1-40 m/s
//! (`dynamics::lateral_modes`; the integrators of s and v_x left out).
//! `cargo run --release -p arena-sim --example stability`
//!
//! It prints:
//! 1. for the K_s schedule of `DriverParams::steering_ratio_at` (params.rs), each style's largest Re lambda
//!    over 1-40 m/s (every 0.5 m/s), where it is reached, and the value at a few speeds;
//! 2. at each of a few speeds, the window of K_s in which every style's lateral modes have
//!    Re lambda <= -0.02 1/s (issue 23's bound), that window times v_x^2, and the K_s of
//!    schedule and of issue 23's, K_0 v_ref / v_x;
//! 3. the largest Re lambda per style under K_0 v_ref / v_x, for comparison.

use arena_sim::dynamics::{DriverParams, Style, lateral_modes};

/// Issue 23's bound on every lateral mode's real part (1/s).
const BOUND: f64 = -0.02;
/// The speeds scanned for the largest Re lambda: 1 to 40 m/s every 0.5 m/s.
fn speeds() -> impl Iterator<Item = f64> {
    (2..=80).map(|k| k as f64 * 0.5)
}
/// The speeds at which the K_s window is printed (m/s).
const WINDOW_SPEEDS: [f64; 14] = [1.0, 1.5, 2.0, 3.0, 5.0, 7.5, 10.0, 15.0, 20.0, 25.0, 30.0, 33.0, 36.0, 40.0];

/// The largest real part of `driver`'s lateral modes at `speed` (1/s).
fn max_re(driver: &DriverParams, speed: f64) -> f64 {
    lateral_modes(driver, speed).iter().map(|l| l.re).fold(f64::MIN, f64::max)
}

/// The driver of `style` with its K_0 scaled so that K_s at `speed` is `ks`. About straight
/// cruising only K_s at that speed enters the Jacobian (its slope in v_x multiplies the
/// preview error, zero there), so this is the closed loop of any schedule with that K_s.
fn with_ratio(style: Style, speed: f64, ks: f64) -> DriverParams {
    let mut driver = DriverParams::for_style(style);
    driver.steering_ratio *= ks / driver.steering_ratio_at(speed);
    driver
}

/// Whether every style's lateral modes keep within `BOUND` with K_s = `ks` at `speed`.
fn holds(speed: f64, ks: f64) -> bool {
    Style::ALL.iter().all(|&style| max_re(&with_ratio(style, speed, ks), speed) <= BOUND)
}

/// The boundary of the window between `inside` (holds) and `outside` (does not), by bisection
/// in the logarithm.
fn boundary(speed: f64, mut inside: f64, mut outside: f64) -> f64 {
    for _ in 0..40 {
        let mid = (inside * outside).sqrt();
        if holds(speed, mid) { inside = mid } else { outside = mid }
    }
    inside
}

/// The window [low, high] of K_s that holds at `speed`, from a grid 1e-4..1e3 rad/m at 200
/// points a decade refined by bisection; `None` if nothing on the grid holds. Panics if
/// the grid finds more than one window.
fn window(speed: f64) -> Option<(f64, f64)> {
    let grid: Vec<f64> = (0..=1400).map(|k| 1e-4 * 10f64.powf(k as f64 / 200.0)).collect();
    let inside: Vec<usize> = (0..grid.len()).filter(|&k| holds(speed, grid[k])).collect();
    let (&first, &last) = (inside.first()?, inside.last()?);
    assert_eq!(last - first + 1, inside.len(), "more than one window at {speed} m/s");
    assert!(first > 0 && last < grid.len() - 1, "the window at {speed} m/s reaches the grid's end");
    Some((boundary(speed, grid[first], grid[first - 1]), boundary(speed, grid[last], grid[last + 1])))
}

/// The worst (largest) Re lambda over `speeds()` for `driver_at(speed)`, and where.
fn worst(driver_at: impl Fn(f64) -> DriverParams) -> (f64, f64) {
    speeds().map(|v| (max_re(&driver_at(v), v), v)).fold((f64::MIN, 0.0), |a, b| if b.0 > a.0 { b } else { a })
}

fn main() {
    let schedule = DriverParams::default();
    println!(
        "## The K_s schedule of params.rs (`DriverParams::steering_ratio_at`), K_0 = {} rad/m, v_ref = {} m/s\n",
        schedule.steering_ratio, schedule.reference_speed
    );
    let shown = [1.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 36.0, 40.0];
    print!("| style | largest Re λ, 1–40 m/s (1/s) | at (m/s) |");
    shown.iter().for_each(|v| print!(" {v} m/s |"));
    println!("\n|---|---:|---:|{}", "---:|".repeat(shown.len()));
    for style in Style::ALL {
        let driver = DriverParams::for_style(style);
        let (re, at) = worst(|_| driver);
        print!("| {} | {re:+.3} | {at} |", style.name());
        shown.iter().for_each(|&v| print!(" {:+.3} |", max_re(&driver, v)));
        println!();
    }

    println!("\n## The window of K_s with every style's lateral modes at Re λ <= {BOUND} 1/s\n");
    println!(
        "| v_x (m/s) | K_s from (rad/m) | K_s to (rad/m) | from × v_x² | to × v_x² | K_s of params.rs | K_0 v_ref/v_x (issue 23) |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|");
    for v in WINDOW_SPEEDS {
        let previous = schedule.steering_ratio * schedule.reference_speed / v;
        match window(v) {
            Some((low, high)) => println!(
                "| {v} | {low:.4} | {high:.4} | {:.3} | {:.1} | {:.4} | {previous:.4} |",
                low * v * v,
                high * v * v,
                schedule.steering_ratio_at(v)
            ),
            None => println!("| {v} | none | none | | | {:.4} | {previous:.4} |", schedule.steering_ratio_at(v)),
        }
    }

    println!("\n## Issue 23's schedule, K_s = K_0 v_ref / v_x (same K_0 and v_ref)\n");
    println!("| style | largest Re λ, 1–40 m/s (1/s) | at (m/s) | at 30 m/s | at 36 m/s |");
    println!("|---|---:|---:|---:|---:|");
    for style in Style::ALL {
        let previous = |v: f64| with_ratio(style, v, schedule.steering_ratio * schedule.reference_speed / v);
        let (re, at) = worst(previous);
        let at_speed = |v: f64| max_re(&previous(v), v);
        println!("| {} | {re:+.3} | {at} | {:+.3} | {:+.3} |", style.name(), at_speed(30.0), at_speed(36.0));
    }
}
