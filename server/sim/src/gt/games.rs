//! The lane-change games of §IV: Nash equilibrium (eq. 15–16) and Stackelberg
//! equilibrium (eq. 17–18) between the ego car (EC: an acceleration and a lane choice
//! sigma) and the adjacent car of each side (AC: an acceleration only), on costs of
//! eq. (9)–(14) averaged over predicted motion. Each side is its own two-player game
//! (eq. 16c–f / 18c–f); EC keeps the side whose equilibrium costs it least (eq. 16a / 18a).
//!
//! The strategy sets are acceleration grids within [a_min, a_max], clipped so the speed
//! stays within its bounds over the next control period. Each is a target, reached from
//! the player's last command at the jerk bound (`jerk`): its predicted motion and its
//! comfort cost follow that ramp.

use serde::{Deserialize, Serialize};

use super::costs::{self, CostComponents, CostParams};
use super::jerk::{AccelRamp, JerkParams};
use super::merge::{self, Crossing, MergeParams, UnderWay};
use super::prediction::{self, Kinematics, PredictionParams, SpeedBounds};
use super::styles::CostWeights;
use crate::dynamics::{LANE_CHANGE_DURATION, LateralPath};
use crate::road::LaneChange;

/// Which equilibrium a game-theoretic driver plays.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Game {
    /// Eq. (15)–(16): EC and AC as equal players, each a best response to the other.
    Nash,
    /// Eq. (17)–(18): EC leads, anticipating AC's best response; AC follows.
    Stackelberg,
}

impl Game {
    /// Both games, Nash first.
    pub const ALL: [Game; 2] = [Game::Nash, Game::Stackelberg];

    /// The lowercase name used in scenario files and reports.
    pub fn name(self) -> &'static str {
        match self {
            Game::Nash => "nash",
            Game::Stackelberg => "stackelberg",
        }
    }
}

/// The strategy sets and the equilibrium options.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GameParams {
    /// a_min of eq. (15) (m/s^2), for EC and AC alike. -4, chosen here (firm braking,
    /// within the world's 6 m/s^2 limit).
    pub accel_min: f64,
    /// a_max of eq. (15) (m/s^2). 3, chosen here (highway-env's comfortable maximum).
    pub accel_max: f64,
    /// Spacing of the acceleration grid (m/s^2). 0.25, chosen here: 29 values per player,
    /// fine enough to separate the styles, small enough for the 1 ms budget.
    pub accel_step: f64,
    /// v_min of eq. (15) (m/s). 0: cars do not reverse. v_max is each lane's speed limit.
    pub speed_min: f64,
    /// Relative tolerance on the follower's best-response set gamma of eq. (17b): AC
    /// replies are kept whose cost is within (1 + tolerance) of the best, and the leader
    /// guards against the worst of them. 0.3, chosen here: the smallest of 0.1, 0.2, 0.3
    /// under which every Stackelberg lane change of Scenarios A and B comes later than its
    /// Nash twin with a larger gap, as the paper's do (docs/paper-reproduction.md, "Nash
    /// against Stackelberg"); with 0 (eq. 17b exactly) the two games give the same runs.
    pub follower_tolerance: f64,
    /// Whether AC's lateral safety term of eq. (12) is switched by EC's sigma^2 as EC's
    /// is (eq. 10), or always paid. `switched`, the reading of "AC's lateral safety cost
    /// equals EC's" (docs/paper-reproduction.md, "Nash against Stackelberg").
    #[serde(default)]
    pub adjacent_lateral: AdjacentLateral,
}

/// How AC pays the lateral term of eq. (12) (§IV-A leaves it open; docs/paper-reproduction.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AdjacentLateral {
    /// As EC's: times sigma^2, so zero while EC keeps its lane.
    #[default]
    Switched,
    /// Always, whatever EC decides (the sigma^2-free reading).
    Always,
}

impl Default for GameParams {
    fn default() -> Self {
        GameParams {
            accel_min: -4.0,
            accel_max: 3.0,
            accel_step: 0.25,
            speed_min: 0.0,
            follower_tolerance: 0.3,
            adjacent_lateral: AdjacentLateral::Switched,
        }
    }
}

impl GameParams {
    /// The acceleration grid for a car at `speed` within `bounds`, each value clipped to
    /// what the next control period `dt` allows and to what `jerk` lets it settle from on
    /// the bounds (`JerkParams::envelope`), duplicates dropped, ascending.
    pub fn grid(&self, speed: f64, bounds: SpeedBounds, dt: f64, jerk: &JerkParams) -> Vec<f64> {
        let steps = ((self.accel_max - self.accel_min) / self.accel_step).round().max(0.0) as usize;
        let (low, high) = jerk.envelope(speed, bounds);
        let mut grid: Vec<f64> = Vec::with_capacity(steps + 1);
        for k in 0..=steps {
            let a = (self.accel_min + k as f64 * self.accel_step).min(self.accel_max);
            let a = prediction::feasible_accel(a, speed, bounds, dt).clamp(low, high);
            if grid.last().is_none_or(|&last| a > last) {
                grid.push(a);
            }
        }
        grid
    }
}

/// Which of EC's costs a side's game must compute. AC's are always all there (every
/// equilibrium needs AC's best replies); EC's are needed only where an equilibrium
/// search reads them, and computing only those is what makes a decision fast. `All`
/// fills the whole table: the straightforward reference the tests compare against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Needs {
    /// Every cell.
    All,
    /// The columns that are some row's best reply (eq. 15).
    Nash,
    /// Each row's follower set within this tolerance (eq. 17b).
    Stackelberg(f64),
    /// None: only AC's replies are read.
    Replies,
}

impl Needs {
    /// What `game` reads.
    pub fn of(game: Game, params: &GameParams) -> Needs {
        match game {
            Game::Nash => Needs::Nash,
            Game::Stackelberg => Needs::Stackelberg(params.follower_tolerance),
        }
    }
}

/// A bimatrix game: `rows` leader (EC) actions × `cols` follower (AC) actions, costs
/// stored row-major. EC's cells that its `Needs` left out hold NaN and are never read.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PayoffTable {
    /// Number of EC actions.
    pub rows: usize,
    /// Number of AC actions (1 when there is no AC).
    pub cols: usize,
    /// J^EC per (row, col).
    pub ec: Vec<f64>,
    /// J^AC per (row, col); NaN where a fast search proved the cell cannot matter (it
    /// costs AC more than its best reply and than any follower-set bound).
    pub ac: Vec<f64>,
    /// AC's best reply per row, when the builder found it; empty: found from `ac`.
    pub replies: Vec<usize>,
    /// Rows the builder proved cannot be EC's choice nor any column's least cost for EC
    /// (`Situation::side_game_with`): none of their cells is computed or read. Empty: none.
    pub pruned: Vec<bool>,
}

/// A chosen pair of actions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Profile {
    /// EC's action.
    pub row: usize,
    /// AC's action (the one EC predicts).
    pub col: usize,
    /// False when Nash found no pure equilibrium (see `SideGame::nash`).
    pub exact: bool,
}

impl PayoffTable {
    fn ec(&self, row: usize, col: usize) -> f64 {
        let cost = self.ec[row * self.cols + col];
        debug_assert!(!cost.is_nan(), "EC's cost at ({row}, {col}) was not computed");
        cost
    }

    fn ac(&self, row: usize, col: usize) -> f64 {
        self.ac[row * self.cols + col]
    }

    fn in_play(&self, row: usize) -> bool {
        !self.pruned.get(row).copied().unwrap_or(false)
    }

