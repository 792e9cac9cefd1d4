//! How a scenario is refused: `ScenarioError` names the file, `ScenarioErrorKind` what
//! is wrong (the vehicle, the dotted key, the lane), and `Display` says it as one line
//! a person can act on. Every other file of `scenario` returns these kinds.

use std::fmt;

use super::MAX_SCENARIO_DEPTH;

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
    /// Occurs when tables and arrays nest deeper than `MAX_SCENARIO_DEPTH` (text or overrides).
    TooDeep {
        /// How deep they nest, as far as counted (`MAX_SCENARIO_DEPTH` + 1 at most).
        depth: usize,
    },
    /// Occurs when every `[vary]` draw of a reset placed cars on each other or off the
    /// road, `draws` of them (`EPISODE_DRAWS`, fewer for a large file).
    DrawsExhausted {
        /// How many draws were made.
        draws: usize,
        /// Why the last was refused (an `Overlap` or `OffRoad`).
        last: Box<ScenarioErrorKind>,
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
        write!(f, "invalid scenario '{}': {}", self.file, self.kind)
    }
}

impl fmt::Display for ScenarioErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
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
            ScenarioErrorKind::DrawsExhausted { draws, last } => {
                write!(
                    f,
                    "[vary] drew this episode {draws} times and every draw was refused; the last: {last}. \
                     Narrow the [vary] ranges so that cars cannot land on each other or off the road"
                )
            }
            ScenarioErrorKind::BadOverride { key, message } => write!(f, "override `{key}`: {message}"),
            ScenarioErrorKind::TooDeep { depth } => {
                write!(f, "tables and arrays nest {depth} deep; a scenario nests at most {MAX_SCENARIO_DEPTH}")
            }
        }
    }
}

impl std::error::Error for ScenarioError {}
