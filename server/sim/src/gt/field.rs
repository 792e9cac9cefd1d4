//! The potential field of §V-A: eq. (20) around each obstacle car, eq. (21) along each
//! lane line and road edge, summed by eq. (19). The MPC puts it in its first output and
//! linearises it along the predicted path. Positions are Frenet (s, d); an obstacle's
//! heading is relative to the lane, so eq. (20)'s rotation works the same on the curve.

use serde::{Deserialize, Serialize};

use crate::road::{LaneId, Road};

/// The field's constants; the paper names them but gives no values.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FieldParams {
    /// a^oc of eq. (20), the obstacle's peak (dimensionless). 1, chosen here (the field
    /// is a unitless output of the MPC; Q sets its weight).
    pub obstacle_peak: f64,
    /// rho_X of eq. (20) (m): longitudinal spread. 6, chosen here (a car length plus a
    /// metre): the field fades within two car lengths.
    pub rho_x: f64,
    /// rho_Y of eq. (20) (m): lateral spread. 1.2, chosen here: a car one lane over (4 m)
    /// sees under 1 % of the peak, so neighbours do not push each other apart.
    pub rho_y: f64,
    /// b of eq. (20), the shape exponent. 1 (a Gaussian), chosen here.
    pub shape: f64,
    /// c of eq. (20) (s/m): how far the field leans ahead of a moving car. 0.05, chosen
    /// here: at 30 m/s the peak sits about 6 m ahead of the car's centre.
    pub speed_skew: f64,
    /// a^r of eq. (21) for a road edge (dimensionless). 0.2, chosen here: small at the
    /// lane centre (0.1) so it does not bias lane keeping, 0.7 on the edge.
    pub edge_peak: f64,
    /// a^r of eq. (21) for a lane line between two lanes (dimensionless). 0.05, chosen
    /// here: lane changes cross it.
    pub line_peak: f64,
    /// d-dagger of eq. (21) (m): the safety threshold. 0.3, chosen here.
    pub safety_threshold: f64,
    /// Obstacles farther than this along the road (m) are left out. 80, chosen here.
    pub range: f64,
}

impl Default for FieldParams {
    fn default() -> Self {
        FieldParams {
            obstacle_peak: 1.0,
            rho_x: 6.0,
            rho_y: 1.2,
            shape: 1.0,
            speed_skew: 0.05,
            edge_peak: 0.2,
            line_peak: 0.05,
            safety_threshold: 0.3,
            range: 80.0,
        }
    }
}

/// An obstacle car, predicted at constant speed along its lane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obstacle {
    /// Position along the road now (m).
    pub s: f64,
    /// Offset now (m).
    pub d: f64,
    /// Heading relative to the lane (rad).
    pub heading: f64,
    /// Speed (m/s).
    pub speed: f64,
}

/// A lane line or road edge: a line of constant offset over a stretch of road.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Line {
    /// Its offset (m).
    pub d: f64,
    /// a^r: edge or lane line.
    pub peak: f64,
    /// Where it starts and ends along the road (m).
    pub from: f64,
    /// See `from`.
    pub to: f64,
    /// Which side of it the road is, for an edge drawn one-sided: +1 at larger d, -1 at
    /// smaller; 0 for a lane line or an edge whose field is symmetric (eq. 21 as written).
    pub road_side: i8,
}

impl Line {
    /// d of eq. (21) at offset `d`: the distance to the line; beyond a one-sided edge (off
    /// the road), zero: the field stays at its value on the edge, so it neither pulls a
    /// plan further off the road nor pushes one across a lane line.
    #[inline]
    pub fn distance(&self, d: f64) -> f64 {
        match self.road_side {
            0 => (d - self.d).abs(),
            side => (f64::from(side) * (d - self.d)).max(0.0),
        }
    }

    /// The derivative of `distance` in d (0 on the line and off the road beyond an edge).
    #[inline]
    pub fn slope(&self, d: f64) -> f64 {
        let side = match self.road_side {
            0 => (d - self.d).signum(),
            side => f64::from(side),
        };
        if self.distance(d) > 0.0 { side } else { 0.0 }
    }
}

