use super::*;
use arena_protocol::InfoValue;
use arena_sim::scenario::builtin;

fn env(name: &str, options: CreateOptions) -> Env {
    Env::new(builtin(name).unwrap().unwrap(), &options, 1).unwrap()
}

fn meta(agent: &str, choice: u32) -> Vec<(String, Action)> {
    vec![(agent.to_string(), Action::Meta(choice))]
}

#[test]
fn step_before_reset_is_refused_and_reset_makes_every_agent_live() {
    let mut env = env("merge", CreateOptions::default());
    assert_eq!(env.step(&[]).unwrap_err().code, ErrorCode::NotReset);
    let outcome = env.reset(Some(3), &[]);
    assert_eq!(outcome.len(), 1);
    assert_eq!(env.live_agents(), ["ec_0"]);
}

#[test]
fn observations_lie_inside_their_space() {
    for name in ["merge", "overtake", "highway"] {
        for kind in [ObservationKind::Kinematics, ObservationKind::KinematicsWithMask] {
            let mut env = env(name, CreateOptions { observation: Some(kind), ..CreateOptions::default() });
            let specs = env.specs();
            let space = &specs.observation_spaces[0].1;
            let reset = env.reset(Some(1), &[]);
            assert!(space.contains(&reset[0].1), "{name}: reset observation outside {space:?}");
            for _ in 0..5 {
                let steps = env.step(&[]).unwrap();
                assert!(space.contains(&steps[0].observation), "{name}: {:?}", steps[0].observation);
            }
            let state = env.state().unwrap();
            assert!(specs.state_space.contains(&state), "{name}: state outside its space");
        }
    }
}

#[test]
fn a_crashed_agent_leaves_at_once_and_never_returns() {
    // merge: ec in the lane that ends; asking for "slower" while holding the lane drives
    // it into the lane end... it stops instead (meta keeps speed). Drive it right, off
    // the road edge, which ends its episode.
    let mut env = env("merge", CreateOptions::default());
    env.reset(Some(0), &[]);
    let mut finished_at = None;
    for k in 0..200 {
        let steps = env.step(&meta("ec_0", 0)).unwrap(); // left into ac's lane: a crash or a merge
        let ec = &steps[0];
        if ec.terminated || ec.truncated {
            finished_at = Some(k);
            break;
        }
    }
    // Whatever ended it, afterwards ec is gone for good.
    assert!(finished_at.is_some());
    assert!(env.live_agents().is_empty());
    assert_eq!(env.step(&meta("ec_0", 1)).unwrap_err().code, ErrorCode::AgentNotLive);
}

#[test]
fn missing_action_keeps_lane_and_speed() {
    let mut a = env("highway", CreateOptions::default());
    let mut b = env("highway", CreateOptions::default());
    assert_eq!(a.reset(Some(5), &[]), b.reset(Some(5), &[]));
    for _ in 0..3 {
        assert_eq!(a.step(&[]).unwrap(), b.step(&meta("ego_0", 1)).unwrap());
    }
}

#[test]
fn truncation_at_exactly_max_cycles() {
    let mut env = env("highway", CreateOptions { max_cycles: Some(3), ..CreateOptions::default() });
    env.reset(Some(2), &[]);
    assert!(!env.step(&[]).unwrap()[0].truncated);
    assert!(!env.step(&[]).unwrap()[0].truncated);
    let last = env.step(&[]).unwrap();
    assert!(last[0].truncated && !last[0].terminated);
    assert!(env.live_agents().is_empty());
}

#[test]
fn unknown_option_keys_are_ignored() {
    let mut a = env("merge", CreateOptions::default());
    let mut b = env("merge", CreateOptions::default());
    let odd = [("no_such_option".to_string(), OptionValue::Bool(true))];
    assert_eq!(a.reset(Some(9), &odd), b.reset(Some(9), &[]));
}

