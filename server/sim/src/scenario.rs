//! Scenario files: TOML as written by people (`ScenarioFile`, parsed with serde and
//! unknown keys refused), validated into a `Scenario` that can build a fresh `World` for
//! any seed. Every refusal names the file, the vehicle or key, and what is wrong.

use std::fmt;
use std::path::Path;

use rand::{Rng, RngExt};
use serde::Deserialize;

use crate::dynamics::{LateralPath, Style, VehicleParams};
use crate::gt::{Game, GtDriver, GtParams};
use crate::road::{LaneId, Pose, Road, Section};
use crate::scene::Role;
use crate::world::{AgentCommand, Driver, Vehicle, World, WorldParams};

/// Occurs when a scenario cannot be loaded; `file` names it.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenarioError {
    /// The file (or inline name) the scenario came from.
    pub file: String,
    /// What is wrong.
    pub kind: ScenarioErrorKind,
}

/// The ways a scenario can be wrong.
#[derive(Debug, Clone, PartialEq)]
pub enum ScenarioErrorKind {
    /// Occurs when the file cannot be read.
    Io(String),
    /// Occurs when the TOML is malformed, a key is unknown or a field missing; the
    /// message is the parser's, with line and column.
    Syntax(String),
    /// Occurs when a vehicle is placed on a lane the road does not have.
    UnknownLane {
        /// The vehicle's name.
        vehicle: String,
        /// The lane it names.
        lane: i64,
        /// How many lanes the road has.
        lanes: usize,
    },
    /// Occurs when a vehicle starts off the paved road (past its lane's end, say).
    OffRoad {
        /// The vehicle's name.
        vehicle: String,
        /// Where it is and why that is off the road.
        detail: String,
    },
    /// Occurs when two vehicles start overlapping.
    Overlap {
        /// One vehicle's name.
        first: String,
        /// The other's.
        second: String,
    },
    /// Occurs when two vehicles share a name.
    DuplicateName(String),
    /// Occurs when a value is out of its range; `key` is its dotted path.
    Invalid {
        /// Dotted path of the value.
        key: String,
        /// What is wrong with it.
        message: String,
    },
    /// Occurs when tables and arrays nest deeper than `MAX_DEPTH` (text or overrides).
    TooDeep {
        /// How deep they nest, as far as counted (`MAX_DEPTH` + 1 at most).
        depth: usize,
    },
    /// Occurs when an override names a key that cannot be set.
    BadOverride {
        /// The override's dotted key.
        key: String,
        /// Why it cannot be applied.
        message: String,
    },
}

impl fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "invalid scenario '{}': ", self.file)?;
        match &self.kind {
            ScenarioErrorKind::Io(message) => write!(f, "cannot read it: {message}"),
            ScenarioErrorKind::Syntax(message) => write!(f, "{}", message.trim_end()),
            ScenarioErrorKind::UnknownLane { vehicle, lane, lanes } => {
                write!(f, "vehicle '{vehicle}' is on lane {lane}, but the road has lanes 0..={}", lanes - 1)
            }
            ScenarioErrorKind::OffRoad { vehicle, detail } => {
                write!(f, "vehicle '{vehicle}' starts off the road: {detail}")
            }
            ScenarioErrorKind::Overlap { first, second } => {
                write!(f, "vehicles '{first}' and '{second}' overlap at the start; move one of them")
            }
            ScenarioErrorKind::DuplicateName(name) => {
                write!(f, "two vehicles are named '{name}'; names must be unique")
            }
            ScenarioErrorKind::Invalid { key, message } => write!(f, "`{key}` {message}"),
            ScenarioErrorKind::BadOverride { key, message } => write!(f, "override `{key}`: {message}"),
            ScenarioErrorKind::TooDeep { depth } => {
                write!(f, "tables and arrays nest {depth} deep; a scenario nests at most {MAX_DEPTH}")
            }
        }
    }
}

impl std::error::Error for ScenarioError {}

/// How deep a scenario's tables and arrays may nest, its text and overrides together (the
/// shipped files nest 3 deep). Parsing, validating and dropping a TOML value recurse on
/// its depth, and a scenario can come from a client.
pub const MAX_DEPTH: usize = 16;

/// The scenario files shipped in `scenarios/`, compiled in so the server needs no
/// files beside it: (name, file name, text).
pub const BUILTIN: [(&str, &str, &str); 7] = [
    ("merge", "merge.toml", include_str!("../../../scenarios/merge.toml")),
    ("overtake", "overtake.toml", include_str!("../../../scenarios/overtake.toml")),
    ("highway", "highway.toml", include_str!("../../../scenarios/highway.toml")),
    ("merge-ac", "merge-ac.toml", include_str!("../../../scenarios/merge-ac.toml")),
    ("highway-gt", "highway-gt.toml", include_str!("../../../scenarios/highway-gt.toml")),
    ("merge-random", "merge-random.toml", include_str!("../../../scenarios/merge-random.toml")),
    ("overtake-random", "overtake-random.toml", include_str!("../../../scenarios/overtake-random.toml")),
];

