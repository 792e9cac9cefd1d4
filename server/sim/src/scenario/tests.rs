use std::path::Path;

use super::*;
use crate::dynamics::Style;
use crate::gt::{Game, GtParams};
use crate::road::LaneId;
use crate::scene::Role;

fn parse(text: &str) -> Result<Scenario, ScenarioError> {
    Scenario::parse("test.toml", text, &[])
}

const GOOD: &str = r#"
name = "t"
[road]
lanes = 2
speed_limits = [30.0, 30.0]
sections = [{ length = 500.0 }]
lane_ends = [{ lane = 1, s = 200.0 }]
[[vehicle]]
name = "a"
lane = 0
s = 10.0
speed = 20.0
driver = { kind = "agent" }
[[vehicle]]
name = "b"
lane = 1
s = 30.0
speed = 20.0
driver = { kind = "idm", style = "aggressive" }
"#;

fn with(replace: &str, by: &str) -> String {
    assert!(GOOD.contains(replace), "test setup: {replace}");
    GOOD.replacen(replace, by, 1)
}

#[test]
fn every_shipped_scenario_loads_and_builds() {
    for (name, file, _) in BUILTIN_SCENARIOS {
        let scenario = builtin_scenario(name).unwrap().unwrap_or_else(|e| panic!("{file}: {e}"));
        assert_eq!(scenario.name, name);
        let learners = if name == "merge-duo" { 2 } else { 1 };
        assert_eq!(scenario.agents().count(), learners, "{file} has {learners} learner(s)");
        let world = scenario.build(7);
        assert!(world.vehicles().len() >= 2);
    }
    let highway = builtin_scenario("highway").unwrap().unwrap();
    assert_eq!(highway.build(1).vehicles().len(), 51);
    assert_eq!((highway.step_dt, highway.max_cycles, highway.road.lane_count()), (1.0, 40, 4));
}

#[test]
fn overtake_places_the_papers_cars_in_their_lanes() {
    let overtake = builtin_scenario("overtake").unwrap().unwrap();
    let lanes: Vec<u32> = overtake.vehicles.iter().map(|v| v.lane.0).collect();
    assert_eq!(lanes, [1, 1, 0, 2]); // ec, lc middle; ac1 left; ac2 right
    for spec in &overtake.vehicles {
        let offset = spec.d - overtake.road.lane_center(spec.lane);
        assert!(offset.abs() < 0.1, "{} is {offset} m off its lane centre", spec.name);
    }
}

#[test]
fn a_good_file_loads_and_overrides_apply() {
    let scenario = parse(GOOD).unwrap();
    assert_eq!(scenario.vehicles[1].style, Style::Aggressive);
    let overrides = [
        ("vehicle.b.speed".to_string(), toml::Value::Float(12.0)),
        ("sim.max_cycles".to_string(), toml::Value::Integer(9)),
    ];
    let changed = Scenario::parse("test.toml", GOOD, &overrides).unwrap();
    assert_eq!((changed.vehicles[1].speed, changed.max_cycles), (12.0, 9));
}

fn error(text: &str) -> String {
    let err = parse(text).expect_err("should be refused");
    assert_eq!(err.file, "test.toml");
    err.to_string()
}

#[test]
fn unknown_key_is_named() {
    let message = error(&with(
        "speed = 20.0\ndriver = { kind = \"agent\" }",
        "speed = 20.0\nsped = 3.0\ndriver = { kind = \"agent\" }",
    ));
    assert!(message.contains("invalid scenario 'test.toml'") && message.contains("sped"), "{message}");
}

#[test]
fn missing_field_is_named() {
    let message = error(&with("speed = 20.0\ndriver = { kind = \"agent\" }", "driver = { kind = \"agent\" }"));
    assert!(message.contains("missing field") && message.contains("speed"), "{message}");
}

#[test]
fn unknown_lane_names_the_vehicle_and_the_lanes() {
    let message = error(&with("lane = 0", "lane = 3"));
    assert!(message.contains("vehicle 'a' is on lane 3, but the road has lanes 0..=1"), "{message}");
}

#[test]
fn vehicle_past_its_lane_end_is_off_road() {
    let message = error(&with("s = 30.0", "s = 230.0"));
    assert!(message.contains("vehicle 'b' starts off the road") && message.contains("outside lane 1"), "{message}");
}

#[test]
fn global_position_off_the_road_is_refused() {
    let message = error(&with("lane = 0\ns = 10.0", "x = 10.0\ny = 9.0"));
    assert!(message.contains("vehicle 'a' starts off the road"), "{message}");
}

#[test]
fn overlapping_vehicles_are_named() {
    let message = error(&with("lane = 1\ns = 30.0", "lane = 0\ns = 13.0"));
    assert!(message.contains("vehicles 'a' and 'b' overlap"), "{message}");
}

#[test]
fn duplicate_names_and_bad_values_are_refused() {
    assert!(error(&with("name = \"b\"", "name = \"a\"")).contains("two vehicles are named 'a'"));
    assert!(
        error(&with("speed_limits = [30.0, 30.0]", "speed_limits = [30.0]"))
            .contains("`road.speed_limits` has 1 entries")
    );
    assert!(
        error(&with("lane = 1, s = 200.0", "lane = 5, s = 200.0"))
            .contains("`road.lane_ends[0].lane` 5 does not exist")
    );
    assert!(
        error(&with("{ length = 500.0 }", "{ length = -5.0 }")).contains("`road.sections[0].length` must be positive")
    );
    assert!(error(&with("speed = 20.0", "speed = -1.0")).contains("vehicle 'a'.speed"));
    assert!(error(&with("kind = \"agent\"", "kind = \"robot\"")).contains("robot"));
    assert!(error("name = ").contains("invalid scenario 'test.toml'"));
}

