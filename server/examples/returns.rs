//! Episode returns of simple policies on every built-in scenario, in process: the figures
//! of docs/rewards.md. Policies: `idle` (the default action), `random` (uniform over the
//! action space, seeded), `expert` (the built-in AV's `expert_action`, Stackelberg).
//!
//! Run: `cargo run --release -p arena-server --example returns -- [EPISODES] [--csv FILE]`
//! (default 20 episodes). `--csv` also writes every episode (`scenario,policy,seed,return,
//! end_reason`), the raw result docs/rewards.md's table is rendered from (scripts/docs-tables).

use arena_protocol::{Action, ActionType, CreateOptions, Game, Info, InfoValue, MetaAction, ResetOptions};
use arena_server::env::Env;
use arena_sim::BUILTIN_SCENARIOS;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

#[derive(Clone, Copy, Debug)]
enum Policy {
    Idle,
    Random,
    Expert,
}

/// One episode's return for the first agent, and how it ended.
fn episode(env: &mut Env, policy: Policy, seed: u64, rng: &mut ChaCha8Rng) -> (f64, String) {
    let reset = env.reset(Some(seed), &ResetOptions::default()).expect("a built-in scenario resets");
    let agent = reset[0].agent.clone();
    let mut expert = expert_action(&reset[0].info);
    let mut total = 0.0;
    loop {
        let action = match policy {
            Policy::Idle => None,
            Policy::Random => Some(Action::Meta(rng.random_range(0..MetaAction::ALL.len() as u32))),
            Policy::Expert => expert.map(Action::Meta),
        };
        let actions: Vec<(String, Action)> = action.map(|a| (agent.clone(), a)).into_iter().collect();
        let step = env.step(&actions).expect("a valid step").remove(0);
        total += step.reward;
        expert = expert_action(&step.info);
        if step.terminated || step.truncated {
            return (total, step.info.end_reason().map_or("unknown", |end| end.name()).to_string());
        }
    }
}

fn expert_action(info: &Info) -> Option<u32> {
    match info.get(arena_protocol::info::EXPERT_ACTION)? {
        InfoValue::I64(a) => u32::try_from(*a).ok(),
        _ => None,
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let csv_path = args.iter().position(|a| a == "--csv").map(|k| args.get(k + 1).expect("--csv FILE").clone());
    let episodes: u64 = args.first().filter(|a| *a != "--csv").and_then(|a| a.parse().ok()).unwrap_or(20);
    let mut csv = String::from("scenario,policy,seed,return,end_reason\n");
    println!("| scenario | policy | min | mean | max | how episodes ended |");
    println!("|---|---|---|---|---|---|");
    for (name, file, text) in BUILTIN_SCENARIOS {
        let scenario = arena_sim::Scenario::parse(file, text, &[]).expect("built-in scenarios validate");
        if scenario.agents().next().is_none() {
            continue;
        }
        let options = CreateOptions {
            action_type: Some(ActionType::Meta),
            expert: Some(Game::Stackelberg),
            ..CreateOptions::default()
        };
        for policy in [Policy::Idle, Policy::Random, Policy::Expert] {
            let mut env = Env::new(scenario.clone(), &options, 0).expect("a learner to drive");
            let mut rng = ChaCha8Rng::seed_from_u64(7);
            let runs: Vec<(f64, String)> =
                (0..episodes).map(|seed| episode(&mut env, policy, seed, &mut rng)).collect();
            let policy_name = format!("{policy:?}").to_lowercase();
            for (seed, (total, why)) in runs.iter().enumerate() {
                csv += &format!("{name},{policy_name},{seed},{total},{why}\n");
            }
            let returns: Vec<f64> = runs.iter().map(|r| r.0).collect();
            let mean = returns.iter().sum::<f64>() / returns.len() as f64;
            let min = returns.iter().copied().fold(f64::INFINITY, f64::min);
            let max = returns.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let mut reasons: Vec<String> = runs.iter().map(|r| r.1.clone()).collect();
            reasons.sort();
            reasons.dedup();
            let counts: Vec<String> =
                reasons.iter().map(|why| format!("{} {why}", runs.iter().filter(|r| &r.1 == why).count())).collect();
            println!("| {name} | {policy_name} | {min:.2} | {mean:.2} | {max:.2} | {} |", counts.join(", "));
        }
    }
    if let Some(path) = csv_path {
        std::fs::write(&path, csv).unwrap_or_else(|e| panic!("writing {path}: {e}"));
        eprintln!("csv: {path}");
    }
}