    /// The rows in play: all but the pruned ones, in order.
    fn rows_in_play(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.rows).filter(|&row| self.in_play(row))
    }

    /// AC's best reply to `row` (the first of equal ones).
    pub fn best_reply(&self, row: usize) -> usize {
        match self.replies.get(row) {
            Some(&col) => col,
            None => (0..self.cols).fold(0, |best, col| if self.ac(row, col) < self.ac(row, best) { col } else { best }),
        }
    }

    /// Eq. (15): a pure Nash equilibrium, each action a best response to the other; of
    /// several, the one EC prefers. `None` when the table has none. Reads EC's costs only
    /// in the columns that are some row's best reply (`Needs::Nash`).
    pub fn nash(&self) -> Option<Profile> {
        let mut column_min: Vec<Option<f64>> = vec![None; self.cols];
        let mut best: Option<(usize, usize)> = None;
        for row in self.rows_in_play() {
            let col = self.best_reply(row); // eq. (15b)
            let floor = *column_min[col]
                .get_or_insert_with(|| self.rows_in_play().map(|r| self.ec(r, col)).fold(f64::INFINITY, f64::min));
            let is_equilibrium = self.ec(row, col) <= floor; // eq. (15a)
            if is_equilibrium && best.is_none_or(|(r, c)| self.ec(row, col) < self.ec(r, c)) {
                best = Some((row, col));
            }
        }
        best.map(|(row, col)| Profile { row, col, exact: true })
    }

    /// Of the rows `allowed`, the one whose cost against AC's best reply is least, as
    /// an inexact profile: what EC does when there is no equilibrium to play.
    fn best_against_replies(&self, allowed: impl Iterator<Item = usize>) -> Profile {
        let mut best = (f64::INFINITY, 0, 0);
        for row in allowed.filter(|&row| self.in_play(row)) {
            let col = self.best_reply(row);
            if self.ec(row, col) < best.0 {
                best = (self.ec(row, col), row, col);
            }
        }
        Profile { row: best.1, col: best.2, exact: false }
    }

    /// Eq. (17): EC minimises its worst cost over AC's best-response set gamma (eq. 17b:
    /// every reply no worse than any other; with `tolerance` > 0, every reply within
    /// (1 + tolerance) of the best). `col` is the reply EC guards against.
    pub fn stackelberg(&self, tolerance: f64) -> Profile {
        let mut best = (f64::INFINITY, 0, 0);
        for row in self.rows_in_play() {
            let bound = follower_bound(self.ac(row, self.best_reply(row)), tolerance);
            let mut worst = (f64::NEG_INFINITY, 0);
            for col in 0..self.cols {
                if self.ac(row, col) <= bound && self.ec(row, col) > worst.0 {
                    worst = (self.ec(row, col), col); // eq. (17b), then the max of (17a)
                }
            }
            if worst.0 < best.0 {
                best = (worst.0, row, worst.1); // eq. (17a)'s min
            }
        }
        Profile { row: best.1, col: best.2, exact: true }
    }
}

/// A car whose cost enters a game: where it is, how it weighs the costs, its speed bounds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Player {
    /// Now.
    pub now: Kinematics,
    /// Its last commanded acceleration (m/s^2), where its candidates ramp from (`jerk`).
    pub accel: f64,
    /// Table III for its style.
    pub weights: CostWeights,
    /// v_min and v_max of its lane.
    pub bounds: SpeedBounds,
}

/// The adjacent car of one side, with what its own costs need.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Adjacent {
    /// AC itself (bounds: its lane's).
    pub player: Player,
    /// Its lead obstacle for eq. (11) (a car or its lane's end), other than EC.
    pub leader: Option<Kinematics>,
    /// Its lead car for eq. (14), other than EC.
    pub lead: Option<Kinematics>,
}

/// One lane EC may choose: its own (sigma = 0) or a neighbour (sigma = -1 left, +1 right).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaneOption {
    /// -1, 0 or 1.
    pub sigma: i8,
    /// The lane's centre (m).
    pub centre: f64,
    /// v_max there (m/s).
    pub speed_limit: f64,
    /// EC's lead obstacle for eq. (11) in this lane (a car, or the lane's end as a
    /// stopped car). Used for sigma = 0.
    pub leader: Option<Kinematics>,
    /// EC's lead car for eq. (14) in this lane, other than AC (lane ends excluded).
    pub lead: Option<Kinematics>,
    /// The adjacent car of this lane (sigma != 0 only).
    pub adjacent: Option<Adjacent>,
}

/// Everything a decision reads, taken from the world by `driver`.
#[derive(Debug, Clone, PartialEq)]
pub struct Situation {
    /// EC (bounds: its current lane's).
    pub ego: Player,
    /// EC's own lane.
    pub keep: LaneOption,
    /// Left (sigma = -1) and right (sigma = +1) lanes, where they can be chosen.
    pub sides: [Option<LaneOption>; 2],
    /// The side of a lane change under way: EC then chooses only its acceleration.
    pub committed: Option<i8>,
    /// Distance from EC's centre to the end of its lane (m), if the lane ends before the
    /// road does: a lane change out of it must cross the line before (`merge`).
    pub lane_end: Option<f64>,
    /// How the lane change under way is timed, from the driver's memory (`merge`); `None`:
    /// at `LANE_CHANGE_DURATION`, its crossing unknown.
    pub under_way: Option<UnderWay>,
    /// EC's lateral speed (m/s, + to the left), for a change under way that is late.
    pub lateral_speed: f64,
    /// Lane width (m), for a_y of eq. (13).
    pub lane_width: f64,
    /// l_v of eq. (11c)/(12c): one car length (m).
    pub car_length: f64,
    /// Control period (s): the strategies must keep the speed in bounds over it.
    pub period: f64,
}

/// All constants of the decision layer.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct DecisionParams {
    /// eq. (10)–(14).
    pub costs: CostParams,
    /// The horizon the costs are averaged over.
    pub prediction: PredictionParams,
    /// Strategy sets and equilibrium options.
    pub game: GameParams,
    /// Lane changes out of an ending lane (docs/design.md, "Merging that completes").
    #[serde(default)]
    pub merge: MergeParams,
    /// The jerk bound (docs/design.md, "Jerk").
    #[serde(default)]
    pub jerk: JerkParams,
}

/// What a game decided for EC.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Decision {
    /// a_x* (m/s^2).
    pub accel: f64,
    /// sigma*: the lane change chosen.
    pub lane_change: LaneChange,
    /// EC's predicted cost components at the chosen profile (mean over the horizon).
    pub predicted: CostComponents,
    /// J^EC of eq. (9) at the chosen profile.
    pub cost: f64,
    /// The adjacent car's acceleration EC predicts in the chosen side's game.
    pub response: Option<f64>,
    /// False when Nash had no pure equilibrium (EC then kept its current lane decision)
    /// or the driver fell back to its safe command.
    pub exact: bool,
    /// The full-width duration (s) of the chosen lane change when it was shortened from
    /// `LANE_CHANGE_DURATION` to cross the line before EC's lane ends (`merge`).
    #[serde(default)]
    pub duration: Option<f64>,
    /// Seconds to the lane line predicted for the chosen lane change out of an ending
    /// lane (`merge`): what the driver remembers of it while it is under way.
    #[serde(default)]
    pub crossing: Option<f64>,
    /// Whether EC gives up the lane change under way: it can no longer cross the line
    /// before its lane ends, and can still stop in its lane (`merge`).
    #[serde(default)]
    pub aborted: bool,
}

/// One side's game, built: the actions and the tables.
#[derive(Debug, Clone)]
pub struct SideGame {
    /// EC's actions: (acceleration, sigma).
    pub ec_actions: Vec<(f64, i8)>,
    /// AC's accelerations (one 0 when there is no AC).
    pub ac_actions: Vec<f64>,
    /// The costs.
    pub table: PayoffTable,
    pub(crate) option: Option<LaneOption>,
}

impl SideGame {
    /// Eq. (15) on this side's game. With no pure equilibrium, no lane change starts from
    /// a profile that is not one: EC keeps its current lane decision (the rows of the
    /// lane change under way, else those that keep the lane), taking its best row
    /// against AC's best replies, and the profile is marked inexact.
    pub fn nash(&self) -> Profile {
        if let Some(profile) = self.table.nash() {
            return profile;
        }
        let committed = self.ec_actions.iter().all(|&(_, sigma)| sigma != 0);
        let current = |row: &usize| committed || self.ec_actions[*row].1 == 0;
        self.table.best_against_replies((0..self.table.rows).filter(current))
    }
}

/// AC's cells computed at once (`lane_change_entries`).
const LANES: usize = 4;

/// AC's cost terms that do not depend on EC's action (`Situation::ac_terms`), weighted:
/// comfort per action; efficiency per action and sample, unless a lead-car cap
/// (`lead_range` > 0) makes it depend on EC's position.
struct AcTerms {
    safety_weight: f64,
    comfort: Vec<f64>,
    /// Per action, its samples in order (`samples` of them each).
    efficiency: Option<Vec<f64>>,
}

impl AcTerms {
    /// Per AC action, a lower bound on AC's cost in any lane-change row: the cost with
    /// the lateral term at zero (and the efficiency at zero where it is not known),
    /// summed as `ac_entry` sums. Rounding is monotonic, so it is a bound in floating
    /// point too.
    fn floors(&self, samples: usize) -> Vec<f64> {
        (0..self.comfort.len())
            .map(|col| {
                let mut sum = 0.0;
                for k in 0..samples {
                    let efficiency = self.efficiency.as_ref().map_or(0.0, |e| e[col * samples + k]);
                    sum += self.safety_weight * 0.0 + self.comfort[col] + efficiency;
                }
                sum / samples.max(1) as f64
            })
            .collect()
    }
}

