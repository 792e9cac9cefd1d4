//! The options of `CreateEnv`, declared once. `create_options!` below makes both the
//! `CreateOptions` struct (its fields in wire order, each field's doc its only
//! description) and `CREATE_OPTIONS`, the table clients and docs read: the Python
//! extension takes its keywords from it (names, defaults, what each takes, docstrings),
//! and docs/protocol.md's list of the options is written from it (a test here checks
//! that list). A new option is one line below, and its behaviour in the server.

use serde::{Deserialize, Serialize};

use crate::messages::{ActionType, BuiltinPolicy, Game, ObservationKind, OptionValue};

/// How a client reads a create option from its user, and the option's default (off for
/// a flag, "the scenario's" or "the server's" for the others: none is sent).
#[derive(Debug, Clone, Copy)]
pub enum OptionKind {
    /// On or off.
    Flag,
    /// A whole number.
    Count,
    /// Two whole numbers.
    Pair,
    /// One of a set of names; the function lists them.
    Choice(fn() -> Vec<String>),
    /// Dotted scenario keys and their values.
    Overrides,
    /// A list of names.
    Names,
}

impl OptionKind {
    /// What the option takes, for help texts: "True or False", "one of meta, continuous".
    pub fn takes(self) -> String {
        match self {
            OptionKind::Flag => "true or false".into(),
            OptionKind::Count => "a whole number".into(),
            OptionKind::Pair => "two whole numbers".into(),
            OptionKind::Choice(names) => format!("one of {}", names().join(", ")),
            OptionKind::Overrides => "dotted scenario keys and their values".into(),
            OptionKind::Names => "a list of names".into(),
        }
    }
}

/// A create option's value as a client read it from its user (by the option's
/// `OptionKind`), before it is checked.
#[derive(Debug, Clone, PartialEq)]
pub enum Given {
    /// For a `Flag`.
    Flag(bool),
    /// For a `Count`.
    Count(i64),
    /// For a `Pair`.
    Pair(i64, i64),
    /// For a `Choice`.
    Name(String),
    /// For `Overrides`.
    Overrides(Vec<(String, OptionValue)>),
    /// For `Names`.
    Names(Vec<String>),
}

/// One create option: what `CREATE_OPTIONS` holds per field of `CreateOptions`.
#[derive(Debug, Clone, Copy)]
pub struct CreateOption {
    /// The field's name, which is the Python keyword too.
    pub name: &'static str,
    /// The field's Rust type, as docs/protocol.md shows it.
    pub wire: &'static str,
    /// The field's doc, line by line.
    pub doc: &'static [&'static str],
    /// How a client reads it.
    pub kind: OptionKind,
    /// Sets the field from a value read as `kind` says, or says what is wrong with it
    /// (without the option's name).
    pub set: fn(&mut CreateOptions, Given) -> Result<(), String>,
}

impl CreateOption {
    /// The doc as one paragraph.
    pub fn doc(&self) -> String {
        self.doc.iter().map(|line| line.trim()).collect::<Vec<_>>().join(" ")
    }
}

/// A field type of `CreateOptions`: how a client reads it (`KIND`) and turns what it read
/// into the field.
trait OptionField: Sized {
    const KIND: OptionKind;
    fn read(given: Given) -> Result<Self, String>;
}

/// A closed set of named choices that a create option takes one of.
trait Choice: std::str::FromStr<Err: std::fmt::Display> {
    fn names() -> Vec<String>;
}

macro_rules! choices {
    ($($ty:ty),+) => {$(
        impl Choice for $ty {
            fn names() -> Vec<String> {
                <$ty>::ALL.map(|choice| choice.name().to_string()).to_vec()
            }
        }
    )+};
}

choices!(ActionType, ObservationKind, Game);

impl Choice for BuiltinPolicy {
    fn names() -> Vec<String> {
        BuiltinPolicy::forms().to_vec()
    }
}

