//! `arena bench`: what the protocol and the server add to a bare Zenoh round trip, and
//! how many env steps a batch gets through.
//!
//! 1. Round trips on merge.toml (its adjacent car driven by IDM, so a world step costs
//!    microseconds): a step, and a raw Zenoh get on the server's echo key with the same
//!    request and reply sizes, interleaved so both see the same conditions.
//! 2. The same single steps while a second client steps a 64-env batch in a loop on the
//!    same server: a big batch must not hold up another client's steps.
//! 3. Batched throughput on highway.toml for 1, 16 and 64 envs: env-steps per second
//!    and simulated seconds per wall second.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use arena_client::blocking::{Client, Env};
use arena_client::{Action, CreateOptions, ScenarioSource};
use arena_protocol::session::ConnectionFlags;
use arena_protocol::{
    ClientId, EnvId, MetaAction, OptionValue, PROTOCOL_VERSION, Reply, ReplyBody, Request, RequestBody, encode,
};
use serde::Serialize;

/// Arguments of `arena bench`.
#[derive(Debug, clap::Args)]
pub struct BenchArgs {
    #[command(flatten)]
    connection: ConnectionFlags,
    /// Round trips of each kind to time.
    #[arg(long, default_value_t = 2000)]
    round_trips: usize,
    /// Seconds of batched stepping per batch size.
    #[arg(long, default_value_t = 5.0)]
    batch_seconds: f64,
    /// Batch sizes to measure.
    #[arg(long, value_delimiter = ',', default_value = "1,16,64")]
    batches: Vec<usize>,
    /// Numbers of open highway.toml envs (reset, 50 vehicles each) at which to read the
    /// server's resident memory. Past 256 the server needs a higher
    /// `--max-envs-per-client`.
    #[arg(long, value_delimiter = ',', default_value = "1,100")]
    memory_envs: Vec<usize>,
    /// Print the figures as one JSON object instead of a table.
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Serialize)]
struct BatchFigures {
    envs: usize,
    /// How many servers the envs were spread over.
    servers: usize,
    env_steps_per_s: f64,
    sim_seconds_per_s: f64,
}

#[derive(Debug, Serialize)]
struct MemoryFigures {
    envs: usize,
    rss_mib: f64,
    kib_per_env: f64,
}

#[derive(Debug, Serialize)]
struct Figures {
    server: String,
    step_request_bytes: usize,
    step_reply_bytes: usize,
    raw_get_p50_us: f64,
    raw_get_p99_us: f64,
    step_p50_us: f64,
    step_p99_us: f64,
    ratio_p50: f64,
    /// Single steps while another client steps `LOAD_BATCH` envs in a loop.
    loaded_step_p50_us: f64,
    loaded_step_p99_us: f64,
    /// loaded_step_p99_us / step_p99_us (target <= 2).
    loaded_ratio_p99: f64,
    batch: Vec<BatchFigures>,
    memory: Vec<MemoryFigures>,
}

fn percentile(sorted: &[Duration], p: f64) -> f64 {
    let index = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted.get(index).map_or(f64::NAN, |d| d.as_secs_f64() * 1e6)
}

fn progress(json: bool, message: &str) {
    if !json {
        eprintln!("{message}");
    }
}

