//! `arena eval`: policies compared on scenarios over the same seeds (a paired comparison):
//! rates with Wilson intervals, other figures as median and IQM with bootstrap intervals,
//! and every policy's paired differences from a reference policy (`arena_eval`),
//! printed as tables and written as Markdown, CSV and JSON with box plots of the paper's
//! cost components and bars of how the episodes ended. Built-in drivers (`gt:...`, `expert`,
//! `idm`) run in the server (the env's `policy` option); `idle` and `random` act here.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use arena_client::blocking::{Client, Env};
use arena_client::{Action, CreateOptions, ScenarioSource};
use arena_eval::budget::{self, Budget, Clock};
use arena_eval::league::{League, LeagueSettings, league_markdown};
use arena_eval::stats::Bootstrap;
use arena_eval::{self as eval, Episode, Settings, Summary, crossplay};
use arena_protocol::session::ConnectionFlags;
use arena_protocol::{BuiltinPolicy, MetaAction, OptionValue, Space};
use indicatif::{ProgressBar, ProgressStyle};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

mod plots;

/// The most envs one run steps together: a server's default `--max-envs-per-client`.
const MAX_BATCH: u64 = 256;

/// Arguments of `arena eval`.
#[derive(Debug, clap::Args)]
pub struct EvalArgs {
    #[command(flatten)]
    connection: ConnectionFlags,
    /// Scenario to evaluate on (repeat for several): merge, overtake, highway, ...
    #[arg(long = "scenario", required = true)]
    scenarios: Vec<String>,
    /// Episodes per policy and scenario; episode i is reset with seed `--seed` + i for
    /// every policy.
    #[arg(long, default_value_t = 20)]
    episodes: u64,
    /// Policy (repeat for several): gt:<aggressive|normal|conservative>:<nash|stackelberg>,
    /// expert (gt in the learner's own style, Stackelberg), idm, idle, random.
    #[arg(long = "policy", default_values_t = ["expert".to_string(), "idm".to_string(), "idle".to_string(), "random".to_string()])]
    policies: Vec<String>,
    /// Seed of the first episode.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Episode length in steps, instead of each scenario's.
    #[arg(long)]
    max_cycles: Option<u32>,
    /// Envs stepped together in one round trip (1..=256, a server's default per-client
    /// env limit).
    #[arg(long, default_value_t = 16)]
    batch: u64,
    /// The policy the others are compared with, seed by seed (default: the first
    /// `--policy`).
    #[arg(long)]
    reference: Option<String>,
    /// Bootstrap resamples of every interval but the rates' (seeded: the same episodes
    /// give the same table).
    #[arg(long, default_value_t = Bootstrap::default().reps)]
    bootstrap: usize,
    /// A league file (JSON) to add this run's rows to, created if missing; refused when
    /// its seed, episode count or episode length differ (new scenarios join). Writes league.md
    /// beside it.
    #[arg(long)]
    league: Option<PathBuf>,
    /// Cross-play: every policy against every opponent the AV can be (gt:<style>:<game>
    /// for the three styles and two games, and idm) on the same seeds; writes
    /// crossplay.md and a heatmap per scenario and figure (success, at fault, return).
    /// The opponents are the scenario's cars driven by gt and its [traffic] gt cars.
    #[arg(long)]
    opponents: bool,
    /// The figure league.md ranks by (a figure key: return, success, rms_safety, ...).
    #[arg(long, default_value = "return")]
    rank: String,
    /// Folder for results.md, results.csv, differences.csv, episodes.csv, results.json and the plots
    /// (created if missing).
    #[arg(long, default_value = "out/eval")]
    out: PathBuf,
}

/// Who drives the learners.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Policy {
    /// A driver of the server.
    Server(BuiltinPolicy),
    /// Keep lane and target speed.
    Idle,
    /// Uniform over the action space, seeded by the episode's seed.
    Random,
}