/// The most a reply may cost AC and still be in its follower set of eq. (17b), when its
/// best reply costs `floor`: within (1 + tolerance) of the best.
fn follower_bound(floor: f64, tolerance: f64) -> f64 {
    floor + tolerance * floor.abs()
}

/// What one cell of a side's tables reads.
struct Cell<'a> {
    samples: &'a Samples,
    option: Option<&'a LaneOption>,
    params: &'a DecisionParams,
}

/// One player's predicted paths, one per action, each of the horizon's samples, in one
/// buffer: a side's game predicts up to 58 of them every control period.
struct Paths {
    samples: Vec<Kinematics>,
    per_path: usize,
}

impl Paths {
    /// Room for `paths` paths, each to be predicted into `path_mut`.
    fn new(params: &PredictionParams, paths: usize) -> Paths {
        let per_path = params.samples.max(1);
        Paths { samples: vec![Kinematics::default(); paths * per_path], per_path }
    }

    fn path_mut(&mut self, path: usize) -> &mut [Kinematics] {
        &mut self.samples[path * self.per_path..(path + 1) * self.per_path]
    }

    fn len(&self) -> usize {
        self.samples.len() / self.per_path
    }

    fn iter(&self) -> std::slice::ChunksExact<'_, Kinematics> {
        self.samples.chunks_exact(self.per_path)
    }

    fn get(&self, path: usize) -> Option<&[Kinematics]> {
        self.samples.get(path * self.per_path..(path + 1) * self.per_path)
    }
}

impl std::ops::Index<usize> for Paths {
    type Output = [Kinematics];

    fn index(&self, path: usize) -> &[Kinematics] {
        self.get(path).expect("a path of the game")
    }
}

/// EC's lane-keeping rows of one side's game: their accelerations, predicted paths and
/// EC's costs (`Situation::keep_rows`). They read neither side's AC, so the other side's
/// game of the same decision takes them as they are.
struct KeepRows {
    accels: Vec<f64>,
    paths: Paths,
    costs: Vec<f64>,
}

/// The predicted samples every entry of a side's tables reads.
struct Samples {
    ec: Paths,
    /// Per EC action, the full-width duration of its lane change (s).
    durations: Vec<f64>,
    ac: Paths,
    leader: Vec<Kinematics>,
    lead: Vec<Kinematics>,
    lead_side: Vec<Kinematics>,
    ac_leader: Vec<Kinematics>,
    ac_lead: Vec<Kinematics>,
}

/// J_rc of eq. (13) with a_x along `ramp`, averaged over the horizon's samples as the
/// other costs are: the target's own where every sample comes after the ramp.
fn ramp_comfort(c: &CostParams, p: &PredictionParams, sigma: i8, ramp: AccelRamp, lateral_accel: f64) -> f64 {
    let first = p.times().next().unwrap_or(0.0);
    if ramp.duration() <= first {
        return costs::comfort(c, sigma, ramp.to, lateral_accel);
    }
    let sum: f64 = p.times().map(|t| costs::comfort(c, sigma, ramp.at(t), lateral_accel)).sum();
    sum / p.samples.max(1) as f64
}

fn constant_speed(p: &PredictionParams, car: Option<Kinematics>) -> Vec<Kinematics> {
    let mut out = vec![Kinematics::default(); if car.is_some() { p.samples.max(1) } else { 0 }];
    if let Some(car) = car {
        let bounds = SpeedBounds { min: 0.0, max: f64::INFINITY };
        prediction::predict(p, car, AccelRamp::step(0.0), bounds, None, &mut out);
    }
    out
}

impl Situation {
    fn option(&self, sigma: i8) -> Option<&LaneOption> {
        match sigma {
            0 => Some(&self.keep),
            -1 => self.sides[0].as_ref(),
            _ => self.sides[1].as_ref(),
        }
    }

    fn ego_bounds(&self, option: &LaneOption, params: &GameParams) -> SpeedBounds {
        SpeedBounds { min: params.speed_min, max: option.speed_limit }
    }

    /// The lateral path of a lane change to `option` starting now, shortened in
    /// proportion when part of the way is already done.
    fn lane_change_path(&self, option: &LaneOption, duration: f64) -> LateralPath {
        let remaining = ((option.centre - self.ego.now.d).abs() / self.lane_width).clamp(0.25, 1.0);
        LateralPath { from: self.ego.now.d, to: option.centre, start: 0.0, duration: duration * remaining }
    }

    /// A lane change to `option` out of EC's ending lane, if its lane ends.
    fn crossing(&self, option: &LaneOption) -> Option<Crossing> {
        let left = self.lane_end?;
        let (origin, from, to, lateral_speed) = (self.keep.centre, self.ego.now.d, option.centre, self.lateral_speed);
        Some(Crossing { origin, from, lateral_speed, to, line: 0.5 * (origin + to), left, width: self.lane_width })
    }

    /// The full-width duration of EC's action (accel, sigma): `LANE_CHANGE_DURATION` (or
    /// the pace of the change under way), or out of an ending lane the longest that
    /// crosses the line in time; `None` when none does (`merge`).
    fn fitted_duration(&self, accel: f64, sigma: i8, params: &DecisionParams) -> Option<f64> {
        let under_way = self.timing(sigma);
        let longest = under_way.map_or(LANE_CHANGE_DURATION, |u| u.pace);
        let option = self.option(sigma).filter(|_| sigma != 0 && params.merge.enabled);
        let Some((option, crossing)) = option.and_then(|o| Some((o, self.crossing(o)?))) else {
            return Some(longest);
        };
        let (speed, bounds, m) = (self.ego.now.speed, self.ego_bounds(option, &params.game), &params.merge);
        let ramp = params.jerk.ramp(self.ego.accel, accel);
        match under_way {
            Some(u) => crossing.fit(m, longest, |t| crossing.time_under_way(u, t), speed, ramp, bounds),
            None => crossing.fit(m, longest, |t| crossing.time_from_rest(m, t), speed, ramp, bounds),
        }
    }

    /// The timing of the lane change under way to side `sigma`, if it is one.
    fn timing(&self, sigma: i8) -> Option<UnderWay> {
        let default = UnderWay { pace: LANE_CHANGE_DURATION, crossing_in: None };
        (sigma != 0 && self.binding() == Some(sigma)).then(|| self.under_way.unwrap_or(default))
    }

    /// Seconds to the lane line predicted for EC's action (accel, sigma) at full-width
    /// `duration`, for a lane change out of an ending lane (`merge`): from rest for one that
    /// starts, the remembered prediction rescaled for one under way.
    fn crossing_time(&self, sigma: i8, duration: f64, params: &DecisionParams) -> Option<f64> {
        let option = self.option(sigma).filter(|_| sigma != 0 && params.merge.enabled)?;
        let crossing = self.crossing(option)?;
        match self.timing(sigma) {
            // What was predicted, at the new pace: past due stays past due.
            Some(u) => u.crossing_in.map(|t| t * duration / u.pace),
            None => Some(crossing.time_from_rest(&params.merge, duration)),
        }
    }

    /// The duration EC's action is predicted with: fitted, or where nothing fits (a change
    /// kept only because EC can stop neither), the shortest.
    fn duration(&self, accel: f64, sigma: i8, params: &DecisionParams) -> f64 {
        self.fitted_duration(accel, sigma, params).unwrap_or(params.merge.min_duration.min(LANE_CHANGE_DURATION))
    }

    /// Whether EC is more than a quarter lane off its lane's centre while it changes no
    /// lane: back from an aborted change, or just across the line of one it finished. It
    /// starts none until it has settled, so that it does not turn back at once into the
    /// change it gave up. In an ending lane (`merge`), only while it still drives at
    /// `crossing_speed` or more: nearly stopped, it can no longer move sideways.
    fn unsettled(&self, params: &DecisionParams) -> bool {
        let off = (self.ego.now.d - self.keep.centre).abs() > 0.25 * self.lane_width;
        let m = &params.merge;
        match self.lane_end {
            None => off,
            Some(_) => m.enabled && off && self.ego.now.speed >= m.crossing_speed,
        }
    }

    /// Whether EC can still stop `margin` short of its lane's end, braking towards a_min
    /// from its last command at the jerk bound, or at once when the braking is exempt
    /// from the bound (`exempt`: an abort, `jerk::Exemption`).
    fn can_stop(&self, params: &DecisionParams, margin: f64, exempt: bool) -> bool {
        let a_min = params.game.accel_min;
        let ramp = if exempt { AccelRamp::step(a_min) } else { params.jerk.ramp(self.ego.accel, a_min) };
        self.lane_end.is_none_or(|left| merge::can_stop(self.ego.now.speed, ramp, left, margin))
    }

