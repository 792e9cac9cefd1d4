//! The spatial index `Road::to_frenet` searches: a bounding box around each section of the
//! reference line, a hierarchy of boxes over runs of consecutive sections, and each
//! section's chord, so a query measures the few sections near the point instead of every one.
//!
//! Boxes and chords bound every foot point the measurement can compute, rounding included,
//! and a box or section is skipped only when it is strictly farther than the best section
//! so far, so the answer is the one a walk over every section gives.

use super::{Pose, Section, SectionStart, advance, is_straight};
use std::f64::consts::{FRAC_PI_2, PI};

/// Sections per leaf: their chords are tested before any is measured, which is dearer.
const LEAF: usize = 4;
/// Arcs turning further than this (rad) get no chord: one of a half turn or more does not
/// lie along its chord.
const CHORD_TURN: f64 = 3.0;

/// An axis-aligned box, `lo` to `hi` in X and Y.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Bounds {
    lo: [f64; 2],
    hi: [f64; 2],
}

impl Bounds {
    const EMPTY: Bounds = Bounds { lo: [f64::INFINITY; 2], hi: [f64::NEG_INFINITY; 2] };

    fn union(self, other: Bounds) -> Bounds {
        Bounds {
            lo: [self.lo[0].min(other.lo[0]), self.lo[1].min(other.lo[1])],
            hi: [self.hi[0].max(other.hi[0]), self.hi[1].max(other.hi[1])],
        }
    }

    #[cfg(test)]
    pub(super) fn contains(&self, x: f64, y: f64) -> bool {
        (self.lo[0]..=self.hi[0]).contains(&x) && (self.lo[1]..=self.hi[1]).contains(&y)
    }

    /// A lower bound on the distance `foot` computes from (x, y) to any point in the
    /// box. Rounding is monotone, so the gaps are no larger than the foot's; the factor
    /// covers the last bits of `length` and `hypot`.
    fn distance_below(&self, x: f64, y: f64) -> f64 {
        let dx = (self.lo[0] - x).max(x - self.hi[0]).max(0.0);
        let dy = (self.lo[1] - y).max(y - self.hi[1]).max(0.0);
        length(dx, dy) * (1.0 - 1e-9)
    }
}

/// The length of (dx, dy) to within a few ulps: a square root where the squares do not
/// overflow, being several times quicker than `hypot`.
fn length(dx: f64, dy: f64) -> f64 {
    let squared = dx * dx + dy * dy;
    if squared.is_finite() { squared.sqrt() } else { dx.hypot(dy) }
}

/// The box around a section's reference line: every point `advance` gives along it.
pub(super) fn section_bounds(section: Section, start: Pose) -> Bounds {
    let end = advance(start, section.curvature(), section.length());
    if is_straight(section.curvature()) {
        // x0 + t cos(h) rounds monotonically in t, so the computed ends bound the rest.
        return Bounds { lo: [start.x.min(end.x), start.y.min(end.y)], hi: [start.x.max(end.x), start.y.max(end.y)] };
    }
    // `advance` puts the point at heading h at (x0 + r (sin h - sin h0), y0 - r (cos h - cos h0)).
    let radius = 1.0 / section.curvature();
    let (sin0, cos0) = start.heading.sin_cos();
    let ((sin_lo, sin_hi), (cos_lo, cos_hi)) = sweep_ranges(start.heading, end.heading);
    let xs = [start.x + radius * (sin_lo - sin0), start.x + radius * (sin_hi - sin0)];
    let ys = [start.y - radius * (cos_lo - cos0), start.y - radius * (cos_hi - cos0)];
    // Sines and the sums above are each within a few ulps; a thousand times that.
    let pad = 1e-12 * (start.x.abs() + start.y.abs() + radius.abs());
    Bounds {
        lo: [xs[0].min(xs[1]) - pad, ys[0].min(ys[1]) - pad],
        hi: [xs[0].max(xs[1]) + pad, ys[0].max(ys[1]) + pad],
    }
}