#[test]
fn every_shipped_physics_step_keeps_lane_changes_within_bounds_and_rk4_stable() {
    // docs/parameters.md, "Physics step": the dynamics tests hold lane changes to these
    // bounds at 10 ms; highway.toml runs at 1/30 s, highway-gt.toml at 20 ms.
    use crate::dynamics::{LANE_CHANGE_BOUNDS, RK4_CHECK_SPEEDS, Style, rk4_growth};
    let bounds = LANE_CHANGE_BOUNDS;
    for (name, ..) in BUILTIN_SCENARIOS {
        let dt = builtin_scenario(name).unwrap().unwrap().world.physics_dt;
        for style in Style::ALL {
            for speed in bounds.speeds {
                for left in [true, false] {
                    let response = bounds.response(style, speed, left, dt);
                    assert!(
                        bounds.hold(&response),
                        "{name} (dt {dt}): {style:?} at {speed} m/s, left {left}: {response:?}"
                    );
                }
            }
            for speed in RK4_CHECK_SPEEDS {
                let growth = rk4_growth(style, speed, dt);
                assert!(
                    growth <= 1.0 + 1e-6,
                    "{name} (dt {dt}): RK4 grows {style:?}'s modes at {speed} m/s by {growth}"
                );
            }
        }
    }
}

#[test]
fn a_physics_step_that_does_not_divide_the_periods_is_refused() {
    let sim =
        |physics: f64, step: f64| format!("name = \"t\"\n[sim]\nphysics_dt = {physics}\nstep_dt = {step}\n[road]");
    let file = |sim: String| GOOD.replacen("name = \"t\"\n[road]", &sim, 1);
    // control_dt is 0.1 by default: 3 steps of 1/30 s and 4 of 25 ms fit it, 0.04 does not.
    assert!(parse(&file(sim(1.0 / 30.0, 1.0))).is_ok());
    assert!(parse(&file(sim(0.025, 1.0))).is_ok());
    assert!(error(&file(sim(0.04, 1.0))).contains("`sim.control_dt` must be a whole number of physics steps"));
    assert!(error(&file(sim(0.025, 0.11))).contains("`sim.step_dt` must be a whole number of physics steps"));
}

#[test]
fn bad_overrides_are_refused_like_bad_files() {
    let refuse = |key: &str, value: toml::Value| {
        Scenario::parse("test.toml", GOOD, &[(key.to_string(), value)]).unwrap_err().to_string()
    };
    assert!(refuse("vehicle.zed.speed", toml::Value::Float(1.0)).contains("there is no vehicle named 'zed'"));
    assert!(
        refuse("road.lanes", toml::Value::Integer(7))
            .contains("`road.speed_limits` has 2 entries but the road has 7 lanes")
    );
    assert!(refuse("sim.bogus", toml::Value::Integer(1)).contains("bogus"));
    assert!(refuse("vehicle.a.lane", toml::Value::Integer(9)).contains("vehicle 'a' is on lane 9"));
    // A misspelt field is refused naming the override that brought it, as the user wrote it.
    let misspelt = refuse("vehicle.a.sped", toml::Value::Float(20.0));
    assert!(
        misspelt.starts_with("invalid scenario 'test.toml': override `vehicle.a.sped`: unknown field `sped`"),
        "{misspelt}"
    );
    let wrong_type = refuse("vehicle.a.speed", toml::Value::String("fast".into()));
    assert!(wrong_type.contains("vehicle.a.speed"), "{wrong_type}");
}

/// A value of arrays nested `n` deep around an integer.
fn nested_arrays(n: usize) -> toml::Value {
    (0..n).fold(toml::Value::Integer(1), |inner, _| toml::Value::Array(vec![inner]))
}

fn kind_of(text: &str, overrides: &[(String, toml::Value)]) -> ScenarioErrorKind {
    Scenario::parse("test.toml", text, overrides).expect_err("refused").kind
}

#[test]
fn nesting_past_max_depth_is_refused_in_text_keys_and_values_and_not_below() {
    // The file itself is depth 1, so n arrays inside it nest 1 + n deep.
    let deep_text = |n: usize| format!("deep = {}1{}\n{GOOD}", "[".repeat(n), "]".repeat(n));
    assert!(
        matches!(kind_of(&deep_text(MAX_SCENARIO_DEPTH - 1), &[]), ScenarioErrorKind::Syntax(e) if e.contains("deep"))
    );
    assert_eq!(
        kind_of(&deep_text(MAX_SCENARIO_DEPTH), &[]),
        ScenarioErrorKind::TooDeep { depth: MAX_SCENARIO_DEPTH + 1 }
    );
    // Past toml's own recursion limit (80) the parser refuses it; no stack is at risk.
    assert!(matches!(kind_of(&deep_text(5000), &[]), ScenarioErrorKind::Syntax(_)));

    let key = |parts: usize| vec!["x"; parts].join(".");
    let one = |key: String, value: toml::Value| vec![(key, value)];
    let below = kind_of(GOOD, &one(key(MAX_SCENARIO_DEPTH), toml::Value::Integer(1)));
    let unknown = |kind: &ScenarioErrorKind| match kind {
        ScenarioErrorKind::BadOverride { key: named, message } => {
            *named == key(MAX_SCENARIO_DEPTH) && message.contains("unknown field `x`")
        }
        _ => false,
    };
    assert!(unknown(&below), "refused for its unknown field, naming the override: {below:?}");
    let above = kind_of(GOOD, &one(key(MAX_SCENARIO_DEPTH + 1), toml::Value::Integer(1)));
    assert!(matches!(above, ScenarioErrorKind::BadOverride { ref message, .. } if message.contains("17 parts")));
    // The key that overflowed the server's stack: refused before any table is made.
    let crash = kind_of(GOOD, &one(format!("{}a", "a.".repeat(15_000)), toml::Value::Integer(1)));
    assert!(matches!(crash, ScenarioErrorKind::BadOverride { ref message, .. } if message.contains("15001 parts")));

    // A value nests from its key's depth: `sim.x` is depth 2, so its arrays start at 3.
    let below = kind_of(GOOD, &one("sim.x".into(), nested_arrays(MAX_SCENARIO_DEPTH - 2)));
    assert!(matches!(below, ScenarioErrorKind::BadOverride { ref key, .. } if key == "sim.x"), "{below:?}");
    let above = kind_of(GOOD, &one("sim.x".into(), nested_arrays(MAX_SCENARIO_DEPTH - 1)));
    assert_eq!(above, ScenarioErrorKind::TooDeep { depth: MAX_SCENARIO_DEPTH + 1 });
}