    /// Of the accelerations `grid` that keep EC's lane, those after one control period of
    /// which EC can still stop `stop_margin` short of its lane's end braking towards a_min
    /// at the jerk bound; all of them if its lane does not end (`merge`). The period's
    /// command ramps from the last one, or with `exempt` (an abort) is the acceleration
    /// itself. If none can: all of them when the jerk bound is off (the next period may
    /// brake at a_min at once), else those that stop shortest, since under the bound a
    /// command let go climbs for periods before it can brake again.
    fn keeping(&self, grid: Vec<f64>, params: &DecisionParams, exempt: bool) -> Vec<f64> {
        let Some(left) = self.lane_end.filter(|_| params.merge.enabled) else { return grid };
        let (speed, dt, a_min) = (self.ego.now.speed, self.period, params.game.accel_min);
        let bounds = SpeedBounds { min: params.game.speed_min, max: f64::INFINITY };
        // After one period: how far EC went, how fast it goes, how it brakes from there.
        let after = |a: f64| {
            let first = if exempt { AccelRamp::step(a) } else { params.jerk.ramp(self.ego.accel, a) };
            let (ds, v) = prediction::advance_ramp(speed, first, bounds, dt);
            (ds, v, params.jerk.ramp(first.at(dt), a_min))
        };
        let stops = |a: f64| {
            let (ds, v, brake) = after(a);
            merge::can_stop(v, brake, left - ds, params.merge.stop_margin)
        };
        if grid.iter().any(|&a| stops(a)) {
            return grid.into_iter().filter(|&a| stops(a)).collect();
        }
        if !params.jerk.enabled {
            return grid;
        }
        let reach = |a: f64| {
            let (ds, v, brake) = after(a);
            ds + merge::stopping_distance(v, brake)
        };
        let shortest = grid.iter().map(|&a| reach(a)).fold(f64::INFINITY, f64::min);
        grid.into_iter().filter(|&a| reach(a) <= shortest).collect()
    }

    /// The lane change under way, while it binds: its lane is still an option.
    fn binding(&self) -> Option<i8> {
        self.committed.filter(|&c| self.option(c).is_some())
    }

    /// EC's actions for the game of side `side` (-1 or +1). A lane change under way
    /// binds only while its lane is still an option.
    ///
    /// Out of an ending lane (`merge`), a lane change that cannot cross the line before
    /// the end is no action, unless EC can stop short of the end in none of them either
    /// (then they all stay, at the shortest duration). A change under way none of whose
    /// accelerations crosses in time is aborted if EC can still stop: its actions are
    /// those that keep the lane.
    fn ec_actions(&self, side: i8, params: &DecisionParams) -> Vec<(f64, i8)> {
        let game = &params.game;
        let committed = self.binding();
        let sigmas: &[i8] = match committed {
            Some(c) if c == side => &[side][..],
            Some(_) => &[],
            None if self.option(side).is_some() => &[0, side][..],
            None => &[0][..],
        };
        let mut actions = Vec::new();
        for &sigma in sigmas {
            let Some(option) = self.option(sigma) else { continue };
            let bounds = self.ego_bounds(option, game);
            let grid = game.grid(self.ego.now.speed, bounds, self.period, &params.jerk);
            if sigma == 0 {
                actions.extend(self.keeping(grid, params, false).into_iter().map(|a| (a, 0)));
                continue;
            }
            if committed.is_none() && self.unsettled(params) {
                continue;
            }
            let fits: Vec<f64> =
                grid.iter().copied().filter(|&a| self.fitted_duration(a, sigma, params).is_some()).collect();
            // A change under way is given up if EC can still stop before the end; one is
            // not started if EC can stop with room to pull out later.
            let m = &params.merge;
            // An abort brakes at once (exempt from the jerk bound); a change not started
            // leaves a way out at the bound.
            let aborting = committed.is_some();
            let stops =
                fits.is_empty() && self.can_stop(params, if aborting { m.end_margin } else { m.stop_margin }, aborting);
            if stops && aborting {
                // Abort: brake in the lane instead (the game of the lane kept).
                let keep = game.grid(self.ego.now.speed, self.ego_bounds(&self.keep, game), self.period, &params.jerk);
                actions.extend(self.keeping(keep, params, true).into_iter().map(|a| (a, 0)));
            } else if stops {
                continue;
            } else if fits.is_empty() {
                actions.extend(grid.into_iter().map(|a| (a, sigma)));
            } else {
                actions.extend(fits.into_iter().map(|a| (a, sigma)));
            }
        }
        actions
    }

    /// Builds the game of side `side` (eq. 16c–f / 18c–f) with AC's cost table and the
    /// cells of EC's that `needs` asks for.
    pub fn side_game(&self, side: i8, params: &DecisionParams, needs: Needs) -> SideGame {
        let (ec_actions, ac_actions) = self.actions(side, params);
        self.side_game_with(side, ec_actions, ac_actions, params, needs)
    }

    /// EC's and AC's actions in side `side`'s game (AC's one 0 when there is no AC).
    fn actions(&self, side: i8, params: &DecisionParams) -> (Vec<(f64, i8)>, Vec<f64>) {
        let adjacent = self.option(side).and_then(|o| o.adjacent);
        let grid = |ac: Adjacent| params.game.grid(ac.player.now.speed, ac.player.bounds, self.period, &params.jerk);
        (self.ec_actions(side, params), adjacent.map_or(vec![0.0], grid))
    }

    /// Builds side `side`'s game for the given actions (a row or column may be a single
    /// action, as a follower replying to one observed decision needs).
    pub fn side_game_with(
        &self,
        side: i8,
        ec_actions: Vec<(f64, i8)>,
        ac_actions: Vec<f64>,
        params: &DecisionParams,
        needs: Needs,
    ) -> SideGame {
        self.side_game_keeping(side, ec_actions, ac_actions, params, needs, None).0
    }