/// The ranges of sin and cos over the headings between `a` and `b`: their values at the
/// ends, widened to +-1 where a quarter turn k pi/2 lies inside (or within rounding of) it.
fn sweep_ranges(a: f64, b: f64) -> ((f64, f64), (f64, f64)) {
    let (low, high) = (a.min(b), a.max(b));
    let slack = 1e-9 * (1.0 + low.abs().max(high.abs()));
    let (first, last) = (((low - slack) / FRAC_PI_2).ceil(), ((high + slack) / FRAC_PI_2).floor());
    // Four quarter turns are the whole circle; so is a heading too large to tell quarters
    // apart, or a non-finite one.
    if !(last - first < 4.0 && high - low < 2.0 * PI && low.abs().max(high.abs()) < 1e12) {
        return ((-1.0, 1.0), (-1.0, 1.0));
    }
    let ((sin_a, cos_a), (sin_b, cos_b)) = (a.sin_cos(), b.sin_cos());
    let mut sin = (sin_a.min(sin_b), sin_a.max(sin_b));
    let mut cos = (cos_a.min(cos_b), cos_a.max(cos_b));
    for quarter in first as i64..=last as i64 {
        match quarter.rem_euclid(4) {
            0 => cos.1 = 1.0,
            1 => sin.1 = 1.0,
            2 => cos.0 = -1.0,
            _ => sin.0 = -1.0,
        }
    }
    (sin, cos)
}

/// A section's chord, from its start to its end, and how far its curve strays from it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Chord {
    a: [f64; 2],
    b: [f64; 2],
    /// The arc's sagitta plus rounding; infinite where the chord does not bound the curve.
    slack: f64,
}

impl Chord {
    pub(super) fn new(section: Section, start: Pose) -> Chord {
        let end = advance(start, section.curvature(), section.length());
        let (a, b) = ([start.x, start.y], [end.x, end.y]);
        // The computed curve is a few ulps off the exact one; a thousand times that.
        let radius = if is_straight(section.curvature()) { 0.0 } else { 1.0 / section.curvature() };
        let pad = 1e-12 * (start.x.abs() + start.y.abs() + radius.abs() + section.length());
        let turn = (end.heading - start.heading).abs();
        if radius == 0.0 {
            return Chord { a, b, slack: pad };
        }
        // An arc turning less than a half turn lies within its sagitta of its chord.
        let slack = if turn < CHORD_TURN { radius.abs() * (1.0 - (turn / 2.0).cos()) + pad } else { f64::INFINITY };
        Chord { a, b, slack }
    }

    /// A lower bound on the distance `foot` computes from (x, y) to the section.
    /// The nearest point of the chord is found to within rounding of the coordinates,
    /// which the last term covers.
    pub(super) fn distance_below(&self, x: f64, y: f64) -> f64 {
        let (along, across) = ([self.b[0] - self.a[0], self.b[1] - self.a[1]], [x - self.a[0], y - self.a[1]]);
        let squared = along[0] * along[0] + along[1] * along[1];
        let t =
            if squared > 0.0 { ((across[0] * along[0] + across[1] * along[1]) / squared).clamp(0.0, 1.0) } else { 0.0 };
        let gap = length(across[0] - t * along[0], across[1] - t * along[1]);
        let scale = x.abs() + y.abs() + self.a[0].abs() + self.a[1].abs() + self.b[0].abs() + self.b[1].abs();
        gap * (1.0 - 1e-9) - self.slack - 1e-9 * scale
    }
}

/// A box over sections `first..end`; a split's left child is the next node, its right
/// child `right`.
#[derive(Clone, Copy)]
struct Node {
    bounds: Bounds,
    kind: Kind,
}

#[derive(Clone, Copy)]
enum Kind {
    Leaf { first: usize, end: usize },
    Split { right: usize },
}

/// Bounding-volume hierarchy over the sections in road order: consecutive sections lie
/// close together, so halving the run keeps the boxes tight without sorting.
#[derive(Clone)]
pub(super) struct SectionIndex {
    nodes: Vec<Node>,
    chords: Vec<Chord>,
}

