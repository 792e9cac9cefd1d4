//! What one agent's episode came to, summed up as it runs and reported in the info of its
//! last step (`episode_*` keys, docs/evaluation.md): the figures `arena eval` tables, so
//! a policy driven in the server and one driven through a client are measured by the
//! same code. The cost RMS is the paper's (Tables V and VII, as `arena paper` computes
//! it): over every control period, of the stage cost sampled at the period's end.

use arena_protocol::InfoValue;

use arena_sim::gt::CostComponents;
use arena_sim::road::LaneId;
use arena_sim::scenario::Goal;
use arena_sim::world::{Status, VehicleId, World};

use super::reward::StepCost;

/// The running figures of one agent's episode.
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeStats {
    steps: u32,
    total_reward: f64,
    speed_sum: f64,
    min_gap: f64,
    min_ttc: f64,
    cost_squares: CostComponents,
    cost_samples: u32,
    /// Offset and lane the episode started with, to see the first lane crossing.
    start_d: f64,
    start_lane: LaneId,
    /// Start of the current run of steps with a lane change under way.
    changing_since: Option<f64>,
    /// Set once the vehicle has crossed half a lane from where it started.
    t_c: Option<f64>,
    crossed: bool,
}

impl EpisodeStats {
    /// The figures of an episode starting in `world` now.
    pub fn start(world: &World, id: VehicleId) -> EpisodeStats {
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
        }
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

    /// The `episode_*` infos of the last step, which ended for `end_reason`.
    pub fn finish(&self, world: &World, id: VehicleId, goal: &Goal, end_reason: &str) -> Vec<(String, InfoValue)> {
        let n = f64::from(self.cost_samples.max(1));
        let rms = |square: f64| (square / n).sqrt();
        let figures = [
            ("episode_success", InfoValue::Bool(succeeded(world, id, goal, end_reason))),
            ("episode_return", InfoValue::F64(self.total_reward)),
            ("episode_length", InfoValue::I64(i64::from(self.steps))),
            ("episode_mean_speed", InfoValue::F64(self.speed_sum / f64::from(self.steps.max(1)))),
            ("episode_min_gap", InfoValue::F64(self.min_gap)),
            ("episode_min_ttc", InfoValue::F64(self.min_ttc)),
            ("episode_rms_safety", InfoValue::F64(rms(self.cost_squares.safety))),
            ("episode_rms_comfort", InfoValue::F64(rms(self.cost_squares.comfort))),
            ("episode_rms_efficiency", InfoValue::F64(rms(self.cost_squares.efficiency))),
        ];
        let mut values: Vec<(String, InfoValue)> =
            figures.into_iter().map(|(key, value)| (key.to_string(), value)).collect();
        // Only when there was a lane change: a NaN would make equal infos compare unequal.
        if let Some(t_c) = self.t_c {
            values.push(("episode_t_c".to_string(), InfoValue::F64(t_c)));
        }
        values
    }
}

/// Whether the episode reached the scenario's goal: it ended on the road (time limit or
/// the road's end), in a goal lane, ahead of every car it had to pass.
fn succeeded(world: &World, id: VehicleId, goal: &Goal, end_reason: &str) -> bool {
    if !matches!(end_reason, "time_limit" | "road_end") {
        return false;
    }
    let vehicle = world.vehicle(id);
    let in_lane = goal.lanes.is_empty() || goal.lanes.contains(&world.current_lane(id));
    let ahead = goal
        .ahead_of
        .iter()
        .all(|name| world.find(name).is_none_or(|other| vehicle.state.s > world.vehicle(other).state.s));
    in_lane && ahead
}

/// The smallest bumper-to-bumper gap (m) and time to collision (s) to the cars that
/// matter now: the car ahead in the lane the vehicle is in and in the lane it changes
/// to, and the car behind in that target lane. Infinite when there is none (or, for the
/// time, when no gap ahead or behind closes).
fn closest_approach(world: &mut World, id: VehicleId) -> (f64, f64) {
    let scene = world.scene();
    let car = scene.car(id);
    let length = scene.vehicle.length;
    let (s, speed) = (car.state.s, car.speed());
    // (gap, closing speed) to the car ahead in each lane, and behind in the target lane.
    let ahead = [car.lane, car.target_lane]
        .map(|lane| scene.ahead(lane, s, &[id]).map(|ahead| (ahead.state.s - s - length, speed - ahead.speed())));
    let behind = (car.target_lane != car.lane)
        .then(|| scene.behind(car.target_lane, s, &[id]))
        .flatten()
        .map(|behind| (s - behind.state.s - length, behind.speed() - speed));
    ahead.into_iter().chain([behind]).flatten().fold((f64::INFINITY, f64::INFINITY), |(gap, ttc), (g, closing)| {
        // Beside a car (g <= 0) there is no time to close a gap along the road.
        let time = if g > 0.0 && closing > 0.0 { g / closing } else { f64::INFINITY };
        (gap.min(g), ttc.min(time))
    })
}
