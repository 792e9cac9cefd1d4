//! `arena paper` and `arena calibrate` without the CLI (and so without Zenoh): the same
//! argument structs and functions, for a quick build while working on the fit.
//!
//! ```sh
//! cargo run --release -p arena-paper --example paper -- calibrate --on A
//! cargo run --release -p arena-paper --example paper -- paper --params paper-fit
//! ```

use clap::Parser;

/// The paper's runs and the fit of its open constants, in process.
#[derive(Debug, Parser)]
enum Command {
    /// Reproduce the paper's Scenario A and B tables and plots (as `arena paper`).
    Paper(arena_paper::report::PaperArgs),
    /// Fit the paper's open constants to Tables IV and VI (as `arena calibrate`).
    Calibrate(arena_paper::calibrate::CalibrateArgs),
}

fn main() -> anyhow::Result<()> {
    match Command::parse() {
        Command::Paper(args) => arena_paper::report::run(args),
        Command::Calibrate(args) => arena_paper::calibrate::run(args),
    }
}
