//! The lane-change costs of eq. (9)–(14): driving safety (longitudinal to the lead car,
//! lateral to the adjacent car, switched by sigma), ride comfort and travel efficiency,
//! for one car at one instant. The games average them over predicted motion.
//!
//! Positions are in the road's Frenet frame (s along, d to the left), as everywhere in
//! the world: the Euclidean distances of eq. (11c) and (12c) are taken in (s, d).

use std::ops::{Add, Mul};

use serde::{Deserialize, Serialize};

use super::prediction::Kinematics;
use super::styles::CostWeights;
use crate::dynamics::Style;

/// The constants of eq. (10)–(14) the paper leaves open. All chosen here; the reasons are
/// in docs/parameters.md, "Game-theoretic AV".
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CostParams {
    /// kappa_v-log of eq. (11a) (s^2/m^2): weight of the closing speed on the lead car. 0.1.
    pub kappa_v_log: f64,
    /// kappa_s-log of eq. (11a) (m^2): weight of the inverse squared gap to the lead car. 1.5e4.
    pub kappa_s_log: f64,
    /// kappa_v-lat of eq. (12a) (s^2/m^2): weight of the closing speed on the adjacent car. 2.
    pub kappa_v_lat: f64,
    /// kappa_s-lat of eq. (12a) (m^2): weight of the inverse squared gap to the adjacent car. 3e4.
    pub kappa_s_lat: f64,
    /// kappa_ax of eq. (13) (s^4/m^2): weight of the squared longitudinal acceleration. 10.
    pub kappa_ax: f64,
    /// kappa_ay of eq. (13) (s^4/m^2): weight of the squared lateral acceleration. 10.
    pub kappa_ay: f64,
    /// epsilon of eq. (11a)/(12a) (m^2): keeps the denominators away from zero. 1e-3.
    pub epsilon: f64,
    /// A car ahead counts as the lead car of eq. (14) (v-bar = min(v_max, v_LC)) only while
    /// its gap (centre to centre) is below this (m). 0, chosen here: the cap is off and
    /// v-bar = v_max. Taken literally, eq. (14) makes following a slow car cost nothing, so
    /// no style overtakes in Scenario B, and the paper's own Table VII (the conservative
    /// car, which follows LC, has the largest efficiency cost) is consistent only with
    /// v-bar = v_max (docs/parameters.md).
    pub lead_range: f64,
}

impl Default for CostParams {
    fn default() -> Self {
        CostParams {
            kappa_v_log: 0.1,
            kappa_s_log: 1.5e4,
            kappa_v_lat: 2.0,
            kappa_s_lat: 3e4,
            kappa_ax: 10.0,
            kappa_ay: 10.0,
            epsilon: 1e-3,
            lead_range: 0.0,
        }
    }
}

/// The three costs of eq. (9) before weighting.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct CostComponents {
    /// J_ds, driving safety, eq. (10).
    pub safety: f64,
    /// J_rc, ride comfort, eq. (13).
    pub comfort: f64,
    /// J_pe, travel efficiency, eq. (14).
    pub efficiency: f64,
}

impl CostComponents {
    /// J of eq. (9) with Table III's weights for `style`.
    pub fn weighted(&self, style: Style) -> f64 {
        self.weighted_by(&CostWeights::for_style(style))
    }

    /// J of eq. (9) with explicit weights.
    pub fn weighted_by(&self, w: &CostWeights) -> f64 {
        // eq. (9)
        w.safety * self.safety + w.comfort * self.comfort + w.efficiency * self.efficiency
    }

    /// Each component squared: the terms of an RMS over a run (Tables V and VII).
    pub fn squared(self) -> CostComponents {
        CostComponents {
            safety: self.safety * self.safety,
            comfort: self.comfort * self.comfort,
            efficiency: self.efficiency * self.efficiency,
        }
    }
}

impl Add for CostComponents {
    type Output = CostComponents;
    fn add(self, other: CostComponents) -> CostComponents {
        CostComponents {
            safety: self.safety + other.safety,
            comfort: self.comfort + other.comfort,
            efficiency: self.efficiency + other.efficiency,
        }
    }
}

impl Mul<f64> for CostComponents {
    type Output = CostComponents;
    fn mul(self, k: f64) -> CostComponents {
        CostComponents { safety: self.safety * k, comfort: self.comfort * k, efficiency: self.efficiency * k }
    }
}