impl std::str::FromStr for Policy {
    type Err = String;
    fn from_str(text: &str) -> Result<Self, String> {
        match text {
            "idle" => Ok(Policy::Idle),
            "random" => Ok(Policy::Random),
            _ => text.parse().map(Policy::Server).map_err(|e: String| e + ", idle, random"),
        }
    }
}

/// Runs `arena eval`.
pub fn run(args: EvalArgs) -> anyhow::Result<()> {
    anyhow::ensure!(args.episodes >= 1, "--episodes must be at least 1");
    anyhow::ensure!(
        (1..=MAX_BATCH).contains(&args.batch),
        "--batch must be within 1..={MAX_BATCH} (a server lets one client hold {MAX_BATCH} envs by default), not {}",
        args.batch
    );
    let policies = args
        .policies
        .iter()
        .map(|name| name.parse::<Policy>().map(|p| (name.clone(), p)).map_err(anyhow::Error::msg))
        .collect::<anyhow::Result<Vec<_>>>()?;
    for (list, what) in [(&args.policies, "--policy"), (&args.scenarios, "--scenario")] {
        if let Some(twice) = list.iter().enumerate().find_map(|(i, x)| list[..i].contains(x).then_some(x)) {
            anyhow::bail!("{what} {twice} is given twice");
        }
    }
    if let Some(reference) = args.reference.as_ref().filter(|r| !args.policies.contains(r)) {
        anyhow::bail!("--reference {reference} is not one of the --policy values ({})", args.policies.join(", "));
    }
    if eval::figure_index(&args.rank).is_none() {
        let keys: Vec<&str> = eval::FIGURES.iter().map(|f| f.key).collect();
        anyhow::bail!("--rank {} is not a figure ({})", args.rank, keys.join(", "));
    }
    anyhow::ensure!(args.bootstrap >= 100, "--bootstrap must be at least 100 resamples, not {}", args.bootstrap);
    let (client, server) = crate::connect(&args.connection)?;
    anyhow::ensure!(
        !(args.opponents && args.league.is_some()),
        "--opponents and --league cannot be combined: a league ranks policies against each scenario's own opponents"
    );
    let opponents = if args.opponents { crossplay::opponents() } else { vec![] };
    let cells = opponents.len().max(1);
    let total = args.episodes.saturating_mul((policies.len() * args.scenarios.len() * cells) as u64);
    let bar = ProgressBar::new(total).with_style(
        ProgressStyle::with_template("{msg:32} [{bar:30}] {pos}/{len} episodes, {elapsed} (eta {eta})")
            .map_err(|e| anyhow::anyhow!("progress bar template: {e}"))?
            .progress_chars("=> "),
    );
    let mut episodes = Vec::new();
    let mut budgets = Vec::new();
    for scenario in &args.scenarios {
        for (name, policy) in &policies {
            let against: Vec<Option<&crossplay::Opponent>> =
                if opponents.is_empty() { vec![None] } else { opponents.iter().map(Some).collect() };
            for opponent in against {
                let row = opponent.map_or(name.clone(), |o| crossplay::row_name(name, &o.name));
                bar.set_message(format!("{scenario} / {row}"));
                let overrides = opponent.map_or(vec![], |o| o.overrides.clone());
                let run = Run {
                    client: &client,
                    server: &server,
                    scenario,
                    name: &row,
                    policy: *policy,
                    overrides,
                    args: &args,
                };
                let (done, micros) = run.episodes(&bar)?;
                episodes.extend(done);
                let clock = if matches!(policy, Policy::Server(_)) { Clock::Server } else { Clock::Client };
                budgets.push(Budget::new(scenario, &row, clock, &micros));
            }
        }
    }
    bar.finish_and_clear();
    client.close()?;
    let reference = match (&args.reference, opponents.first()) {
        (Some(reference), Some(first)) => Some(crossplay::row_name(reference, &first.name)),
        (reference, _) => reference.clone(),
    };
    let settings = Settings { reference, bootstrap: Bootstrap { reps: args.bootstrap, ..Bootstrap::default() } };
    let summaries = eval::summarise(&episodes, &settings).map_err(anyhow::Error::msg)?;
    print!("{}\n{}", eval::markdown(&summaries), budget::markdown(&budgets));
    write(&args, &summaries, &episodes, &budgets)?;
    if args.opponents {
        write_crossplay(&args, &summaries)?;
    }
    if let Some(path) = &args.league {
        join_league(&args, path, &settings, &episodes)?;
    }
    Ok(())
}