#[test]
fn missing_files_are_reported_by_name() {
    let err = Scenario::load(Path::new("/nonexistent/nothing.toml")).unwrap_err();
    assert_eq!(err.file, "nothing.toml");
    assert!(matches!(err.kind, ScenarioErrorKind::Io(_)));
}

#[test]
fn a_gt_driver_loads_with_its_game_and_role() {
    let text = with(
        "driver = { kind = \"agent\" }",
        "driver = { kind = \"gt\", style = \"aggressive\", game = \"stackelberg\" }",
    );
    let scenario = parse(&text).unwrap();
    let expected = DriverSpec::Gt { game: Game::Stackelberg, role: Role::Leader, params: GtParams::default() };
    assert_eq!((scenario.vehicles[0].driver, scenario.vehicles[0].style), (expected, Style::Aggressive));
    let text =
        with("driver = { kind = \"agent\" }", "driver = { kind = \"gt\", game = \"nash\", role = \"follower\" }");
    let world = parse(&text).unwrap().build(0);
    match world.gt_setup(crate::VehicleId(0)) {
        Some(setup) => assert_eq!((setup.game, setup.role), (Game::Nash, Role::Follower)),
        None => panic!("expected a gt driver, got {:?}", world.vehicles()[0].driver),
    }
}

#[test]
fn a_bad_gt_driver_is_refused_with_the_reason() {
    let bad_game = error(&with("driver = { kind = \"agent\" }", "driver = { kind = \"gt\", game = \"pareto\" }"));
    assert!(bad_game.contains("pareto") && bad_game.contains("nash") && bad_game.contains("stackelberg"), "{bad_game}");
    let no_game = error(&with("driver = { kind = \"agent\" }", "driver = { kind = \"gt\" }"));
    assert!(no_game.contains("missing field") && no_game.contains("game"), "{no_game}");
    let bad_role =
        error(&with("driver = { kind = \"agent\" }", "driver = { kind = \"gt\", game = \"nash\", role = \"boss\" }"));
    assert!(bad_role.contains("boss") && bad_role.contains("follower"), "{bad_role}");
    let tolerance = error(&with(
        "driver = { kind = \"agent\" }",
        "driver = { kind = \"gt\", game = \"nash\", follower_tolerance = -0.5 }",
    ));
    assert!(tolerance.contains("vehicle 'a'.driver.follower_tolerance") && tolerance.contains("-0.5"), "{tolerance}");
    let preset = error(&with(
        "driver = { kind = \"agent\" }",
        "driver = { kind = \"gt\", game = \"nash\", params = \"paper-fitt\" }",
    ));
    assert!(
        preset.contains("driver.params") && preset.contains("'paper-fitt'") && preset.contains("paper-fit"),
        "{preset}"
    );
}

#[test]
fn a_scenario_names_built_in_presets_only_never_a_file() {
    for path in ["/etc/hostname", "presets/paper-fit.toml", "paper-fit.toml"] {
        let message = error(&with(
            "driver = { kind = \"agent\" }",
            &format!("driver = {{ kind = \"gt\", game = \"nash\", params = \"{path}\" }}"),
        ));
        assert!(message.contains("driver.params") && message.contains("built-in presets only"), "{message}");
    }
}

#[test]
fn a_gt_driver_takes_its_constants_from_a_preset_and_its_own_tolerance() {
    let text = with(
        "driver = { kind = \"agent\" }",
        "driver = { kind = \"gt\", game = \"stackelberg\", params = \"paper-fit\", follower_tolerance = 0.7 }",
    );
    let scenario = parse(&text).unwrap();
    let mut expected = arena_preset_gt("paper-fit");
    expected.decision.game.follower_tolerance = 0.7;
    let DriverSpec::Gt { params, .. } = scenario.vehicles[0].driver else { panic!("a gt driver") };
    assert_eq!(params, expected);
}

fn arena_preset_gt(name: &str) -> GtParams {
    crate::preset::Preset::load(name).unwrap().gt
}

#[test]
fn every_shipped_file_declares_the_name_it_is_served_under_and_has_a_learner() {
    for (name, file, text) in BUILTIN_SCENARIOS {
        let scenario = Scenario::parse(file, text, &[]).unwrap();
        assert_eq!(scenario.name, name, "{file}");
        assert_eq!(format!("{name}.toml"), file);
        assert!(scenario.agents().next().is_some(), "{file} has no learner");
    }
}

#[test]
fn a_varied_scenario_draws_each_episode_from_the_seed() {
    use rand::SeedableRng;
    let scenario = builtin_scenario("merge-random").unwrap().unwrap();
    assert_eq!(scenario.vary.len(), 6);
    let draw = |seed| {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        scenario.episode(&mut rng, &[]).unwrap()
    };
    assert_eq!(draw(1), draw(1));
    let (a, b) = (draw(1), draw(2));
    assert_ne!(a.vehicles, b.vehicles);
    for episode in [a, b] {
        let ac = episode.vehicles.iter().find(|v| v.name == "ac").unwrap();
        assert!((30.0..75.0).contains(&ac.s) && (12.0..22.0).contains(&ac.speed), "{ac:?}");
    }
    // The paper's own files draw nothing: every episode is the scenario itself.
    let merge = builtin_scenario("merge").unwrap().unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    assert_eq!(merge.episode(&mut rng, &[]).unwrap(), merge);
}

#[test]
fn bad_vary_and_reward_tables_are_refused_with_the_key() {
    let bad_range = format!("{GOOD}\n[vary]\n\"vehicle.a.s\" = {{ range = [5.0] }}\n");
    assert!(error(&bad_range).contains("vary.\"vehicle.a.s\""), "{}", error(&bad_range));
    let bad_kind = format!("{GOOD}\n[vary]\n\"vehicle.a.s\" = [1.0, 2.0]\n");
    assert!(error(&bad_kind).contains("range = [low, high]"));
    let bad_scale = format!("{GOOD}\n[reward]\ncost_scale = -1.0\n");
    assert!(error(&bad_scale).contains("reward.cost_scale"));
    let bad_crash = format!("{GOOD}\n[reward]\ncrash = 3.0\n");
    assert!(error(&bad_crash).contains("reward.crash"));
    // A failure at the time limit lies between the crash reward and 0.
    for failure in ["1.0", "-1e9"] {
        let bad_failure = format!("{GOOD}\n[reward]\ncrash = -100.0\nfailure = {failure}\n");
        assert!(error(&bad_failure).contains("reward.failure"), "{}", error(&bad_failure));
    }
    let good = parse(&format!("{GOOD}\n[reward]\ncrash = -100.0\nfailure = -20.0\n")).expect("a good failure");
    assert_eq!((good.reward.failure_reward(10), good.reward.crash_reward(10)), (-20.0, -100.0));
}