/// Eq. (20): the field of one obstacle at (s, d).
#[cfg(test)]
fn obstacle_field(p: &FieldParams, oc: &Obstacle, s: f64, d: f64) -> f64 {
    obstacle_gradient(p, oc, oc.heading.sin_cos(), s, d).0
}

/// Eq. (20) at (s, d) and its partial derivatives in s and d, by the chain rule through
/// the obstacle's axes (X-hat, Y-hat); `turn` is the (sin, cos) of its heading, the same
/// at every instant of a plan (`Field::new` computes it once).
#[inline]
fn obstacle_gradient(p: &FieldParams, oc: &Obstacle, (sin, cos): (f64, f64), s: f64, d: f64) -> (f64, f64, f64) {
    let (ds, dd) = (s - oc.s, d - oc.d);
    let x = cos * ds + sin * dd; // X-hat
    let y = -sin * ds + cos * dd; // Y-hat
    let along = x * x / (2.0 * p.rho_x * p.rho_x);
    let q = along + y * y / (2.0 * p.rho_y * p.rho_y);
    let (along_x, q_y) = (x / (p.rho_x * p.rho_x), y / (p.rho_y * p.rho_y)); // q_x = along_x
    let k = if x < 0.0 { -1.0 } else { 1.0 };
    let (gamma, gamma_x, gamma_y) = if q > 1e-12 {
        let root = q.sqrt();
        let spread = along / (2.0 * q * root); // d(q^-1/2)/dq times -along
        (k * along / root, k * (along_x / root - spread * along_x), -k * spread * q_y)
    } else {
        (0.0, 0.0, 0.0)
    };
    let (shaped, shaped_q) = match p.shape {
        1.0 => (q, 1.0),
        _ if q > 0.0 => (q.powf(p.shape), p.shape * q.powf(p.shape - 1.0)),
        _ => (0.0, 0.0),
    };
    let skew = p.speed_skew * oc.speed;
    let theta = -shaped + skew * gamma;
    let value = p.obstacle_peak * theta.exp(); // eq. (20)
    let (value_x, value_y) = (value * (skew * gamma_x - shaped_q * along_x), value * (skew * gamma_y - shaped_q * q_y));
    (value, value_x * cos - value_y * sin, value_x * sin + value_y * cos)
}

/// Eq. (21): the field of a line at `distance` (m) from it, for a car `width` wide (W).
#[inline]
pub(crate) fn road_field(p: &FieldParams, width: f64, peak: f64, distance: f64) -> f64 {
    peak * (-distance + p.safety_threshold + 0.5 * width).exp() // eq. (21)
}

/// The lane lines and edges of a road: a boundary between two lanes is a lane line where
/// both exist and an edge where only one does. With `one_sided`, an edge's field is flat
/// off the road (`Line::distance`): past a lane's end the edge then does not hold a
/// merging car's plan back in the ended lane (docs/design.md, "Merging that completes").
pub fn road_lines(road: &Road, p: &FieldParams, one_sided: bool) -> Vec<Line> {
    let (w, n) = (road.lane_width(), road.lane_count());
    let end = |lane: usize| road.lane_end(LaneId(lane as u32));
    let side = |road_side: i8| if one_sided { road_side } else { 0 };
    let mut lines = Vec::with_capacity(2 * n + 1);
    lines.push(Line { d: 0.5 * w, peak: p.edge_peak, from: 0.0, to: end(0), road_side: side(-1) });
    for j in 1..n {
        let d = -(j as f64 - 0.5) * w;
        let (both, one) = (end(j - 1).min(end(j)), end(j - 1).max(end(j)));
        // Past `both` only the longer lane is road: the one above (larger d) or below.
        let road_side = if end(j - 1) >= end(j) { 1 } else { -1 };
        lines.push(Line { d, peak: p.line_peak, from: 0.0, to: both, road_side: 0 });
        lines.push(Line { d, peak: p.edge_peak, from: both, to: one, road_side: side(road_side) });
    }
    let right = Line { d: -(n as f64 - 0.5) * w, peak: p.edge_peak, from: 0.0, to: end(n - 1), road_side: side(1) };
    lines.push(right);
    lines
}

