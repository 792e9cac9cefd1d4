//! Scenario files: TOML as written by people, validated into a `Scenario` that can build a
//! fresh `World` for any seed and draw the scenario of each episode. Every refusal names
//! the file, the vehicle or key, and what is wrong.
//!
//! One concern a file, in the order a scenario goes through them:
//! `file` (the serde types, unknown keys refused) -> `overrides` (dotted keys set on the
//! table, and the bound on its depth) -> `validate` (into `spec`'s checked types) ->
//! `build` (the world at time zero, random traffic included) and `vary` (the `[vary]`
//! draws of each episode); `bounds` holds what one scenario may cost, `error` the ways it
//! can be refused.

use std::path::Path;

use serde::Deserialize;

use crate::road::Road;
use crate::world::WorldParams;

mod bounds;
mod build;
mod error;
mod file;
mod overrides;
mod spec;
mod validate;
mod vary;

pub use bounds::{
    EPISODE_DRAWS, MAX_CONTROL_PERIODS_PER_STEP, MAX_GT_CARS, MAX_GT_DECISIONS_PER_STEP, MAX_LEARNERS,
    MAX_PHYSICS_TICKS_PER_STEP, MAX_ROAD_EXTENT, MAX_ROAD_SECTIONS, MAX_SPEED, MAX_VARY_KEYS, MAX_VEHICLES,
    VARY_DRAW_BUDGET_BYTES,
};
pub use error::{ScenarioError, ScenarioErrorKind};
pub use overrides::MAX_SCENARIO_DEPTH;
pub use spec::{ActionKind, DriverSpec, Goal, GtTraffic, RewardSpec, TrafficSpec, VehicleSpec};
pub use vary::Variation;

use file::ScenarioFile;
use overrides::{OPPONENTS, apply_opponents, apply_override, nesting};

/// The scenario files shipped in `scenarios/`, compiled in so the server needs no
/// files beside it: (name, file name, text).
pub const BUILTIN_SCENARIOS: [(&str, &str, &str); 12] = [
    ("merge", "merge.toml", include_str!("../../../../scenarios/merge.toml")),
    ("overtake", "overtake.toml", include_str!("../../../../scenarios/overtake.toml")),
    ("highway", "highway.toml", include_str!("../../../../scenarios/highway.toml")),
    ("merge-ac", "merge-ac.toml", include_str!("../../../../scenarios/merge-ac.toml")),
    ("merge-duo", "merge-duo.toml", include_str!("../../../../scenarios/merge-duo.toml")),
    ("highway-gt", "highway-gt.toml", include_str!("../../../../scenarios/highway-gt.toml")),
    ("merge-random", "merge-random.toml", include_str!("../../../../scenarios/merge-random.toml")),
    ("overtake-random", "overtake-random.toml", include_str!("../../../../scenarios/overtake-random.toml")),
    ("merge-random-1hz", "merge-random-1hz.toml", include_str!("../../../../scenarios/merge-random-1hz.toml")),
    ("overtake-random-1hz", "overtake-random-1hz.toml", include_str!("../../../../scenarios/overtake-random-1hz.toml")),
    ("merge-random-1hz-v2", "merge-random-1hz-v2.toml", include_str!("../../../../scenarios/merge-random-1hz-v2.toml")),
    (
        "overtake-random-1hz-v2",
        "overtake-random-1hz-v2.toml",
        include_str!("../../../../scenarios/overtake-random-1hz-v2.toml"),
    ),
];

/// The text's TOML table, or its syntax error.
fn parse_table(file: &str, text: &str) -> Result<toml::Table, ScenarioError> {
    text.parse().map_err(|e: toml::de::Error| ScenarioError {
        file: file.to_string(),
        kind: ScenarioErrorKind::Syntax(e.to_string()),
    })
}

