use super::*;
use arena_protocol::{Info, InfoValue, MetaAction, OptionValue};
use arena_sim::builtin_scenario;

const NO_OPTIONS: &ResetOptions = &ResetOptions { overrides: Vec::new() };

/// Reset options overriding `pairs` (dotted keys).
fn overriding(pairs: &[(&str, OptionValue)]) -> ResetOptions {
    ResetOptions { overrides: pairs.iter().map(|(key, value)| (key.to_string(), value.clone())).collect() }
}

fn env(name: &str, options: CreateOptions) -> Env {
    let (_, file, text) = arena_sim::BUILTIN_SCENARIOS.into_iter().find(|(n, ..)| *n == name).unwrap();
    Env::from_text(file, text, &options, 1).unwrap()
}

fn meta(agent: &str, choice: u32) -> Vec<(String, Action)> {
    vec![(agent.to_string(), Action::Meta(choice))]
}

fn meta_of(agent: &str, action: MetaAction) -> Vec<(String, Action)> {
    meta(agent, action.code())
}

#[test]
fn step_before_reset_is_refused_and_reset_makes_every_agent_live() {
    let mut env = env("merge", CreateOptions::default());
    assert_eq!(env.step(&[]).unwrap_err().code, ErrorCode::NotReset);
    let outcome = env.reset(Some(3), NO_OPTIONS).unwrap();
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
            let reset = env.reset(Some(1), NO_OPTIONS).unwrap();
            assert!(space.contains(&reset[0].observation), "{name}: reset observation outside {space:?}");
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
    env.reset(Some(0), NO_OPTIONS).unwrap();
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
    assert_eq!(a.reset(Some(5), NO_OPTIONS).unwrap(), b.reset(Some(5), NO_OPTIONS).unwrap());
    for _ in 0..3 {
        assert_eq!(a.step(&[]).unwrap(), b.step(&meta("ego_0", 1)).unwrap());
    }
}

#[test]
fn truncation_at_exactly_max_cycles() {
    let mut env = env("highway", CreateOptions { max_cycles: Some(3), ..CreateOptions::default() });
    env.reset(Some(2), NO_OPTIONS).unwrap();
    assert!(!env.step(&[]).unwrap()[0].truncated);
    assert!(!env.step(&[]).unwrap()[0].truncated);
    let last = env.step(&[]).unwrap();
    assert!(last[0].truncated && !last[0].terminated);
    assert!(env.live_agents().is_empty());
}

#[test]
fn bad_reset_overrides_are_refused_by_name_and_overrides_apply_to_the_episode() {
    let mut env = env("merge", CreateOptions::default());
    let first = env.reset(Some(9), NO_OPTIONS).unwrap();
    let refused = env.reset(Some(9), &overriding(&[("no_such_key", OptionValue::Bool(true))])).unwrap_err();
    assert_eq!(refused.code, ErrorCode::InvalidScenario);
    assert!(refused.message.contains("no_such_key"), "{refused}");
    assert!(env.step(&[]).is_ok(), "a refused reset leaves the episode as it was");
    let reset = env.reset(Some(9), &overriding(&[("vehicle.ec_0.speed", OptionValue::Float(23.0))])).unwrap();
    let speed = |starts: &[AgentStart]| starts[0].info.get(arena_protocol::info::SPEED).cloned();
    assert_eq!(speed(&reset), Some(InfoValue::F64(23.0)));
    assert_eq!(speed(&first), Some(InfoValue::F64(20.0)));
    // The next reset without the override is the scenario's own again.
    assert_eq!(env.reset(Some(9), NO_OPTIONS).unwrap(), first);
    let bad = overriding(&[("vehicle.nobody.speed", OptionValue::Float(1.0))]);
    assert_eq!(env.reset(Some(9), &bad).unwrap_err().code, ErrorCode::InvalidScenario);
}

#[test]
fn an_override_at_creation_and_the_same_at_reset_give_the_same_episode() {
    for (key, value) in [
        ("vehicle.ac.speed", OptionValue::Float(18.0)),
        ("vehicle.ac.driver", OptionValue::Str("{ kind = \"idm\" }".into())),
        ("road.speed_limits", OptionValue::Str("[30.0, 30.0]".into())),
    ] {
        let options = CreateOptions { overrides: vec![(key.into(), value.clone())], ..CreateOptions::default() };
        let mut created = env("merge", options);
        let mut reset = env("merge", CreateOptions::default());
        let at_creation = created.reset(Some(3), NO_OPTIONS).unwrap();
        let at_reset = reset.reset(Some(3), &overriding(&[(key, value)])).unwrap();
        assert_eq!(at_creation, at_reset, "{key}");
        for _ in 0..30 {
            assert_eq!(created.step(&[]).unwrap(), reset.step(&[]).unwrap(), "{key}");
        }
    }
}

#[test]
fn bad_actions_are_refused_without_stepping() {
    let mut env = env("merge", CreateOptions::default());
    env.reset(Some(0), NO_OPTIONS).unwrap();
    let before = env.world().unwrap().state().clone();
    let refuse = |env: &mut Env, actions: Vec<(String, Action)>| env.step(&actions).unwrap_err().code;
    assert_eq!(refuse(&mut env, meta("nobody", 1)), ErrorCode::UnknownAgent);
    assert_eq!(refuse(&mut env, meta("ec_0", 5)), ErrorCode::InvalidAction);
    assert_eq!(refuse(&mut env, vec![("ec_0".into(), Action::Continuous([0.0, 0.0]))]), ErrorCode::WrongActionType);
    let mut twice = meta("ec_0", 1);
    twice.extend(meta("ec_0", 2));
    assert_eq!(refuse(&mut env, twice), ErrorCode::InvalidAction);
    assert_eq!(env.world().unwrap().state(), &before);

    let mut continuous = super::Env::new(
        builtin_scenario("merge").unwrap().unwrap(),
        &CreateOptions { action_type: Some(ActionType::Continuous), ..CreateOptions::default() },
        1,
    )
    .unwrap();
    continuous.reset(Some(0), NO_OPTIONS).unwrap();
    for bad in [[f32::NAN, 0.0], [0.0, f32::INFINITY], [100.0, 0.0], [0.0, -9.0]] {
        assert_eq!(refuse(&mut continuous, vec![("ec_0".into(), Action::Continuous(bad))]), ErrorCode::InvalidAction);
    }
    assert!(continuous.step(&[("ec_0".into(), Action::Continuous([1.0, 0.0]))]).is_ok());
}

#[test]
fn same_seed_same_bits_other_seed_differs() {
    let run = |seed| {
        let mut env = env("highway", CreateOptions::default());
        let mut replies = vec![format!("{:?}", env.reset(Some(seed), NO_OPTIONS))];
        for k in 0..5u32 {
            replies.push(format!("{:?}", env.step(&meta("ego_0", k % 5)).unwrap()));
        }
        replies
    };
    assert_eq!(run(4), run(4));
    assert_ne!(run(4), run(5));
}

#[test]
fn a_stepper_dropped_and_built_again_mid_episode_changes_no_bit() {
    // Every shipped scenario with a learner, with an expert, explanations and solver
    // counts on; the stepper is dropped before every step, after it made decisions ahead
    // (every second step) that go with it.
    let options = CreateOptions {
        expert: Some(arena_protocol::Game::Stackelberg),
        diagnostics: true,
        explain: true,
        ..Default::default()
    };
    let (mut tested, mut steps) = (Vec::new(), 0);
    for (name, file, text) in arena_sim::BUILTIN_SCENARIOS {
        let Ok(mut reference) = Env::from_text(file, text, &options, 1) else { continue };
        tested.push(name);
        let mut fresh = reference.clone();
        let learners = reference.agents.iter().map(|a| a.name.clone()).collect::<Vec<_>>();
        let mut replies =
            [&mut reference, &mut fresh].map(|env| format!("{:?}", env.reset(Some(7), NO_OPTIONS).unwrap()));
        assert_eq!(replies[0], replies[1], "{name}: reset");
        for k in 0..20u32 {
            if reference.live_agents().is_empty() {
                break;
            }
            steps += 1;
            let actions: Vec<(String, Action)> =
                learners.iter().flat_map(|learner| meta(learner, (k / 3) % 5)).collect();
            if k % 2 == 0 {
                fresh.decide_ahead(&|| false);
            }
            fresh.stepper = fresh.stepper_for_episode();
            for (env, reply) in [&mut reference, &mut fresh].into_iter().zip(&mut replies) {
                *reply = format!("{:?} {:?}", env.step(&actions).unwrap(), env.take_explanations());
            }
            assert_eq!(replies[0], replies[1], "{name}: step {k}");
        }
        assert!(reference.state == fresh.state, "{name}: the envs' states parted");
        assert!(reference.world().unwrap().state() == fresh.world().unwrap().state(), "{name}: the worlds parted");
    }
    assert!(tested.len() >= 6 && steps >= 100, "only {tested:?} have a learner, stepped {steps} times");
}

fn info<'a>(step: &'a AgentStep, key: &str) -> Option<&'a InfoValue> {
    step.info.get(key)
}

#[test]
fn reward_maps_the_cost_into_the_unit_interval_and_a_crash_earns_the_default_crash_reward() {
    let mut env = env("merge", CreateOptions::default());
    env.reset(Some(0), NO_OPTIONS).unwrap();
    let step = &env.step(&[]).unwrap()[0];
    let Some(&InfoValue::F64(cost)) = info(step, "cost") else { panic!("no cost in {:?}", step.info) };
    let scale = arena_sim::RewardSpec::DEFAULT_COST_SCALE;
    assert!(cost > 0.0 && step.reward > 0.0 && step.reward <= 1.0);
    // EC drives about 20 m/s of the 25 it aims for: 0.8 of J_0 / (J_0 + J).
    let Some(&InfoValue::F64(speed)) = info(step, "speed") else { panic!() };
    let progress = step.reward / (scale / (scale + cost));
    assert!((progress - speed / 25.0).abs() < 0.01 && progress < 0.85, "{progress} at {speed} m/s");
    assert_eq!(step.info.end_reason(), Some(EndReason::Running), "until the step an agent leaves");
    // Full throttle into a slow car ahead in the same lane crashes.
    let options = CreateOptions { action_type: Some(ActionType::Continuous), ..CreateOptions::default() };
    let mut env = super::Env::new(builtin_scenario("merge").unwrap().unwrap(), &options, 1).unwrap();
    let slow_car_ahead = overriding(&[
        ("vehicle.ac.lane", OptionValue::Int(1)),
        ("vehicle.ac.s", OptionValue::Float(80.0)),
        ("vehicle.ac.speed", OptionValue::Float(5.0)),
        ("vehicle.ac.target_speed", OptionValue::Float(5.0)),
    ]);
    env.reset(Some(0), &slow_car_ahead).unwrap();
    let mut last = None;
    for _ in 0..200 {
        let steps = env.step(&[("ec_0".to_string(), Action::Continuous([1.0, 0.0]))]).unwrap();
        if steps[0].terminated || steps[0].truncated {
            last = Some(steps[0].clone());
            break;
        }
    }
    let last = last.expect("the episode ended");
    assert_eq!(last.info.end_reason(), Some(EndReason::Collision), "{:?}", last.info);
    let bonus = arena_sim::RewardSpec::DEFAULT_GOAL_BONUS;
    assert_eq!(last.reward, -2200.0 - 2.0 * bonus, "200 steps: -((1 + the risk weight 10) x 200 + 2 x the goal bonus)");
}

