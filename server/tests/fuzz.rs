//! Property-based fuzzing of what arrives from outside the process, bounded so it runs in
//! the default test command: random and mutated request payloads fed to the registry's
//! request handler. Every reply is the documented answer to what arrived: bytes that are
//! not a request get `MalformedRequest` or `WrongVersion`; a request gets a reply of its
//! own kind or a coded refusal that is never `Internal` (no panic) and never touches an
//! env it does not own; and the registry answers a good request afterwards. Longer runs:
//! raise PROPTEST_CASES.

use arena_protocol::{
    Action, ClientId, CreateOptions, EnvId, ErrorCode, PROTOCOL_VERSION, Reply, ReplyBody, Request, RequestBody,
    ResetOptions, ScenarioSource, decode, encode,
};
use arena_server::transport::{Limits, Registry, Scenarios};
use proptest::prelude::*;

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