/// The index follows from the sections and their starts, which the road compares already.
impl PartialEq for SectionIndex {
    fn eq(&self, _: &SectionIndex) -> bool {
        true
    }
}

/// The section measured nearest so far, and what its measurement carries.
struct Best<T> {
    distance: f64,
    section: usize,
    value: Option<T>,
}

impl SectionIndex {
    /// Indexes the sections that have a start (all of them, for a road `Road::new` built).
    pub(super) fn new(sections: &[Section], starts: &[SectionStart]) -> SectionIndex {
        let boxes: Vec<Bounds> =
            sections.iter().zip(starts).map(|(section, start)| section_bounds(*section, start.pose)).collect();
        let chords = sections.iter().zip(starts).map(|(section, start)| Chord::new(*section, start.pose)).collect();
        let mut index = SectionIndex { nodes: Vec::with_capacity(2 * boxes.len() / LEAF + 1), chords };
        index.build(&boxes, 0, boxes.len());
        index
    }

    fn build(&mut self, boxes: &[Bounds], first: usize, end: usize) -> Bounds {
        let at = self.nodes.len();
        if end - first <= LEAF {
            let bounds = boxes[first..end].iter().fold(Bounds::EMPTY, |all, b| all.union(*b));
            self.nodes.push(Node { bounds, kind: Kind::Leaf { first, end } });
            return bounds;
        }
        self.nodes.push(Node { bounds: Bounds::EMPTY, kind: Kind::Split { right: 0 } });
        let middle = first + (end - first) / 2;
        let left = self.build(boxes, first, middle);
        let right = self.nodes.len();
        let bounds = left.union(self.build(boxes, middle, end));
        self.nodes[at] = Node { bounds, kind: Kind::Split { right } };
        bounds
    }

    /// The value `measure` gives with the smallest finite distance from (x, y), the lowest
    /// section index among equals; `None` if no section is at a finite distance.
    /// `measure(i)` must compute a distance to a point of section `i`'s reference line.
    pub(super) fn nearest<T>(&self, x: f64, y: f64, measure: impl FnMut(usize) -> (f64, T)) -> Option<T> {
        self.nearest_within(x, y, f64::INFINITY, usize::MAX, measure)
    }

    /// `nearest` among the sections at most `within` away, `None` if there is none, after
    /// at most `budget` boxes and sections looked at: the best found by then (the nearest,
    /// unless more than `budget` lie about as near, as where a road crosses itself many
    /// times).
    pub(super) fn nearest_within<T>(
        &self,
        x: f64,
        y: f64,
        within: f64,
        budget: usize,
        mut measure: impl FnMut(usize) -> (f64, T),
    ) -> Option<T> {
        let mut best = Best { distance: within, section: usize::MAX, value: None };
        let mut left = budget;
        self.visit(0, x, y, &mut measure, &mut best, &mut left);
        best.value
    }

    /// Pushes onto `out`, in road order, every section whose box and chord come within
    /// `bound` of (x, y); false, with `out` cut short, once more than `cap` do.
    pub(super) fn collect(&self, x: f64, y: f64, bound: f64, cap: usize, out: &mut Vec<u32>) -> bool {
        self.gather(0, x, y, bound, cap, out)
    }

    fn gather(&self, node: usize, x: f64, y: f64, bound: f64, cap: usize, out: &mut Vec<u32>) -> bool {
        let node_at = &self.nodes[node];
        if node_at.bounds.distance_below(x, y) > bound {
            return true;
        }
        match node_at.kind {
            Kind::Leaf { first, end } => {
                for section in first..end {
                    if self.chords[section].distance_below(x, y) <= bound {
                        if out.len() == cap {
                            return false;
                        }
                        out.push(section as u32);
                    }
                }
                true
            }
            Kind::Split { right } => {
                self.gather(node + 1, x, y, bound, cap, out) && self.gather(right, x, y, bound, cap, out)
            }
        }
    }