#[test]
fn driving_past_the_end_of_the_lane_ends_with_lane_end_and_time_limits_with_time_limit() {
    let options = CreateOptions { max_cycles: Some(400), ..CreateOptions::default() };
    let mut env = env("merge", options);
    // With the adjacent car far behind nothing is hit; holding the lane runs off its end.
    env.reset(Some(0), &overriding(&[("vehicle.ac.s", OptionValue::Float(5.0))])).unwrap();
    let ended = (0..400).find_map(|_| {
        let steps = env.step(&meta_of("ec_0", MetaAction::Idle)).unwrap();
        (steps[0].terminated || steps[0].truncated).then(|| steps[0].clone())
    });
    let ended = ended.expect("the lane ends within 400 steps");
    assert_eq!(ended.info.end_reason(), Some(EndReason::LaneEnd));
    let bonus = arena_sim::RewardSpec::DEFAULT_GOAL_BONUS;
    assert_eq!(ended.reward, -4400.0 - 2.0 * bonus, "-((1 + 10) x 400 + 2 x the goal bonus)");
    let mut short = env_with_cycles("highway", 2);
    short.reset(Some(0), NO_OPTIONS).unwrap();
    short.step(&[]).unwrap();
    let last = short.step(&[]).unwrap().remove(0);
    assert!(last.truncated);
    assert_eq!(last.info.end_reason(), Some(EndReason::TimeLimit));
}

fn env_with_cycles(name: &str, cycles: u32) -> Env {
    env(name, CreateOptions { max_cycles: Some(cycles), ..CreateOptions::default() })
}

#[test]
fn slower_can_stop_a_learner_behind_the_end_of_its_lane() {
    // The ladder goes down to 0: five `slower` from 25 m/s and the car stops.
    let mut env = env("merge", CreateOptions::default());
    env.reset(Some(0), &overriding(&[("vehicle.ac.s", OptionValue::Float(5.0))])).unwrap();
    let mut last = None;
    for _ in 0..150 {
        let steps = env.step(&meta_of("ec_0", MetaAction::Slower)).unwrap();
        assert!(!steps[0].terminated, "{:?}", steps[0].info);
        last = Some(steps[0].clone());
    }
    let last = last.unwrap();
    let Some(&InfoValue::F64(speed)) = info(&last, "speed") else { panic!() };
    let Some(&InfoValue::F64(s)) = info(&last, "s") else { panic!() };
    assert!(speed.abs() < 0.1 && s < 252.0, "stopped at s = {s}, speed {speed}");
    assert_eq!(info(&last, "action_applied"), Some(&InfoValue::Bool(false)), "at 0 `slower` has nothing to do");
}

#[test]
fn renders_show_the_road() {
    let mut env = env("overtake", CreateOptions { render_size: Some((60, 120)), ..CreateOptions::default() });
    env.reset(Some(0), NO_OPTIONS).unwrap();
    let Frame::Rgb { height, width, pixels } = env.render(RenderMode::RgbArray, None).unwrap() else { panic!("rgb") };
    assert_eq!((height, width, pixels.len()), (60, 120, 60 * 120 * 3));
    assert!(pixels.chunks(3).any(|p| p == [50, 200, 80]), "the learner is drawn green");
    assert!(pixels.chunks(3).any(|p| p == [60, 120, 235]), "the game-theoretic adjacent cars are drawn blue");
    assert!(pixels.chunks(3).any(|p| p == [230, 200, 60]), "the IDM lead car is drawn yellow");
    assert!(pixels.chunks(3).filter(|p| *p == [255, 255, 255]).count() > 50, "the time and legend are written");
    let Frame::Ansi(text) = env.render(RenderMode::Ansi, None).unwrap() else { panic!("ansi") };
    let road: String = text.lines().filter(|l| l.starts_with('.') || l.starts_with(' ')).collect();
    assert_eq!((road.matches('@').count(), road.matches('G').count(), road.matches('>').count()), (1, 2, 1), "{text}");
    assert!(text.contains("G game-theoretic"), "{text}");
    assert_eq!(text.lines().filter(|l| l.starts_with('-')).count(), 4, "{text}");
}

/// The colour of pixel (row, col) of an RGB frame.
fn pixel(frame: &Frame, row: u32, col: u32) -> [u8; 3] {
    let Frame::Rgb { width, pixels, .. } = frame else { panic!("rgb") };
    let at = ((row * width + col) * 3) as usize;
    [pixels[at], pixels[at + 1], pixels[at + 2]]
}

/// How many pixels of `frame` have colour `paint`, in rows `rows`.
fn painted(frame: &Frame, paint: [u8; 3], rows: std::ops::Range<u32>) -> usize {
    let Frame::Rgb { width, .. } = frame else { panic!("rgb") };
    rows.flat_map(|row| (0..*width).map(move |col| (row, col))).filter(|&(r, c)| pixel(frame, r, c) == paint).count()
}

#[test]
fn rgb_frames_follow_the_vehicle_the_client_names() {
    let mut env = env("merge", CreateOptions { render_size: Some((300, 600)), ..CreateOptions::default() });
    env.reset(Some(0), NO_OPTIONS).unwrap();
    let centre = |follow| pixel(&env.render(RenderMode::RgbArray, follow).unwrap(), 150, 300);
    assert_eq!(centre(None), [50, 200, 80], "by default the frame is centred on the learner, drawn green");
    assert_eq!(centre(Some("ac")), [60, 120, 235], "following the game-theoretic AC puts it, blue, at the centre");
    let refused = env.render(RenderMode::RgbArray, Some("nobody")).unwrap_err();
    assert_eq!(refused.code, ErrorCode::InvalidOption);
    assert!(refused.message.contains("'nobody'") && refused.message.contains("ac, ec_0"), "{refused}");
    let Frame::Ansi(text) = env.render(RenderMode::Ansi, Some("ac")).unwrap() else { panic!("ansi") };
    assert!(text.contains("ac: lane 0"), "{text}");
}

#[test]
fn rgb_frames_draw_a_bend_as_a_bend() {
    // A left bend of radius 80 m from (0, 0), heading east. 40 m along it the road lies
    // at (80 sin 0.5, 80 (1 - cos 0.5)) = (38.4, 9.8); the straight tangent at (40, 0) is
    // 9.4 m right of the bend's centre line, off the road.
    let text = r#"
        name = "bend"
        [road]
        lanes = 2
        lane_width = 4.0
        speed_limits = [20.0, 20.0]
        origin = { x = 0.0, y = 0.0, heading = 0.0 }
        sections = [{ length = 300.0, radius = 80.0 }]
        [[vehicle]]
        name = "ego"
        lane = 0
        s = 1.0
        speed = 10.0
        driver = { kind = "agent", style = "normal" }
    "#;
    let options = CreateOptions { render_size: Some((300, 600)), ..CreateOptions::default() };
    let mut env = Env::from_text("bend.toml", text, &options, 1).unwrap();
    env.reset(Some(0), NO_OPTIONS).unwrap();
    let frame = env.render(RenderMode::RgbArray, None).unwrap();
    // 5 pixels per metre (600 px for 120 m), centred on the car at s = 1 m.
    let at = |x: f64, y: f64| pixel(&frame, (150.0 - (y - 0.0) * 5.0) as u32, (300.0 + (x - 1.0) * 5.0) as u32);
    assert_eq!(at(38.4, 9.8), [90, 90, 90], "40 m along the bend is asphalt");
    assert_eq!(at(40.0, 0.0), [60, 110, 60], "the straight tangent 40 m on is grass");
    assert_eq!(at(-10.0, 0.0), [60, 110, 60], "before the road's start is grass");
}

#[test]
fn rgb_frames_paint_a_game_theoretic_car_in_its_styles_blue() {
    let mut env = env("merge", CreateOptions { render_size: Some((300, 600)), ..CreateOptions::default() });
    let styled = |style: &str| overriding(&[("vehicle.ac.driver.style", OptionValue::Str(style.into()))]);
    let mut centre = |style: &str| {
        env.reset(Some(0), &styled(style)).unwrap();
        pixel(&env.render(RenderMode::RgbArray, Some("ac")).unwrap(), 150, 300)
    };
    // The recordings' blues (protocol/src/palette.rs), darker the bolder.
    assert_eq!(centre("aggressive"), [40, 70, 200]);
    assert_eq!(centre("normal"), [60, 120, 235]);
    assert_eq!(centre("conservative"), [120, 190, 250]);
}

#[test]
fn rgb_frames_mark_lane_ends_and_show_how_the_episode_ended() {
    let mut env = env("merge", CreateOptions { render_size: Some((300, 600)), ..CreateOptions::default() });
    env.reset(Some(0), NO_OPTIONS).unwrap();
    let first = env.render(RenderMode::RgbArray, None).unwrap();
    assert_eq!(painted(&first, [150, 20, 20], 0..300), 0, "no end banner while the episode runs");
    assert_eq!(painted(&first, [200, 30, 30], 0..280), 0, "the lane end (s = 252) is out of the first frame");
    // Idle in the ending lane: the learner drives past its end.
    while !env.live_agents().is_empty() {
        env.step(&[]).unwrap();
    }
    let last = env.render(RenderMode::RgbArray, None).unwrap();
    assert!(painted(&last, [150, 20, 20], 0..20) > 100, "the end reason is written on a red banner");
    assert!(painted(&last, [200, 30, 30], 0..280) > 20, "the lane end is marked red and white across its lane");
}

#[test]
fn rgb_text_grows_with_the_frame() {
    let mut env = env("merge", CreateOptions { render_size: Some((600, 1200)), ..CreateOptions::default() });
    env.reset(Some(0), NO_OPTIONS).unwrap();
    let large = env.render(RenderMode::RgbArray, None).unwrap();
    let mut env =
        super::tests::env("merge", CreateOptions { render_size: Some((150, 300)), ..CreateOptions::default() });
    env.reset(Some(0), NO_OPTIONS).unwrap();
    let small = env.render(RenderMode::RgbArray, None).unwrap();
    // The legend's learner swatch: 5 x 5 font pixels, each 1 pixel at 150 rows, 4 at 600.
    assert_eq!(painted(&small, [50, 200, 80], 143..150), 25);
    assert_eq!(painted(&large, [50, 200, 80], 572..600), 25 * 16);
}

