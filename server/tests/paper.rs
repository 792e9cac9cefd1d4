//! The paper's qualitative results (§VI) on the real scenarios, for the three styles and
//! both games, exactly as `arena paper` runs them: decision order and side in Scenario A,
//! lane choice in Scenario B, and no collision anywhere.

use std::sync::OnceLock;

use arena_server::av::Game;
use arena_server::dynamics::Style;
use arena_server::paper::{self, PaperOptions, PaperScenario, Record, Trace};

/// All 12 runs, made once for every test of this file.
fn runs() -> &'static Vec<(Record, Trace)> {
    static RUNS: OnceLock<Vec<(Record, Trace)>> = OnceLock::new();
    RUNS.get_or_init(|| {
        let mut runs = Vec::new();
        for scenario in PaperScenario::ALL {
            for style in Style::ALL {
                for game in Game::ALL {
                    let run = paper::run(scenario, style, game, &PaperOptions::default())
                        .expect("the shipped scenarios accept the gt overrides");
                    runs.push(run);
                }
            }
        }
        runs
    })
}

fn run(scenario: PaperScenario, style: Style, game: Game) -> &'static (Record, Trace) {
    runs()
        .iter()
        .find(|(r, _)| r.scenario == scenario.name() && r.style == style.name() && r.game == game.name())
        .expect("every combination was run")
}

fn record(scenario: PaperScenario, style: Style, game: Game) -> &'static Record {
    &run(scenario, style, game).0
}

#[test]
fn in_the_merge_aggressive_decides_first_and_conservative_last_in_both_games() {
    for game in Game::ALL {
        let [a, n, c] = Style::ALL.map(|style| record(PaperScenario::A, style, game).t_c);
        let (Some(a), Some(n), Some(c)) = (a, n, c) else {
            panic!("{game:?}: every style must merge, got {a:?} {n:?} {c:?}");
        };
        assert!(a < n && n < c, "{game:?}: t_c aggressive {a}, normal {n}, conservative {c}");
    }
}

#[test]
fn in_the_merge_aggressive_and_normal_go_ahead_of_the_adjacent_car_and_conservative_behind() {
    for game in Game::ALL {
        for style in Style::ALL {
            let r = record(PaperScenario::A, style, game);
            assert_eq!(r.lane_change, -1, "{style:?} {game:?} must merge left");
            let gap = r.gaps_at_t_c["AC"];
            match style {
                Style::Conservative => assert!(gap < 0.0, "{game:?}: conservative merges behind AC, gap {gap}"),
                _ => assert!(gap > 0.0, "{style:?} {game:?}: merges ahead of AC, gap {gap}"),
            }
        }
    }
}

#[test]
fn in_the_overtake_aggressive_and_normal_change_left_and_conservative_keeps_its_lane() {
    for game in Game::ALL {
        for style in [Style::Aggressive, Style::Normal] {
            let r = record(PaperScenario::B, style, game);
            assert_eq!(r.lane_change, -1, "{style:?} {game:?} must overtake on the left: {r:?}");
            assert!(r.t_c.is_some() && r.gaps_at_t_c.len() == 2 && r.speeds_at_t_c.len() == 3);
        }
        let conservative = record(PaperScenario::B, Style::Conservative, game);
        assert_eq!((conservative.lane_change, conservative.t_c), (0, None), "{game:?}: {conservative:?}");
        assert!(conservative.gaps_at_t_c.is_empty() && conservative.speeds_at_t_c.is_empty());
    }
}

#[test]
fn no_run_collides() {
    for (r, _) in runs() {
        assert!(!r.collision, "{} {} {} collided", r.scenario, r.style, r.game);
    }
}

#[test]
fn the_costs_reflect_the_styles() {
    // Table V/VII's pattern on efficiency: the aggressive style keeps its speed shortfall
    // smallest, the conservative one largest.
    for scenario in PaperScenario::ALL {
        for game in Game::ALL {
            let [a, n, c] = Style::ALL.map(|style| record(scenario, style, game).rms_cost.efficiency);
            assert!(a < n && n < c, "{scenario:?} {game:?}: efficiency RMS {a} {n} {c}");
        }
    }
}

#[test]
fn a_run_is_reproducible_to_the_bit_and_serialises_as_documented() {
    let again = paper::run(PaperScenario::B, Style::Normal, Game::Stackelberg, &PaperOptions::default()).unwrap().0;
    assert_eq!(&again, record(PaperScenario::B, Style::Normal, Game::Stackelberg));
    let json = serde_json::to_value(record(PaperScenario::B, Style::Conservative, Game::Nash)).unwrap();
    for key in ["scenario", "style", "game", "t_c", "gaps_at_t_c", "speeds_at_t_c", "lane_change", "collision"] {
        assert!(json.get(key).is_some(), "missing {key}: {json}");
    }
    assert!(json["t_c"].is_null());
    for key in ["safety", "comfort", "efficiency"] {
        assert!(json["rms_cost"][key].as_f64().is_some_and(|v| v > 0.0), "rms_cost.{key}: {json}");
    }
}

#[test]
fn nash_and_stackelberg_coincide_until_stackelberg_decides_and_it_decides_no_later() {
    // docs/paper-reproduction.md, "Nash against Stackelberg": while EC keeps its lane J^EC
    // does not depend on AC's action, so the two exact games make the same moves; and the
    // leader's lane-change value is never above a Nash one, so SE switches no later.
    for scenario in PaperScenario::ALL {
        for style in Style::ALL {
            let (ne, ne_trace) = run(scenario, style, Game::Nash);
            let (se, se_trace) = run(scenario, style, Game::Stackelberg);
            let until = se.t_c.unwrap_or(f64::INFINITY);
            let before = |trace: &'static Trace| trace.samples.iter().take_while(move |s| s.t < until);
            assert!(before(ne_trace).eq(before(se_trace)), "{scenario:?} {style:?}: the runs differ before t_c");
            if let (Some(ne), Some(se)) = (ne.t_c, se.t_c) {
                assert!(se <= ne, "{scenario:?} {style:?}: SE decided at {se} s, after NE at {ne} s");
            }
        }
    }
}
