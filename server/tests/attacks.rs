//! Requests within the protocol's bounds that once stopped a server (docs/reliability.md,
//! "Attacks"), sent as bytes through the request handler as they arrive from Zenoh: each
//! is now refused with a coded error naming what was too much, or answered within its
//! bounded cost, and the server answers the next request. Snapshot forgeries are the
//! env's own tests (env/snapshot.rs); the scenario bounds at and just past each constant
//! are arena-sim's (scenario/tests.rs); a busy env beside a bystander is bystander.rs.

use std::time::{Duration, Instant};

use arena_protocol::{
    ClientId, ClientTag, CreateOptions, EnvId, ErrorCode, MAX_MESSAGE_BYTES, OptionValue, PROTOCOL_VERSION, RenderMode,
    Reply, ReplyBody, Request, RequestBody, ResetOptions, ScenarioSource, decode, encode,
};
use arena_server::env::MAX_AGENT_PERIODS;
use arena_server::transport::{Limits, MAX_CLIENT_TAGS, ORPHAN_GRACE, Registry, Scenarios};

const CLIENT: ClientId = ClientId(41);

fn registry() -> Registry {
    Registry::new("attacks".into(), Scenarios::load(None).expect("built-in scenarios"), Limits::default())
}

/// The reply's body and the size of its bytes.
fn ask(registry: &Registry, body: RequestBody) -> (ReplyBody, usize) {
    let bytes = registry.handle(&encode(&Request { version: PROTOCOL_VERSION, client: CLIENT, body }));
    let reply: Reply = decode(&bytes).expect("a reply");
    (reply.body, bytes.len())
}

fn create(registry: &Registry, scenario: ScenarioSource, options: CreateOptions) -> Result<EnvId, (ErrorCode, String)> {
    match ask(registry, RequestBody::CreateEnv { scenario, options }).0 {
        ReplyBody::Created { env, .. } => Ok(env),
        ReplyBody::Error(e) => Err((e.code, e.message)),
        other => panic!("a create got {other:?}"),
    }
}

fn named(name: &str) -> ScenarioSource {
    ScenarioSource::Named(name.into())
}

fn inline(text: String) -> ScenarioSource {
    ScenarioSource::Inline { file_name: "attack.toml".into(), text }
}

/// `refused` is an `InvalidScenario` whose message has every one of `needles`.
fn invalid(refused: Result<EnvId, (ErrorCode, String)>, needles: &[&str]) {
    let (code, message) = refused.expect_err("refused");
    assert_eq!(code, ErrorCode::InvalidScenario, "{message}");
    for needle in needles {
        assert!(message.contains(needle), "'{needle}' not in: {message}");
    }
}

/// The server still creates, resets and steps an env of the README's scenario.
fn still_serves(registry: &Registry) {
    let env = create(registry, named("merge"), CreateOptions::default()).expect("a create after the attack");
    let reset = RequestBody::Reset { env, seq: 1, seed: Some(1), options: ResetOptions::default() };
    assert!(matches!(ask(registry, reset).0, ReplyBody::Reset(_)));
    assert!(matches!(ask(registry, RequestBody::Step { env, seq: 2, actions: vec![] }).0, ReplyBody::Step(_)));
}

fn reset(registry: &Registry, env: EnvId, overrides: &[(&str, OptionValue)]) -> ReplyBody {
    let overrides = overrides.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
    ask(registry, RequestBody::Reset { env, seq: 1, seed: Some(3), options: ResetOptions { overrides } }).0
}

fn refused_reset(body: ReplyBody, needles: &[&str]) {
    let ReplyBody::Error(error) = body else { panic!("a reset past the bounds got {body:?}") };
    assert_eq!(error.code, ErrorCode::InvalidScenario, "{}", error.message);
    for needle in needles {
        assert!(error.message.contains(needle), "'{needle}' not in: {}", error.message);
    }
}

/// A straight road of `lanes` lanes and `sections` sections, with one learner and the
/// given `[road]` extras.
fn road_of(sections: usize, lanes: usize, arcs: bool) -> String {
    let section = |k: usize| match (arcs, k % 2) {
        (true, 0) => "{ length = 400.0, radius = 300.0 }".to_string(),
        (true, _) => "{ length = 400.0, radius = -300.0 }".to_string(),
        _ => format!("{{ length = {} }}", 50_000.0 / sections as f64),
    };
    let sections: Vec<String> = (0..sections).map(section).collect();
    let limits = vec!["30.0"; lanes].join(", ");
    format!(
        "name = \"road\"\n[road]\nlanes = {lanes}\nlane_width = 3.5\nspeed_limits = [{limits}]\nsections = [{}]\n\
         [[vehicle]]\nname = \"ego\"\nlane = 0\ns = 3.0\nspeed = 10.0\ndriver = {{ kind = \"agent\" }}\n",
        sections.join(", ")
    )
}

