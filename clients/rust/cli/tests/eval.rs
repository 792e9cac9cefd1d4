//! `arena eval` run as a user runs it, against a real arena-server on a loopback port:
//! its cost RMS and t_c for the game-theoretic EC equal `arena paper`'s, the same seeds
//! give the same tables, and bad input is refused with a message naming it.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;

use common::{Harness, serve};

use arena_paper::{PaperOptions, PaperScenario};
use arena_sim::Game;
use arena_sim::Style;

/// A fresh folder for one run's output, removed when the test ends (passed or not).
struct OutDir(PathBuf);

impl std::ops::Deref for OutDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl Drop for OutDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn out_dir(name: &str) -> OutDir {
    let dir = std::env::temp_dir().join(format!("arena-eval-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    OutDir(dir)
}

fn eval(harness: &Harness, out: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_arena"))
        .args(["eval", "--connect", &harness.endpoint, "--out"])
        .arg(out)
        .args(args)
        .output()
        .expect("run arena eval")
}

fn results(out: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(out.join("results.json")).expect("results.json written");
    serde_json::from_str(&text).expect("results.json is JSON")
}

#[test]
fn the_rms_costs_and_t_c_of_the_gt_ec_on_merge_equal_arena_papers() {
    let harness = serve();
    let out = out_dir("paper");
    let policies = ["gt:aggressive:stackelberg", "gt:normal:stackelberg", "gt:conservative:stackelberg"];
    let mut args = vec!["--scenario", "merge", "--episodes", "1", "--max-cycles", "160"];
    for policy in policies {
        args.extend(["--policy", policy]);
    }
    let output = eval(&harness, &out, &args);
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let json = results(&out);
    let figure = |episode: &serde_json::Value, key: &str| {
        let k = arena_eval::figure_index(key).expect("a figure");
        episode["figures"][k].as_f64().expect("a number")
    };
    for (policy, style) in policies.into_iter().zip(Style::ALL) {
        let (record, _) = arena_paper::run(PaperScenario::A, style, Game::Stackelberg, &PaperOptions::default())
            .expect("the paper's run");
        let episode = json["episodes"].as_array().unwrap().iter().find(|e| e["policy"] == policy).expect("ran");
        let rms = record.rms_cost;
        assert_eq!(figure(episode, "rms_safety"), rms.safety, "{policy}");
        assert_eq!(figure(episode, "rms_comfort"), rms.comfort, "{policy}");
        assert_eq!(figure(episode, "rms_efficiency"), rms.efficiency, "{policy}");
        assert_eq!(Some(figure(episode, "t_c")), record.t_c, "{policy}");
        assert_eq!(figure(episode, "success"), 1.0, "{policy} merges");
    }
}

#[test]
fn the_same_seeds_give_identical_tables() {
    let harness = serve();
    let args = [
        "--scenario",
        "merge-random",
        "--episodes",
        "3",
        "--seed",
        "7",
        "--policy",
        "expert",
        "--policy",
        "random",
        "--policy",
        "idle",
    ];
    let (first, second) = (out_dir("a"), out_dir("b"));
    for out in [&first, &second] {
        let output = eval(&harness, out, &args);
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    }
    for file in ["results.md", "results.csv", "episodes.csv", "results.json"] {
        let read = |dir: &Path| std::fs::read_to_string(dir.join(file)).expect("written");
        assert_eq!(read(&first), read(&second), "{file}");
    }
    let json = results(&first);
    assert_eq!(json["episodes"].as_array().map(Vec::len), Some(9), "3 policies x 3 episodes");
    let seeds: Vec<u64> = json["episodes"].as_array().unwrap().iter().filter_map(|e| e["seed"].as_u64()).collect();
    assert_eq!(seeds, [7, 8, 9].repeat(3), "every policy plays the same seeds");
    for plot in ["costs_merge-random.png", "rates_merge-random.png"] {
        let bytes = std::fs::read(first.join(plot)).expect("plot written");
        assert!(bytes.starts_with(b"\x89PNG"), "{plot} is a PNG");
    }
    // The compute budget: the server's clock for the AV, this process's for the others,
    // one sample per agent and step (merge-random: one learner, 200 steps at most).
    let budget = std::fs::read_to_string(first.join("budget.csv")).expect("budget.csv written");
    let rows: Vec<Vec<&str>> = budget.lines().skip(1).map(|line| line.split(',').collect()).collect();
    let clocks: Vec<(&str, &str)> = rows.iter().map(|r| (r[1], r[2])).collect();
    assert_eq!(clocks, [("expert", "server"), ("random", "client"), ("idle", "client")], "{budget}");
    for row in &rows {
        let steps: usize = row[3].parse().unwrap();
        let (p50, p99): (f64, f64) = (row[4].parse().unwrap(), row[5].parse().unwrap());
        // An idle action may take less than the clock's resolution; the AV's never does.
        let timed = p50 > 0.0 || row[2] == "client";
        assert!((3..=600).contains(&steps) && p50 >= 0.0 && timed && p99 >= p50, "{budget}");
    }
    assert!(std::fs::read_to_string(first.join("budget.md")).unwrap().contains("| expert | server |"));
}

#[test]
fn bad_policies_scenarios_and_counts_are_refused_by_name() {
    let harness = serve();
    let out = out_dir("bad");
    let cases: [(&[&str], &str); 6] = [
        (&["--scenario", "merge", "--policy", "gt:calm:nash"], "unknown built-in policy 'gt:calm:nash'"),
        (&["--scenario", "nowhere"], "nowhere"),
        (&["--scenario", "merge", "--episodes", "0"], "--episodes must be at least 1"),
        (&["--scenario", "merge", "--policy", "idle", "--policy", "idle"], "--policy idle is given twice"),
        (
            &["--scenario", "merge", "--policy", "idle", "--reference", "ppo"],
            "--reference ppo is not one of the --policy",
        ),
        (&["--scenario", "merge", "--bootstrap", "10"], "--bootstrap must be at least 100"),
    ];
    for (args, message) in cases {
        let output = eval(&harness, &out, args);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success() && stderr.contains(message), "{args:?}: {stderr}");
    }
}

#[test]
fn a_league_accepts_a_run_of_its_settings_and_refuses_one_of_other_seeds() {
    let harness = serve();
    let out = out_dir("league");
    let league = out.join("league.json");
    let league_arg = league.to_str().expect("a UTF-8 path").to_string();
    let base = ["--scenario", "merge-random", "--episodes", "2", "--max-cycles", "30", "--league", &league_arg];
    let run = |policy: &str, seed: &str| {
        let mut args = base.to_vec();
        args.extend(["--policy", policy, "--seed", seed]);
        eval(&harness, &out, &args)
    };
    let first = run("idle", "0");
    assert!(first.status.success(), "{}", String::from_utf8_lossy(&first.stderr));
    let second = run("random", "0");
    assert!(second.status.success(), "{}", String::from_utf8_lossy(&second.stderr));
    let table = std::fs::read_to_string(out.join("league.md")).expect("league.md written");
    assert!(table.contains("| idle |") && table.contains("| random |"), "{table}");
    let before = std::fs::read_to_string(&league).expect("the league file");
    let refused = run("idm", "7");
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success() && stderr.contains("first seed 7, not the league's 0"), "{stderr}");
    assert_eq!(std::fs::read_to_string(&league).expect("the league file"), before, "a refused run changes nothing");
}

