//! The K_s study of docs/parameters.md ("K_s"): the lateral modes of the closed loop of
//! eq. (1)-(8), driver and bicycle, about a car cruising straight at 1-40 m/s
//! (`dynamics::lateral_modes`; the integrators of s and v_x left out), and the lane change
//! of `dynamics::LANE_CHANGE_BOUNDS`, as K_s varies.
//! `cargo run --release -p arena-sim --example stability`
//!
//! It prints:
//! 1. for the drivers of params.rs, each style's largest Re lambda over 1-40 m/s (every
//!    0.5 m/s), where it is reached, and its value at a few speeds;
//! 2. at each lane-change speed, per style, the window of K_s in which the lateral modes
//!    keep Re lambda <= -0.02 1/s (issue 23's bound) and the one in which the lane change
//!    keeps the bounds (settling, overshoot; both directions);
//!    and how the windows' edges scale: the largest stable K_s times v_x^2, the smallest
//!    K_s of a lane change within bounds times v_x;
//! 3. for schedules K_s = K_0 (v_ref / v_x)^p (p = 1, the issue's; params.rs' p; 2), per
//!    style, the K_0 that keep the bound at every speed of 1-40 m/s, the K_0 that keep
//!    every lane change within bounds, both, and params.rs' K_0;
//! 4. for comparison, the largest Re lambda under the schedule issue 23 found unstable,
//!    K_s = 0.05 * 20 / v_x for every style.
//!
//! A K_s is tried by scaling a driver's K_0 so that its schedule gives that K_s at the
//! speed in question: about straight cruising only K_s there enters the Jacobian (its
//! slope in v_x multiplies the preview error, zero there), and a lane change at constant
//! speed keeps v_x within millimetres per second of it.

use arena_sim::analysis::{LANE_CHANGE_BOUNDS, lateral_modes};
use arena_sim::{DriverParams, Style};

/// Issue 23's bound on every lateral mode's real part (1/s).
const BOUND: f64 = -0.02;
/// The schedule issue 23 found unstable: K_s = ISSUE_K0 * ISSUE_V_REF / v_x (rad/m, m/s).
const ISSUE_K0: f64 = 0.05;
const ISSUE_V_REF: f64 = 20.0;
/// The physics step of the lane changes (s), as `examples/lane_change.rs`.
const DT: f64 = 0.01;

/// The speeds of the bound: 1 to 40 m/s every 0.5 m/s.
fn speeds() -> Vec<f64> {
    (2..=80).map(|k| k as f64 * 0.5).collect()
}

/// The largest real part of `driver`'s lateral modes at `speed` (1/s).
fn max_re(driver: &DriverParams, speed: f64) -> f64 {
    lateral_modes(driver, speed).iter().map(|l| l.re).fold(f64::MIN, f64::max)
}

/// The driver of `style` with its K_0 scaled so that K_s at `speed` is `ks`.
fn with_ratio(style: Style, speed: f64, ks: f64) -> DriverParams {
    let mut driver = DriverParams::for_style(style);
    driver.steering_ratio *= ks / driver.steering_ratio_at(speed);
    driver
}

fn stable(style: Style, speed: f64, ks: f64) -> bool {
    max_re(&with_ratio(style, speed, ks), speed) <= BOUND
}

fn changes_lane(style: Style, speed: f64, ks: f64) -> bool {
    let (bounds, driver) = (LANE_CHANGE_BOUNDS, with_ratio(style, speed, ks));
    [true, false].iter().all(|&left| bounds.hold(&bounds.response_of(&driver, speed, left, DT)))
}