#[test]
fn the_server_clocks_the_decisions_of_the_learners_it_drives_and_nothing_else() {
    let policy = Some(BuiltinPolicy::Gt { style: None, game: arena_protocol::Game::Stackelberg });
    let mut driven = env("merge", CreateOptions { policy, ..CreateOptions::default() });
    driven.reset(Some(0), NO_OPTIONS).unwrap();
    for _ in 0..5 {
        driven.step(&[]).unwrap();
    }
    let statistics = driven.statistics();
    assert_eq!(statistics.decision_micros.len(), 1);
    let (agent, micros) = &statistics.decision_micros[0];
    assert_eq!((agent.as_str(), micros.len()), ("ec_0", 5), "one sample per step");
    assert!(micros.iter().all(|&us| us > 0.0 && us.is_finite()), "{micros:?}");
    let mut played = env("merge", CreateOptions::default());
    played.reset(Some(0), NO_OPTIONS).unwrap();
    played.step(&[]).unwrap();
    assert!(played.statistics().decision_micros.is_empty(), "a learner the client drives is the client's to time");
}

#[test]
fn past_a_lane_end_the_line_beside_it_is_a_solid_edge_and_the_ended_lane_has_none() {
    let mut env = env("merge", CreateOptions::default());
    env.reset(Some(0), NO_OPTIONS).unwrap();
    let world = env.world().unwrap();
    let marked = |s: f64, d: f64| super::render::is_marking(world, s, d, 0.05);
    // Between lanes 0 and 1 (d = -2): dashed while both go on, solid after lane 1 ends.
    let before: Vec<bool> = (0..12).map(|k| marked(100.0 + k as f64 * 0.5, -2.0)).collect();
    assert!(before.contains(&true) && before.contains(&false), "dashed: {before:?}");
    assert!((0..40).all(|k| marked(260.0 + k as f64 * 0.5, -2.0)), "solid past the end");
    // The right edge of lane 1 (d = -6) is drawn up to the end and not after.
    assert!(marked(200.0, -6.0) && !marked(300.0, -6.0));
}

#[test]
fn expert_infos_say_what_the_built_in_av_would_do() {
    let options = CreateOptions { expert: Some(arena_protocol::Game::Stackelberg), ..CreateOptions::default() };
    let mut env = env("merge", options);
    let value = |info: &Info, key: &str| info.get(key).cloned();
    let reset = env.reset(Some(0), NO_OPTIONS).unwrap();
    let step = env.step(&[]).unwrap();
    for info in [&reset[0].info, &step[0].info] {
        let Some(InfoValue::I64(action)) = value(info, "expert_action") else { panic!("{info:?}") };
        let Some(InfoValue::I64(sigma)) = value(info, "expert_sigma") else { panic!("{info:?}") };
        assert!((0..5).contains(&action) && (-1..=1).contains(&sigma));
        // EC's lane (1) ends; the only way to change lanes is left.
        assert!(sigma <= 0 && action != 2, "sigma {sigma}, action {action}");
        // A lane change in the expert's decision is the lane action; otherwise a speed one.
        let speed_actions = [MetaAction::Idle, MetaAction::Faster, MetaAction::Slower];
        match sigma {
            -1 => assert_eq!(action, i64::from(MetaAction::LaneLeft.code())),
            _ => assert!(speed_actions.map(|a| i64::from(a.code())).contains(&action), "{action}"),
        }
    }
    let plain = super::Env::new(builtin_scenario("merge").unwrap().unwrap(), &CreateOptions::default(), 1)
        .unwrap()
        .reset(Some(0), NO_OPTIONS)
        .unwrap();
    assert!(value(&plain[0].info, "expert_action").is_none(), "only on request");
}

#[test]
fn rewards_are_bounded_and_a_crash_is_worse_than_any_step_or_episode_without_one() {
    use rand::{RngExt, SeedableRng};
    for (name, ..) in arena_sim::BUILTIN_SCENARIOS {
        for action_type in [ActionType::Meta, ActionType::Continuous] {
            let options = CreateOptions { action_type: Some(action_type), ..CreateOptions::default() };
            let mut env = env(name, options);
            let agent = env.specs().possible_agents[0].clone();
            let max_cycles = env.specs().max_cycles;
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
            let (mut crashed_returns, mut clean_returns, mut failed_returns) = (Vec::new(), Vec::new(), Vec::new());
            // Random play, then two adversaries: always left, always full throttle.
            for policy in 0..3 {
                'episodes: for seed in 0..4 {
                    env.reset(Some(seed), NO_OPTIONS).unwrap();
                    let (mut total, mut crashed) = (0.0, false);
                    loop {
                        let action = match (action_type, policy) {
                            (ActionType::Meta, 0) => Action::Meta(rng.random_range(0..5)),
                            (ActionType::Meta, 1) => Action::Meta(MetaAction::LaneLeft.code()),
                            (ActionType::Meta, _) => Action::Meta(MetaAction::Faster.code()),
                            (_, 0) => Action::Continuous([rng.random_range(-1.0..=1.0), rng.random_range(-1.0..=1.0)]),
                            (_, 1) => Action::Continuous([0.0, 1.0]),
                            (_, _) => Action::Continuous([1.0, 0.0]),
                        };
                        let step = env.step(&[(agent.clone(), action)]).unwrap().remove(0);
                        // A time limit reached short of a goal that must be reached
                        // (`[goal] fail_at_time_limit`) ends the episode as a crash does.
                        // It pays `[reward] failure` (the crash reward by default), no less.
                        if step.terminated && step.info.end_reason() == Some(EndReason::TimeLimit) {
                            let failure = env.scenario.reward.failure_reward(max_cycles);
                            assert_eq!(step.reward, failure, "{name}: {:?}", step.info);
                            assert!(failure >= env.scenario.reward.crash_reward(max_cycles) && failure <= 0.0);
                            failed_returns.push(total + step.reward);
                            continue 'episodes;
                        }
                        let ended_badly = matches!(
                            step.info.end_reason(),
                            Some(EndReason::Collision | EndReason::OffRoad | EndReason::LaneEnd)
                        );
                        // The defaults: a step in [-risk weight - goal bonus, 1 + goal bonus], a
                        // crash at -((1 + risk weight) x max_cycles + 2 x goal bonus); the weight
                        // and the bonus are the scenario's (overtake's 15 and 50), the bonus 0 on
                        // one without a goal (the highways).
                        let weight = env.scenario.reward.risk_weight;
                        let bonus = env.scenario.reward.goal_bonus;
                        let has_goal = !(env.scenario.goal.lanes.is_empty() && env.scenario.goal.ahead_of.is_empty());
                        assert!(has_goal || bonus == 0.0, "{name}: bonus {bonus} without a goal");
                        if ended_badly {
                            let crash = -((1.0 + weight) * f64::from(max_cycles) + 2.0 * bonus);
                            assert_eq!(step.reward, crash, "{name}: {:?}", step.info);
                            crashed = true;
                        } else {
                            let (low, high) = (-weight - bonus, 1.0 + bonus);
                            assert!(step.reward >= low && step.reward <= high, "{name}: reward {}", step.reward);
                        }
                        total += step.reward;
                        if step.terminated || step.truncated {
                            break;
                        }
                    }
                    if crashed { crashed_returns.push(total) } else { clean_returns.push(total) }
                }
            }
            assert!(!crashed_returns.is_empty(), "{name} {action_type:?}: the adversaries crash");
            let worst_clean = clean_returns.iter().chain(&failed_returns).copied().fold(f64::INFINITY, f64::min);
            assert!(crashed_returns.iter().all(|&r| r < worst_clean), "{name}: {crashed_returns:?} {clean_returns:?}");
        }
    }
}

/// The mean return over seeds 0..10 of `scenario` (overtake-random, its 1 Hz version or
/// merge-random-1hz, with `reward` overrides) of a learner that changes into the left
/// lane at once, beside the cars there, and then only speeds up (what PPO learned under
/// the reward without risk), and of the AV (`expert`) in its place.
fn squeezer_and_av_returns(scenario: &str, reward: &[(&str, f64)]) -> (f64, f64) {
    let overrides: Vec<(String, OptionValue)> =
        reward.iter().map(|&(key, value)| (key.to_string(), OptionValue::Float(value))).collect();
    let mut returns = [0.0; 2];
    let expert = arena_protocol::BuiltinPolicy::Gt { style: None, game: arena_protocol::Game::Stackelberg };
    for (k, policy) in [None, Some(expert)].into_iter().enumerate() {
        let options = CreateOptions { policy, overrides: overrides.clone(), ..CreateOptions::default() };
        let mut env = env(scenario, options);
        for seed in 0..10 {
            env.reset(Some(seed), NO_OPTIONS).unwrap();
            for step in 0.. {
                let action = if step == 0 { MetaAction::LaneLeft } else { MetaAction::Faster };
                let actions =
                    if policy.is_some() { vec![] } else { vec![("ec_0".to_string(), Action::Meta(action.code()))] };
                let reply = env.step(&actions).unwrap().remove(0);
                returns[k] += reply.reward / 10.0;
                if reply.terminated || reply.truncated {
                    break;
                }
            }
        }
    }
    (returns[0], returns[1])
}

/// Every (reward overrides, squeeze, AV) of a run of `squeezer_and_av_returns`, as CSV
/// (`scenario,overrides,squeeze,av`, overrides as `key=value;...`).
#[derive(Default)]
struct SqueezeCsv(String);

impl SqueezeCsv {
    fn returns(&mut self, scenario: &str, reward: &[(&str, f64)]) -> (f64, f64) {
        let (squeezer, av) = squeezer_and_av_returns(scenario, reward);
        let overrides: Vec<String> = reward.iter().map(|(key, value)| format!("{key}={value}")).collect();
        self.0 += &format!("{scenario},{},{squeezer},{av}\n", overrides.join(";"));
        (squeezer, av)
    }

    /// Writes the rows to $ARENA_SQUEEZE_CSV, if set (docs/rewards.md's table is rendered
    /// from that file: scripts/docs-tables).
    fn write(self) {
        if let Ok(path) = std::env::var("ARENA_SQUEEZE_CSV") {
            std::fs::write(&path, format!("scenario,overrides,squeeze,av\n{}", self.0)).unwrap();
        }
    }
}