    /// `side_game_with`, taking the lane-keeping rows' paths and costs from `shared` (the
    /// other side's game of the same decision) when its lane-keeping actions are the
    /// same; returns its own for the next side.
    fn side_game_keeping(
        &self,
        side: i8,
        ec_actions: Vec<(f64, i8)>,
        ac_actions: Vec<f64>,
        params: &DecisionParams,
        needs: Needs,
        shared: Option<KeepRows>,
    ) -> (SideGame, KeepRows) {
        let option = self.option(side).copied();
        let mut samples = self.samples_but_ec(&ec_actions, &ac_actions, option.as_ref(), params);
        // EC's cost in each lane-keeping row (the same in every column: while EC keeps its
        // lane its cost does not depend on AC), their least, and the lane-change rows whose
        // comfort alone costs more than that: pruned before their paths are predicted.
        let kept = self.keep_rows(&ec_actions, &mut samples, option.as_ref(), params, shared);
        let keep_costs: Vec<Option<f64>> = {
            let mut costs = kept.costs.iter();
            ec_actions.iter().map(|action| if action.1 == 0 { costs.next().copied() } else { None }).collect()
        };
        let keep_best = keep_costs.iter().flatten().fold(f64::INFINITY, |best, &own| best.min(own));
        let prunes = self.prunes(params, needs) && keep_best < f64::INFINITY;
        let unpredicted: Vec<bool> = (ec_actions.iter().enumerate())
            .map(|(row, &(accel, sigma))| {
                sigma != 0 && prunes && self.ec_comfort_floor(&samples, row, accel, sigma, params) > keep_best
            })
            .collect();
        for (row, &action) in ec_actions.iter().enumerate() {
            if action.1 != 0 && !unpredicted[row] {
                self.predict_ec(&mut samples, row, action, params);
            }
        }
        let (rows, cols) = (ec_actions.len(), ac_actions.len());
        let mut table = PayoffTable {
            rows,
            cols,
            ec: vec![f64::NAN; rows * cols],
            ac: vec![f64::NAN; rows * cols],
            replies: Vec::with_capacity(rows),
            pruned: vec![false; rows],
        };
        let cell = Cell { samples: &samples, option: option.as_ref(), params };
        // Lower bounds on AC's cost per column for a lane-change row: the lateral term is
        // never negative, so a column whose bound exceeds the best cost found cannot be
        // AC's reply nor in its follower set, and is not computed (`Needs::All` computes
        // every cell: the reference).
        let terms = self.ac_terms(&cell, &ac_actions);
        let n = samples.ec.get(0).map_or(0, <[Kinematics]>::len);
        let floors = terms.as_ref().map_or_else(|| vec![0.0; cols], |terms| terms.floors(n));
        let mut by_floor: Vec<usize> = (0..cols).collect();
        by_floor.sort_by(|&a, &b| floors[a].total_cmp(&floors[b]).then(a.cmp(&b)));
        let tolerance = match needs {
            Needs::Stackelberg(tolerance) => tolerance,
            _ => 0.0,
        };
        // While EC keeps its lane, AC's cost does not depend on EC's action: one row of AC
        // costs serves all those rows.
        let mut keeping: Option<(Vec<f64>, usize)> = None;
        // A lane-keeping row costing EC more than the best one, in every column, is
        // neither its Stackelberg choice nor a Nash equilibrium and lowers no column's
        // least cost: an equilibrium search skips it (a NaN cost is kept, as it compares).
        let search = matches!(needs, Needs::Nash | Needs::Stackelberg(_));
        let dominated = |row: usize| search && keep_costs[row].is_some_and(|own| own > keep_best);
        for (row, &(accel, sigma)) in ec_actions.iter().enumerate() {
            let against_keeping = sigma != 0 && prunes;
            if unpredicted[row]
                || dominated(row)
                || (against_keeping && self.ec_floor(&cell, row, accel, sigma) > keep_best)
            {
                table.pruned[row] = true;
                table.replies.push(0); // never read
                continue;
            }
            let replies = &mut table.ac[row * cols..(row + 1) * cols];
            let reply = if let (0, Some((alone, reply)), AdjacentLateral::Switched) =
                (sigma, &keeping, params.game.adjacent_lateral)
            {
                replies.copy_from_slice(alone);
                *reply
            } else if sigma == 0 || needs == Needs::All {
                for (col, cost) in replies.iter_mut().enumerate() {
                    *cost = self.ac_entry(&cell, row, col, sigma, ac_actions[col]);
                }
                let reply = (0..cols).fold(0, |best, col| if replies[col] < replies[best] { col } else { best });
                if sigma == 0 {
                    keeping = Some((replies.to_vec(), reply));
                }
                reply
            } else {
                let mut best = (f64::INFINITY, usize::MAX);
                let mut bound = f64::INFINITY;
                let mut next = 0;
                while next < cols && floors[by_floor[next]] <= bound {
                    // Up to four columns at once; those past the bound cost more than it,
                    // so computing them changes no reply and no follower set.
                    let batch = &by_floor[next..(next + LANES).min(cols)];
                    next += batch.len();
                    let costs = match terms.as_ref().and_then(|t| Some((t, t.efficiency.as_deref()?))) {
                        Some((terms, efficiency)) => self.ac_lane_change_entries(&cell, row, batch, terms, efficiency),
                        None => std::array::from_fn(|i| {
                            batch.get(i).map_or(0.0, |&col| self.ac_entry(&cell, row, col, sigma, ac_actions[col]))
                        }),
                    };
                    for (&col, &cost) in batch.iter().zip(&costs) {
                        replies[col] = cost;
                        if cost < best.0 || (cost == best.0 && col < best.1) {
                            best = (cost, col);
                            bound = follower_bound(cost, tolerance);
                        }
                    }
                }
                best.1
            };
            table.replies.push(reply);
            if let Some(own) = keep_costs[row] {
                table.ec[row * cols..(row + 1) * cols].fill(own);
            }
        }
        let mut wanted = vec![matches!(needs, Needs::All); rows * cols];
        match needs {
            Needs::All | Needs::Replies => {}
            Needs::Nash => {
                let mut columns: Vec<usize> = table.rows_in_play().map(|row| table.replies[row]).collect();
                columns.sort_unstable();
                columns.dedup();
                for col in columns {
                    (0..rows).for_each(|row| wanted[row * cols + col] = true);
                }
            }
            Needs::Stackelberg(tolerance) => {
                // Lane-keeping rows hold their one cost in every column already.
                for row in table.rows_in_play().filter(|&row| ec_actions[row].1 != 0) {
                    let bound = follower_bound(table.ac(row, table.best_reply(row)), tolerance);
                    for col in (0..cols).filter(|&col| table.ac(row, col) <= bound) {
                        wanted[row * cols + col] = true;
                    }
                }
            }
        }
        for (row, &(accel, sigma)) in ec_actions.iter().enumerate() {
            if sigma == 0 || !table.in_play(row) {
                continue;
            }
            for col in (0..cols).filter(|&col| wanted[row * cols + col]) {
                table.ec[row * cols + col] =
                    self.ec_entry(&cell, row, col, accel, sigma).weighted_by(&self.ego.weights);
            }
        }
        (SideGame { ec_actions, ac_actions, table, option }, kept)
    }

    /// EC's lane-keeping rows of a side's game (sigma = 0, in order): their paths written
    /// into `samples` and their costs, copied from `shared` when it has the same actions.
    fn keep_rows(
        &self,
        ec_actions: &[(f64, i8)],
        samples: &mut Samples,
        option: Option<&LaneOption>,
        params: &DecisionParams,
        shared: Option<KeepRows>,
    ) -> KeepRows {
        let keep: Vec<(usize, f64)> =
            ec_actions.iter().enumerate().filter(|(_, action)| action.1 == 0).map(|(row, a)| (row, a.0)).collect();
        let same = |shared: &KeepRows| {
            shared.accels.len() == keep.len()
                && keep.iter().zip(&shared.accels).all(|(k, a)| k.1.to_bits() == a.to_bits())
        };
        if let Some(shared) = shared.filter(same) {
            for (k, &(row, _)) in keep.iter().enumerate() {
                samples.ec.path_mut(row).copy_from_slice(&shared.paths[k]);
            }
            return shared;
        }
        for &(row, accel) in &keep {
            self.predict_ec(samples, row, (accel, 0), params);
        }
        let cell = Cell { samples, option, params };
        let costs =
            keep.iter().map(|&(row, accel)| self.ec_entry(&cell, row, 0, accel, 0).weighted_by(&self.ego.weights));
        let mut paths = Paths::new(&params.prediction, keep.len());
        for (k, &(row, _)) in keep.iter().enumerate() {
            paths.path_mut(k).copy_from_slice(&samples.ec[row]);
        }
        KeepRows { accels: keep.iter().map(|k| k.1).collect(), paths, costs: costs.collect() }
    }

    /// Every path a side's tables read, EC's predicted for every action.
    fn samples(
        &self,
        ec_actions: &[(f64, i8)],
        ac_actions: &[f64],
        option: Option<&LaneOption>,
        params: &DecisionParams,
    ) -> Samples {
        let mut samples = self.samples_but_ec(ec_actions, ac_actions, option, params);
        for (row, &action) in ec_actions.iter().enumerate() {
            self.predict_ec(&mut samples, row, action, params);
        }
        samples
    }

    /// Every path a side's tables read but EC's (`predict_ec`, row by row).
    fn samples_but_ec(
        &self,
        ec_actions: &[(f64, i8)],
        ac_actions: &[f64],
        option: Option<&LaneOption>,
        params: &DecisionParams,
    ) -> Samples {
        let p = &params.prediction;
        let durations: Vec<f64> =
            ec_actions.iter().map(|&(accel, sigma)| self.duration(accel, sigma, params)).collect();
        let adjacent = option.and_then(|o| o.adjacent);
        let mut ac = Paths::new(p, if adjacent.is_some() { ac_actions.len() } else { 0 });
        if let Some(adj) = adjacent {
            for (col, &accel) in ac_actions.iter().enumerate() {
                let ramp = params.jerk.ramp(adj.player.accel, accel);
                prediction::predict(p, adj.player.now, ramp, adj.player.bounds, None, ac.path_mut(col));
            }
        }
        Samples {
            ec: Paths::new(p, ec_actions.len()),
            durations,
            ac,
            leader: constant_speed(p, self.keep.leader),
            lead: constant_speed(p, self.keep.lead),
            lead_side: constant_speed(p, option.filter(|o| o.sigma != 0).and_then(|o| o.lead)),
            ac_leader: constant_speed(p, adjacent.and_then(|a| a.leader)),
            ac_lead: constant_speed(p, adjacent.and_then(|a| a.lead)),
        }
    }

    /// EC's predicted path for its action (accel, sigma) of row `row`.
    fn predict_ec(&self, samples: &mut Samples, row: usize, (accel, sigma): (f64, i8), params: &DecisionParams) {
        let target = self.option(sigma).unwrap_or(&self.keep);
        let bounds = self.ego_bounds(target, &params.game);
        let path = (sigma != 0).then(|| self.lane_change_path(target, samples.durations[row]));
        let ramp = params.jerk.ramp(self.ego.accel, accel);
        prediction::predict(&params.prediction, self.ego.now, ramp, bounds, path.as_ref(), samples.ec.path_mut(row));
    }

