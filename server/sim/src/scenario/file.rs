//! The scenario file as people write it: serde types that mirror the TOML table by
//! table, with its defaults and unknown keys refused, and nothing checked beyond what
//! serde checks (ripgrep's LowArgs; `validate` turns them into the checked `Scenario`).

use serde::de::{DeserializeOwned, Error as _};
use serde::{Deserialize, Deserializer};

use super::{ActionKind, RewardSpec};
use crate::dynamics::Style;
use crate::gt::Game;
use crate::scene::Role;
use crate::world::WorldParams;

/// The file as written.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ScenarioFile {
    pub(super) name: String,
    #[serde(default)]
    pub(super) description: String,
    #[serde(default)]
    pub(super) sim: SimFile,
    pub(super) road: RoadFile,
    #[serde(default, rename = "vehicle")]
    pub(super) vehicles: Vec<VehicleFile>,
    pub(super) traffic: Option<TrafficFile>,
    #[serde(default)]
    pub(super) reward: RewardFile,
    #[serde(default)]
    pub(super) goal: GoalFile,
    #[serde(default)]
    pub(super) vary: toml::Table,
}

#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub(super) struct GoalFile {
    pub(super) lanes: Vec<i64>,
    pub(super) ahead_of: Vec<String>,
    pub(super) fail_at_time_limit: bool,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub(super) struct RewardFile {
    pub(super) cost_scale: f64,
    pub(super) risk_weight: f64,
    pub(super) goal_bonus: f64,
    pub(super) crash: Option<f64>,
    pub(super) failure: Option<f64>,
}

impl Default for RewardFile {
    fn default() -> Self {
        RewardFile {
            cost_scale: RewardSpec::DEFAULT_COST_SCALE,
            risk_weight: RewardSpec::DEFAULT_RISK_WEIGHT,
            goal_bonus: RewardSpec::DEFAULT_GOAL_BONUS,
            crash: None,
            failure: None,
        }
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub(super) struct SimFile {
    pub(super) physics_dt: f64,
    pub(super) control_dt: f64,
    pub(super) step_dt: f64,
    pub(super) max_cycles: u32,
}

impl Default for SimFile {
    fn default() -> Self {
        let world = WorldParams::default();
        SimFile { physics_dt: world.physics_dt, control_dt: world.control_dt, step_dt: 0.1, max_cycles: 200 }
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RoadFile {
    pub(super) lanes: i64,
    #[serde(default = "default_lane_width")]
    pub(super) lane_width: f64,
    pub(super) speed_limits: Vec<f64>,
    #[serde(default)]
    pub(super) origin: OriginFile,
    pub(super) sections: Vec<SectionFile>,
    #[serde(default)]
    pub(super) lane_ends: Vec<LaneEndFile>,
}

fn default_lane_width() -> f64 {
    4.0
}

#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct OriginFile {
    pub(super) x: f64,
    pub(super) y: f64,
    pub(super) heading: f64,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SectionFile {
    pub(super) length: f64,
    /// Signed radius (m), positive bends left; absent for a straight section.
    pub(super) radius: Option<f64>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct LaneEndFile {
    pub(super) lane: i64,
    pub(super) s: f64,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct VehicleFile {
    pub(super) name: String,
    pub(super) lane: Option<i64>,
    pub(super) s: Option<f64>,
    pub(super) x: Option<f64>,
    pub(super) y: Option<f64>,
    pub(super) speed: f64,
    pub(super) target_speed: Option<f64>,
    pub(super) driver: DriverFile,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub(super) enum DriverFile {
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

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct TrafficFile {
    pub(super) count: u32,
    #[serde(default = "default_density")]
    pub(super) density: f64,
    pub(super) speed: [f64; 2],
    pub(super) lanes: Option<Vec<i64>>,
    #[serde(default = "default_style")]
    pub(super) style: Style,
    /// Where the traffic starts (m along the road); absent: ahead of the named vehicles.
    pub(super) start: Option<f64>,
    pub(super) gt: Option<GtTrafficFile>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct GtTrafficFile {
    pub(super) count: u32,
    /// One game, or a list the cars take in turn with the styles.
    pub(super) game: OneOrMany<Game>,
    #[serde(default = "default_styles")]
    pub(super) style: OneOrMany<Style>,
    #[serde(default)]
    pub(super) role: Role,
}

/// A value written alone (`style = "normal"`) or as a list (`style = ["normal", ...]`).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct OneOrMany<T>(pub(super) Vec<T>);

impl<'de, T: DeserializeOwned> Deserialize<'de> for OneOrMany<T> {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        match toml::Value::deserialize(deserializer)? {
            toml::Value::Array(items) => items.into_iter().map(T::deserialize).collect::<Result<_, _>>(),
            one => T::deserialize(one).map(|value| vec![value]),
        }
        .map(OneOrMany)
        .map_err(D::Error::custom)
    }
}

fn default_styles() -> OneOrMany<Style> {
    OneOrMany(vec![Style::Normal])
}

fn default_density() -> f64 {
    1.0
}
