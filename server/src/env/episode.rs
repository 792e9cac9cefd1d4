//! The terminate phase of a step and what one agent's episode came to: why it ended
//! (`EndReason`), and its figures, summed up as it runs and reported in the info of its
//! last step (`episode_*` keys, docs/evaluation.md): the figures `arena eval` tables, so
//! a policy driven in the server and one driven through a client are measured by the
//! same code. The cost RMS is the paper's (Tables V and VII, as `arena paper` computes
//! it): over every control period, of the stage cost sampled at the period's end.

use arena_protocol::EndReason;

use arena_sim::CostComponents;
use arena_sim::Goal;
use arena_sim::LaneId;
use arena_sim::{Ending, Status, VehicleId, World};

use super::risk::closest_approach;
use super::simulate::StepCost;

/// Why vehicle `id`'s episode ended, if it did (`World::ending` in the protocol's words;
/// the time limit is the env's).
pub fn ended(world: &World, id: VehicleId) -> Option<EndReason> {
    world.ending(id).map(|ending| match ending {
        Ending::Collision => EndReason::Collision,
        Ending::LaneEnd => EndReason::LaneEnd,
        Ending::OffRoad => EndReason::OffRoad,
        Ending::RoadEnd => EndReason::RoadEnd,
    })
}

/// An episode's figures, as its last info reports them; all zero before (`done` false).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Figures {
    /// Whether these are an ended episode's.
    pub done: bool,
    /// The scenario's goal was reached.
    pub success: bool,
    /// Sum of rewards.
    pub total_reward: f64,
    /// Steps.
    pub length: u32,
    /// Mean speed along the lane (m/s).
    pub mean_speed: f64,
    /// Smallest gap to a car that mattered (m); +inf if none did.
    pub min_gap: f64,
    /// Smallest time to collision (s); +inf if no gap closed.
    pub min_ttc: f64,
    /// RMS of each cost component over the control periods.
    pub rms: CostComponents,
    /// When the first lane change crossing half a lane began (s); +inf if none did.
    pub t_c: f64,
    /// The 95th percentile of the commanded jerk (m/s^3).
    pub p95_jerk: f64,
    /// The largest commanded jerk (m/s^3).
    pub max_jerk: f64,
}

/// The most control periods an env's episodes may hold for all its learners together
/// (max_cycles x periods per step x learners): each period keeps one commanded jerk per
/// learner (8 bytes) for the episode's percentile, so this bounds that memory at 8 MiB an
/// env. One learner may drive 2^20 periods (29 simulated hours at 0.1 s), 1 024 learners
/// 1 024 periods each.
pub const MAX_AGENT_PERIODS: usize = 1 << 20;

/// The running figures of one agent's episode.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EpisodeStats {
    pub(super) steps: u32,
    pub(super) total_reward: f64,
    pub(super) speed_sum: f64,
    pub(super) min_gap: f64,
    pub(super) min_ttc: f64,
    pub(super) cost_squares: CostComponents,
    pub(super) cost_samples: u32,
    /// Offset and lane the episode started with, to see the first lane crossing.
    pub(super) start_d: f64,
    pub(super) start_lane: LaneId,
    /// Start of the current run of steps with a lane change under way.
    pub(super) changing_since: Option<f64>,
    /// Set once the vehicle has crossed half a lane from where it started.
    pub(super) t_c: Option<f64>,
    pub(super) crossed: bool,
    /// The acceleration commanded in the last control period, and every commanded jerk.
    pub(super) last_accel: Option<f64>,
    pub(super) jerks: Vec<f64>,
}

impl EpisodeStats {
    /// The figures of an episode starting in `world` now, of at most `periods` control
    /// periods (room for their jerks is made now, not in a later step).
    pub fn start(world: &World, id: VehicleId, periods: usize) -> EpisodeStats {
        let vehicle = world.vehicle(id);
        EpisodeStats {
            steps: 0,
            total_reward: 0.0,
            speed_sum: 0.0,
            min_gap: f64::INFINITY,
            min_ttc: f64::INFINITY,
            cost_squares: CostComponents::default(),
            cost_samples: 0,
            start_d: vehicle.state.d,
            start_lane: world.current_lane(id),
            changing_since: None,
            t_c: None,
            crossed: false,
            last_accel: None,
            jerks: Vec::with_capacity(periods),
        }
    }

