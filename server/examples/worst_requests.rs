//! The most expensive request of each kind the server's bounds admit, answered through
//! the request handler as they arrive from Zenoh: CPU seconds (every thread of the
//! process, decision pool included) and peak memory above what the process held before,
//! per request. docs/reliability.md ("Bounded cost") records its figures.
//!
//! Run: `cargo run --release -p arena-server --example worst_requests` (Linux: reads
//! /proc/self).

use std::f64::consts::PI;

use arena_protocol::{
    ClientId, CreateOptions, EnvId, OptionValue, PROTOCOL_VERSION, RenderMode, Reply, ReplyBody, Request, RequestBody,
    ResetOptions, ScenarioSource, decode, encode,
};
use arena_server::transport::{Limits, Registry, Scenarios};

const CLIENT: ClientId = ClientId(5);

fn main() {
    let start = status_kib("VmRSS:");
    let registry = Registry::new("worst".into(), Scenarios::load(None).expect("built-in scenarios"), Limits::default());
    println!("| request | CPU s | peak MiB above before | reply bytes | answer |");
    println!("|---|---:|---:|---:|---|");
    let big = render_options();
    // Steps: every vehicle the bound admits at the most ticks a step; the most
    // game-theoretic decisions a step, in a knot where every game is played.
    let crowd = worst_step(&registry, "2048 IDM vehicles, 1000 ticks and 100 periods a step", crowd(), big.clone());
    let gt_knot =
        worst_step(&registry, "64 gt cars in a knot, 5 periods a step (320 decisions)", knot(16, 0.5), big.clone());
    worst_step(&registry, "32 gt cars in a knot, 10 periods a step (320 decisions)", knot(8, 1.0), big.clone());
    // Renders at the largest frame: the zigzag road and the ring that lies over itself.
    let recorded = CreateOptions { record: true, ..big.clone() };
    for (what, text) in [("zigzag, 64 lanes", road(Road::Zigzag)), ("ring, 16 lanes", road(Road::Ring))] {
        let env = created(&registry, &format!("create: 1024-section {what} road"), text, recorded.clone());
        measure(&registry, &format!("reset with recording: {what}"), reset(env, &[]));
        measure(&registry, &format!("render 2300 x 2300: {what}"), render(env));
    }
    measure(&registry, "render 2300 x 2300: 2048 vehicles", render(crowd));
    // Snapshots of the largest world, taken and restored.
    let snapshot = match measure(&registry, "snapshot: 2048 vehicles", RequestBody::Snapshot { env: crowd }) {
        ReplyBody::Snapshot(bytes) => bytes,
        other => panic!("{other:?}"),
    };
    measure(&registry, "restore: 2048 vehicles", RequestBody::Restore { env: crowd, seq: 90, snapshot });
    let snapshot = match measure(&registry, "snapshot: 64 gt cars", RequestBody::Snapshot { env: gt_knot }) {
        ReplyBody::Snapshot(bytes) => bytes,
        other => panic!("{other:?}"),
    };
    measure(&registry, "restore: 64 gt cars", RequestBody::Restore { env: gt_knot, seq: 90, snapshot });
    // A 1 MiB file whose every [vary] draw puts a car on another.
    let env =
        created(&registry, "create: 1 MiB, 2048 cars, a [vary] that always overlaps", vary(), CreateOptions::default());
    measure(&registry, "reset: that [vary], every draw refused", reset(env, &[]));
    let kept = (status_kib("VmRSS:").saturating_sub(start)) as f64 / 1024.0;
    println!("\nresident after: {kept:.1} MiB more than at the start, for the {} envs above", registry.len());
    kept_at_most(&registry);
}