fn misread(kind: OptionKind, given: &Given) -> String {
    format!("takes {}, not {given:?}", kind.takes())
}

impl OptionField for bool {
    const KIND: OptionKind = OptionKind::Flag;
    fn read(given: Given) -> Result<bool, String> {
        match given {
            Given::Flag(on) => Ok(on),
            other => Err(misread(Self::KIND, &other)),
        }
    }
}

fn count(n: i64) -> Result<u32, String> {
    u32::try_from(n).map_err(|_| format!("{n} is not a whole number from 0 to {}", u32::MAX))
}

impl OptionField for Option<u32> {
    const KIND: OptionKind = OptionKind::Count;
    fn read(given: Given) -> Result<Self, String> {
        match given {
            Given::Count(n) => count(n).map(Some),
            other => Err(misread(Self::KIND, &other)),
        }
    }
}

impl OptionField for Option<(u32, u32)> {
    const KIND: OptionKind = OptionKind::Pair;
    fn read(given: Given) -> Result<Self, String> {
        match given {
            Given::Pair(a, b) => Ok(Some((count(a)?, count(b)?))),
            other => Err(misread(Self::KIND, &other)),
        }
    }
}

impl<T: Choice> OptionField for Option<T> {
    const KIND: OptionKind = OptionKind::Choice(T::names);
    fn read(given: Given) -> Result<Self, String> {
        match given {
            Given::Name(name) => name.parse::<T>().map(Some).map_err(|e| e.to_string()),
            other => Err(misread(Self::KIND, &other)),
        }
    }
}

impl OptionField for Vec<(String, OptionValue)> {
    const KIND: OptionKind = OptionKind::Overrides;
    fn read(given: Given) -> Result<Self, String> {
        match given {
            Given::Overrides(pairs) => Ok(pairs),
            other => Err(misread(Self::KIND, &other)),
        }
    }
}

impl OptionField for Option<Vec<String>> {
    const KIND: OptionKind = OptionKind::Names;
    fn read(given: Given) -> Result<Self, String> {
        match given {
            Given::Names(names) => Ok(Some(names)),
            other => Err(misread(Self::KIND, &other)),
        }
    }
}