mod fuzz {
    //! Scenario text mutated from the shipped files: the loader answers Ok or an error
    //! for every input, and never panics.
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

        #[test]
        fn mutated_scenario_files_load_or_are_refused(
            which in 0usize..BUILTIN_SCENARIOS.len(),
            edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<char>(), 0u8..3), 1..8),
        ) {
            let mut text: Vec<char> = BUILTIN_SCENARIOS[which].2.chars().collect();
            for (at, c, kind) in edits {
                let i = at.index(text.len().max(1)).min(text.len());
                match kind {
                    0 if i < text.len() => text[i] = c,
                    1 => text.insert(i, c),
                    _ if i < text.len() => { text.remove(i); }
                    _ => {}
                }
            }
            let text: String = text.into_iter().collect();
            if let Ok(scenario) = Scenario::parse("fuzz.toml", &text, &[]) {
                // What validates also builds.
                let world = scenario.build(0);
                prop_assert!(world.vehicles().len() >= scenario.vehicles.len());
            }
        }
    }
}

#[test]
fn a_goal_names_lanes_of_the_road_and_vehicles_of_the_file() {
    let goal = |table: &str| with("[[vehicle]]\nname = \"a\"", &format!("{table}\n[[vehicle]]\nname = \"a\""));
    let scenario = parse(&goal("[goal]\nlanes = [0]\nahead_of = [\"b\"]")).expect("a good goal");
    assert_eq!(scenario.goal, Goal { lanes: vec![LaneId(0)], ahead_of: vec!["b".into()], fail_at_time_limit: false });
    assert_eq!(parse(GOOD).expect("no goal").goal, Goal::default());
    let message = error(&goal("[goal]\nlanes = [2]"));
    assert!(message.contains("`goal.lanes` lists lane 2, but the road's lanes are 0..=1"), "{message}");
    let message = error(&goal("[goal]\nahead_of = [\"lc\"]"));
    assert!(message.contains("`goal.ahead_of` names 'lc'"), "{message}");
    let message = error(&goal("[goal]\nlane = 0"));
    assert!(message.contains("unknown field `lane`"), "{message}");
}

// Cross-play: `opponents.<what>` drives every opponent at once (arena eval --opponents).

fn builtin_with(name: &str, overrides: &[(&str, &str)]) -> Result<Scenario, ScenarioError> {
    let (_, file, text) = BUILTIN_SCENARIOS.iter().find(|(n, ..)| *n == name).expect("a built-in scenario");
    let overrides: Vec<(String, toml::Value)> =
        overrides.iter().map(|(k, v)| (k.to_string(), toml::Value::String(v.to_string()))).collect();
    Scenario::parse(file, text, &overrides)
}

fn opponent_drivers(scenario: &Scenario) -> Vec<(String, Style, Option<Game>)> {
    let game = |driver: &DriverSpec| match driver {
        DriverSpec::Gt { game, .. } => Some(*game),
        _ => None,
    };
    scenario.vehicles.iter().filter(|v| v.name != "ec_0").map(|v| (v.name.clone(), v.style, game(&v.driver))).collect()
}

#[test]
fn opponents_take_the_style_and_game_given_over_the_drawn_ones() {
    use rand::SeedableRng;
    let plain = builtin_with("merge-random", &[]).unwrap();
    let crossed =
        builtin_with("merge-random", &[("opponents.style", "aggressive"), ("opponents.game", "nash")]).unwrap();
    let mut styles = Vec::new();
    for seed in 0..12 {
        let drawn = plain.episode(&mut rand_chacha::ChaCha8Rng::seed_from_u64(seed), &[]).unwrap();
        let against = crossed.episode(&mut rand_chacha::ChaCha8Rng::seed_from_u64(seed), &[]).unwrap();
        assert_eq!(opponent_drivers(&against), vec![("ac".to_string(), Style::Aggressive, Some(Game::Nash))]);
        styles.push(drawn.vehicles[1].style);
        // Everything else drawn is drawn the same: the same episodes, another opponent.
        let place = |s: &Scenario| s.vehicles.iter().map(|v| (v.s, v.speed, v.lane)).collect::<Vec<_>>();
        assert_eq!(place(&drawn), place(&against), "seed {seed}");
    }
    assert!(
        styles.contains(&Style::Normal) && styles.contains(&Style::Conservative),
        "[vary] draws the style: {styles:?}"
    );
}

#[test]
fn idm_opponents_replace_gt_vehicles_and_gt_traffic() {
    let merge = builtin_with("merge", &[("opponents.driver", "idm")]).unwrap();
    assert_eq!(opponent_drivers(&merge), vec![("ac".to_string(), Style::Normal, None)]);
    assert!(matches!(merge.vehicles[1].driver, DriverSpec::Idm));
    let highway = builtin_with("highway-gt", &[("opponents.style", "conservative")]).unwrap();
    let gt = highway.traffic.as_ref().and_then(|t| t.gt.as_ref()).expect("highway-gt has gt traffic");
    assert_eq!((&gt.styles[..], &gt.games[..], gt.count), (&[Style::Conservative][..], &[Game::Stackelberg][..], 8));
    let idm = builtin_with("highway-gt", &[("opponents.driver", "idm")]).unwrap();
    assert!(idm.traffic.as_ref().is_some_and(|t| t.gt.is_none()));
}

#[test]
fn opponents_that_cannot_be_set_are_refused_by_name() {
    let refused = |name: &str, key: &str, value: &str| builtin_with(name, &[(key, value)]).unwrap_err().to_string();
    let none = refused("highway", "opponents.style", "aggressive");
    assert!(none.contains("opponents.style") && none.contains("no opponents"), "{none}");
    let driver = refused("merge", "opponents.driver", "gt");
    assert!(driver.contains("\"idm\""), "{driver}");
    let what = refused("merge", "opponents.speed", "3");
    assert!(what.contains("opponents.style, opponents.game or opponents.driver"), "{what}");
    let style = refused("merge", "opponents.style", "reckless");
    assert!(style.contains("reckless"), "{style}");
}