/// Delta s of eq. (11c)/(12c): the centre distance less l_v, one car length
/// (`VehicleParams::length`); negative when the cars' footprints overlap.
#[inline]
pub(crate) fn separation(car_length: f64, a: Kinematics, b: Kinematics) -> f64 {
    let (ds, dd) = (a.s - b.s, a.d - b.d);
    (ds * ds + dd * dd).sqrt() - car_length // eq. (11c), (12c)
}

/// The gap term kappa / (Delta s^2 + epsilon) of eq. (11a)/(12a), with Delta s clamped at
/// zero (past that the inverse square would fall again as the overlap deepens) and the
/// term multiplied by 1 + the overlap (m), so that a deeper predicted overlap still costs
/// more and braking harder before an unavoidable contact still pays.
#[inline]
fn proximity(p: &CostParams, car_length: f64, kappa: f64, a: Kinematics, b: Kinematics) -> f64 {
    let separation = separation(car_length, a, b);
    let gap = separation.max(0.0);
    kappa / (gap * gap + p.epsilon) * (1.0 + (-separation).max(0.0))
}

/// J_ds-log of eq. (11): closing speed on the lead car `leader` and the gap to it.
#[inline]
pub fn longitudinal_safety(p: &CostParams, car_length: f64, ego: Kinematics, leader: Kinematics) -> f64 {
    let dv = leader.speed - ego.speed; // eq. (11b)
    let lambda = if dv < 0.0 { 1.0 } else { 0.0 }; // eq. (12d) under (11)
    p.kappa_v_log * lambda * dv * dv + proximity(p, car_length, p.kappa_s_log, ego, leader) // eq. (11a)
}

/// J_ds-lat of eq. (12) between the ego car and the adjacent car of the target lane.
/// Eq. (12b) takes dv = v_EC - v_AC, the closing speed when AC is behind EC (both of the
/// paper's scenarios start so); here dv is the front car's speed less the rear car's, so
/// lambda also flags closing when EC falls in behind AC. Symmetric in its two cars, which
/// is how the AC's lateral cost "is equal to" the EC's (§IV-A).
#[inline]
pub fn lateral_safety(p: &CostParams, car_length: f64, ego: Kinematics, adjacent: Kinematics) -> f64 {
    let (front, rear) = if ego.s >= adjacent.s { (ego, adjacent) } else { (adjacent, ego) };
    let dv = front.speed - rear.speed; // eq. (12b), see above
    let lambda = if dv < 0.0 { 1.0 } else { 0.0 }; // eq. (12d)
    p.kappa_v_lat * lambda * dv * dv + proximity(p, car_length, p.kappa_s_lat, ego, adjacent) // eq. (12a)
}

/// J_ds of eq. (10): the longitudinal term when keeping the lane, the lateral one when
/// changing (sigma in {-1, 0, 1}).
#[inline]
pub fn safety(sigma: i8, longitudinal: f64, lateral: f64) -> f64 {
    let s2 = f64::from(sigma * sigma);
    (s2 - 1.0) * (s2 - 1.0) * longitudinal + s2 * lateral // eq. (10)
}

/// J_rc of eq. (13) from the longitudinal and lateral accelerations (m/s^2).
#[inline]
pub fn comfort(p: &CostParams, sigma: i8, accel: f64, lateral_accel: f64) -> f64 {
    let s2 = f64::from(sigma * sigma);
    p.kappa_ax * accel * accel + s2 * p.kappa_ay * lateral_accel * lateral_accel // eq. (13)
}

/// v-bar of eq. (14): the lane's speed limit, or the lead car's speed if it is slower and
/// within `lead_range` of the ego car.
#[inline]
pub fn target_speed(p: &CostParams, ego: Kinematics, speed_limit: f64, leader: Option<Kinematics>) -> f64 {
    match leader {
        Some(leader) if leader.s >= ego.s && leader.s - ego.s < p.lead_range => speed_limit.min(leader.speed),
        _ => speed_limit,
    } // eq. (14), v-bar
}