/// The window [low, high] of K_s (rad/m) in which `holds`, from a grid over [from, to] at 100
/// points a decade refined by bisection in the logarithm; `None` if nothing on the grid
/// holds. Panics if the grid finds more than one window or the window reaches its end.
fn window(from: f64, to: f64, holds: impl Fn(f64) -> bool) -> Option<(f64, f64)> {
    let points = (100.0 * (to / from).log10()).round() as usize;
    let grid: Vec<f64> = (0..=points).map(|k| from * (to / from).powf(k as f64 / points as f64)).collect();
    let inside: Vec<usize> = (0..grid.len()).filter(|&k| holds(grid[k])).collect();
    let (&first, &last) = (inside.first()?, inside.last()?);
    assert_eq!(last - first + 1, inside.len(), "more than one window");
    assert!(first > 0 && last < grid.len() - 1, "the window reaches the grid's end");
    let edge = |mut inside: f64, mut outside: f64| {
        for _ in 0..30 {
            let mid = (inside * outside).sqrt();
            if holds(mid) { inside = mid } else { outside = mid }
        }
        inside
    };
    Some((edge(grid[first], grid[first - 1]), edge(grid[last], grid[last + 1])))
}

/// The K_s windows of one style: of the bound at every speed of `speeds()`, and of the lane
/// change at every speed of `LANE_CHANGE_BOUNDS`.
struct Windows {
    stable: Vec<(f64, (f64, f64))>,
    lane_change: Vec<(f64, (f64, f64))>,
}

fn windows(style: Style) -> Windows {
    let stable = speeds()
        .into_iter()
        .map(|v| (v, window(1e-4, 1e3, |ks| stable(style, v, ks)).expect("a stable K_s at every speed")))
        .collect();
    let lane_change = LANE_CHANGE_BOUNDS
        .speeds
        .iter()
        .map(|&v| (v, window(1e-3, 1.0, |ks| changes_lane(style, v, ks)).expect("a K_s that changes lanes")))
        .collect();
    Windows { stable, lane_change }
}

/// The K_0 (rad/m) of K_s = K_0 (v_ref / v_x)^p that keep K_s inside every window of `of`;
/// `None` if none does.
fn k0_window(of: &[(f64, (f64, f64))], v_ref: f64, p: f64) -> Option<(f64, f64)> {
    let factor = |v: f64| (v_ref / v).powf(p);
    let low = of.iter().map(|&(v, (low, _))| low / factor(v)).fold(0.0, f64::max);
    let high = of.iter().map(|&(v, (_, high))| high / factor(v)).fold(f64::INFINITY, f64::min);
    (low <= high).then_some((low, high))
}

fn intersect(a: Option<(f64, f64)>, b: Option<(f64, f64)>) -> Option<(f64, f64)> {
    let ((a0, a1), (b0, b1)) = (a?, b?);
    (a0.max(b0) <= a1.min(b1)).then_some((a0.max(b0), a1.min(b1)))
}

fn show(window: Option<(f64, f64)>) -> String {
    window.map_or("none".to_string(), |(low, high)| format!("{low:.4}–{high:.4}"))
}

