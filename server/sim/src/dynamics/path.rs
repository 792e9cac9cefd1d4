//! The lateral path drivers preview: a quintic in time from one offset to the next, the
//! "consecutive preview points" of §III-B, and the one duration every lane change takes.

use serde::{Deserialize, Serialize};

/// Duration of one lane change's lateral path (s), for every driver: IDM/MOBIL, learners'
/// meta actions, the game-theoretic AV's predictions and a scenario's start onto its lane.
/// 4, chosen here: a 4 s quintic settles every style within the bounds of
/// docs/parameters.md at 15-30 m/s.
pub const LANE_CHANGE_DURATION: f64 = 4.0;

/// Below this speed (m/s) a lateral path under way advances slower than the clock, at
/// speed / `FULL_PACE_SPEED` of it (`LateralPath::pace`), and stands while the car stands.
/// 5, chosen here: a 4 s change then covers at least 20 m of road, and its peak lateral
/// speed (15/8 of a 4 m lane over 4 s, 1.9 m/s) asks for a heading of at most 0.38 rad
/// (22°) against the lane. On the clock alone, a change begun as the car stopped (IDM
/// braking at a lane end or behind a queue) ran to its end while the car stood; the
/// driver then steered to the wheels' lock towards a preview point a lane away, and the
/// car, creeping off, turned across the lane beside and off the road's far edge
/// (traffic's on-ramp tests). At highway speeds the path runs on the clock as before.
pub const FULL_PACE_SPEED: f64 = 5.0;

/// A smooth lateral path from one offset to another (a quintic in time with zero
/// lateral speed and acceleration at both ends): the "consecutive preview points" of
/// §III-B. Drivers preview it `T_p` ahead rather than aiming at the final lane, which
/// with a constant K_s overshoots by metres (docs/design.md, "Preview path").
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LateralPath {
    /// Offset at the start (m).
    pub from: f64,
    /// Offset at the end (m).
    pub to: f64,
    /// Simulated time the path starts (s).
    pub start: f64,
    /// Duration (s).
    pub duration: f64,
}

impl LateralPath {
    /// A path that stays at `d`.
    pub fn hold(d: f64) -> LateralPath {
        LateralPath { from: d, to: d, start: 0.0, duration: 1.0 }
    }

    /// A lane change from offset `from` to `to` starting at `start`.
    pub fn lane_change(from: f64, to: f64, start: f64) -> LateralPath {
        LateralPath { from, to, start, duration: LANE_CHANGE_DURATION }
    }

    /// The path's offset at time `t` (m).
    pub fn offset_at(&self, t: f64) -> f64 {
        let u = ((t - self.start) / self.duration).clamp(0.0, 1.0);
        let blend = u * u * u * (10.0 - 15.0 * u + 6.0 * u * u);
        self.from + (self.to - self.from) * blend
    }

    /// The preview point Y_p for a driver at time `t` with preview time `T_p`.
    pub fn preview(&self, t: f64, preview_time: f64) -> f64 {
        self.offset_at(t + preview_time)
    }

    /// Lets a path under way at time `t` advance by only speed / `FULL_PACE_SPEED` of the
    /// physics step `dt` a car at `speed` (m/s, along its lane) spends on it: its start
    /// moves later by the rest. A path not yet begun or finished, or a car at
    /// `FULL_PACE_SPEED` or faster, leaves it as it is.
    pub fn pace(&mut self, t: f64, dt: f64, speed: f64) {
        if speed < FULL_PACE_SPEED && t > self.start && !self.finished(t) {
            self.start += dt * (1.0 - speed.max(0.0) / FULL_PACE_SPEED);
        }
    }

    /// Whether the path has reached its end at time `t`.
    pub fn finished(&self, t: f64) -> bool {
        t >= self.start + self.duration
    }
}