#[test]
fn passing_cars_side_by_side_returns_less_than_the_av_under_the_default_reward() {
    // The figures of docs/rewards.md ("Risk", "Goal"): `-- --nocapture` prints them, and
    // ARENA_SQUEEZE_CSV=FILE writes them as CSV.
    let mut csv = SqueezeCsv::default();
    let (squeezer, av) = csv.returns("overtake-random", &[]);
    eprintln!("default reward (goal bonus 50): squeezing {squeezer:.1}, the AV {av:.1}");
    assert!(squeezer < av, "squeezing beside cars returns {squeezer}, the AV {av}");
    // Without the risk term the squeeze out-earns the AV, as PPO found (docs/rewards.md).
    let (squeezer, av) = csv.returns("overtake-random", &[("reward.risk_weight", 0.0)]);
    eprintln!("risk weight 0: squeezing {squeezer:.1}, the AV {av:.1}");
    assert!(squeezer > av + 50.0, "without risk: squeezing {squeezer}, the AV {av}");
    // The goal bonus is paid to both when both pass; the AV passes in fewer of these
    // episodes than the squeeze (it waits behind the slow car when no gap opens). Under
    // overtake-random's risk weight of 15 no bonus from 0 to 100 hands the squeeze the lead.
    for bonus in [0.0, 100.0] {
        let (squeezer, av) = csv.returns("overtake-random", &[("reward.goal_bonus", bonus)]);
        eprintln!("goal bonus {bonus}: squeezing {squeezer:.1}, the AV {av:.1}");
        assert!(squeezer < av, "goal bonus {bonus}: squeezing {squeezer}, the AV {av}");
    }
    // The same under a risk weight of 10 (docs/rewards.md's first two columns): the AV
    // leads up to a bonus of 50; at 100 the two come within a few points of each other,
    // which is why overtake-random pays risk at 15.
    for bonus in [0.0, 50.0, 100.0] {
        let reward = [("reward.goal_bonus", bonus), ("reward.risk_weight", 10.0)];
        let (squeezer, av) = csv.returns("overtake-random", &reward);
        eprintln!("risk weight 10, goal bonus {bonus}: squeezing {squeezer:.1}, the AV {av:.1}");
        assert!(
            bonus >= 100.0 || squeezer < av,
            "risk weight 10, goal bonus {bonus}: squeezing {squeezer}, the AV {av}"
        );
    }
    csv.write();
}

#[test]
fn passing_cars_side_by_side_returns_less_than_the_av_deciding_once_a_second() {
    // overtake-random-1hz: the squeeze holds its lane change for a whole second, and the
    // reward of a step is the mean over its ten control periods, goal bonus 5.
    let (squeezer, av) = squeezer_and_av_returns("overtake-random-1hz", &[]);
    eprintln!("1 Hz, default reward (goal bonus 5): squeezing {squeezer:.1}, the AV {av:.1}");
    assert!(squeezer < av, "squeezing beside cars returns {squeezer}, the AV {av}");
    let (squeezer, av) = squeezer_and_av_returns("overtake-random-1hz", &[("reward.risk_weight", 0.0)]);
    eprintln!("1 Hz, risk weight 0: squeezing {squeezer:.1}, the AV {av:.1}");
    assert!(squeezer > av + 5.0, "without risk: squeezing {squeezer}, the AV {av}");
    // Twice the bonus, as overtake-random's test pays 100 against its 50.
    let (squeezer, av) = squeezer_and_av_returns("overtake-random-1hz", &[("reward.goal_bonus", 10.0)]);
    eprintln!("1 Hz, goal bonus 10: squeezing {squeezer:.1}, the AV {av:.1}");
    assert!(squeezer < av, "goal bonus 10: squeezing {squeezer}, the AV {av}");
    // merge-random-1hz pays a goal bonus of 2 for entering the through lane: cutting in
    // at once beside AC and speeding up still returns less than the AV's merge.
    let (squeezer, av) = squeezer_and_av_returns("merge-random-1hz", &[]);
    eprintln!("merge-random-1hz (goal bonus 2): cutting in {squeezer:.1}, the AV {av:.1}");
    assert!(squeezer < av, "merge-random-1hz: cutting in {squeezer}, the AV {av}");
    // Version 2 (a time limit short of the goal fails as a crash does) keeps the ranking.
    for scenario in ["merge-random-1hz-v2", "overtake-random-1hz-v2"] {
        let (squeezer, av) = squeezer_and_av_returns(scenario, &[]);
        eprintln!("{scenario}: squeezing {squeezer:.1}, the AV {av:.1}");
        assert!(squeezer < av, "{scenario}: squeezing {squeezer}, the AV {av}");
    }
}

#[test]
fn the_goal_bonus_is_paid_once_on_the_step_the_goal_is_reached() {
    // The AV drives the learner's car on merge: it merges into lane 0 (the goal) once.
    let rewards = |bonus: f64| {
        let gt = arena_protocol::BuiltinPolicy::Gt { style: None, game: arena_protocol::Game::Stackelberg };
        let overrides = vec![("reward.goal_bonus".to_string(), OptionValue::Float(bonus))];
        let mut env = env("merge", CreateOptions { policy: Some(gt), overrides, ..CreateOptions::default() });
        env.reset(Some(0), NO_OPTIONS).unwrap();
        let mut rewards = Vec::new();
        loop {
            let step = env.step(&[]).unwrap().remove(0);
            rewards.push(step.reward);
            if step.terminated || step.truncated {
                return (rewards, step.info.clone());
            }
        }
    };
    let ((without, _), (with, info)) = (rewards(0.0), rewards(30.0));
    assert_eq!(figure(&info, arena_protocol::info::EPISODE_SUCCESS), InfoValue::Bool(true));
    let paid: Vec<(usize, f64)> =
        with.iter().zip(&without).map(|(a, b)| a - b).enumerate().filter(|(_, d)| *d != 0.0).collect();
    assert_eq!(paid.len(), 1, "{paid:?}");
    assert!((paid[0].1 - 30.0).abs() < 1e-9, "{paid:?}");
    // Paid on the step the car enters lane 0, not at the start or the end.
    assert!(paid[0].0 > 0 && paid[0].0 + 1 < with.len(), "{paid:?}");
}

#[test]
fn running_out_of_time_short_of_the_goal_fails_as_a_crash_in_version_2_only() {
    // `slower` on every step stops short of merge's lane end and waits out the clock.
    let last_step = |name: &str, policy: Option<arena_protocol::BuiltinPolicy>| {
        let mut env = env(name, CreateOptions { policy, ..CreateOptions::default() });
        env.reset(Some(3), NO_OPTIONS).unwrap();
        let actions = if env.policy.is_some() { Vec::new() } else { meta_of("ec_0", MetaAction::Slower) };
        loop {
            let step = env.step(&actions).unwrap().remove(0);
            if step.terminated || step.truncated {
                return (step, env.scenario.reward.failure_reward(env.max_cycles));
            }
        }
    };
    for (name, fails) in [("merge-random-1hz", false), ("merge-random-1hz-v2", true)] {
        let (step, crash) = last_step(name, None);
        assert_eq!(step.info.end_reason(), Some(EndReason::TimeLimit), "{name}");
        assert_eq!(figure(&step.info, arena_protocol::info::EPISODE_SUCCESS), InfoValue::Bool(false), "{name}");
        assert_eq!((step.terminated, step.truncated), (fails, !fails), "{name}");
        assert_eq!(step.reward == crash, fails, "{name}: reward {} (failure {crash})", step.reward);
    }
    // The AV merges: its time limit is a truncation, in version 2 as before.
    let gt = arena_protocol::BuiltinPolicy::Gt { style: None, game: arena_protocol::Game::Stackelberg };
    let (step, crash) = last_step("merge-random-1hz-v2", Some(gt));
    assert_eq!(figure(&step.info, arena_protocol::info::EPISODE_SUCCESS), InfoValue::Bool(true));
    assert!(step.truncated && !step.terminated && step.reward > crash, "{step:?}");
}

#[test]
fn a_randomised_scenario_repeats_an_episode_bit_for_bit_for_its_seed_and_varies_across_seeds() {
    for name in ["merge-random", "overtake-random"] {
        let run = |seed| {
            let mut env = env(name, CreateOptions::default());
            let mut replies = vec![format!("{:?}", env.reset(Some(seed), NO_OPTIONS).unwrap())];
            for k in 0..20u32 {
                replies.push(format!("{:?}", env.step(&meta("ec_0", k % 5)).unwrap()));
            }
            replies
        };
        assert_eq!(run(5), run(5), "{name}");
        let (a, b) = (run(5), run(6));
        assert_ne!(a[0], b[0], "{name}: two seeds, one first observation");
    }
}

#[test]
fn a_render_size_whose_frames_could_not_travel_is_refused_at_creation() {
    let create = |size| {
        Env::new(
            builtin_scenario("merge").unwrap().unwrap(),
            &CreateOptions { render_size: Some(size), ..CreateOptions::default() },
            1,
        )
    };
    let refused = create((4096, 4096)).unwrap_err();
    assert_eq!(refused.code, ErrorCode::InvalidScenario);
    assert!(refused.message.contains("50331648 bytes") && refused.message.contains("message limit"), "{refused}");
    let mut largest = create((2300, 2300)).unwrap();
    largest.reset(Some(0), NO_OPTIONS).unwrap();
    let Frame::Rgb { pixels, .. } = largest.render(RenderMode::RgbArray, None).unwrap() else { panic!("rgb") };
    assert!(
        arena_protocol::encode(&Frame::Rgb { height: 2300, width: 2300, pixels }).len()
            < arena_protocol::MAX_MESSAGE_BYTES
    );
}

/// Runs one episode of `env` (seed 0) with no actions; returns the last step's info.
fn last_info(env: &mut Env) -> Info {
    env.reset(Some(0), NO_OPTIONS).unwrap();
    loop {
        let steps = env.step(&[]).unwrap();
        let agent = &steps[0];
        let ends = agent.terminated || agent.truncated;
        assert_eq!(agent.info.get(arena_protocol::info::EPISODE_DONE), Some(&InfoValue::Bool(ends)));
        if !ends {
            let figures = agent.info.values.iter().filter(|(k, _)| k.starts_with("episode_"));
            assert!(
                figures
                    .clone()
                    .all(|(_, v)| matches!(v, InfoValue::F64(0.0) | InfoValue::I64(0) | InfoValue::Bool(false))),
                "zero until the last step: {:?}",
                agent.info
            );
        }
        if ends {
            return agent.info.clone();
        }
    }
}

fn figure(info: &Info, key: &str) -> InfoValue {
    info.get(key).cloned().unwrap_or_else(|| panic!("{key}: {info:?}"))
}

