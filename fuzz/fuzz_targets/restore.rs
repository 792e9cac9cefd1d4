//! Feeds arbitrary snapshot bodies to `Restore` through the server's request handler
//! (`Registry::handle`), as a client may send any. The input's first byte picks one of
//! the live envs (`arena_fuzz::restore_envs`: every shipped scenario, and options with
//! continuous actions, an expert, a built-in policy), created once for the run and taken
//! to mid-episode; the rest is a snapshot body, to which the harness adds the header and
//! a matching checksum, so every mutation reaches the body's decoding and checks (the
//! checksum tells damage, not forgery). Holds:
//!
//! - no panic and no hang; a refused restore is a coded refusal, never `Internal`;
//! - an accepted restore leaves an env like a stepped one: its observations are finite,
//!   its own snapshot is taken, and that snapshot restores into a fresh env of the same
//!   scenario and options, whose snapshot is then the same bytes; three steps each get a
//!   step reply with finite observations and rewards, or a coded refusal; after them
//!   the env's snapshot is taken again.
#![no_main]

use std::sync::{LazyLock, Mutex};

use arena_fuzz::{CLIENT, RestoreEnv, ask, framed, live_env, restore_envs};
use arena_protocol::{
    AgentStart, AgentStep, EnvId, ErrorCode, Observation, Reply, ReplyBody, Request, RequestBody, ScenarioSource,
    TensorData, decode, encode,
};
use arena_server::transport::{Limits, Registry, Scenarios};
use libfuzzer_sys::fuzz_target;

/// Steps taken after an accepted restore.
const STEPS: usize = 3;

/// A live env: its id and the last sequence number sent to it.
struct Live {
    id: EnvId,
    seq: u64,
}

struct Harness {
    registry: Registry,
    specs: Vec<RestoreEnv>,
    live: Mutex<Vec<Live>>,
}

static HARNESS: LazyLock<Harness> = LazyLock::new(|| {
    let registry = Registry::new("fuzz".into(), Scenarios::load(None).expect("built-in scenarios"), Limits::default());
    let specs = restore_envs();
    let live = specs.iter().map(|spec| live_env(&registry, spec)).map(|(id, seq)| Live { id, seq }).collect();
    Harness { registry, specs, live: Mutex::new(live) }
});

/// A sequenced request (`make` given the next sequence number) to `env`, answered the
/// way a server does: a step or reset that leaves the episode going lets the env decide
/// ahead once the reply is out.
fn sequenced(registry: &Registry, env: &mut Live, make: impl FnOnce(EnvId, u64) -> RequestBody) -> ReplyBody {
    env.seq += 1;
    let request = encode(&Request::new(CLIENT, make(env.id, env.seq)));
    let (reply, ahead) = registry.handle_then(None, &request);
    if let Some(ahead) = ahead {
        registry.decide_ahead(ahead);
    }
    decode::<Reply>(&reply).expect("every reply decodes").body
}

fn finite(observation: &Observation) -> bool {
    let tensors: Vec<&TensorData> = match observation {
        Observation::Tensor(tensor) => vec![&tensor.data],
        Observation::Dict(entries) => entries.iter().map(|(_, tensor)| &tensor.data).collect(),
    };
    tensors.into_iter().all(|data| match data {
        TensorData::F32(values) => values.iter().all(|v| v.is_finite()),
        TensorData::U8(_) | TensorData::I8(_) | TensorData::I64(_) => true,
    })
}

fn check_start(start: &AgentStart) {
    assert!(finite(&start.observation), "a restored observation of {} is not finite", start.agent);
}

fn check_step(step: &AgentStep) {
    assert!(finite(&step.observation), "an observation of {} is not finite", step.agent);
    assert!(step.reward.is_finite(), "{}'s reward {} is not finite", step.agent, step.reward);
}

/// A refusal names what it refuses: never `Internal`, which a panic inside a request is.
fn check_refusal(what: &str, reply: &ReplyBody) {
    match reply {
        ReplyBody::Error(e) => assert_ne!(e.code, ErrorCode::Internal, "{what}: {e}"),
        other => panic!("{what} got {other:?}"),
    }
}

/// The env's snapshot, which an env that restored or stepped always has.
fn snapshot(registry: &Registry, env: EnvId, when: &str) -> Vec<u8> {
    match ask(registry, RequestBody::Snapshot { env }) {
        ReplyBody::Snapshot(bytes) => bytes,
        other => panic!("{when}, the env's snapshot got {other:?}"),
    }
}

/// `snapshot` restores into a fresh env of `spec`, whose own snapshot is then the same.
fn restores_into_fresh(registry: &Registry, spec: &RestoreEnv, snapshot: Vec<u8>) {
    let scenario = ScenarioSource::Named(spec.scenario.into());
    let created = ask(registry, RequestBody::CreateEnv { scenario, options: spec.options.clone() });
    let ReplyBody::Created { env, .. } = created else {
        panic!("cannot create a fresh {} env: {created:?}", spec.name)
    };
    let mut fresh = Live { id: env, seq: 0 };
    let reply =
        sequenced(registry, &mut fresh, |env, seq| RequestBody::Restore { env, seq, snapshot: snapshot.clone() });
    assert!(
        matches!(reply, ReplyBody::Reset(_)),
        "a fresh {} env refused a restored env's snapshot: {reply:?}",
        spec.name
    );
    let again = self::snapshot(registry, env, "restored from a restored env's snapshot");
    assert!(again == snapshot, "a fresh {} env restored from a snapshot snapshots other bytes", spec.name);
    assert!(matches!(ask(registry, RequestBody::Close { env }), ReplyBody::Closed));
}

/// The invariants of an env that took a restore.
fn accepted(registry: &Registry, spec: &RestoreEnv, env: &mut Live) {
    restores_into_fresh(registry, spec, snapshot(registry, env.id, "after an accepted restore"));
    for _ in 0..STEPS {
        match sequenced(registry, env, |env, seq| RequestBody::Step { env, seq, actions: vec![] }) {
            ReplyBody::Step(step) => step.steps.iter().for_each(check_step),
            refused => check_refusal("a step after an accepted restore", &refused),
        }
    }
    snapshot(registry, env.id, "after steps from an accepted restore");
}

fuzz_target!(|bytes: &[u8]| {
    let Some((&pick, body)) = bytes.split_first() else { return };
    let harness = &*HARNESS;
    let index = usize::from(pick) % harness.specs.len();
    let mut live = harness.live.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    let env = &mut live[index];
    let snapshot = framed(body);
    match sequenced(&harness.registry, env, |env, seq| RequestBody::Restore { env, seq, snapshot }) {
        ReplyBody::Reset(reset) => {
            reset.agents.iter().for_each(check_start);
            accepted(&harness.registry, &harness.specs[index], env);
        }
        refused => check_refusal("a restore", &refused),
    }
});
