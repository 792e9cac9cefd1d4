//! The paper's test runs (§VI): Scenario A (merge) and B (overtake) with the ego car and
//! its adjacent cars driven by the `gt` AV, for a style and a game; the figures of
//! Tables IV–VII (t_c, gaps and speeds at t_c, RMS of the three costs) and the time
//! series of Figs. 8, 9, 12, 13. `arena paper` and the tests both run through here.
//!
//! ```
//! use arena_server::av::Game;
//! use arena_server::dynamics::Style;
//! use arena_server::paper::{PaperOptions, PaperScenario, run};
//!
//! let options = PaperOptions { duration: Some(1.0), ..PaperOptions::default() };
//! let (record, trace) = run(PaperScenario::A, Style::Normal, Game::Nash, &options).unwrap();
//! assert_eq!(record.scenario, "A");
//! assert_eq!(trace.samples.len(), 10);
//! ```

use std::collections::BTreeMap;

use serde::Serialize;

use crate::av::{CostComponents, Game, stage_cost};
use crate::dynamics::Style;
use crate::scenario::{BUILTIN, Scenario, ScenarioError};
use crate::world::{Driver, Status, VehicleId, World};

/// One of the paper's two scenarios.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub enum PaperScenario {
    /// §VI-A, merging from an ending lane (scenarios/merge.toml).
    A,
    /// §VI-B, overtaking on a curve (scenarios/overtake.toml).
    B,
}

impl PaperScenario {
    /// Both, in the paper's order.
    pub const ALL: [PaperScenario; 2] = [PaperScenario::A, PaperScenario::B];

    /// "A" or "B".
    pub fn name(self) -> &'static str {
        match self {
            PaperScenario::A => "A",
            PaperScenario::B => "B",
        }
    }

    /// The built-in scenario file.
    pub fn file(self) -> &'static str {
        match self {
            PaperScenario::A => "merge",
            PaperScenario::B => "overtake",
        }
    }

    /// (scenario vehicle name, the paper's role) of EC and its adjacent cars, EC first.
    pub fn roles(self) -> &'static [(&'static str, &'static str)] {
        match self {
            PaperScenario::A => &[("ec_0", "EC"), ("ac", "AC")],
            PaperScenario::B => &[("ec_0", "EC"), ("ac1", "AC1"), ("ac2", "AC2")],
        }
    }

    /// Simulated seconds per run: past the conservative style's merge in A (about 7 s in
    /// the paper, plus the 4 s change), and the paper's figure span in B.
    pub fn duration(self) -> f64 {
        match self {
            PaperScenario::A => 16.0,
            PaperScenario::B => 10.0,
        }
    }
}

/// Options of a paper run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaperOptions {
    /// Relative tolerance on the Stackelberg follower set (eq. 17b); 0 is the paper's.
    pub follower_tolerance: f64,
    /// Style of the adjacent cars (the paper does not say; normal).
    pub adjacent_style: Style,
    /// Simulated seconds, if not the scenario's own.
    pub duration: Option<f64>,
    /// World seed (the paper's scenarios have no random traffic; any seed gives the same run).
    pub seed: u64,
}

impl Default for PaperOptions {
    fn default() -> Self {
        PaperOptions { follower_tolerance: 0.0, adjacent_style: Style::Normal, duration: None, seed: 0 }
    }
}

/// The figures of Tables IV–VII for one run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Record {
    /// "A" or "B".
    pub scenario: String,
    /// "aggressive", "normal" or "conservative".
    pub style: String,
    /// "nash" or "stackelberg".
    pub game: String,
    /// Time (s) at which EC's decision became a lane change and stayed one; none if it
    /// never changed lanes.
    pub t_c: Option<f64>,
    /// s_EC - s_other (m, centre to centre) at t_c, by the other car's role.
    pub gaps_at_t_c: BTreeMap<String, f64>,
    /// Speeds (m/s) at t_c, by role.
    pub speeds_at_t_c: BTreeMap<String, f64>,
    /// The lane change decided at t_c: -1 left, 1 right, 0 none.
    pub lane_change: i8,
    /// Whether any two cars collided or EC left the road.
    pub collision: bool,
    /// RMS over the run of EC's three cost components (`av::stage_cost`).
    pub rms_cost: CostComponents,
}

/// The state of the run at one control instant.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Sample {
    /// Simulated time (s).
    pub t: f64,
    /// Speed of each role (m/s), in `Trace::roles` order.
    pub speeds: Vec<f64>,
    /// s_EC - s_other (m) for each role after EC.
    pub gaps: Vec<f64>,
    /// EC's decision made at `t`.
    pub sigma: i8,
    /// EC's lateral offset (m).
    pub d: f64,
    /// EC's stage cost right after deciding.
    pub cost: CostComponents,
}

