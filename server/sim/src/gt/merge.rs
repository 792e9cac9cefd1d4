//! Lane changes out of an ending lane that complete (docs/design.md, "Merging that
//! completes"): a change must bring EC's centre across the lane line before its lane
//! ends. Each candidate lane change (an acceleration of the game's grid with sigma != 0)
//! gets the longest duration, between `min_duration` and `LANE_CHANGE_DURATION`, whose
//! predicted crossing comes `end_margin` before the end at `crossing_speed` or more; one
//! that cannot is no candidate (`games` builds the strategy sets from this). A change
//! under way that no longer can is aborted, if EC can still stop in its lane; keeping the
//! lane, EC stays able to stop `stop_margin` short of the end.
//!
//! A change that starts is predicted to cross when the games' quintic path does
//! (`dynamics::LateralPath`, EC holding its candidate acceleration), plus a response lag:
//! the MPC-driven car crosses the line a little after the path's midpoint. A change under
//! way keeps to what was predicted when it began (the driver remembers it), and is judged
//! by its lateral speed once that is telling.

use serde::{Deserialize, Serialize};

use super::jerk::AccelRamp;
use super::prediction::{self, SpeedBounds};

/// The constants of lane changes out of an ending lane.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MergeParams {
    /// Whether lane changes out of an ending lane are fitted to the distance left (and
    /// aborted when they no longer fit), keeping the lane keeps EC able to stop, and road
    /// edges are one-sided (`field::road_lines`). true; false is the AV before issue 23:
    /// every change the fixed `LANE_CHANGE_DURATION`.
    pub enabled: bool,
    /// T_min (s): the shortest lane change, at the pace of the whole lane width. 3, chosen
    /// here: the quintic's peak lateral acceleration 10/sqrt(3) w / T^2 is then 2.57 m/s^2
    /// for w = 4 m (1.44 at 4 s), under the 0.3 g often taken as the comfort limit.
    pub min_duration: f64,
    /// How long after the path the car crosses the line (s), for the whole lane width
    /// (proportionally less for what is left of a change under way). 0.5, chosen here:
    /// the MPC-driven car crosses 0.2-0.4 s after the 4 s path's midpoint, 0.4-0.65 s
    /// after the 3 s path's, at 5-25 m/s for every style.
    pub response_lag: f64,
    /// The crossing must come this far (m) before the lane's end. 1, chosen here: under
    /// the 2.7 m the paper's tightest run (Scenario A, conservative) leaves at its
    /// decision, so that run keeps its 4 s change.
    pub end_margin: f64,
    /// EC keeping (or returning to) its ending lane must be able to stop this far (m) short
    /// of the end, braking at a_min: its accelerations that would not leave it able to are
    /// no actions, and a change under way is aborted only while EC can. 5, chosen here:
    /// from a standstill the car crosses the lane line within 3-4 m of travel.
    pub stop_margin: f64,
    /// A crossing counts only if EC still drives at least this fast (m/s) when it comes:
    /// the lateral path is in time, but a car moves sideways only while it rolls, and one
    /// that brakes to a stop mid-change stands across the line. 2, chosen here: the MPC's
    /// `min_speed`, below which it aims straight at the target lane.
    pub crossing_speed: f64,
}

impl Default for MergeParams {
    fn default() -> Self {
        MergeParams {
            enabled: true,
            min_duration: 3.0,
            response_lag: 0.5,
            end_margin: 1.0,
            stop_margin: 5.0,
            crossing_speed: 2.0,
        }
    }
}

/// A lane change EC may make from where it is: from offset `from` to `to` across the
/// line at `line`, with `left` metres to the end of its lane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossing {
    /// The centre of the lane EC leaves (m).
    pub origin: f64,
    /// EC's offset now (m).
    pub from: f64,
    /// EC's lateral speed now (m/s, + to the left).
    pub lateral_speed: f64,
    /// The target lane's centre (m).
    pub to: f64,
    /// The lane line between the two lanes (m).
    pub line: f64,
    /// Distance from EC's centre to the end of its lane (m).
    pub left: f64,
    /// Lane width (m).
    pub width: f64,
}

