//! Writes the seed inputs of `decode_request`, `handle_request` and `restore` into
//! `fuzz/seeds/<target>`, so they follow the protocol (its version, its messages, its
//! snapshots) rather than being bytes nobody can remake. Run from the repository root
//! after any change to the protocol or to what a snapshot holds:
//!
//! ```sh
//! cargo +nightly run --manifest-path fuzz/Cargo.toml --bin write_seeds
//! ```
//!
//! `decode_request` gets one encoded request of every kind. `handle_request` gets each of
//! them twice, in the target's two modes (its first byte): `raw-*` (0, the request as it
//! arrives) and `live-*` (1, then the byte that picks a live env, then the request, which
//! the target points at that env). `restore` gets, for each of its envs, the byte that
//! picks it and the body of a snapshot of that env taken mid-episode, named after the
//! env (`<scenario>`, or the scenario and its options). Files of these names are
//! replaced; others are left.

use std::path::{Path, PathBuf};

use arena_fuzz::{ask, body, live_env, restore_envs};
use arena_protocol::{
    Action, BatchStep, ClientId, CreateOptions, EnvId, OptionValue, PROTOCOL_VERSION, RenderMode, ReplyBody, Request,
    RequestBody, ResetOptions, ScenarioSource, encode,
};
use arena_server::transport::{Limits, Registry, Scenarios};

/// The requests, by file name, and the live env `handle_request` should point each at
/// (0 merge, 1 highway, 2 overtake with continuous actions: its `LIVE` table).
fn requests() -> Vec<(&'static str, u8, Vec<u8>)> {
    let request = |body| encode(&Request { version: PROTOCOL_VERSION, client: ClientId(7), body });
    let env = EnvId(0);
    vec![
        ("server-info", 0, request(RequestBody::ServerInfo)),
        (
            "create-env-merge",
            0,
            request(RequestBody::CreateEnv {
                scenario: ScenarioSource::Named("merge".into()),
                options: CreateOptions::default(),
            }),
        ),
        (
            "reset",
            0,
            request(RequestBody::Reset {
                env,
                seq: 1,
                seed: Some(4),
                options: ResetOptions { overrides: vec![("vehicle.ac.speed".into(), OptionValue::Float(18.0))] },
            }),
        ),
        ("step", 0, request(RequestBody::Step { env, seq: 1, actions: vec![("ec_0".into(), Action::Meta(3))] })),
        (
            "step-highway",
            1,
            request(RequestBody::Step { env, seq: 1, actions: vec![("ego_0".into(), Action::Meta(0))] }),
        ),
        (
            "step-continuous",
            2,
            request(RequestBody::Step {
                env,
                seq: 1,
                actions: vec![("ec_0".into(), Action::Continuous([0.5, -0.25]))],
            }),
        ),
        (
            // Env ids 0 and 1: the target adds each id to the picking byte, so this batch
            // steps merge and highway together.
            "step-batch",
            0,
            request(RequestBody::StepBatch {
                steps: vec![
                    BatchStep { env: EnvId(0), seq: 1, actions: vec![("ec_0".into(), Action::Meta(1))] },
                    BatchStep { env: EnvId(1), seq: 1, actions: vec![("ego_0".into(), Action::Meta(4))] },
                ],
            }),
        ),
        ("render-ansi", 0, request(RequestBody::Render { env, mode: RenderMode::Ansi, follow: None })),
        ("render-rgb", 2, request(RequestBody::Render { env, mode: RenderMode::RgbArray, follow: Some("ac".into()) })),
        ("statistics", 0, request(RequestBody::Statistics { env })),
        ("state", 0, request(RequestBody::State { env })),
        ("specs", 0, request(RequestBody::Specs { env })),
        ("record", 0, request(RequestBody::Record { env, on: true })),
        ("snapshot", 0, request(RequestBody::Snapshot { env })),
        // Not a snapshot: the target's mutations reach the snapshot reader from here.
        ("restore", 0, request(RequestBody::Restore { env, seq: 2, snapshot: b"ARENASNP\x07\x00".to_vec() })),
        ("close", 0, request(RequestBody::Close { env })),
    ]
}

fn write(dir: &Path, name: &str, bytes: &[u8]) {
    std::fs::create_dir_all(dir).unwrap_or_else(|e| panic!("cannot create {}: {e}", dir.display()));
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap_or_else(|e| panic!("cannot write {}: {e}", path.display()));
}

/// Writes `restore`'s seeds: each env's picking byte, then its snapshot's body. Returns
/// how many.
fn restore_seeds(seeds: &Path) -> usize {
    let registry = Registry::new("seeds".into(), Scenarios::load(None).expect("built-in scenarios"), Limits::default());
    let envs = restore_envs();
    for (index, spec) in envs.iter().enumerate() {
        let (env, _) = live_env(&registry, spec);
        let ReplyBody::Snapshot(snapshot) = ask(&registry, RequestBody::Snapshot { env }) else {
            panic!("no snapshot of the {} env", spec.name)
        };
        let pick = u8::try_from(index).expect("fewer than 256 envs");
        write(&seeds.join("restore"), &spec.name, &[&[pick][..], body(&snapshot)].concat());
    }
    envs.len()
}

fn main() {
    let seeds = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("seeds");
    let mut count = 0;
    for (name, live, bytes) in requests() {
        write(&seeds.join("decode_request"), name, &bytes);
        write(&seeds.join("handle_request"), &format!("raw-{name}"), &[&[0][..], &bytes].concat());
        write(&seeds.join("handle_request"), &format!("live-{name}"), &[&[1, live][..], &bytes].concat());
        count += 1;
    }
    println!("wrote {count} requests (protocol {PROTOCOL_VERSION}) to {}", seeds.display());
    let snapshots = restore_seeds(&seeds);
    println!("wrote {snapshots} snapshot bodies to {}", seeds.join("restore").display());
}
