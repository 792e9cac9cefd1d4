//! Property-based fuzzing of what arrives from outside the process, bounded so it runs in
//! the default test command: random and mutated request payloads fed to the registry's
//! request handler. Every reply is the documented answer to what arrived: bytes that are
//! not a request get `MalformedRequest` or `WrongVersion`; a request gets a reply of its
//! own kind or a coded refusal that is never `Internal` (no panic) and never touches an
//! env it does not own; and the registry answers a good request afterwards.
//!
//! Snapshots, mutated and restored (`mutated_snapshots_are_refused_or_restore_a_sound_env`):
//! real snapshots of envs of several scenarios and options, their bodies changed byte by
//! byte and field by field and their checksums made to match again (as anyone can), sent
//! as `Restore`. A refusal is coded, never `Internal`, and leaves the env as it was; an
//! accepted one leaves an env that holds what a stepped one does: finite observations, a
//! snapshot of its own that a fresh env of the same scenario and options restores and
//! snapshots back to the same bytes, and three steps that each get a step reply with
//! finite observations and rewards, the same as the fresh env's, or a coded refusal.
//!
//! Longer runs: raise PROPTEST_CASES; the cargo-fuzz targets in fuzz/ run longer still.

use std::ops::Range;
use std::sync::LazyLock;

use arena_protocol::{
    Action, ActionType, BuiltinPolicy, ClientId, CreateOptions, EnvId, ErrorCode, Game, ObservationKind, OptionValue,
    PROTOCOL_VERSION, Reply, ReplyBody, Request, RequestBody, ResetOptions, ScenarioSource, TensorData, decode, encode,
};
use arena_server::transport::{Limits, Registry, Scenarios};
use arena_sim::{GtMemory, RngState, Vehicle, WorldState};
use proptest::prelude::*;
use proptest::sample::{Index, select};
use serde::de::DeserializeOwned;

fn registry() -> Registry {
    Registry::new("fuzz".into(), Scenarios::load(None).expect("built-in scenarios"), Limits::default())
}

/// Valid requests of every kind the mutations start from.
fn seeds() -> Vec<Vec<u8>> {
    let request = |body| encode(&Request { version: PROTOCOL_VERSION, client: ClientId(7), body });
    vec![
        request(RequestBody::ServerInfo),
        request(RequestBody::CreateEnv {
            scenario: ScenarioSource::Named("merge".into()),
            options: CreateOptions::default(),
        }),
        request(RequestBody::Reset { env: EnvId(3), seq: 1, seed: Some(4), options: ResetOptions::default() }),
        request(RequestBody::Step { env: EnvId(3), seq: 2, actions: vec![("ec_0".into(), Action::Meta(3))] }),
        request(RequestBody::Record { env: EnvId(3), on: true }),
        request(RequestBody::Snapshot { env: EnvId(3) }),
        request(RequestBody::Render {
            env: EnvId(3),
            mode: arena_protocol::RenderMode::RgbArray,
            follow: Some("ac".into()),
        }),
        request(RequestBody::Statistics { env: EnvId(3) }),
        request(RequestBody::Restore { env: EnvId(3), seq: 3, snapshot: b"ARENASNP\x07\x00 not a state".to_vec() }),
    ]
}