/// `GOOD`'s road made 2 km long with `traffic` as its `[traffic]` table.
fn with_traffic(traffic: &str) -> String {
    with("sections = [{ length = 500.0 }]", "sections = [{ length = 2000.0 }]") + "[traffic]\n" + traffic
}

#[test]
fn gt_traffic_of_several_styles_and_games_drives_every_pair_in_turn() {
    let text = with_traffic(
        "count = 12\nspeed = [20.0, 22.0]\n\
         gt = { count = 7, game = [\"nash\", \"stackelberg\"], style = [\"aggressive\", \"normal\", \"conservative\"] }",
    );
    let scenario = parse(&text).unwrap();
    let gt = scenario.traffic.as_ref().and_then(|t| t.gt.clone()).unwrap();
    let pairs: Vec<_> = (0..7).map(|k| gt.driver(k)).collect();
    use {Game::*, Style::*};
    let expected = [
        (Aggressive, Nash),
        (Aggressive, Stackelberg),
        (Normal, Nash),
        (Normal, Stackelberg),
        (Conservative, Nash),
        (Conservative, Stackelberg),
        (Aggressive, Nash),
    ];
    assert_eq!(pairs, expected);
    // The world's gt cars, in the order they were placed, drive those pairs.
    let world = scenario.build(3);
    let placed: Vec<_> = (0..world.vehicles().len() as u32)
        .map(crate::VehicleId)
        .filter_map(|id| world.gt_setup(id).map(|setup| (world.style(id), setup.game)))
        .collect();
    assert_eq!(placed, expected);
    // One of each, as before: every gt car alike.
    let one = parse(&with_traffic("count = 4\nspeed = [20.0, 22.0]\ngt = { count = 2, game = \"nash\" }")).unwrap();
    let gt = one.traffic.unwrap().gt.unwrap();
    assert_eq!((gt.driver(0), gt.driver(1)), ((Normal, Nash), (Normal, Nash)));
}

#[test]
fn bad_lists_of_gt_styles_and_games_are_refused_with_the_key() {
    let refused = |gt: &str| error(&with_traffic(&format!("count = 4\nspeed = [20.0, 22.0]\ngt = {gt}")));
    let empty = refused("{ count = 2, game = \"nash\", style = [] }");
    assert!(empty.contains("traffic.gt.style") && empty.contains("at least one"), "{empty}");
    let empty = refused("{ count = 2, game = [] }");
    assert!(empty.contains("traffic.gt.game") && empty.contains("at least one"), "{empty}");
    let unknown = refused("{ count = 2, game = \"nash\", style = [\"normal\", \"reckless\"] }");
    assert!(unknown.contains("reckless") && unknown.contains("conservative"), "{unknown}");
    let unknown = refused("{ count = 2, game = [\"nash\", 3] }");
    assert!(unknown.contains("game"), "{unknown}");
}

#[test]
fn traffic_with_a_start_fills_the_road_from_there_and_keeps_clear_of_named_vehicles() {
    // Vehicle a is in lane 0 at s = 10 and b in lane 1 at 30; traffic in lane 0 only.
    let traffic = |start: &str| format!("count = 20\nspeed = [20.0, 22.0]\nlanes = [0]\nstart = {start}\n");
    let scenario = parse(&with_traffic(&traffic("100.0"))).unwrap();
    let spec = scenario.traffic.clone().unwrap();
    let world = scenario.build(5);
    let placed: Vec<f64> = world.vehicles()[2..].iter().map(|v| v.state.s).collect();
    let lanes = scenario.road.lane_count();
    let (first, last) = (placed[0], placed[placed.len() - 1]);
    assert!(first > 100.0 + 0.9 * spec.spacing(20.0, lanes) - 1e-9 && first < 100.0 + 1.1 * spec.spacing(22.0, lanes));
    assert!(placed.windows(2).all(|w| w[1] > w[0]) && last <= 100.0 + spec.reach(lanes), "{placed:?}");
    // Without a start it goes ahead of the frontmost named vehicle (b, at 30).
    let ahead = parse(&with_traffic("count = 20\nspeed = [20.0, 22.0]\nlanes = [0]\n")).unwrap().build(5);
    assert!(ahead.vehicles()[2].state.s > 30.0 && ahead.vehicles()[2].state.s < 100.0);
    // A named vehicle in the traffic's lanes within its stretch is refused by name.
    let inside = error(&with_traffic(&traffic("0.0")));
    assert!(inside.contains("traffic.start") && inside.contains("'a'") && inside.contains("lane 0"), "{inside}");
    for start in ["-5.0", "2000.0", "nan"] {
        let off = error(&with_traffic(&traffic(start)));
        assert!(off.contains("traffic.start") && off.contains("position on the road"), "{start}: {off}");
    }
}

#[test]
fn the_density_of_traffic_is_counted_per_km_and_lane() {
    // highway.toml: 4 lanes, density 1, 21-24 m/s: one car per 34.5 x exp(-0.5) = 20.9 m
    // of road, over 4 lanes: 12.0 vehicles per km per lane.
    let highway = builtin_scenario("highway").unwrap().unwrap();
    let per_km = highway.traffic.unwrap().vehicles_per_km_per_lane(4);
    assert!((per_km - 1000.0 / (34.5 * (-0.5f64).exp() * 4.0)).abs() < 1e-9 && (per_km - 11.95).abs() < 0.01);
}

// Bounds: what one scenario may cost (`bounds`), on the file and after overrides and draws.

/// `cars` vehicles 10 m apart in four lanes of a long road, the `k`th driven by `driver(k)`;
/// `sim` and `extra` are spliced in as tables.
fn crowd(cars: usize, driver: impl Fn(usize) -> &'static str, sim: &str, extra: &str) -> String {
    let mut text =
        format!("name = \"t\"\n[sim]\n{sim}\n{extra}\n[road]\nlanes = 4\nspeed_limits = [30.0, 30.0, 30.0, 30.0]\n");
    text.push_str(&format!("sections = [{{ length = {}.0 }}]\n", 1000 + 10 * cars / 4));
    for k in 0..cars {
        let (lane, s) = (k % 4, 10 * (k / 4));
        text.push_str(&format!(
            "[[vehicle]]\nname = \"c{k}\"\nlane = {lane}\ns = {s}.0\nspeed = 20.0\ndriver = {}\n",
            driver(k)
        ));
    }
    text
}