/// Adds the run to the league file at `path` (a new league if there is none) and writes
/// league.md beside it.
fn join_league(args: &EvalArgs, path: &Path, settings: &Settings, episodes: &[Episode]) -> anyhow::Result<()> {
    let run = LeagueSettings {
        scenarios: args.scenarios.clone(),
        seed: args.seed,
        episodes: args.episodes,
        max_cycles: args.max_cycles,
    };
    let mut league = match std::fs::read_to_string(path) {
        Ok(text) => League::from_json(&text).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => League::new(run.clone()),
        Err(e) => return Err(anyhow::Error::new(e).context(format!("reading {}", path.display()))),
    };
    league.add(&run, episodes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    let summaries = league.summaries(&Settings { reference: None, ..settings.clone() }).map_err(anyhow::Error::msg)?;
    let table = league_markdown(&league, &summaries, &args.rank).map_err(anyhow::Error::msg)?;
    if let Some(folder) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(folder).with_context(|| format!("creating {}", folder.display()))?;
    }
    std::fs::write(path, league.to_json()).with_context(|| format!("writing {}", path.display()))?;
    let md = path.with_file_name("league.md");
    std::fs::write(&md, table).with_context(|| format!("writing {}", md.display()))?;
    println!("league: {} and {}", path.display(), md.display());
    Ok(())
}

/// One policy on one scenario.
struct Run<'a> {
    client: &'a Client,
    server: &'a str,
    scenario: &'a str,
    name: &'a str,
    policy: Policy,
    /// Create overrides (the opponents of a cross-play cell).
    overrides: Vec<(String, String)>,
    args: &'a EvalArgs,
}

/// An env of a run with the episode it is playing.
struct Slot {
    env: Env,
    seed: u64,
    random: ChaCha8Rng,
    live: Vec<String>,
}