/// The reply to `bytes` is the one the protocol documents for them.
fn answered(registry: &Registry, bytes: &[u8]) {
    let reply: Reply = decode(&registry.handle(bytes)).expect("a reply");
    assert_eq!(reply.version, PROTOCOL_VERSION);
    let refused = |reply: &Reply| match &reply.body {
        ReplyBody::Error(e) => Some(e.code),
        _ => None,
    };
    match decode::<Request>(bytes) {
        Err(_) => {
            let code = refused(&reply);
            assert!(
                matches!(code, Some(ErrorCode::MalformedRequest | ErrorCode::WrongVersion)),
                "bytes that are no request got {code:?}"
            );
        }
        Ok(request) => {
            assert_ne!(refused(&reply), Some(ErrorCode::Internal), "{request:?} made the server panic");
            let kind_matches = match (&request.body, &reply.body) {
                (_, ReplyBody::Error(e)) if request.version != PROTOCOL_VERSION => e.code == ErrorCode::WrongVersion,
                (RequestBody::ServerInfo, ReplyBody::ServerInfo(_)) => true,
                (RequestBody::CreateEnv { .. }, ReplyBody::Created { .. }) => true,
                (RequestBody::CreateEnv { .. }, ReplyBody::Error(e)) => matches!(
                    e.code,
                    ErrorCode::UnknownScenario | ErrorCode::InvalidScenario | ErrorCode::PayloadTooLarge
                ),
                // No env was created for these ids: every env request meets an unknown env.
                (RequestBody::StepBatch { steps }, ReplyBody::StepBatch(items)) => items.len() == steps.len(),
                (RequestBody::StepBatch { .. } | RequestBody::Close { .. }, ReplyBody::Error(e))
                | (RequestBody::Reset { .. } | RequestBody::Step { .. }, ReplyBody::Error(e))
                | (
                    RequestBody::Render { .. }
                    | RequestBody::State { .. }
                    | RequestBody::Specs { .. }
                    | RequestBody::Record { .. }
                    | RequestBody::Snapshot { .. }
                    | RequestBody::Statistics { .. }
                    | RequestBody::Restore { .. },
                    ReplyBody::Error(e),
                ) => {
                    matches!(e.code, ErrorCode::UnknownEnv | ErrorCode::PayloadTooLarge | ErrorCode::MalformedRequest)
                }
                _ => false,
            };
            assert!(kind_matches, "{request:?} got {:?}", reply.body);
        }
    }
    let info = encode(&Request::new(ClientId(1), RequestBody::ServerInfo));
    assert!(matches!(decode::<Reply>(&registry.handle(&info)).map(|r| r.body), Ok(ReplyBody::ServerInfo(_))));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    #[test]
    fn random_payloads_are_answered(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
        answered(&registry(), &bytes);
    }

    #[test]
    fn mutated_requests_are_answered(
        which in any::<prop::sample::Index>(),
        flips in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
        cut in any::<prop::sample::Index>(),
        truncate in any::<bool>(),
    ) {
        let registry = registry();
        let seeds = seeds();
        let mut bytes = seeds[which.index(seeds.len())].clone();
        for (at, value) in flips {
            let i = at.index(bytes.len());
            bytes[i] = value;
        }
        if truncate {
            bytes.truncate(cut.index(bytes.len() + 1));
        }
        answered(&registry, &bytes);
    }

    /// A real snapshot, damaged (bytes changed, cut short, and with its checksum made to
    /// match again, as a forger would): restored or refused as `InvalidSnapshot`, never a
    /// panic, and the env steps on.
    #[test]
    fn damaged_snapshots_are_refused_or_restored(
        flips in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
        cut in any::<prop::sample::Index>(),
        truncate in any::<bool>(),
        forge in any::<bool>(),
    ) {
        let (registry, env, mut bytes) = live_snapshot();
        let body = bytes.len() - 32;
        for (at, value) in flips {
            // Past the header: the header's own refusals have their unit test.
            let i = 10 + at.index(body - 10);
            bytes[i] = value;
        }
        if truncate {
            bytes.truncate(cut.index(bytes.len() + 1));
        }
        if forge && bytes.len() > 42 {
            let end = bytes.len() - 32;
            let checksum = <sha3::Sha3_256 as sha3::Digest>::digest(&bytes[..end]);
            bytes[end..].copy_from_slice(&checksum);
        }
        let reply = ask(&registry, RequestBody::Restore { env, seq: 5, snapshot: bytes });
        match reply {
            ReplyBody::Reset(_) => {}
            ReplyBody::Error(e) => prop_assert_eq!(e.code, ErrorCode::InvalidSnapshot, "{}", e),
            other => prop_assert!(false, "a restore got {:?}", other),
        }
        let step = ask(&registry, RequestBody::Step { env, seq: 6, actions: vec![] });
        let steps_on = match &step {
            ReplyBody::Step(_) => true,
            ReplyBody::Error(e) => e.code == ErrorCode::AgentNotLive,
            _ => false,
        };
        prop_assert!(steps_on, "after a restore, a step got {:?}", step);
    }
}