const IDM: &str = "{ kind = \"idm\" }";
const AGENT: &str = "{ kind = \"agent\" }";
const GT: &str = "{ kind = \"gt\", game = \"stackelberg\" }";

/// Passes `at` and refuses `above` with `ScenarioErrorKind::Invalid` naming `key` and the bound.
fn bound_holds(at: &str, above: &str, key: &str, bound: usize) {
    if let Err(e) = parse(at) {
        panic!("at the bound of {key}: {e}");
    }
    match parse(above).expect_err("past the bound").kind {
        ScenarioErrorKind::Invalid { key: named, message } => {
            assert_eq!(named, key, "{message}");
            assert!(message.contains(&format!(" {bound} ")), "{message}");
        }
        other => panic!("{key}: {other:?}"),
    }
}

#[test]
fn a_road_has_at_most_max_road_sections() {
    let road = |n: usize| {
        with("sections = [{ length = 500.0 }]", &format!("sections = [{}]", vec!["{ length = 1.0 }"; n].join(", ")))
    };
    bound_holds(&road(MAX_ROAD_SECTIONS), &road(MAX_ROAD_SECTIONS + 1), "road.sections", MAX_ROAD_SECTIONS);
    assert!(parse(&road(30_000)).unwrap_err().to_string().contains("join consecutive straight sections"));
}

#[test]
fn a_scenario_has_at_most_max_vehicles_named_in_traffic_and_both() {
    let idm = |_| IDM;
    bound_holds(&crowd(MAX_VEHICLES, idm, "", ""), &crowd(MAX_VEHICLES + 1, idm, "", ""), "vehicle", MAX_VEHICLES);
    let traffic = |named: usize, count: usize| {
        crowd(named, idm, "", &format!("[traffic]\ncount = {count}\nspeed = [20.0, 25.0]"))
    };
    bound_holds(&traffic(0, MAX_VEHICLES), &traffic(0, MAX_VEHICLES + 1), "traffic.count", MAX_VEHICLES);
    bound_holds(&traffic(48, MAX_VEHICLES - 48), &traffic(48, MAX_VEHICLES - 47), "traffic.count", MAX_VEHICLES);
    let message = parse(&traffic(0, 10_001)).unwrap_err().to_string();
    assert!(message.contains("`traffic.count` 10001") && message.contains("lower traffic.count"), "{message}");
}

#[test]
fn a_scenario_has_at_most_max_learners() {
    let agents = |n: usize| crowd(n + 1, move |k| if k < n { AGENT } else { IDM }, "", "");
    bound_holds(&agents(MAX_LEARNERS), &agents(MAX_LEARNERS + 1), "vehicle", MAX_LEARNERS);
}

#[test]
fn a_scenario_has_at_most_max_gt_cars_named_and_in_traffic() {
    let named = |n: usize| crowd(n, |_| GT, "", "");
    bound_holds(&named(MAX_GT_CARS), &named(MAX_GT_CARS + 1), "vehicle", MAX_GT_CARS);
    let traffic = |named: usize, gt: usize| {
        let table = format!("[traffic]\ncount = 100\nspeed = [20.0, 25.0]\ngt = {{ count = {gt}, game = \"nash\" }}");
        crowd(named + 1, move |k| if k < named { GT } else { AGENT }, "", &table)
    };
    bound_holds(&traffic(4, MAX_GT_CARS - 4), &traffic(4, MAX_GT_CARS - 3), "traffic.gt.count", MAX_GT_CARS);
    assert_eq!(parse(&traffic(4, MAX_GT_CARS - 4)).unwrap().gt_cars(), MAX_GT_CARS);
}

#[test]
fn an_env_step_takes_at_most_max_physics_ticks() {
    let sim = |step: f64| crowd(2, |_| IDM, &format!("physics_dt = 0.001\ncontrol_dt = 0.1\nstep_dt = {step:?}"), "");
    let ticks = MAX_PHYSICS_TICKS_PER_STEP as f64 * 0.001;
    bound_holds(&sim(ticks), &sim(ticks + 0.001), "sim.physics_dt", MAX_PHYSICS_TICKS_PER_STEP);
    assert_eq!(parse(&sim(ticks)).unwrap().physics_ticks_per_step(), MAX_PHYSICS_TICKS_PER_STEP);
    // The step that never ended: a billion ticks.
    let message = error(&crowd(2, |_| IDM, "physics_dt = 1e-9\nstep_dt = 1.0", ""));
    assert!(message.contains("`sim.physics_dt`") && message.contains("1000000000 physics ticks"), "{message}");
}

#[test]
fn an_env_step_takes_at_most_max_control_periods() {
    let sim = |step: f64| crowd(2, |_| IDM, &format!("physics_dt = 0.05\ncontrol_dt = 0.1\nstep_dt = {step:?}"), "");
    let periods = MAX_CONTROL_PERIODS_PER_STEP as f64 * 0.1;
    bound_holds(&sim(periods), &sim(periods + 0.05), "sim.step_dt", MAX_CONTROL_PERIODS_PER_STEP);
    assert_eq!(parse(&sim(periods)).unwrap().control_periods_per_step(), MAX_CONTROL_PERIODS_PER_STEP);
    let message = error(&crowd(2, |_| IDM, "physics_dt = 0.5\ncontrol_dt = 0.5\nstep_dt = 500.0", ""));
    assert!(message.contains("`sim.step_dt`") && message.contains("1000 control periods"), "{message}");
}

#[test]
fn an_env_step_takes_at_most_max_gt_decisions() {
    // 1 s steps of 0.1 s control periods: 10 decisions a car.
    let cars = MAX_GT_DECISIONS_PER_STEP / 10;
    let gt = |n: usize| crowd(n + 1, move |k| if k < n { GT } else { AGENT }, "step_dt = 1.0", "");
    bound_holds(&gt(cars), &gt(cars + 1), "sim.step_dt", MAX_GT_DECISIONS_PER_STEP);
    assert_eq!(parse(&gt(cars)).unwrap().gt_decisions_per_step(), MAX_GT_DECISIONS_PER_STEP);
    let highway = builtin_scenario("highway-gt").unwrap().unwrap();
    assert_eq!((highway.gt_cars(), highway.control_periods_per_step(), highway.gt_decisions_per_step()), (8, 10, 80));
    assert_eq!(builtin_scenario("merge").unwrap().unwrap().gt_decisions_per_step(), 1);
}