    fn visit<T>(
        &self,
        node: usize,
        x: f64,
        y: f64,
        measure: &mut impl FnMut(usize) -> (f64, T),
        best: &mut Best<T>,
        left: &mut usize,
    ) {
        if *left == 0 {
            return;
        }
        *left -= 1;
        match self.nodes[node].kind {
            Kind::Leaf { first, end } => {
                for section in first..end {
                    if self.chords[section].distance_below(x, y) > best.distance || *left == 0 {
                        continue;
                    }
                    *left -= 1;
                    let (distance, value) = measure(section);
                    let nearer = distance < best.distance || (distance == best.distance && section < best.section);
                    if distance < f64::INFINITY && nearer {
                        *best = Best { distance, section, value: Some(value) };
                    }
                }
            }
            Kind::Split { right } => {
                let mut children =
                    [node + 1, right].map(|child| (self.nodes[child].bounds.distance_below(x, y), child));
                if children[1].0 < children[0].0 {
                    children.swap(0, 1);
                }
                for (below, child) in children {
                    if below > best.distance {
                        continue;
                    }
                    self.visit(child, x, y, measure, best, left);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::foot;
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A section of random length and curvature: straight, nearly straight, gentle, tight,
    /// either sign, up to several full turns.
    fn random_section(rng: &mut ChaCha8Rng) -> Section {
        let length = 10f64.powf(rng.random_range(-2.0..3.0));
        let curvature = match rng.random_range(0..4) {
            0 => return Section::Straight { length },
            1 => 10f64.powf(rng.random_range(-12.0..-9.0)),
            _ => 10f64.powf(rng.random_range(-5.0..0.0)),
        };
        Section::Arc { length, curvature: if rng.random_bool(0.5) { curvature } else { -curvature } }
    }

    #[test]
    fn a_section_box_holds_every_point_along_it() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..20_000 {
            let section = random_section(&mut rng);
            let start = Pose {
                x: rng.random_range(-1e5..1e5),
                y: rng.random_range(-1e5..1e5),
                heading: rng.random_range(-100.0..100.0),
            };
            let bounds = section_bounds(section, start);
            let (curvature, length) = (section.curvature(), section.length());
            let mut along: Vec<f64> = (0..50).map(|_| rng.random_range(0.0..=length)).collect();
            along.extend([0.0, length]);
            // The axis extremes: where the heading is a quarter turn, as near as t can land.
            let turns = (start.heading / FRAC_PI_2).floor() as i64;
            for quarter in turns - 8..=turns + 8 {
                let t = (quarter as f64 * FRAC_PI_2 - start.heading) / curvature;
                along.extend([t, t.next_down(), t.next_up()].into_iter().filter(|t| (0.0..=length).contains(t)));
            }
            for t in along {
                let point = advance(start, curvature, t);
                assert!(
                    bounds.contains(point.x, point.y),
                    "{section:?} from {start:?}: t {t} at {point:?} outside {bounds:?}"
                );
            }
        }
    }

    #[test]
    fn the_distances_below_a_box_and_a_chord_are_at_most_the_measured_one() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for _ in 0..100_000 {
            let section = random_section(&mut rng);
            let start = Pose {
                x: rng.random_range(-1e4..1e4),
                y: rng.random_range(-1e4..1e4),
                heading: rng.random_range(-10.0..10.0),
            };
            let (bounds, chord) = (section_bounds(section, start), Chord::new(section, start));
            let on = advance(start, section.curvature(), rng.random_range(0.0..=section.length()));
            let off = 10f64.powf(rng.random_range(-9.0..4.0));
            let (x, y) = (on.x + rng.random_range(-off..off), on.y + rng.random_range(-off..off));
            let (distance, _) = foot(section, SectionStart { s: 0.0, pose: start }, x, y);
            assert!(bounds.distance_below(x, y) <= distance, "{section:?} from {start:?}, ({x}, {y}): box");
            assert!(chord.distance_below(x, y) <= distance, "{section:?} from {start:?}, ({x}, {y}): chord");
        }
    }
}
