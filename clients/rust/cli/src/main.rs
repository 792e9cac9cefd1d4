//! `arena`: the command-line client of highway-arena.

use clap::{Parser, Subcommand};

mod bench;
mod play;

/// Command-line client of highway-arena. `bench` and `play` talk to a running
/// `arena-server` (start one with `arena-server`); `paper` runs in process.
#[derive(Debug, Parser)]
#[command(name = "arena", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Measure what the protocol and server add to a Zenoh round trip, and batched
    /// throughput on highway.toml.
    Bench(bench::BenchArgs),
    /// Step an env with a built-in policy and watch it as text in the terminal.
    Play(play::PlayArgs),
    /// Reproduce the paper's Scenario A and B tables and plots, in process.
    Paper(arena_paper::report::PaperArgs),
}

fn main() -> anyhow::Result<()> {
    match Cli::parse().command {
        Command::Bench(args) => bench::run(args),
        Command::Play(args) => play::run(args),
        Command::Paper(args) => arena_paper::report::run(args),
    }
}