#[test]
fn a_vary_table_draws_at_most_max_vary_keys() {
    let vary = |n: usize| {
        let keys: String = (0..n).map(|k| format!("\"vehicle.c{k}.speed\" = {{ range = [19.0, 21.0] }}\n")).collect();
        format!("{}[vary]\n{keys}", crowd(n, |_| IDM, "", ""))
    };
    bound_holds(&vary(MAX_VARY_KEYS), &vary(MAX_VARY_KEYS + 1), "vary", MAX_VARY_KEYS);
}

#[test]
fn the_road_reaches_at_most_max_road_extent() {
    let origin =
        |x: &str| with("sections = [", &format!("origin = {{ x = {x}, y = 0.0, heading = 0.0 }}\nsections = ["));
    assert!(parse(&origin("1e6")).is_ok());
    let message = error(&origin("1.000001e6"));
    assert!(message.contains("`road.origin.x`") && message.contains("MAX_ROAD_EXTENT"), "{message}");
    let long = error(&with("{ length = 500.0 }", "{ length = 500.0 }, { length = 1e6 }"));
    assert!(long.contains("`road.sections` makes the road 1000500 m long"), "{long}");
    let wide = error(&with("speed_limits", "lane_width = 6e5\nspeed_limits"));
    assert!(wide.contains("`road.lane_width`") && wide.contains("wide"), "{wide}");
}

#[test]
fn non_finite_origins_and_places_are_refused_by_key() {
    for value in ["nan", "inf", "-inf"] {
        for (field, key) in [("x", "road.origin.x"), ("y", "road.origin.y"), ("heading", "road.origin.heading")] {
            let origin = ["x", "y", "heading"].map(|f| format!("{f} = {}", if f == field { value } else { "0.0" }));
            let text = with("sections = [", &format!("origin = {{ {} }}\nsections = [", origin.join(", ")));
            let message = error(&text);
            assert!(message.contains(&format!("`{key}`")) && message.to_lowercase().contains(value), "{message}");
        }
        for (place, key) in
            [(format!("x = {value}\ny = 0.0"), "vehicle 'a'.x"), (format!("x = 10.0\ny = {value}"), "vehicle 'a'.y")]
        {
            let message = error(&with("lane = 0\ns = 10.0", &place));
            assert!(message.contains(&format!("`{key}`")) && message.to_lowercase().contains(value), "{message}");
        }
    }
    // What a NaN place used to become: the road's start, s = 0.
    assert!(parse(&with("lane = 0\ns = 10.0", "x = 0.0\ny = 0.0")).is_ok());
}

#[test]
fn bounds_hold_after_overrides_and_draws() {
    use rand::SeedableRng;
    let refuse = |overrides: &[(&str, toml::Value)]| {
        let overrides: Vec<_> = overrides.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
        Scenario::parse("test.toml", GOOD, &overrides).unwrap_err().to_string()
    };
    let ticks = refuse(&[("sim.physics_dt", toml::Value::Float(1e-9)), ("sim.step_dt", toml::Value::Float(1.0))]);
    assert!(ticks.contains("`sim.physics_dt`"), "{ticks}");
    let speed = [toml::Value::Float(20.0), toml::Value::Float(25.0)];
    let traffic = toml::Table::from_iter([
        ("count".to_string(), toml::Value::Integer(MAX_VEHICLES as i64)),
        ("speed".to_string(), toml::Value::Array(speed.to_vec())),
    ]);
    let traffic = refuse(&[("traffic", toml::Value::Table(traffic))]);
    assert!(traffic.contains("`traffic.count`") && traffic.contains("2050 vehicles"), "{traffic}");
    // A draw past a bound is refused as it is, not drawn again.
    let drawn = format!("{GOOD}\n[vary]\n\"sim.step_dt\" = {{ choose = [1000.0] }}\n");
    let scenario = parse(&drawn).unwrap();
    let error = scenario.episode(&mut rand_chacha::ChaCha8Rng::seed_from_u64(0), &[]).unwrap_err().to_string();
    assert!(error.contains("`sim.physics_dt`") && error.contains("100000 physics ticks"), "{error}");
}

#[test]
fn a_vary_that_always_overlaps_is_refused_within_the_budget() {
    use rand::SeedableRng;
    let always = format!(
        "{GOOD}\n[vary]\n\"vehicle.b.lane\" = {{ choose = [0] }}\n\"vehicle.b.s\" = {{ range = [10.0, 12.0] }}\n"
    );
    let refused = |text: &str| {
        let scenario = parse(text).unwrap();
        scenario.episode(&mut rand_chacha::ChaCha8Rng::seed_from_u64(5), &[]).unwrap_err()
    };
    let error = refused(&always);
    match &error.kind {
        ScenarioErrorKind::DrawsExhausted { draws, last } => {
            assert_eq!(*draws, EPISODE_DRAWS);
            assert!(matches!(**last, ScenarioErrorKind::Overlap { .. }), "{last:?}");
        }
        other => panic!("{other:?}"),
    }
    let message = error.to_string();
    assert!(message.contains("20 times") && message.contains("vehicles 'a' and 'b' overlap"), "{message}");
    assert!(message.contains("Narrow the [vary] ranges"), "{message}");
    // A file near the 1 MiB an inline scenario may have gets the draws the budget pays for.
    let padded = format!("{always}# {}\n", "-".repeat(1 << 20));
    assert!(matches!(refused(&padded).kind, ScenarioErrorKind::DrawsExhausted { draws: 3, .. }));
    assert_eq!(bounds::episode_draws(1 << 20), VARY_DRAW_BUDGET_BYTES >> 20);
    // A draw that fits is drawn as before: from one reading of the text.
    let fits = format!("{GOOD}\n[vary]\n\"vehicle.b.s\" = {{ range = [30.0, 40.0] }}\n");
    let scenario = parse(&fits).unwrap();
    let episode = scenario.episode(&mut rand_chacha::ChaCha8Rng::seed_from_u64(5), &[]).unwrap();
    assert!((30.0..40.0).contains(&episode.vehicles[1].s));
}

