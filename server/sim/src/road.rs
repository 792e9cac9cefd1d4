//! Lane geometry: a reference line made of straight and circular-arc sections, lanes
//! laid side by side along it, lanes that end, and the Frenet (s, d) <-> global (X, Y)
//! conversion every other module reads positions through; (X, Y) -> (s, d) searches a
//! spatial index of the sections (`index`) built with the road.
//!
//! Conventions, as in the paper's Scenario B: lane 0 is the leftmost lane and lane
//! indices grow to the right, so a lane change with sigma = -1 goes to `lane - 1`. The
//! lateral offset `d` is measured to the left of the reference line, which is the centre
//! line of lane 0; lane `i` has its centre at `d = -i * lane_width`.

mod index;

use index::SectionIndex;
use serde::{Deserialize, Serialize};
use std::fmt;

/// Index of a lane, 0 = leftmost.
#[repr(transparent)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct LaneId(pub u32);

/// A lane change relative to the lane a car is in: the paper's sigma of eq. (10)
/// (-1 left, 0 keep, +1 right) as a type.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LaneChange {
    /// To the lane on the left (sigma = -1).
    Left,
    /// Stay in the lane (sigma = 0).
    #[default]
    Keep,
    /// To the lane on the right (sigma = +1).
    Right,
}

impl LaneChange {
    /// The paper's sigma: -1, 0 or 1.
    pub fn sigma(self) -> i8 {
        match self {
            LaneChange::Left => -1,
            LaneChange::Keep => 0,
            LaneChange::Right => 1,
        }
    }

    /// "left", "keep" or "right", as reports print it.
    pub fn name(self) -> &'static str {
        match self {
            LaneChange::Left => "left",
            LaneChange::Keep => "keep",
            LaneChange::Right => "right",
        }
    }

    /// The change of the given sign (negative: left).
    pub fn from_sigma(sigma: i8) -> LaneChange {
        match sigma.signum() {
            -1 => LaneChange::Left,
            0 => LaneChange::Keep,
            _ => LaneChange::Right,
        }
    }

    /// The change that leads from lane `from` to lane `to` (its direction only).
    pub fn between(from: LaneId, to: LaneId) -> LaneChange {
        LaneChange::from_sigma((i64::from(to.0) - i64::from(from.0)).signum() as i8)
    }
}

/// One piece of the reference line.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Section {
    /// A straight piece of the given length (m).
    Straight {
        /// Length (m).
        length: f64,
    },
    /// A circular arc of the given length (m) and signed curvature (1/m, positive bends left).
    Arc {
        /// Length along the arc (m).
        length: f64,
        /// Signed curvature (1/m), positive bends left.
        curvature: f64,
    },
}

impl Section {
    /// Length along the reference line (m).
    pub fn length(&self) -> f64 {
        match *self {
            Section::Straight { length } | Section::Arc { length, .. } => length,
        }
    }

    /// Signed curvature (1/m).
    pub fn curvature(&self) -> f64 {
        match *self {
            Section::Straight { .. } => 0.0,
            Section::Arc { curvature, .. } => curvature,
        }
    }
}

/// A pose in the global frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Global X (m).
    pub x: f64,
    /// Global Y (m), positive to the left of the road's initial heading.
    pub y: f64,
    /// Heading (rad), counter-clockwise from the X axis.
    pub heading: f64,
}

/// The sections near a patch of a picture (`Road::nearby`), in road order.
#[derive(Debug, Clone, Default)]
pub struct NearbySections(Vec<u32>);

/// Where a section starts, precomputed so conversions need no walk along the road.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
struct SectionStart {
    s: f64,
    pose: Pose,
}

/// A multi-lane road.
#[derive(Clone, PartialEq, Serialize, Deserialize)]
#[serde(from = "RoadFields")]
pub struct Road {
    sections: Vec<Section>,
    starts: Vec<SectionStart>,
    lane_width: f64,
    /// Per lane: where the lane ends (m along the reference line), or the road's length.
    lane_ends: Vec<f64>,
    /// Per lane: the speed limit (m/s), `v_max` of eq. (14).
    speed_limits: Vec<f64>,
    length: f64,
    /// Where `to_frenet` looks for the nearest section; it follows from the fields above.
    #[serde(skip)]
    index: SectionIndex,
}