/// The quintic blend of `LateralPath::offset_at`, 0 at u = 0 and 1 at u = 1.
fn blend(u: f64) -> f64 {
    u * u * u * (10.0 - 15.0 * u + 6.0 * u * u)
}

/// The u in [0, 1] at which `blend(u)` = `part` (clamped): how far in time along a
/// quintic lane change its offset has come `part` of the way (also `safety`'s).
pub(super) fn phase(part: f64) -> f64 {
    super::bisect(0.0, 1.0, |u| blend(u) < part).1
}

/// How a change under way is timed, from the driver's memory.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnderWay {
    /// Its full-width duration (s).
    pub pace: f64,
    /// Seconds to the line at that pace, as predicted when it began (or was last
    /// shortened), counted from now; `None` when no memory says (a learner's change).
    pub crossing_in: Option<f64>,
}

impl Crossing {
    /// The part of a whole lane width still to go (what `Situation::lane_change_path`
    /// scales the duration by).
    pub fn remaining(&self) -> f64 {
        ((self.to - self.from).abs() / self.width).clamp(0.25, 1.0)
    }

    /// Whether EC's centre is across the line already.
    fn across(&self) -> bool {
        (self.line - self.from) * (self.to - self.line) <= 0.0
    }

    /// Seconds to the line for a change starting now at full-width duration `duration`:
    /// the path from EC's offset crosses it at `fraction` of its length, the car
    /// `response_lag` (times the part of a width to go) later. 0 once across.
    pub fn time_from_rest(&self, params: &MergeParams, duration: f64) -> f64 {
        if self.across() {
            return 0.0;
        }
        let span = self.to - self.from;
        let fraction = phase((self.line - self.from) / span);
        let remaining = self.remaining();
        fraction * remaining * duration + params.response_lag * remaining
    }

    /// Seconds to the line for the change under way `under_way` at full-width duration
    /// `duration` (at most its pace): what was predicted when it began, scaled to the new
    /// duration; once the car is a quarter of the way across (its lateral speed then
    /// near its peak) or that prediction is past, the distance to the line over the
    /// lateral speed towards it (never, standing), likewise scaled: a car held back (by
    /// the field of a car beside) is seen to be late. At least, and for a change without
    /// memory exactly, what is left of the quintic from the lane EC leaves at the phase
    /// its offset shows, with no lag (the car is moving). 0 once across.
    pub fn time_under_way(&self, under_way: UnderWay, duration: f64) -> f64 {
        if self.across() {
            return 0.0;
        }
        let span = self.to - self.origin;
        let done = if span == 0.0 { 1.0 } else { ((self.from - self.origin) / span).clamp(0.0, 1.0) };
        let part = if span == 0.0 { 0.0 } else { ((self.line - self.origin) / span).clamp(0.0, 1.0) };
        let left = (phase(part) - phase(done)).max(0.0) * duration;
        let towards = self.lateral_speed * (self.to - self.from).signum();
        let kinematic = || match towards > 0.0 {
            true => (self.line - self.from).abs() / towards * duration / under_way.pace,
            false => f64::INFINITY,
        };
        let predicted = match under_way.crossing_in {
            None => 0.0,
            Some(t) if t > 0.0 && done < 0.25 => t * duration / under_way.pace,
            Some(_) => kinematic(),
        };
        predicted.max(left)
    }

