//! `arena paper` without the CLI (which links the Zenoh client): the same library call,
//! `arena_paper::report::run`, printing Tables IV–VII and drawing the plots.
//!
//! `cargo run --release -p arena-paper --example report [-- PRESET [OUT [TOLERANCE]]]`
//! (defaults: `default`, `out/paper`, the preset's follower tolerance; `arena paper
//! --params PRESET --out OUT --follower-tolerance TOLERANCE`)

use arena_paper::report::{self, ReportConfig};

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let mut config = ReportConfig::default();
    if let Some(params) = args.next() {
        config.params = params;
    }
    if let Some(out) = args.next() {
        config.out = out.into();
    }
    if let Some(tolerance) = args.next() {
        config.follower_tolerance = Some(tolerance.parse()?);
    }
    report::run(config)
}
