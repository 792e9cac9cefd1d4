//! The request handler hands the queryable an env's next decisions to make once a
//! reply is sent (`Registry::handle_then`): for a reset and for a single step whose
//! episode goes on, and for nothing else. What they change (nothing but when the work is
//! done) is tested over Zenoh (tests/tests/env_over_zenoh.rs) and in the world
//! (world/tests.rs).

use arena_protocol::{
    ClientId, CreateOptions, EnvId, PROTOCOL_VERSION, Reply, ReplyBody, Request, RequestBody, ResetOptions,
    ScenarioSource, decode, encode,
};
use arena_server::transport::{Limits, Registry, Scenarios};

const CLIENT: ClientId = ClientId(12);

fn request(body: RequestBody) -> Vec<u8> {
    encode(&Request { version: PROTOCOL_VERSION, client: CLIENT, body })
}

/// The reply to `body` and whether decisions are to be made ahead after it.
fn ask(registry: &Registry, body: RequestBody) -> (ReplyBody, bool) {
    let (bytes, ahead) = registry.handle_then(None, &request(body));
    let reply: Reply = decode(&bytes).expect("a reply");
    (reply.body, ahead.is_some())
}

#[test]
fn only_a_reset_or_a_step_whose_episode_goes_on_is_followed_by_decisions_made_ahead() {
    let registry = Registry::new("ahead".into(), Scenarios::load(None).expect("built-in scenarios"), Limits::default());
    let options = CreateOptions { max_cycles: Some(3), ..CreateOptions::default() };
    let create = RequestBody::CreateEnv { scenario: ScenarioSource::Named("highway-gt".into()), options };
    let (ReplyBody::Created { env, .. }, false) = ask(&registry, create) else { panic!("highway-gt is created") };
    let reset = |seq| RequestBody::Reset { env, seq, seed: Some(5), options: ResetOptions::default() };
    let step = |seq| RequestBody::Step { env, seq, actions: vec![] };
    assert!(matches!(ask(&registry, reset(1)), (ReplyBody::Reset(_), true)), "a reset waits for the first step");
    for seq in 2..4 {
        let (reply, ahead) = ask(&registry, step(seq));
        assert!(matches!(reply, ReplyBody::Step(ref s) if !s.agents.is_empty()), "{reply:?}");
        assert!(ahead, "step {seq} goes on: its next decisions are made ahead");
    }
    let (last, ahead) = ask(&registry, step(4));
    assert!(matches!(last, ReplyBody::Step(ref s) if s.agents.is_empty()), "max_cycles 3 ends it: {last:?}");
    assert!(!ahead, "nothing comes after an episode's last step");
    let (refused, ahead) = ask(&registry, step(5));
    assert!(matches!(refused, ReplyBody::Error(_)), "{refused:?}");
    assert!(!ahead, "nor after a refused step");
    let unknown = RequestBody::Step { env: EnvId(7), seq: 1, actions: vec![] };
    assert!(matches!(ask(&registry, unknown), (ReplyBody::Error(_), false)));
    let stale = RequestBody::Reset { env, seq: 1, seed: Some(5), options: ResetOptions::default() };
    assert!(matches!(ask(&registry, stale), (ReplyBody::Error(_), false)), "nor after a refused reset");
}

#[test]
fn an_env_whose_decisions_are_made_ahead_steps_as_one_whose_are_not() {
    let registry = Registry::new("ahead".into(), Scenarios::load(None).expect("built-in scenarios"), Limits::default());
    let create = || RequestBody::CreateEnv {
        scenario: ScenarioSource::Named("highway-gt".into()),
        options: CreateOptions::default(),
    };
    let (ReplyBody::Created { env: ahead, .. }, _) = ask(&registry, create()) else { panic!("created") };
    let (ReplyBody::Created { env: plain, .. }, _) = ask(&registry, create()) else { panic!("created") };
    let mut made = 0;
    for env in [ahead, plain] {
        let reset = RequestBody::Reset { env, seq: 1, seed: Some(9), options: ResetOptions::default() };
        let (bytes, work) = registry.handle_then(None, &request(reset));
        assert!(matches!(decode::<Reply>(&bytes).unwrap().body, ReplyBody::Reset(_)));
        if let (true, Some(work)) = (env == ahead, work) {
            registry.decide_ahead(work);
            made += 1;
        }
    }
    for seq in 2..14 {
        let (bytes, work) =
            registry.handle_then(None, &request(RequestBody::Step { env: ahead, seq, actions: vec![] }));
        if let Some(work) = work {
            registry.decide_ahead(work);
            made += 1;
        }
        let (expected, _) =
            registry.handle_then(None, &request(RequestBody::Step { env: plain, seq, actions: vec![] }));
        let (ReplyBody::Step(got), ReplyBody::Step(want)) =
            (decode::<Reply>(&bytes).unwrap().body, decode::<Reply>(&expected).unwrap().body)
        else {
            panic!("step {seq} was refused");
        };
        assert_eq!(encode(&got.steps), encode(&want.steps), "step {seq}");
        if got.agents.is_empty() {
            break;
        }
    }
    assert!(made >= 4, "decisions were made ahead {made} times: too few steps to compare");
}
