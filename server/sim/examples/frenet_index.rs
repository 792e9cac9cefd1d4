//! What `Road::to_frenet` costs per query on long roads: through the road's section index,
//! and by the walk over every section it replaced, with the answers compared bit for bit.
//! `cargo run --release -p arena-sim --example frenet_index`
//!
//! The roads alternate 5 m straights and 5 m arcs of 400 m radius that bend left for a
//! kilometre, then right for the next, so they meander. Two grids of 50 x 50 points: a
//! 200 m window around the road's middle (what a render asks, pixel by pixel) and the
//! road's whole extent plus 100 m (mostly far from the road).

use arena_sim::{Pose, Road, Section};
use std::hint::black_box;
use std::time::{Duration, Instant};

const SIZES: [usize; 5] = [1, 100, 1_000, 10_000, 30_000];
/// Points per side of each grid.
const GRID: usize = 50;
/// Each timing repeats its grid until at least this long has passed.
const MIN_TIME: Duration = Duration::from_millis(300);

fn meander(count: usize) -> Road {
    let sections = (0..count)
        .map(|i| match i % 2 {
            0 => Section::Straight { length: 5.0 },
            _ if (i / 200) % 2 == 0 => Section::Arc { length: 5.0, curvature: 1.0 / 400.0 },
            _ => Section::Arc { length: 5.0, curvature: -1.0 / 400.0 },
        })
        .collect();
    Road::new(Pose { x: 0.0, y: 0.0, heading: 0.0 }, sections, 3.5, vec![30.0; 3], &[])
}

/// `to_frenet` as it was before the index, from the road's public geometry: each
/// section's start read back through `to_global` (the same bits the road stores).
struct Scan {
    sections: Vec<(Section, f64, Pose)>,
}

impl Scan {
    fn new(road: &Road) -> Scan {
        let mut s = 0.0;
        let mut sections = Vec::new();
        for &section in road.sections() {
            sections.push((section, s, road.to_global(s, 0.0, 0.0)));
            s += section.length();
        }
        Scan { sections }
    }

    fn to_frenet(&self, x: f64, y: f64) -> (f64, f64) {
        let mut best = (f64::INFINITY, 0.0, 0.0);
        for &(section, s, pose) in &self.sections {
            let (along, d) = project(pose, section.curvature(), x, y);
            let clamped = along.clamp(0.0, section.length());
            let foot = advance(pose, section.curvature(), clamped);
            let distance = (foot.x - x).hypot(foot.y - y);
            if distance < best.0 {
                best = (distance, s + clamped, d);
            }
        }
        (best.1, best.2)
    }
}

fn advance(pose: Pose, curvature: f64, length: f64) -> Pose {
    let heading = pose.heading + curvature * length;
    if curvature.abs() < 1e-12 {
        let (sin, cos) = pose.heading.sin_cos();
        return Pose { x: pose.x + length * cos, y: pose.y + length * sin, heading };
    }
    let radius = 1.0 / curvature;
    Pose {
        x: pose.x + radius * (heading.sin() - pose.heading.sin()),
        y: pose.y - radius * (heading.cos() - pose.heading.cos()),
        heading,
    }
}

fn project(start: Pose, curvature: f64, x: f64, y: f64) -> (f64, f64) {
    let (sin, cos) = start.heading.sin_cos();
    let (dx, dy) = (x - start.x, y - start.y);
    if curvature.abs() < 1e-12 {
        return (dx * cos + dy * sin, -dx * sin + dy * cos);
    }
    let radius = 1.0 / curvature;
    let (cx, cy) = (start.x - radius * sin, start.y + radius * cos);
    let (rx, ry) = (x - cx, y - cy);
    let start_angle = (start.y - cy).atan2(start.x - cx);
    let pi = std::f64::consts::PI;
    let angle = (ry.atan2(rx) - start_angle + pi).rem_euclid(2.0 * pi) - pi;
    let d = radius.abs() - rx.hypot(ry);
    (angle * radius, d * radius.signum())
}

/// GRID x GRID points evenly over the box from `lo` to `hi`.
fn grid(lo: (f64, f64), hi: (f64, f64)) -> Vec<(f64, f64)> {
    let at = |i: usize, lo: f64, hi: f64| lo + (hi - lo) * i as f64 / (GRID - 1) as f64;
    (0..GRID).flat_map(|i| (0..GRID).map(move |j| (at(i, lo.0, hi.0), at(j, lo.1, hi.1)))).collect()
}

fn bits((s, d): (f64, f64)) -> (u64, u64) {
    (s.to_bits(), d.to_bits())
}

/// Nanoseconds per query of `frenet` over `points`.
fn ns_per_query(points: &[(f64, f64)], frenet: impl Fn(f64, f64) -> (f64, f64)) -> f64 {
    let start = Instant::now();
    let mut queries = 0;
    while start.elapsed() < MIN_TIME {
        for &(x, y) in points {
            black_box(frenet(black_box(x), black_box(y)));
        }
        queries += points.len();
    }
    start.elapsed().as_nanos() as f64 / queries as f64
}

fn main() {
    println!("ns per to_frenet query (scan: every section; index: the road's own)");
    println!("{:>9} | {:>30} | {:>30}", "", "200 m window at mid-road", "whole extent + 100 m");
    println!("{:>9} | {:>10} {:>9} {:>9} | {:>10} {:>9} {:>9}", "sections", "scan", "index", "x", "scan", "index", "x");
    for count in SIZES {
        let road = meander(count);
        let scan = Scan::new(&road);
        let middle = road.to_global(road.length() / 2.0, 0.0, 0.0);
        let window = grid((middle.x - 100.0, middle.y - 100.0), (middle.x + 100.0, middle.y + 100.0));
        let xs = scan.sections.iter().map(|(.., pose)| pose.x);
        let ys = scan.sections.iter().map(|(.., pose)| pose.y);
        let lo = (xs.clone().fold(f64::INFINITY, f64::min) - 100.0, ys.clone().fold(f64::INFINITY, f64::min) - 100.0);
        let hi = (xs.fold(f64::NEG_INFINITY, f64::max) + 100.0, ys.fold(f64::NEG_INFINITY, f64::max) + 100.0);
        let extent = grid(lo, hi);
        let mut row = format!("{count:>9} |");
        for points in [&window, &extent] {
            let differ =
                points.iter().filter(|&&(x, y)| bits(road.to_frenet(x, y)) != bits(scan.to_frenet(x, y))).count();
            assert_eq!(differ, 0, "{differ} of {} answers differ on {count} sections", points.len());
            let old = ns_per_query(points, |x, y| scan.to_frenet(x, y));
            let new = ns_per_query(points, |x, y| road.to_frenet(x, y));
            row += &format!(" {old:>10.0} {new:>9.0} {:>9.1} |", old / new);
        }
        println!("{}", row.trim_end_matches(" |"));
    }
}