fn ask(registry: &Registry, body: RequestBody) -> ReplyBody {
    let reply: Reply = decode(&registry.handle(&encode(&Request::new(ClientId(7), body)))).expect("a reply");
    reply.body
}

/// A registry with a merge env stepped three times, and that env's snapshot.
fn live_snapshot() -> (Registry, EnvId, Vec<u8>) {
    let registry = registry();
    let scenario = ScenarioSource::Named("merge".into());
    let ReplyBody::Created { env, .. } =
        ask(&registry, RequestBody::CreateEnv { scenario, options: CreateOptions::default() })
    else {
        panic!("merge is created")
    };
    let reset = RequestBody::Reset { env, seq: 1, seed: Some(3), options: ResetOptions::default() };
    assert!(matches!(ask(&registry, reset), ReplyBody::Reset(_)));
    for seq in 2..=4 {
        assert!(matches!(ask(&registry, RequestBody::Step { env, seq, actions: vec![] }), ReplyBody::Step(_)));
    }
    let ReplyBody::Snapshot(bytes) = ask(&registry, RequestBody::Snapshot { env }) else { panic!("a snapshot") };
    (registry, env, bytes)
}

// Snapshots, mutated and restored.

/// The envs whose snapshots are mutated: shipped scenarios, and options that change what
/// a snapshot holds (an expert's memory in each agent, a built-in policy driving the
/// learner) or what a step checks (continuous actions, a masked observation).
fn snapshot_envs() -> Vec<(&'static str, CreateOptions)> {
    let continuous = CreateOptions {
        action_type: Some(ActionType::Continuous),
        observation: Some(ObservationKind::KinematicsWithMask),
        diagnostics: true,
        ..CreateOptions::default()
    };
    let expert = CreateOptions { expert: Some(Game::Stackelberg), ..CreateOptions::default() };
    let policy = BuiltinPolicy::Gt { style: None, game: Game::Nash };
    vec![
        ("merge", CreateOptions::default()),
        ("merge-random", CreateOptions::default()),
        ("highway-gt", CreateOptions::default()),
        ("overtake", continuous),
        ("merge", expert),
        ("highway", CreateOptions { policy: Some(policy), ..CreateOptions::default() }),
    ]
}

/// Bytes before a snapshot's body (magic, protocol version) and of the checksum after it.
const HEADER: usize = 10;
const CHECKSUM: usize = 32;

fn body_of(snapshot: &[u8]) -> &[u8] {
    &snapshot[HEADER..snapshot.len() - CHECKSUM]
}

/// `body` framed as a snapshot: the header of a real one, and a checksum that matches.
fn framed(body: &[u8]) -> Vec<u8> {
    let mut bytes = b"ARENASNP".to_vec();
    bytes.extend_from_slice(&PROTOCOL_VERSION.to_le_bytes());
    bytes.extend_from_slice(body);
    let checksum = <sha3::Sha3_256 as sha3::Digest>::digest(&bytes);
    bytes.extend_from_slice(&checksum);
    bytes
}