    /// The full-width duration T (s) of the slowest lane change within [`min_duration`,
    /// `longest`] whose crossing, `time(T)` seconds from now, comes `end_margin` before
    /// the end at `crossing_speed` or faster, driving `ramp` from `speed` within
    /// `bounds`; `None` if none does.
    pub fn fit(
        &self,
        params: &MergeParams,
        longest: f64,
        time: impl Fn(f64) -> f64,
        speed: f64,
        ramp: AccelRamp,
        bounds: SpeedBounds,
    ) -> Option<f64> {
        let room = self.left - params.end_margin;
        let fits = |duration: f64| {
            let t = time(duration);
            let (ds, v) = prediction::advance_ramp(speed, ramp, bounds, t);
            t == 0.0 || (ds <= room && v >= params.crossing_speed)
        };
        if fits(longest) {
            return Some(longest);
        }
        let shortest = params.min_duration.min(longest);
        if !fits(shortest) {
            return None;
        }
        // The distance grows with T: the longest T whose crossing still fits.
        Some(super::bisect(shortest, longest, fits).0)
    }
}

/// Whether a car at `speed` braking along `ramp` (towards `ramp.to` < 0, m/s^2) stops
/// `margin` short of a point `left` metres ahead.
pub fn can_stop(speed: f64, ramp: AccelRamp, left: f64, margin: f64) -> bool {
    stopping_distance(speed, ramp) <= left - margin
}