impl Run<'_> {
    /// Every episode of the run, in seed order, `args.batch` envs at a time, and the
    /// policy's decision time per agent and step (µs): the server's clock for a built-in
    /// driver, this process's for `idle` and `random`.
    fn episodes(&self, bar: &ProgressBar) -> anyhow::Result<(Vec<Episode>, Vec<f32>)> {
        let options = CreateOptions {
            overrides: self.overrides.iter().map(|(k, v)| (k.clone(), OptionValue::Str(v.clone()))).collect(),
            max_cycles: self.args.max_cycles,
            policy: match self.policy {
                Policy::Server(policy) => Some(policy),
                _ => None,
            },
            ..CreateOptions::default()
        };
        let count = self.args.batch.min(self.args.episodes);
        let mut envs = Vec::with_capacity(count as usize);
        for _ in 0..count {
            let source = ScenarioSource::Named(self.scenario.to_string());
            let env = self
                .client
                .create_env(self.server, source, options.clone())
                .with_context(|| format!("creating an env of scenario '{}' for policy {}", self.scenario, self.name))?;
            envs.push(env);
        }
        let (mut done, mut micros) = (Vec::new(), Vec::new());
        for first in (0..self.args.episodes).step_by(count as usize) {
            let size = count.min(self.args.episodes - first) as usize;
            let mut slots = Vec::with_capacity(size);
            for (k, env) in envs.drain(..size).enumerate() {
                slots.push(self.reset(env, self.args.seed.wrapping_add(first + k as u64))?);
            }
            done.extend(self.play(&mut slots, bar, &mut micros)?);
            envs.extend(slots.into_iter().map(|slot| slot.env));
        }
        for mut env in envs {
            if matches!(self.policy, Policy::Server(_)) {
                let statistics = env.statistics().context("asking the server what its policy's decisions cost")?;
                micros.extend(statistics.decision_micros.into_iter().flat_map(|(_, kept)| kept));
            }
            env.close()?;
        }
        done.sort_by(|a, b| (a.seed, &a.agent).cmp(&(b.seed, &b.agent)));
        Ok((done, micros))
    }

    fn reset(&self, mut env: Env, seed: u64) -> anyhow::Result<Slot> {
        let reply =
            env.reset(Some(seed), vec![]).with_context(|| format!("resetting '{}' with seed {seed}", self.scenario))?;
        let live = reply.agents.into_iter().map(|start| start.agent).collect();
        Ok(Slot { env, seed, random: ChaCha8Rng::seed_from_u64(seed), live })
    }

    /// Steps every slot's episode to its end, all in one batch per step; adds the time
    /// each client-side action took to `micros`.
    fn play(&self, slots: &mut [Slot], bar: &ProgressBar, micros: &mut Vec<f32>) -> anyhow::Result<Vec<Episode>> {
        let mut done = Vec::new();
        loop {
            let mut playing: Vec<&mut Slot> = slots.iter_mut().filter(|slot| !slot.live.is_empty()).collect();
            if playing.is_empty() {
                return Ok(done);
            }
            let actions: Vec<Vec<(String, Action)>> =
                playing.iter_mut().map(|slot| self.actions(slot, micros)).collect();
            let mut envs: Vec<&mut Env> = playing.iter_mut().map(|slot| &mut slot.env).collect();
            let replies = self.client.step_batch(&mut envs, actions)?;
            for (slot, reply) in playing.into_iter().zip(replies) {
                let reply = reply.with_context(|| {
                    format!("stepping '{}' (policy {}, seed {})", self.scenario, self.name, slot.seed)
                })?;
                for step in &reply.steps {
                    if !reply.agents.contains(&step.agent) {
                        let episode = Episode::from_info(self.name, self.scenario, slot.seed, &step.agent, &step.info)
                            .map_err(anyhow::Error::msg)?;
                        done.push(episode);
                    }
                }
                slot.live = reply.agents;
                if slot.live.is_empty() {
                    bar.inc(1);
                }
            }
        }
    }

    /// This step's actions of the slot's live agents, each timed into `micros`; none when
    /// the server drives them.
    fn actions(&self, slot: &mut Slot, micros: &mut Vec<f32>) -> Vec<(String, Action)> {
        let specs = slot.env.specs();
        let mut actions = Vec::with_capacity(slot.live.len());
        for agent in &slot.live {
            let started = Instant::now();
            let space = specs.action_spaces.iter().find(|(a, _)| a == agent).map(|(_, s)| s);
            let action = match (self.policy, space) {
                (Policy::Server(_), _) => continue,
                (Policy::Idle, Some(Space::Box { .. })) => Action::Continuous([0.0, 0.0]),
                (Policy::Idle, _) => Action::Meta(MetaAction::Idle.code()),
                (Policy::Random, Some(Space::Box { .. })) => {
                    Action::Continuous([slot.random.random_range(-1.0..=1.0), slot.random.random_range(-1.0..=1.0)])
                }
                (Policy::Random, _) => Action::Meta(slot.random.random_range(0..MetaAction::ALL.len() as u32)),
            };
            micros.push(started.elapsed().as_secs_f32() * 1e6);
            actions.push((agent.clone(), action));
        }
        actions
    }
}