/// A road as it is written: its fields but the index. Deserializing goes through this so
/// the index is rebuilt from what was read and the format stays the one before the index.
#[derive(Deserialize)]
struct RoadFields {
    sections: Vec<Section>,
    starts: Vec<SectionStart>,
    lane_width: f64,
    lane_ends: Vec<f64>,
    speed_limits: Vec<f64>,
    length: f64,
}

/// The derived text without the index: a scenario's identity hashes this text, so it stays
/// what it was before the index.
impl fmt::Debug for Road {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Road")
            .field("sections", &self.sections)
            .field("starts", &self.starts)
            .field("lane_width", &self.lane_width)
            .field("lane_ends", &self.lane_ends)
            .field("speed_limits", &self.speed_limits)
            .field("length", &self.length)
            .finish()
    }
}

impl From<RoadFields> for Road {
    fn from(fields: RoadFields) -> Road {
        let RoadFields { sections, starts, lane_width, lane_ends, speed_limits, length } = fields;
        let index = SectionIndex::new(&sections, &starts);
        Road { sections, starts, lane_width, lane_ends, speed_limits, length, index }
    }
}

impl Road {
    /// Builds a road from its reference line, starting at `origin`. Lanes run the whole
    /// length unless `lane_ends` says otherwise. Inputs are assumed validated (see
    /// `scenario`); this panics only on an empty section list or zero lanes.
    pub fn new(
        origin: Pose,
        sections: Vec<Section>,
        lane_width: f64,
        speed_limits: Vec<f64>,
        lane_ends: &[(LaneId, f64)],
    ) -> Road {
        assert!(!sections.is_empty() && !speed_limits.is_empty());
        let mut starts = Vec::with_capacity(sections.len());
        let mut s = 0.0;
        let mut pose = origin;
        for section in &sections {
            starts.push(SectionStart { s, pose });
            pose = advance(pose, section.curvature(), section.length());
            s += section.length();
        }
        let mut ends = vec![s; speed_limits.len()];
        for &(lane, end) in lane_ends {
            ends[lane.0 as usize] = end.min(s);
        }
        RoadFields { sections, starts, lane_width, lane_ends: ends, speed_limits, length: s }.into()
    }

    /// A straight road, the common case in tests and benchmarks.
    pub fn straight(length: f64, lanes: usize, lane_width: f64, speed_limit: f64) -> Road {
        let origin = Pose { x: 0.0, y: 0.0, heading: 0.0 };
        Road::new(origin, vec![Section::Straight { length }], lane_width, vec![speed_limit; lanes], &[])
    }

    /// Number of lanes.
    pub fn lane_count(&self) -> usize {
        self.speed_limits.len()
    }

    /// Lane width (m).
    pub fn lane_width(&self) -> f64 {
        self.lane_width
    }

    /// The reference line's sections, in order from its start.
    pub fn sections(&self) -> &[Section] {
        &self.sections
    }

    /// Length of the reference line (m).
    pub fn length(&self) -> f64 {
        self.length
    }

    /// Whether `lane` exists on this road.
    pub fn has_lane(&self, lane: i64) -> bool {
        lane >= 0 && (lane as usize) < self.lane_count()
    }

    /// Lateral offset of the lane's centre line (m).
    pub fn lane_center(&self, lane: LaneId) -> f64 {
        -(lane.0 as f64) * self.lane_width
    }

    /// Where `lane` ends (m along the reference line).
    pub fn lane_end(&self, lane: LaneId) -> f64 {
        self.lane_ends[lane.0 as usize]
    }

    /// Whether a car may change from lane `from` into lane `to`: only if `to` does not end
    /// before `from` does. MOBIL and the game-theoretic AV both ask.
    ///
    /// A lane that ends before the car's own is one it must leave again, and neither MOBIL
    /// nor the AV's games weigh that: MOBIL's incentive is the acceleration gained now,
    /// behind the leaders of this instant, and it sees nothing of the merge back that the
    /// lane's end forces later. The
    /// through driver of an on-ramp does not enter the ramp for this reason (Treiber and
    /// Kesting's on-ramps, traffic-simulation.de, let the main road's cars never change onto
    /// the ramp). A rule from the distance a car needs (a change in, a change out again, and
    /// its stopping distance at b, with margins) was weighed and rejected: it guarantees that
    /// the car can stop before the end, not that it finds a gap to leave by, so in dense
    /// traffic the car still stalls there, which is what the rule is to prevent. A lane that
    /// ends no earlier than the car's own (the through lane, seen from the ramp; two lanes
    /// running the road's length) loses the car nothing and stays an option. No constant.
    pub fn worth_entering(&self, from: LaneId, to: LaneId) -> bool {
        self.lane_end(to) >= self.lane_end(from)
    }

