//! `arena record`: expert datasets are Minari datasets, and Minari is a Python library,
//! so this runs the Python package's recorder (`python -m highway_arena.record`) with the
//! same arguments rather than writing Minari's storage format a second time in Rust.

use anyhow::Context;

/// Arguments of `arena record`: everything after it goes to the recorder.
#[derive(Debug, clap::Args)]
pub struct RecordArgs {
    /// The recorder's arguments: SCENARIO [--episodes N] [--expert gt:<style>:<game>]
    /// [--seed S] [--connect ENDPOINT | --launch] ...; `arena record -- --help` lists them.
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    args: Vec<String>,
}

/// Runs the recorder with the Python of $PYTHON, else `python3`.
pub fn run(args: RecordArgs) -> anyhow::Result<()> {
    let python = std::env::var("PYTHON").unwrap_or_else(|_| "python3".to_string());
    let status = std::process::Command::new(&python)
        .args(["-m", "highway_arena.record"])
        .args(&args.args)
        .status()
        .with_context(|| format!("cannot run {python}: set $PYTHON to the Python that has highway_arena installed"))?;
    match status.code() {
        Some(0) => Ok(()),
        Some(1) if probe_missing(&python) => anyhow::bail!(
            "{python} has no highway_arena package: install it (clients/python/README.md, with the `datasets` \
             extra), or set $PYTHON to the Python that has it"
        ),
        Some(code) => anyhow::bail!(
            "the recorder ({python} -m highway_arena.record) stopped with exit {code}; its message is above"
        ),
        None => anyhow::bail!("the recorder ({python} -m highway_arena.record) was stopped by a signal"),
    }
}

fn probe_missing(python: &str) -> bool {
    let probe = std::process::Command::new(python).args(["-c", "import highway_arena.datasets"]).output();
    probe.is_ok_and(|out| !out.status.success())
}
