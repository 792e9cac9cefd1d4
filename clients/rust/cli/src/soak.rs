//! `arena soak`: many clients, each on its own Zenoh session, stepping their own envs
//! for a while: errors, step latency (p50, p99) and the server's memory before, during
//! and after, so a server a lab leaves running can be checked for leaks and stalls.
//! With `--attackers`, other sessions keep the server busy with the most expensive
//! requests a client may send beside them: what one busy client costs the others.

use std::time::{Duration, Instant};

use anyhow::Context;
use arena_client::{Client, CreateOptions, ScenarioSource};
use arena_protocol::ServerInfo;
use arena_protocol::session::{ConnectionFlags, DEFAULT_CONNECT_TIMEOUT, Role};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

/// The most clients one soak opens: each is a Zenoh session with its own sockets.
const MAX_CLIENTS: usize = 1024;
/// Requests each attacker keeps in flight.
const ATTACK_IN_FLIGHT: usize = 4;
/// The attackers' frames: the largest a reply carries.
const ATTACK_FRAME: (u32, u32) = (2300, 2300);

/// Arguments of `arena soak`.
#[derive(Debug, clap::Args)]
pub struct SoakArgs {
    #[command(flatten)]
    connection: ConnectionFlags,
    /// Clients, each with its own Zenoh session and env.
    #[arg(long, default_value_t = 64)]
    clients: usize,
    /// Seconds of stepping.
    #[arg(long, default_value_t = 60.0)]
    seconds: f64,
    /// Scenario each client steps (an episode that ends is reset).
    #[arg(long, default_value = "merge-random")]
    scenario: String,
    /// Seconds to wait after the clients leave before reading the server's memory "after"
    /// (Zenoh's idle connection threads exit about 10 s after a burst of clients).
    #[arg(long, default_value_t = 15.0, value_name = "SECONDS")]
    settle: f64,
    /// Sessions that keep the server busy beside the clients, each with
    /// `ATTACK_IN_FLIGHT` expensive requests in flight: the --attack-scenario reset,
    /// stepped and rendered at the largest frame, over and over.
    #[arg(long, default_value_t = 0)]
    attackers: usize,
    /// The scenario file the attackers send inline.
    #[arg(long, default_value = "scenarios/stress/knot-32.toml", value_name = "FILE")]
    attack_scenario: std::path::PathBuf,
    /// Print the figures as one JSON object instead of a table.
    #[arg(long)]
    json: bool,
}

/// What one client saw.
#[derive(Debug, Default)]
struct ClientRun {
    latencies: Vec<Duration>,
    errors: Vec<String>,
}

#[derive(Debug, Serialize)]
struct Figures {
    clients: usize,
    attackers: usize,
    attack_requests: usize,
    seconds: f64,
    steps: usize,
    errors: usize,
    first_errors: Vec<String>,
    steps_per_s: f64,
    step_p50_us: f64,
    step_p99_us: f64,
    rss_before_mib: f64,
    rss_peak_mib: f64,
    rss_after_mib: f64,
    envs_after: u32,
}

/// Runs `arena soak`.
pub fn run(args: SoakArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        (1..=MAX_CLIENTS).contains(&args.clients),
        "--clients must be within 1..={MAX_CLIENTS} (each opens its own Zenoh session), not {}",
        args.clients
    );
    anyhow::ensure!(args.seconds.is_finite() && args.seconds > 0.0, "--seconds must be a positive number");
    anyhow::ensure!(
        args.settle.is_finite() && (0.0..=3600.0).contains(&args.settle),
        "--settle must be between 0 and 3600 seconds"
    );
    anyhow::ensure!(args.attackers <= 64, "--attackers must be at most 64, not {}", args.attackers);
    let runtime = tokio::runtime::Runtime::new().context("cannot start the tokio runtime")?;
    let figures = runtime.block_on(soak(&args))?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&figures)?);
    } else {
        print_table(&figures);
    }
    anyhow::ensure!(
        figures.errors == 0,
        "{} of {} steps failed: {:?}",
        figures.errors,
        figures.steps,
        figures.first_errors
    );
    Ok(())
}

async fn soak(args: &SoakArgs) -> anyhow::Result<Figures> {
    let watcher = Client::connect(&args.connection).await.context("opening the Zenoh session")?;
    let server =
        watcher.pick_server_within(Duration::from_secs_f64(DEFAULT_CONNECT_TIMEOUT)).await.with_context(|| {
            format!("no arena-server answered at {}", args.connection.endpoints(Role::Client).join(", "))
        })?;
    let before = watcher.server_info(&server).await?;
    let deadline = Instant::now() + Duration::from_secs_f64(args.seconds);
    let attack = if args.attackers > 0 {
        std::fs::read_to_string(&args.attack_scenario)
            .with_context(|| format!("reading --attack-scenario {}", args.attack_scenario.display()))?
    } else {
        String::new()
    };
    let mut attackers = Vec::with_capacity(args.attackers * ATTACK_IN_FLIGHT);
    for k in 0..args.attackers {
        let client = Client::connect(&args.connection).await.context("opening an attacker's Zenoh session")?;
        for slot in 0..ATTACK_IN_FLIGHT {
            let (client, server, text) = (client.clone(), server.clone(), attack.clone());
            let seed = (k * ATTACK_IN_FLIGHT + slot) as u64;
            attackers.push(tokio::spawn(async move { attack_until(client, server, text, seed, deadline).await }));
        }
    }
    let mut tasks = Vec::with_capacity(args.clients);
    for k in 0..args.clients {
        let (flags, server, scenario) = (args.connection.clone(), server.clone(), args.scenario.clone());
        tasks.push(tokio::spawn(async move { step_until(flags, server, scenario, k as u64, deadline).await }));
    }
    let bar = ProgressBar::new(args.seconds.ceil() as u64).with_style(
        ProgressStyle::with_template("soak [{bar:30}] {pos}/{len} s, server RSS {msg}")
            .map_err(|e| anyhow::anyhow!("progress bar template: {e}"))?
            .progress_chars("=> "),
    );
    let mut peak = before.rss_bytes;
    while Instant::now() < deadline {
        tokio::time::sleep(Duration::from_secs(1).min(deadline.saturating_duration_since(Instant::now()))).await;
        if let Ok(info) = watcher.server_info(&server).await {
            peak = peak.max(info.rss_bytes);
            bar.set_message(format!("{:.1} MiB, {} envs", mib(info.rss_bytes), info.envs));
        }
        bar.inc(1);
    }
    let mut runs = Vec::with_capacity(tasks.len());
    for task in tasks {
        runs.push(task.await.context("a client task")?);
    }
    let mut attack_requests = 0;
    for attacker in attackers {
        attack_requests += attacker.await.context("an attacker task")?;
    }
    bar.finish_and_clear();
    // The server closes the envs of clients that closed and hands memory back once the
    // connection threads have gone.
    tokio::time::sleep(Duration::from_secs_f64(args.settle)).await;
    let after = watcher.server_info(&server).await?;
    watcher.close().await?;
    Ok(figures(args, &runs, attack_requests, &before, peak, &after))
}