    /// Whether these figures, read from outside (a snapshot), could be an episode's of at
    /// most `steps` steps and `periods` control periods on a road of `lanes` lanes: every
    /// sum finite, least gaps and times to collision not NaN nor minus infinity, no more
    /// jerks than periods.
    pub fn check(&self, steps: u32, periods: usize, lanes: usize) -> Result<(), String> {
        let c = &self.cost_squares;
        let sums = [self.total_reward, self.speed_sum, c.safety, c.comfort, c.efficiency, self.start_d];
        let times = [self.changing_since, self.t_c, self.last_accel];
        if !sums.into_iter().chain(times.into_iter().flatten()).all(f64::is_finite) {
            return Err("a sum or time of its episode that is not finite".into());
        }
        // A gap is negative where cars overlap, and +inf until one mattered.
        if [self.min_gap, self.min_ttc].into_iter().any(|least| least.is_nan() || least == f64::NEG_INFINITY) {
            return Err(format!("a least gap {} or time to collision {} that is no size", self.min_gap, self.min_ttc));
        }
        if [c.safety, c.comfort, c.efficiency].into_iter().any(|square| square < 0.0) {
            return Err("a negative sum of squared costs".into());
        }
        if self.steps > steps || self.jerks.len() > periods {
            return Err(format!(
                "{} steps and {} jerks, where the episode has had {steps} steps of at most {periods} periods",
                self.steps,
                self.jerks.len()
            ));
        }
        if !self.jerks.iter().all(|jerk| jerk.is_finite() && *jerk >= 0.0) {
            return Err("a jerk that is not a finite size".into());
        }
        if self.start_lane.0 as usize >= lanes {
            return Err(format!("a start lane the road (lanes 0..{lanes}) does not have"));
        }
        Ok(())
    }

    /// Adds one env step that began at simulated time `started` and left `world` as it is.
    pub fn record(&mut self, world: &mut World, id: VehicleId, started: f64, reward: f64, cost: &StepCost) {
        self.steps += 1;
        self.total_reward += reward;
        self.cost_squares = self.cost_squares + cost.squares;
        self.cost_samples += cost.samples;
        let vehicle = world.vehicle(id);
        self.speed_sum += vehicle.state.lane_speed();
        let (d, target_lane) = (vehicle.state.d, vehicle.target_lane);
        if !self.crossed {
            self.changing_since = match (target_lane != self.start_lane, self.changing_since) {
                (true, None) => Some(started),
                (true, since) => since,
                (false, _) => None,
            };
            if (d - self.start_d).abs() > world.road().lane_width() / 2.0 {
                self.crossed = true;
                self.t_c = Some(self.changing_since.unwrap_or(started));
            }
        }
        if vehicle.status == Status::Driving {
            let (gap, ttc) = closest_approach(world, id);
            self.min_gap = self.min_gap.min(gap);
            self.min_ttc = self.min_ttc.min(ttc);
        }
    }

    /// Adds the accelerations commanded in consecutive control periods of `control_dt`:
    /// each change from the last over the period is a commanded jerk.
    pub fn record_accels(&mut self, accels: &[f64], control_dt: f64) {
        for &accel in accels {
            if let Some(last) = self.last_accel {
                self.jerks.push(((accel - last) / control_dt).abs());
            }
            self.last_accel = Some(accel);
        }
    }

    /// The figures of the episode, which ended for `end`.
    pub fn finish(&mut self, world: &World, id: VehicleId, goal: &Goal, end: EndReason) -> Figures {
        let n = f64::from(self.cost_samples.max(1));
        let rms = |square: f64| (square / n).sqrt();
        Figures {
            done: true,
            success: succeeded(world, id, goal, end),
            total_reward: self.total_reward,
            length: self.steps,
            mean_speed: self.speed_sum / f64::from(self.steps.max(1)),
            min_gap: self.min_gap,
            min_ttc: self.min_ttc,
            rms: CostComponents {
                safety: rms(self.cost_squares.safety),
                comfort: rms(self.cost_squares.comfort),
                efficiency: rms(self.cost_squares.efficiency),
            },
            t_c: self.t_c.unwrap_or(f64::INFINITY),
            p95_jerk: percentile(&mut self.jerks, 0.95),
            max_jerk: self.jerks.iter().copied().fold(0.0, f64::max),
        }
    }
}

/// The `q` quantile of `values` by nearest rank (the smallest value with at least a share
/// `q` of them at or below it); 0 for none. Sorts `values` in place.
fn percentile(values: &mut [f64], q: f64) -> f64 {
    values.sort_unstable_by(f64::total_cmp);
    let rank = (q * values.len() as f64).ceil() as usize;
    values.get(rank.saturating_sub(1)).copied().unwrap_or(0.0)
}

/// Whether the episode reached the scenario's goal: it ended on the road (time limit or
/// the road's end) where the goal asks (`Goal::reached`).
fn succeeded(world: &World, id: VehicleId, goal: &Goal, end: EndReason) -> bool {
    matches!(end, EndReason::TimeLimit | EndReason::RoadEnd) && goal.reached(world, id)
}

#[cfg(test)]
mod tests {
    use super::percentile;

    #[test]
    fn the_95th_percentile_is_the_nearest_rank() {
        let mut values: Vec<f64> = (1..=20).rev().map(f64::from).collect();
        assert_eq!(percentile(&mut values[10..], 0.95), 10.0);
        assert_eq!(percentile(&mut values, 0.95), 19.0);
        assert_eq!(percentile(&mut [], 0.95), 0.0);
    }
}