    /// AC's J_rc of eq. (13) for its action `accel` over the horizon (unweighted).
    fn ac_comfort(&self, params: &DecisionParams, adj: &Adjacent, accel: f64) -> f64 {
        let ramp = params.jerk.ramp(adj.player.accel, accel);
        ramp_comfort(&params.costs, &params.prediction, 0, ramp, 0.0)
    }

    /// AC's row-independent cost terms (`AcTerms`); `None` with no adjacent car.
    fn ac_terms(&self, cell: &Cell, ac_actions: &[f64]) -> Option<AcTerms> {
        let (samples, c) = (cell.samples, &cell.params.costs);
        let adj = cell.option.and_then(|o| o.adjacent)?;
        let w = &adj.player.weights;
        let limit = adj.player.bounds.max;
        let comfort = ac_actions.iter().map(|&a| w.comfort * self.ac_comfort(cell.params, &adj, a)).collect();
        let efficiency = (c.lead_range <= 0.0 && samples.ac.len() == ac_actions.len()).then(|| {
            samples
                .ac
                .iter()
                .flat_map(|path| {
                    path.iter().enumerate().map(|(k, &ac)| {
                        // As `ac_cost` computes v-bar for a lane change with the cap off.
                        let v_bar = costs::target_speed(c, ac, limit, samples.ac_lead.get(k).copied()).min(limit);
                        w.efficiency * costs::efficiency(ac.speed, v_bar)
                    })
                })
                .collect()
        });
        Some(AcTerms { safety_weight: w.safety, comfort, efficiency })
    }

    /// `ac_entry` for a lane-change row and up to `LANES` columns at once, from
    /// precomputed terms: the same operations in the same order in each SIMD lane, so
    /// the same bits as `ac_entry` (the differential test compares the two).
    fn ac_lane_change_entries(
        &self,
        cell: &Cell,
        row: usize,
        cols: &[usize],
        terms: &AcTerms,
        efficiency: &[f64],
    ) -> [f64; LANES] {
        let c = &cell.params.costs;
        let ec_path = &cell.samples.ec[row];
        let n = ec_path.len();
        // Unused lanes repeat the first column; their results are dropped.
        let lane = |i: usize| cols.get(i).copied().unwrap_or(cols[0]);
        let columns = LaneChangeColumns {
            paths: std::array::from_fn(|i| &cell.samples.ac[lane(i)]),
            efficiency: std::array::from_fn(|i| &efficiency[lane(i) * n..(lane(i) + 1) * n]),
            comfort: std::array::from_fn(|i| terms.comfort[lane(i)]),
        };
        let constants = [self.car_length, c.kappa_s_lat, c.epsilon, c.kappa_v_lat, terms.safety_weight];
        lane_change_entries(ec_path, &columns, constants)
    }

    /// The lateral term of eq. (12) at sample `k` of a profile: zero while EC keeps its
    /// lane (eq. 10), shared by EC's cost and AC's (§IV-A).
    fn lateral(&self, c: &CostParams, sigma: i8, ego: Kinematics, ac: Option<Kinematics>) -> f64 {
        match (sigma, ac) {
            (0, _) | (_, None) => 0.0,
            (_, Some(ac)) => costs::lateral_safety(c, self.car_length, ego, ac),
        }
    }

    /// EC's cost components for one profile, averaged over the predicted samples.
    fn ec_entry(&self, cell: &Cell, row: usize, col: usize, accel: f64, sigma: i8) -> CostComponents {
        self.ec_components(cell, row, cell.samples.ac.get(col), accel, sigma)
    }

    /// Whether lane-change rows may be pruned against the lane-keeping ones (`ec_floor`):
    /// for an equilibrium search (the reference `Needs::All` computes everything), when
    /// EC's travel-efficiency term does not depend on AC (no lead-car cap) and its safety
    /// weight is not negative.
    fn prunes(&self, params: &DecisionParams, needs: Needs) -> bool {
        let search = matches!(needs, Needs::Nash | Needs::Stackelberg(_));
        search && params.costs.lead_range <= 0.0 && self.ego.weights.safety >= 0.0
    }

    /// A lower bound on EC's weighted cost in lane-change row `row` against any AC action:
    /// the cost with no AC, which only drops the lateral term (never negative) and, with
    /// the lead-car cap off, changes no other term. Rounding is monotonic, so it is a
    /// bound in floating point too. A row whose bound exceeds the cost of some lane-keeping
    /// row, which is the same in every column, is neither EC's Stackelberg choice (eq.
    /// 17a) nor a Nash equilibrium (eq. 15a), and lowers no column's least cost: it is
    /// pruned without computing its cells.
    fn ec_floor(&self, cell: &Cell, row: usize, accel: f64, sigma: i8) -> f64 {
        self.ec_components(cell, row, None, accel, sigma).weighted_by(&self.ego.weights)
    }

    /// A lower bound on `ec_floor` that reads no predicted path: the weighted comfort term
    /// alone, averaged as `ec_components` averages it. The terms it leaves out are never
    /// negative with no AC (safety is 0, efficiency a square) when the efficiency weight
    /// is not, and rounding is monotonic; otherwise it is -infinity (no bound).
    fn ec_comfort_floor(&self, samples: &Samples, row: usize, accel: f64, sigma: i8, params: &DecisionParams) -> f64 {
        if self.ego.weights.efficiency < 0.0 {
            return f64::NEG_INFINITY;
        }
        let comfort = self.ec_comfort(params, samples.durations[row], accel, sigma);
        let n = samples.ec.per_path;
        let sum = (0..n).fold(0.0, |sum, _| sum + comfort);
        self.ego.weights.comfort * (sum * (1.0 / n as f64))
    }

    /// EC's J_rc of eq. (13) for its action (accel, sigma), its lane change `duration` long.
    fn ec_comfort(&self, params: &DecisionParams, duration: f64, accel: f64, sigma: i8) -> f64 {
        let lateral_accel = prediction::lane_change_accel_over(self.lane_width, duration);
        let ramp = params.jerk.ramp(self.ego.accel, accel);
        ramp_comfort(&params.costs, &params.prediction, sigma, ramp, lateral_accel)
    }

    /// EC's cost components in row `row` against AC's predicted path `ac_path` (none: no
    /// AC), averaged over the predicted samples.
    fn ec_components(
        &self,
        cell: &Cell,
        row: usize,
        ac_path: Option<&[Kinematics]>,
        accel: f64,
        sigma: i8,
    ) -> CostComponents {
        let (samples, c) = (cell.samples, &cell.params.costs);
        let ec_path = &samples.ec[row];
        let target = self.option(sigma).unwrap_or(&self.keep);
        let ec_comfort = self.ec_comfort(cell.params, samples.durations[row], accel, sigma);
        let mut ec_sum = CostComponents::default();
        for (k, &ego) in ec_path.iter().enumerate() {
            let ac = ac_path.map(|path| path[k]);
            let (lead, ec_lead_extra) = if sigma == 0 {
                (samples.lead.get(k).copied(), None)
            } else {
                (samples.lead_side.get(k).copied(), ac.filter(|ac| ac.s >= ego.s))
            };
            let lateral = self.lateral(c, sigma, ego, ac);
            let longitudinal = match sigma {
                0 => samples
                    .leader
                    .get(k)
                    .map_or(0.0, |&leader| costs::longitudinal_safety(c, self.car_length, ego, leader)),
                _ => 0.0, // eq. (10): (sigma^2 - 1)^2 = 0
            };
            let limit = target.speed_limit;
            let v_bar = costs::target_speed(c, ego, limit, lead).min(costs::target_speed(c, ego, limit, ec_lead_extra));
            ec_sum = ec_sum
                + CostComponents {
                    safety: costs::safety(sigma, longitudinal, lateral),
                    comfort: ec_comfort,
                    efficiency: costs::efficiency(ego.speed, v_bar),
                };
        }
        let n = ec_path.len().max(1) as f64;
        ec_sum * (1.0 / n)
    }

    /// AC's weighted cost for one profile, averaged over the predicted samples (0 with no
    /// adjacent car).
    fn ac_entry(&self, cell: &Cell, row: usize, col: usize, sigma: i8, ac_accel: f64) -> f64 {
        let (samples, c) = (cell.samples, &cell.params.costs);
        let (Some(ac_path), Some(adj)) = (samples.ac.get(col), cell.option.and_then(|o| o.adjacent)) else {
            return 0.0;
        };
        let ec_path = &samples.ec[row];
        let ac_comfort = self.ac_comfort(cell.params, &adj, ac_accel);
        let mut ac_sum = 0.0;
        for (k, &ego) in ec_path.iter().enumerate() {
            let ac = ac_path[k];
            let lateral = match cell.params.game.adjacent_lateral {
                AdjacentLateral::Switched => self.lateral(c, sigma, ego, Some(ac)),
                AdjacentLateral::Always => costs::lateral_safety(c, self.car_length, ego, ac),
            };
            ac_sum += self.ac_cost(samples, k, ego, ac, &adj, sigma, ac_comfort, lateral, c);
        }
        ac_sum / ec_path.len().max(1) as f64
    }

