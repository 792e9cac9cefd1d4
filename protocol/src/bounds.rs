//! The bounds of a request's contents: every string and list a client sends is checked
//! against one of these before the server acts on it, so nothing that came from outside
//! can make a parser recurse, or a builder allocate, beyond a known size. The message as
//! a whole is bounded by `MAX_MESSAGE_BYTES` (the codec); these bound its parts. A
//! request past any of them is refused with `ErrorCode::PayloadTooLarge` and a message
//! naming the part, its size and the bound (docs/protocol.md, "Bounds").

use std::fmt;

use crate::messages::{Action, OptionValue, Request, RequestBody, ScenarioSource};
use crate::options::CreateOptions;

/// Longest scenario name, scenario file name or agent name (bytes).
pub const MAX_NAME_BYTES: usize = 128;
/// Longest inline scenario text (bytes).
pub const MAX_SCENARIO_TEXT_BYTES: usize = 1 << 20;
/// Most overrides of a create or of a reset.
pub const MAX_OPTIONS: usize = 64;
/// Longest override key (bytes).
pub const MAX_OPTION_KEY_BYTES: usize = 256;
/// Most dot-separated parts of an override key (`vehicle.ac.speed` has 3).
pub const MAX_OPTION_KEY_PARTS: usize = 10;
/// Longest string value of an override (bytes).
pub const MAX_OPTION_STRING_BYTES: usize = 64 * 1024;
/// Most actions in one step (one per agent).
pub const MAX_ACTIONS: usize = 1024;
/// Largest snapshot a `Restore` may carry (bytes): 4 MiB, chosen here; a snapshot of
/// highway-gt is about 1 % of it (docs/protocol.md, "Snapshots"), and the server refuses
/// to take one larger.
pub const MAX_SNAPSHOT_BYTES: usize = 4 << 20;

/// A part of a request past its bound.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BoundError {
    /// Which part, as a person would name it ("override key 'a.b…'").
    pub what: String,
    /// Its size.
    pub size: usize,
    /// Its bound.
    pub limit: usize,
    /// What is counted ("bytes", "parts", "entries").
    pub unit: &'static str,
}

impl fmt::Display for BoundError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} has {} {}, more than the {} a request may carry (docs/protocol.md, \"Bounds\")",
            self.what, self.size, self.unit, self.limit
        )
    }
}

impl std::error::Error for BoundError {}

/// The first 40 characters of `text`, for naming a part without echoing megabytes.
fn shown(text: &str) -> String {
    match text.char_indices().nth(40) {
        Some((cut, _)) => format!("{}…", &text[..cut]),
        None => text.to_string(),
    }
}

fn at_most(what: impl FnOnce() -> String, size: usize, limit: usize, unit: &'static str) -> Result<(), BoundError> {
    if size > limit { Err(BoundError { what: what(), size, limit, unit }) } else { Ok(()) }
}

fn name(kind: &str, text: &str) -> Result<(), BoundError> {
    at_most(|| format!("{kind} '{}'", shown(text)), text.len(), MAX_NAME_BYTES, "bytes")
}

fn options(kind: &str, options: &[(String, OptionValue)]) -> Result<(), BoundError> {
    at_most(|| format!("the {kind} list"), options.len(), MAX_OPTIONS, "entries")?;
    for (key, value) in options {
        let key_name = || format!("{kind} key '{}'", shown(key));
        at_most(key_name, key.len(), MAX_OPTION_KEY_BYTES, "bytes")?;
        at_most(key_name, key.split('.').count(), MAX_OPTION_KEY_PARTS, "parts")?;
        if let OptionValue::Str(text) = value {
            at_most(|| format!("the value of {kind} '{}'", shown(key)), text.len(), MAX_OPTION_STRING_BYTES, "bytes")?;
        }
    }
    Ok(())
}

fn actions(actions: &[(String, Action)]) -> Result<(), BoundError> {
    at_most(|| "the action list".to_string(), actions.len(), MAX_ACTIONS, "entries")?;
    actions.iter().try_for_each(|(agent, _)| name("agent name", agent))
}

