//! Parameter presets: named sets of the `gt` driver's constants (`GtParams`) that differ
//! from the documented defaults, plus scenario overrides for the paper's runs (the
//! adjacent cars' target speeds, say). A scenario file's `gt` driver names one with
//! `params = "NAME"`; `arena paper --params NAME` runs the paper's tables with one;
//! `arena calibrate` writes one. Built-in presets live in `presets/` and are compiled in;
//! any other is read from a `.toml` file.
//!
//! A preset's `[gt]` table is laid over the serialised defaults key by key, so it holds
//! only what it changes, and a key the defaults do not have is an error naming it.

use std::collections::BTreeMap;
use std::fmt;

use serde::{Deserialize, Serialize};

use crate::gt::GtParams;

/// The presets shipped in `presets/`: (name, text).
pub const BUILTIN_PRESETS: [(&str, &str); 2] = [
    ("default", include_str!("../../../presets/default.toml")),
    ("paper-fit", include_str!("../../../presets/paper-fit.toml")),
];

/// A preset, validated: the full constants it gives and its scenario overrides.
#[derive(Debug, Clone, PartialEq)]
pub struct Preset {
    /// Its name.
    pub name: String,
    /// One line on what it is.
    pub description: String,
    /// The `gt` driver's constants: the defaults with the preset's `[gt]` laid over.
    pub gt: GtParams,
    /// Per built-in scenario name, (dotted key, value) overrides for the paper's runs.
    pub scenario: BTreeMap<String, Vec<(String, toml::Value)>>,
}

/// A preset file as written.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PresetFile {
    /// Its name.
    pub name: String,
    /// One line on what it is.
    #[serde(default)]
    pub description: String,
    /// Fields of `GtParams` that differ from the defaults, by their path.
    #[serde(default)]
    pub gt: toml::Table,
    /// Per scenario name, dotted-key overrides (`"vehicle.ac.target_speed" = 21.0`).
    #[serde(default)]
    pub scenario: BTreeMap<String, toml::Table>,
}

/// Why a preset could not be loaded.
#[derive(Debug, Clone, PartialEq)]
pub struct PresetError {
    /// The name or file asked for.
    pub preset: String,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for PresetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "invalid parameter preset '{}': {}", self.preset, self.message)
    }
}

impl std::error::Error for PresetError {}

impl Preset {
    /// The built-in presets' names, for error messages and help.
    pub fn builtin_names() -> Vec<&'static str> {
        BUILTIN_PRESETS.iter().map(|(name, _)| *name).collect()
    }

    /// Loads preset `name_or_file`: a built-in name, or a path to a `.toml` file (anything
    /// with a `/` or ending in `.toml`), relative to the working directory. For the command
    /// line only: scenario files, which clients may send, name built-in presets (`builtin`).
    pub fn load(name_or_file: &str) -> Result<Preset, PresetError> {
        if name_or_file.contains('/') || name_or_file.ends_with(".toml") {
            let fail = |message: String| PresetError { preset: name_or_file.to_string(), message };
            let text = std::fs::read_to_string(name_or_file).map_err(|e| fail(format!("cannot read it: {e}")))?;
            return Preset::parse(name_or_file, &text);
        }
        Preset::builtin(name_or_file, ", or give a path to a .toml preset file")
    }

    /// Loads the built-in preset `name`; an unknown name's error lists them, then `hint`.
    pub fn builtin(name: &str, hint: &str) -> Result<Preset, PresetError> {
        match BUILTIN_PRESETS.iter().find(|(builtin, _)| *builtin == name) {
            Some((_, text)) => Preset::parse(name, text),
            None => Err(PresetError {
                preset: name.to_string(),
                message: format!("no such built-in preset; choose one of {}{hint}", Preset::builtin_names().join(", ")),
            }),
        }
    }

    /// Parses and validates preset text; `source` names it in errors.
    pub fn parse(source: &str, text: &str) -> Result<Preset, PresetError> {
        let fail = |message: String| PresetError { preset: source.to_string(), message };
        let file: PresetFile = toml::from_str(text).map_err(|e| fail(e.to_string().trim_end().to_string()))?;
        let gt = gt_params(&file.gt).map_err(fail)?;
        let scenario = file
            .scenario
            .iter()
            .map(|(name, table)| (name.clone(), table.iter().map(|(k, v)| (k.clone(), v.clone())).collect()))
            .collect();
        Ok(Preset { name: file.name, description: file.description, gt, scenario })
    }

    /// The `[gt]` table of a preset holding `params`: every leaf that differs from the
    /// defaults, so a written preset says only what it changes.
    pub fn changes_of(params: &GtParams) -> toml::Table {
        let defaults = toml::Table::try_from(GtParams::default()).expect("GtParams serialises to TOML");
        let ours = toml::Table::try_from(*params).expect("GtParams serialises to TOML");
        diff(&defaults, &ours)
    }
}

