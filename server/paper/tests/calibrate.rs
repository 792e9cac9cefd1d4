//! `arena calibrate` (issue 14): the shipped fit loads and keeps the paper's orderings;
//! a fit recovers known constants from the model's own tables; the same seed gives the
//! same fit, whatever the number of threads.

use arena_paper::calibrate::{self, FitSpec, Target, knob, records};
use arena_paper::compare;
use arena_paper::{PaperOptions, PaperScenario, Record};
use arena_sim::Game;
use arena_sim::LaneChange;
use arena_sim::Style;

fn find(records: &[Record], scenario: PaperScenario, style: Style, game: Game) -> &Record {
    records
        .iter()
        .find(|r| r.scenario == scenario.name() && r.style == style.name() && r.game == game.name())
        .expect("every run was made")
}

#[test]
fn the_paper_fit_preset_loads_and_keeps_the_papers_orderings() {
    let (preset, options) = calibrate::options_of("paper-fit").expect("the shipped preset loads");
    assert_eq!(preset.name, "paper-fit");
    let records = records(&PaperScenario::ALL, &options).unwrap();
    for game in Game::ALL {
        let [a, n, c] = Style::ALL.map(|style| find(&records, PaperScenario::A, style, game));
        let (ta, tn, tc) = (a.t_c.unwrap(), n.t_c.unwrap(), c.t_c.unwrap());
        assert!(ta < tn && tn < tc, "{game:?}: A's t_c {ta} {tn} {tc}");
        assert!(a.gaps_at_t_c["AC"] > 0.0 && n.gaps_at_t_c["AC"] > 0.0, "{game:?}: ahead of AC");
        assert!(c.gaps_at_t_c["AC"] < 0.0, "{game:?}: the conservative EC merges behind AC");
        for style in [Style::Aggressive, Style::Normal] {
            assert_eq!(find(&records, PaperScenario::B, style, game).lane_change, LaneChange::Left, "{style:?}");
        }
        assert_eq!(find(&records, PaperScenario::B, Style::Conservative, game).t_c, None, "{game:?}: keeps");
    }
    assert!(records.iter().all(|r| !r.collision), "no collision with the fitted constants");
    // Issue 23: the stable K_s schedule left the fit at 38 of the 48 cells of Tables IV and
    // VI within the paper's figure +-30 %; issue 24's jerk bound moved one out (A
    // conservative's Nash gap, docs/paper-reproduction.md says why). No change may lose
    // another.
    let (within, cells) = compare::score(&compare::cells(&records));
    assert_eq!(cells, 48, "Tables IV and VI have 48 cells");
    assert!(within >= 37, "paper-fit: {within} of 48 cells within +-30 %, fewer than 37");
}

/// A small fit of Scenario A's runs toward `target`, from `start`.
fn spec(knobs: &[&str], target: Target, start: PaperOptions, seed: u64, jobs: usize) -> FitSpec {
    FitSpec {
        knobs: knobs.iter().map(|k| knob(k).unwrap()).collect(),
        target,
        start,
        seeds: Vec::new(),
        particles: 8,
        iterations: 10,
        spread: 0.3,
        seed,
        jobs,
    }
}

#[test]
fn a_fit_to_the_models_own_tables_recovers_the_constants_they_were_made_with() {
    // Known constants: AC aims for 20 m/s (the file: 22) and the games allow 2.5 m/s^2
    // (default 3). The target is the model's own Table IV under them; the fit starts
    // from the file's and the defaults, and must land within 5 % of each knob's range.
    // The model is the AV without the jerk bound (issue 24): under it the games' a_max is
    // reached only along a 4 m/s^3 ramp, Table IV hardly depends on it, and the same fit
    // finds 2.73 for 2.5. What is tested is the fit, on constants the tables pin down.
    let names = ["merge.ac.target_speed", "game.accel_max"];
    let truth = [20.0, 2.5];
    let mut start = PaperOptions::default();
    start.params.decision.jerk.enabled = false;
    let mut known = start.clone();
    for (name, value) in names.iter().zip(truth) {
        knob(name).unwrap().set(&mut known, value);
    }
    let target = Target::from_records(&records(&[PaperScenario::A], &known).unwrap());
    let fit = calibrate::fit(&spec(&names, target, start, 7, 2), None).unwrap();
    for (name, value) in names.iter().zip(truth) {
        let knob = knob(name).unwrap();
        let found = knob.get(&fit.options);
        let tolerance = 0.05 * (knob.high - knob.low);
        assert!((found - value).abs() <= tolerance, "{name}: found {found}, made with {value} (± {tolerance})");
    }
    assert!(fit.loss < fit.start_loss, "the fit improved on its start: {} -> {}", fit.start_loss, fit.loss);
}

#[test]
fn the_same_seed_gives_the_same_fit_whatever_the_threads() {
    let names = ["costs.kappa_v_log", "merge.ac.target_speed"];
    let small = |seed, jobs| FitSpec {
        particles: 4,
        iterations: 2,
        ..spec(&names, Target::paper(&[PaperScenario::A]), PaperOptions::default(), seed, jobs)
    };
    let one = calibrate::fit(&small(3, 1), None).unwrap();
    let two = calibrate::fit(&small(3, 2), None).unwrap();
    let values = |fit: &calibrate::Fit| calibrate::knob_values(&small(3, 1).knobs, &fit.options);
    assert_eq!(values(&one), values(&two));
    assert_eq!(one.loss.to_bits(), two.loss.to_bits());
    let other = calibrate::fit(&small(4, 1), None).unwrap();
    assert_ne!(values(&one), values(&other), "another seed moves the swarm elsewhere");
}

#[test]
fn a_written_preset_reads_back_as_the_fit() {
    let mut options = PaperOptions::default();
    knob("costs.kappa_ax").unwrap().set(&mut options, 12.5);
    knob("overtake.ac2.target_speed").unwrap().set(&mut options, 23.0);
    knob("overtake.adjacent.style").unwrap().set(&mut options, 0.0);
    let text = calibrate::preset_text("t", "a test", &options);
    let preset = arena_sim::Preset::parse("t", &text).unwrap();
    let read = PaperOptions::with_preset(&preset);
    assert_eq!(read.params, options.params);
    assert_eq!(knob("overtake.ac2.target_speed").unwrap().get(&read), 23.0);
    assert_eq!(knob("merge.ac.target_speed").unwrap().get(&read), 22.0, "unset: the file's");
    assert_eq!(knob("overtake.adjacent.style").unwrap().get(&read), 0.0, "aggressive");
    assert_eq!(knob("merge.adjacent.style").unwrap().get(&read), 1.0, "unset: normal, the paper runs' default");
    let records = records(&[PaperScenario::B], &read).unwrap();
    assert!(records.iter().all(|r| r.diagnostics.len() == 3), "the style reaches the runs' drivers");
    let unknown = knob("costs.kappa_q").unwrap_err().to_string();
    assert!(unknown.contains("'costs.kappa_q'") && unknown.contains("costs.kappa_ax"), "{unknown}");
}
