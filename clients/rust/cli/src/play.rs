//! `arena play`: steps an env on a server with a built-in policy (by default the
//! game-theoretic AV itself, driving in the learner's place in the server, as `arena
//! eval`'s `expert` row does) and redraws its ansi render
//! in the terminal after every step; each episode ends with its return and why it ended.

use std::time::{Duration, Instant};

use arena_client::{Action, CreateOptions, Frame, RenderMode, ScenarioSource};
use arena_protocol::session::ConnectionFlags;
use arena_protocol::{BuiltinPolicy, Game, Info, InfoValue, MetaAction, Space};

/// Arguments of `arena play`.
#[derive(Debug, clap::Args)]
pub struct PlayArgs {
    #[command(flatten)]
    connection: ConnectionFlags,
    /// Scenario on the server (merge, overtake, highway, ...).
    #[arg(long, default_value = "merge")]
    scenario: String,
    /// How every agent acts: expert (the game-theoretic AV drives in its place, in its
    /// style, Stackelberg: `arena eval`'s expert), expert-replay (the agent plays the
    /// AV's `expert_action` labels in its own action space: a driver of its own), idle
    /// (keep lane and target speed), faster, or random.
    #[arg(long, value_enum, default_value_t = Policy::Expert)]
    policy: Policy,
    /// Seed of the episode (and of the random policy).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Episodes to play.
    #[arg(long, default_value_t = 1)]
    episodes: u32,
    /// Playback speed: 1 shows simulated time as it passes, 2 twice as fast; 0 as fast
    /// as it can.
    #[arg(long, default_value_t = 1.0)]
    speed: f64,
}

/// Built-in policies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum Policy {
    Expert,
    ExpertReplay,
    Idle,
    Faster,
    Random,
}

/// Runs `arena play`.
pub fn run(args: PlayArgs) -> anyhow::Result<()> {
    anyhow::ensure!(args.speed.is_finite() && args.speed >= 0.0, "--speed must be 0 or more, not {}", args.speed);
    let (client, server) = crate::connect(&args.connection)?;
    let expert = (args.policy == Policy::ExpertReplay).then_some(Game::Stackelberg);
    let driven = args.policy == Policy::Expert;
    let policy = driven.then_some(BuiltinPolicy::Gt { style: None, game: Game::Stackelberg });
    let options = CreateOptions { expert, policy, ..CreateOptions::default() };
    let mut env = client.create_env(&server, ScenarioSource::Named(args.scenario.clone()), options)?;
    let specs = env.specs().clone();
    let mut random = args.seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    for episode in 0..args.episodes {
        let reset = env.reset(Some(args.seed + u64::from(episode)), vec![])?;
        let mut infos: Vec<(String, Info)> = reset.agents.into_iter().map(|start| (start.agent, start.info)).collect();
        let mut live = specs.possible_agents.clone();
        let mut returns = vec![0.0; specs.possible_agents.len()];
        let mut endings = vec![String::from("still driving"); specs.possible_agents.len()];
        let mut cycle = 0;
        while !live.is_empty() {
            let started = Instant::now();
            let actions = if driven { Vec::new() } else { live.clone() };
            let actions = actions
                .iter()
                .map(|agent| {
                    let space = specs.action_spaces.iter().find(|(a, _)| a == agent).map(|(_, s)| s);
                    let info = infos.iter().find(|(a, _)| a == agent).map(|(_, i)| i);
                    (agent.clone(), choose(args.policy, space, info, &mut random))
                })
                .collect();
            let reply = env.step(actions)?;
            for step in &reply.steps {
                let Some(k) = specs.possible_agents.iter().position(|a| *a == step.agent) else { continue };
                returns[k] += step.reward;
                if let Some(end) = step.info.end_reason().filter(|end| *end != arena_protocol::EndReason::Running) {
                    endings[k] = format!("{end} after {} steps", cycle + 1);
                }
            }
            infos = reply.steps.iter().map(|step| (step.agent.clone(), step.info.clone())).collect();
            live = reply.agents.clone();
            cycle += 1;
            if let Frame::Ansi(text) = env.render(RenderMode::Ansi, None)? {
                print!(
                    "\x1b[2J\x1b[H{} — episode {} step {cycle}/{}\n{text}",
                    args.scenario,
                    episode + 1,
                    specs.max_cycles
                );
                for (agent, total) in specs.possible_agents.iter().zip(&returns) {
                    println!("{agent}: return {total:.1}");
                }
            }
            if args.speed > 0.0 {
                let frame = Duration::from_secs_f64(specs.dt / args.speed);
                std::thread::sleep(frame.saturating_sub(started.elapsed()));
            }
        }
        println!("episode {} ended:", episode + 1);
        for ((agent, total), ending) in specs.possible_agents.iter().zip(&returns).zip(&endings) {
            println!("  {agent}: {ending}, return {total:.1}");
        }
    }
    env.close()?;
    client.close()?;
    Ok(())
}

/// The action of `policy` for an agent with action `space` whose last info is `info`.
fn choose(policy: Policy, space: Option<&Space>, info: Option<&Info>, state: &mut u64) -> Action {
    *state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    let draw = (*state >> 33) as f64 / (1u64 << 31) as f64;
    let expert = info.and_then(|info| info.get(arena_protocol::info::EXPERT_ACTION));
    match (policy, expert) {
        (Policy::ExpertReplay, Some(InfoValue::I64(action))) => return Action::Meta(*action as u32),
        (Policy::ExpertReplay, Some(InfoValue::F64s(values))) if values.len() == 2 => {
            return Action::Continuous([values[0] as f32, values[1] as f32]);
        }
        _ => {}
    }
    match (policy, space) {
        (Policy::Idle | Policy::Expert | Policy::ExpertReplay, Some(Space::Box { .. })) => {
            Action::Continuous([0.0, 0.0])
        }
        (Policy::Faster, Some(Space::Box { high, .. })) => Action::Continuous([high[0] / 2.0, 0.0]),
        (Policy::Random, Some(Space::Box { low, high, .. })) => {
            Action::Continuous([low[0] + (high[0] - low[0]) * draw as f32, 0.0])
        }
        (Policy::Random, _) => {
            let count = MetaAction::ALL.len() as u32;
            Action::Meta((draw * f64::from(count)) as u32 % count)
        }
        (Policy::Faster, _) => Action::Meta(MetaAction::Faster.code()),
        (Policy::Idle | Policy::Expert | Policy::ExpertReplay, _) => Action::Meta(MetaAction::Idle.code()),
    }
}