fn main() {
    println!("## The drivers of params.rs: largest Re λ of the lateral modes (1/s)\n");
    let shown = [1.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 36.0, 40.0];
    print!("| style | K_0 (rad/m) | largest, 1–40 m/s | at (m/s) |");
    shown.iter().for_each(|v| print!(" {v} m/s |"));
    println!("\n|---|---:|---:|---:|{}", "---:|".repeat(shown.len()));
    for style in Style::ALL {
        let driver = DriverParams::for_style(style);
        let (re, at) = speeds()
            .into_iter()
            .map(|v| (max_re(&driver, v), v))
            .fold((f64::MIN, 0.0), |a, b| if b.0 > a.0 { b } else { a });
        print!("| {} | {} | {re:+.3} | {at} |", style.name(), driver.steering_ratio);
        shown.iter().for_each(|&v| print!(" {:+.3} |", max_re(&driver, v)));
        println!();
    }

    let all: Vec<(Style, Windows)> = Style::ALL.iter().map(|&style| (style, windows(style))).collect();
    println!("\n## K_s (rad/m) keeping the lateral modes at Re λ <= {BOUND} 1/s, and the lane change within bounds\n");
    println!("| speed (m/s) | style | stable | lane change | both |");
    println!("|---:|---|---|---|---|");
    for (k, &v) in LANE_CHANGE_BOUNDS.speeds.iter().enumerate() {
        for (style, windows) in &all {
            let stable = windows.stable.iter().find(|(speed, _)| *speed == v).map(|&(_, w)| w);
            let lane_change = Some(windows.lane_change[k].1);
            let both = intersect(stable, lane_change);
            println!("| {v} | {} | {} | {} | {} |", style.name(), show(stable), show(lane_change), show(both));
        }
    }

    let edge_speeds = [1.0, 2.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 36.0, 40.0];
    println!(
        "\nThe largest stable K_s times v_x² (rad m), and the smallest K_s of a lane change within bounds times v_x (rad):\n"
    );
    print!("| style |");
    edge_speeds.iter().for_each(|v| print!(" K_s v² at {v} m/s |"));
    LANE_CHANGE_BOUNDS.speeds.iter().for_each(|v| print!(" lane change: K_s v at {v} m/s |"));
    println!("\n|---|{}", "---:|".repeat(edge_speeds.len() + LANE_CHANGE_BOUNDS.speeds.len()));
    for (style, windows) in &all {
        print!("| {} |", style.name());
        for v in edge_speeds {
            let (_, (_, high)) = windows.stable.iter().find(|(speed, _)| *speed == v).expect("a speed of speeds()");
            print!(" {:.1} |", high * v * v);
        }
        windows.lane_change.iter().for_each(|&(v, (low, _))| print!(" {:.2} |", low * v));
        println!();
    }

    let schedule = DriverParams::default();
    let v_ref = schedule.reference_speed;
    let p_params = -schedule.steering_ratio_slope_at(v_ref) * v_ref / schedule.steering_ratio_at(v_ref);
    println!("\n## K_0 (rad/m) of K_s = K_0 ({v_ref} m/s / v_x)^p: the bound at 1–40 m/s, the lane changes, both\n");
    println!("| p | style | stable | lane changes | both | params.rs |");
    println!("|---:|---|---|---|---|---:|");
    for p in [1.0, p_params, 2.0] {
        let mut common = Some((0.0, f64::INFINITY));
        for (style, windows) in &all {
            let stable = k0_window(&windows.stable, v_ref, p);
            let lane_change = k0_window(&windows.lane_change, v_ref, p);
            let both = intersect(stable, lane_change);
            common = intersect(common, both);
            let chosen =
                if p == p_params { DriverParams::for_style(*style).steering_ratio.to_string() } else { String::new() };
            println!(
                "| {p:.1} | {} | {} | {} | {} | {chosen} |",
                style.name(),
                show(stable),
                show(lane_change),
                show(both)
            );
        }
        println!("| {p:.1} | one K_0 for all | | | {} | |", show(common));
    }

    println!("\n## For comparison: K_s = {ISSUE_K0} · {ISSUE_V_REF} m/s / v_x for every style (issue 23)\n");
    println!("| style | largest Re λ, 1–40 m/s (1/s) | at (m/s) | 20 m/s | 27 m/s | 30 m/s | 36 m/s |");
    println!("|---|---:|---:|---:|---:|---:|---:|");
    for style in Style::ALL {
        let at_speed = |v: f64| max_re(&with_ratio(style, v, ISSUE_K0 * ISSUE_V_REF / v), v);
        let (re, at) =
            speeds().into_iter().map(|v| (at_speed(v), v)).fold((f64::MIN, 0.0), |a, b| if b.0 > a.0 { b } else { a });
        print!("| {} | {re:+.3} | {at} |", style.name());
        [20.0, 27.0, 30.0, 36.0].iter().for_each(|&v| print!(" {:+.3} |", at_speed(v)));
        println!();
    }
}