#[test]
fn bad_actions_are_refused_without_stepping() {
    let mut env = env("merge", CreateOptions::default());
    env.reset(Some(0), &[]);
    let before = env.world().unwrap().clone();
    let refuse = |env: &mut Env, actions: Vec<(String, Action)>| env.step(&actions).unwrap_err().code;
    assert_eq!(refuse(&mut env, meta("nobody", 1)), ErrorCode::UnknownAgent);
    assert_eq!(refuse(&mut env, meta("ec_0", 5)), ErrorCode::InvalidAction);
    assert_eq!(refuse(&mut env, vec![("ec_0".into(), Action::Continuous([0.0, 0.0]))]), ErrorCode::WrongActionType);
    let mut twice = meta("ec_0", 1);
    twice.extend(meta("ec_0", 2));
    assert_eq!(refuse(&mut env, twice), ErrorCode::InvalidAction);
    assert_eq!(env.world().unwrap(), &before);

    let mut continuous = super::Env::new(
        builtin("merge").unwrap().unwrap(),
        &CreateOptions { action_type: Some(ActionType::Continuous), ..CreateOptions::default() },
        1,
    )
    .unwrap();
    continuous.reset(Some(0), &[]);
    for bad in [[f32::NAN, 0.0], [0.0, f32::INFINITY], [100.0, 0.0], [0.0, -9.0]] {
        assert_eq!(refuse(&mut continuous, vec![("ec_0".into(), Action::Continuous(bad))]), ErrorCode::InvalidAction);
    }
    assert!(continuous.step(&[("ec_0".into(), Action::Continuous([1.0, 0.0]))]).is_ok());
}

#[test]
fn same_seed_same_bits_other_seed_differs() {
    let run = |seed| {
        let mut env = env("highway", CreateOptions::default());
        let mut replies = vec![format!("{:?}", env.reset(Some(seed), &[]))];
        for k in 0..5u32 {
            replies.push(format!("{:?}", env.step(&meta("ego_0", k % 5)).unwrap()));
        }
        replies
    };
    assert_eq!(run(4), run(4));
    assert_ne!(run(4), run(5));
}

#[test]
fn reward_is_minus_the_cost_and_a_crash_costs_the_penalty() {
    let mut env = env("merge", CreateOptions::default());
    env.reset(Some(0), &[]);
    let step = &env.step(&[]).unwrap()[0];
    let cost = step.info.values.iter().find(|(k, _)| k == "cost").map(|(_, v)| v.clone());
    let Some(InfoValue::F64(cost)) = cost else { panic!("no cost in {:?}", step.info) };
    assert!(cost > 0.0);
    assert_eq!(step.reward, -cost);
}

#[test]
fn renders_show_the_road() {
    let mut env = env("overtake", CreateOptions { render_size: Some((60, 120)), ..CreateOptions::default() });
    env.reset(Some(0), &[]);
    let Frame::Rgb { height, width, pixels } = env.render(RenderMode::RgbArray).unwrap() else { panic!("rgb") };
    assert_eq!((height, width, pixels.len()), (60, 120, 60 * 120 * 3));
    assert!(pixels.chunks(3).any(|p| p == [50, 200, 80]), "the agent is drawn");
    let Frame::Ansi(text) = env.render(RenderMode::Ansi).unwrap() else { panic!("ansi") };
    assert_eq!(text.matches('@').count(), 1);
    assert_eq!(text.lines().filter(|l| l.starts_with('-')).count(), 4, "{text}");
}

#[test]
fn expert_infos_say_what_the_built_in_av_would_do() {
    let options = CreateOptions { expert: Some(arena_protocol::Game::Stackelberg), ..CreateOptions::default() };
    let mut env = env("merge", options);
    let value = |info: &Info, key: &str| info.values.iter().find(|(k, _)| k == key).map(|(_, v)| v.clone());
    let reset = env.reset(Some(0), &[]);
    let step = env.step(&[]).unwrap();
    for info in [&reset[0].2, &step[0].info] {
        let Some(InfoValue::I64(action)) = value(info, "expert_action") else { panic!("{info:?}") };
        let Some(InfoValue::I64(sigma)) = value(info, "expert_sigma") else { panic!("{info:?}") };
        assert!((0..5).contains(&action) && (-1..=1).contains(&sigma));
        // EC's lane (1) ends; the only way to change lanes is left.
        assert!(sigma <= 0 && action != 2, "sigma {sigma}, action {action}");
        let expected = i64::from(action::meta_equivalent(
            match value(info, "expert_accel") {
                Some(InfoValue::F64(a)) => a,
                other => panic!("{other:?}"),
            },
            arena_sim::road::LaneChange::from_sigma(sigma as i8),
        ));
        assert_eq!(action, expected);
    }
    let plain =
        super::Env::new(builtin("merge").unwrap().unwrap(), &CreateOptions::default(), 1).unwrap().reset(Some(0), &[]);
    assert!(value(&plain[0].2, "expert_action").is_none(), "only on request");
}