/// Runs `arena bench`.
pub fn run(args: BenchArgs) -> anyhow::Result<()> {
    if args.round_trips == 0 || !(args.batch_seconds.is_finite() && args.batch_seconds > 0.0) {
        anyhow::bail!("--round-trips must be at least 1 and --batch-seconds positive");
    }
    if args.batches.contains(&0) {
        anyhow::bail!("--batches: every batch size must be at least 1, e.g. --batches 1,16,64");
    }
    let (client, server) = crate::connect(&args.connection)?;
    progress(
        args.json,
        &format!("server {server}: timing {} step and raw round trips on merge.toml", args.round_trips),
    );

    // merge.toml's AC is a game-theoretic follower; its decisions would be timed too.
    let idm_ac = CreateOptions {
        overrides: vec![("vehicle.ac.driver".into(), OptionValue::Str(r#"{ kind = "idm", style = "normal" }"#.into()))],
        ..CreateOptions::default()
    };
    let mut env = client.create_env(&server, ScenarioSource::Named("merge".into()), idm_ac)?;
    env.reset(Some(0), vec![])?;
    let actions = vec![("ec_0".to_string(), Action::Meta(MetaAction::Idle.code()))];
    let sample = env.step(actions.clone())?;
    let request_bytes = encode(&Request {
        version: PROTOCOL_VERSION,
        client: ClientId(u128::MAX),
        body: RequestBody::Step { env: EnvId(u128::MAX), seq: u64::MAX / 2, actions: actions.clone() },
    })
    .len();
    let reply_bytes = encode(&Reply { version: PROTOCOL_VERSION, body: ReplyBody::Step(sample) }).len();

    let (mut steps, mut raws) = (Vec::with_capacity(args.round_trips), Vec::with_capacity(args.round_trips));
    for k in 0..args.round_trips {
        steps.push(timed_step(&mut env, &actions, k)?);
        raws.push(client.block_on(client.inner().echo(&server, request_bytes, reply_bytes as u32))?);
        if !args.json && (k + 1) % 500 == 0 {
            eprintln!("  {}/{}", k + 1, args.round_trips);
        }
    }
    steps.sort();
    raws.sort();

    progress(args.json, &format!("the same steps while another client steps {LOAD_BATCH} envs per batch in a loop"));
    let loaded = steps_under_batch_load(&args, &server, &mut env, &actions)?;
    env.close()?;

    let mut batch = Vec::new();
    for &size in &args.batches {
        progress(args.json, &format!("batch of {size} highway.toml envs for {} s", args.batch_seconds));
        batch.push(measure_batch(&client, size, args.batch_seconds)?);
    }

    let memory = measure_memory(&client, &server, &args.memory_envs, args.json)?;
    let figures = Figures {
        server,
        step_request_bytes: request_bytes,
        step_reply_bytes: reply_bytes,
        raw_get_p50_us: percentile(&raws, 0.5),
        raw_get_p99_us: percentile(&raws, 0.99),
        step_p50_us: percentile(&steps, 0.5),
        step_p99_us: percentile(&steps, 0.99),
        ratio_p50: percentile(&steps, 0.5) / percentile(&raws, 0.5),
        loaded_step_p50_us: percentile(&loaded, 0.5),
        loaded_step_p99_us: percentile(&loaded, 0.99),
        loaded_ratio_p99: percentile(&loaded, 0.99) / percentile(&steps, 0.99),
        batch,
        memory,
    };
    client.close()?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&figures)?);
    } else {
        println!("step request {} B, step reply {} B", figures.step_request_bytes, figures.step_reply_bytes);
        println!("raw Zenoh get   p50 {:8.1} us   p99 {:8.1} us", figures.raw_get_p50_us, figures.raw_get_p99_us);
        println!("step round trip p50 {:8.1} us   p99 {:8.1} us", figures.step_p50_us, figures.step_p99_us);
        println!("ratio (p50)     {:.3}  (target <= 1.25)", figures.ratio_p50);
        println!(
            "step beside a {LOAD_BATCH}-env batch loop: p50 {:8.1} us   p99 {:8.1} us   p99 ratio {:.2} (target <= 2)",
            figures.loaded_step_p50_us, figures.loaded_step_p99_us, figures.loaded_ratio_p99
        );
        for b in &figures.batch {
            println!(
                "batch {:3} envs on {} server(s): {:9.1} env-steps/s, {:9.1} simulated s per wall s",
                b.envs, b.servers, b.env_steps_per_s, b.sim_seconds_per_s
            );
        }
        for m in &figures.memory {
            println!("{:5} envs open: server RSS {:8.1} MiB, {:7.1} KiB per env", m.envs, m.rss_mib, m.kib_per_env);
        }
    }
    Ok(())
}

/// Envs per batch of the concurrent load in `steps_under_batch_load`.
const LOAD_BATCH: usize = 64;

/// One timed step of `env`; an episode that ended is reset, untimed.
fn timed_step(env: &mut Env, actions: &[(String, Action)], k: usize) -> anyhow::Result<Duration> {
    let clock = Instant::now();
    let reply = env.step(actions.to_vec())?;
    let elapsed = clock.elapsed();
    if reply.agents.is_empty() {
        env.reset(Some(k as u64), vec![])?;
    }
    Ok(elapsed)
}

/// Single step round trips of `env` while a second client, on its own session, steps
/// `LOAD_BATCH` highway.toml envs of the same server in a loop.
fn steps_under_batch_load(
    args: &BenchArgs,
    server: &str,
    env: &mut Env,
    actions: &[(String, Action)],
) -> anyhow::Result<Vec<Duration>> {
    let stop = Arc::new(AtomicBool::new(false));
    let (ready, started) = std::sync::mpsc::channel();
    let load = {
        let (stop, flags, server) = (Arc::clone(&stop), args.connection.clone(), server.to_string());
        std::thread::spawn(move || batch_loop(&flags, &server, &stop, ready))
    };
    if started.recv().is_err() {
        // The loop ended before its first batch: its error says why.
        load.join().map_err(|_| anyhow::anyhow!("the batch loop panicked"))??;
        anyhow::bail!("the batch loop stopped before stepping");
    }
    let mut times = Vec::with_capacity(args.round_trips);
    for k in 0..args.round_trips {
        times.push(timed_step(env, actions, k)?);
    }
    stop.store(true, Ordering::Relaxed);
    load.join().map_err(|_| anyhow::anyhow!("the batch loop panicked"))??;
    times.sort();
    Ok(times)
}

