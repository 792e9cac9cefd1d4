//! An agent's info dict: its keys, their types and their order, written once. Every
//! agent's info has the keys of `SCHEMA`, in that order, on reset and on every step, each
//! a number (never NaN) or a bool, so libraries that build their specs from the first
//! info (TorchRL, BenchMARL) or store infos in typed buffers (Tianshou) see one schema.
//! Options add keys that are then present on every step: `EXPERT` with `expert`, and
//! `gt.<car>.<count>` (`DIAGNOSTIC_COUNTS`) with `diagnostics`. What ended an episode is a
//! code (`EndReason`), and the episode's figures are zero until its last step
//! (`EPISODE_DONE`). "Never" (no car ahead, no lane crossed) is +infinity.

use serde::{Deserialize, Serialize};

use crate::names::named;

/// An agent's info dict.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Info {
    /// Entries, in a fixed order.
    pub values: Vec<(String, InfoValue)>,
}

/// An info value.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum InfoValue {
    /// A float.
    F64(f64),
    /// A boolean.
    Bool(bool),
    /// An integer.
    I64(i64),
    /// Floats of a fixed length (a continuous `expert_action`).
    F64s(Vec<f64>),
}

/// The type of an info value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InfoKind {
    /// `InfoValue::F64`.
    F64,
    /// `InfoValue::Bool`.
    Bool,
    /// `InfoValue::I64`.
    I64,
    /// `InfoValue::F64s`.
    F64s,
}

impl InfoValue {
    /// Its type.
    pub fn kind(&self) -> InfoKind {
        match self {
            InfoValue::F64(_) => InfoKind::F64,
            InfoValue::Bool(_) => InfoKind::Bool,
            InfoValue::I64(_) => InfoKind::I64,
            InfoValue::F64s(_) => InfoKind::F64s,
        }
    }
}

impl Info {
    /// The value of `key`.
    pub fn get(&self, key: &str) -> Option<&InfoValue> {
        self.values.iter().find(|(k, _)| k == key).map(|(_, value)| value)
    }

    /// The value of `key` as a number: floats and integers as they are, bools as 0 or 1.
    pub fn number(&self, key: &str) -> Option<f64> {
        match self.get(key)? {
            InfoValue::F64(x) => Some(*x),
            InfoValue::I64(x) => Some(*x as f64),
            InfoValue::Bool(x) => Some(f64::from(u8::from(*x))),
            InfoValue::F64s(_) => None,
        }
    }

    /// Why the agent's episode ended, or `Running`; `None` when the key is missing or
    /// holds no known code.
    pub fn end_reason(&self) -> Option<EndReason> {
        match self.get(END_REASON)? {
            InfoValue::I64(code) => EndReason::from_code(*code),
            _ => None,
        }
    }

    /// Appends an entry.
    pub fn push(&mut self, key: &str, value: InfoValue) {
        self.values.push((key.to_string(), value));
    }
}

/// Why an agent's episode ended (`END_REASON`, as its code).
#[repr(i64)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum EndReason {
    /// Not ended.
    Running = 0,
    /// Hit another vehicle.
    Collision = 1,
    /// Over the road's edge.
    OffRoad = 2,
    /// Drove past the end of its lane.
    LaneEnd = 3,
    /// Reached the end of the road.
    RoadEnd = 4,
    /// The episode reached `max_cycles`.
    TimeLimit = 5,
}

named!(EndReason, "end reason", {
    Running => "running", Collision => "collision", OffRoad => "off_road", LaneEnd => "lane_end",
    RoadEnd => "road_end", TimeLimit => "time_limit",
});

impl EndReason {
    /// Its code, as the info carries it.
    pub fn code(self) -> i64 {
        self as i64
    }

    /// The end reason of a code.
    pub fn from_code(code: i64) -> Option<EndReason> {
        Self::ALL.get(usize::try_from(code).ok()?).copied()
    }