/// Loads a built-in scenario by name (`merge`, `overtake`, `highway`, ...).
pub fn builtin(name: &str) -> Option<Result<Scenario, ScenarioError>> {
    BUILTIN.iter().find(|(n, ..)| *n == name).map(|(_, file, text)| Scenario::parse(file, text, &[]))
}

/// The file as written.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct ScenarioFile {
    name: String,
    #[serde(default)]
    description: String,
    #[serde(default)]
    sim: SimFile,
    road: RoadFile,
    #[serde(default, rename = "vehicle")]
    vehicles: Vec<VehicleFile>,
    traffic: Option<TrafficFile>,
    #[serde(default)]
    reward: RewardFile,
    #[serde(default)]
    goal: GoalFile,
    #[serde(default)]
    vary: toml::Table,
}

#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct GoalFile {
    lanes: Vec<i64>,
    ahead_of: Vec<String>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RewardFile {
    cost_scale: f64,
    crash: Option<f64>,
}

impl Default for RewardFile {
    fn default() -> Self {
        RewardFile { cost_scale: RewardSpec::DEFAULT_COST_SCALE, crash: None }
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct SimFile {
    physics_dt: f64,
    control_dt: f64,
    step_dt: f64,
    max_cycles: u32,
}

impl Default for SimFile {
    fn default() -> Self {
        let world = WorldParams::default();
        SimFile { physics_dt: world.physics_dt, control_dt: world.control_dt, step_dt: 0.1, max_cycles: 200 }
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RoadFile {
    lanes: i64,
    #[serde(default = "default_lane_width")]
    lane_width: f64,
    speed_limits: Vec<f64>,
    #[serde(default)]
    origin: OriginFile,
    sections: Vec<SectionFile>,
    #[serde(default)]
    lane_ends: Vec<LaneEndFile>,
}

fn default_lane_width() -> f64 {
    4.0
}

#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct OriginFile {
    x: f64,
    y: f64,
    heading: f64,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct SectionFile {
    length: f64,
    /// Signed radius (m), positive bends left; absent for a straight section.
    radius: Option<f64>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct LaneEndFile {
    lane: i64,
    s: f64,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct VehicleFile {
    name: String,
    lane: Option<i64>,
    s: Option<f64>,
    x: Option<f64>,
    y: Option<f64>,
    speed: f64,
    target_speed: Option<f64>,
    driver: DriverFile,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
enum DriverFile {
    Agent {
        #[serde(default = "default_style")]
        style: Style,
        #[serde(default)]
        action: ActionKind,
    },
    Idm {
        #[serde(default = "default_style")]
        style: Style,
    },
    Gt {
        #[serde(default = "default_style")]
        style: Style,
        game: Game,
        #[serde(default)]
        role: Role,
        /// Overrides the preset's (or the default) follower-set tolerance.
        follower_tolerance: Option<f64>,
        /// A parameter preset (`crate::preset`): a built-in name or a .toml file.
        params: Option<String>,
    },
}

fn default_style() -> Style {
    Style::Normal
}

/// How a learner drives its vehicle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ActionKind {
    /// Discrete 5: lane left, idle, lane right, faster, slower.
    #[default]
    Meta,
    /// Acceleration and lateral preview target.
    Continuous,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct TrafficFile {
    count: u32,
    #[serde(default = "default_density")]
    density: f64,
    speed: [f64; 2],
    lanes: Option<Vec<i64>>,
    #[serde(default = "default_style")]
    style: Style,
    gt: Option<GtTrafficFile>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct GtTrafficFile {
    count: u32,
    game: Game,
    #[serde(default = "default_style")]
    style: Style,
    #[serde(default)]
    role: Role,
}

fn default_density() -> f64 {
    1.0
}

/// A named vehicle, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleSpec {
    /// Unique name.
    pub name: String,
    /// Lane it starts in.
    pub lane: LaneId,
    /// Start position along the road (m).
    pub s: f64,
    /// Start offset (m).
    pub d: f64,
    /// Start speed (m/s).
    pub speed: f64,
    /// Speed its driver aims for (m/s).
    pub target_speed: f64,
    /// Driving style.
    pub style: Style,
    /// Who drives it.
    pub driver: DriverSpec,
}

/// Who drives a named vehicle.
#[derive(Debug, Clone, Copy, PartialEq)]
// A spec is built once per scenario and copied into a driver: the size of the `Gt`
// variant (its constants, by value so the spec stays plain `Copy` data) costs nothing.
#[allow(clippy::large_enum_variant)]
pub enum DriverSpec {
    /// A learner, through the env.
    Agent(ActionKind),
    /// IDM + MOBIL.
    Idm,
    /// The game-theoretic AV of `gt`.
    Gt {
        /// Nash or Stackelberg.
        game: Game,
        /// Leader (the paper's EC) or follower (its AC).
        role: Role,
        /// Its constants: the defaults, or the preset its `params` names, with its
        /// `follower_tolerance` (eq. 17b) if given.
        params: GtParams,
    },
}

/// Random IDM traffic placed like highway-env's `Vehicle.create_random`.
#[derive(Debug, Clone, PartialEq)]
pub struct TrafficSpec {
    /// How many vehicles.
    pub count: u32,
    /// highway-env's `vehicles_density`.
    pub density: f64,
    /// Initial speed range (m/s); each car's target speed is its initial speed.
    pub speed: [f64; 2],
    /// Lanes to place cars in.
    pub lanes: Vec<LaneId>,
    /// Style of their steering.
    pub style: Style,
    /// How many of them the game-theoretic AV drives, spread evenly through the traffic
    /// (every `count / gt.count`-th car), and how.
    pub gt: Option<GtTraffic>,
}

/// The game-theoretic cars among random traffic.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GtTraffic {
    /// How many.
    pub count: u32,
    /// Nash or Stackelberg.
    pub game: Game,
    /// Their style.
    pub style: Style,
    /// Leader or follower.
    pub role: Role,
}

/// How the env turns the paper's cost J into a reward (docs/rewards.md).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RewardSpec {
    /// J_0 of r = J_0 / (J_0 + J): the cost at which a step earns half the most.
    pub cost_scale: f64,
    /// The reward of the step an agent crashes or leaves the road; `None`: minus the
    /// episode length in steps, below any episode without a crash.
    pub crash: Option<f64>,
}

impl RewardSpec {
    /// J_0 by default: what the normal style pays in efficiency alone 11 m/s off its
    /// target speed (0.2 x 11.2^2); calm driving costs a few units and earns about 0.8
    /// (docs/rewards.md).
    pub const DEFAULT_COST_SCALE: f64 = 25.0;
}

/// What a learner's episode must achieve to count as a success (`arena eval`, the
/// `episode_success` info): end without a crash, off the road or past its lane's end, and
/// then in one of `lanes` (if any are given) ahead of every vehicle of `ahead_of`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Goal {
    /// Lanes the learner must end in; empty: any.
    pub lanes: Vec<LaneId>,
    /// Vehicles the learner must end ahead of (greater s).
    pub ahead_of: Vec<String>,
}

/// One value a scenario draws afresh for each episode.
#[derive(Debug, Clone, PartialEq)]
pub enum Variation {
    /// Uniform between two numbers.
    Range(f64, f64),
    /// One of these values, each equally likely.
    Choose(Vec<toml::Value>),
}

/// A validated scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// Short name (`merge`).
    pub name: String,
    /// One line on what it is.
    pub description: String,
    /// The road.
    pub road: Road,
    /// Physics and control timing.
    pub world: WorldParams,
    /// Simulated seconds per env step.
    pub step_dt: f64,
    /// Env steps per episode before truncation.
    pub max_cycles: u32,
    /// Named vehicles in file order.
    pub vehicles: Vec<VehicleSpec>,
    /// Random background traffic, if any.
    pub traffic: Option<TrafficSpec>,
    /// The reward's constants.
    pub reward: RewardSpec,
    /// What counts as a learner's success.
    pub goal: Goal,
    /// Values drawn afresh for each episode, by dotted key (`[vary]`).
    pub vary: Vec<(String, Variation)>,
    /// Where it came from, to draw episodes: the file name, its text, its overrides.
    source: (String, String, Vec<(String, toml::Value)>),
}

/// Draws that may fail validation (two cars placed overlapping, say) are retried this
/// many times before the episode is refused.
const EPISODE_DRAWS: usize = 20;

impl Scenario {
    /// Reads and validates a scenario file.
    pub fn load(path: &Path) -> Result<Scenario, ScenarioError> {
        let file = path.file_name().map_or_else(|| path.display().to_string(), |f| f.to_string_lossy().into_owned());
        let text = std::fs::read_to_string(path)
            .map_err(|e| ScenarioError { file: file.clone(), kind: ScenarioErrorKind::Io(e.to_string()) })?;
        Scenario::parse(&file, &text, &[])
    }

    /// Parses and validates scenario text; `overrides` are (dotted key, TOML value)
    /// pairs applied before validation, so they are checked exactly as the file is.
    pub fn parse(file: &str, text: &str, overrides: &[(String, toml::Value)]) -> Result<Scenario, ScenarioError> {
        let fail = |kind| ScenarioError { file: file.to_string(), kind };
        let mut table: toml::Table =
            text.parse().map_err(|e: toml::de::Error| fail(ScenarioErrorKind::Syntax(e.to_string())))?;
        for (key, value) in overrides {
            apply_override(&mut table, key, value.clone()).map_err(&fail)?;
        }
        let depth = nesting(&table);
        if depth > MAX_DEPTH {
            return Err(fail(ScenarioErrorKind::TooDeep { depth }));
        }
        let raw: ScenarioFile = if overrides.is_empty() {
            toml::from_str(text)
        } else {
            ScenarioFile::deserialize(toml::Value::Table(table))
        }
        .map_err(|e: toml::de::Error| fail(ScenarioErrorKind::Syntax(e.to_string())))?;
        let mut scenario = raw.validate().map_err(fail)?;
        scenario.source = (file.to_string(), text.to_string(), overrides.to_vec());
        Ok(scenario)
    }

    /// The scenario of one episode: its `[vary]` values drawn from `rng`, then `extra`
    /// overrides applied (the reset's own). With neither, the scenario itself.
    pub fn episode(&self, rng: &mut impl Rng, extra: &[(String, toml::Value)]) -> Result<Scenario, ScenarioError> {
        if self.vary.is_empty() && extra.is_empty() {
            return Ok(self.clone());
        }
        let (file, text, overrides) = &self.source;
        // Only drawn values can be drawn again: with nothing to vary, one attempt.
        let attempts = if self.vary.is_empty() { 1 } else { EPISODE_DRAWS };
        let mut attempt = 1;
        loop {
            let mut all = overrides.clone();
            all.extend(self.vary.iter().map(|(key, variation)| (key.clone(), variation.draw(rng))));
            all.extend(extra.iter().cloned());
            match Scenario::parse(file, text, &all) {
                Err(error)
                    if attempt < attempts
                        && matches!(
                            error.kind,
                            ScenarioErrorKind::Overlap { .. } | ScenarioErrorKind::OffRoad { .. }
                        ) =>
                {
                    attempt += 1;
                }
                result => return result,
            }
        }
    }

    /// Builds the world at time zero; `seed` drives the random traffic. The named
    /// vehicles enter the world sorted by name, so nothing in it (ids, tie-breaks, the
    /// order of sums) depends on the order of `[[vehicle]]` blocks in the file.
    pub fn build(&self, seed: u64) -> World {
        let mut world = World::new(self.road.clone(), self.world, seed);
        let mut named: Vec<&VehicleSpec> = self.vehicles.iter().collect();
        named.sort_by(|a, b| a.name.cmp(&b.name));
        for spec in named {
            let driver = match spec.driver {
                DriverSpec::Agent(_) => Driver::Agent(AgentCommand::Track),
                DriverSpec::Idm => Driver::Idm,
                DriverSpec::Gt { game, role, params } => Driver::Gt(Box::new(GtDriver::new(game, role, params))),
            };
            let mut vehicle = Vehicle::new(&spec.name, &self.road, spec.lane, spec.s, spec.speed, spec.style, driver);
            vehicle.state.d = spec.d;
            vehicle.path = LateralPath::lane_change(spec.d, self.road.lane_center(spec.lane), 0.0);
            vehicle.target_speed = spec.target_speed;
            world.add(vehicle);
        }
        if let Some(traffic) = &self.traffic {
            place_traffic(&mut world, traffic);
        }
        world
    }

    /// The learner-driven vehicles, in file order: the env's `possible_agents`.
    pub fn agents(&self) -> impl Iterator<Item = &VehicleSpec> {
        self.vehicles.iter().filter(|v| matches!(v.driver, DriverSpec::Agent(_)))
    }
}

impl Variation {
    fn draw(&self, rng: &mut impl Rng) -> toml::Value {
        match self {
            Variation::Range(low, high) if low < high => toml::Value::Float(rng.random_range(*low..*high)),
            Variation::Range(low, _) => toml::Value::Float(*low),
            Variation::Choose(values) => values[rng.random_range(0..values.len())].clone(),
        }
    }
}

/// Whether car `k` of `count` is one of `gt` game-theoretic ones spread evenly.
fn is_gt_car(k: u32, count: u32, gt: u32) -> bool {
    let share = |k: u64| k * u64::from(gt) / u64::from(count.max(1));
    share(u64::from(k) + 1) > share(u64::from(k))
}

/// highway-env's `create_random`: each car goes ahead of the frontmost one by
/// `(12 + v) * exp(-5/40 * lanes) / density * U(0.9, 1.1)`, in a random lane.
fn place_traffic(world: &mut World, traffic: &TrafficSpec) {
    let lanes_factor = (-5.0 / 40.0 * world.road().lane_count() as f64).exp();
    for k in 0..traffic.count {
        let speed = world.rng().random_range(traffic.speed[0]..=traffic.speed[1]);
        let lane = traffic.lanes[world.rng().random_range(0..traffic.lanes.len())];
        let offset = (12.0 + speed) * lanes_factor / traffic.density;
        let front =
            world.vehicles().iter().map(|v| v.state.s).fold(None, |m: Option<f64>, s| Some(m.map_or(s, |m| m.max(s))));
        let s = front.unwrap_or(3.0 * offset) + offset * world.rng().random_range(0.9..1.1);
        let name = format!("car{k}");
        let (style, driver) = match traffic.gt {
            Some(gt) if is_gt_car(k, traffic.count, gt.count) => {
                (gt.style, Driver::Gt(Box::new(GtDriver::new(gt.game, gt.role, GtParams::default()))))
            }
            _ => (traffic.style, Driver::Idm),
        };
        let vehicle = Vehicle::new(&name, world.road(), lane, s, speed, style, driver);
        world.add(vehicle);
    }
}

/// Sets `key` (dotted; `vehicle.<name>.<field>` addresses a vehicle by name) to `value`.
fn apply_override(table: &mut toml::Table, key: &str, value: toml::Value) -> Result<(), ScenarioErrorKind> {
    let bad = |message: String| ScenarioErrorKind::BadOverride { key: key.to_string(), message };
    let parts: Vec<&str> = key.split('.').collect();
    if parts.len() > MAX_DEPTH {
        return Err(bad(format!("it has {} parts; a scenario nests at most {MAX_DEPTH} deep", parts.len())));
    }
    if parts.iter().any(|part| part.is_empty()) {
        return Err(bad("every part of a dotted key must be non-empty".into()));
    }
    let (last, path) = parts.split_last().ok_or_else(|| bad("empty key".into()))?;
    let mut current = table;
    let mut parts = path.iter();
    while let Some(&part) = parts.next() {
        let entry = current.entry(part).or_insert_with(|| toml::Value::Table(toml::Table::new()));
        current = match entry {
            toml::Value::Table(inner) => inner,
            toml::Value::Array(items) => {
                let name =
                    parts.next().ok_or_else(|| bad(format!("name the `{part}` to change: {part}.<name>.<field>")))?;
                items
                    .iter_mut()
                    .find_map(|item| match item {
                        toml::Value::Table(t) if t.get("name").and_then(toml::Value::as_str) == Some(name) => Some(t),
                        _ => None,
                    })
                    .ok_or_else(|| bad(format!("there is no {part} named '{name}'")))?
            }
            _ => return Err(bad(format!("`{part}` is a value, not a table"))),
        };
    }
    current.insert(last.to_string(), value);
    Ok(())
}

/// How deep `table`'s tables and arrays nest (a flat table is 1), counted without
/// recursion and no further than `MAX_DEPTH` + 1.
fn nesting(table: &toml::Table) -> usize {
    let mut deepest = 1;
    let mut pending: Vec<(&toml::Value, usize)> = table.values().map(|value| (value, 2)).collect();
    while let Some((value, depth)) = pending.pop() {
        let inner: Box<dyn Iterator<Item = &toml::Value>> = match value {
            toml::Value::Table(table) => Box::new(table.values()),
            toml::Value::Array(items) => Box::new(items.iter()),
            _ => continue,
        };
        deepest = deepest.max(depth);
        if depth > MAX_DEPTH {
            break;
        }
        pending.extend(inner.map(|value| (value, depth + 1)));
    }
    deepest
}

impl ScenarioFile {
    fn validate(self) -> Result<Scenario, ScenarioErrorKind> {
        let invalid = |key: &str, message: String| ScenarioErrorKind::Invalid { key: key.to_string(), message };
        let sim = &self.sim;
        for (key, value) in
            [("sim.physics_dt", sim.physics_dt), ("sim.control_dt", sim.control_dt), ("sim.step_dt", sim.step_dt)]
        {
            if !(value.is_finite() && value > 0.0) {
                return Err(invalid(key, format!("must be a positive number of seconds, not {value}")));
            }
        }
        if sim.control_dt < sim.physics_dt || sim.step_dt < sim.physics_dt {
            return Err(invalid("sim.physics_dt", "must not exceed control_dt and step_dt".into()));
        }
        // The world ticks round(period / physics_dt) times per period: a step that does not
        // divide it would silently stretch the control period (0.04 s makes 0.12 s of 0.1 s).
        for (key, period) in [("sim.control_dt", sim.control_dt), ("sim.step_dt", sim.step_dt)] {
            let ticks = period / sim.physics_dt;
            if (ticks - ticks.round()).abs() > 1e-6 * ticks {
                let message = format!("must be a whole number of physics steps ({} s), not {ticks:.3}", sim.physics_dt);
                return Err(invalid(key, message));
            }
        }
        if sim.max_cycles == 0 {
            return Err(invalid("sim.max_cycles", "must be at least 1".into()));
        }
        let road = self.road.validate()?;
        let vehicles = self.vehicles.iter().map(|v| v.validate(&road)).collect::<Result<Vec<_>, _>>()?;
        check_names_and_overlaps(&vehicles, &road)?;
        let traffic = self.traffic.map(|t| t.validate(&road)).transpose()?;
        let reward = self.reward.validate(sim.max_cycles)?;
        let goal = self.goal.validate(&road, &vehicles)?;
        let vary = validate_vary(&self.vary)?;
        Ok(Scenario {
            name: self.name,
            description: self.description,
            road,
            world: WorldParams { physics_dt: sim.physics_dt, control_dt: sim.control_dt },
            step_dt: sim.step_dt,
            max_cycles: sim.max_cycles,
            vehicles,
            traffic,
            reward,
            goal,
            vary,
            source: Default::default(),
        })
    }
}

impl RewardFile {
    fn validate(&self, _max_cycles: u32) -> Result<RewardSpec, ScenarioErrorKind> {
        let invalid = |key: &str, message: String| ScenarioErrorKind::Invalid { key: key.to_string(), message };
        if !(self.cost_scale.is_finite() && self.cost_scale > 0.0) {
            return Err(invalid("reward.cost_scale", format!("must be a positive number, not {}", self.cost_scale)));
        }
        if let Some(crash) = self.crash.filter(|c| !(c.is_finite() && *c < 0.0)) {
            return Err(invalid("reward.crash", format!("must be a negative number, not {crash}")));
        }
        Ok(RewardSpec { cost_scale: self.cost_scale, crash: self.crash })
    }
}

impl GoalFile {
    fn validate(&self, road: &Road, vehicles: &[VehicleSpec]) -> Result<Goal, ScenarioErrorKind> {
        let invalid = |key: &str, message: String| ScenarioErrorKind::Invalid { key: key.to_string(), message };
        let mut lanes = Vec::with_capacity(self.lanes.len());
        for &lane in &self.lanes {
            if !road.has_lane(lane) {
                return Err(invalid(
                    "goal.lanes",
                    format!("lists lane {lane}, but the road's lanes are 0..={}", road.lane_count() - 1),
                ));
            }
            lanes.push(LaneId(lane as u32));
        }
        if let Some(name) = self.ahead_of.iter().find(|name| !vehicles.iter().any(|v| &v.name == *name)) {
            return Err(invalid("goal.ahead_of", format!("names '{name}', which is no [[vehicle]] of the file")));
        }
        Ok(Goal { lanes, ahead_of: self.ahead_of.clone() })
    }
}

/// `[vary]`: each key a dotted override path, each value `{ range = [low, high] }` or
/// `{ choose = [value, ...] }`.
fn validate_vary(vary: &toml::Table) -> Result<Vec<(String, Variation)>, ScenarioErrorKind> {
    let invalid = |key: &str, message: &str| ScenarioErrorKind::Invalid {
        key: format!("vary.\"{key}\""),
        message: message.to_string(),
    };
    let form = "must be { range = [low, high] } with numbers low <= high, or { choose = [value, ...] }";
    let mut out = Vec::with_capacity(vary.len());
    for (key, value) in vary {
        let table = value.as_table().ok_or_else(|| invalid(key, form))?;
        let variation = match (table.get("range"), table.get("choose"), table.len()) {
            (Some(toml::Value::Array(range)), None, 1) => {
                let number = |v: &toml::Value| v.as_float().or_else(|| v.as_integer().map(|i| i as f64));
                match range.as_slice() {
                    [low, high] => match (number(low), number(high)) {
                        (Some(low), Some(high)) if low.is_finite() && high.is_finite() && low <= high => {
                            Variation::Range(low, high)
                        }
                        _ => return Err(invalid(key, form)),
                    },
                    _ => return Err(invalid(key, form)),
                }
            }
            (None, Some(toml::Value::Array(values)), 1) if !values.is_empty() => Variation::Choose(values.clone()),
            _ => return Err(invalid(key, form)),
        };
        out.push((key.clone(), variation));
    }
    Ok(out)
}

impl RoadFile {
    fn validate(&self) -> Result<Road, ScenarioErrorKind> {
        let invalid = |key: &str, message: String| ScenarioErrorKind::Invalid { key: key.to_string(), message };
        if !(1..=64).contains(&self.lanes) {
            return Err(invalid("road.lanes", format!("must be between 1 and 64, not {}", self.lanes)));
        }
        if !(self.lane_width.is_finite() && self.lane_width > 0.0) {
            return Err(invalid("road.lane_width", format!("must be positive, not {}", self.lane_width)));
        }
        if self.speed_limits.len() != self.lanes as usize {
            return Err(invalid(
                "road.speed_limits",
                format!("has {} entries but the road has {} lanes", self.speed_limits.len(), self.lanes),
            ));
        }
        if let Some(bad) = self.speed_limits.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
            return Err(invalid("road.speed_limits", format!("must be positive speeds in m/s, not {bad}")));
        }
        if self.sections.is_empty() {
            return Err(invalid("road.sections", "needs at least one section".into()));
        }
        let mut sections = Vec::with_capacity(self.sections.len());
        for (i, section) in self.sections.iter().enumerate() {
            if !(section.length.is_finite() && section.length > 0.0) {
                return Err(invalid(
                    &format!("road.sections[{i}].length"),
                    format!("must be positive, not {}", section.length),
                ));
            }
            sections.push(match section.radius {
                None => Section::Straight { length: section.length },
                Some(radius) if radius.is_finite() && radius.abs() > self.lane_width * self.lanes as f64 => {
                    Section::Arc { length: section.length, curvature: 1.0 / radius }
                }
                Some(radius) => {
                    return Err(invalid(
                        &format!("road.sections[{i}].radius"),
                        format!("{radius} m is tighter than the road is wide; lanes would fold over"),
                    ));
                }
            });
        }
        let length: f64 = sections.iter().map(Section::length).sum();
        let mut ends = Vec::new();
        for (i, end) in self.lane_ends.iter().enumerate() {
            if !(0..self.lanes).contains(&end.lane) {
                return Err(invalid(
                    &format!("road.lane_ends[{i}].lane"),
                    format!("{} does not exist (lanes 0..={})", end.lane, self.lanes - 1),
                ));
            }
            if !(end.s.is_finite() && end.s > 0.0 && end.s <= length) {
                return Err(invalid(
                    &format!("road.lane_ends[{i}].s"),
                    format!("{} is not on the road (0..{length})", end.s),
                ));
            }
            ends.push((LaneId(end.lane as u32), end.s));
        }
        let origin = Pose { x: self.origin.x, y: self.origin.y, heading: self.origin.heading };
        Ok(Road::new(origin, sections, self.lane_width, self.speed_limits.clone(), &ends))
    }
}

impl VehicleFile {
    fn validate(&self, road: &Road) -> Result<VehicleSpec, ScenarioErrorKind> {
        let vehicle = self.name.clone();
        let invalid = |field: &str, message: String| ScenarioErrorKind::Invalid {
            key: format!("vehicle '{}'.{field}", self.name),
            message,
        };
        if self.name.is_empty() || self.name.contains(|c: char| c.is_whitespace() || c == '/') {
            return Err(invalid("name", "must be non-empty, without spaces or '/'".into()));
        }
        if !(self.speed.is_finite() && self.speed >= 0.0) {
            return Err(invalid("speed", format!("must be a speed >= 0 in m/s, not {}", self.speed)));
        }
        let target_speed = self.target_speed.unwrap_or(self.speed);
        if !(target_speed.is_finite() && target_speed > 0.0) {
            return Err(invalid("target_speed", format!("must be positive, not {target_speed}")));
        }
        let (s, d, lane) = match (self.lane, self.s, self.x, self.y) {
            (Some(lane), Some(s), None, None) => {
                if !road.has_lane(lane) {
                    return Err(ScenarioErrorKind::UnknownLane { vehicle, lane, lanes: road.lane_count() });
                }
                let lane = LaneId(lane as u32);
                (s, road.lane_center(lane), lane)
            }
            (None, None, Some(x), Some(y)) => {
                let (s, d) = road.to_frenet(x, y);
                let lane = road.lane_at(s, d).ok_or_else(|| ScenarioErrorKind::OffRoad {
                    vehicle: vehicle.clone(),
                    detail: format!("({x}, {y}) is {d:.2} m from the reference line, outside every lane"),
                })?;
                (s, d, lane)
            }
            _ => return Err(invalid("position", "give either `lane` and `s`, or `x` and `y`".into())),
        };
        if !s.is_finite() || s < 0.0 || s > road.lane_end(lane) {
            return Err(ScenarioErrorKind::OffRoad {
                vehicle,
                detail: format!("s = {s} is outside lane {} (0..={})", lane.0, road.lane_end(lane)),
            });
        }
        let (style, driver) = match &self.driver {
            DriverFile::Agent { style, action } => (*style, DriverSpec::Agent(*action)),
            DriverFile::Idm { style } => (*style, DriverSpec::Idm),
            DriverFile::Gt { style, game, role, follower_tolerance, params } => {
                let mut constants = match params {
                    // Built-in names only: a scenario may come from a client, and must not
                    // make the server read its files.
                    Some(name) => {
                        let hint =
                            "(a scenario names built-in presets only; a preset file is for `arena paper --params`)";
                        crate::preset::builtin(name, hint).map_err(|e| invalid("driver.params", e.to_string()))?.gt
                    }
                    None => GtParams::default(),
                };
                if let Some(tolerance) = *follower_tolerance {
                    if !(tolerance.is_finite() && tolerance >= 0.0) {
                        return Err(invalid(
                            "driver.follower_tolerance",
                            format!("must be a number >= 0, not {tolerance}"),
                        ));
                    }
                    constants.decision.game.follower_tolerance = tolerance;
                }
                (*style, DriverSpec::Gt { game: *game, role: *role, params: constants })
            }
        };
        Ok(VehicleSpec { name: self.name.clone(), lane, s, d, speed: self.speed, target_speed, style, driver })
    }
}

fn check_names_and_overlaps(vehicles: &[VehicleSpec], road: &Road) -> Result<(), ScenarioErrorKind> {
    let body = VehicleParams::default();
    let half = (body.length / 2.0, body.width / 2.0);
    for (i, a) in vehicles.iter().enumerate() {
        for b in &vehicles[i + 1..] {
            if a.name == b.name {
                return Err(ScenarioErrorKind::DuplicateName(a.name.clone()));
            }
            let pa = road.to_global(a.s, a.d, 0.0);
            let pb = road.to_global(b.s, b.d, 0.0);
            if crate::world::oriented_boxes_overlap((pa.x, pa.y, pa.heading), (pb.x, pb.y, pb.heading), half) {
                return Err(ScenarioErrorKind::Overlap { first: a.name.clone(), second: b.name.clone() });
            }
        }
    }
    Ok(())
}

impl TrafficFile {
    fn validate(self, road: &Road) -> Result<TrafficSpec, ScenarioErrorKind> {
        let invalid = |key: &str, message: String| ScenarioErrorKind::Invalid { key: key.to_string(), message };
        if self.count > 10_000 {
            return Err(invalid("traffic.count", format!("{} is more than the 10000 a world supports", self.count)));
        }
        if !(self.density.is_finite() && self.density > 0.0) {
            return Err(invalid("traffic.density", format!("must be positive, not {}", self.density)));
        }
        let [low, high] = self.speed;
        if !(low.is_finite() && high.is_finite() && 0.0 < low && low <= high) {
            return Err(invalid(
                "traffic.speed",
                format!("must be [low, high] with 0 < low <= high, not [{low}, {high}]"),
            ));
        }
        let lanes = self.lanes.unwrap_or_else(|| (0..road.lane_count() as i64).collect());
        if lanes.is_empty() {
            return Err(invalid("traffic.lanes", "must name at least one lane".into()));
        }
        if let Some(&lane) = lanes.iter().find(|&&l| !road.has_lane(l)) {
            return Err(invalid(
                "traffic.lanes",
                format!("lane {lane} does not exist (lanes 0..={})", road.lane_count() - 1),
            ));
        }
        let gt = self.gt.map(|gt| GtTraffic { count: gt.count, game: gt.game, style: gt.style, role: gt.role });
        if let Some(gt) = gt.filter(|gt| gt.count > self.count) {
            return Err(invalid(
                "traffic.gt.count",
                format!("{} is more than the {} cars of traffic", gt.count, self.count),
            ));
        }
        Ok(TrafficSpec {
            gt,
            count: self.count,
            density: self.density,
            speed: self.speed,
            lanes: lanes.into_iter().map(|l| LaneId(l as u32)).collect(),
            style: self.style,
        })
    }
}

#[cfg(test)]
mod tests;