    /// Speed limit of `lane` (m/s).
    pub fn speed_limit(&self, lane: LaneId) -> f64 {
        self.speed_limits[lane.0 as usize]
    }

    /// The lane whose strip contains offset `d`, if any (lanes that have ended excluded).
    pub fn lane_at(&self, s: f64, d: f64) -> Option<LaneId> {
        // Truncation is floor here because negatives are refused first; f64::floor is a
        // libm call on baseline x86-64, and this runs for every vehicle every step.
        let position = -d / self.lane_width + 0.5;
        if !(0.0..self.lane_count() as f64).contains(&position) {
            return None;
        }
        let lane = LaneId(position as u32);
        (s <= self.lane_end(lane)).then_some(lane)
    }

    /// The lane nearest to offset `d`, clamped to the road.
    pub fn nearest_lane(&self, d: f64) -> LaneId {
        let index = (-d / self.lane_width).round().clamp(0.0, (self.lane_count() - 1) as f64);
        LaneId(index as u32)
    }

    /// The offsets (low, high) between which the centre line of a body reaching
    /// `half_width` to either side keeps all of it on lanes that have not ended at `s`:
    /// the outer edges of the outermost such lanes, moved in by `half_width`. Past every
    /// lane's end, the whole road's.
    pub fn paved_band(&self, s: f64, half_width: f64) -> (f64, f64) {
        let open = |lane: &usize| s <= self.lane_ends[*lane];
        let lanes = 0..self.lane_count();
        let left = lanes.clone().find(open).unwrap_or(0);
        let right = lanes.rev().find(open).unwrap_or(self.lane_count() - 1);
        let half = 0.5 * self.lane_width;
        let edge = |lane: usize, side: f64| self.lane_center(LaneId(lane as u32)) + side * (half - half_width);
        (edge(right, -1.0), edge(left, 1.0))
    }

    /// Whether (s, d) lies on the paved road: within the outer edges and on a lane that has
    /// not ended.
    pub fn contains(&self, s: f64, d: f64) -> bool {
        (0.0..=self.length).contains(&s) && self.lane_at(s, d).is_some()
    }

    fn section_index(&self, s: f64) -> usize {
        self.starts.partition_point(|start| start.s <= s).saturating_sub(1)
    }

    /// Curvature of the reference line at `s` (1/m).
    pub fn curvature(&self, s: f64) -> f64 {
        self.sections[self.section_index(s)].curvature()
    }

    /// Frenet (s, d) and heading relative to the tangent -> global pose. Past either end
    /// the road is extended along its end tangents.
    pub fn to_global(&self, s: f64, d: f64, relative_heading: f64) -> Pose {
        let index = self.section_index(s);
        let (section, start) = (self.sections[index], self.starts[index]);
        let along = s - start.s;
        let reference = if along < 0.0 {
            advance(start.pose, 0.0, along)
        } else if along > section.length() {
            advance(advance(start.pose, section.curvature(), section.length()), 0.0, along - section.length())
        } else {
            advance(start.pose, section.curvature(), along)
        };
        let (sin, cos) = reference.heading.sin_cos();
        Pose { x: reference.x - d * sin, y: reference.y + d * cos, heading: reference.heading + relative_heading }
    }

    /// Global (X, Y) -> Frenet (s, d): the nearest point of the reference line, on the
    /// first of equally near sections. A point with a non-finite coordinate is at no finite
    /// distance from any section, and gets (0, 0).
    pub fn to_frenet(&self, x: f64, y: f64) -> (f64, f64) {
        if !(x.is_finite() && y.is_finite()) {
            return (0.0, 0.0);
        }
        let nearest = self.index.nearest(x, y, |i| foot(self.sections[i], self.starts[i], x, y));
        nearest.unwrap_or((0.0, 0.0))
    }

