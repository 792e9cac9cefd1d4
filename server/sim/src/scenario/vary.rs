//! Per-episode draws: the `[vary]` table (each key a dotted override, each value a range
//! or a choice) validated into `Variation`s, and `Scenario::episode`, which draws them
//! from the env's RNG and validates the result as a file, retrying a draw that places
//! two cars overlapping, within the budget of `bounds`.

use rand::{Rng, RngExt};

use super::bounds::{MAX_VARY_KEYS, episode_draws};
use super::{Scenario, ScenarioError, ScenarioErrorKind};

/// One value a scenario draws afresh for each episode.
#[derive(Debug, Clone, PartialEq)]
pub enum Variation {
    /// Uniform between two numbers.
    Range(f64, f64),
    /// One of these values, each equally likely.
    Choose(Vec<toml::Value>),
}

impl Scenario {
    /// The scenario of one episode: its `[vary]` values drawn from `rng`, then `extra`
    /// overrides applied (the reset's own). With neither, the scenario itself. Draws that
    /// place two cars on each other or off the road are made again, `EPISODE_DRAWS` times
    /// at most and fewer for a large file (`VARY_DRAW_BUDGET_BYTES`); then the reset is
    /// refused with `DrawsExhausted`.
    pub fn episode(&self, rng: &mut impl Rng, extra: &[(String, toml::Value)]) -> Result<Scenario, ScenarioError> {
        if self.vary.is_empty() && extra.is_empty() {
            return Ok(self.clone());
        }
        let (file, text, overrides) = &self.source;
        // Read once: each draw starts from a copy of the table, not from the text.
        let table = super::parse_table(file, text)?;
        // Only drawn values can be drawn again: with nothing to vary, one attempt.
        let draws = if self.vary.is_empty() { 1 } else { episode_draws(text.len()) };
        let mut attempt = 1;
        loop {
            let mut all = overrides.clone();
            all.extend(self.vary.iter().map(|(key, variation)| (key.clone(), variation.draw(rng))));
            all.extend(extra.iter().cloned());
            match Scenario::from_table(file, table.clone(), &all, None) {
                Ok(mut scenario) => {
                    scenario.source = (file.clone(), text.clone(), all);
                    return Ok(scenario);
                }
                Err(error)
                    if matches!(error.kind, ScenarioErrorKind::Overlap { .. } | ScenarioErrorKind::OffRoad { .. }) =>
                {
                    if self.vary.is_empty() {
                        return Err(error);
                    }
                    if attempt == draws {
                        let kind = ScenarioErrorKind::DrawsExhausted { draws, last: Box::new(error.kind) };
                        return Err(ScenarioError { kind, ..error });
                    }
                    attempt += 1;
                }
                Err(error) => return Err(error),
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
    if vary.len() > MAX_VARY_KEYS {
        return Err(ScenarioErrorKind::Invalid {
            key: "vary".to_string(),
            message: format!(
                "draws {} keys, more than the {MAX_VARY_KEYS} a scenario may draw (MAX_VARY_KEYS); \
                 draw fewer values",
                vary.len()
            ),
        });
    }
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
