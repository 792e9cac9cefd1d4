//! The lateral path drivers preview: a quintic in time from one offset to the next, the
//! "consecutive preview points" of §III-B, and the one duration every lane change takes.

use serde::{Deserialize, Serialize};

/// Duration of one lane change's lateral path (s), for every driver: IDM/MOBIL, learners'
/// meta actions, the game-theoretic AV's predictions and a scenario's start onto its lane.
/// 4, chosen here: a 4 s quintic settles every style within the bounds of
/// docs/parameters.md at 15-30 m/s.
pub const LANE_CHANGE_DURATION: f64 = 4.0;

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

    /// Whether the path has reached its end at time `t`.
    pub fn finished(&self, t: f64) -> bool {
        t >= self.start + self.duration
    }
}