#[test]
fn a_goal_names_each_lane_and_vehicle_once() {
    let goal = |table: &str| with("[[vehicle]]\nname = \"a\"", &format!("{table}\n[[vehicle]]\nname = \"a\""));
    assert!(error(&goal("[goal]\nlanes = [0, 1, 0]")).contains("`goal.lanes` lists lane 0 twice"));
    assert!(error(&goal("[goal]\nahead_of = [\"b\", \"b\"]")).contains("`goal.ahead_of` names 'b' twice"));
}

mod overlap {
    //! The grid's overlap check against every pair, on seeded random placements.
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use crate::dynamics::VehicleParams;
    use crate::road::{Pose, Road, Section};
    use crate::scenario::validate::first_overlap;
    use crate::world::oriented_boxes_overlap;

    /// Straight, tight arcs both ways, and a full circle and more, so that the road
    /// crosses itself and far-apart s meet.
    fn roads() -> Vec<Road> {
        let origin = Pose { x: 3.0, y: -7.0, heading: 0.4 };
        let bends = vec![
            Section::Straight { length: 40.0 },
            Section::Arc { length: 60.0, curvature: 1.0 / 13.0 },
            Section::Arc { length: 50.0, curvature: -1.0 / 15.0 },
            Section::Straight { length: 30.0 },
        ];
        let circle = vec![Section::Arc { length: 250.0, curvature: 1.0 / 20.0 }];
        vec![
            Road::new(origin, bends, 4.0, vec![30.0; 3], &[]),
            Road::new(origin, circle, 4.0, vec![30.0; 3], &[]),
            Road::straight(200.0, 3, 4.0, 30.0),
        ]
    }

    fn place(road: &Road, cars: usize, rng: &mut ChaCha8Rng) -> Vec<(f64, f64, f64)> {
        (0..cars)
            .map(|_| {
                let s = rng.random_range(0.0..road.length());
                let d =
                    rng.random_range(-(road.lane_count() as f64 - 0.5) * road.lane_width()..0.5 * road.lane_width());
                let pose = road.to_global(s, d, rng.random_range(-0.3..0.3));
                (pose.x, pose.y, pose.heading)
            })
            .collect()
    }

    fn every_pair(poses: &[(f64, f64, f64)]) -> Vec<(usize, usize)> {
        let half = (VehicleParams::default().length / 2.0, VehicleParams::default().width / 2.0);
        (0..poses.len())
            .flat_map(|i| (i + 1..poses.len()).map(move |j| (i, j)))
            .filter(|&(i, j)| oriented_boxes_overlap(poses[i], poses[j], half))
            .collect()
    }

    #[test]
    fn the_grid_finds_the_first_pair_every_pair_finds() {
        let body = VehicleParams::default();
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let (mut overlapping, mut clear) = (0, 0);
        for road in roads() {
            for round in 0..300 {
                let poses = place(&road, 2 + round % 40, &mut rng);
                let pairs = every_pair(&poses);
                assert_eq!(first_overlap(&poses, &body), pairs.first().copied(), "{poses:?}");
                if pairs.is_empty() {
                    clear += 1
                } else {
                    overlapping += 1
                }
                // Each pair alone among the cars that touch nothing: found, and named.
                let lonely: Vec<usize> =
                    (0..poses.len()).filter(|&k| pairs.iter().all(|&(i, j)| i != k && j != k)).collect();
                for &(i, j) in &pairs {
                    let mut cars: Vec<usize> = lonely.iter().copied().chain([i, j]).collect();
                    cars.sort_unstable();
                    let subset: Vec<_> = cars.iter().map(|&k| poses[k]).collect();
                    let found = first_overlap(&subset, &body).map(|(a, b)| (cars[a], cars[b]));
                    assert_eq!(found, Some((i, j)));
                }
            }
        }
        assert!(overlapping > 100 && clear > 100, "{overlapping} placements overlap, {clear} do not");
    }

    #[test]
    fn a_crowd_in_one_place_is_found_at_once() {
        let body = VehicleParams::default();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for road in roads() {
            // Two thousand cars within a few metres: the first cell's first cars.
            let mut poses = place(&road, 50, &mut rng);
            let at = road.to_global(20.0, -4.0, 0.0);
            poses.extend((0..2000).map(|k| (at.x + 0.001 * k as f64, at.y, at.heading)));
            let (i, j) = first_overlap(&poses, &body).expect("a crowd overlaps");
            let half = (body.length / 2.0, body.width / 2.0);
            assert!(oriented_boxes_overlap(poses[i], poses[j], half));
        }
    }
}

#[test]
fn speeds_are_at_most_max_speed() {
    let at = format!("{MAX_SPEED:.1}");
    let past = format!("{:.1}", MAX_SPEED + 0.5);
    for (replace, key) in
        [("s = 10.0\nspeed = 20.0", "vehicle 'a'.speed"), ("speed_limits = [30.0, 30.0]", "road.speed_limits")]
    {
        let (good, bad) = match key {
            "road.speed_limits" => (format!("speed_limits = [{at}, 30.0]"), format!("speed_limits = [{past}, 30.0]")),
            _ => (format!("s = 10.0\nspeed = {at}"), format!("s = 10.0\nspeed = {past}")),
        };
        assert!(parse(&with(replace, &good)).is_ok(), "{key} at {at}");
        let message = error(&with(replace, &bad));
        assert!(message.contains(&format!("`{key}`")) && message.contains("MAX_SPEED"), "{message}");
    }
    // A speed of 1e180 turned the dynamics to NaN within a step (the restore fuzz target).
    let message = error(&with("s = 10.0\nspeed = 20.0", "s = 10.0\nspeed = 1e180"));
    assert!(message.contains("MAX_SPEED"), "{message}");
    let target = error(&with("s = 10.0\nspeed = 20.0", &format!("s = 10.0\nspeed = 20.0\ntarget_speed = {past}")));
    assert!(target.contains("target_speed") && target.contains("MAX_SPEED"), "{target}");
}