    /// J^AC at one sample: its own lead obstacle while EC keeps its lane, the shared
    /// lateral term while EC comes over (§IV-A), its comfort and efficiency.
    #[allow(clippy::too_many_arguments)]
    fn ac_cost(
        &self,
        samples: &Samples,
        k: usize,
        ego: Kinematics,
        ac: Kinematics,
        adj: &Adjacent,
        sigma: i8,
        comfort: f64,
        lateral: f64,
        c: &CostParams,
    ) -> f64 {
        let longitudinal = match sigma {
            0 => samples
                .ac_leader
                .get(k)
                .map_or(0.0, |&leader| costs::longitudinal_safety(c, self.car_length, ac, leader)),
            _ => 0.0, // eq. (10): (sigma^2 - 1)^2 = 0
        };
        let limit = adj.player.bounds.max;
        let mut v_bar = costs::target_speed(c, ac, limit, samples.ac_lead.get(k).copied());
        if sigma != 0 {
            v_bar = v_bar.min(costs::target_speed(c, ac, limit, Some(ego)));
        }
        // eq. (10) for AC; with `AdjacentLateral::Always` the lateral term is paid in
        // full while EC keeps its lane too (sigma = 0 drops it from `costs::safety`).
        let safety = match sigma {
            0 => costs::safety(0, longitudinal, 0.0) + lateral,
            _ => costs::safety(sigma, longitudinal, lateral),
        };
        let parts = CostComponents { safety, comfort, efficiency: costs::efficiency(ac.speed, v_bar) };
        parts.weighted_by(&adj.player.weights)
    }

    /// EC's unweighted cost components at one profile of a side's game.
    fn components(&self, game: &SideGame, profile: Profile, params: &DecisionParams) -> CostComponents {
        let (accel, sigma) = game.ec_actions[profile.row];
        let ac_accel = game.ac_actions[profile.col];
        let ec_actions = vec![(accel, sigma)];
        let ac_actions = vec![ac_accel];
        let samples = self.samples(&ec_actions, &ac_actions, game.option.as_ref(), params);
        let cell = Cell { samples: &samples, option: game.option.as_ref(), params };
        let _ = ac_accel;
        self.ec_entry(&cell, 0, 0, accel, sigma)
    }

    /// EC's decision: each side's equilibrium (eq. 16c–f or 18c–f), then the cheaper
    /// side (eq. 16a / 18a; on a tie the left one, whose game is built first).
    pub fn decide(&self, game: Game, params: &DecisionParams) -> Decision {
        self.decide_reading(game, params, Needs::of(game, &params.game))
    }

    /// `decide`, computing the cells of EC's tables that `needs` asks for (`Needs::All`:
    /// the whole tables, the reference the fast search is tested against).
    pub fn decide_reading(&self, game: Game, params: &DecisionParams, needs: Needs) -> Decision {
        let played = self.play(game, params, needs);
        let Some(chosen) = chosen_side(&played) else {
            return Decision { exact: false, ..Decision::default() };
        };
        let (side_game, profile, cost) = played[chosen].as_ref().expect("a chosen side was played");
        self.decision_of(side_game, *profile, *cost, params)
    }

    /// Each side's game (left, right) with its equilibrium (eq. 16c–f or 18c–f) and EC's
    /// cost there; `None` for a side where EC has no action.
    fn play(&self, game: Game, params: &DecisionParams, needs: Needs) -> [Option<(SideGame, Profile, f64)>; 2] {
        let mut keeping: Option<KeepRows> = None;
        [-1, 1].map(|side| {
            let (ec_actions, ac_actions) = self.actions(side, params);
            let (side_game, kept) = self.side_game_keeping(side, ec_actions, ac_actions, params, needs, keeping.take());
            keeping = Some(kept);
            if side_game.ec_actions.is_empty() {
                return None;
            }
            let profile = match game {
                Game::Nash => side_game.nash(),
                Game::Stackelberg => side_game.table.stackelberg(params.game.follower_tolerance),
            };
            let cost = side_game.table.ec(profile.row, profile.col);
            Some((side_game, profile, cost))
        })
    }

    /// EC's decision at `profile` of `side_game`.
    fn decision_of(&self, side_game: &SideGame, profile: Profile, cost: f64, params: &DecisionParams) -> Decision {
        let (accel, sigma) = side_game.ec_actions[profile.row];
        let response = side_game.option.and_then(|o| o.adjacent).map(|_| side_game.ac_actions[profile.col]);
        let predicted = self.components(side_game, profile, params);
        let full = self.duration(accel, sigma, params);
        let duration = Some(full).filter(|&t| sigma != 0 && t < LANE_CHANGE_DURATION);
        let crossing = self.crossing_time(sigma, full, params);
        let aborted = sigma == 0 && self.binding().is_some();
        let (lane_change, exact) = (LaneChange::from_sigma(sigma), profile.exact);
        Decision { accel, lane_change, predicted, cost, response, exact, duration, crossing, aborted }
    }

    /// `decide` again, keeping what it played: both sides' games as the search computed
    /// them, their equilibria, the side chosen, and the predicted paths at its
    /// equilibrium (issue 27's explanation; only asked for, never on the driving path).
    pub fn explain(&self, game: Game, params: &DecisionParams) -> GameExplained {
        let played = self.play(game, params, Needs::of(game, &params.game));
        let chosen = chosen_side(&played);
        let mut explained = GameExplained { chosen, ..GameExplained::default() };
        if let Some((side_game, profile, _)) = chosen.and_then(|at| played[at].as_ref()) {
            (explained.planned, explained.predicted) = self.paths(side_game, *profile, params);
        }
        explained.times = params.prediction.times().collect();
        explained.sides = played
            .into_iter()
            .zip([-1, 1])
            .map(|(side, sigma)| side.map(|(g, profile, cost)| g.explained(sigma, profile, cost)))
            .collect();
        explained
    }

    /// A follower's game explained: side `side`'s game as the follower built it, at
    /// `profile`, with EC's and AC's predicted paths there.
    pub fn explain_side(
        &self,
        side: i8,
        side_game: SideGame,
        profile: Profile,
        params: &DecisionParams,
    ) -> GameExplained {
        let (planned, predicted) = self.paths(&side_game, profile, params);
        let cost = side_game.table.ec[profile.row * side_game.table.cols + profile.col];
        let at = usize::from(side == 1);
        let mut sides = vec![None, None];
        sides[at] = Some(side_game.explained(side, profile, cost));
        let times = params.prediction.times().collect();
        GameExplained { sides, chosen: Some(at), planned, predicted, times }
    }

    /// EC's and AC's predicted paths at `profile` of `side_game` (AC's empty with no AC).
    fn paths(
        &self,
        side_game: &SideGame,
        profile: Profile,
        params: &DecisionParams,
    ) -> (Vec<Kinematics>, Vec<Kinematics>) {
        let ec_actions = [side_game.ec_actions[profile.row]];
        let ac_actions = [side_game.ac_actions[profile.col]];
        let option = side_game.option.as_ref();
        let samples = self.samples(&ec_actions, &ac_actions, option, params);
        let path = |paths: &Paths| paths.get(0).map_or_else(Vec::new, <[Kinematics]>::to_vec);
        (path(&samples.ec), path(&samples.ac))
    }
}

/// Of the sides played, the one whose equilibrium costs EC least (eq. 16a / 18a; on a
/// tie the left one).
fn chosen_side(played: &[Option<(SideGame, Profile, f64)>; 2]) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for (at, side) in played.iter().enumerate() {
        if let Some((_, _, cost)) = side
            && best.is_none_or(|(_, b)| *cost < b)
        {
            best = Some((at, *cost));
        }
    }
    best.map(|(at, _)| at)
}

/// A decision explained (issue 27): each side's game as the search computed it, the
/// side chosen, and the predicted paths at its equilibrium.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GameExplained {
    /// The left (sigma = -1) and right (+1) games; `None` where EC had no action.
    pub sides: Vec<Option<SideExplained>>,
    /// The side whose equilibrium was played (index into `sides`).
    pub chosen: Option<usize>,
    /// EC's predicted path at the chosen profile (one sample per prediction step).
    pub planned: Vec<Kinematics>,
    /// AC's predicted path at the chosen profile (empty with no AC).
    pub predicted: Vec<Kinematics>,
    /// The time of each path sample after the decision (s).
    pub times: Vec<f64>,
}