/// Where a snapshot body's fields lie, as far as their public types let them be found:
/// the body is the server's private `Body` (scenario, hash, options, then the env's state:
/// world seed, reset overrides, seed stream, cycles, agents; then the world's state) in
/// the protocol's codec, and a field of public type `T` at a known start ends where the
/// bytes first decode as a whole `T`. Of the agents, the first one's vehicle and expert
/// memory are found; then the world, and in it that vehicle's state (its eight floats
/// begin the vehicle).
#[derive(Debug, Clone)]
struct Layout {
    world_seed: Range<usize>,
    overrides: Range<usize>,
    seeds: Range<usize>,
    cycles: Range<usize>,
    agents: Range<usize>,
    vehicle: Range<usize>,
    live: Range<usize>,
    expert: Range<usize>,
    world: Range<usize>,
    learner: Range<usize>,
}

/// The bytes from `at` that are one whole `T`.
fn span<T: DeserializeOwned>(body: &[u8], at: usize) -> Range<usize> {
    let end = (at..=body.len()).find(|&end| decode::<T>(&body[at..end]).is_ok());
    at..end.unwrap_or_else(|| panic!("no {} at byte {at} of a snapshot body", std::any::type_name::<T>()))
}

impl Layout {
    fn of(body: &[u8]) -> Layout {
        let scenario = span::<String>(body, 0);
        let hash = span::<[u8; 32]>(body, scenario.end);
        let options = span::<String>(body, hash.end);
        let world_seed = span::<u64>(body, options.end);
        let overrides = span::<Vec<(String, OptionValue)>>(body, world_seed.end);
        let seeds = span::<RngState>(body, overrides.end);
        let cycles = span::<u32>(body, seeds.end);
        let count = span::<u64>(body, cycles.end);
        let vehicle = span::<u32>(body, count.end);
        let live = span::<bool>(body, vehicle.end);
        let expert = span::<Option<GtMemory>>(body, live.end);
        // The first place after the first agent's expert from which the rest decodes as a
        // world.
        let world = (expert.end..body.len())
            .find(|&at| decode::<WorldState>(&body[at..]).is_ok())
            .expect("a world at the end of a snapshot body");
        let index: u32 = decode(&body[vehicle.clone()]).expect("the agent's vehicle id");
        let mut at = span::<u64>(body, world).end;
        for _ in 0..index {
            at = span::<Vehicle>(body, at).end;
        }
        // A vehicle's state is its first field.
        let learner = at;
        Layout {
            world_seed,
            overrides,
            seeds,
            cycles: cycles.clone(),
            agents: cycles.end..world,
            vehicle,
            live,
            expert,
            world: world..body.len(),
            learner: learner..learner + 64,
        }
    }

    fn field(&self, field: Field) -> Range<usize> {
        match field {
            Field::Seeds => self.seeds.clone(),
            Field::Agents => self.agents.clone(),
            Field::Expert => self.expert.clone(),
            Field::World => self.world.clone(),
        }
    }
}

/// A real snapshot the mutations start from, of env `env` of `snapshot_envs`.
struct Base {
    env: usize,
    snapshot: Vec<u8>,
    layout: Layout,
}

/// Two snapshots of each env of `snapshot_envs`, of different episodes and times.
static BASES: LazyLock<Vec<Base>> = LazyLock::new(|| {
    let registry = registry();
    let mut bases = Vec::new();
    for (env, (scenario, options)) in snapshot_envs().into_iter().enumerate() {
        for (seed, steps) in [(3, 3), (11, 8)] {
            let mut handle = Handle::create(&registry, scenario, &options);
            assert!(matches!(handle.reset(seed), ReplyBody::Reset(_)), "{scenario} resets");
            for _ in 0..steps {
                assert!(matches!(handle.step(), ReplyBody::Step(_)), "{scenario} steps");
            }
            let snapshot = handle.snapshot().expect("a stepped env's snapshot");
            bases.push(Base { env, layout: Layout::of(body_of(&snapshot)), snapshot });
        }
    }
    bases
});

/// An env in a registry, and the last sequence number sent to it.
struct Handle<'a> {
    registry: &'a Registry,
    env: EnvId,
    seq: u64,
}