    /// Whether an episode that ended so failed: the learner crashed or left the road (over
    /// its edge or past its lane's end); reaching the road's end or the time limit is no
    /// failure.
    pub fn failed(self) -> bool {
        matches!(self, EndReason::Collision | EndReason::OffRoad | EndReason::LaneEnd)
    }
}

/// Speed along the vehicle's heading (m/s).
pub const SPEED: &str = "speed";
/// The lane nearest the vehicle's centre (0 is the rightmost).
pub const LANE: &str = "lane";
/// Distance along the road (m).
pub const S: &str = "s";
/// It hit another vehicle.
pub const CRASHED: &str = "crashed";
/// It left the road (its edge, or past the end of its lane).
pub const OFF_ROAD: &str = "off_road";
/// The step's mean weighted cost J (eq. 9) with the agent's style weights; 0 on reset.
pub const COST: &str = "cost";
/// The step's mean safety cost (eq. 10-12).
pub const COST_SAFETY: &str = "cost_safety";
/// The step's mean comfort cost (eq. 13).
pub const COST_COMFORT: &str = "cost_comfort";
/// The step's mean efficiency cost (eq. 14).
pub const COST_EFFICIENCY: &str = "cost_efficiency";
/// Whether the agent's action changed its command (false for a lane change that the
/// road does not allow, say); true on reset.
pub const ACTION_APPLIED: &str = "action_applied";
/// `EndReason` code: 0 while running.
pub const END_REASON: &str = "end_reason";
/// The vehicle the agent's vehicle collided with (its index in the world: the scenario's
/// named vehicles sorted by name, then the traffic cars in the order drawn), -1 while it
/// has not.
pub const COLLISION_WITH: &str = "collision_with";
/// 1 if the agent's vehicle was at fault for that collision (it cut in too close ahead of
/// the other car, or did not keep its distance to a car in its lane; docs/design.md,
/// "Collision attribution"), else 0.
pub const AT_FAULT: &str = "at_fault";
/// Whether this is the agent's last step: then the `episode_*` figures are its episode's.
pub const EPISODE_DONE: &str = "episode_done";
/// The scenario's goal was reached (docs/evaluation.md).
pub const EPISODE_SUCCESS: &str = "episode_success";
/// Sum of the episode's rewards.
pub const EPISODE_RETURN: &str = "episode_return";
/// Steps in the episode.
pub const EPISODE_LENGTH: &str = "episode_length";
/// Mean speed along the lane over the episode's steps (m/s).
pub const EPISODE_MEAN_SPEED: &str = "episode_mean_speed";
/// Smallest bumper-to-bumper gap to a car that mattered (m); +inf if none did.
pub const EPISODE_MIN_GAP: &str = "episode_min_gap";
/// Smallest time to collision with such a car (s); +inf if no gap closed.
pub const EPISODE_MIN_TTC: &str = "episode_min_ttc";
/// RMS of the safety cost over the episode's control periods (Tables V, VII).
pub const EPISODE_RMS_SAFETY: &str = "episode_rms_safety";
/// RMS of the comfort cost.
pub const EPISODE_RMS_COMFORT: &str = "episode_rms_comfort";
/// RMS of the efficiency cost.
pub const EPISODE_RMS_EFFICIENCY: &str = "episode_rms_efficiency";
/// When the first lane change that crossed half a lane began (s, Tables IV, VI); +inf if
/// none did.
pub const EPISODE_T_C: &str = "episode_t_c";
/// The 95th percentile of the episode's commanded jerk (m/s^3): the change of the
/// acceleration commanded in one control period from the last, over the period, in
/// magnitude (docs/evaluation.md); 0 with fewer than two periods.
pub const EPISODE_P95_JERK: &str = "episode_p95_jerk";
/// The largest commanded jerk of the episode (m/s^3), likewise.
pub const EPISODE_MAX_JERK: &str = "episode_max_jerk";

