//! What the `restore` target and the seed writer (`write_seeds`) share: the envs the
//! target restores snapshots into, how they are brought to mid-episode, and the framing
//! of a snapshot around its body, so that each seed is the body of a real snapshot of
//! the very env the target points it at.

use arena_protocol::{
    ActionType, BuiltinPolicy, ClientId, CreateOptions, EnvId, Game, ObservationKind, PROTOCOL_VERSION, Reply,
    ReplyBody, Request, RequestBody, ResetOptions, ScenarioSource, decode, encode,
};
use arena_server::transport::Registry;
use sha3::Digest;

/// Who the fuzzed envs belong to.
pub const CLIENT: ClientId = ClientId(7);

/// The first bytes of every snapshot (server/src/env/snapshot.rs).
const MAGIC: &[u8; 8] = b"ARENASNP";

/// Bytes before a snapshot's body: the magic and the protocol version (u16, LE).
const HEADER: usize = MAGIC.len() + 2;

/// Bytes of a snapshot's SHA3-256 checksum, after the body.
const CHECKSUM: usize = 32;

/// The seed of the reset before a live env's steps, and how many steps it takes.
const RESET_SEED: u64 = 3;
const STEPS: u64 = 3;

/// An env the `restore` target holds: the name of its seed file, its scenario and its
/// create options.
pub struct RestoreEnv {
    /// Its seed's file name: the scenario's, and the options' when they are not its own.
    pub name: String,
    /// A built-in scenario.
    pub scenario: &'static str,
    pub options: CreateOptions,
}

/// The envs of the `restore` target, by index (an input's first byte modulo their
/// number): every shipped scenario with its own options, then three with options that
/// change what a snapshot holds or what a step checks (continuous actions and a masked
/// observation; an expert's memory in each agent; a built-in policy driving the learner).
pub fn restore_envs() -> Vec<RestoreEnv> {
    let mut envs: Vec<RestoreEnv> = arena_sim::BUILTIN_SCENARIOS
        .iter()
        .map(|&(scenario, ..)| RestoreEnv { name: scenario.into(), scenario, options: CreateOptions::default() })
        .collect();
    let continuous = CreateOptions {
        action_type: Some(ActionType::Continuous),
        observation: Some(ObservationKind::KinematicsWithMask),
        diagnostics: true,
        ..CreateOptions::default()
    };
    let expert = CreateOptions { expert: Some(Game::Stackelberg), ..CreateOptions::default() };
    let policy = BuiltinPolicy::Gt { style: None, game: Game::Nash };
    let policy = CreateOptions { policy: Some(policy), ..CreateOptions::default() };
    envs.push(RestoreEnv { name: "overtake-continuous".into(), scenario: "overtake", options: continuous });
    envs.push(RestoreEnv { name: "merge-expert".into(), scenario: "merge", options: expert });
    envs.push(RestoreEnv { name: "merge-random-policy".into(), scenario: "merge-random", options: policy });
    envs
}

/// The body of `request` sent as `CLIENT`, answered by `registry`.
pub fn ask(registry: &Registry, body: RequestBody) -> ReplyBody {
    let request = encode(&Request::new(CLIENT, body));
    decode::<Reply>(&registry.handle(&request)).expect("every reply decodes").body
}

/// Creates `spec`'s env, resets it and steps it `STEPS` times without actions; returns
/// its id and the last sequence number it was sent.
pub fn live_env(registry: &Registry, spec: &RestoreEnv) -> (EnvId, u64) {
    let scenario = ScenarioSource::Named(spec.scenario.into());
    let created = ask(registry, RequestBody::CreateEnv { scenario, options: spec.options.clone() });
    let ReplyBody::Created { env, .. } = created else { panic!("cannot create the {} env: {created:?}", spec.name) };
    let reset = RequestBody::Reset { env, seq: 1, seed: Some(RESET_SEED), options: ResetOptions::default() };
    let reply = ask(registry, reset);
    assert!(matches!(reply, ReplyBody::Reset(_)), "the {} env does not reset: {reply:?}", spec.name);
    for seq in 2..=STEPS + 1 {
        let reply = ask(registry, RequestBody::Step { env, seq, actions: vec![] });
        assert!(matches!(reply, ReplyBody::Step(_)), "the {} env does not step: {reply:?}", spec.name);
    }
    (env, STEPS + 1)
}

/// A snapshot of `body`: the header of this protocol version before it, a checksum that
/// matches after it.
pub fn framed(body: &[u8]) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(HEADER + body.len() + CHECKSUM);
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&PROTOCOL_VERSION.to_le_bytes());
    bytes.extend_from_slice(body);
    let checksum = sha3::Sha3_256::digest(&bytes);
    bytes.extend_from_slice(&checksum);
    bytes
}

/// The body of a snapshot the server made (`framed`'s inverse).
pub fn body(snapshot: &[u8]) -> &[u8] {
    assert!(snapshot.starts_with(MAGIC) && snapshot.len() > HEADER + CHECKSUM, "not a snapshot");
    &snapshot[HEADER..snapshot.len() - CHECKSUM]
}