#[test]
fn a_built_in_policy_drives_the_learner_in_the_server_and_its_episode_is_summed_up() {
    let gt = arena_protocol::BuiltinPolicy::Gt { style: None, game: arena_protocol::Game::Stackelberg };
    let mut driven = env("merge", CreateOptions { policy: Some(gt), ..CreateOptions::default() });
    let info = last_info(&mut driven);
    // The game-theoretic EC merges into lane 0 (the paper's Scenario A): a success, with
    // its lane change begun within the first seconds, as `arena paper` finds.
    assert_eq!(info.end_reason(), Some(EndReason::TimeLimit));
    assert_eq!(figure(&info, "episode_success"), InfoValue::Bool(true));
    assert_eq!(figure(&info, "episode_length"), InfoValue::I64(200));
    let InfoValue::F64(t_c) = figure(&info, "episode_t_c") else { panic!() };
    assert!((0.5..8.0).contains(&t_c), "t_c {t_c}");
    let InfoValue::F64(gap) = figure(&info, "episode_min_gap") else { panic!() };
    assert!(gap > 0.0 && gap.is_finite(), "min gap {gap}");
    // Sending actions to a learner the server drives is refused, naming the option.
    driven.reset(Some(0), NO_OPTIONS).unwrap();
    let refused = driven.step(&meta("ec_0", 1)).unwrap_err();
    assert!(refused.code == ErrorCode::InvalidAction && refused.message.contains("policy"), "{refused}");

    // Idle in the ending lane: it drives past the lane's end, never merges, and fails.
    let mut idle = env("merge", CreateOptions::default());
    let info = last_info(&mut idle);
    assert_eq!(info.end_reason(), Some(EndReason::LaneEnd));
    assert_eq!(figure(&info, "episode_success"), InfoValue::Bool(false));
    assert_eq!(figure(&info, "episode_t_c"), InfoValue::F64(f64::INFINITY), "no lane change: never");
    assert!(matches!(figure(&info, "episode_length"), InfoValue::I64(n) if n < 200));
}

#[test]
fn an_idm_policy_keeps_the_learner_in_traffic_without_a_crash() {
    let options = CreateOptions { policy: Some(arena_protocol::BuiltinPolicy::Idm), ..CreateOptions::default() };
    let mut env = env("highway", options);
    let info = last_info(&mut env);
    assert_eq!(figure(&info, "episode_success"), InfoValue::Bool(true), "{info:?}");
    let InfoValue::F64(ttc) = figure(&info, "episode_min_ttc") else { panic!() };
    assert!(ttc > 0.0, "{ttc}");
}

#[test]
fn standing_still_earns_nothing_however_cheap_it_is() {
    // `slower` down the target-speed ladder to 0 at the start of merge: the car stops
    // short of the lane end, and the paper's J, whose efficiency term measures speed
    // against the driver's own target, charges almost nothing (PPO found this). The
    // reward measures progress against the speed the scenario aims for, fixed per episode.
    let mut env = env("merge", CreateOptions::default());
    env.reset(Some(0), NO_OPTIONS).unwrap();
    let mut last = None;
    for _ in 0..100 {
        last = Some(env.step(&meta_of("ec_0", MetaAction::Slower)).unwrap()[0].clone());
    }
    let last = last.unwrap();
    let Some(&InfoValue::F64(speed)) = info(&last, "speed") else { panic!() };
    let Some(&InfoValue::F64(cost)) = info(&last, "cost") else { panic!() };
    assert!(speed < 0.1 && !last.terminated, "stopped and still in the episode: {speed} m/s");
    assert!(cost < 1.0, "J alone would pay it nearly the most: cost {cost}");
    assert!(last.reward < 0.01, "reward {}", last.reward);
}

#[test]
fn diagnostics_on_request_count_each_game_theoretic_cars_plans_and_qp_iterations() {
    let mut diagnosed = env("merge", CreateOptions { diagnostics: true, ..CreateOptions::default() });
    let count = |step: &AgentStep, key: &str| match info(step, key) {
        Some(InfoValue::I64(n)) => *n,
        other => panic!("{key}: {other:?} in {:?}", step.info),
    };
    diagnosed.reset(Some(0), NO_OPTIONS).unwrap();
    for k in 1..=5 {
        let step = diagnosed.step(&[]).unwrap()[0].clone();
        // merge has one gt car, AC; it plans once per control period, one per step here.
        assert_eq!(count(&step, "gt.ac.plans"), k);
        // AC keeps its lane: no bound of its QP is active, which is solved directly.
        assert_eq!((count(&step, "gt.ac.qp_iterations"), count(&step, "gt.ac.qp_iterations_total")), (0, 0));
        assert_eq!((count(&step, "gt.ac.fallbacks"), count(&step, "gt.ac.inexact")), (0, 0));
    }
    let mut plain = env("merge", CreateOptions::default());
    plain.reset(Some(0), NO_OPTIONS).unwrap();
    let step = plain.step(&[]).unwrap()[0].clone();
    assert!(!step.info.values.iter().any(|(k, _)| k.starts_with("gt.")), "only on request");
}

#[test]
fn the_observed_neighbours_are_those_a_full_sort_puts_first() {
    let mut env = env("highway", CreateOptions::default());
    env.reset(Some(2), NO_OPTIONS).unwrap();
    for _ in 0..3 {
        env.step(&[]).unwrap();
        let scene = env.world.as_mut().unwrap().scene();
        for car in scene.cars().iter().filter(|car| car.on_road()) {
            let mut all: Vec<(f64, VehicleId)> = scene
                .around(car.state.s, observation::SIGHT)
                .filter(|other| other.id != car.id)
                .map(|other| ((other.state.s - car.state.s).abs(), other.id))
                .collect();
            all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let mut expected: Vec<Option<VehicleId>> = all.iter().take(4).map(|&(_, id)| Some(id)).collect();
            expected.resize(4, None);
            assert_eq!(observation::nearest::<4>(scene, car.id, car.state.s).to_vec(), expected, "{:?}", car.id);
        }
    }
}

/// The (key, type) list of an info, and whether any number in it is NaN.
fn shape(info: &Info) -> (Vec<(String, arena_protocol::InfoKind)>, bool) {
    let nan = info.values.iter().any(|(_, v)| match v {
        InfoValue::F64(x) => x.is_nan(),
        InfoValue::F64s(xs) => xs.iter().any(|x| x.is_nan()),
        _ => false,
    });
    (info.values.iter().map(|(k, v)| (k.clone(), v.kind())).collect(), nan)
}

mod schema {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

        /// Every scenario, with every option that adds keys: the infos of reset and of
        /// every step (the last included) have the same keys, types and order, begin with
        /// `info::SCHEMA`, and hold no NaN.
        #[test]
        fn infos_keep_one_schema_from_reset_to_the_last_step(
            scenario in 0usize..arena_sim::BUILTIN_SCENARIOS.len(),
            option in 0usize..4,
            seed in 0u64..1000,
            actions in proptest::collection::vec(0u32..5, 40),
        ) {
            let name = arena_sim::BUILTIN_SCENARIOS[scenario].0;
            let continuous = option == 2;
            let options = CreateOptions {
                max_cycles: Some(40),
                action_type: Some(if continuous { ActionType::Continuous } else { ActionType::Meta }),
                expert: (option == 1 || option == 2).then_some(arena_protocol::Game::Nash),
                diagnostics: option == 3,
                ..CreateOptions::default()
            };
            let mut env = env(name, options);
            let starts = env.reset(Some(seed), NO_OPTIONS).unwrap();
            let (first, nan) = shape(&starts[0].info);
            prop_assert!(!nan, "{name}: NaN on reset");
            let schema: Vec<_> = arena_protocol::info::SCHEMA.iter().map(|(k, t)| (k.to_string(), *t)).collect();
            prop_assert_eq!(&first[..schema.len()], &schema[..], "{}: the schema first", name);
            let agents = env.specs().possible_agents;
            for start in &starts {
                prop_assert_eq!(&shape(&start.info).0, &first);
            }
            for &code in &actions {
                let action = if continuous { Action::Continuous([code as f32 / 4.0 - 0.5, 0.0]) } else { Action::Meta(code) };
                let chosen: Vec<_> = agents.iter().map(|a| (a.clone(), action.clone())).collect();
                let Ok(steps) = env.step(&chosen) else { break };
                for step in &steps {
                    let (keys, nan) = shape(&step.info);
                    prop_assert!(!nan, "{}: NaN in {:?}", name, step.info);
                    prop_assert_eq!(&keys, &first, "{}: another schema at a step", name);
                }
            }
        }
    }
}

#[test]
fn an_action_for_an_agent_that_has_finished_is_ignored_and_one_for_an_unknown_agent_refused() {
    // merge-duo: EC idles in the ending lane and runs off its end while AC drives on.
    let options = || CreateOptions { max_cycles: Some(300), ..CreateOptions::default() };
    let (mut always, mut live_only) = (env("merge-duo", options()), env("merge-duo", options()));
    always.reset(Some(0), NO_OPTIONS).unwrap();
    live_only.reset(Some(0), NO_OPTIONS).unwrap();
    let both = [("ec_0".to_string(), Action::Meta(1)), ("ac_0".to_string(), Action::Meta(1))];
    let mut after_ec_left = 0;
    while !live_only.live_agents().is_empty() {
        let live: Vec<_> = both.iter().filter(|(a, _)| live_only.live_agents().contains(a)).cloned().collect();
        after_ec_left += usize::from(live.len() == 1);
        assert_eq!(always.step(&both).unwrap(), live_only.step(&live).unwrap());
    }
    assert!(after_ec_left > 10, "AC drove on alone for {after_ec_left} steps");
    always.reset(Some(0), NO_OPTIONS).unwrap();
    assert_eq!(always.step(&meta("nobody", 1)).unwrap_err().code, ErrorCode::UnknownAgent);
}

/// The expert keys of a reply when the AV drives the learner: (`expert_accel`,
/// `expert_sigma`, `expert_action`).
fn labels(info: &Info) -> (f64, i64, InfoValue) {
    let InfoValue::F64(accel) = figure(info, "expert_accel") else { panic!("{info:?}") };
    let InfoValue::I64(sigma) = figure(info, "expert_sigma") else { panic!("{info:?}") };
    (accel, sigma, figure(info, "expert_action"))
}

#[test]
fn when_the_av_drives_the_expert_keys_are_what_it_does_next() {
    let policy = arena_protocol::BuiltinPolicy::Gt { style: None, game: arena_protocol::Game::Nash };
    for action_type in [ActionType::Continuous, ActionType::Meta] {
        let options = CreateOptions {
            policy: Some(policy),
            expert: Some(arena_protocol::Game::Nash),
            action_type: Some(action_type),
            ..CreateOptions::default()
        };
        let mut env = env("merge-random", options);
        let mut info = env.reset(Some(0), NO_OPTIONS).unwrap().remove(0).info;
        let (mut steps, mut lane_changes) = (0, 0);
        loop {
            let (accel, sigma, action) = labels(&info);
            let reply = env.step(&[]).unwrap().remove(0);
            // One control period a step in merge-random: the period just run applied the
            // command the reply before had labelled.
            let world = env.world().unwrap();
            let id = env.state.agents[0].vehicle;
            let arena_sim::Driver::Gt(driving) = &world.vehicle(id).driver else { panic!("the AV drives ec_0") };
            assert_eq!(driving.decision.accel.to_bits(), accel.to_bits(), "{action_type:?} step {steps}");
            assert_eq!(i64::from(driving.decision.lane_change.sigma()), sigma, "{action_type:?} step {steps}");
            if let (ActionType::Continuous, InfoValue::F64s(values)) = (action_type, &action) {
                let applied = world.vehicle(id).command.accel / action::CONTINUOUS_ACCEL_SCALE;
                assert_eq!(values[0].to_bits(), applied.clamp(-1.0, 1.0).to_bits(), "step {steps}");
            }
            lane_changes += i64::from(sigma != 0);
            steps += 1;
            if reply.terminated || reply.truncated {
                break;
            }
            info = reply.info;
        }
        assert!(steps > 20 && lane_changes > 0, "{action_type:?}: {steps} steps, {lane_changes} with a lane change");
    }
}