    /// The sections a patch of a picture needs (its points at most `radius` from (x, y)),
    /// for `to_frenet_among` to answer each of its points that lies within `within` of the
    /// reference line. At most `cap` sections: where more lie that near (a road passing
    /// the patch over and over), only the one nearest its centre is kept, so a picture's
    /// cost is bounded whatever the road; elsewhere the answers are `to_frenet`'s.
    pub fn nearby(&self, x: f64, y: f64, radius: f64, within: f64, cap: usize) -> NearbySections {
        if !(x.is_finite() && y.is_finite()) {
            return NearbySections(Vec::new());
        }
        let measure = |i: usize| {
            let distance = foot(self.sections[i], self.starts[i], x, y).0;
            (distance, (distance, i))
        };
        let reach = within + radius;
        // Any section found bounds how far a point's nearest can be; the search is cut short
        // where the road lies over itself.
        let centre = self.index.nearest_within(x, y, reach, cap.saturating_mul(4).saturating_add(64), measure);
        let bound =
            centre.map_or(reach, |(distance, i)| (self.foot_reach(i, x, y, distance) + radius).min(within) + radius);
        let mut sections = Vec::new();
        if !self.index.collect(x, y, bound, cap, &mut sections) {
            sections = centre.map(|(_, i)| vec![i as u32]).unwrap_or_default();
        }
        NearbySections(sections)
    }

    /// A bound on section `i`'s foot distance from any point within r of (x, y), less r:
    /// on a straight its foot distance from (x, y), `distance` (the foot is its nearest
    /// point); on an arc the farthest of that and its two ends, since the clamped foot of
    /// a point beyond the arc's ends may be the farther end.
    fn foot_reach(&self, i: usize, x: f64, y: f64, distance: f64) -> f64 {
        let section = self.sections[i];
        if is_straight(section.curvature()) {
            return distance;
        }
        let start = self.starts[i].pose;
        let end = advance(start, section.curvature(), section.length());
        distance.max((start.x - x).hypot(start.y - y)).max((end.x - x).hypot(end.y - y))
    }

    /// `to_frenet` of a point of the patch `nearby` was made for, if it lies within
    /// `within` of the reference line: the first of the nearest of those sections.
    pub fn to_frenet_among(&self, nearby: &NearbySections, x: f64, y: f64, within: f64) -> Option<(f64, f64)> {
        let mut best: Option<(f64, (f64, f64))> = None;
        for &i in &nearby.0 {
            let (distance, frenet) = foot(self.sections[i as usize], self.starts[i as usize], x, y);
            if distance <= within && best.is_none_or(|(least, _)| distance < least) {
                best = Some((distance, frenet));
            }
        }
        best.map(|(_, frenet)| frenet)
    }

    /// `to_frenet` as it was before the index: every section measured, the first nearest kept.
    #[cfg(test)]
    fn to_frenet_scan(&self, x: f64, y: f64) -> (f64, f64) {
        let mut best = (f64::INFINITY, 0.0, 0.0);
        for (section, start) in self.sections.iter().zip(&self.starts) {
            let (along, d) = project(start.pose, section.curvature(), x, y);
            let clamped = along.clamp(0.0, section.length());
            let foot = advance(start.pose, section.curvature(), clamped);
            let distance = (foot.x - x).hypot(foot.y - y);
            if distance < best.0 {
                best = (distance, start.s + clamped, d);
            }
        }
        (best.1, best.2)
    }
}

/// The point of a section's reference line nearest (x, y): its distance, and its (s, d).
fn foot(section: Section, start: SectionStart, x: f64, y: f64) -> (f64, (f64, f64)) {
    let (along, d) = project(start.pose, section.curvature(), x, y);
    let clamped = along.clamp(0.0, section.length());
    let foot = advance(start.pose, section.curvature(), clamped);
    ((foot.x - x).hypot(foot.y - y), (start.s + clamped, d))
}

/// Below this curvature (1/m) a section is computed as a line: the arc's formulas would
/// lose their digits to a radius of over 1e12 m.
fn is_straight(curvature: f64) -> bool {
    curvature.abs() < 1e-12
}

