//! The paper's test runs (§VI): Scenario A (merge) and B (overtake) with the ego car and
//! its adjacent cars driven by the `gt` AV, for a style and a game; the figures of
//! Tables IV–VII (t_c, gaps and speeds at t_c, RMS of the three costs) and the time
//! series of Figs. 8, 9, 12, 13. `arena paper` and the tests both run through here.
//!
//! ```
//! use arena_sim::Game;
//! use arena_sim::Style;
//! use arena_paper::{PaperOptions, PaperScenario, run};
//!
//! let options = PaperOptions { duration: Some(1.0), ..PaperOptions::default() };
//! let (record, trace) = run(PaperScenario::A, Style::Normal, Game::Nash, &options).unwrap();
//! assert_eq!(record.scenario, "A");
//! assert_eq!(trace.samples.len(), 10);
//! ```

pub mod calibrate;
pub mod compare;
pub mod report;

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use arena_sim::LaneChange;
use arena_sim::Preset;
use arena_sim::Stepper;
use arena_sim::Style;
use arena_sim::{BUILTIN_SCENARIOS, DriverSpec, Scenario, ScenarioError};
use arena_sim::{CostComponents, Game, GtParams, stage_cost};
use arena_sim::{Driver, Status, VehicleId, World};

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
#[derive(Debug, Clone, PartialEq)]
pub struct PaperOptions {
    /// The scenario file's text, if not the built-in one (a permuted copy, say).
    pub scenario_text: Option<String>,
    /// The constants of every `gt` car of the run (EC and its adjacent cars): the
    /// defaults, a preset's (`with_preset`) or a candidate of `arena calibrate`.
    pub params: GtParams,
    /// Per built-in scenario name ("merge", "overtake"), dotted-key overrides of the
    /// scenario file (a preset's adjacent-car target speeds, say).
    pub scenario_overrides: BTreeMap<String, Vec<(String, toml::Value)>>,
    /// Style of the adjacent cars (the paper does not say; normal).
    pub adjacent_style: Style,
    /// Simulated seconds, if not the scenario's own.
    pub duration: Option<f64>,
    /// World seed (the paper's scenarios have no random traffic; any seed gives the same run).
    pub seed: u64,
}

impl Default for PaperOptions {
    fn default() -> Self {
        PaperOptions {
            scenario_text: None,
            params: GtParams::default(),
            scenario_overrides: BTreeMap::new(),
            adjacent_style: Style::Normal,
            duration: None,
            seed: 0,
        }
    }
}