/// Writes the tables and plots into `args.out`.
fn write(args: &EvalArgs, summaries: &[Summary], episodes: &[Episode], budgets: &[Budget]) -> anyhow::Result<()> {
    let out = &args.out;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let save = |file: &str, text: String| -> anyhow::Result<PathBuf> {
        let path = out.join(file);
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
        Ok(path)
    };
    save("results.md", markdown_document(args, summaries))?;
    save("budget.md", budget::markdown(budgets))?;
    save("budget.csv", budget::csv(budgets))?;
    save("results.csv", eval::csv(summaries))?;
    save("differences.csv", eval::differences_csv(summaries))?;
    save("episodes.csv", eval::episodes_csv(episodes))?;
    save("results.json", eval::json(summaries, episodes))?;
    for scenario in &args.scenarios {
        plots::costs(&out.join(format!("costs_{scenario}.png")), scenario, episodes)?;
        plots::rates(&out.join(format!("rates_{scenario}.png")), scenario, summaries)?;
    }
    println!("written: {}", written(out, &args.scenarios));
    Ok(())
}

/// crossplay.md (every matrix) and crossplay_<scenario>_<figure>.png (each as a heatmap).
fn write_crossplay(args: &EvalArgs, summaries: &[Summary]) -> anyhow::Result<()> {
    let out = &args.out;
    let text = format!(
        "# arena eval --opponents\n\n{} episodes per cell, seeds {}..{}, the same in every cell. Rows: the policy \
         evaluated; columns: who drives its opponents (the scenario's gt vehicles and gt traffic). Rates: mean \
         and 95 % Wilson interval; return: IQM and 95 % bootstrap interval.\n{}",
        args.episodes,
        args.seed,
        args.seed.wrapping_add(args.episodes - 1),
        crossplay::markdown(summaries, &args.scenarios, &args.policies)
    );
    let path = out.join("crossplay.md");
    std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    for scenario in &args.scenarios {
        for figure in crossplay::MATRIX_FIGURES {
            let png = out.join(format!("crossplay_{scenario}_{figure}.png"));
            plots::crossplay(&png, scenario, figure, &args.policies, summaries)?;
        }
    }
    println!("cross-play: {0}/crossplay.md, crossplay_<scenario>_<figure>.png", out.display());
    Ok(())
}

fn written(out: &Path, scenarios: &[String]) -> String {
    let plots = if scenarios.len() == 1 { scenarios[0].clone() } else { "<scenario>".to_string() };
    format!(
        "{0}/results.md, results.csv, differences.csv, episodes.csv, results.json, budget.md, budget.csv, \
         costs_{plots}.png, rates_{plots}.png",
        out.display()
    )
}

/// results.md: the command's settings, the table, and what each column means (the compute
/// budget, wall time of this machine, is budget.md: results.md stays the same bits for
/// the same seeds).
fn markdown_document(args: &EvalArgs, summaries: &[Summary]) -> String {
    let mut text = format!(
        "# arena eval\n\n{} episodes per policy and scenario, seeds {}..{} (the same for every policy){}.\n\n",
        args.episodes,
        args.seed,
        args.seed.wrapping_add(args.episodes - 1),
        args.max_cycles.map_or(String::new(), |n| format!(", {n} steps per episode"))
    );
    text.push_str(&eval::markdown(summaries));
    text.push_str(&format!(
        "\nRates: mean and 95 % Wilson interval. Other figures: median and interquartile mean (the mean of the \
         middle half) over the episodes where the figure applies, with 95 % percentile intervals from {} bootstrap \
         resamples (seed 0), as rliable computes them; the mean and its t interval are in results.csv and \
         results.json. \"(1 distinct)\": every episode came out the same, so there is nothing to put an \
         interval on; differences and probabilities of improvement are computed on the distinct pairs, and one \
         distinct pair gets neither an interval nor a mark. docs/evaluation.md says how to read each table.\n\n",
        args.bootstrap
    ));
    for figure in eval::FIGURES {
        text.push_str(&format!("- **{}**: {}\n", figure.heading, figure.what));
    }
    text.push_str("\nWhat each policy's decisions cost per step on this machine: budget.md and budget.csv.\n");
    text
}