/// Steps `LOAD_BATCH` envs per round trip until `stop`; says `ready` after the first.
fn batch_loop(
    flags: &ConnectionFlags,
    server: &str,
    stop: &AtomicBool,
    ready: std::sync::mpsc::Sender<()>,
) -> anyhow::Result<()> {
    let (other, _) = crate::connect(flags)?;
    let mut envs = Vec::with_capacity(LOAD_BATCH);
    for seed in 0..LOAD_BATCH {
        let mut env = other.create_env(server, ScenarioSource::Named("highway".into()), CreateOptions::default())?;
        env.reset(Some(seed as u64), vec![])?;
        envs.push(env);
    }
    let agent = envs[0].specs().possible_agents.first().cloned().unwrap_or_default();
    while !stop.load(Ordering::Relaxed) {
        let actions = (0..LOAD_BATCH).map(|_| vec![(agent.clone(), Action::Meta(MetaAction::Idle.code()))]).collect();
        let mut handles: Vec<&mut Env> = envs.iter_mut().collect();
        let results = other.step_batch(&mut handles, actions)?;
        for (k, result) in results.into_iter().enumerate() {
            if result?.agents.is_empty() {
                envs[k].reset(None, vec![])?;
            }
        }
        let _ = ready.send(());
    }
    for env in &mut envs {
        env.close()?;
    }
    other.close()?;
    Ok(())
}

/// The server's resident memory with each number of reset highway.toml envs open, and
/// the growth per env over its memory before any was opened.
fn measure_memory(client: &Client, server: &str, counts: &[usize], json: bool) -> anyhow::Result<Vec<MemoryFigures>> {
    let rss = || -> anyhow::Result<u64> { Ok(client.server_info(server)?.rss_bytes) };
    let baseline = rss()?;
    let mut envs: Vec<Env> = Vec::new();
    let mut figures = Vec::with_capacity(counts.len());
    for &count in counts {
        progress(json, &format!("opening highway.toml envs up to {count}"));
        while envs.len() < count {
            let mut env =
                client.create_env(server, ScenarioSource::Named("highway".into()), CreateOptions::default())?;
            env.reset(Some(envs.len() as u64), vec![])?;
            envs.push(env);
        }
        let now = rss()?;
        let per_env = now.saturating_sub(baseline) as f64 / count.max(1) as f64 / 1024.0;
        figures.push(MemoryFigures { envs: count, rss_mib: now as f64 / (1024.0 * 1024.0), kib_per_env: per_env });
    }
    for env in &mut envs {
        env.close()?;
    }
    Ok(figures)
}

fn measure_batch(client: &Client, size: usize, seconds: f64) -> anyhow::Result<BatchFigures> {
    let mut envs: Vec<Env> = Vec::with_capacity(size);
    // Spread over every server found (through a router, all of a site's), as a vector env does.
    let mut servers = client.place(size)?;
    for (seed, server) in servers.iter().enumerate() {
        let mut env = client.create_env(server, ScenarioSource::Named("highway".into()), CreateOptions::default())?;
        env.reset(Some(seed as u64), vec![])?;
        envs.push(env);
    }
    let dt = envs[0].specs().dt;
    let agent = envs[0].specs().possible_agents.first().cloned().unwrap_or_default();
    let (mut stepped, mut rounds) = (0usize, 0u64);
    let clock = Instant::now();
    while clock.elapsed().as_secs_f64() < seconds {
        let actions = (0..size).map(|_| vec![(agent.clone(), Action::Meta(MetaAction::Idle.code()))]).collect();
        let mut handles: Vec<&mut Env> = envs.iter_mut().collect();
        let results = client.step_batch(&mut handles, actions)?;
        rounds += 1;
        for (k, result) in results.into_iter().enumerate() {
            let reply = result?;
            stepped += 1;
            if reply.agents.is_empty() {
                envs[k].reset(Some(rounds * size as u64 + k as u64), vec![])?;
            }
        }
    }
    let elapsed = clock.elapsed().as_secs_f64();
    for env in &mut envs {
        env.close()?;
    }
    let rate = stepped as f64 / elapsed;
    servers.sort();
    servers.dedup();
    Ok(BatchFigures { envs: size, servers: servers.len(), env_steps_per_s: rate, sim_seconds_per_s: rate * dt })
}