impl PaperOptions {
    /// The defaults with `preset`'s constants and scenario overrides.
    pub fn with_preset(preset: &Preset) -> PaperOptions {
        PaperOptions { params: preset.gt, scenario_overrides: preset.scenario.clone(), ..PaperOptions::default() }
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
    /// The lane change decided at t_c.
    pub lane_change: LaneChange,
    /// Whether any two cars collided or EC left the road.
    pub collision: bool,
    /// RMS over the run of EC's three cost components (`gt::stage_cost`).
    pub rms_cost: CostComponents,
    /// Decisions of the run's game-theoretic cars taken without a pure Nash equilibrium
    /// (they then keep their current lane decision).
    pub inexact_decisions: u32,
    /// Per game-theoretic car, by role: what its planning did over the run.
    pub diagnostics: BTreeMap<String, GtReport>,
}

/// What one game-theoretic car's planning did over a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GtReport {
    /// Control periods planned.
    pub plans: u32,
    /// Mean interior-point iterations of its MPC's QPs.
    pub mean_qp_iterations: f64,
    /// Plans that fell back to the safe command.
    pub fallbacks: u32,
    /// Decisions taken without a pure Nash equilibrium.
    pub inexact: u32,
    /// Commands that left the jerk bound because a lane change was aborted (exempt).
    pub abort_jumps: u32,
    /// Commands that left the jerk bound because a safety override braked (exempt).
    pub emergency_jumps: u32,
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
    /// EC's lane change decided at `t`.
    pub lane_change: LaneChange,
    /// EC's lateral offset (m).
    pub d: f64,
    /// EC's commanded acceleration for the period that starts at `t` (m/s^2).
    pub accel: f64,
    /// EC's stage cost at the end of the control period that starts at `t`.
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
    let mut overrides = vec![("vehicle.ec_0.driver".to_string(), toml::Value::Table(ec))];
    for (name, _) in &scenario.roles()[1..] {
        let mut ac = toml::Table::new();
        ac.insert("kind".into(), "gt".into());
        ac.insert("style".into(), options.adjacent_style.name().into());
        ac.insert("game".into(), game.name().into());
        ac.insert("role".into(), "follower".into());
        overrides.push((format!("vehicle.{name}.driver"), toml::Value::Table(ac)));
    }
    // A preset's own, last: they may set a field of the drivers above (an AC's style).
    overrides.extend(options.scenario_overrides.get(scenario.file()).cloned().unwrap_or_default());
    let (_, file, text) =
        BUILTIN_SCENARIOS.iter().find(|(name, ..)| *name == scenario.file()).copied().unwrap_or(BUILTIN_SCENARIOS[0]);
    let text = options.scenario_text.as_deref().unwrap_or(text);
    let mut parsed = Scenario::parse(file, text, &overrides)?;
    for vehicle in &mut parsed.vehicles {
        if let DriverSpec::Gt { params, .. } = &mut vehicle.driver {
            *params = options.params;
        }
    }
    Ok(parsed.build(options.seed))
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
    let substeps = world.params().substeps_per_control();
    let periods = (options.duration.unwrap_or(scenario.duration()) / world.params().control_dt).round() as usize;
    let mut samples = Vec::with_capacity(periods);
    let params = world.gt_params(ec);
    let mut stepper = Stepper::new();
    for _ in 0..periods {
        let (t, speeds, gaps, d) = observe(&world, &ids);
        stepper.tick(&mut world); // decides at t
        let lane_change = match &world.vehicle(ec).driver {
            Driver::Gt(gt) => gt.decision.lane_change,
            _ => LaneChange::Keep,
        };
        let accel = world.vehicle(ec).command.accel;
        for _ in 1..substeps {
            stepper.tick(&mut world);
        }
        // At the period's end, as the env samples its rewards: one definition of the RMS
        // for `arena paper` and `arena eval`.
        let cost = stage_cost(world.scene(), ec, &params);
        samples.push(Sample { t, speeds, gaps, lane_change, d, accel, cost });
    }
    let collision = !world.collisions().is_empty() || matches!(world.vehicle(ec).status, Status::OffRoad);
    let trace = Trace { roles: roles.iter().map(|(_, r)| r.to_string()).collect(), samples };
    let inexact = world
        .vehicles()
        .iter()
        .map(|v| match &v.driver {
            Driver::Gt(gt) => gt.diagnostics.inexact,
            _ => 0,
        })
        .sum();
    let mut record = summarise(scenario, style, game, &trace, collision, world.road().lane_width(), inexact);
    for ((_, role), &id) in roles.iter().zip(&ids) {
        if let Driver::Gt(gt) = &world.vehicle(id).driver {
            let d = &gt.diagnostics;
            let report = GtReport {
                plans: d.plans,
                mean_qp_iterations: d.iterations_total as f64 / f64::from(d.plans.max(1)),
                fallbacks: d.fallbacks,
                inexact: d.inexact,
                abort_jumps: d.abort_jumps,
                emergency_jumps: d.emergency_jumps,
            };
            record.diagnostics.insert(role.to_string(), report);
        }
    }
    (record, trace)
}

fn observe(world: &World, ids: &[VehicleId]) -> (f64, Vec<f64>, Vec<f64>, f64) {
    let ec = world.vehicle(ids[0]);
    let speeds = ids.iter().map(|&id| world.vehicle(id).state.lane_speed()).collect();
    let gaps = ids[1..].iter().map(|&id| ec.state.s - world.vehicle(id).state.s).collect();
    (world.time(), speeds, gaps, ec.state.d)
}