/// One attacker's request stream until `deadline`: creates an env of `text` (sent
/// inline), then resets, steps and renders it at `ATTACK_FRAME`; returns how many
/// requests were answered (refusals included: they cost the server too).
async fn attack_until(client: Client, server: String, text: String, seed: u64, deadline: Instant) -> usize {
    let scenario = ScenarioSource::Inline { file_name: "attack.toml".into(), text };
    let options = CreateOptions { render_size: Some(ATTACK_FRAME), ..CreateOptions::default() };
    let Ok(mut env) = client.create_env(&server, scenario, options).await else { return 0 };
    let mut answered = 1;
    while Instant::now() < deadline {
        let _ = env.reset(Some(seed), vec![]).await;
        let _ = env.step(vec![]).await;
        let _ = env.render(arena_protocol::RenderMode::RgbArray, None).await;
        answered += 3;
    }
    let _ = env.close().await;
    answered
}

/// One client: its own session and env, stepping until `deadline`.
async fn step_until(
    flags: ConnectionFlags,
    server: String,
    scenario: String,
    seed: u64,
    deadline: Instant,
) -> ClientRun {
    let mut run = ClientRun::default();
    let client = match Client::connect(&flags).await {
        Ok(client) => client,
        Err(e) => {
            run.errors.push(format!("connect: {e}"));
            return run;
        }
    };
    match client.create_env(&server, ScenarioSource::Named(scenario), CreateOptions::default()).await {
        Ok(mut env) => {
            let mut live = false;
            while Instant::now() < deadline {
                if !live {
                    match env.reset(Some(seed), vec![]).await {
                        Ok(_) => live = true,
                        Err(e) => run.errors.push(format!("reset: {e}")),
                    }
                    continue;
                }
                let started = Instant::now();
                match env.step(vec![]).await {
                    Ok(reply) => {
                        run.latencies.push(started.elapsed());
                        live = !reply.agents.is_empty();
                    }
                    Err(e) => run.errors.push(format!("step: {e}")),
                }
            }
            if let Err(e) = env.close().await {
                run.errors.push(format!("close: {e}"));
            }
        }
        Err(e) => run.errors.push(format!("create: {e}")),
    }
    if let Err(e) = client.close().await {
        run.errors.push(format!("client close: {e}"));
    }
    run
}

fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1024.0 * 1024.0)
}

fn figures(
    args: &SoakArgs,
    runs: &[ClientRun],
    attack_requests: usize,
    before: &ServerInfo,
    peak: u64,
    after: &ServerInfo,
) -> Figures {
    let mut latencies: Vec<Duration> = runs.iter().flat_map(|r| r.latencies.iter().copied()).collect();
    latencies.sort();
    let percentile = |p: f64| {
        let index = ((latencies.len() as f64 - 1.0) * p).round() as usize;
        latencies.get(index).map_or(f64::NAN, |d| d.as_secs_f64() * 1e6)
    };
    let errors: Vec<&String> = runs.iter().flat_map(|r| &r.errors).collect();
    Figures {
        clients: args.clients,
        attackers: args.attackers,
        attack_requests,
        seconds: args.seconds,
        steps: latencies.len(),
        errors: errors.len(),
        first_errors: errors.iter().take(5).map(|e| e.to_string()).collect(),
        steps_per_s: latencies.len() as f64 / args.seconds,
        step_p50_us: percentile(0.5),
        step_p99_us: percentile(0.99),
        rss_before_mib: mib(before.rss_bytes),
        rss_peak_mib: mib(peak),
        rss_after_mib: mib(after.rss_bytes),
        envs_after: after.envs,
    }
}

fn print_table(f: &Figures) {
    println!(
        "| clients | attackers (requests) | seconds | steps | errors | steps/s | step p50 | step p99 | RSS before | peak | \
         after | envs after |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    println!(
        "| {} | {} ({}) | {:.0} | {} | {} | {:.0} | {:.0} µs | {:.0} µs | {:.1} MiB | {:.1} MiB | {:.1} MiB | {} |",
        f.clients,
        f.attackers,
        f.attack_requests,
        f.seconds,
        f.steps,
        f.errors,
        f.steps_per_s,
        f.step_p50_us,
        f.step_p99_us,
        f.rss_before_mib,
        f.rss_peak_mib,
        f.rss_after_mib,
        f.envs_after
    );
    for error in &f.first_errors {
        println!("error: {error}");
    }
}