/// The time series of a run (Figs. 8, 9, 12, 13).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Trace {
    /// Role names, EC first.
    pub roles: Vec<String>,
    /// One per control period.
    pub samples: Vec<Sample>,
}

/// The world of `scenario` with EC a `gt` leader of `style` and its adjacent cars `gt`
/// followers, all playing `game`.
pub fn world(
    scenario: PaperScenario,
    style: Style,
    game: Game,
    options: &PaperOptions,
) -> Result<World, ScenarioError> {
    let mut ec = toml::Table::new();
    ec.insert("kind".into(), "gt".into());
    ec.insert("style".into(), style.name().into());
    ec.insert("game".into(), game.name().into());
    ec.insert("follower_tolerance".into(), options.follower_tolerance.into());
    let mut overrides = vec![("vehicle.ec_0.driver".to_string(), toml::Value::Table(ec))];
    for (name, _) in &scenario.roles()[1..] {
        let mut ac = toml::Table::new();
        ac.insert("kind".into(), "gt".into());
        ac.insert("style".into(), options.adjacent_style.name().into());
        ac.insert("game".into(), game.name().into());
        ac.insert("role".into(), "follower".into());
        overrides.push((format!("vehicle.{name}.driver"), toml::Value::Table(ac)));
    }
    let (_, file, text) = BUILTIN.iter().find(|(name, ..)| *name == scenario.file()).copied().unwrap_or(BUILTIN[0]);
    Ok(Scenario::parse(file, text, &overrides)?.build(options.seed))
}

/// Runs one scenario × style × game and returns its record and time series.
pub fn run(
    scenario: PaperScenario,
    style: Style,
    game: Game,
    options: &PaperOptions,
) -> Result<(Record, Trace), ScenarioError> {
    let world = world(scenario, style, game, options)?;
    Ok(run_world(scenario, style, game, world, options))
}

/// Runs a world built by [`world`] (perhaps with its drivers' constants changed).
pub fn run_world(
    scenario: PaperScenario,
    style: Style,
    game: Game,
    mut world: World,
    options: &PaperOptions,
) -> (Record, Trace) {
    let roles = scenario.roles();
    let ids: Vec<VehicleId> = roles.iter().filter_map(|(name, _)| world.find(name)).collect();
    let ec = ids[0];
    let substeps = world.params.substeps_per_control();
    let periods = (options.duration.unwrap_or(scenario.duration()) / world.params.control_dt).round() as usize;
    let mut samples = Vec::with_capacity(periods);
    for _ in 0..periods {
        let (t, speeds, gaps, d) = observe(&world, &ids);
        world.tick(); // decides at t
        let sigma = match &world.vehicle(ec).driver {
            Driver::Gt(gt) => gt.decision.sigma,
            _ => 0,
        };
        let cost = stage_cost(&world, ec);
        for _ in 1..substeps {
            world.tick();
        }
        samples.push(Sample { t, speeds, gaps, sigma, d, cost });
    }
    let collision = !world.collisions.is_empty() || matches!(world.vehicle(ec).status, Status::OffRoad);
    let trace = Trace { roles: roles.iter().map(|(_, r)| r.to_string()).collect(), samples };
    let record = summarise(scenario, style, game, &trace, collision);
    (record, trace)
}

fn observe(world: &World, ids: &[VehicleId]) -> (f64, Vec<f64>, Vec<f64>, f64) {
    let ec = world.vehicle(ids[0]);
    let speeds = ids.iter().map(|&id| world.vehicle(id).state.lane_speed()).collect();
    let gaps = ids[1..].iter().map(|&id| ec.state.s - world.vehicle(id).state.s).collect();
    (world.time, speeds, gaps, ec.state.d)
}

/// t_c (DESIGN.md): the start of the last run of lane-change decisions (sigma != 0) that
/// lasts until EC's lane changed (its offset crossed half a lane) or the run ended.
pub fn decision_time(trace: &Trace, lane_width: f64) -> Option<usize> {
    let samples = &trace.samples;
    let start_d = samples.first()?.d;
    let crossed = samples.iter().position(|s| (s.d - start_d).abs() > lane_width / 2.0).unwrap_or(samples.len());
    let mut start = None;
    for (k, sample) in samples[..crossed].iter().enumerate() {
        start = match (sample.sigma != 0, start) {
            (true, None) => Some(k),
            (true, started) => started,
            (false, _) => None,
        };
    }
    start
}

