//! Feeds arbitrary bytes to the server's request handler (`Registry::handle`), which
//! decodes them and acts on them as it does for every request arriving over Zenoh. A
//! live Close is let through and the env recreated at once (same scenario and options,
//! new id), so closing a real env is fuzzed too and the live envs never run out. Holds:
//! no panic, and every reply decodes as a `Reply`.
//!
//! Env ids are random 128-bit numbers, so no input could name an env the registry holds.
//! The target creates `LIVE` envs at start, as client 7, and the input's first byte picks
//! a mode. Even: the rest goes to the handler as it is. Odd: the next byte picks a live
//! env and the rest, if it decodes as a `Request`, is pointed at the live envs before it
//! is re-encoded and sent (what does not decode is sent as it is): its client becomes 7
//! and each env id `e` in it (Reset, Step, Render, State, Specs, Close, and each step of
//! a StepBatch) becomes live env (picking byte + `e`) mod the number of live envs. Its
//! sequence numbers are taken relative to the env's last one, `seq` mod 4 saying which:
//! 0 repeats it (a retry), 1 and 2 go one and two past it, 3 is one before it (stale).
//! The fuzzer's own numbers would otherwise soon reach a huge value that leaves every
//! later Reset and Step of that env stale for the rest of the run.
//!
//! One registry for the whole run, as a server has: envs created along the way
//! accumulate up to `Limits::default()`.
#![no_main]

use std::sync::{LazyLock, Mutex};

use arena_protocol::{
    ActionType, ClientId, CreateOptions, EnvId, ObservationKind, PROTOCOL_VERSION, Reply, ReplyBody, Request,
    RequestBody, ScenarioSource, decode, encode,
};
use arena_server::transport::{Limits, Registry, Scenarios};
use libfuzzer_sys::fuzz_target;

/// Who the live envs belong to, and who every retargeted request claims to be.
const CLIENT: ClientId = ClientId(7);

/// The live envs: scenario and create options. Overtake's has the options the other two
/// leave at their defaults, so steps check continuous actions and observations carry a
/// mask (fuzz/src/bin/write_seeds.rs points its seeds at these by index).
fn live_spec(index: usize) -> (&'static str, CreateOptions) {
    match index {
        0 => ("merge", CreateOptions::default()),
        1 => ("highway", CreateOptions::default()),
        _ => (
            "overtake",
            CreateOptions {
                action_type: Some(ActionType::Continuous),
                observation: Some(ObservationKind::KinematicsWithMask),
                render_size: Some((32, 64)),
                diagnostics: true,
                ..CreateOptions::default()
            },
        ),
    }
}

const LIVE: usize = 3;

/// A live env: its id and the last sequence number sent to it.
struct Live {
    id: EnvId,
    last_seq: u64,
}

struct Harness {
    registry: Registry,
    live: Mutex<Vec<Live>>,
}

static HARNESS: LazyLock<Harness> = LazyLock::new(|| {
    let registry = Registry::new("fuzz".into(), Scenarios::load(None).expect("built-in scenarios"), Limits::default());
    let live = (0..LIVE).map(|index| Live { id: create(&registry, index), last_seq: 0 }).collect();
    Harness { registry, live: Mutex::new(live) }
});

/// Creates live env `index` through the registry, as any client would.
fn create(registry: &Registry, index: usize) -> EnvId {
    let (name, options) = live_spec(index);
    let scenario = ScenarioSource::Named(name.into());
    let reply = registry.handle(&encode(&Request::new(CLIENT, RequestBody::CreateEnv { scenario, options })));
    match decode::<Reply>(&reply) {
        Ok(Reply { body: ReplyBody::Created { env, .. }, .. }) => env,
        other => panic!("cannot create the live {name} env: {other:?}"),
    }
}

/// The sequence number to send to an env whose last one is `last`, for the fuzzer's
/// `wanted`; `last` follows it when the request `counts` (a stale number leaves it).
fn sequence(last: &mut u64, wanted: u64, counts: bool) -> u64 {
    let seq = match wanted % 4 {
        0 => *last,
        1 => last.saturating_add(1),
        2 => last.saturating_add(2),
        _ => last.saturating_sub(1),
    };
    if counts {
        *last = (*last).max(seq);
    }
    seq
}

/// Points `request` at the live envs (see the top of the file); returns the index of the
/// live env it closes, if it is a Close.
fn retarget(request: &mut Request, pick: u8, live: &mut [Live]) -> Option<usize> {
    request.client = CLIENT;
    // A request of another version is refused before any env is touched.
    let counts = request.version == PROTOCOL_VERSION;
    let n = live.len();
    let choose = |env: EnvId| (usize::from(pick) + (env.0 % n as u128) as usize) % n;
    let mut point = |env: &mut EnvId, seq: Option<&mut u64>| {
        let index = choose(*env);
        *env = live[index].id;
        if let Some(seq) = seq {
            *seq = sequence(&mut live[index].last_seq, *seq, counts);
        }
        index
    };
    match &mut request.body {
        RequestBody::ServerInfo | RequestBody::CreateEnv { .. } => None,
        RequestBody::Reset { env, seq, .. }
        | RequestBody::Step { env, seq, .. }
        | RequestBody::Restore { env, seq, .. } => {
            point(env, Some(seq));
            None
        }
        RequestBody::StepBatch { steps } => {
            for step in steps {
                point(&mut step.env, Some(&mut step.seq));
            }
            None
        }
        RequestBody::Render { env, .. }
        | RequestBody::State { env }
        | RequestBody::Specs { env }
        | RequestBody::Record { env, .. }
        | RequestBody::Snapshot { env }
        | RequestBody::Statistics { env } => {
            point(env, None);
            None
        }
        RequestBody::Close { env } => Some(point(env, None)),
    }
}

fn answered(registry: &Registry, bytes: &[u8]) -> Reply {
    let reply = registry.handle(bytes);
    decode::<Reply>(&reply).unwrap_or_else(|e| panic!("the reply to {bytes:?} does not decode: {e}"))
}

fuzz_target!(|bytes: &[u8]| {
    let harness = &*HARNESS;
    let Some((&mode, rest)) = bytes.split_first() else {
        answered(&harness.registry, bytes);
        return;
    };
    let live_mode = mode % 2 == 1 && !rest.is_empty();
    if !live_mode {
        answered(&harness.registry, rest);
        return;
    }
    let (pick, payload) = (rest[0], &rest[1..]);
    let Ok(mut request) = decode::<Request>(payload) else {
        answered(&harness.registry, payload);
        return;
    };
    let mut live = harness.live.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    let closes = retarget(&mut request, pick, &mut live);
    let reply = answered(&harness.registry, &encode(&request));
    if let (Some(index), ReplyBody::Closed) = (closes, &reply.body) {
        live[index] = Live { id: create(&harness.registry, index), last_seq: 0 };
    }
});