/// Loads a built-in scenario by name (`merge`, `overtake`, `highway`, ...).
pub fn builtin_scenario(name: &str) -> Option<Result<Scenario, ScenarioError>> {
    BUILTIN_SCENARIOS.iter().find(|(n, ..)| *n == name).map(|(_, file, text)| Scenario::parse(file, text, &[]))
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

impl Scenario {
    /// Reads and validates a scenario file.
    pub fn load(path: &Path) -> Result<Scenario, ScenarioError> {
        let file = path.file_name().map_or_else(|| path.display().to_string(), |f| f.to_string_lossy().into_owned());
        let text = std::fs::read_to_string(path)
            .map_err(|e| ScenarioError { file: file.clone(), kind: ScenarioErrorKind::Io(e.to_string()) })?;
        Scenario::parse(&file, &text, &[])
    }

    /// Parses and validates scenario text; `overrides` are (dotted key, TOML value)
    /// pairs applied before validation, so they are checked exactly as the file is; those
    /// of every opponent (`opponents.<what>`) last, over any other that sets an opponent.
    pub fn parse(file: &str, text: &str, overrides: &[(String, toml::Value)]) -> Result<Scenario, ScenarioError> {
        let table = parse_table(file, text)?;
        let mut scenario = Scenario::from_table(file, table, overrides, Some(text))?;
        scenario.source = (file.to_string(), text.to_string(), overrides.to_vec());
        Ok(scenario)
    }

    /// `parse` from the text's table; `text`, if given, is deserialized in its place when
    /// there are no overrides, for the parser's line and column in a refusal.
    fn from_table(
        file: &str,
        mut table: toml::Table,
        overrides: &[(String, toml::Value)],
        text: Option<&str>,
    ) -> Result<Scenario, ScenarioError> {
        let fail = |kind| ScenarioError { file: file.to_string(), kind };
        let (opponents, others): (Vec<_>, Vec<_>) = overrides.iter().partition(|(key, _)| key.starts_with(OPPONENTS));
        for (key, value) in others {
            apply_override(&mut table, key, value.clone()).map_err(&fail)?;
        }
        for (key, value) in opponents {
            apply_opponents(&mut table, key, value.clone()).map_err(&fail)?;
        }
        let depth = nesting(&table);
        if depth > MAX_SCENARIO_DEPTH {
            return Err(fail(ScenarioErrorKind::TooDeep { depth }));
        }
        let raw: ScenarioFile = match text {
            Some(text) if overrides.is_empty() => toml::from_str(text),
            _ => ScenarioFile::deserialize(toml::Value::Table(table)),
        }
        .map_err(|e: toml::de::Error| fail(blame(overrides, e.to_string())))?;
        raw.validate().map_err(fail)
    }

    /// The learner-driven vehicles, in file order: the env's `possible_agents`.
    pub fn agents(&self) -> impl Iterator<Item = &VehicleSpec> {
        self.vehicles.iter().filter(|v| matches!(v.driver, DriverSpec::Agent(_)))
    }
}

/// A table that does not deserialize, as the override that set what its `message`
/// names, so the user reads the key they wrote: an unknown field (`unknown field
/// \`sped\``: the last override with a part `sped`), or a wrong value (`in
/// \`vehicle.speed\``, which leaves out the vehicle's name: the last override from
/// `vehicle.` to `.speed`); else as the file's error.
fn blame(overrides: &[(String, toml::Value)], message: String) -> ScenarioErrorKind {
    let after = |text: &str| message.rsplit_once(text).and_then(|(_, rest)| rest.split_once('`')).map(|(q, _)| q);
    let (field, path) = (after("unknown field `"), after("in `"));
    let names = |key: &str| match (field, path) {
        (Some(field), _) => key.split('.').any(|part| part == field),
        (None, Some(path)) => ends(key) == ends(path),
        (None, None) => false,
    };
    match overrides.iter().rev().find(|(key, _)| names(key)) {
        Some((key, _)) => ScenarioErrorKind::BadOverride { key: key.clone(), message: message.trim_end().to_string() },
        None => ScenarioErrorKind::Syntax(message),
    }
}

/// The first and last parts of a dotted key.
fn ends(key: &str) -> (Option<&str>, Option<&str>) {
    (key.split('.').next(), key.rsplit('.').next())
}

#[cfg(test)]
mod tests;