#[test]
fn an_expert_that_is_not_the_driving_av_is_refused() {
    let options = CreateOptions {
        policy: Some(arena_protocol::BuiltinPolicy::Gt { style: None, game: arena_protocol::Game::Nash }),
        expert: Some(arena_protocol::Game::Stackelberg),
        ..CreateOptions::default()
    };
    let (_, file, text) = arena_sim::BUILTIN_SCENARIOS[0];
    let Err(refused) = Env::from_text(file, text, &options, 1) else { panic!("two experts") };
    assert!(refused.message.contains("expert nash"), "{}", refused.message);
}

/// Two continuous learners on a straight two-lane road, `a_rear` behind `b_front` (world
/// indices 0 and 1: named vehicles are sorted by name), each holding its speed.
fn two_cars(front_lane: u32, front_s: f64) -> Env {
    let text = format!(
        r#"
name = "two-cars"
[sim]
step_dt = 0.1
max_cycles = 100
[road]
lanes = 2
speed_limits = [30.0, 30.0]
sections = [{{ length = 1000.0 }}]
[[vehicle]]
name = "a_rear"
lane = 0
s = 20.0
speed = 20.0
driver = {{ kind = "agent", action = "continuous" }}
[[vehicle]]
name = "b_front"
lane = {front_lane}
s = {front_s}
speed = 12.0
driver = {{ kind = "agent", action = "continuous" }}
"#
    );
    Env::from_text("two-cars.toml", &text, &CreateOptions::default(), 1).unwrap()
}

/// Steps `a_rear` straight on and `b_front` towards lane `front_to` (continuous actions
/// aim relative to the current lane) until both ended; each one's (end reason,
/// collision_with, at_fault) from its last info.
fn crash(env: &mut Env, front_to: i64) -> Vec<(String, EndReason, i64, i64)> {
    let mut last = Vec::new();
    let reset = env.reset(Some(0), NO_OPTIONS).unwrap();
    let front = reset.iter().find(|r| r.agent == "b_front").unwrap();
    let mut front_lane = front.info.number("lane").unwrap() as i64;
    for _ in 0..100 {
        let offset = (front_lane - front_to) as f32;
        let actions = [
            ("a_rear".to_string(), Action::Continuous([0.0, 0.0])),
            ("b_front".to_string(), Action::Continuous([0.0, offset])),
        ];
        for step in env.step(&actions).unwrap() {
            let integer = |key: &str| step.info.number(key).unwrap() as i64;
            if step.agent == "b_front" {
                front_lane = integer("lane");
            }
            if step.terminated || step.truncated {
                let end = step.info.end_reason().unwrap();
                last.push((step.agent.clone(), end, integer("collision_with"), integer("at_fault")));
            }
        }
        if env.live_agents().is_empty() {
            break;
        }
    }
    last.sort_by(|a, b| a.0.cmp(&b.0));
    last
}

#[test]
fn a_rear_end_collision_names_the_other_car_and_faults_the_car_behind() {
    let mut env = two_cars(0, 60.0);
    let ended = crash(&mut env, 0);
    let c = EndReason::Collision;
    assert_eq!(ended, vec![("a_rear".into(), c, 1, 1), ("b_front".into(), c, 0, 0)]);
}

#[test]
fn a_cut_in_collision_faults_the_car_that_changed_lanes() {
    // b_front steers one lane to the left (into a_rear's lane) 25 m ahead at 8 m/s less.
    let mut env = two_cars(1, 45.0);
    let ended = crash(&mut env, 0);
    let c = EndReason::Collision;
    assert_eq!(ended, vec![("a_rear".into(), c, 1, 0), ("b_front".into(), c, 0, 1)]);
}

#[test]
fn before_any_collision_nobody_collided_or_is_at_fault() {
    let mut env = two_cars(1, 200.0);
    let reset = env.reset(Some(0), NO_OPTIONS).unwrap();
    let step = env.step(&[]).unwrap();
    for info in reset.iter().map(|r| &r.info).chain(step.iter().map(|s| &s.info)) {
        assert_eq!((info.number("collision_with"), info.number("at_fault")), (Some(-1.0), Some(0.0)), "{info:?}");
    }
}

#[test]
fn commanded_jerk_is_the_change_of_acceleration_between_control_periods() {
    // a_rear alone in its lane commands +0.5 and 0 in turn (x 6 m/s^2, the continuous
    // scale) every 0.1 s step: each change is 3 m/s^2 over 0.1 s, 30 m/s^3.
    let mut env = two_cars(1, 200.0);
    env.reset(Some(0), NO_OPTIONS).unwrap();
    let mut last = None;
    for k in 0..100 {
        let accel = if k % 2 == 0 { 0.5 } else { 0.0 };
        let steps = env.step(&[("a_rear".to_string(), Action::Continuous([accel, 0.0]))]).unwrap();
        last = steps.into_iter().find(|s| s.agent == "a_rear").filter(|s| s.terminated || s.truncated).or(last);
    }
    let info = &last.expect("a_rear's episode ended").info;
    let near = |key: &str| (info.number(key).unwrap() - 30.0).abs() < 1e-9;
    assert!(near("episode_max_jerk") && near("episode_p95_jerk"), "{info:?}");
}

#[test]
fn recorded_road_geometry_follows_the_road_curves_and_ends() {
    // overtake: a straight, then arcs; every lane line follows them in world coordinates.
    let mut overtake = env("overtake", CreateOptions { record: true, ..CreateOptions::default() });
    overtake.reset(Some(0), NO_OPTIONS).unwrap();
    let start = overtake.world_start().expect("recording");
    let world = overtake.world().unwrap();
    let road = world.road();
    assert_eq!(start.road.lanes.len(), road.lane_count());
    for (i, lane) in start.road.lanes.iter().enumerate() {
        assert_eq!(lane.centre.len(), lane.left.len());
        assert_eq!(lane.centre.len(), lane.right.len());
        // Each point of the centre line is the road's own point at some s, on this lane.
        for (point, (left, right)) in lane.centre.iter().zip(lane.left.iter().zip(&lane.right)) {
            let (_, d) = road.to_frenet(point[0], point[1]);
            assert!((d - road.lane_center(arena_sim::LaneId(i as u32))).abs() < 1e-6, "lane {i}: d {d}");
            let width = (left[0] - right[0]).hypot(left[1] - right[1]);
            assert!((width - road.lane_width()).abs() < 1e-9, "lane {i}: width {width}");
        }
        // Consecutive chords turn: the road is curved, and it is drawn so.
        let headings: Vec<f64> =
            lane.centre.windows(2).map(|pair| (pair[1][1] - pair[0][1]).atan2(pair[1][0] - pair[0][0])).collect();
        let turn = headings.iter().copied().fold(f64::NEG_INFINITY, f64::max)
            - headings.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(turn > 0.2, "lane {i}: the polyline turns by {turn} rad only");
        assert!(lane.centre.len() > 20, "lane {i}: arcs sampled densely, {} points", lane.centre.len());
        let last = lane.centre.last().unwrap();
        let end = road.to_global(lane.end, road.lane_center(arena_sim::LaneId(i as u32)), 0.0);
        assert!((last[0] - end.x).abs() < 1e-9 && (last[1] - end.y).abs() < 1e-9, "lane {i} ends at its end");
    }
    // merge: the ending lane is marked so, and it stops where the scenario says.
    let mut merge = env("merge", CreateOptions { record: true, ..CreateOptions::default() });
    merge.reset(Some(0), NO_OPTIONS).unwrap();
    let start = merge.world_start().unwrap();
    let ending: Vec<_> = start.road.lanes.iter().filter(|lane| lane.ends_early).collect();
    assert_eq!(ending.len(), 1);
    assert!(ending[0].end < start.road.length);
    // Without recording there is no world to send.
    let mut plain = env("merge", CreateOptions::default());
    plain.reset(Some(0), NO_OPTIONS).unwrap();
    assert!(plain.world_start().is_none());
    assert!(plain.reset_world().is_none());
}

#[test]
fn with_explain_a_reset_names_the_vehicles_the_explanations_point_to() {
    let mut explained = env("merge-ac", CreateOptions { explain: true, ..CreateOptions::default() });
    explained.reset(Some(5), NO_OPTIONS).unwrap();
    // Not recording: no frames, but the reset's world, so a client can name the cars.
    assert!(explained.world_start().is_none());
    let start = explained.reset_world().expect("explain: the reset names the vehicles");
    let names: Vec<&str> = start.vehicles.iter().map(|v| v.name.as_str()).collect();
    assert_eq!(names, ["ac_0", "ec"]);
    explained.step(&meta_of("ac_0", MetaAction::Idle)).unwrap();
    let decisions = explained.take_explanations();
    assert!(!decisions.is_empty());
    for e in &decisions {
        assert_eq!(names[e.vehicle as usize], "ec");
        assert!(e.tables.iter().filter_map(|t| t.adjacent).all(|ac| names[ac as usize] == "ac_0"));
    }
}

#[test]
fn a_recording_that_would_not_fit_a_reply_is_refused() {
    // highway-gt's 51 vehicles at 11 frames a step fit; 10 000 vehicles at 11 do not.
    assert!(recording::check_fits(51, 11).is_ok());
    let refused = recording::check_fits(10_000, 11).unwrap_err();
    assert_eq!(refused.code, ErrorCode::InvalidScenario);
    assert!(refused.message.contains("10000 vehicles x 11 frames"), "{}", refused.message);
    assert!(refused.env_usable);
    // A reset that would record too much leaves the env as it was: a highway of 2 000
    // cars stepped 10 s at a time (101 frames a step) is refused, and the last episode
    // goes on.
    let mut env = env("highway", CreateOptions { record: true, ..CreateOptions::default() });
    env.reset(Some(1), NO_OPTIONS).unwrap();
    env.step(&[]).unwrap();
    let time = env.world().unwrap().time();
    let huge = overriding(&[("traffic.count", OptionValue::Int(2000)), ("sim.step_dt", OptionValue::Float(10.0))]);
    let error = env.reset(Some(2), &huge).unwrap_err();
    assert!(error.message.contains("record:"), "{}", error.message);
    assert_eq!(env.world().unwrap().time(), time);
    assert_eq!(env.step(&[]).unwrap().len(), 1);
}