/// t_c (docs/design.md, "t_c"): the start of the last run of lane-change decisions (sigma != 0) that
/// lasts until EC's lane changed (its offset crossed half a lane) or the run ended.
pub fn decision_time(trace: &Trace, lane_width: f64) -> Option<usize> {
    let samples = &trace.samples;
    let start_d = samples.first()?.d;
    let crossed = samples.iter().position(|s| (s.d - start_d).abs() > lane_width / 2.0).unwrap_or(samples.len());
    let mut start = None;
    for (k, sample) in samples[..crossed].iter().enumerate() {
        start = match (sample.lane_change != LaneChange::Keep, start) {
            (true, None) => Some(k),
            (true, started) => started,
            (false, _) => None,
        };
    }
    start
}

fn rms(trace: &Trace) -> CostComponents {
    let n = trace.samples.len().max(1) as f64;
    let squares = trace.samples.iter().fold(CostComponents::default(), |acc, s| acc + s.cost.squared());
    CostComponents {
        safety: (squares.safety / n).sqrt(),
        comfort: (squares.comfort / n).sqrt(),
        efficiency: (squares.efficiency / n).sqrt(),
    }
}

fn summarise(
    scenario: PaperScenario,
    style: Style,
    game: Game,
    trace: &Trace,
    collision: bool,
    lane_width: f64,
    inexact_decisions: u32,
) -> Record {
    let at = decision_time(trace, lane_width);
    let (mut gaps, mut speeds) = (BTreeMap::new(), BTreeMap::new());
    let mut lane_change = LaneChange::Keep;
    if let Some(k) = at {
        let sample = &trace.samples[k];
        for (role, speed) in trace.roles.iter().zip(&sample.speeds) {
            speeds.insert(role.clone(), *speed);
        }
        for (role, gap) in trace.roles[1..].iter().zip(&sample.gaps) {
            gaps.insert(role.clone(), *gap);
        }
        lane_change = sample.lane_change;
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
        inexact_decisions,
        diagnostics: BTreeMap::new(),
    }
}

/// The paper's figures for one run, for printing side by side.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// t_c (s), none for "-".
    pub t_c: Option<f64>,
    /// Gaps at t_c (m) by role.
    pub gaps: BTreeMap<String, f64>,
    /// Speeds at t_c (m/s) by role.
    pub speeds: BTreeMap<String, f64>,
    /// RMS safety, comfort, efficiency as printed (Table V: x 10^5; Table VII: x 10^4).
    pub rms: [f64; 3],
}

/// One scenario's published tables, as `published.toml` holds them.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PublishedTable {
    t_c: Vec<f64>,
    gaps: BTreeMap<String, Vec<f64>>,
    speeds: BTreeMap<String, Vec<f64>>,
    #[allow(dead_code)] // documents the printed scale; the values are compared as printed
    rms_scale: f64,
    safety: Vec<f64>,
    comfort: Vec<f64>,
    efficiency: Vec<f64>,
}

/// Tables IV–VII of the paper, from `published.toml`.
#[derive(Debug, Deserialize)]
#[allow(non_snake_case)]
struct Published {
    A: PublishedTable,
    B: PublishedTable,
}

const PUBLISHED: &str = include_str!("../published.toml");

/// Tables IV–VII: the paper's figures for one run.
pub fn reference(scenario: PaperScenario, style: Style, game: Game) -> Reference {
    // The file is compiled in and checked by a test, so a parse error is a build defect.
    let published: Published = toml::from_str(PUBLISHED).expect("server/paper/published.toml is valid");
    let table = match scenario {
        PaperScenario::A => published.A,
        PaperScenario::B => published.B,
    };
    let column = match style {
        Style::Aggressive => 0,
        Style::Normal => 1,
        Style::Conservative => 2,
    } * 2
        + usize::from(game == Game::Stackelberg);
    let at = |values: &BTreeMap<String, Vec<f64>>| {
        values.iter().filter_map(|(role, v)| Some((role.clone(), *v.get(column)?))).collect::<BTreeMap<_, _>>()
    };
    Reference {
        t_c: table.t_c.get(column).copied(),
        gaps: at(&table.gaps),
        speeds: at(&table.speeds),
        rms: [table.safety[column], table.comfort[column], table.efficiency[column]],
    }
}