/// `CreateOptions` and `CREATE_OPTIONS` from one list of documented fields.
macro_rules! create_options {
    ($($(#[doc = $doc:literal])+ $field:ident: $ty:ty,)+) => {
        /// Options of `CreateEnv`, fields in wire order; `CREATE_OPTIONS` describes each.
        /// `None` keeps the scenario's choice (or the server's default); flags are off by
        /// default.
        #[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
        pub struct CreateOptions {
            $($(#[doc = $doc])+ pub $field: $ty,)+
        }

        /// Every field of `CreateOptions`, in wire order.
        pub const CREATE_OPTIONS: &[CreateOption] = &[$(CreateOption {
            name: stringify!($field),
            wire: stringify!($ty),
            doc: &[$($doc),+],
            kind: <$ty as OptionField>::KIND,
            set: |options, given| {
                options.$field = <$ty as OptionField>::read(given)?;
                Ok(())
            },
        }),+];
    };
}

create_options! {
    /// (dotted key, value) overrides of the scenario, applied before it is validated
    /// (`vehicle.ac.speed`, `traffic.count`); a `Str` value that parses as a TOML value
    /// (`{ kind = "idm" }`) is used as that value.
    overrides: Vec<(String, OptionValue)>,
    /// The action type of every agent, instead of each learner's in the scenario: `meta`
    /// is Discrete(5) (lane left, idle, lane right, faster, slower), `continuous` a Box
    /// of 2 in [-1, 1] (acceleration, preview offset).
    action_type: Option<ActionType>,
    /// What agents observe: the kinematics matrix (default), or a Dict of it and an int8
    /// `action_mask` of the meta actions that can act now.
    observation: Option<ObservationKind>,
    /// Episode length in steps, instead of the scenario's; at least 1.
    max_cycles: Option<u32>,
    /// (height, width) of `RgbArray` frames, default (300, 600): each within 16..=4096, and
    /// a frame (height x width x 3 bytes) must fit a reply, so at most about 2300 x 2300;
    /// larger is refused at creation (`InvalidScenario`).
    render_size: Option<(u32, u32)>,
    /// Every info carries what the built-in game-theoretic AV would do in the agent's
    /// place, deciding with this game: `expert_action` (in the agent's action space),
    /// `expert_accel`, `expert_sigma`. With a `gt` policy they are that driver's own next
    /// action, and this must be the policy's game.
    expert: Option<Game>,
    /// The server drives every learner with this built-in driver, as `arena eval` does
    /// (version 2): the agents stay agents (observations, rewards, infos), and a step
    /// must carry no actions. `gt:<style>:<game>` is the game-theoretic AV as a leader in
    /// that style, `expert` the AV in each learner's own style playing Stackelberg, `idm`
    /// IDM + MOBIL in the learner's style.
    policy: Option<BuiltinPolicy>,
    /// Every info carries each game-theoretic car's solver counts since the episode began
    /// (version 2): `gt.<car>.plans`, `.qp_iterations`, `.qp_iterations_total`,
    /// `.fallbacks`, `.inexact`.
    diagnostics: bool,
    /// Recording on from the start (version 7): reset replies carry a `WorldStart`, step
    /// replies a `WorldFrame` per control period ("Recordings"; `Record` turns it on or
    /// off later).
    record: bool,
    /// Every game-theoretic decision explained (version 8): step replies carry them in
    /// `explain` ("The AV explained"); each decision then costs about twice as much.
    explain: bool,
    /// Metres of road across the width of `RgbArray` frames, default 120 (version 10;
    /// highway-env's screen width over its `scaling`): more shows more of the traffic,
    /// fewer zooms in. Within 10..=10000, and at most 20 pixels a metre unless it is 120
    /// or more (a frame 600 wide shows at least 30 m), so that a frame costs no more than
    /// a default one may.
    render_window: Option<u32>,
    /// Only these info keys, in the infos' own order, instead of all (version 12): for
    /// vectorised training that carries infos through pipes, `["end_reason",
    /// "episode_done", "episode_success", "episode_return"]` say, which then keep that
    /// fixed schema. Each must be a key the env's infos have (`info::SCHEMA`, the `expert`
    /// keys with `expert`, `gt.<car>.<count>` with `diagnostics`); an unknown one is
    /// refused at creation (`InvalidOption`).
    info_keys: Option<Vec<String>>,
}

#[cfg(test)]
mod tests {
    use std::fmt::Write as _;

    use super::*;
    use crate::{Style, codec::encode};

    fn option(name: &str) -> &'static CreateOption {
        CREATE_OPTIONS.iter().find(|o| o.name == name).unwrap()
    }

    /// docs/protocol.md's list of the create options, as it stands between its markers.
    fn markdown() -> String {
        let mut table = String::from("| # | field | type | takes | what it does |\n|---|---|---|---|---|\n");
        for (index, option) in CREATE_OPTIONS.iter().enumerate() {
            let takes = match option.kind {
                OptionKind::Choice(names) => {
                    let names: Vec<_> = names().iter().map(|name| format!("`{}`", name.replace('|', "\\|"))).collect();
                    format!("one of {}", names.join(", "))
                }
                kind => kind.takes(),
            };
            let _ = writeln!(table, "| {index} | `{}` | `{}` | {takes} | {} |", option.name, option.wire, option.doc());
        }
        table
    }

    const BEGIN: &str = "<!-- create options: written from protocol/src/options.rs, checked by its tests -->\n";
    const END: &str = "<!-- end of the create options -->";

    /// Checks docs/protocol.md's list against the table; with `ARENA_WRITE_DOCS=1` it
    /// writes the table's list there instead.
    #[test]
    fn docs_protocol_md_lists_the_create_options_of_the_table() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/protocol.md");
        let text = std::fs::read_to_string(path).unwrap();
        let (before, rest) = text.split_once(BEGIN).expect("docs/protocol.md has the create options' first marker");
        let (listed, after) = rest.split_once(END).expect("docs/protocol.md has the create options' last marker");
        let expected = markdown();
        if std::env::var_os("ARENA_WRITE_DOCS").is_some_and(|v| v == "1") {
            std::fs::write(path, format!("{before}{BEGIN}{expected}{END}{after}")).unwrap();
            return;
        }
        assert!(
            listed == expected,
            "docs/protocol.md's create options are not the table's: run \
             `ARENA_WRITE_DOCS=1 cargo test -p arena-protocol options` to write them there"
        );
    }

    #[test]
    fn the_table_is_the_structs_fields_in_wire_order() {
        let names: Vec<_> = CREATE_OPTIONS.iter().map(|o| o.name).collect();
        assert_eq!(
            names,
            [
                "overrides",
                "action_type",
                "observation",
                "max_cycles",
                "render_size",
                "expert",
                "policy",
                "diagnostics",
                "record",
                "explain",
                "render_window",
                "info_keys"
            ]
        );
        assert_eq!(option("render_size").wire, "Option<(u32, u32)>");
        assert_eq!(option("overrides").wire, "Vec<(String, OptionValue)>");
        assert!(option("max_cycles").doc().starts_with("Episode length in steps, instead of the scenario's"));
        // Each option set through the table lands in its own field, the others untouched:
        // the bytes of the whole struct say so.
        let mut options = CreateOptions::default();
        (option("explain").set)(&mut options, Given::Flag(true)).unwrap();
        (option("max_cycles").set)(&mut options, Given::Count(9)).unwrap();
        assert_eq!(options, CreateOptions { explain: true, max_cycles: Some(9), ..CreateOptions::default() });
        let last = encode(&options);
        assert_eq!(
            &last[last.len() - 5..],
            [0, 0, 1, 0, 0],
            "diagnostics, record, explain, render_window, info_keys end the bytes"
        );
    }

    #[test]
    fn each_kind_reads_what_it_takes_and_says_what_is_wrong() {
        let mut options = CreateOptions::default();
        let mut set = |name: &str, given| (option(name).set)(&mut options, given);
        set("action_type", Given::Name("continuous".into())).unwrap();
        set("policy", Given::Name("gt:aggressive:nash".into())).unwrap();
        set("render_size", Given::Pair(60, 120)).unwrap();
        set("overrides", Given::Overrides(vec![("traffic.count".into(), OptionValue::Int(3))])).unwrap();
        assert_eq!(set("max_cycles", Given::Count(-1)), Err("-1 is not a whole number from 0 to 4294967295".into()));
        assert_eq!(
            set("render_size", Given::Pair(60, 1 << 40)),
            Err("1099511627776 is not a whole number from 0 to 4294967295".into())
        );
        assert_eq!(
            set("observation", Given::Name("pixels".into())),
            Err("unknown observation 'pixels': use one of kinematics, kinematics_with_mask".into())
        );
        assert!(set("policy", Given::Name("calm".into())).unwrap_err().contains("gt:<aggressive"));
        assert_eq!(set("diagnostics", Given::Count(1)), Err("takes true or false, not Count(1)".into()));
        assert_eq!(
            options,
            CreateOptions {
                overrides: vec![("traffic.count".into(), OptionValue::Int(3))],
                action_type: Some(ActionType::Continuous),
                render_size: Some((60, 120)),
                policy: Some(BuiltinPolicy::Gt { style: Some(Style::Aggressive), game: Game::Nash }),
                ..CreateOptions::default()
            }
        );
        assert_eq!(option("expert").kind.takes(), "one of nash, stackelberg");
    }
}