/// Every agent's info, in this order, on reset and on every step.
pub const SCHEMA: [(&str, InfoKind); 26] = [
    (SPEED, InfoKind::F64),
    (LANE, InfoKind::I64),
    (S, InfoKind::F64),
    (CRASHED, InfoKind::Bool),
    (OFF_ROAD, InfoKind::Bool),
    (COST, InfoKind::F64),
    (COST_SAFETY, InfoKind::F64),
    (COST_COMFORT, InfoKind::F64),
    (COST_EFFICIENCY, InfoKind::F64),
    (ACTION_APPLIED, InfoKind::Bool),
    (END_REASON, InfoKind::I64),
    (COLLISION_WITH, InfoKind::I64),
    (AT_FAULT, InfoKind::I64),
    (EPISODE_DONE, InfoKind::Bool),
    (EPISODE_SUCCESS, InfoKind::Bool),
    (EPISODE_RETURN, InfoKind::F64),
    (EPISODE_LENGTH, InfoKind::I64),
    (EPISODE_MEAN_SPEED, InfoKind::F64),
    (EPISODE_MIN_GAP, InfoKind::F64),
    (EPISODE_MIN_TTC, InfoKind::F64),
    (EPISODE_RMS_SAFETY, InfoKind::F64),
    (EPISODE_RMS_COMFORT, InfoKind::F64),
    (EPISODE_RMS_EFFICIENCY, InfoKind::F64),
    (EPISODE_T_C, InfoKind::F64),
    (EPISODE_P95_JERK, InfoKind::F64),
    (EPISODE_MAX_JERK, InfoKind::F64),
];

/// What the built-in AV would do in the agent's place (option `expert`): an action of
/// the agent's own space (an integer for meta agents, 2 floats for continuous ones).
pub const EXPERT_ACTION: &str = "expert_action";
/// The AV's planned acceleration (m/s^2).
pub const EXPERT_ACCEL: &str = "expert_accel";
/// The AV's lane-change decision σ: -1 left, 0 keep, 1 right (`LaneChange::sigma`, the paper's σ).
pub const EXPERT_SIGMA: &str = "expert_sigma";

/// The keys `expert` adds after `SCHEMA`, in order (`EXPERT_ACTION` is `I64` for meta
/// agents).
pub const EXPERT: [(&str, InfoKind); 3] =
    [(EXPERT_ACTION, InfoKind::F64s), (EXPERT_ACCEL, InfoKind::F64), (EXPERT_SIGMA, InfoKind::I64)];

/// The solver counts `diagnostics` adds per game-theoretic car, as `gt.<car>.<count>`
/// (integers, since the episode began), cars in the world's order.
pub const DIAGNOSTIC_COUNTS: [&str; 5] = ["plans", "qp_iterations", "qp_iterations_total", "fallbacks", "inexact"];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn end_reason_codes_are_their_order_and_info_reads_them() {
        for (code, reason) in EndReason::ALL.into_iter().enumerate() {
            assert_eq!(reason.code(), code as i64);
            assert_eq!(EndReason::from_code(code as i64), Some(reason));
        }
        assert_eq!(EndReason::from_code(6), None);
        assert_eq!(EndReason::from_code(-1), None);
        let failed: Vec<_> = EndReason::ALL.into_iter().filter(|r| r.failed()).map(EndReason::name).collect();
        assert_eq!(failed, ["collision", "off_road", "lane_end"]);
        let mut info = Info::default();
        info.push(END_REASON, InfoValue::I64(3));
        info.push(EPISODE_DONE, InfoValue::Bool(true));
        assert_eq!(info.end_reason(), Some(EndReason::LaneEnd));
        assert_eq!(info.number(EPISODE_DONE), Some(1.0));
        assert_eq!(info.number("missing"), None);
    }

    #[test]
    fn the_schema_names_each_key_once() {
        let mut names: Vec<&str> = SCHEMA.iter().chain(&EXPERT).map(|(name, _)| *name).collect();
        names.sort_unstable();
        let before = names.len();
        names.dedup();
        assert_eq!(names.len(), before);
    }
}