/// The lines of lane keeping in `lane` at `s`: the two that bound it, each at the higher
/// of their peaks (an edge's, if either is one), so that the road's part of the field is
/// least at the lane's centre. Eq. (21) as `road_lines` draws it is least where an edge's
/// and a lane line's slopes balance, 0.13 m off the centre of an outer lane. A bound is a
/// lane line where the lane beside it is still there at `s` (as `road_lines` draws it).
pub fn lane_lines(road: &Road, lane: LaneId, s: f64, p: &FieldParams) -> Vec<Line> {
    let (centre, half) = (road.lane_center(lane), 0.5 * road.lane_width());
    let beside =
        |other: Option<u32>| other.is_some_and(|k| (k as usize) < road.lane_count() && s <= road.lane_end(LaneId(k)));
    let shared = s <= road.lane_end(lane) && beside(lane.0.checked_sub(1)) && beside(Some(lane.0 + 1));
    let peak = if shared { p.line_peak } else { p.edge_peak.max(p.line_peak) };
    let to = road.lane_end(lane);
    [centre + half, centre - half].map(|d| Line { d, peak, from: 0.0, to, road_side: 0 }).to_vec()
}

/// The field a car sees: obstacles and lines, evaluated at predicted instants.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    /// The constants.
    pub params: FieldParams,
    /// W of eq. (21): the planning car's width (m), from `VehicleParams`.
    pub width: f64,
    /// Nearby cars (`add_obstacle`, so each one's turn is kept beside it).
    obstacles: Vec<Obstacle>,
    /// The road's lines.
    pub lines: Vec<Line>,
    /// Each obstacle's (sin, cos) of its heading: computed once, read at every instant.
    turns: Vec<(f64, f64)>,
}

impl Field {
    /// The field of `obstacles` and `lines` for a car `width` wide.
    pub fn new(params: FieldParams, width: f64, obstacles: Vec<Obstacle>, lines: Vec<Line>) -> Field {
        let turns = obstacles.iter().map(|oc| oc.heading.sin_cos()).collect();
        Field { params, width, obstacles, lines, turns }
    }

    /// Adds one more car to the field.
    pub fn add_obstacle(&mut self, obstacle: Obstacle) {
        self.obstacles.push(obstacle);
        self.turns.push(obstacle.heading.sin_cos());
    }

    /// Eq. (19) at (s, d), `t` seconds from now (obstacles moved on at their speed).
    pub fn value(&self, s: f64, d: f64, t: f64) -> f64 {
        self.gradient(s, d, t).0
    }