/// Moves along a circle of the given curvature (a line if zero) by `length`.
fn advance(pose: Pose, curvature: f64, length: f64) -> Pose {
    let heading = pose.heading + curvature * length;
    if is_straight(curvature) {
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

/// Projects (x, y) onto the line or circle through `start`: (distance along, offset left).
fn project(start: Pose, curvature: f64, x: f64, y: f64) -> (f64, f64) {
    let (sin, cos) = start.heading.sin_cos();
    let (dx, dy) = (x - start.x, y - start.y);
    if is_straight(curvature) {
        return (dx * cos + dy * sin, -dx * sin + dy * cos);
    }
    let radius = 1.0 / curvature;
    let (cx, cy) = (start.x - radius * sin, start.y + radius * cos);
    let (rx, ry) = (x - cx, y - cy);
    let start_angle = (start.y - cy).atan2(start.x - cx);
    let angle = wrap(ry.atan2(rx) - start_angle);
    let d = radius.abs() - rx.hypot(ry);
    (angle * radius, d * radius.signum())
}

fn wrap(angle: f64) -> f64 {
    (angle + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI) - std::f64::consts::PI
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn curved() -> Road {
        let origin = Pose { x: 0.0, y: 4.0, heading: 0.0 };
        let sections = vec![
            Section::Straight { length: 50.0 },
            Section::Arc { length: 400.0, curvature: 1.0 / 300.0 },
            Section::Arc { length: 200.0, curvature: -1.0 / 500.0 },
        ];
        Road::new(origin, sections, 4.0, vec![30.0; 3], &[(LaneId(2), 300.0)])
    }

    #[test]
    fn frenet_round_trip_on_every_section() {
        let road = curved();
        for &s in &[0.0, 10.0, 49.9, 50.1, 200.0, 449.0, 460.0, 640.0] {
            for &d in &[0.0, -4.0, -8.0, 1.5] {
                let pose = road.to_global(s, d, 0.0);
                let (s2, d2) = road.to_frenet(pose.x, pose.y);
                assert!((s - s2).abs() < 1e-6 && (d - d2).abs() < 1e-6, "s {s} d {d} -> {s2} {d2}");
            }
        }
    }

    #[test]
    fn left_arc_turns_left_and_lanes_keep_their_width() {
        let road = curved();
        let start = road.to_global(50.0, 0.0, 0.0);
        let end = road.to_global(450.0, 0.0, 0.0);
        assert!((end.heading - start.heading - 400.0 / 300.0).abs() < 1e-9);
        let inner = road.to_global(300.0, 0.0, 0.0);
        let outer = road.to_global(300.0, -4.0, 0.0);
        assert!(((inner.x - outer.x).hypot(inner.y - outer.y) - 4.0).abs() < 1e-9);
    }

    #[test]
    fn lanes_end_and_lookups_respect_edges() {
        let road = curved();
        assert_eq!(road.lane_at(100.0, -8.3), Some(LaneId(2)));
        assert_eq!(road.lane_at(301.0, -8.3), None);
        assert_eq!(road.lane_at(100.0, 2.1), None);
        assert_eq!(road.lane_at(100.0, -10.1), None);
        assert!(road.contains(100.0, -1.9) && !road.contains(-1.0, 0.0));
        assert_eq!(road.nearest_lane(-5.0), LaneId(1));
    }

    /// A road of `count` straight and arc sections (both signs, some turning full circles)
    /// from a random origin, every radius wider than the road as `scenario` requires.
    fn random_road(rng: &mut ChaCha8Rng, count: usize) -> Road {
        let lanes = rng.random_range(1..=5);
        let lane_width = rng.random_range(2.5..4.5);
        let origin = Pose {
            x: rng.random_range(-1e4..1e4),
            y: rng.random_range(-1e4..1e4),
            heading: rng.random_range(-10.0..10.0),
        };
        let width = lane_width * lanes as f64;
        let sections = (0..count)
            .map(|_| {
                let length = 10f64.powf(rng.random_range(-1.0..2.5));
                if rng.random_bool(0.4) {
                    return Section::Straight { length };
                }
                let radius = width * (1.0 + 10f64.powf(rng.random_range(-3.0..4.0)));
                let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                Section::Arc { length, curvature: sign / radius }
            })
            .collect();
        Road::new(origin, sections, lane_width, vec![30.0; lanes], &[])
    }

    /// Points near the road (about its lanes, past its ends, on its joints, at its arcs'
    /// centres, where many sections are equally near), far from it, and not finite.
    fn query_points(rng: &mut ChaCha8Rng, road: &Road) -> Vec<(f64, f64)> {
        let width = road.lane_width() * road.lane_count() as f64;
        let mut points = Vec::new();
        for _ in 0..100 {
            let s = rng.random_range(-20.0..road.length() + 20.0);
            let pose = road.to_global(s, rng.random_range(-3.0 * width..3.0 * width), 0.0);
            points.push((pose.x, pose.y));
        }
        for _ in 0..20 {
            let start = road.starts[rng.random_range(0..road.starts.len())];
            let pose = road.to_global(start.s, rng.random_range(-width..width), rng.random_range(-1.0..1.0));
            points.push((pose.x, pose.y));
            points.push((start.pose.x + rng.random_range(-5.0..5.0), start.pose.y + rng.random_range(-5.0..5.0)));
            points.push((start.pose.x, start.pose.y));
            let section = road.sections[road.section_index(start.s)];
            if let Section::Arc { curvature, .. } = section {
                let (sin, cos) = start.pose.heading.sin_cos();
                points.push((start.pose.x - sin / curvature, start.pose.y + cos / curvature));
            }
        }
        let reach = road.length() + 1e3;
        let origin = road.starts[0].pose;
        for _ in 0..30 {
            points.push((origin.x + rng.random_range(-reach..reach), origin.y + rng.random_range(-reach..reach)));
        }
        let odd = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e300, -1e300, f64::MAX, 0.0];
        for &x in &odd {
            points.push((x, origin.y));
            points.push((origin.x, x));
            points.push((x, x));
        }
        points
    }

    fn bits((s, d): (f64, f64)) -> (u64, u64) {
        (s.to_bits(), d.to_bits())
    }

    #[test]
    fn frenet_among_the_sections_near_a_patch_is_the_scan_or_says_farther() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for case in 0..100 {
            let count = (10f64.powf(rng.random_range(0.0..3.0)) as usize).max(1);
            let road = random_road(&mut rng, count);
            let (within, radius) = (rng.random_range(1.0..60.0), rng.random_range(0.01..5.0));
            for (cx, cy) in query_points(&mut rng, &road) {
                let nearby = road.nearby(cx, cy, radius, within, usize::MAX);
                for _ in 0..4 {
                    let (angle, r) = (rng.random_range(0.0..6.3f64), rng.random_range(0.0..radius));
                    let (x, y) = (cx + r * angle.cos(), cy + r * angle.sin());
                    let (s, d) = road.to_frenet_scan(x, y);
                    let foot = road.to_global(s, 0.0, 0.0);
                    let distance = (foot.x - x).hypot(foot.y - y);
                    match road.to_frenet_among(&nearby, x, y, within) {
                        Some(found) => assert_eq!(bits(found), bits((s, d)), "case {case}, ({x}, {y})"),
                        None => {
                            assert!(distance.is_nan() || distance > within * (1.0 - 1e-9), "case {case}: {distance}")
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn a_patch_where_the_road_lies_over_itself_keeps_one_section() {
        // One ring passed 50 times: every section is as near as every other.
        let ring = Section::Arc { length: 2.0 * std::f64::consts::PI * 100.0, curvature: 0.01 };
        let road = Road::new(Pose { x: 0.0, y: 0.0, heading: 0.0 }, vec![ring; 50], 3.5, vec![30.0; 2], &[]);
        let on_it = road.to_global(10.0, 0.0, 0.0);
        assert_eq!(road.nearby(on_it.x, on_it.y, 0.5, 10.0, 8).0.len(), 1);
        assert_eq!(road.nearby(on_it.x, on_it.y, 0.5, 10.0, 64).0.len(), 50);
        assert!(road.to_frenet_among(&road.nearby(on_it.x, on_it.y, 0.5, 10.0, 8), on_it.x, on_it.y, 10.0).is_some());
    }

    #[test]
    fn indexed_frenet_is_the_scan_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for case in 0..300 {
            let count = (10f64.powf(rng.random_range(0.0..3.3)) as usize).max(1);
            let road = random_road(&mut rng, count);
            for (x, y) in query_points(&mut rng, &road) {
                let (indexed, scan) = (road.to_frenet(x, y), road.to_frenet_scan(x, y));
                assert_eq!(
                    bits(indexed),
                    bits(scan),
                    "case {case}, {count} sections, ({x}, {y}): {indexed:?} vs {scan:?}"
                );
            }
        }
    }

    #[test]
    fn a_road_read_back_equals_its_original_and_finds_the_same_feet() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let road = random_road(&mut rng, 50);
        let back: Road = toml::from_str(&toml::to_string(&road).unwrap()).unwrap();
        assert_eq!(back, road);
        for (x, y) in query_points(&mut rng, &road) {
            assert_eq!(bits(back.to_frenet(x, y)), bits(road.to_frenet_scan(x, y)));
        }
    }

    #[test]
    fn debug_text_is_the_fields_without_the_index() {
        let text = format!("{:?}", Road::straight(100.0, 1, 4.0, 30.0));
        let fields = "sections: [Straight { length: 100.0 }], starts: [SectionStart { s: 0.0, pose: Pose { x: 0.0, \
            y: 0.0, heading: 0.0 } }], lane_width: 4.0, lane_ends: [100.0], speed_limits: [30.0], length: 100.0";
        assert_eq!(text, format!("Road {{ {fields} }}"));
    }
}
