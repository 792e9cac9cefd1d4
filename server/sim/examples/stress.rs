//! The stress suite of issue 43 (docs/baselines.md, "Stress suite (issue 43)"): every
//! family of scenarios/stress/ over its seeds, 40 s an episode, the learner's car on IDM
//! (or, in the adversarial families, driven by a script that pushes the AV), and one row
//! per family of a markdown table; every episode also goes to a CSV as it ends.
//!
//! `cargo run --release -p arena-sim --example stress -- [--seeds N] [--first S] [--family NAME]... [--csv PATH]`
//!
//! `--seeds` episodes per family (default 100) from reset seed `--first` (default 0);
//! `--family` runs only the families named (repeat it; default: all); `--csv` where the
//! per-episode results go (default stress.csv); `--notes` prints what happened in each
//! episode (collisions, phantom braking, drift) as it ends. Every collision with a gt car
//! or the learner's car in it is judged by counterfactual replays (`arena_sim::verdict`,
//! issue 46); its note gives the verdict beside the responsibility rule's.

#[path = "../tests/support/highway_gt.rs"]
#[allow(dead_code)]
mod highway_gt;
// The test reads the parts the suite does not (a replay check).
#[path = "../tests/support/stress.rs"]
#[allow(dead_code)]
mod stress;

use std::io::Write;
use std::time::Instant;

use stress::{FAMILIES, Family, Summary};

/// What the command line asks for.
struct Options {
    seeds: u64,
    first: u64,
    families: Vec<&'static Family>,
    csv: String,
    notes: bool,
}

const USAGE: &str = "usage: stress [--seeds N] [--first S] [--family NAME]... [--csv PATH] [--notes]";

fn parse(args: &[String]) -> Result<Options, String> {
    let mut options = Options { seeds: 100, first: 0, families: Vec::new(), csv: "stress.csv".into(), notes: false };
    let mut args = args.iter();
    while let Some(flag) = args.next() {
        let mut value = || args.next().ok_or_else(|| format!("{flag} needs a value\n{USAGE}"));
        let number =
            |text: &str| text.parse::<u64>().map_err(|_| format!("invalid {flag} '{text}': expected a whole number"));
        match flag.as_str() {
            "--seeds" => options.seeds = number(value()?)?,
            "--first" => options.first = number(value()?)?,
            "--family" => options.families.push(stress::find_family(value()?)?),
            "--csv" => options.csv = value()?.clone(),
            "--notes" => options.notes = true,
            "--help" | "-h" => {
                println!(
                    "{USAGE}\n\nRuns the stress families of scenarios/stress/ (docs/baselines.md, \"Stress suite\")."
                );
                std::process::exit(0);
            }
            other => return Err(format!("unknown argument '{other}'\n{USAGE}")),
        }
    }
    if options.seeds == 0 {
        return Err("invalid --seeds '0': run at least one episode".into());
    }
    if options.first.checked_add(options.seeds).is_none() {
        return Err(format!("--first {} plus --seeds {} is past the last seed", options.first, options.seeds));
    }
    if options.families.is_empty() {
        options.families = FAMILIES.iter().collect();
    }
    Ok(options)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let options = parse(&args).unwrap_or_else(|message| {
        eprintln!("error: {message}");
        std::process::exit(2);
    });
    let mut csv = std::fs::File::create(&options.csv).unwrap_or_else(|e| {
        eprintln!("error: cannot write {}: {e}", options.csv);
        std::process::exit(1);
    });
    writeln!(csv, "{}", stress::CSV_HEADER).expect("write the CSV");
    let (first, last) = (options.first, options.first + options.seeds - 1);
    println!("stress suite: seeds {first}..={last} per family, {} s an episode; CSV {}", stress::SECONDS, options.csv);
    let began = Instant::now();
    let mut summaries = Vec::new();
    for &family in &options.families {
        let scenario = family.scenario();
        let mut summary = Summary::default();
        let started = Instant::now();
        for (k, seed) in (first..=last).enumerate() {
            eprint!(
                "\r{}: seed {seed} ({}/{}), {:.0} s",
                family.name,
                k + 1,
                options.seeds,
                started.elapsed().as_secs_f64()
            );
            let episode = stress::run(family, &scenario, seed);
            writeln!(csv, "{}", stress::csv_row(family, &episode)).and_then(|()| csv.flush()).expect("write the CSV");
            if options.notes {
                for note in &episode.notes {
                    eprintln!("\n  {} seed {seed}: {note}", family.name);
                }
            }
            summary.add(&episode);
        }
        eprintln!("\r{}: {} episodes in {:.0} s", family.name, options.seeds, started.elapsed().as_secs_f64());
        summaries.push((family, summary));
    }
    println!("\n{}", stress::header());
    for (family, summary) in &summaries {
        println!("{}", stress::row(family, family.density(), summary));
    }
    if let Some(merges) = stress::merge_table(&summaries) {
        println!("\n{merges}");
    }
    println!("wall time {:.0} s", began.elapsed().as_secs_f64());
}