/// The most an env keeps between requests: the 1 MiB file, 64 overrides of 64 KiB at
/// create and at reset, recording on, a step's frames of 2048 vehicles in its cached reply.
fn kept_at_most(registry: &Registry) {
    let overrides: Vec<(String, OptionValue)> =
        (0..64).map(|_| ("description".to_string(), OptionValue::Str("x".repeat(64 << 10)))).collect();
    let options = CreateOptions { overrides: overrides.clone(), record: true, ..CreateOptions::default() };
    let before = status_kib("VmRSS:");
    let mut text = vary();
    text.truncate(text.find("[vary]").expect("a [vary] table"));
    while text.len() < (1 << 20) - 64 {
        text += "# padding to the inline bound\n";
    }
    let env = created(registry, "create: the env that keeps the most", text, options);
    let reset = RequestBody::Reset { env, seq: 1, seed: Some(1), options: ResetOptions { overrides } };
    measure(registry, "reset: 64 overrides of 64 KiB, recording", reset);
    measure(registry, "step: 2048 vehicles recorded", RequestBody::Step { env, seq: 2, actions: vec![] });
    let kept = (status_kib("VmRSS:").saturating_sub(before)) as f64 / 1024.0;
    println!("\nthat env keeps {kept:.1} MiB resident between requests");
}

fn render_options() -> CreateOptions {
    CreateOptions { render_size: Some((2300, 2300)), ..CreateOptions::default() }
}

fn worst_step(registry: &Registry, what: &str, text: String, options: CreateOptions) -> EnvId {
    let env = created(registry, &format!("create: {what}"), text, options);
    measure(registry, &format!("reset: {what}"), reset(env, &[]));
    for seq in 2..5 {
        measure(registry, &format!("step {}: {what}", seq - 1), RequestBody::Step { env, seq, actions: vec![] });
    }
    env
}

fn reset(env: EnvId, overrides: &[(&str, OptionValue)]) -> RequestBody {
    let overrides = overrides.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
    RequestBody::Reset { env, seq: 1, seed: Some(1), options: ResetOptions { overrides } }
}

fn render(env: EnvId) -> RequestBody {
    RequestBody::Render { env, mode: RenderMode::RgbArray, follow: None }
}

fn created(registry: &Registry, what: &str, text: String, options: CreateOptions) -> EnvId {
    let scenario = ScenarioSource::Inline { file_name: "worst.toml".into(), text };
    match measure(registry, what, RequestBody::CreateEnv { scenario, options }) {
        ReplyBody::Created { env, .. } => env,
        other => panic!("{what}: {other:?}"),
    }
}

/// Answers `body`, printing its row; returns the reply.
fn measure(registry: &Registry, what: &str, body: RequestBody) -> ReplyBody {
    let bytes = encode(&Request { version: PROTOCOL_VERSION, client: CLIENT, body });
    let (rss, cpu) = (reset_peak(), cpu_seconds());
    let answer = registry.handle(&bytes);
    let (cpu, peak) = (cpu_seconds() - cpu, peak_bytes().saturating_sub(rss));
    let reply: Reply = decode(&answer).expect("a reply");
    let shown = match &reply.body {
        ReplyBody::Error(e) => format!("{:?}: {}", e.code, e.message.chars().take(60).collect::<String>()),
        _ => "answered".to_string(),
    };
    println!("| {what} | {cpu:.3} | {:.1} | {} | {shown} |", peak as f64 / (1 << 20) as f64, answer.len());
    reply.body
}

/// User and system CPU seconds of every thread of the process.
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").expect("/proc/self/stat");
    let fields: Vec<&str> = stat.rsplit(')').next().expect("a stat line").split_whitespace().collect();
    let ticks: f64 = fields[11].parse::<f64>().expect("utime") + fields[12].parse::<f64>().expect("stime");
    ticks / 100.0
}

/// Resets the kernel's peak-RSS mark and returns the RSS now (bytes).
fn reset_peak() -> u64 {
    std::fs::write("/proc/self/clear_refs", "5").expect("clear_refs");
    status_kib("VmRSS:") * 1024
}

fn peak_bytes() -> u64 {
    status_kib("VmHWM:") * 1024
}