/// One side's game as the search computed it: the actions, both cost tables (row-major,
/// NaN where the search proved a cell irrelevant and skipped it), its equilibrium.
#[derive(Debug, Clone, PartialEq)]
pub struct SideExplained {
    /// -1 left, +1 right.
    pub side: i8,
    /// EC's actions: (acceleration m/s^2, sigma).
    pub ec_actions: Vec<(f64, i8)>,
    /// AC's accelerations (one 0 with no AC).
    pub ac_actions: Vec<f64>,
    /// J^EC per (row, col); NaN: not computed.
    pub ec: Vec<f64>,
    /// J^AC per (row, col); NaN: not computed.
    pub ac: Vec<f64>,
    /// Rows pruned whole (`PayoffTable::pruned`).
    pub pruned: Vec<bool>,
    /// The equilibrium's row.
    pub row: usize,
    /// Its column.
    pub col: usize,
    /// False for a Nash game without a pure equilibrium (`SideGame::nash`).
    pub exact: bool,
    /// J^EC there.
    pub cost: f64,
}

impl SideGame {
    fn explained(self, side: i8, profile: Profile, cost: f64) -> SideExplained {
        let PayoffTable { rows, ec, ac, mut pruned, .. } = self.table;
        pruned.resize(rows, false);
        SideExplained {
            side,
            ec_actions: self.ec_actions,
            ac_actions: self.ac_actions,
            ec,
            ac,
            pruned,
            row: profile.row,
            col: profile.col,
            exact: profile.exact,
            cost,
        }
    }
}

/// Up to `LANES` of AC's columns against one lane-change row: their predicted paths,
/// their weighted efficiency per sample and their weighted comfort.
struct LaneChangeColumns<'a> {
    paths: [&'a [Kinematics]; LANES],
    efficiency: [&'a [f64]; LANES],
    comfort: [f64; LANES],
}

/// `Situation::ac_entry` for a lane-change row and `LANES` columns at once: eq. (12)'s
/// lateral term as `costs::lateral_safety` computes it, lane by lane, plus comfort and
/// efficiency, averaged over the samples. Compiled for AVX-512, AVX2 and SSE4.1 and
/// picked at run time, as the world step's block is (`dynamics::Fleet`): the same
/// operations in the same order in every lane and at every width (`Lanes`), so the same
/// bits as one cell at a time (the differential test compares the two).
/// `constants`: the car's length, kappa_s,lat, epsilon, kappa_v,lat, the safety weight.
#[multiversion::multiversion(targets("x86_64+avx512f+avx512vl+avx512dq", "x86_64+avx2+avx", "x86_64+sse4.1"))]
fn lane_change_entries(ec_path: &[Kinematics], columns: &LaneChangeColumns, constants: [f64; 5]) -> [f64; LANES] {
    lane_change_entries_in(ec_path, columns, constants)
}

/// `lane_change_entries` for whichever instruction set its caller was compiled for.
#[inline(always)]
fn lane_change_entries_in(ec_path: &[Kinematics], columns: &LaneChangeColumns, constants: [f64; 5]) -> [f64; LANES] {
    use crate::dynamics::{Lanes, mask};
    let [car_length, kappa_s_lat, epsilon, kappa_v_lat, safety_weight] = constants;
    let splat = Lanes::<LANES>::splat;
    let (zero, one) = (splat(0.0), splat(1.0));
    let comfort = Lanes(columns.comfort);
    let mut sum = zero;
    for (k, ego) in ec_path.iter().enumerate() {
        let at = |field: fn(&Kinematics) -> f64| Lanes::gather(|i| field(&columns.paths[i][k]));
        let (s, d, speed) = (at(|a| a.s), at(|a| a.d), at(|a| a.speed));
        let ego_front = mask(|i| ego.s >= s.0[i]);
        let dv = Lanes::select(ego_front, splat(ego.speed) - speed, speed - splat(ego.speed));
        let lambda = Lanes::select(dv.lt(zero), one, zero);
        let (ds, dd) = (splat(ego.s) - s, splat(ego.d) - d);
        let separation = (ds * ds + dd * dd).map(f64::sqrt) - splat(car_length);
        let gap = separation.max(zero);
        let proximity = splat(kappa_s_lat) / (gap * gap + splat(epsilon)) * (one + (-separation).max(zero));
        let lateral = splat(kappa_v_lat) * lambda * dv * dv + proximity;
        let efficiency = Lanes::gather(|i| columns.efficiency[i][k]);
        sum = sum + (splat(safety_weight) * lateral + comfort + efficiency);
    }
    (sum / splat(ec_path.len().max(1) as f64)).0
}

#[cfg(test)]
mod lane_change_entries_tests {
    use super::*;

    /// A small xorshift: the same paths on every run.
    fn draws(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// The car's length and the safety weight the test's cells use.
    const CAR_LENGTH: f64 = 4.8;
    const SAFETY_WEIGHT: f64 = 1.7;

    /// One cell as `costs::lateral_safety` and the scalar sum compute it.
    fn one_cell(ec_path: &[Kinematics], ac: &[Kinematics], efficiency: &[f64], comfort: f64, c: &CostParams) -> f64 {
        let (car_length, weight) = (CAR_LENGTH, SAFETY_WEIGHT);
        let mut sum = 0.0;
        for (k, &ego) in ec_path.iter().enumerate() {
            sum += weight * costs::lateral_safety(c, car_length, ego, ac[k]) + comfort + efficiency[k];
        }
        sum / ec_path.len() as f64
    }

    #[test]
    fn every_instruction_set_gives_each_cell_the_bits_of_the_cell_alone() {
        let c = CostParams::default();
        let constants = [CAR_LENGTH, c.kappa_s_lat, c.epsilon, c.kappa_v_lat, SAFETY_WEIGHT];
        let mut next = draws(0x5eed_cafe);
        let path = |n: usize, next: &mut dyn FnMut() -> f64| -> Vec<Kinematics> {
            let (s0, d0) = (100.0 * next(), -12.0 * next());
            (0..n)
                .map(|k| Kinematics { s: s0 + k as f64 * (2.0 + next()), d: d0 + next(), speed: 35.0 * next() })
                .collect()
        };
        let mut checked = 0;
        for n in [1, 5, 26] {
            for _ in 0..200 {
                let ec = path(n, &mut next);
                let ac: Vec<Vec<Kinematics>> = (0..LANES).map(|_| path(n, &mut next)).collect();
                let efficiency: Vec<Vec<f64>> = (0..LANES).map(|_| (0..n).map(|_| 3.0 * next()).collect()).collect();
                let comfort: [f64; LANES] = std::array::from_fn(|_| next());
                let columns = LaneChangeColumns {
                    paths: std::array::from_fn(|i| ac[i].as_slice()),
                    efficiency: std::array::from_fn(|i| efficiency[i].as_slice()),
                    comfort,
                };
                let expected: Vec<u64> =
                    (0..LANES).map(|i| one_cell(&ec, &ac[i], &efficiency[i], comfort[i], &c).to_bits()).collect();
                for (name, got) in with_each_instruction_set(&ec, &columns, constants) {
                    assert_eq!(got.map(f64::to_bits).to_vec(), expected, "{name}, {n} samples");
                    checked += 1;
                }
            }
        }
        assert!(checked >= 600, "{checked}");
    }

    /// The cells compiled for each instruction set this machine has, and dispatched.
    fn with_each_instruction_set(
        ec: &[Kinematics],
        columns: &LaneChangeColumns,
        constants: [f64; 5],
    ) -> Vec<(&'static str, [f64; LANES])> {
        let mut out = vec![
            ("baseline", lane_change_entries_in(ec, columns, constants)),
            ("dispatched", lane_change_entries(ec, columns, constants)),
        ];
        #[cfg(target_arch = "x86_64")]
        {
            #[target_feature(enable = "avx512f,avx512vl,avx512dq")]
            unsafe fn avx512(ec: &[Kinematics], columns: &LaneChangeColumns, constants: [f64; 5]) -> [f64; LANES] {
                lane_change_entries_in(ec, columns, constants)
            }
            #[target_feature(enable = "avx2,avx")]
            unsafe fn avx2(ec: &[Kinematics], columns: &LaneChangeColumns, constants: [f64; 5]) -> [f64; LANES] {
                lane_change_entries_in(ec, columns, constants)
            }
            if is_x86_feature_detected!("avx512f") && is_x86_feature_detected!("avx512vl") {
                // SAFETY: the features were detected on this machine.
                out.push(("avx512", unsafe { avx512(ec, columns, constants) }));
            }
            if is_x86_feature_detected!("avx2") {
                // SAFETY: as above.
                out.push(("avx2", unsafe { avx2(ec, columns, constants) }));
            }
        }
        out
    }
}