fn create(scenario: &ScenarioSource, create: &CreateOptions) -> Result<(), BoundError> {
    match scenario {
        ScenarioSource::Named(scenario) => name("scenario name", scenario)?,
        ScenarioSource::Inline { file_name, text } => {
            name("scenario file name", file_name)?;
            at_most(
                || format!("inline scenario '{}'", shown(file_name)),
                text.len(),
                MAX_SCENARIO_TEXT_BYTES,
                "bytes",
            )?;
        }
    }
    options("override", &create.overrides)?;
    let info_keys = create.info_keys.as_deref().unwrap_or_default();
    at_most(|| "the info_keys list".to_string(), info_keys.len(), MAX_OPTIONS, "entries")?;
    info_keys.iter().try_for_each(|key| name("info key", key))
}

/// Checks reset overrides that did not come in a request (a snapshot carries its
/// episode's) against the bounds a reset's own are held to.
pub fn check_reset_overrides(overrides: &[(String, OptionValue)]) -> Result<(), BoundError> {
    options("reset override", overrides)
}

/// Checks every string and list of `request` against its bound.
pub fn check(request: &Request) -> Result<(), BoundError> {
    match &request.body {
        RequestBody::CreateEnv { scenario, options } => create(scenario, options),
        RequestBody::Reset { options: reset, .. } => check_reset_overrides(&reset.overrides),
        RequestBody::Step { actions: step, .. } => actions(step),
        RequestBody::StepBatch { steps } => steps.iter().try_for_each(|step| actions(&step.actions)),
        RequestBody::Restore { snapshot, .. } => {
            at_most(|| "the snapshot".to_string(), snapshot.len(), MAX_SNAPSHOT_BYTES, "bytes")
        }
        RequestBody::Render { follow: Some(vehicle), .. } => name("the render's follow name", vehicle),
        RequestBody::ServerInfo
        | RequestBody::Render { follow: None, .. }
        | RequestBody::Statistics { .. }
        | RequestBody::State { .. }
        | RequestBody::Specs { .. }
        | RequestBody::Close { .. }
        | RequestBody::Record { .. }
        | RequestBody::Snapshot { .. } => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ClientId, EnvId};

    fn create_with(overrides: Vec<(String, OptionValue)>) -> Request {
        let options = CreateOptions { overrides, ..CreateOptions::default() };
        Request::new(ClientId(1), RequestBody::CreateEnv { scenario: ScenarioSource::Named("merge".into()), options })
    }

    fn reset_with(options: Vec<(String, OptionValue)>) -> Request {
        let options = crate::ResetOptions { overrides: options };
        Request::new(ClientId(1), RequestBody::Reset { env: EnvId(1), seq: 1, seed: None, options })
    }

    fn inline(file_name: &str, text_bytes: usize) -> Request {
        let scenario = ScenarioSource::Inline { file_name: file_name.into(), text: "#".repeat(text_bytes) };
        Request::new(ClientId(1), RequestBody::CreateEnv { scenario, options: CreateOptions::default() })
    }

    fn step_with(actions: Vec<(String, Action)>) -> Request {
        Request::new(ClientId(1), RequestBody::Step { env: EnvId(1), seq: 1, actions })
    }

    /// `below` passes, `above` is refused with `unit` and `limit` in its message.
    fn bound_holds(below: Request, above: Request, unit: &str, limit: usize) {
        assert_eq!(check(&below), Ok(()));
        let error = check(&above).expect_err("past the bound");
        assert_eq!((error.unit, error.limit), (unit, limit), "{error}");
        let text = error.to_string();
        assert!(text.contains(&format!("more than the {limit}")) && text.contains("Bounds"), "{text}");
    }

    fn key_of_parts(parts: usize) -> String {
        vec!["a"; parts].join(".")
    }

    #[test]
    fn override_and_option_keys_are_bounded_in_parts_and_bytes() {
        let one = |key: String| vec![(key, OptionValue::Int(1))];
        for (make, kind) in [(create_with as fn(_) -> Request, "override"), (reset_with, "reset override")] {
            let (below, above) = (key_of_parts(MAX_OPTION_KEY_PARTS), key_of_parts(MAX_OPTION_KEY_PARTS + 1));
            bound_holds(make(one(below)), make(one(above.clone())), "parts", MAX_OPTION_KEY_PARTS);
            assert!(check(&make(one(above))).unwrap_err().what.starts_with(kind));
            let (below, above) = ("k".repeat(MAX_OPTION_KEY_BYTES), "k".repeat(MAX_OPTION_KEY_BYTES + 1));
            bound_holds(make(one(below)), make(one(above)), "bytes", MAX_OPTION_KEY_BYTES);
        }
        // The key that overflowed the server's stack (15 000 parts, about 30 KB).
        let error = check(&create_with(one(format!("{}a", "a.".repeat(15_000))))).unwrap_err();
        assert_eq!(error.unit, "bytes", "{error}");
        assert!(error.what.len() < 80, "the message echoes the key: {}", error.what);
    }

    #[test]
    fn option_lists_and_string_values_are_bounded() {
        let many = |n: usize| (0..n).map(|k| (format!("k{k}"), OptionValue::Bool(true))).collect::<Vec<_>>();
        bound_holds(create_with(many(MAX_OPTIONS)), create_with(many(MAX_OPTIONS + 1)), "entries", MAX_OPTIONS);
        bound_holds(reset_with(many(MAX_OPTIONS)), reset_with(many(MAX_OPTIONS + 1)), "entries", MAX_OPTIONS);
        let string = |n: usize| vec![("k".to_string(), OptionValue::Str("[".repeat(n)))];
        bound_holds(
            create_with(string(MAX_OPTION_STRING_BYTES)),
            create_with(string(MAX_OPTION_STRING_BYTES + 1)),
            "bytes",
            MAX_OPTION_STRING_BYTES,
        );
    }

    #[test]
    fn info_keys_are_bounded_in_entries_and_bytes() {
        let keys = |keys: Vec<String>| {
            let options = CreateOptions { info_keys: Some(keys), ..CreateOptions::default() };
            Request::new(
                ClientId(1),
                RequestBody::CreateEnv { scenario: ScenarioSource::Named("merge".into()), options },
            )
        };
        let many = |n: usize| (0..n).map(|k| format!("k{k}")).collect::<Vec<_>>();
        bound_holds(keys(many(MAX_OPTIONS)), keys(many(MAX_OPTIONS + 1)), "entries", MAX_OPTIONS);
        bound_holds(
            keys(vec!["k".repeat(MAX_NAME_BYTES)]),
            keys(vec!["k".repeat(MAX_NAME_BYTES + 1)]),
            "bytes",
            MAX_NAME_BYTES,
        );
    }

    #[test]
    fn names_inline_scenarios_and_action_lists_are_bounded() {
        let named = |n: usize| {
            let scenario = ScenarioSource::Named("m".repeat(n));
            Request::new(ClientId(1), RequestBody::CreateEnv { scenario, options: CreateOptions::default() })
        };
        bound_holds(named(MAX_NAME_BYTES), named(MAX_NAME_BYTES + 1), "bytes", MAX_NAME_BYTES);
        bound_holds(
            inline(&"f".repeat(MAX_NAME_BYTES), 10),
            inline(&"f".repeat(MAX_NAME_BYTES + 1), 10),
            "bytes",
            MAX_NAME_BYTES,
        );
        bound_holds(
            inline("mine.toml", MAX_SCENARIO_TEXT_BYTES),
            inline("mine.toml", MAX_SCENARIO_TEXT_BYTES + 1),
            "bytes",
            MAX_SCENARIO_TEXT_BYTES,
        );
        let agents = |n: usize| (0..n).map(|k| (format!("a{k}"), Action::Meta(1))).collect::<Vec<_>>();
        bound_holds(step_with(agents(MAX_ACTIONS)), step_with(agents(MAX_ACTIONS + 1)), "entries", MAX_ACTIONS);
        let restore =
            |n: usize| Request::new(ClientId(1), RequestBody::Restore { env: EnvId(1), seq: 1, snapshot: vec![7; n] });
        bound_holds(restore(MAX_SNAPSHOT_BYTES), restore(MAX_SNAPSHOT_BYTES + 1), "bytes", MAX_SNAPSHOT_BYTES);
        let agent = |n: usize| vec![("x".repeat(n), Action::Meta(1))];
        bound_holds(step_with(agent(MAX_NAME_BYTES)), step_with(agent(MAX_NAME_BYTES + 1)), "bytes", MAX_NAME_BYTES);
        let batch = |n: usize| {
            let step = crate::BatchStep { env: EnvId(2), seq: 1, actions: agent(n) };
            Request::new(ClientId(1), RequestBody::StepBatch { steps: vec![step] })
        };
        bound_holds(batch(MAX_NAME_BYTES), batch(MAX_NAME_BYTES + 1), "bytes", MAX_NAME_BYTES);
    }
}