fn status_kib(key: &str) -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").expect("/proc/self/status");
    let line = status.lines().find(|line| line.starts_with(key)).expect("the key");
    line.split_whitespace().nth(1).and_then(|kib| kib.parse().ok()).expect("kB")
}

fn header(sim: &str, lanes: usize, sections: &str) -> String {
    let limits = vec!["30.0"; lanes].join(", ");
    format!(
        "name = \"worst\"\n[sim]\n{sim}\n[road]\nlanes = {lanes}\nlane_width = 3.5\nspeed_limits = [{limits}]\n\
         sections = [{sections}]\n[[vehicle]]\nname = \"ego\"\nlane = 0\ns = 10.0\nspeed = 20.0\n\
         driver = {{ kind = \"agent\" }}\n"
    )
}

/// 2047 IDM cars and the learner on 8 lanes, 10 s steps at 10 ms physics.
fn crowd() -> String {
    let mut text =
        header("physics_dt = 0.01\ncontrol_dt = 0.1\nstep_dt = 10.0\nmax_cycles = 10", 8, "{ length = 20000.0 }");
    text += "[traffic]\ncount = 2047\ndensity = 1.0\nspeed = [20.0, 28.0]\n";
    text
}

/// `rows` rows of four gt cars, 12 m apart, every style and both games, `step_dt` steps.
fn knot(rows: usize, step_dt: f64) -> String {
    let sim = format!("physics_dt = 0.02\nstep_dt = {step_dt}\nmax_cycles = 40");
    let mut text = header(&sim, 4, "{ length = 5000.0 }").replace("s = 10.0", "s = 30.0");
    let styles = ["aggressive", "normal", "conservative"];
    for k in 0..rows * 4 {
        let game = if k % 2 == 0 { "nash" } else { "stackelberg" };
        text += &format!(
            "[[vehicle]]\nname = \"gt{k}\"\nlane = {}\ns = {}\nspeed = {}\n\
             driver = {{ kind = \"gt\", style = \"{}\", game = \"{game}\", role = \"leader\" }}\n",
            k % 4,
            50.0 + 12.0 * (k / 4) as f64,
            22.0 + (k % 5) as f64,
            styles[k % 3],
        );
    }
    text
}

enum Road {
    Zigzag,
    Ring,
}

/// 1024 sections: arcs of alternate sides on 64 lanes, or one ring of 16 lanes passed
/// 1024 times (as long as a road may be).
fn road(shape: Road) -> String {
    let (lanes, section): (usize, Box<dyn Fn(usize) -> String>) = match shape {
        Road::Zigzag => (
            64,
            Box::new(|k: usize| {
                format!("{{ length = 400.0, radius = {} }}", if k.is_multiple_of(2) { 300.0 } else { -300.0 })
            }),
        ),
        Road::Ring => (16, Box::new(|_| format!("{{ length = {}, radius = 150.0 }}", 2.0 * PI * 150.0))),
    };
    let sections: Vec<String> = (0..1024).map(section).collect();
    header("step_dt = 0.1", lanes, &sections.join(", "))
}

/// 2047 cars in a 1 MiB file whose [vary] puts the last on the one a row behind it.
fn vary() -> String {
    let mut text = header("step_dt = 0.1", 8, "{ length = 20000.0 }");
    for k in 0..2047 {
        text += &format!(
            "[[vehicle]]\nname = \"c{k}\"\nlane = {}\ns = {}\nspeed = 20.0\ndriver = {{ kind = \"idm\" }}\n",
            k % 8,
            40.0 + 9.0 * (k / 8) as f64
        );
    }
    // c2038 is in c2046's lane, a row behind it.
    let at = 40.0 + 9.0 * (2038 / 8) as f64;
    text += &format!("[vary]\n\"vehicle.c2046.s\" = {{ range = [{at}, {at}] }}\n");
    while text.len() < (1 << 20) - 64 {
        text += "# padding to the inline bound\n";
    }
    text
}