#[test]
fn cross_play_on_merge_fills_the_matrix_of_every_style_and_game_identically_twice() {
    let harness = serve();
    let args = ["--scenario", "merge", "--episodes", "1", "--policy", "gt:normal:stackelberg", "--opponents"];
    let (first, second) = (out_dir("cross-a"), out_dir("cross-b"));
    for out in [&first, &second] {
        let output = eval(&harness, out, &args);
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    }
    for file in ["crossplay.md", "results.json"] {
        let read = |dir: &Path| std::fs::read_to_string(dir.join(file)).expect("written");
        assert_eq!(read(&first), read(&second), "{file}");
    }
    let json = results(&first);
    let episodes = json["episodes"].as_array().expect("episodes");
    let rows: Vec<&str> = episodes.iter().filter_map(|e| e["policy"].as_str()).collect();
    let mut expected = Vec::new();
    for style in ["aggressive", "normal", "conservative"] {
        for game in ["nash", "stackelberg"] {
            expected.push(format!("gt:normal:stackelberg vs gt:{style}:{game}"));
        }
    }
    expected.push("gt:normal:stackelberg vs idm".to_string());
    assert_eq!(rows, expected, "one cell per style and game, then IDM");
    // The opponent is really another driver: AC's style changes how the merge goes.
    let k = arena_eval::figure_index("return").expect("a figure");
    let returns: Vec<f64> = episodes.iter().map(|e| e["figures"][k].as_f64().expect("a number")).collect();
    assert_ne!(returns[0], returns[4], "aggressive and conservative opponents give the same return: {returns:?}");
    let table = std::fs::read_to_string(first.join("crossplay.md")).expect("crossplay.md");
    assert!(table.contains("### merge: success (one distinct episode per cell: no intervals)"), "{table}");
    for figure in ["success", "at_fault", "return"] {
        let bytes = std::fs::read(first.join(format!("crossplay_merge_{figure}.png"))).expect("heatmap written");
        assert!(bytes.starts_with(b"\x89PNG"), "{figure} heatmap is a PNG");
    }
    let out = out_dir("cross-none");
    let refused =
        eval(&harness, &out, &["--scenario", "highway", "--episodes", "1", "--policy", "idle", "--opponents"]);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success() && stderr.contains("no opponents"), "{stderr}");
}
