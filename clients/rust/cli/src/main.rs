//! `arena`: the command-line client of highway-arena.

use clap::{Parser, Subcommand};

mod bench;
mod eval;
mod paper;
mod play;
mod record;
mod soak;

/// Command-line client of highway-arena. `bench`, `eval`, `play` and `soak` talk to a running
/// `arena-server` (start one with `arena-server`); `paper` and `calibrate` run in process.
#[derive(Debug, Parser)]
#[command(name = "arena", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// On an error, print where it came from too (its backtrace, when RUST_BACKTRACE=1);
    /// RUST_LOG set does the same.
    #[arg(short, long, global = true)]
    verbose: bool,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Measure what the protocol and server add to a Zenoh round trip, and batched
    /// throughput on highway.toml.
    Bench(bench::BenchArgs),
    /// Compare policies (built-in drivers, idle, random) on scenarios over the same seeds:
    /// success, collision and off-road rates, t_c, speed, gaps, the paper's cost RMS and
    /// return, with 95 % intervals; a table, Markdown, CSV, JSON and PNG plots.
    Eval(eval::EvalArgs),
    /// Record the built-in AV driving in a learner's place as a Minari dataset (runs
    /// `python -m highway_arena.record`; `arena record -- --help` for its options).
    Record(record::RecordArgs),
    /// Many clients stepping their own envs for a while: errors, step latency and the
    /// server's memory before, during and after.
    Soak(soak::SoakArgs),
    /// Step an env with a built-in policy and watch it as text in the terminal.
    Play(play::PlayArgs),
    /// Reproduce the paper's Scenario A and B tables and plots, in process.
    Paper(paper::PaperArgs),
    /// Fit the constants the paper leaves open to its Tables IV and VI (seeded particle
    /// swarm), print every cell ours | paper, and write the fit as a parameter preset.
    Calibrate(paper::CalibrateArgs),
}

/// A client on `flags` and the server it found: within the connect timeout, or an error
/// that names the endpoints tried and what to do.
fn connect(
    flags: &arena_protocol::session::ConnectionFlags,
) -> anyhow::Result<(arena_client::blocking::Client, String)> {
    use anyhow::Context;
    use arena_protocol::session::{DEFAULT_CONNECT_TIMEOUT, Role};
    let where_ = flags.endpoints(Role::Client).join(", ");
    // A bad endpoint or an unreadable --zenoh-config is said as it is, not as a router that
    // did not answer.
    flags.zenoh_config(Role::Client).map_err(anyhow::Error::msg)?;
    let client = arena_client::blocking::Client::connect(flags).with_context(|| {
        format!(
            "cannot open a Zenoh session to {where_}: is the router running and listening there, and does \
             it ask for credentials (--zenoh-config a file with your user and password, docs/deployment.md)?"
        )
    })?;
    let server =
        client.pick_server_within(std::time::Duration::from_secs_f64(DEFAULT_CONNECT_TIMEOUT)).with_context(|| {
            format!(
                "no arena-server answered at {where_} within {DEFAULT_CONNECT_TIMEOUT} s: start one there \
                 (`arena-server --listen {where_}`), or point --connect at the endpoint yours listens on"
            )
        })?;
    Ok((client, server))
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let verbose = cli.verbose || std::env::var_os("RUST_LOG").is_some();
    match run(cli.command) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(error) => {
            report(&error, verbose);
            std::process::ExitCode::FAILURE
        }
    }
}

fn run(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Bench(args) => bench::run(args),
        Command::Eval(args) => eval::run(args),
        Command::Play(args) => play::run(args),
        Command::Record(args) => record::run(args),
        Command::Soak(args) => soak::run(args),
        Command::Paper(args) => paper::run_paper(args),
        Command::Calibrate(args) => paper::run_calibrate(args),
    }
}

/// An error and its causes; the backtrace anyhow took (with RUST_BACKTRACE=1) only when
/// asked, since it says where in our code the error arose, not what the user should do.
fn report(error: &anyhow::Error, verbose: bool) {
    if verbose {
        eprintln!("Error: {error:?}");
        return;
    }
    eprintln!("Error: {error}");
    let causes: Vec<_> = error.chain().skip(1).collect();
    if !causes.is_empty() {
        eprintln!("\nCaused by:");
        for (i, cause) in causes.iter().enumerate() {
            eprintln!("    {i}: {cause}");
        }
    }
}
