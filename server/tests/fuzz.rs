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
                    | RequestBody::Record { .. },
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
        which in 0usize..4,
        flips in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
        cut in any::<prop::sample::Index>(),
        truncate in any::<bool>(),
    ) {
        let registry = registry();
        let mut bytes = seeds()[which].clone();
        for (at, value) in flips {
            let i = at.index(bytes.len());
            bytes[i] = value;
        }
        if truncate {
            bytes.truncate(cut.index(bytes.len() + 1));
        }
        answered(&registry, &bytes);
    }
}