/// The defaults with `changes` laid over, checked key by key.
fn gt_params(changes: &toml::Table) -> Result<GtParams, String> {
    let defaults = toml::Table::try_from(GtParams::default()).map_err(|e| e.to_string())?;
    let mut merged = defaults;
    lay_over(&mut merged, changes, "gt")?;
    let params: GtParams = toml::Value::Table(merged).try_into().map_err(|e: toml::de::Error| e.to_string())?;
    params.check().map_err(|e| format!("gt.{e}"))?;
    Ok(params)
}

fn lay_over(base: &mut toml::Table, changes: &toml::Table, path: &str) -> Result<(), String> {
    for (key, value) in changes {
        let here = format!("{path}.{key}");
        match (base.get_mut(key), value) {
            (None, _) => {
                let known: Vec<&str> = base.keys().map(String::as_str).collect();
                return Err(format!("unknown key '{here}'; {path} has {}", known.join(", ")));
            }
            (Some(toml::Value::Table(inner)), toml::Value::Table(change)) => lay_over(inner, change, &here)?,
            (Some(toml::Value::Table(_)), _) => return Err(format!("'{here}' must be a table")),
            (Some(slot), value) => {
                // An integer where a float is expected is fine (`horizon = 3`).
                *slot = match (&*slot, value) {
                    (toml::Value::Float(_), toml::Value::Integer(i)) => toml::Value::Float(*i as f64),
                    _ => value.clone(),
                };
            }
        }
    }
    Ok(())
}

fn diff(base: &toml::Table, ours: &toml::Table) -> toml::Table {
    let mut out = toml::Table::new();
    for (key, value) in ours {
        match (base.get(key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => {
                let inner = diff(b, o);
                if !inner.is_empty() {
                    out.insert(key.clone(), toml::Value::Table(inner));
                }
            }
            (Some(b), o) if b == o => {}
            _ => {
                out.insert(key.clone(), value.clone());
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_builtin_preset_loads_and_default_is_the_defaults() {
        for name in Preset::builtin_names() {
            let preset = Preset::load(name).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(preset.name, name, "a built-in preset's name is its key");
        }
        assert_eq!(Preset::load("default").unwrap().gt, GtParams::default());
    }

    #[test]
    fn a_preset_changes_only_what_it_names() {
        let text = "name = \"t\"\n[gt.decision.costs]\nkappa_ax = 5\n[gt.decision.prediction]\nsamples = 8\n";
        let preset = Preset::parse("t", text).unwrap();
        let mut expected = GtParams::default();
        expected.decision.costs.kappa_ax = 5.0;
        expected.decision.prediction.samples = 8;
        assert_eq!(preset.gt, expected);
        let changes = Preset::changes_of(&preset.gt);
        assert_eq!(gt_params(&changes).unwrap(), expected, "the written changes read back");
        assert_eq!(changes.len(), 1, "only [decision] differs: {changes:?}");
    }

    #[test]
    fn a_bad_preset_is_named_with_the_choices() {
        let unknown = Preset::load("no-such-preset").unwrap_err().to_string();
        assert!(unknown.contains("'no-such-preset'") && unknown.contains("default, paper-fit"), "{unknown}");
        let key = Preset::parse("t", "name = \"t\"\n[gt.decision.costs]\nkappa_x = 1.0\n").unwrap_err().to_string();
        assert!(key.contains("gt.decision.costs.kappa_x") && key.contains("kappa_ax"), "{key}");
        let missing = Preset::load("presets/missing.toml").unwrap_err().to_string();
        assert!(missing.contains("presets/missing.toml") && missing.contains("cannot read"), "{missing}");
        let negative = Preset::parse("t", "name = \"t\"\n[gt.decision.game]\nfollower_tolerance = -1\n").unwrap_err();
        assert!(negative.to_string().contains("follower_tolerance"), "{negative}");
    }

    #[test]
    fn a_preset_cannot_ask_for_unbounded_work() {
        for (section, key, value, named) in [
            ("game", "accel_step", "1e-300", "accel_step"),
            ("prediction", "samples", "1000000000", "samples"),
            ("prediction", "horizon", "1e9", "horizon"),
        ] {
            let text = format!("name = \"t\"\n[gt.decision.{section}]\n{key} = {value}\n");
            let refused = Preset::parse("t", &text).unwrap_err().to_string();
            assert!(refused.contains(named) && refused.contains("at most"), "{refused}");
        }
    }
}