/// A long straight road of four lanes with `n` learners beside the first.
fn learners(n: usize) -> String {
    let mut text = road_of(1, 4, false);
    for k in 0..n {
        text += &format!(
            "[[vehicle]]\nname = \"a{k}\"\nlane = {}\ns = {}\nspeed = 10\ndriver = {{ kind = \"agent\" }}\n",
            k % 4,
            20.0 + 8.0 * (k / 4) as f64
        );
    }
    text
}

#[test]
fn episodes_whose_length_or_step_has_no_bound_are_refused_before_anything_is_made() {
    let registry = registry();
    // max_cycles 2^32 - 1 with 500 s steps reserved 171 TB for the episode's jerks.
    let long = CreateOptions { max_cycles: Some(u32::MAX), ..CreateOptions::default() };
    invalid(create(&registry, named("merge"), long), &["max_cycles 4294967295", "periods an episode"]);
    // merge: one learner, one period a step.
    let most = MAX_AGENT_PERIODS as u32;
    let at = CreateOptions { max_cycles: Some(most), ..CreateOptions::default() };
    assert!(create(&registry, named("merge"), at).is_ok(), "max_cycles {most} fits");
    let past = CreateOptions { max_cycles: Some(most + 1), ..CreateOptions::default() };
    invalid(create(&registry, named("merge"), past), &[&format!("max_cycles {}", most + 1)]);
    let slow =
        CreateOptions { overrides: vec![("sim.step_dt".into(), OptionValue::Float(500.0))], ..Default::default() };
    invalid(create(&registry, named("merge"), slow), &["sim.step_dt"]);
    // A physics step of a nanosecond made one step never end; through a reset too.
    let env = create(&registry, named("merge"), CreateOptions::default()).expect("merge");
    refused_reset(reset(&registry, env, &[("sim.physics_dt", OptionValue::Float(1e-9))]), &["sim.physics_dt"]);
    refused_reset(reset(&registry, env, &[("sim.step_dt", OptionValue::Float(500.0))]), &["sim.step_dt"]);
    still_serves(&registry);
}

#[test]
fn learners_and_game_theoretic_decisions_past_their_bounds_are_refused() {
    let registry = registry();
    // 18 009 learners in 1 MiB took 12 s to create and 11.6 MiB a step reply.
    let mut text = learners(18_009);
    text.truncate(arena_protocol::bounds::MAX_SCENARIO_TEXT_BYTES);
    text.truncate(text.rfind("[[vehicle]]").expect("a vehicle"));
    invalid(create(&registry, inline(text), CreateOptions::default()), &["vehicles"]);
    // The server's own policy makes every learner a game-theoretic car, an expert adds a
    // decision per learner and step: both count.
    let policy = arena_protocol::BuiltinPolicy::Gt { style: None, game: arena_protocol::Game::Nash };
    let driven = CreateOptions { policy: Some(policy), ..CreateOptions::default() };
    // Just at and just past each bound (the file's own learner and `n` more).
    let gt_cars = arena_sim::MAX_GT_CARS;
    assert!(create(&registry, inline(learners(gt_cars - 1)), driven.clone()).is_ok(), "{gt_cars} cars fit");
    invalid(create(&registry, inline(learners(gt_cars)), driven), &[&format!("{} game-theoretic cars", gt_cars + 1)]);
    let advised = CreateOptions { expert: Some(arena_protocol::Game::Nash), ..CreateOptions::default() };
    let decisions = arena_sim::MAX_GT_DECISIONS_PER_STEP;
    assert!(create(&registry, inline(learners(decisions - 1)), advised.clone()).is_ok(), "{decisions} experts fit");
    invalid(create(&registry, inline(learners(decisions)), advised), &[&format!("{} expert decision", decisions + 1)]);
    still_serves(&registry);
}