// --- The AV explained (issue 27, point 3) ---

/// A plain search of the tables an explanation shows, written apart from the games: the
/// equilibrium of `t` (row, column, exact) for `game` with follower tolerance `tolerance`;
/// `answers`: the car is the follower, whose Stackelberg table is one row to reply to.
/// Skipped cells (NaN) and pruned rows are never candidates; a cell the search must read
/// that is NaN fails the test.
fn searched(t: &arena_protocol::GameTable, game: Game, tolerance: f64, answers: bool) -> (usize, usize, bool) {
    let (rows, cols) = (t.ec_actions.len(), t.ac_actions.len());
    assert_eq!((t.ec_costs.len(), t.ac_costs.len(), t.pruned.len()), (rows * cols, rows * cols, rows));
    let ec = |r: usize, c: usize| {
        let cost = t.ec_costs[r * cols + c];
        assert!(!cost.is_nan(), "EC's cost at ({r}, {c}) is read by the equilibrium but not shown");
        cost
    };
    let ac = |r: usize, c: usize| t.ac_costs[r * cols + c];
    let reply = |r: usize| {
        let mut best = None;
        for c in 0..cols {
            if !ac(r, c).is_nan() && best.is_none_or(|b| ac(r, c) < ac(r, b)) {
                best = Some(c);
            }
        }
        best.expect("a row in play shows at least one AC cost")
    };
    let in_play: Vec<usize> = (0..rows).filter(|&r| !t.pruned[r]).collect();
    if answers && game == Game::Stackelberg {
        assert_eq!(rows, 1, "a Stackelberg follower replies to one announced action");
        return (0, reply(0), true);
    }
    match game {
        Game::Stackelberg => {
            let mut best: Option<(f64, usize, usize)> = None;
            for &r in &in_play {
                let floor = ac(r, reply(r));
                let bound = floor + tolerance * floor.abs();
                let mut worst: Option<(f64, usize)> = None;
                for c in (0..cols).filter(|&c| ac(r, c) <= bound) {
                    if worst.is_none_or(|(w, _)| ec(r, c) > w) {
                        worst = Some((ec(r, c), c));
                    }
                }
                let (w, c) = worst.expect("the best reply is in the follower set");
                if best.is_none_or(|(b, ..)| w < b) {
                    best = Some((w, r, c));
                }
            }
            let (_, r, c) = best.expect("a row in play");
            (r, c, true)
        }
        Game::Nash => {
            let mut best: Option<(f64, usize, usize)> = None;
            for &r in &in_play {
                let c = reply(r);
                let column_min = in_play.iter().map(|&q| ec(q, c)).fold(f64::INFINITY, f64::min);
                if ec(r, c) <= column_min && best.is_none_or(|(b, ..)| ec(r, c) < b) {
                    best = Some((ec(r, c), r, c));
                }
            }
            if let Some((_, r, c)) = best {
                return (r, c, true);
            }
            // No pure equilibrium: the current lane decision's best row against replies.
            let committed = t.ec_actions.iter().all(|&(_, sigma)| sigma != 0);
            let mut fallback: Option<(f64, usize, usize)> = None;
            for &r in in_play.iter().filter(|&&r| committed || t.ec_actions[r].1 == 0) {
                let c = reply(r);
                if fallback.is_none_or(|(b, ..)| ec(r, c) < b) {
                    fallback = Some((ec(r, c), r, c));
                }
            }
            let (_, r, c) = fallback.expect("a row keeps the current decision");
            (r, c, false)
        }
    }
}

/// What `explained_episode` saw.
#[derive(Default)]
struct ExplainedEpisode {
    steps: Vec<Vec<u8>>,
    decisions: usize,
    lane_changes: usize,
    skipped_cells: usize,
    pruned_rows: usize,
    /// The largest encoded explanation of one decision, and of one step's (bytes).
    largest: usize,
    largest_step: usize,
}

/// Steps `name` (seed 7) with `actions` for every step, explain on or off; checks every
/// explanation's tables against `searched` and the action the car took.
fn explained_episode(name: &str, explain: bool, steps: usize, action: &[(String, Action)]) -> ExplainedEpisode {
    let mut env = env(name, CreateOptions { explain, ..CreateOptions::default() });
    let mut seen = ExplainedEpisode::default();
    let reset = env.reset(Some(7), NO_OPTIONS).unwrap();
    seen.steps.push(arena_protocol::encode(&reset));
    for _ in 0..steps {
        if env.live_agents().is_empty() {
            break;
        }
        let stepped = env.step(action).unwrap();
        seen.steps.push(arena_protocol::encode(&stepped));
        let explained = env.take_explanations();
        seen.largest_step = seen.largest_step.max(arena_protocol::encode(&explained).len());
        assert_eq!(
            explained.is_empty(),
            !explain || env.world().unwrap().vehicles().iter().all(|v| !matches!(v.driver, arena_sim::Driver::Gt(_)))
        );
        for e in explained {
            check_explained(&env, &e);
            seen.largest = seen.largest.max(arena_protocol::encode(&e).len());
            seen.decisions += 1;
            seen.lane_changes += usize::from(e.sigma != 0);
            for t in &e.tables {
                seen.skipped_cells += t.ec_costs.iter().chain(&t.ac_costs).filter(|c| c.is_nan()).count();
                seen.pruned_rows += t.pruned.iter().filter(|&&p| p).count();
            }
        }
    }
    seen
}

/// The issue's test for one decision: each table's equilibrium is what a plain search of
/// the shown cells finds, the chosen table is the cheapest for EC, and the chosen cell's
/// action is the one the car took.
fn check_explained(env: &Env, e: &arena_protocol::DecisionExplained) {
    let world = env.world().unwrap();
    let params = world.gt_params(VehicleId(e.vehicle));
    let tolerance = params.decision.game.follower_tolerance;
    let answers = e.ec != e.vehicle;
    let game = match (e.role, answers) {
        // A follower alone plays Nash in its own lane.
        (arena_protocol::GtRole::Follower, false) => Game::Nash,
        _ => super::game(e.game),
    };
    let mut cheapest: Option<(f64, usize)> = None;
    for (at, t) in e.tables.iter().enumerate() {
        let (row, col, exact) = searched(t, game, tolerance, answers);
        assert_eq!(
            (row, col, exact),
            (t.row as usize, t.col as usize, t.exact),
            "t={} car {}: side {}'s equilibrium ({} x {} table)",
            e.time,
            e.vehicle,
            t.side,
            t.ec_actions.len(),
            t.ac_actions.len()
        );
        let cost = t.ec_costs[row * t.ac_actions.len() + col];
        if !answers && cheapest.is_none_or(|(c, _)| cost < c) {
            cheapest = Some((cost, at));
        }
    }
    if !answers {
        assert_eq!(cheapest.map(|(_, at)| at as u32), e.chosen, "t={} car {}: the side chosen", e.time, e.vehicle);
    }
    let Some(t) = e.chosen.map(|at| &e.tables[at as usize]) else { return };
    let (row, col) = (t.row as usize, t.col as usize);
    let (accel, sigma) = if answers { (t.ac_actions[col], 0) } else { t.ec_actions[row] };
    if !e.fallback {
        assert_eq!((accel, sigma), (e.games_accel, e.sigma), "t={} car {}: the action taken", e.time, e.vehicle);
    }
    if !e.safety && !e.fallback {
        assert_eq!(e.accel, e.games_accel, "t={} car {}: commanded without an override", e.time, e.vehicle);
    }
    assert_eq!(e.planned.len(), params.decision.prediction.samples, "one planned point per sample");
}

#[test]
fn explained_tables_reproduce_the_decision_the_av_took_on_merge() {
    // merge-ac: a Stackelberg leader merges from the ending lane beside the learner.
    let keep = meta_of("ac_0", MetaAction::Idle);
    let on = explained_episode("merge-ac", true, 120, &keep);
    let off = explained_episode("merge-ac", false, 120, &keep);
    assert!(on.steps == off.steps, "an episode with explain on differs from the same without");
    assert!(on.decisions >= 100, "{} decisions explained", on.decisions);
    assert!(on.lane_changes > 0, "no explained lane change: the merge was not explained");
    assert!(on.skipped_cells > 0, "no skipped cell shown: the fast search's tables were not the ones shown");
    // merge: the learner merges, a Stackelberg follower answers it.
    let merge_left = meta_of("ec_0", MetaAction::LaneLeft);
    let on = explained_episode("merge", true, 60, &merge_left);
    let off = explained_episode("merge", false, 60, &merge_left);
    assert!(on.steps == off.steps, "merge: an episode with explain on differs from the same without");
    assert!(on.decisions >= 30, "{} follower decisions explained", on.decisions);
}

#[test]
fn explained_highway_gt_is_the_same_episode_and_every_decision_checks() {
    let on = explained_episode("highway-gt", true, 30, &[]);
    let off = explained_episode("highway-gt", false, 30, &[]);
    assert!(on.steps == off.steps, "highway-gt: an episode with explain on differs from the same without");
    assert!(on.decisions >= 8 * 30, "{} decisions explained", on.decisions);
    assert!(on.pruned_rows > 0 || on.skipped_cells > 0, "no skipped cell in {} decisions", on.decisions);
    // The bound `explain::check_fits` refuses by is one: no decision encodes to more.
    let bound = explain::bytes_per_decision(29, 6);
    assert!(on.largest <= bound, "a decision of {} bytes, above the bound {bound}", on.largest);
    // highway-gt, 10 periods of 8 cars a step: 56 kB a decision, 2.7 MB a step at most
    // (docs/protocol.md); under the 6 MiB a reset is refused above.
    assert!(on.largest_step < 6 << 20, "a step of {} bytes", on.largest_step);
}

#[test]
fn explanations_that_could_not_fit_a_reply_are_refused_at_reset() {
    let options = CreateOptions { explain: true, ..CreateOptions::default() };
    let mut env = env("highway-gt", options);
    let fine = ResetOptions::default();
    assert!(env.reset(Some(1), &fine).is_ok());
    // Twenty control periods a step: eight cars' twenty decisions of up to 63 kB each.
    let long_steps = overriding(&[("sim.step_dt", OptionValue::Float(2.0))]);
    let refused = env.reset(Some(1), &long_steps);
    let error = refused.expect_err("twenty periods of eight cars' tables fit no reply");
    assert_eq!(error.code, ErrorCode::InvalidScenario);
    assert!(error.message.contains("explain:"), "{}", error.message);
}

// --- Snapshots (issue 27, point 4) ---

