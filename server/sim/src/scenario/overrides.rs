//! Dotted-key overrides (`vehicle.<name>.<field>`, `sim.step_dt`, and `opponents.<what>`
//! for every opponent at once) applied to a scenario's TOML table before it is validated,
//! so they are checked exactly as the file is, and the bound on how deep that table may
//! nest: a scenario, its overrides included, can come from a client, and parsing,
//! validating and dropping a TOML value recurse on its depth.

use super::ScenarioErrorKind;

/// How deep a scenario's tables and arrays may nest, its text and overrides together (the
/// shipped files nest 3 deep). Parsing, validating and dropping a TOML value recurse on
/// its depth, and a scenario can come from a client.
pub const MAX_SCENARIO_DEPTH: usize = 16;

/// Sets `key` (dotted; `vehicle.<name>.<field>` addresses a vehicle by name) to `value`.
pub(super) fn apply_override(table: &mut toml::Table, key: &str, value: toml::Value) -> Result<(), ScenarioErrorKind> {
    let bad = |message: String| ScenarioErrorKind::BadOverride { key: key.to_string(), message };
    let parts: Vec<&str> = key.split('.').collect();
    if parts.len() > MAX_SCENARIO_DEPTH {
        return Err(bad(format!("it has {} parts; a scenario nests at most {MAX_SCENARIO_DEPTH} deep", parts.len())));
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

/// The prefix of the keys that drive every opponent at once (`apply_opponents`).
pub(super) const OPPONENTS: &str = "opponents.";

/// Sets what `key` names for every opponent of the scenario: `opponents.style`
/// (aggressive, normal, conservative), `opponents.game` (nash, stackelberg), or
/// `opponents.driver = "idm"` (IDM + MOBIL in their place). The opponents are the cars a
/// learner competes against: every `[[vehicle]]` driven by `gt`, and the game-theoretic
/// traffic (`[traffic] gt`), which becomes IDM traffic under `driver = "idm"`. Applied
/// after every other override and `[vary]` draw, so a drawn style does not undo it.
pub(super) fn apply_opponents(table: &mut toml::Table, key: &str, value: toml::Value) -> Result<(), ScenarioErrorKind> {
    let bad = |message: String| ScenarioErrorKind::BadOverride { key: key.to_string(), message };
    let what = key.strip_prefix(OPPONENTS).unwrap_or(key);
    let text = value.as_str().ok_or_else(|| bad(format!("expected a string, not {value}")))?;
    if what == "driver" && text != "idm" {
        return Err(bad(format!("the one driver opponents can be given is \"idm\", not \"{text}\"")));
    }
    if !matches!(what, "style" | "game" | "driver") {
        return Err(bad("opponents.<what> is opponents.style, opponents.game or opponents.driver".into()));
    }
    let mut found = 0;
    if let Some(toml::Value::Array(vehicles)) = table.get_mut("vehicle") {
        for vehicle in vehicles.iter_mut().filter_map(toml::Value::as_table_mut) {
            let Some(toml::Value::Table(driver)) = vehicle.get_mut("driver") else { continue };
            if driver.get("kind").and_then(toml::Value::as_str) != Some("gt") {
                continue;
            }
            found += 1;
            if what == "driver" {
                let style = driver.get("style").cloned().unwrap_or_else(|| toml::Value::String("normal".into()));
                *driver = toml::Table::from_iter([("kind".to_string(), value.clone()), ("style".to_string(), style)]);
            } else {
                driver.insert(what.to_string(), value.clone());
            }
        }
    }
    if let Some(toml::Value::Table(traffic)) = table.get_mut("traffic") {
        if what == "driver" {
            found += usize::from(traffic.remove("gt").is_some());
        } else if let Some(toml::Value::Table(gt)) = traffic.get_mut("gt") {
            found += 1;
            gt.insert(what.to_string(), value.clone());
        }
    }
    if found == 0 {
        return Err(bad("the scenario has no opponents (no vehicle driven by gt, no [traffic] gt); \
             cross-play needs one that has, such as merge-random, overtake-random, merge-ac or highway-gt"
            .into()));
    }
    Ok(())
}

/// How deep `table`'s tables and arrays nest (a flat table is 1), counted without
/// recursion and no further than `MAX_SCENARIO_DEPTH` + 1.
pub(super) fn nesting(table: &toml::Table) -> usize {
    let mut deepest = 1;
    let mut pending: Vec<(&toml::Value, usize)> = table.values().map(|value| (value, 2)).collect();
    while let Some((value, depth)) = pending.pop() {
        let inner: Box<dyn Iterator<Item = &toml::Value>> = match value {
            toml::Value::Table(table) => Box::new(table.values()),
            toml::Value::Array(items) => Box::new(items.iter()),
            _ => continue,
        };
        deepest = deepest.max(depth);
        if depth > MAX_SCENARIO_DEPTH {
            break;
        }
        pending.extend(inner.map(|value| (value, depth + 1)));
    }
    deepest
}
