//! `arena paper` and `arena calibrate`: their flags. The runs themselves live in
//! `arena-paper` (in process, no server), which takes the plain configs these convert to;
//! each default is the library's own (`ReportConfig::default`, `CalibrateConfig::default`).

use std::path::PathBuf;

use arena_paper::calibrate::CalibrateConfig;
use arena_paper::report::ReportConfig;

/// Arguments of `arena paper` (its help line is in main.rs).
#[derive(Debug, clap::Args)]
pub struct PaperArgs {
    /// Also write every figure of the tables as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Folder for the PNG plots (created if missing).
    #[arg(long, default_value_os_t = ReportConfig::default().out)]
    out: PathBuf,
    /// Parameter preset of every game-theoretic car: a built-in name (default,
    /// paper-fit) or a .toml file, such as one `arena calibrate` wrote.
    #[arg(long, default_value_t = ReportConfig::default().params)]
    params: String,
    /// Relative tolerance on the Stackelberg follower set of eq. (17b), if not the
    /// preset's (0 is eq. 17b exactly).
    #[arg(long)]
    follower_tolerance: Option<f64>,
}

/// Runs `arena paper`.
pub fn run_paper(args: PaperArgs) -> anyhow::Result<()> {
    let PaperArgs { json, out, params, follower_tolerance } = args;
    arena_paper::report::run(ReportConfig { json, out, params, follower_tolerance })
}

/// Arguments of `arena calibrate`.
#[derive(Debug, clap::Args)]
pub struct CalibrateArgs {
    /// Which table to fit: A (Table IV), B (Table VI) or both (jointly). The other is
    /// printed as held out.
    #[arg(long, default_value_t = CalibrateConfig::default().on, value_parser = ["A", "B", "both"])]
    on: String,
    /// Seed of the swarm: the same seed gives the same fit.
    #[arg(long, default_value_t = CalibrateConfig::default().seed)]
    seed: u64,
    /// Particles of the swarm.
    #[arg(long, default_value_t = CalibrateConfig::default().particles)]
    particles: usize,
    /// Swarm iterations of the last fit (each evaluates every particle: 12 runs for --on
    /// both, 6 for A or B).
    #[arg(long, default_value_t = CalibrateConfig::default().iterations)]
    iterations: u64,
    /// With --on both: swarm iterations of a fit of each table alone, run first (the
    /// other table held out) to seed the joint swarm; 0 (the default) skips them: in our
    /// runs the seeded joint fits put fewer cells in the ±30 % band (docs/paper-reproduction.md).
    #[arg(long, default_value_t = CalibrateConfig::default().held_out_iterations)]
    held_out_iterations: u64,
    /// Spread of the initial swarm around the start, as a share of each knob's range.
    #[arg(long, default_value_t = CalibrateConfig::default().spread)]
    spread: f64,
    /// Threads evaluating candidates (the fit does not depend on it).
    #[arg(long, default_value_t = CalibrateConfig::default().jobs)]
    jobs: usize,
    /// Start from this preset (a built-in name or a .toml file) instead of the defaults.
    #[arg(long, default_value_t = CalibrateConfig::default().from)]
    from: String,
    /// Knobs to fit (comma-separated); by default all but the adjacent cars' style.
    /// `--knobs list` prints them.
    #[arg(long, value_delimiter = ',')]
    knobs: Vec<String>,
    /// Name of the preset written.
    #[arg(long, default_value_t = CalibrateConfig::default().name)]
    name: String,
    /// Folder the preset is written to, as NAME.toml (created if missing).
    #[arg(long, default_value_os_t = CalibrateConfig::default().out)]
    out: PathBuf,
}

/// Runs `arena calibrate`.
pub fn run_calibrate(args: CalibrateArgs) -> anyhow::Result<()> {
    let CalibrateArgs { on, seed, particles, iterations, held_out_iterations, spread, jobs, from, knobs, name, out } =
        args;
    arena_paper::calibrate::run(CalibrateConfig {
        on,
        seed,
        particles,
        iterations,
        held_out_iterations,
        spread,
        jobs,
        from,
        knobs,
        name,
        out,
    })
}