/// J_pe of eq. (14): the squared shortfall (or excess) of speed against `target`.
#[inline]
pub fn efficiency(speed: f64, target: f64) -> f64 {
    (speed - target) * (speed - target) // eq. (14)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// l_v: the default body length of `VehicleParams`.
    const L: f64 = 5.0;

    fn car(s: f64, d: f64, speed: f64) -> Kinematics {
        Kinematics { s, d, speed }
    }

    #[test]
    fn longitudinal_safety_charges_closing_speed_only_when_closing() {
        let p = CostParams::default();
        // 25 m behind a car 5 m/s slower: gap 20 m, dv = -5.
        let closing = longitudinal_safety(&p, L, car(0.0, 0.0, 20.0), car(25.0, 0.0, 15.0));
        assert!((closing - (p.kappa_v_log * 25.0 + p.kappa_s_log / (400.0 + p.epsilon))).abs() < 1e-9);
        // A faster lead car only leaves the gap term.
        let opening = longitudinal_safety(&p, L, car(0.0, 0.0, 15.0), car(25.0, 0.0, 20.0));
        assert!((opening - p.kappa_s_log / (400.0 + p.epsilon)).abs() < 1e-9);
    }

    #[test]
    fn lateral_safety_uses_the_euclidean_gap_and_is_symmetric() {
        let p = CostParams::default();
        let (ec, ac) = (car(12.0, -4.0, 20.0), car(0.0, 0.0, 18.0));
        let gap = (144.0f64 + 16.0).sqrt() - 5.0;
        let expected = p.kappa_s_lat / (gap * gap + p.epsilon); // EC ahead and faster: opening
        assert!((lateral_safety(&p, L, ec, ac) - expected).abs() < 1e-9);
        assert_eq!(lateral_safety(&p, L, ec, ac), lateral_safety(&p, L, ac, ec));
        // EC behind a slower AC closes on it: the speed term appears.
        let behind = lateral_safety(&p, L, car(-12.0, -4.0, 20.0), ac);
        assert!((behind - expected - p.kappa_v_lat * 4.0).abs() < 1e-9);
    }

    #[test]
    fn overlapping_cars_cost_the_most_and_more_the_deeper() {
        let p = CostParams::default();
        let touching = lateral_safety(&p, L, car(0.0, 0.0, 20.0), car(5.0, 0.0, 20.0));
        let overlapping = lateral_safety(&p, L, car(0.0, 0.0, 20.0), car(1.0, 0.0, 20.0));
        assert!((touching - p.kappa_s_lat / p.epsilon).abs() < 1e-6);
        assert!((overlapping - p.kappa_s_lat / p.epsilon * 5.0).abs() < 1e-6);
        assert_eq!(separation(L, car(0.0, 0.0, 20.0), car(1.0, 0.0, 20.0)), -4.0);
    }

    #[test]
    fn sigma_switches_between_the_safety_terms_and_adds_lateral_comfort() {
        assert_eq!(safety(0, 3.0, 7.0), 3.0);
        assert_eq!(safety(1, 3.0, 7.0), 7.0);
        assert_eq!(safety(-1, 3.0, 7.0), 7.0);
        let p = CostParams::default();
        assert_eq!(comfort(&p, 0, 2.0, 1.5), p.kappa_ax * 4.0);
        assert_eq!(comfort(&p, -1, 2.0, 1.5), p.kappa_ax * 4.0 + p.kappa_ay * 2.25);
    }

    #[test]
    fn efficiency_targets_a_near_slow_leader_or_the_limit() {
        let p = CostParams::default();
        let ego = car(0.0, 0.0, 20.0);
        assert_eq!(target_speed(&p, ego, 30.0, None), 30.0);
        assert_eq!(target_speed(&p, ego, 30.0, Some(car(20.0, 0.0, 15.0))), 30.0, "the cap is off by default");
        let p = CostParams { lead_range: 30.0, ..p };
        assert_eq!(target_speed(&p, ego, 30.0, Some(car(20.0, 0.0, 15.0))), 15.0);
        assert_eq!(target_speed(&p, ego, 30.0, Some(car(p.lead_range + 1.0, 0.0, 15.0))), 30.0);
        assert_eq!(target_speed(&p, ego, 30.0, Some(car(-5.0, 0.0, 15.0))), 30.0);
        assert_eq!(efficiency(20.0, 30.0), 100.0);
    }

    #[test]
    fn weighted_is_eq_9_with_table_iii() {
        let c = CostComponents { safety: 1.0, comfort: 2.0, efficiency: 4.0 };
        assert!((c.weighted(Style::Aggressive) - (0.1 + 0.2 + 3.2)).abs() < 1e-12);
        assert!((c.weighted(Style::Conservative) - (0.7 + 0.4 + 0.4)).abs() < 1e-12);
    }
}