impl<'a> Handle<'a> {
    fn create(registry: &'a Registry, scenario: &str, options: &CreateOptions) -> Handle<'a> {
        let scenario = ScenarioSource::Named(scenario.into());
        let created = ask(registry, RequestBody::CreateEnv { scenario, options: options.clone() });
        let ReplyBody::Created { env, .. } = created else { panic!("cannot create an env: {created:?}") };
        Handle { registry, env, seq: 0 }
    }

    fn sequenced(&mut self, body: impl FnOnce(EnvId, u64) -> RequestBody) -> ReplyBody {
        self.seq += 1;
        ask(self.registry, body(self.env, self.seq))
    }

    fn reset(&mut self, seed: u64) -> ReplyBody {
        self.sequenced(|env, seq| RequestBody::Reset { env, seq, seed: Some(seed), options: ResetOptions::default() })
    }

    fn step(&mut self) -> ReplyBody {
        self.sequenced(|env, seq| RequestBody::Step { env, seq, actions: vec![] })
    }

    fn restore(&mut self, snapshot: Vec<u8>) -> ReplyBody {
        self.sequenced(|env, seq| RequestBody::Restore { env, seq, snapshot })
    }

    /// The env's snapshot, or what was answered instead.
    fn snapshot(&self) -> Result<Vec<u8>, String> {
        match ask(self.registry, RequestBody::Snapshot { env: self.env }) {
            ReplyBody::Snapshot(bytes) => Ok(bytes),
            other => Err(format!("{other:?}")),
        }
    }
}

/// A field found by `Layout` that a mutation replaces or changes in place.
#[derive(Debug, Clone, Copy)]
enum Field {
    Seeds,
    Agents,
    Expert,
    World,
}

/// A change of one field of a body, made with its public type.
#[derive(Debug, Clone)]
enum FieldMutation {
    WorldSeed(u64),
    Overrides(Vec<(String, OptionValue)>),
    Cycles(u32),
    Vehicle(u32),
    /// The first agent live if it was not, and not if it was.
    Live,
    /// A float of the expert's memory or the world (one of those `floats` finds, picked
    /// by `at`) overwritten with `value`, the field still decoding as its type.
    Float {
        field: Field,
        at: Index,
        value: f64,
    },
    /// One of the eight floats of the first agent's vehicle state (speeds, heading,
    /// position, steering) overwritten with `value`.
    Learner {
        float: usize,
        value: f64,
    },
    /// The field as another base snapshot (another time, episode or env) has it.
    Donor {
        field: Field,
        donor: Index,
    },
}

/// A change of a body's bytes, blind to its fields.
#[derive(Debug, Clone)]
enum ByteMutation {
    Flip { at: Index, bit: u8 },
    Set { at: Index, value: u8 },
    Insert { at: Index, bytes: Vec<u8> },
    Remove { at: Index, len: usize },
    Truncate { at: Index },
}

/// The largest finite size the floats written into a body take. Larger ones are left out
/// while they break the property for a reason outside snapshots: a vehicle whose speed,
/// heading or steering is finite but huge (past 1e170) passes the state checks, which ask
/// for finite numbers, and the dynamics overflow to NaN within a step; a scenario's
/// speeds need only be finite too, so overtake with continuous actions and the override
/// `vehicle.ec_0.speed = 1e180` steps to the same NaN from `CreateEnv`. The `restore`
/// fuzz target finds these (docs/reliability.md, "Longer fuzz runs"). Up to 1e9 holds:
/// merge's, merge-random's and overtake's learner with any of its eight state numbers at
/// +-1e9 (or 1e3, 100, 10, 1) steps three times to finite observations.
const MAX_FINITE: f64 = 1e9;

fn special_float() -> impl Strategy<Value = f64> {
    let specials = vec![
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        0.0,
        -0.0,
        -1.0,
        1e-300,
        f64::MIN_POSITIVE,
        MAX_FINITE,
        -MAX_FINITE,
    ];
    prop_oneof![3 => select(specials), 1 => -MAX_FINITE..=MAX_FINITE]
}

fn option_value() -> impl Strategy<Value = OptionValue> {
    prop_oneof![
        any::<bool>().prop_map(OptionValue::Bool),
        select(vec![0, 1, -1, 3, 1 << 20, i64::MAX, i64::MIN]).prop_map(OptionValue::Int),
        special_float().prop_map(OptionValue::Float),
        select(vec!["aggressive", "nash", "", "{ kind = \"idm\" }"]).prop_map(|s| OptionValue::Str(s.into())),
    ]
}

fn field() -> impl Strategy<Value = Field> {
    select(vec![Field::Seeds, Field::Agents, Field::Expert, Field::World])
}

fn field_mutation() -> impl Strategy<Value = FieldMutation> {
    let keys = vec![
        "vehicle.ac.speed",
        "vehicle.ac.s",
        "vehicle.ec_0.speed",
        "vehicle.ec_0.lane",
        "vehicle.ac.driver.style",
        "road.lanes",
        "sim.max_cycles",
        "no.such.key",
    ];
    let overrides = proptest::collection::vec((select(keys).prop_map(String::from), option_value()), 0..4);
    // The floats weigh most: a number that is not finite in the learner's state is what
    // a step turns into observations at once.
    prop_oneof![
        1 => any::<u64>().prop_map(FieldMutation::WorldSeed),
        1 => overrides.prop_map(FieldMutation::Overrides),
        1 => prop_oneof![0u32..400, any::<u32>()].prop_map(FieldMutation::Cycles),
        1 => prop_oneof![0u32..8, any::<u32>()].prop_map(FieldMutation::Vehicle),
        1 => Just(FieldMutation::Live),
        2 => (select(vec![Field::Expert, Field::World]), any::<Index>(), special_float())
            .prop_map(|(field, at, value)| FieldMutation::Float { field, at, value }),
        3 => (0usize..8, special_float()).prop_map(|(float, value)| FieldMutation::Learner { float, value }),
        1 => (field(), any::<Index>()).prop_map(|(field, donor)| FieldMutation::Donor { field, donor }),
    ]
}

fn byte_mutation() -> impl Strategy<Value = ByteMutation> {
    prop_oneof![
        (any::<Index>(), 0u8..8).prop_map(|(at, bit)| ByteMutation::Flip { at, bit }),
        (any::<Index>(), any::<u8>()).prop_map(|(at, value)| ByteMutation::Set { at, value }),
        (any::<Index>(), proptest::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(at, bytes)| ByteMutation::Insert { at, bytes }),
        (any::<Index>(), 1usize..64).prop_map(|(at, len)| ByteMutation::Remove { at, len }),
        any::<Index>().prop_map(|at| ByteMutation::Truncate { at }),
    ]
}

/// `bytes` with `range` replaced by `with`.
fn spliced(bytes: &[u8], range: Range<usize>, with: &[u8]) -> Vec<u8> {
    [&bytes[..range.start], with, &bytes[range.end..]].concat()
}

/// Where in `region` a float of the state likely starts: eight bytes that read as one of
/// the sizes a state holds (zero, or between 1e-9 and 1e7 in magnitude), each place
/// eight bytes past the one before at least, so a run of zeros (0.0 beside 0.0) gives
/// the places of its floats, not a place inside two. Eight bytes across two floats
/// rarely read so otherwise (their exponent comes from inside a mantissa).
fn floats(region: &[u8]) -> Vec<usize> {
    let plausible = |x: f64| x == 0.0 || (1e-9..=1e7).contains(&x.abs());
    let read = |i: usize| f64::from_le_bytes(region[i..i + 8].try_into().expect("eight bytes"));
    let mut places = Vec::new();
    let mut i = 0;
    while i + 8 <= region.len() {
        if plausible(read(i)) {
            places.push(i);
            i += 8;
        } else {
            i += 1;
        }
    }
    places
}

/// `region` with the `which`th of its `floats` that can be overwritten by `value`, the
/// region still decoding as a `T` other than it was, so overwritten; `None` if none can.
fn float_in<T: DeserializeOwned>(region: &[u8], which: &Index, value: f64) -> Option<Vec<u8>> {
    let places = floats(region);
    let first = which.index(places.len().max(1));
    places.iter().cycle().skip(first).take(places.len()).find_map(|&i| {
        let changed = spliced(region, i..i + 8, &value.to_le_bytes());
        (changed != region && decode::<T>(&changed).is_ok()).then_some(changed)
    })
}

/// `base`'s body with `mutation` applied.
fn field_mutated(base: &Base, mutation: &FieldMutation) -> Vec<u8> {
    let body = body_of(&base.snapshot);
    let layout = &base.layout;
    match mutation {
        FieldMutation::WorldSeed(seed) => spliced(body, layout.world_seed.clone(), &encode(seed)),
        FieldMutation::Overrides(overrides) => spliced(body, layout.overrides.clone(), &encode(overrides)),
        FieldMutation::Cycles(cycles) => spliced(body, layout.cycles.clone(), &encode(cycles)),
        FieldMutation::Vehicle(vehicle) => spliced(body, layout.vehicle.clone(), &encode(vehicle)),
        FieldMutation::Live => spliced(body, layout.live.clone(), &[1 - body[layout.live.start]]),
        FieldMutation::Float { field, at, value } => {
            let range = layout.field(*field);
            let region = &body[range.clone()];
            let changed = match field {
                Field::World => float_in::<WorldState>(region, at, *value),
                _ => float_in::<Option<GtMemory>>(region, at, *value),
            };
            changed.map_or_else(|| body.to_vec(), |changed| spliced(body, range, &changed))
        }
        FieldMutation::Learner { float, value } => {
            let at = layout.learner.start + 8 * float;
            spliced(body, at..at + 8, &value.to_le_bytes())
        }
        FieldMutation::Donor { field, donor } => {
            let donor = &BASES[donor.index(BASES.len())];
            let with = &body_of(&donor.snapshot)[donor.layout.field(*field)];
            spliced(body, layout.field(*field), with)
        }
    }
}

fn byte_mutated(mut body: Vec<u8>, mutation: &ByteMutation) -> Vec<u8> {
    let at = |at: &Index, len: usize| at.index(len.max(1)).min(len);
    match mutation {
        ByteMutation::Flip { at: i, bit } if !body.is_empty() => {
            let i = i.index(body.len());
            body[i] ^= 1 << bit;
        }
        ByteMutation::Set { at: i, value } if !body.is_empty() => {
            let i = i.index(body.len());
            body[i] = *value;
        }
        ByteMutation::Insert { at: i, bytes } => {
            let i = at(i, body.len() + 1);
            body.splice(i..i, bytes.iter().copied());
        }
        ByteMutation::Remove { at: i, len } => {
            let i = at(i, body.len());
            body.drain(i..(i + len).min(body.len()));
        }
        ByteMutation::Truncate { at: i } => body.truncate(at(i, body.len() + 1)),
        ByteMutation::Flip { .. } | ByteMutation::Set { .. } => {}
    }
    body
}

/// Whether every number an observation holds is finite.
fn finite_observation(observation: &arena_protocol::Observation) -> bool {
    let finite = |data: &TensorData| match data {
        TensorData::F32(values) => values.iter().all(|v| v.is_finite()),
        TensorData::U8(_) | TensorData::I8(_) | TensorData::I64(_) => true,
    };
    match observation {
        arena_protocol::Observation::Tensor(tensor) => finite(&tensor.data),
        arena_protocol::Observation::Dict(entries) => entries.iter().all(|(_, tensor)| finite(&tensor.data)),
    }
}

/// A step's reply after an accepted restore: a step with finite observations and rewards,
/// or a coded refusal.
fn check_step(reply: &ReplyBody) -> Result<(), TestCaseError> {
    match reply {
        ReplyBody::Step(step) => {
            for agent in &step.steps {
                prop_assert!(finite_observation(&agent.observation), "{}'s observation: {:?}", agent.agent, agent);
                prop_assert!(agent.reward.is_finite(), "{}'s reward {}", agent.agent, agent.reward);
            }
        }
        ReplyBody::Error(e) => prop_assert_ne!(e.code, ErrorCode::Internal, "a step after a restore: {}", e),
        other => prop_assert!(false, "a step after a restore got {:?}", other),
    }
    Ok(())
}

/// What an env that took a restore holds: its snapshot restores into a fresh env of the
/// same scenario and options, which snapshots it back to the same bytes; three steps
/// each get a step reply or a coded refusal, the fresh env's the same; and it still
/// snapshots after them.
fn check_accepted(env: &mut Handle, scenario: &str, options: &CreateOptions) -> Result<(), TestCaseError> {
    let snapshot = env.snapshot();
    prop_assert!(snapshot.is_ok(), "the restored env's snapshot got {:?}", snapshot);
    let snapshot = snapshot.unwrap_or_default();
    let mut fresh = Handle::create(env.registry, scenario, options);
    let reply = fresh.restore(snapshot.clone());
    prop_assert!(matches!(reply, ReplyBody::Reset(_)), "a fresh env refused a restored env's snapshot: {:?}", reply);
    prop_assert!(fresh.snapshot().as_ref() == Ok(&snapshot), "the fresh env snapshots other bytes");
    fresh.seq = env.seq;
    for _ in 0..3 {
        let (reply, fresh_reply) = (env.step(), fresh.step());
        check_step(&reply)?;
        prop_assert_eq!(&reply, &fresh_reply, "the restored env and a fresh one restored from it step apart");
    }
    let after = env.snapshot();
    prop_assert!(after.is_ok(), "the restored env's snapshot after three steps got {:?}", after);
    Ok(())
}

/// Restores `base` into a new env, then `body` framed as a snapshot, and checks the reply.
fn restore_mutated(base: &Base, body: &[u8]) -> Result<(), TestCaseError> {
    let (scenario, options) = &snapshot_envs()[base.env];
    let registry = registry();
    let mut env = Handle::create(&registry, scenario, options);
    prop_assert!(matches!(env.restore(base.snapshot.clone()), ReplyBody::Reset(_)), "{} restores", scenario);
    match env.restore(framed(body)) {
        ReplyBody::Reset(reset) => {
            for agent in &reset.agents {
                prop_assert!(finite_observation(&agent.observation), "restored {}: {:?}", agent.agent, agent);
            }
            check_accepted(&mut env, scenario, options)
        }
        ReplyBody::Error(e) => {
            prop_assert_ne!(e.code, ErrorCode::Internal, "a restore: {}", e);
            prop_assert!(env.snapshot().as_ref() == Ok(&base.snapshot), "a refused restore ({}) changed the env", e);
            Ok(())
        }
        other => Err(TestCaseError::fail(format!("a restore got {other:?}"))),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// Real snapshots of envs of several scenarios and options (`snapshot_envs`), a
    /// field of their body changed with its type (or not) and then bytes of it changed
    /// blind (or not), checksum made to match: see the top of the file for what holds.
    #[test]
    fn mutated_snapshots_are_refused_or_restore_a_sound_env(
        base in any::<Index>(),
        field in proptest::option::weighted(0.75, field_mutation()),
        bytes in proptest::collection::vec(byte_mutation(), 0..3),
    ) {
        let base = &BASES[base.index(BASES.len())];
        let body = field.as_ref().map_or_else(|| body_of(&base.snapshot).to_vec(), |m| field_mutated(base, m));
        let body = bytes.iter().fold(body, byte_mutated);
        restore_mutated(base, &body)?;
    }
}