    /// `value` with its gradient (d/ds, d/dd), analytic: the lines' fields change only
    /// across them (a line's start or end is a step the MPC does not linearise).
    pub fn gradient(&self, s: f64, d: f64, t: f64) -> (f64, f64, f64) {
        let p = &self.params;
        let (mut cars, mut cars_s, mut cars_d) = (0.0, 0.0, 0.0);
        for (oc, &turn) in self.obstacles.iter().zip(&self.turns) {
            let moved = Obstacle { s: oc.s + oc.speed * t, ..*oc };
            let (value, along, across) = obstacle_gradient(p, &moved, turn, s, d);
            (cars, cars_s, cars_d) = (cars + value, cars_s + along, cars_d + across);
        }
        let (mut road, mut road_d) = (0.0, 0.0);
        for line in self.lines.iter().filter(|line| (line.from..=line.to).contains(&s)) {
            let value = road_field(p, self.width, line.peak, line.distance(d));
            (road, road_d) = (road + value, road_d - value * line.slope(d));
        }
        (cars + road, cars_s, cars_d + road_d) // eq. (19)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::road::{Pose, Section};

    #[test]
    fn obstacle_field_peaks_at_the_car_and_leans_ahead_when_moving() {
        let p = FieldParams::default();
        let still = Obstacle { s: 0.0, d: 0.0, heading: 0.0, speed: 0.0 };
        assert!((obstacle_field(&p, &still, 0.0, 0.0) - p.obstacle_peak).abs() < 1e-12);
        // Standing still it is symmetric; a Gaussian in each axis.
        let ahead = obstacle_field(&p, &still, 6.0, 0.0);
        assert!((ahead - obstacle_field(&p, &still, -6.0, 0.0)).abs() < 1e-12);
        assert!((ahead - (-0.5f64).exp()).abs() < 1e-12);
        let moving = Obstacle { speed: 30.0, ..still };
        assert!(obstacle_field(&p, &moving, 6.0, 0.0) > obstacle_field(&p, &moving, -6.0, 0.0));
        // One lane over, a car barely registers.
        assert!(obstacle_field(&p, &moving, 0.0, 4.0) < 0.01);
    }

    #[test]
    fn the_analytic_gradient_matches_central_differences() {
        let road = Road::new(
            Pose { x: 0.0, y: 0.0, heading: 0.0 },
            vec![Section::Straight { length: 500.0 }],
            4.0,
            vec![25.0, 25.0, 25.0],
            &[(LaneId(2), 300.0)],
        );
        let obstacles = vec![
            Obstacle { s: 40.0, d: -4.0, heading: 0.05, speed: 20.0 },
            Obstacle { s: 55.0, d: -7.5, heading: -0.1, speed: 12.0 },
        ];
        for (shape, one_sided) in [(1.0, true), (1.3, false)] {
            let params = FieldParams { shape, ..FieldParams::default() };
            let lines = road_lines(&road, &params, one_sided);
            let field = Field::new(params, 2.0, obstacles.clone(), lines);
            let h = 1e-5;
            for (s, d, t) in
                [(38.0, -3.1, 0.0), (46.0, -5.0, 0.4), (60.0, -9.3, 1.2), (30.0, 1.7, 0.0), (310.0, -9.0, 0.0)]
            {
                let (_, along, across) = field.gradient(s, d, t);
                let fd_s = (field.value(s + h, d, t) - field.value(s - h, d, t)) / (2.0 * h);
                let fd_d = (field.value(s, d + h, t) - field.value(s, d - h, t)) / (2.0 * h);
                let close = |a: f64, b: f64| (a - b).abs() <= 1e-6 * (1.0 + b.abs());
                assert!(
                    close(along, fd_s) && close(across, fd_d),
                    "at ({s}, {d}, {t}): {along} {across} against {fd_s} {fd_d}"
                );
            }
        }
    }

    #[test]
    fn a_turned_obstacle_turns_its_field() {
        let p = FieldParams { speed_skew: 0.0, ..FieldParams::default() };
        let turned = Obstacle { s: 0.0, d: 0.0, heading: std::f64::consts::FRAC_PI_2, speed: 0.0 };
        let straight = Obstacle { heading: 0.0, ..turned };
        assert!((obstacle_field(&p, &turned, 0.0, 3.0) - obstacle_field(&p, &straight, 3.0, 0.0)).abs() < 1e-12);
    }

    #[test]
    fn road_lines_follow_lane_ends() {
        let road = Road::new(
            Pose { x: 0.0, y: 0.0, heading: 0.0 },
            vec![Section::Straight { length: 500.0 }],
            4.0,
            vec![25.0, 25.0],
            &[(LaneId(1), 200.0)],
        );
        let p = FieldParams::default();
        let lines = road_lines(&road, &p, false);
        let at =
            |s: f64, d: f64| lines.iter().filter(move |l| l.d == d && (l.from..=l.to).contains(&s)).map(|l| l.peak);
        assert_eq!(at(100.0, -2.0).collect::<Vec<_>>(), vec![p.line_peak]);
        assert_eq!(at(300.0, -2.0).collect::<Vec<_>>(), [p.edge_peak]);
        assert_eq!(at(300.0, -6.0).count(), 0);
        assert_eq!(at(100.0, 2.0).collect::<Vec<_>>(), [p.edge_peak]);
    }

    #[test]
    fn road_field_is_eq_21_and_grows_toward_its_line() {
        let p = FieldParams::default();
        assert!((road_field(&p, 2.0, 2.0, 1.3) - 2.0).abs() < 1e-12); // d = d-dagger + W/2
        let line = Line { d: 2.0, peak: 1.0, from: 0.0, to: 100.0, road_side: 0 };
        let field = Field::new(p, 2.0, vec![], vec![line]);
        let (value, ds, dd) = field.gradient(50.0, 0.5, 0.0);
        assert!((value - road_field(&p, 2.0, 1.0, 1.5)).abs() < 1e-12);
        assert!(ds.abs() < 1e-9 && dd > 0.0);
        assert!((dd - value).abs() < 1e-5); // d/dd of exp(-(2 - d) + ...) is the value itself
    }
}