/// Steps `env` `n` times with a fixed cycle of meta actions for every live agent,
/// returning each step's result as bytes (errors included), to compare bit for bit.
fn run(env: &mut Env, n: usize, offset: usize) -> Vec<Vec<u8>> {
    use MetaAction::{Faster, Idle, LaneLeft, LaneRight, Slower};
    let cycle = [Idle, Faster, Idle, Slower, Idle, Idle, LaneLeft, Idle, Idle, Idle, Slower, Idle, LaneRight, Idle];
    (0..n)
        .map(|k| {
            let action = cycle[(k + offset) % cycle.len()];
            let actions: Vec<(String, Action)> =
                env.live_agents().into_iter().map(|agent| (agent, Action::Meta(action.code()))).collect();
            match env.step(&actions) {
                Ok(steps) => arena_protocol::encode(&steps),
                Err(e) => e.message.into_bytes(),
            }
        })
        .collect()
}

#[test]
fn a_snapshot_restored_into_a_fresh_env_continues_bit_for_bit() {
    for name in ["highway-gt", "merge-random", "merge"] {
        let expert = Some(arena_protocol::Game::Stackelberg);
        let options = CreateOptions { expert, max_cycles: Some(150), ..CreateOptions::default() };
        let mut original = env(name, options.clone());
        original.reset(Some(11), NO_OPTIONS).unwrap();
        run(&mut original, 50, 0);
        let snapshot = original.snapshot().unwrap();
        let a = run(&mut original, 50, 50);
        let stepped = a.iter().filter(|step| step.len() > 200).count();
        eprintln!("{name}: {stepped} steps after the snapshot, {} bytes", snapshot.len());
        assert!(stepped > 0, "{name}: the agents stepped after the snapshot");

        // Another env of the scenario (another entropy, other seeds), reset otherwise.
        let (_, file, text) = arena_sim::BUILTIN_SCENARIOS.into_iter().find(|(n, ..)| *n == name).unwrap();
        let mut fresh = Env::from_text(file, text, &options, 99).unwrap();
        fresh.reset(Some(5), NO_OPTIONS).unwrap();
        run(&mut fresh, 3, 0);
        let starts = fresh.restore(&snapshot).unwrap();
        assert_eq!(starts.iter().map(|s| s.agent.clone()).collect::<Vec<_>>(), fresh.live_agents());
        assert!(fresh.snapshot().unwrap() == snapshot, "{name}: restoring changes nothing of the state");
        let b = run(&mut fresh, 50, 50);
        assert!(a == b, "{name}: the restored env stepped otherwise");

        // Back in the original env too, after it ran on: a branch point.
        original.restore(&snapshot).unwrap();
        assert!(run(&mut original, 50, 50) == a, "{name}: restored into its own env");
        // A reset without a seed continues the seed stream the snapshot holds.
        fresh.restore(&snapshot).unwrap();
        original.restore(&snapshot).unwrap();
        let (x, y) = (fresh.reset(None, NO_OPTIONS).unwrap(), original.reset(None, NO_OPTIONS).unwrap());
        assert!(arena_protocol::encode(&x) == arena_protocol::encode(&y), "{name}: seed stream");
    }
}

#[test]
fn a_restored_env_explains_and_clocks_as_the_original_did() {
    let policy = Some(BuiltinPolicy::Gt { style: None, game: arena_protocol::Game::Stackelberg });
    let options = CreateOptions { explain: true, policy, ..CreateOptions::default() };
    let mut original = env("merge-ac", options.clone());
    original.reset(Some(5), NO_OPTIONS).unwrap();
    for _ in 0..5 {
        original.step(&[]).unwrap();
    }
    let snapshot = original.snapshot().unwrap();
    original.take_explanations();
    let mut fresh = env("merge-ac", options);
    fresh.restore(&snapshot).unwrap();
    for _ in 0..3 {
        original.step(&[]).unwrap();
        fresh.step(&[]).unwrap();
        let (a, b) = (original.take_explanations(), fresh.take_explanations());
        assert!(!a.is_empty(), "merge-ac's AVs explain every step");
        // Bytes, not ==: skipped cells are NaN.
        assert!(
            arena_protocol::encode(&a) == arena_protocol::encode(&b),
            "the restored env explains the same decisions"
        );
    }
    let clocked = |env: &Env| env.statistics().decision_micros.iter().map(|(_, kept)| kept.len()).sum::<usize>();
    assert_eq!(clocked(&fresh), 3, "the restored env's policy is clocked from the restore on");
}

#[test]
fn a_snapshot_of_another_scenario_options_or_version_or_damaged_is_refused_and_the_env_goes_on() {
    let mut merge = env("merge", CreateOptions::default());
    merge.reset(Some(2), NO_OPTIONS).unwrap();
    run(&mut merge, 5, 0);
    let snapshot = merge.snapshot().unwrap();
    let mut target = env("merge", CreateOptions::default());
    target.reset(Some(3), NO_OPTIONS).unwrap();
    let before = target.snapshot().unwrap();
    let refused = |target: &mut Env, bytes: &[u8], needles: &[&str]| {
        let error = target.restore(bytes).unwrap_err();
        assert_eq!(error.code, ErrorCode::InvalidSnapshot, "{error}");
        assert!(error.env_usable);
        for needle in needles {
            assert!(error.message.contains(needle), "'{needle}' not in: {}", error.message);
        }
    };
    // Another scenario.
    let mut highway = env("highway-gt", CreateOptions::default());
    highway.reset(Some(1), NO_OPTIONS).unwrap();
    refused(&mut highway, &snapshot, &["scenario 'merge'", "scenario 'highway-gt'", "resolved content"]);
    // The same scenario with an override: another resolved content.
    let overridden = CreateOptions {
        overrides: vec![("vehicle.ac.speed".into(), OptionValue::Float(19.0))],
        ..CreateOptions::default()
    };
    let mut other = env("merge", overridden);
    other.reset(Some(1), NO_OPTIONS).unwrap();
    refused(&mut other, &snapshot, &["scenario 'merge'", "resolved content"]);
    // Other options.
    let mut longer = env("merge", CreateOptions { max_cycles: Some(7), ..CreateOptions::default() });
    longer.reset(Some(1), NO_OPTIONS).unwrap();
    refused(&mut longer, &snapshot, &["max_cycles 7", "same options"]);
    // Another protocol version, in its header.
    let mut versioned = snapshot.clone();
    versioned[8] = versioned[8].wrapping_add(1);
    let (theirs, ours) = (arena_protocol::PROTOCOL_VERSION + 1, arena_protocol::PROTOCOL_VERSION);
    refused(&mut target, &versioned, &[&format!("protocol version {theirs}"), &format!("speaks version {ours}")]);
    // Not a snapshot, truncated, corrupted.
    refused(&mut target, b"hello", &["not an env snapshot"]);
    for cut in [10, 11, 41, 42, snapshot.len() / 2, snapshot.len() - 1] {
        refused(&mut target, &snapshot[..cut], &["truncated"]);
    }
    for at in [12, snapshot.len() / 2, snapshot.len() - 40, snapshot.len() - 1] {
        let mut corrupted = snapshot.clone();
        corrupted[at] ^= 0x10;
        refused(&mut target, &corrupted, &["corrupted"]);
    }
    // The refused restores left the env as it was, and it steps on.
    assert!(target.snapshot().unwrap() == before, "a refused restore changed the env");
    assert!(target.step(&[]).is_ok());
    // Before any reset: nothing to snapshot.
    assert_eq!(env("merge", CreateOptions::default()).snapshot().unwrap_err().code, ErrorCode::NotReset);
}

/// The own row's s column of `observation` (the nearness of the end of the agent's lane).
fn lane_end_nearness(observation: &Observation) -> f32 {
    let Observation::Tensor(arena_protocol::Tensor { data: arena_protocol::TensorData::F32(data), .. }) = observation
    else {
        panic!("{observation:?}")
    };
    data[1]
}

#[test]
fn the_own_row_shows_how_near_the_end_of_the_agents_lane_is() {
    // merge: EC starts 200 m before its lane's end (252 m), out of sight (100 m); held in
    // its lane at its speed, the nearness rises with every step until the lane ends.
    let mut merging = env("merge", CreateOptions::default());
    let reset = merging.reset(Some(0), NO_OPTIONS).unwrap();
    assert_eq!(lane_end_nearness(&reset[0].observation), 0.0);
    let mut seen = Vec::new();
    loop {
        let step = merging.step(&meta_of("ec_0", MetaAction::Idle)).unwrap().remove(0);
        if step.terminated || step.truncated {
            assert_eq!(figure(&step.info, arena_protocol::info::END_REASON), InfoValue::I64(3), "lane_end");
            break;
        }
        seen.push(lane_end_nearness(&step.observation));
    }
    assert!(seen.windows(2).all(|pair| pair[1] >= pair[0]), "{seen:?}");
    assert!(seen[0] == 0.0 && *seen.last().unwrap() > 0.9, "{seen:?}");
    // merge-ac: the learner holds the through lane, which runs on past sight: always 0.
    let mut through = env("merge-ac", CreateOptions::default());
    through.reset(Some(0), NO_OPTIONS).unwrap();
    for _ in 0..100 {
        let step = through.step(&meta_of("ac_0", MetaAction::Idle)).unwrap().remove(0);
        assert_eq!(lane_end_nearness(&step.observation), 0.0);
    }
}

#[test]
fn info_keys_keep_only_the_named_keys_and_unknown_ones_are_refused_by_name() {
    let named = ["episode_return", "end_reason"].map(String::from).to_vec();
    let mut env = env("merge", CreateOptions { info_keys: Some(named), ..CreateOptions::default() });
    let start = env.reset(Some(0), NO_OPTIONS).unwrap();
    let keys = |info: &Info| info.values.iter().map(|(k, _)| k.clone()).collect::<Vec<_>>();
    // In the infos' own order (end_reason comes before the episode's figures), on reset
    // and on every step.
    assert_eq!(keys(&start[0].info), ["end_reason", "episode_return"]);
    let step = env.step(&meta("ec_0", 1)).unwrap();
    assert_eq!(keys(&step[0].info), ["end_reason", "episode_return"]);
    let refuse = |keys: &[&str], expert| {
        let options = CreateOptions {
            info_keys: Some(keys.iter().map(|k| k.to_string()).collect()),
            expert,
            ..CreateOptions::default()
        };
        Env::new(env.scenario.clone(), &options, 0).err()
    };
    let unknown = refuse(&["speed", "sped"], None).expect("an unknown key is refused");
    assert_eq!(unknown.code, ErrorCode::InvalidOption);
    assert!(unknown.message.contains("'sped'") && unknown.message.contains("speed, lane"), "{unknown}");
    let expert = refuse(&["expert_action"], None).expect("an expert key without expert is refused");
    assert!(expert.message.contains("`expert` option"), "{expert}");
    assert!(refuse(&["expert_action"], Some(arena_protocol::Game::Stackelberg)).is_none());
    assert!(refuse(&["gt.ac.plans"], None).expect("a count without diagnostics").message.contains("diagnostics"));
}