fn rms(trace: &Trace) -> CostComponents {
    let n = trace.samples.len().max(1) as f64;
    let squares = trace.samples.iter().fold(CostComponents::default(), |acc, s| {
        acc + CostComponents {
            safety: s.cost.safety * s.cost.safety,
            comfort: s.cost.comfort * s.cost.comfort,
            efficiency: s.cost.efficiency * s.cost.efficiency,
        }
    });
    CostComponents {
        safety: (squares.safety / n).sqrt(),
        comfort: (squares.comfort / n).sqrt(),
        efficiency: (squares.efficiency / n).sqrt(),
    }
}

fn summarise(scenario: PaperScenario, style: Style, game: Game, trace: &Trace, collision: bool) -> Record {
    let lane_width = 4.0;
    let at = decision_time(trace, lane_width);
    let (mut gaps, mut speeds) = (BTreeMap::new(), BTreeMap::new());
    let mut lane_change = 0;
    if let Some(k) = at {
        let sample = &trace.samples[k];
        for (role, speed) in trace.roles.iter().zip(&sample.speeds) {
            speeds.insert(role.clone(), *speed);
        }
        for (role, gap) in trace.roles[1..].iter().zip(&sample.gaps) {
            gaps.insert(role.clone(), *gap);
        }
        lane_change = sample.sigma;
    }
    Record {
        scenario: scenario.name().to_string(),
        style: style.name().to_string(),
        game: game.name().to_string(),
        t_c: at.map(|k| trace.samples[k].t),
        gaps_at_t_c: gaps,
        speeds_at_t_c: speeds,
        lane_change,
        collision,
        rms_cost: rms(trace),
    }
}

/// The paper's figures for one run, for printing side by side.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// t_c (s), none for "-".
    pub t_c: Option<f64>,
    /// Gaps at t_c (m) by role.
    pub gaps: Vec<(&'static str, f64)>,
    /// Speeds at t_c (m/s) by role.
    pub speeds: Vec<(&'static str, f64)>,
    /// RMS safety, comfort, efficiency as printed (Table V: × 10^5; Table VII: × 10^4).
    pub rms: [f64; 3],
}

/// Tables IV–VII.
pub fn reference(scenario: PaperScenario, style: Style, game: Game) -> Reference {
    let column = match style {
        Style::Aggressive => 0,
        Style::Normal => 1,
        Style::Conservative => 2,
    } * 2
        + usize::from(game == Game::Stackelberg);
    match scenario {
        PaperScenario::A => {
            const T_C: [f64; 6] = [2.24, 2.72, 5.04, 5.36, 7.00, 7.18];
            const GAP: [f64; 6] = [13.77, 16.46, 18.06, 18.86, -1.37, -1.99];
            const V_EC: [f64; 6] = [24.15, 24.83, 23.25, 23.40, 17.03, 11.07];
            const V_AC: [f64; 6] = [18.66, 19.17, 20.76, 20.91, 21.49, 21.52];
            const SAFETY: [f64; 6] = [776.0, 428.0, 153.0, 119.0, 63.0, 50.0];
            const COMFORT: [f64; 6] = [365.0, 231.0, 183.0, 147.0, 105.0, 104.0];
            const EFFICIENCY: [f64; 6] = [114.0, 79.0, 275.0, 215.0, 394.0, 329.0];
            Reference {
                t_c: Some(T_C[column]),
                gaps: vec![("AC", GAP[column])],
                speeds: vec![("EC", V_EC[column]), ("AC", V_AC[column])],
                rms: [SAFETY[column], COMFORT[column], EFFICIENCY[column]],
            }
        }
        PaperScenario::B => {
            const T_C: [f64; 4] = [2.98, 3.44, 3.90, 4.20];
            const GAP1: [f64; 4] = [28.66, 33.32, 25.53, 26.20];
            const GAP2: [f64; 4] = [26.22, 31.21, 22.55, 24.06];
            const V_EC: [f64; 4] = [27.03, 27.22, 23.43, 23.44];
            const V_AC1: [f64; 4] = [16.96, 17.22, 20.11, 20.31];
            const V_AC2: [f64; 4] = [16.23, 16.52, 19.82, 20.04];
            const SAFETY: [f64; 6] = [289.0, 192.0, 152.0, 105.0, 36.0, 31.0];
            const COMFORT: [f64; 6] = [280.0, 269.0, 191.0, 142.0, 61.0, 53.0];
            const EFFICIENCY: [f64; 6] = [119.0, 107.0, 279.0, 205.0, 371.0, 344.0];
            let rms = [SAFETY[column], COMFORT[column], EFFICIENCY[column]];
            if column >= 4 {
                return Reference { t_c: None, gaps: vec![], speeds: vec![], rms };
            }
            Reference {
                t_c: Some(T_C[column]),
                gaps: vec![("AC1", GAP1[column]), ("AC2", GAP2[column])],
                speeds: vec![("EC", V_EC[column]), ("AC1", V_AC1[column]), ("AC2", V_AC2[column])],
                rms,
            }
        }
    }
}
