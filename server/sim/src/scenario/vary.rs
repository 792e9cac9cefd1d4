//! Per-episode draws: the `[vary]` table (each key a dotted override, each value a range
//! or a choice) validated into `Variation`s, and `Scenario::episode`, which draws them
//! from the env's RNG and validates the result as a file, retrying a draw that places
//! two cars overlapping.

use rand::{Rng, RngExt};

use super::{Scenario, ScenarioError, ScenarioErrorKind};

/// One value a scenario draws afresh for each episode.
#[derive(Debug, Clone, PartialEq)]
pub enum Variation {
    /// Uniform between two numbers.
    Range(f64, f64),
    /// One of these values, each equally likely.
    Choose(Vec<toml::Value>),
}

/// Draws that may fail validation (two cars placed overlapping, say) are retried this
/// many times before the episode is refused.
const EPISODE_DRAWS: usize = 20;

impl Scenario {
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

/// `[vary]`: each key a dotted override path, each value `{ range = [low, high] }` or
/// `{ choose = [value, ...] }`.
pub(super) fn validate_vary(vary: &toml::Table) -> Result<Vec<(String, Variation)>, ScenarioErrorKind> {
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
