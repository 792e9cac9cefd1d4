//! Property-based fuzzing of what arrives from outside the process, bounded so it runs in
//! the default test command: random and mutated request payloads fed to the registry's
//! request handler (which decodes them), and every reply decodes as a `Reply` (the
//! server never panics and answers everything). Longer runs: raise PROPTEST_CASES.

use arena_protocol::{
    Action, ClientId, CreateOptions, EnvId, PROTOCOL_VERSION, Reply, Request, RequestBody, ScenarioSource, decode,
    encode,
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
        request(RequestBody::Reset { env: EnvId(3), seq: 1, seed: Some(4), options: vec![] }),
        request(RequestBody::Step { env: EnvId(3), seq: 2, actions: vec![("ec_0".into(), Action::Meta(3))] }),
    ]
}

fn answered(registry: &Registry, bytes: &[u8]) {
    let reply = registry.handle(bytes);
    assert!(decode::<Reply>(&reply).is_ok(), "the reply to {bytes:?} does not decode");
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
