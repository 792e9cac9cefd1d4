//! The env over a real Zenoh session: PettingZoo rules, determinism across clients,
//! isolation, every kind of bad input, and safe retries.

mod common;

use arena_client::{Action, ClientError, CreateOptions, ErrorCode, OptionValue, ScenarioSource};
use arena_protocol::session::{ConnectionFlags, Mode, Role};
use arena_protocol::{
    BatchStep, ClientId, EnvId, PROTOCOL_VERSION, Reply, ReplyBody, Request, RequestBody, decode, encode, keys,
};
use zenoh::Wait;

fn code(result: Result<impl std::fmt::Debug, ClientError>) -> ErrorCode {
    match result {
        Err(ClientError::Server(reply)) => reply.code,
        other => panic!("expected a coded error, got {other:?}"),
    }
}

fn meta(agent: &str, choice: u32) -> Vec<(String, Action)> {
    vec![(agent.to_string(), Action::Meta(choice))]
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn agents_leave_at_once_and_never_return() {
    let harness = common::start().await;
    let client = harness.client().await;
    let mut env =
        harness.env_with(&client, "merge", CreateOptions { max_cycles: Some(400), ..Default::default() }).await;
    let reset = env.reset(Some(0), vec![]).await.unwrap();
    assert_eq!(reset.agents.len(), 1);
    // Steer left into the adjacent car's lane again and again: ec merges or crashes;
    // either way it must finish before the lane ends and leave at once.
    let mut finished = false;
    for _ in 0..400 {
        let step = env.step(meta("ec_0", 0)).await.unwrap();
        assert_eq!(step.steps.len(), 1, "every agent live before the step has its row");
        if step.steps[0].terminated || step.steps[0].truncated {
            assert!(step.agents.is_empty(), "a finished agent leaves `agents` in the same step");
            finished = true;
            break;
        }
        assert_eq!(step.agents, ["ec_0"]);
    }
    assert!(finished);
    assert_eq!(code(env.step(meta("ec_0", 1)).await), ErrorCode::AgentNotLive);
    assert_eq!(code(env.step(vec![]).await), ErrorCode::AgentNotLive);
    let again = env.reset(Some(0), vec![]).await.unwrap();
    assert_eq!(again.agents, reset.agents, "reset brings agents back with the same start");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_recording_env_sends_the_world_and_stops_when_told() {
    let harness = common::start().await;
    let client = harness.client().await;
    let mut env = harness.env_with(&client, "merge", CreateOptions::default()).await;
    assert!(env.record(true).await.unwrap().is_none(), "nothing to show before a reset");
    let start = env.reset(Some(0), vec![]).await.unwrap().world.expect("recording: the world on reset");
    assert_eq!(start.vehicles.len(), 2);
    let step = env.step(meta("ec_0", 1)).await.unwrap();
    assert_eq!(step.world.len(), 1);
    assert_eq!(step.world[0].vehicles.len(), 2);
    assert!(env.record(false).await.unwrap().is_none());
    assert!(env.step(meta("ec_0", 1)).await.unwrap().world.is_empty());
    let now = env.record(true).await.unwrap().expect("the world now");
    assert!((now.frame.time - 0.2).abs() < 1e-9, "{}", now.frame.time);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_render_follows_the_named_vehicle_and_statistics_time_the_servers_policy() {
    let harness = common::start().await;
    let client = harness.client().await;
    let expert = "expert".parse().unwrap();
    let mut driven =
        harness.env_with(&client, "merge", CreateOptions { policy: Some(expert), ..Default::default() }).await;
    let mut played = harness.env_with(&client, "merge", CreateOptions::default()).await;
    for env in [&mut driven, &mut played] {
        env.reset(Some(0), vec![]).await.unwrap();
    }
    for _ in 0..3 {
        driven.step(vec![]).await.unwrap();
        played.step(meta("ec_0", 1)).await.unwrap();
    }
    let statistics = driven.statistics().await.unwrap();
    let [(agent, micros)] = &statistics.decision_micros[..] else { panic!("{statistics:?}") };
    assert_eq!((agent.as_str(), micros.len()), ("ec_0", 3));
    assert!(micros.iter().all(|&us| us > 0.0), "{micros:?}");
    assert!(played.statistics().await.unwrap().decision_micros.is_empty());

    let arena_client::Frame::Ansi(text) = played.render(arena_protocol::RenderMode::Ansi, Some("ac")).await.unwrap()
    else {
        panic!("ansi")
    };
    assert!(text.contains("ac: lane 0"), "{text}");
    let refused = played.render(arena_protocol::RenderMode::RgbArray, Some("nobody")).await;
    assert_eq!(code(refused), ErrorCode::InvalidOption);
    played.step(meta("ec_0", 1)).await.expect("the env keeps working");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_explaining_env_sends_the_avs_decisions_and_the_same_episode() {
    let harness = common::start().await;
    let client = harness.client().await;
    let explaining = CreateOptions { explain: true, ..Default::default() };
    let mut on = harness.env_with(&client, "merge-ac", explaining).await;
    let mut off = harness.env_with(&client, "merge-ac", CreateOptions::default()).await;
    let (started, plain) = (on.reset(Some(2), vec![]).await.unwrap(), off.reset(Some(2), vec![]).await.unwrap());
    assert_eq!(started.agents, plain.agents, "explained or not, the same start");
    // Explaining, the reset names the vehicles the decisions point to by index.
    assert!(plain.world.is_none());
    let world = started.world.expect("explain: the world on reset");
    let names: Vec<&str> = world.vehicles.iter().map(|v| v.name.as_str()).collect();
    assert_eq!(names, ["ac_0", "ec"]);
    let mut played_against_ac = 0;
    for _ in 0..20 {
        let (a, b) = (on.step(meta("ac_0", 1)).await.unwrap(), off.step(meta("ac_0", 1)).await.unwrap());
        assert_eq!(a.steps, b.steps, "explained or not, the same step");
        assert!(b.explain.is_empty(), "explanations only when asked");
        // merge-ac: one game-theoretic leader, "ec" (vehicle 1), one decision a step.
        let [decision] = &a.explain[..] else { panic!("{} decisions in a step", a.explain.len()) };
        assert_eq!((decision.vehicle, decision.ec), (1, 1));
        let table = &decision.tables[decision.chosen.expect("a side played") as usize];
        let (accel, sigma) = table.ec_actions[table.row as usize];
        assert_eq!((accel, sigma), (decision.games_accel, decision.sigma), "the chosen cell is the action taken");
        // ac_0 beside on the left is the adjacent car while that side is open to a change
        // (it closes once ac_0, faster, is level with the slowing EC: the gap rule).
        assert_eq!(table.side, -1, "the ending lane's only way out is left");
        assert!(table.adjacent.is_none_or(|ac| ac == 0), "the adjacent car is ac_0: {:?}", table.adjacent);
        played_against_ac += usize::from(table.adjacent == Some(0));
    }
    assert!(played_against_ac > 0, "EC never played its game against ac_0");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn missing_action_is_idle() {
    let harness = common::start().await;
    let client = harness.client().await;
    let mut a = harness.env(&client, "highway").await;
    let mut b = harness.env(&client, "highway").await;
    a.reset(Some(8), vec![]).await.unwrap();
    b.reset(Some(8), vec![]).await.unwrap();
    for _ in 0..3 {
        let with_idle = a.step(meta("ego_0", 1)).await.unwrap();
        let without = b.step(vec![]).await.unwrap();
        assert_eq!(with_idle.steps, without.steps);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_agent_truncates_at_exactly_max_cycles() {
    let harness = common::start().await;
    let client = harness.client().await;
    let mut env =
        harness.env_with(&client, "highway", CreateOptions { max_cycles: Some(4), ..Default::default() }).await;
    assert_eq!(env.specs().max_cycles, 4);
    env.reset(Some(1), vec![]).await.unwrap();
    for cycle in 1..=4 {
        let step = env.step(vec![]).await.unwrap();
        assert_eq!(step.steps[0].truncated, cycle == 4, "cycle {cycle}");
    }
    assert_eq!(code(env.step(vec![]).await), ErrorCode::AgentNotLive);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn reset_overrides_of_unknown_keys_are_refused_by_name_and_good_ones_reach_the_episode() {
    let harness = common::start().await;
    let client = harness.client().await;
    let mut env = harness.env(&client, "merge").await;
    let plain = env.reset(Some(4), vec![]).await.unwrap();
    let refused = env.reset(Some(4), vec![("no_such_key".into(), OptionValue::Int(3))]).await;
    assert_eq!(code(refused.clone().map(|_| ())), ErrorCode::InvalidScenario);
    assert!(format!("{:?}", refused.err()).contains("no_such_key"));
    let moved = vec![("vehicle.ec_0.speed".into(), OptionValue::Float(23.0))];
    let changed = env.reset(Some(4), moved).await.unwrap();
    assert_ne!(plain.agents, changed.agents);
    assert!(env.step(vec![]).await.is_ok(), "the env serves on after a refused reset");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn same_seed_same_replies_across_clients_other_seed_differs() {
    let harness = common::start().await;
    let (first, second) = (harness.client().await, harness.client().await);
    let mut a = harness.env(&first, "highway").await;
    let mut b = harness.env(&second, "highway").await;
    let mut c = harness.env(&second, "highway").await;
    let ra = a.reset(Some(21), vec![]).await.unwrap();
    let rb = b.reset(Some(21), vec![]).await.unwrap();
    let rc = c.reset(Some(22), vec![]).await.unwrap();
    assert_eq!(ra.agents, rb.agents);
    assert_ne!(ra.agents, rc.agents);
    for k in 0..6u32 {
        let (sa, sb) = (a.step(meta("ego_0", k % 5)).await.unwrap(), b.step(meta("ego_0", k % 5)).await.unwrap());
        assert_eq!(format!("{sa:?}"), format!("{sb:?}"), "step {k} differs");
    }
}

/// A server makes an env's next decisions while each step's reply travels
/// (`Env::decide_ahead`); the next step uses them only if its actions left the learner's
/// vehicle as it was. Idle steps, steps that change the vehicle and a snapshot between
/// them: every reply and the snapshot are the bits the env gives in process, without.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_server_deciding_ahead_replies_the_bits_of_the_env_in_process() {
    let harness = common::start().await;
    let client = harness.client().await;
    let options = CreateOptions { max_cycles: Some(60), ..Default::default() };
    let mut remote = harness.env_with(&client, "highway-gt", options.clone()).await;
    let scenario = arena_sim::builtin_scenario("highway-gt").expect("shipped").expect("loads");
    let mut local = arena_server::env::Env::new(scenario, &options, 0).expect("env");
    let reset = remote.reset(Some(5), vec![]).await.unwrap();
    assert_eq!(reset.agents, local.reset(Some(5), &Default::default()).unwrap());
    // Idle (1) mostly; lane changes (0, 2), faster (3) and slower (4) between.
    let choices = [1, 1, 1, 3, 1, 1, 0, 1, 1, 4, 1, 2, 1, 1, 1];
    let mut snapshots_compared = false;
    for (k, &choice) in choices.iter().enumerate() {
        let actions = meta("ego_0", choice);
        let step = remote.step(actions.clone()).await.unwrap();
        let expected = local.step(&actions).unwrap();
        assert_eq!(encode(&step.steps), encode(&expected), "step {k} (action {choice})");
        assert_eq!(step.agents, local.live_agents(), "step {k}");
        if step.agents.is_empty() {
            break;
        }
        if k == 7 {
            assert_eq!(remote.snapshot().await.unwrap(), local.snapshot().unwrap(), "snapshot after step {k}");
            snapshots_compared = true;
        }
    }
    assert!(snapshots_compared, "the episode ended before the snapshot: pick another seed");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_cannot_touch_another_clients_env() {
    // Through a router, so that the intruder sees what other clients show of themselves
    // (a peer server does not pass liveliness tokens between its clients).
    let harness = common::start_router().await;
    let (owner, intruder) = (harness.client_as(Mode::Client).await, harness.client_as(Mode::Client).await);
    let mut env = harness.env(&owner, "merge").await;
    env.reset(Some(0), vec![]).await.unwrap();
    let request = Request {
        version: PROTOCOL_VERSION,
        client: intruder.id(),
        body: RequestBody::Step { env: env.id(), seq: 99, actions: vec![] },
    };
    let reply = raw(&harness, &encode(&request)).await;
    assert!(matches!(reply.body, ReplyBody::Error(ref e) if e.code == ErrorCode::UnknownEnv), "{reply:?}");

    // Everything the intruder can learn about the owner is its liveliness token: a tag,
    // not the id the server checks. Every number seen there is refused too.
    let flags = ConnectionFlags { mode: Some(Mode::Client), ..ConnectionFlags::connecting_to(&harness.endpoint) };
    let spy = zenoh::open(flags.zenoh_config(Role::Client).unwrap()).await.unwrap();
    let tokens = spy.liveliness().get(keys::clients_liveliness_wildcard("arena").unwrap()).await.unwrap();
    let mut seen = Vec::new();
    while let Ok(token) = tokens.recv_async().await {
        let key = token.result().expect("a token").key_expr().to_string();
        seen.push(keys::client_tag_from_liveliness("arena", &key).expect("a client key"));
    }
    spy.close().await.unwrap();
    assert!(seen.contains(&owner.id().tag().to_string()), "the owner's token is seen: {seen:?}");
    assert!(!seen.contains(&owner.id().to_string()), "the owner's id is never shown: {seen:?}");
    for (k, tag) in seen.iter().enumerate() {
        let client = ClientId(u128::from_str_radix(tag, 16).unwrap());
        let close = Request { version: PROTOCOL_VERSION, client, body: RequestBody::Close { env: env.id() } };
        let step = Request {
            version: PROTOCOL_VERSION,
            client,
            body: RequestBody::Step { env: env.id(), seq: 100 + k as u64, actions: vec![] },
        };
        for request in [step, close] {
            assert_eq!(raw_code(&raw(&harness, &encode(&request)).await), ErrorCode::UnknownEnv);
        }
    }
    // The owner's env did not move.
    assert_eq!(env.step(vec![]).await.unwrap().seq, 2);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn replies_from_any_session_but_the_servers_are_dropped() {
    // Through a router, another session can declare a queryable on the server's request
    // key (deploy/auth's access control forbids it; the default does not) and answer
    // first. The client takes only the reply whose replier is the server's session.
    let harness = common::start_behind_router().await;
    let flags = ConnectionFlags { mode: Some(Mode::Client), ..ConnectionFlags::connecting_to(&harness.endpoint) };
    let rogue = zenoh::open(flags.zenoh_config(Role::Client).unwrap()).await.unwrap();
    let forged = encode(&Reply::new(ReplyBody::Closed));
    let asked = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let counter = std::sync::Arc::clone(&asked);
    let _queryable = rogue
        .declare_queryable(keys::server_rpc("arena", harness.server.id()).unwrap())
        .callback(move |query| {
            counter.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
            query.reply(query.key_expr().clone(), forged.clone()).wait().ok();
        })
        .await
        .unwrap();
    let client = harness.client_as(Mode::Client).await;
    // Ask until the rogue has been asked too (its declaration takes a moment to reach the
    // router), and at least 20 times; every answer must be the server's.
    for k in 0..500 {
        let info = client.server_info(harness.server.id()).await.expect("the server's own reply");
        assert_eq!(info.server_id, harness.server.id());
        if k >= 20 && asked.load(std::sync::atomic::Ordering::SeqCst) > 0 {
            break;
        }
    }
    assert!(asked.load(std::sync::atomic::Ordering::SeqCst) > 0, "the rogue queryable was never asked");
    rogue.close().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_retried_step_returns_the_same_reply_and_steps_once() {
    let harness = common::start().await;
    let client = harness.client().await;
    let mut env = harness.env(&client, "highway").await;
    let mut twin = harness.env(&client, "highway").await;
    env.reset(Some(3), vec![]).await.unwrap();
    twin.reset(Some(3), vec![]).await.unwrap();
    let first = env.step_with_seq(2, meta("ego_0", 3)).await.unwrap();
    let retried = env.step_with_seq(2, meta("ego_0", 3)).await.unwrap();
    assert_eq!(format!("{first:?}"), format!("{retried:?}"));
    // Had the retry stepped again, the next step would be the twin's third, not second.
    let next = env.step_with_seq(3, vec![]).await.unwrap();
    twin.step(meta("ego_0", 3)).await.unwrap();
    let twin_next = twin.step(vec![]).await.unwrap();
    assert_eq!(next.steps, twin_next.steps);
    assert_eq!(code(env.step_with_seq(1, vec![]).await), ErrorCode::StaleSequence);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_batch_steps_many_envs_in_one_round_trip() {
    let harness = common::start().await;
    let client = harness.client().await;
    let mut envs = Vec::new();
    for seed in 0..6 {
        let mut env = harness.env(&client, "highway").await;
        env.reset(Some(seed), vec![]).await.unwrap();
        envs.push(env);
    }
    let mut single = harness.env(&client, "highway").await;
    single.reset(Some(4), vec![]).await.unwrap();
    let expected = single.step(meta("ego_0", 2)).await.unwrap();
    let mut handles: Vec<_> = envs.iter_mut().collect();
    let replies = client.step_batch(&mut handles, (0..6).map(|_| meta("ego_0", 2)).collect()).await.unwrap();
    assert_eq!(replies.len(), 6);
    assert_eq!(replies[4].as_ref().unwrap().steps, expected.steps);
}

/// Sends raw bytes to the server's request key from a session of its own.
async fn raw(harness: &common::Harness, bytes: &[u8]) -> Reply {
    let flags = ConnectionFlags::connecting_to(&harness.endpoint);
    let session = zenoh::open(flags.zenoh_config(Role::Client).unwrap()).await.unwrap();
    let key = keys::server_rpc("arena", harness.server.id()).unwrap();
    let mut reply = None;
    for _ in 0..50 {
        let replies =
            session.get(&key).payload(bytes.to_vec()).timeout(std::time::Duration::from_secs(5)).await.unwrap();
        if let Ok(answer) = replies.recv_async().await {
            reply = Some(answer.result().expect("an ok reply").payload().to_bytes().into_owned());
            break;
        }
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
    }
    session.close().wait().ok();
    decode(&reply.expect("the server answered")).expect("a reply that decodes")
}

fn raw_code(reply: &Reply) -> ErrorCode {
    match &reply.body {
        ReplyBody::Error(e) => e.code,
        other => panic!("expected an error reply, got {other:?}"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_kind_of_bad_input_gets_its_coded_error_and_the_server_keeps_serving() {
    let harness = common::start_with(arena_server::transport::Limits { max_envs: 3, ..Default::default() }).await;
    let client = harness.client().await;
    let mut env = harness.env(&client, "merge").await;
    let stranger = ClientId(7);
    let mut seen = Vec::new();

    // 1-4: bytes that are not a request of this protocol.
    seen.push(raw_code(&raw(&harness, b"\xff\xfe garbage \x00\x01").await));
    let good = encode(&Request { version: PROTOCOL_VERSION, client: stranger, body: RequestBody::ServerInfo });
    seen.push(raw_code(&raw(&harness, &good[..good.len() / 2 + 1]).await));
    let mut from_the_future =
        encode(&Request { version: PROTOCOL_VERSION + 1, client: stranger, body: RequestBody::ServerInfo });
    seen.push(raw_code(&raw(&harness, &from_the_future).await));
    from_the_future.resize(arena_protocol::MAX_MESSAGE_BYTES + 1, 0);
    seen.push(raw_code(&raw(&harness, &from_the_future).await));
    assert_eq!(
        seen,
        [ErrorCode::MalformedRequest, ErrorCode::MalformedRequest, ErrorCode::WrongVersion, ErrorCode::PayloadTooLarge]
    );
    assert!(matches!(raw(&harness, &good).await.body, ReplyBody::ServerInfo(_)), "still serving");

    // 5-7: envs that do not exist or are not creatable.
    let ghost = Request {
        version: PROTOCOL_VERSION,
        client: client.id(),
        body: RequestBody::State { env: arena_protocol::EnvId(42) },
    };
    assert_eq!(raw_code(&raw(&harness, &encode(&ghost)).await), ErrorCode::UnknownEnv);
    let unknown =
        client.create_env(harness.server.id(), ScenarioSource::Named("nowhere".into()), CreateOptions::default()).await;
    assert_eq!(code(unknown), ErrorCode::UnknownScenario);
    let inline =
        ScenarioSource::Inline { file_name: "mine.toml".into(), text: "name = \"x\"\n[road]\nlanes = 0\n".into() };
    let bad_file = client.create_env(harness.server.id(), inline, CreateOptions::default()).await;
    match bad_file {
        Err(ClientError::Server(e)) => {
            assert_eq!(e.code, ErrorCode::InvalidScenario);
            assert!(e.message.contains("mine.toml"), "{}", e.message);
        }
        other => panic!("{other:?}"),
    }
    // merge.toml's text sent as overtake-random would label every result overtake-random.
    let merge = include_str!("../../scenarios/merge.toml");
    let misnamed = |name: &str| ScenarioSource::Inline { file_name: name.into(), text: merge.into() };
    match client.create_env(harness.server.id(), misnamed("overtake-random"), CreateOptions::default()).await {
        Err(ClientError::Server(e)) => {
            assert_eq!(e.code, ErrorCode::InvalidScenario);
            assert!(e.message.contains("declares name = \"merge\" but was sent as 'overtake-random'"), "{}", e.message);
        }
        other => panic!("{other:?}"),
    }
    for taken in ["merge", "my-merge.toml"] {
        let env = client.create_env(harness.server.id(), misnamed(taken), CreateOptions::default()).await;
        env.unwrap_or_else(|e| panic!("{taken}: {e}")).close().await.unwrap();
    }
    let bad_override =
        CreateOptions { overrides: vec![("vehicle.ec_0.lane".into(), OptionValue::Int(9))], ..Default::default() };
    let refused = client.create_env(harness.server.id(), ScenarioSource::Named("merge".into()), bad_override).await;
    assert_eq!(code(refused), ErrorCode::InvalidScenario);

    // 8-9: before reset.
    assert_eq!(code(env.step(vec![]).await), ErrorCode::NotReset);
    assert_eq!(code(env.state().await), ErrorCode::NotReset);
    env.reset(Some(0), vec![]).await.unwrap();

    // 10-14: actions.
    assert_eq!(code(env.step(meta("nobody", 1)).await), ErrorCode::UnknownAgent);
    assert_eq!(code(env.step(meta("ec_0", 7)).await), ErrorCode::InvalidAction);
    assert_eq!(code(env.step(vec![("ec_0".into(), Action::Continuous([0.0, 1.0]))]).await), ErrorCode::WrongActionType);
    let mut continuous = harness
        .env_with(
            &client,
            "merge",
            CreateOptions { action_type: Some(arena_protocol::ActionType::Continuous), ..Default::default() },
        )
        .await;
    continuous.reset(Some(0), vec![]).await.unwrap();
    assert_eq!(
        code(continuous.step(vec![("ec_0".into(), Action::Continuous([f32::NAN, 0.0]))]).await),
        ErrorCode::InvalidAction
    );
    assert_eq!(
        code(continuous.step(vec![("ec_0".into(), Action::Continuous([50.0, 0.0]))]).await),
        ErrorCode::InvalidAction
    );

    // 15: too many envs (limit 3: env, continuous, and one more).
    let _third = harness.env(&client, "merge").await;
    let fourth =
        client.create_env(harness.server.id(), ScenarioSource::Named("merge".into()), CreateOptions::default()).await;
    assert_eq!(code(fourth), ErrorCode::TooManyEnvs);

    // 16-17: after close.
    continuous.close().await.unwrap();
    assert_eq!(code(continuous.step(vec![]).await), ErrorCode::EnvClosed);
    let close_again =
        Request { version: PROTOCOL_VERSION, client: client.id(), body: RequestBody::Close { env: continuous.id() } };
    assert_eq!(raw_code(&raw(&harness, &encode(&close_again)).await), ErrorCode::EnvClosed);
    // To anyone else a closed env looks like one that never existed.
    let probe =
        Request { version: PROTOCOL_VERSION, client: stranger, body: RequestBody::Close { env: continuous.id() } };
    assert_eq!(raw_code(&raw(&harness, &encode(&probe)).await), ErrorCode::UnknownEnv);

    // 18: a stale sequence number.
    let step = env.step(meta("ec_0", 1)).await.unwrap();
    assert_eq!(code(env.step_with_seq(step.seq - 1, vec![]).await), ErrorCode::StaleSequence);

    // And a valid request still works after all of it.
    let fine = env.step(meta("ec_0", 1)).await.unwrap();
    assert_eq!(fine.agents, ["ec_0"]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn envs_of_a_client_that_leaves_are_reclaimed() {
    let harness = common::start().await;
    let client = harness.client().await;
    let _env = harness.env(&client, "merge").await;
    assert_eq!(harness.server.registry().len(), 1);
    client.close().await.unwrap();
    // Within the grace a client has to come back (its link may only have dropped), and
    // the sweep after it.
    let limit = arena_server::transport::ORPHAN_GRACE + std::time::Duration::from_secs(2);
    let started = std::time::Instant::now();
    while started.elapsed() < limit {
        if harness.server.registry().is_empty() {
            return;
        }
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
    }
    panic!("the env outlived its client by {limit:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn idle_envs_are_reclaimed_and_say_so() {
    let limits =
        arena_server::transport::Limits { idle_timeout: std::time::Duration::from_millis(300), ..Default::default() };
    let harness = common::start_with(limits).await;
    let client = harness.client().await;
    let mut env = harness.env(&client, "merge").await;
    env.reset(Some(0), vec![]).await.unwrap();
    for _ in 0..200 {
        if harness.server.registry().is_empty() {
            assert_eq!(code(env.step(vec![]).await), ErrorCode::EnvClosed);
            return;
        }
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
    }
    panic!("an idle env was never reclaimed");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn one_client_cannot_take_a_shared_server() {
    let limits = arena_server::transport::Limits { max_envs: 10, max_envs_per_client: 2, ..Default::default() };
    let harness = common::start_with(limits).await;
    let (greedy, other) = (harness.client().await, harness.client().await);
    let mut first = harness.env(&greedy, "merge").await;
    let _second = harness.env(&greedy, "merge").await;
    let merge = || ScenarioSource::Named("merge".into());
    let server = harness.server.id();
    match greedy.create_env(server, merge(), CreateOptions::default()).await {
        Err(ClientError::Server(e)) => {
            assert_eq!(e.code, ErrorCode::TooManyEnvs);
            assert!(e.message.contains("this client holds its limit of 2"), "{}", e.message);
        }
        other => panic!("{other:?}"),
    }
    // The server has room, and the other client gets it; closing one frees the greedy's share.
    assert!(other.create_env(server, merge(), CreateOptions::default()).await.is_ok());
    first.close().await.unwrap();
    assert!(greedy.create_env(server, merge(), CreateOptions::default()).await.is_ok(), "a closed env frees its place");
    assert_eq!(harness.server.registry().len(), 3);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn more_kinds_of_bad_input_each_get_their_code_and_the_env_keeps_working() {
    let harness = common::start().await;
    let client = harness.client().await;
    let server = harness.server.id();
    let create = |options: CreateOptions| client.create_env(server, ScenarioSource::Named("merge".into()), options);
    let inline = |text: &str| {
        client.create_env(
            server,
            ScenarioSource::Inline { file_name: "mine.toml".into(), text: text.into() },
            CreateOptions::default(),
        )
    };
    let merge = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/merge.toml")).unwrap();

    // 19-20: nothing at all, and a request of an older protocol.
    assert_eq!(raw_code(&raw(&harness, b"").await), ErrorCode::MalformedRequest);
    let old = encode(&Request { version: PROTOCOL_VERSION - 1, client: client.id(), body: RequestBody::ServerInfo });
    assert_eq!(raw_code(&raw(&harness, &old).await), ErrorCode::WrongVersion);

    // 21-25: creation options out of range.
    let sized = |size| CreateOptions { render_size: Some(size), ..Default::default() };
    assert_eq!(code(create(sized((8, 600))).await), ErrorCode::InvalidScenario, "render size below 16");
    assert_eq!(code(create(sized((4096, 4096))).await), ErrorCode::InvalidScenario, "frames too big for a reply");
    let no_cycles = CreateOptions { max_cycles: Some(0), ..Default::default() };
    assert_eq!(code(create(no_cycles).await), ErrorCode::InvalidScenario);
    let wrong_type = CreateOptions {
        overrides: vec![("vehicle.ac.speed".into(), OptionValue::Str("fast".into()))],
        ..Default::default()
    };
    assert_eq!(code(create(wrong_type).await), ErrorCode::InvalidScenario);
    let no_such_key =
        CreateOptions { overrides: vec![("vehicle.ac.wings".into(), OptionValue::Int(2))], ..Default::default() };
    assert_eq!(code(create(no_such_key).await), ErrorCode::InvalidScenario);

    // 26-29: inline scenario files with each kind of error, each named in the message.
    for (what, text) in [
        ("TOML syntax", "name = \"x\"\n[road\n".to_string()),
        ("unknown key", merge.replace("[road]", "[road]\nbanking = 3.0")),
        ("overlapping vehicles", merge.replace("lane = 1\ns = 52.0", "lane = 0\ns = 52.0")),
        ("no learner", merge.replace("kind = \"agent\"", "kind = \"idm\"")),
    ] {
        match inline(&text).await {
            Err(ClientError::Server(e)) => {
                assert_eq!(e.code, ErrorCode::InvalidScenario, "{what}: {e}");
                assert!(e.message.contains("mine.toml") || e.message.contains("learner"), "{what}: {e}");
            }
            other => panic!("{what}: {other:?}"),
        }
    }

    let mut env = create(CreateOptions::default()).await.expect("a good env");
    env.reset(Some(1), vec![]).await.unwrap();

    // 30-31: reset overrides of a key that does not exist, or of a value out of range.
    let unknown_key = vec![("speed".into(), OptionValue::Float(3.0))];
    assert_eq!(code(env.reset(Some(1), unknown_key).await), ErrorCode::InvalidScenario);
    let bad_override = vec![("vehicle.ec_0.lane".into(), OptionValue::Int(40))];
    assert_eq!(code(env.reset(Some(1), bad_override).await), ErrorCode::InvalidScenario);
    env.reset(Some(1), vec![]).await.unwrap();

    // 32-33: the same agent twice in a step; an infinite continuous action on a meta env.
    let twice = vec![("ec_0".into(), Action::Meta(1)), ("ec_0".into(), Action::Meta(2))];
    assert_eq!(code(env.step(twice).await), ErrorCode::InvalidAction);
    let infinite = vec![("ec_0".into(), Action::Continuous([f32::INFINITY, 0.0]))];
    assert_eq!(code(env.step(infinite).await), ErrorCode::WrongActionType);

    // 34-35: a batch naming one env twice, and a batch longer than a client may hold.
    let twin = BatchStep { env: env.id(), seq: 90, actions: vec![] };
    let body = RequestBody::StepBatch { steps: vec![twin.clone(), BatchStep { seq: 91, ..twin.clone() }] };
    let reply = raw(&harness, &encode(&Request { version: PROTOCOL_VERSION, client: client.id(), body })).await;
    assert_eq!(raw_code(&reply), ErrorCode::MalformedRequest);
    let huge = (0..300u64).map(|k| BatchStep { env: EnvId(u128::from(k)), seq: 1, actions: vec![] }).collect();
    let reply = raw(
        &harness,
        &encode(&Request {
            version: PROTOCOL_VERSION,
            client: client.id(),
            body: RequestBody::StepBatch { steps: huge },
        }),
    )
    .await;
    assert_eq!(raw_code(&reply), ErrorCode::MalformedRequest);

    // 36: an unknown render mode (a variant index no RenderMode has).
    let render = encode(&Request {
        version: PROTOCOL_VERSION,
        client: client.id(),
        body: RequestBody::Render { env: env.id(), mode: arena_protocol::RenderMode::Ansi, follow: None },
    });
    // The mode is the byte before `follow`'s `None`.
    let mut unknown_mode = render.clone();
    let at = unknown_mode.len() - 2;
    unknown_mode[at] = 7;
    assert_eq!(raw_code(&raw(&harness, &unknown_mode).await), ErrorCode::MalformedRequest);

    // 37: an action for an agent that has finished (crashes into the lane's end or merges).
    let mut finished = false;
    for _ in 0..400 {
        let step = env.step(meta("ec_0", 0)).await.unwrap();
        if step.agents.is_empty() {
            finished = true;
            break;
        }
    }
    assert!(finished, "the episode ended");
    assert_eq!(code(env.step(meta("ec_0", 1)).await), ErrorCode::AgentNotLive);

    // 38: a future sequence number is not an error (a request that timed out may never
    // have arrived), and every refused request above left the env usable.
    env.reset(Some(1), vec![]).await.unwrap();
    let ahead = env.step_with_seq(10_000, meta("ec_0", 1)).await.expect("a later sequence number is served");
    assert_eq!(ahead.seq, 10_000);
    assert!(matches!(raw(&harness, &render).await.body, ReplyBody::Render(_)), "the env still renders");
}

fn override_of(key: String) -> CreateOptions {
    CreateOptions { overrides: vec![(key, OptionValue::Int(1))], ..Default::default() }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn keys_that_overflowed_the_stack_get_an_error_and_the_server_keeps_serving() {
    let harness = common::start().await;
    let client = harness.client().await;
    let mut env = harness.env(&client, "merge").await;
    env.reset(Some(0), vec![]).await.unwrap();
    let server = harness.server.id().to_string();
    let merge = || ScenarioSource::Named("merge".into());
    // 15 000 parts (about 30 KB) aborted the server on 07e7a7d; 1 MB is the fuzz runs' reach.
    for key in ["a.".repeat(15_000) + "a", "a.".repeat(500_000)] {
        let created = client.create_env(&server, merge(), override_of(key.clone())).await;
        match created {
            Err(ClientError::Server(e)) => {
                assert_eq!(e.code, ErrorCode::PayloadTooLarge, "{e}");
                assert!(e.message.contains("override key") && e.message.len() < 400, "{}", e.message);
            }
            other => panic!("a {}-byte key: {other:?}", key.len()),
        }
        let reset = env.reset(Some(0), vec![(format!("overrides.{key}"), OptionValue::Int(1))]).await;
        assert_eq!(code(reset), ErrorCode::PayloadTooLarge);
        assert!(env.step(vec![]).await.is_ok(), "the env still steps");
    }
    // Below the wire's bounds, the scenario's own depth bound answers (10 parts, 17 deep
    // once the inline TOML nests): a coded error too.
    let deep = ScenarioSource::Inline {
        file_name: "deep.toml".into(),
        text: format!("x = {}1{}\n", "[".repeat(40), "]".repeat(40)),
    };
    assert_eq!(code(client.create_env(&server, deep, CreateOptions::default()).await), ErrorCode::InvalidScenario);
    let too_many_parts = ["a"; arena_protocol::bounds::MAX_OPTION_KEY_PARTS + 1].join(".");
    assert_eq!(
        code(client.create_env(&server, merge(), override_of(too_many_parts)).await),
        ErrorCode::PayloadTooLarge
    );
    let at_the_bound = ["a"; arena_protocol::bounds::MAX_OPTION_KEY_PARTS].join(".");
    assert_eq!(code(client.create_env(&server, merge(), override_of(at_the_bound)).await), ErrorCode::InvalidScenario);
    assert!(client.server_info(&server).await.is_ok(), "still serving");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_panic_in_a_single_request_closes_that_env_and_is_answered_at_once() {
    let harness = common::start().await;
    let client = harness.client().await;
    let registry = harness.server.registry();
    let mut other = harness.env(&client, "merge").await;
    other.reset(Some(0), vec![]).await.unwrap();
    for kind in ["reset", "step"] {
        let mut env = harness.env(&client, "merge").await;
        if kind == "step" {
            env.reset(Some(0), vec![]).await.unwrap();
        }
        registry.inject_panic(kind);
        let outcome = if kind == "reset" {
            env.reset(Some(0), vec![]).await.map(|_| ())
        } else {
            env.step(vec![]).await.map(|_| ())
        };
        match outcome {
            Err(ClientError::Server(e)) => {
                assert_eq!(e.code, ErrorCode::Internal, "{kind}: {e}");
                assert!(!e.env_usable && e.message.contains("panicked") && e.message.contains("closed"), "{e}");
            }
            other => panic!("{kind}: {other:?}"),
        }
        // A coded reply, so answered: a request left unanswered ends as `Timeout`.
        assert_eq!(code(env.step(vec![]).await), ErrorCode::EnvClosed, "{kind}: the env is closed");
        assert!(other.step(vec![]).await.is_ok(), "{kind}: another env steps on");
    }
    registry.inject_panic("create");
    let created = client.create_env(harness.server.id(), ScenarioSource::Named("merge".into()), Default::default());
    assert_eq!(code(created.await), ErrorCode::Internal);
    assert_eq!(registry.len(), 1, "the panicking create left nothing behind");
    harness.env(&client, "merge").await;
}