#[test]
fn roads_of_many_sections_are_bounded_and_render_and_record_within_a_reply() {
    let registry = registry();
    // 30 000 sections: one render walked them all per pixel and never finished.
    invalid(create(&registry, inline(road_of(30_000, 2, false)), CreateOptions::default()), &["road.sections"]);
    let limit = arena_sim::MAX_ROAD_SECTIONS;
    invalid(create(&registry, inline(road_of(limit + 1, 2, false)), CreateOptions::default()), &["road.sections"]);
    // At the bounds (every section an arc, 64 lanes, recording on), a reset's reply and a
    // render fit a message.
    let options = CreateOptions { record: true, render_size: Some((512, 512)), ..CreateOptions::default() };
    let env = create(&registry, inline(road_of(limit, 64, true)), options).expect("a road at the bounds");
    let reset = RequestBody::Reset { env, seq: 1, seed: Some(1), options: ResetOptions::default() };
    let (body, bytes) = ask(&registry, reset);
    let ReplyBody::Reset(reply) = body else { panic!("{body:?}") };
    assert!(reply.world.is_some(), "a recording's reset carries the road");
    assert!(bytes <= MAX_MESSAGE_BYTES / 2, "a reset reply of {bytes} bytes");
    let (body, _) = ask(&registry, RequestBody::Render { env, mode: RenderMode::RgbArray, follow: None });
    assert!(matches!(body, ReplyBody::Render(_)), "{body:?}");
    // A road that lies over itself at every point: 1024 full circles of one ring. Each
    // pixel's paint looks at a bounded number of its sections.
    let ring = format!("{{ length = {}, radius = 40.0 }}", 2.0 * std::f64::consts::PI * 40.0);
    let rings = road_of(limit, 2, false).replacen(&format!("{{ length = {} }}", 50_000.0 / limit as f64), &ring, limit);
    assert_eq!(rings.matches("radius = 40.0").count(), limit);
    let options = CreateOptions { render_size: Some((512, 512)), ..CreateOptions::default() };
    let env = create(&registry, inline(rings), options).expect("a ring road at the section bound");
    let reset = RequestBody::Reset { env, seq: 1, seed: Some(1), options: ResetOptions::default() };
    assert!(matches!(ask(&registry, reset).0, ReplyBody::Reset(_)));
    let (body, _) = ask(&registry, RequestBody::Render { env, mode: RenderMode::RgbArray, follow: None });
    let ReplyBody::Render(arena_protocol::Frame::Rgb { pixels, .. }) = body else { panic!("{body:?}") };
    assert!(pixels.chunks(3).any(|pixel| pixel != &pixels[..3]), "the ring is drawn");
    still_serves(&registry);
}

#[test]
fn numbers_that_are_not_finite_in_a_scenario_are_refused_naming_the_key() {
    let registry = registry();
    let base = road_of(1, 2, false);
    let origin = base.replace("[road]\n", "[road]\norigin = { x = nan, y = 0.0, heading = 0.0 }\n");
    invalid(create(&registry, inline(origin), CreateOptions::default()), &["road.origin.x"]);
    let placed = base.replace("lane = 0\ns = 3.0", "x = nan\ny = nan");
    invalid(create(&registry, inline(placed), CreateOptions::default()), &["vehicle 'ego'", "x"]);
    let infinite = base.replace("lane = 0\ns = 3.0", "x = inf\ny = 1.0");
    invalid(create(&registry, inline(infinite), CreateOptions::default()), &["vehicle 'ego'", "x"]);
    still_serves(&registry);
}

#[test]
fn client_tags_without_envs_are_bounded_and_an_owner_is_never_forgotten() {
    let registry = registry();
    let env = create(&registry, named("merge"), CreateOptions::default()).expect("merge");
    registry.client_arrived(CLIENT.tag());
    // A session declaring tokens in a loop.
    for k in 0..3 * MAX_CLIENT_TAGS as u128 {
        registry.client_arrived(ClientTag(k + 1_000_000));
        assert!(registry.client_tags() <= MAX_CLIENT_TAGS + 1, "{} tags after {k}", registry.client_tags());
    }
    // The owner's token is remembered through the flood: its env is no orphan.
    let later = Instant::now() + ORPHAN_GRACE + Duration::from_secs(1);
    assert!(registry.unseen_owners(later).is_empty());
    assert_eq!(registry.reclaim_orphans(later), 0);
    assert!(matches!(reset(&registry, env, &[]), ReplyBody::Reset(_)));
}
