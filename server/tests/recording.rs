//! Recordings through the request handler, as bytes in and out: with recording on, a
//! reset reply carries the road and every vehicle and each step reply a frame of every
//! vehicle per control period, which agree with the agents' own infos; with it off (never
//! turned on, or turned off by a `Record` request) the replies carry none; turned on
//! mid-episode, the reply is the world as it is then.

use arena_protocol::{
    Action, ClientId, CreateOptions, EndReason, EnvId, InfoValue, PROTOCOL_VERSION, Reply, ReplyBody, Request,
    RequestBody, ResetOptions, ResetReply, ScenarioSource, StepReply, WorldStart, decode, encode, info,
};
use arena_server::transport::{Limits, Registry, Scenarios};

const CLIENT: ClientId = ClientId(11);

fn registry() -> Registry {
    Registry::new("recording".into(), Scenarios::load(None).expect("built-in scenarios"), Limits::default())
}

fn ask(registry: &Registry, body: RequestBody) -> ReplyBody {
    let reply: Reply = decode(&registry.handle(&encode(&Request { version: PROTOCOL_VERSION, client: CLIENT, body })))
        .expect("a reply");
    reply.body
}

fn create(registry: &Registry, scenario: &str, record: bool) -> EnvId {
    let options = CreateOptions { record, ..CreateOptions::default() };
    match ask(registry, RequestBody::CreateEnv { scenario: ScenarioSource::Named(scenario.into()), options }) {
        ReplyBody::Created { env, .. } => env,
        other => panic!("create {scenario}: {other:?}"),
    }
}

fn reset(registry: &Registry, env: EnvId, seq: u64) -> ResetReply {
    let body = RequestBody::Reset { env, seq, seed: Some(5), options: ResetOptions::default() };
    match ask(registry, body) {
        ReplyBody::Reset(reply) => reply,
        other => panic!("reset: {other:?}"),
    }
}

fn step(registry: &Registry, env: EnvId, seq: u64, actions: Vec<(String, Action)>) -> StepReply {
    match ask(registry, RequestBody::Step { env, seq, actions }) {
        ReplyBody::Step(reply) => reply,
        other => panic!("step: {other:?}"),
    }
}

fn record(registry: &Registry, env: EnvId, on: bool) -> Option<Box<WorldStart>> {
    match ask(registry, RequestBody::Record { env, on }) {
        ReplyBody::Recording(start) => start,
        other => panic!("record: {other:?}"),
    }
}

fn f64_info(info: &arena_protocol::Info, key: &str) -> f64 {
    match info.get(key) {
        Some(InfoValue::F64(x)) => *x,
        other => panic!("{key}: {other:?}"),
    }
}

#[test]
fn a_recording_step_reply_carries_every_vehicle_and_one_without_recording_none() {
    let registry = registry();
    let env = create(&registry, "merge-random", true);
    let start = reset(&registry, env, 1).world.expect("recording on: the reset reply carries the world");
    // merge-random: the learner ec_0 and the game-theoretic ac, and the road's two lanes,
    // the right one ending before the road does.
    let names: Vec<&str> = start.vehicles.iter().map(|v| v.name.as_str()).collect();
    assert_eq!(names, ["ac", "ec_0"]);
    assert!(start.vehicles.iter().any(|v| v.learner && v.name == "ec_0"));
    assert!(matches!(start.vehicles[0].driver, arena_protocol::DriverInfo::Gt { .. }), "{:?}", start.vehicles[0]);
    assert_eq!(start.road.lanes.len(), 2);
    assert_eq!(start.road.lanes.iter().filter(|lane| lane.ends_early).count(), 1);
    assert_eq!(start.frame.time, 0.0);
    assert_eq!(start.frame.vehicles.len(), 2);

    let mut time = 0.0;
    for seq in 2..12 {
        let reply = step(&registry, env, seq, vec![("ec_0".into(), Action::Meta(1))]);
        // merge steps one control period (0.1 s): one frame, of every vehicle.
        assert_eq!(reply.world.len(), 1, "step {seq}");
        let frame = &reply.world[0];
        assert_eq!(frame.vehicles.len(), start.vehicles.len());
        assert!(frame.time > time, "frames move forward in time");
        time = frame.time;
        // The learner's vehicle in the frame is the one its info describes.
        let ec = &frame.vehicles[1];
        let info = &reply.steps[0].info;
        assert_eq!(ec.speed, f64_info(info, info::SPEED));
        assert_eq!(ec.s, f64_info(info, info::S));
        assert_eq!(
            i64::from(ec.lane),
            match info.get(info::LANE) {
                Some(InfoValue::I64(lane)) => *lane,
                other => panic!("lane: {other:?}"),
            }
        );
        assert_eq!(ec.end, EndReason::Running);
    }
    assert!((time - 1.0).abs() < 1e-9, "ten steps of 0.1 s, not {time}");

    // Turned off, the replies carry nothing; an env that never recorded neither.
    assert!(record(&registry, env, false).is_none());
    assert!(step(&registry, env, 12, vec![]).world.is_empty());
    let plain = create(&registry, "merge-random", false);
    assert!(reset(&registry, plain, 1).world.is_none());
    assert!(step(&registry, plain, 2, vec![]).world.is_empty());

    // Turned on mid-episode: the world as it is now, and frames again from the next step.
    let now = record(&registry, plain, true).expect("the world now");
    assert!((now.frame.time - 0.1).abs() < 1e-9, "{}", now.frame.time);
    assert_eq!(now.vehicles.len(), 2);
    assert_eq!(step(&registry, plain, 3, vec![]).world.len(), 1);
}

#[test]
fn a_step_of_several_control_periods_carries_a_frame_per_period() {
    let registry = registry();
    let env = create(&registry, "highway", true);
    let start = reset(&registry, env, 1).world.expect("the world");
    // highway: 51 vehicles, one decision per second, drivers deciding every 0.1 s.
    assert_eq!(start.vehicles.len(), 51);
    let reply = step(&registry, env, 2, vec![]);
    let times: Vec<f64> = reply.world.iter().map(|f| f.time).collect();
    assert_eq!(times.len(), 10, "{times:?}");
    for (k, time) in times.iter().enumerate() {
        assert!((time - 0.1 * (k + 1) as f64).abs() < 1e-9, "{times:?}");
    }
    assert!(reply.world.iter().all(|f| f.vehicles.len() == 51));
}

#[test]
fn the_same_seed_and_actions_record_the_same_bits() {
    let run = || {
        let registry = registry();
        let env = create(&registry, "overtake", true);
        let mut bytes = encode(&reset(&registry, env, 1).world);
        for seq in 2..30 {
            bytes.extend(encode(&step(&registry, env, seq, vec![]).world));
        }
        bytes
    };
    assert_eq!(run(), run());
}
