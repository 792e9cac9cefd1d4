//! Playing the built-in AV's `expert_action` through the env drives as the AV drives: on
//! merge.toml (the paper's Scenario A, the learner as EC against the paper's
//! game-theoretic AC) the expert's lane-change decision comes at the t_c `arena paper`
//! prints for the normal style under Stackelberg, and the meta-action expert merges
//! within a second of the continuous one, neither colliding.

use arena_paper::{PaperOptions, PaperScenario};
use arena_protocol::{Action, ActionType, CreateOptions, EndReason, Game, Info, InfoValue, ResetOptions};
use arena_server::env::Env;
use arena_sim::Style;
use arena_sim::builtin_scenario;

fn value<'a>(info: &'a Info, key: &str) -> &'a InfoValue {
    info.values.iter().find(|(k, _)| k == key).map(|(_, v)| v).unwrap_or_else(|| panic!("no {key} in {info:?}"))
}

fn number(info: &Info, key: &str) -> f64 {
    info.number(key).unwrap_or_else(|| panic!("{key}: {:?}", info.get(key)))
}

/// One episode of ec_0 replaying the expert: per step (time, expert sigma, lateral
/// offset d from the lane centre of lane 1 = -4 m, lane), and how it ended.
struct Replay {
    decisions: Vec<(f64, i64)>,
    lanes: Vec<(f64, i64)>,
    end: EndReason,
}

fn replay(action_type: ActionType) -> Replay {
    let options =
        CreateOptions { action_type: Some(action_type), expert: Some(Game::Stackelberg), ..CreateOptions::default() };
    let mut env = Env::new(builtin_scenario("merge").unwrap().unwrap(), &options, 0).unwrap();
    let mut info = env.reset(Some(0), &ResetOptions::default()).unwrap().remove(0).info;
    let (mut decisions, mut lanes, mut end) = (Vec::new(), Vec::new(), EndReason::Running);
    for k in 0..200 {
        let t = k as f64 * 0.1;
        decisions.push((t, number(&info, "expert_sigma") as i64));
        let action = match value(&info, "expert_action") {
            InfoValue::I64(a) => Action::Meta(*a as u32),
            InfoValue::F64s(v) => Action::Continuous([v[0] as f32, v[1] as f32]),
            other => panic!("{other:?}"),
        };
        let step = env.step(&[("ec_0".to_string(), action)]).unwrap().remove(0);
        lanes.push((t + 0.1, number(&step.info, "lane") as i64));
        info = step.info;
        if step.terminated || step.truncated {
            end = info.end_reason().expect("an end reason");
            break;
        }
    }
    Replay { decisions, lanes, end }
}

/// t_c as `arena paper` defines it: the start of the last run of lane-change decisions
/// before EC is in the new lane.
fn decision_time(replay: &Replay) -> Option<f64> {
    let merged = replay.lanes.iter().find(|(_, lane)| *lane == 0).map_or(f64::INFINITY, |(t, _)| *t);
    let mut start = None;
    for &(t, sigma) in replay.decisions.iter().take_while(|(t, _)| *t < merged) {
        start = match (sigma != 0, start) {
            (true, None) => Some(t),
            (true, started) => started,
            (false, _) => None,
        };
    }
    start
}

fn merge_time(replay: &Replay) -> f64 {
    replay.lanes.iter().find(|(_, lane)| *lane == 0).map(|(t, _)| *t).expect("the expert merges")
}

#[test]
fn the_continuous_expert_decides_at_arena_papers_t_c_and_the_meta_expert_merges_within_a_second() {
    let se = arena_sim::Game::Stackelberg;
    let paper = arena_paper::run(PaperScenario::A, Style::Normal, se, &PaperOptions::default()).unwrap().0;
    let continuous = replay(ActionType::Continuous);
    let meta = replay(ActionType::Meta);
    for run in [&continuous, &meta] {
        assert_eq!(run.end, EndReason::TimeLimit, "no collision, no lane end");
    }
    let t_c = decision_time(&continuous).expect("the expert decides to merge");
    let expected = paper.t_c.expect("arena paper's normal EC merges");
    assert!((t_c - expected).abs() < 1e-6, "env t_c {t_c} against arena paper's {expected}");
    let (a, b) = (merge_time(&continuous), merge_time(&meta));
    assert!((a - b).abs() <= 1.0, "continuous expert in lane 0 at {a} s, meta expert at {b} s");
}