/// How far a car at `speed` travels braking along `ramp` until it stands (m): v^2 / 2b
/// for a step to -b, plus what the ramp down to -b covers first.
pub fn stopping_distance(speed: f64, ramp: AccelRamp) -> f64 {
    let brake = -ramp.to;
    let rise = ramp.duration();
    if rise == 0.0 {
        return speed.max(0.0).powi(2) / (2.0 * brake);
    }
    let bounds = SpeedBounds { min: 0.0, max: f64::INFINITY };
    let (ds, v) = prediction::advance_ramp(speed.max(0.0), ramp, bounds, rise);
    ds + v * v / (2.0 * brake)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::LANE_CHANGE_DURATION;

    const BOUNDS: SpeedBounds = SpeedBounds { min: 0.0, max: 25.0 };

    fn crossing(left: f64) -> Crossing {
        Crossing { origin: -4.0, from: -4.0, lateral_speed: 0.0, to: 0.0, line: -2.0, left, width: 4.0 }
    }

    /// `Crossing::fit` for a change starting now.
    fn start(c: &Crossing, speed: f64, accel: f64) -> Option<f64> {
        let p = MergeParams::default();
        c.fit(&p, LANE_CHANGE_DURATION, |t| c.time_from_rest(&p, t), speed, AccelRamp::step(accel), BOUNDS)
    }

    #[test]
    fn a_change_with_room_keeps_the_full_duration() {
        // 4 s path: crosses at 2 s, + 0.5 s lag = 2.5 s, 50 m at 20 m/s.
        assert_eq!(crossing(51.0).time_from_rest(&MergeParams::default(), 4.0), 2.5);
        assert_eq!(start(&crossing(51.0), 20.0, 0.0), Some(LANE_CHANGE_DURATION));
        assert_eq!(start(&crossing(500.0), 20.0, 3.0), Some(LANE_CHANGE_DURATION));
    }

    #[test]
    fn a_tight_change_is_shortened_down_to_the_minimum_and_then_refused() {
        // Room for 45 m at 20 m/s: 2.25 s, the path's midpoint at 1.75 s: T = 3.5 s.
        let t = start(&crossing(46.0), 20.0, 0.0).unwrap();
        assert!((t - 3.5).abs() < 1e-9, "{t}");
        // T_min = 3 s crosses after 2 s: 40 m; 39 m of room is too little.
        assert!(start(&crossing(41.0), 20.0, 0.0).is_some_and(|t| (t - 3.0).abs() < 1e-9));
        assert_eq!(start(&crossing(40.0), 20.0, 0.0), None);
        // Braking covers less ground: the same room fits.
        assert!(start(&crossing(40.0), 20.0, -4.0).is_some());
        // But not braking to a stop before the line: the car would stand across it.
        assert_eq!(start(&crossing(40.0), 8.0, -4.0), None);
        assert!(start(&crossing(40.0), 8.0, -2.0).is_some());
        // From a standstill, a pull-out that drives.
        assert!(start(&crossing(8.0), 0.0, 0.0).is_none() && start(&crossing(8.0), 0.0, 1.0).is_some());
    }

    #[test]
    fn a_change_across_the_line_always_fits() {
        let across = Crossing { from: -1.5, ..crossing(0.5) };
        assert_eq!(start(&across, 20.0, 0.0), Some(LANE_CHANGE_DURATION));
        let under_way = UnderWay { pace: 3.5, crossing_in: Some(1.0) };
        assert_eq!(across.time_under_way(under_way, 3.5), 0.0);
    }

    #[test]
    fn a_change_under_way_keeps_to_its_prediction_and_is_shortened_when_it_must() {
        let p = MergeParams::default();
        // A fifth of the way across, predicted to cross in 0.9 s at a 4 s pace: 18 m at 20 m/s.
        let early = Crossing { from: -3.2, ..crossing(20.0) };
        let under_way = UnderWay { pace: 4.0, crossing_in: Some(0.9) };
        let fit = |c: &Crossing| c.fit(&p, 4.0, |t| c.time_under_way(under_way, t), 20.0, AccelRamp::step(0.0), BOUNDS);
        assert!((early.time_under_way(under_way, 4.0) - 0.9).abs() < 1e-12);
        assert_eq!(fit(&early), Some(4.0));
        // 15 m of room: 0.75 s, at a pace of 3.33 s.
        let t = fit(&Crossing { left: 16.0, ..early }).unwrap();
        assert!((t - 4.0 * 0.75 / 0.9).abs() < 1e-9, "{t}");
        assert_eq!(fit(&Crossing { left: 12.0, ..early }), None);
        // Without memory: what is left of the quintic from the lane's centre, at least.
        let unknown = UnderWay { pace: 4.0, crossing_in: None };
        let left = early.time_under_way(unknown, 4.0);
        assert!(left > 0.6 && left < 0.75, "{left}");
        assert_eq!(early.time_under_way(UnderWay { crossing_in: Some(0.1), ..under_way }, 4.0), left);
        // Late: by its lateral speed, never while it stands.
        let late = UnderWay { crossing_in: Some(-0.5), ..under_way };
        assert_eq!(early.time_under_way(late, 4.0), f64::INFINITY);
        let moving = Crossing { lateral_speed: 0.5, ..early };
        assert!((moving.time_under_way(late, 4.0) - 2.4).abs() < 1e-12);
        let hold = AccelRamp::step(0.0);
        assert_eq!(moving.fit(&p, 4.0, |t| moving.time_under_way(late, t), 20.0, hold, BOUNDS), None);
        // A quarter of the way across, by its lateral speed too: held back, it is late.
        let quarter = Crossing { from: -3.0, lateral_speed: 0.5, ..crossing(20.0) };
        assert_eq!(quarter.time_under_way(under_way, 4.0), 2.0);
        assert_eq!(quarter.time_under_way(under_way, 3.0), 1.5);
    }

    #[test]
    fn stopping_distance_at_once_and_at_the_jerk_bound() {
        let brake = AccelRamp::step(-4.0);
        assert!(can_stop(20.0, brake, 51.0, 1.0));
        assert!(!can_stop(20.0, brake, 50.0, 1.0));
        assert!(can_stop(0.0, brake, 1.0, 1.0));
        // From +1 m/s^2 down to -4 at 2.5 m/s^3: 2 s of ramp, 20 -> 17 m/s over 38.7 m
        // (20 t + t^2 / 2 - 2.5 t^3 / 6 at t = 2, v = 20 + t - 1.25 t^2), then 17^2 / 8.
        let ramp = AccelRamp { from: 1.0, to: -4.0, rate: 2.5 };
        let expected = 40.0 + 2.0 - 2.5 * 8.0 / 6.0 + 17.0f64.powi(2) / 8.0;
        assert!((stopping_distance(20.0, ramp) - expected).abs() < 1e-9, "{}", stopping_distance(20.0, ramp));
        assert!(!can_stop(20.0, ramp, 51.0, 1.0) && can_stop(20.0, ramp, expected + 1.0, 1.0));
    }
}
