//! The AV's jerk in the paper's twelve runs (issue 24, docs/design.md, "Jerk"): per run,
//! EC's commanded jerk between control periods and its model's longitudinal jerk per
//! physics step, p95 and max of their magnitudes, and the exempt commands; then per style
//! over both scenarios and games. `--off` runs the AV without the jerk bound (before
//! issue 24).
//!
//! `cargo run --release -p arena-paper --example jerk [-- --off] [--csv FILE]`: `--csv` also
//! writes the per-style summary (`style,commanded_p95,commanded_max,per_step_p95,
//! per_step_max`), from which docs/paper-reproduction.md's jerk table is rendered.

use arena_paper::{PaperOptions, PaperScenario};
use arena_sim::analysis::{JerkSummary, commanded_jerk, longitudinal_jerk};
use arena_sim::{Driver, Game, Style};

/// EC's commanded jerks, its per-step jerks and its exempt commands (aborts, emergencies)
/// over one run.
fn run(scenario: PaperScenario, style: Style, game: Game, options: &PaperOptions) -> (Vec<f64>, Vec<f64>, u32, u32) {
    let mut world = arena_paper::world(scenario, style, game, options).expect("the paper's scenarios build");
    let ec = world.find("ec_0").expect("EC is ec_0");
    let substeps = world.params().substeps_per_control();
    let (control_dt, physics_dt) = (world.params().control_dt, world.params().physics_dt);
    let periods = (scenario.duration() / control_dt).round() as usize;
    let (mut commanded, mut per_step) = (Vec::new(), Vec::new());
    let (mut command, mut accel) = (world.vehicle(ec).command.accel, None);
    let mut stepper = arena_sim::Stepper::new();
    for _ in 0..periods {
        for k in 0..substeps {
            stepper.tick(&mut world);
            let v = world.vehicle(ec);
            if k == 0 {
                commanded.push(commanded_jerk(command, v.command.accel, control_dt));
                command = v.command.accel;
            }
            if let Some(previous) = accel {
                per_step.push(longitudinal_jerk(previous, v.longitudinal_accel, physics_dt));
            }
            accel = Some(v.longitudinal_accel);
        }
    }
    let Driver::Gt(gt) = &world.vehicle(ec).driver else { panic!("EC is a gt car") };
    (commanded, per_step, gt.diagnostics.abort_jumps, gt.diagnostics.emergency_jumps)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let csv_path = args.iter().position(|a| a == "--csv").map(|k| args.get(k + 1).expect("--csv FILE").clone());
    let mut csv = String::from("style,commanded_p95,commanded_max,per_step_p95,per_step_max\n");
    let mut options = PaperOptions::default();
    options.params.decision.jerk.enabled = !args.iter().any(|a| a == "--off");
    let jerk = options.params.decision.jerk;
    println!("jerk bound: {} ({} m/s^3)\n", if jerk.enabled { "on" } else { "off" }, jerk.max_jerk);
    println!("| run | commanded p95 | commanded max | per step p95 | per step max | exempt (abort, emergency) |");
    println!("|---|---|---|---|---|---|");
    let mut by_style: Vec<(Style, Vec<f64>, Vec<f64>)> = Style::ALL.iter().map(|&s| (s, vec![], vec![])).collect();
    for scenario in PaperScenario::ALL {
        for style in Style::ALL {
            for game in Game::ALL {
                let (commanded, per_step, aborts, emergencies) = run(scenario, style, game, &options);
                let (c, t) = (JerkSummary::of(commanded.iter().copied()), JerkSummary::of(per_step.iter().copied()));
                println!(
                    "| {} {} {} | {:.2} | {:.2} | {:.2} | {:.2} | {aborts}, {emergencies} |",
                    scenario.name(),
                    style.name(),
                    game.name(),
                    c.p95,
                    c.max,
                    t.p95,
                    t.max
                );
                let entry = by_style.iter_mut().find(|(s, ..)| *s == style).expect("every style");
                entry.1.extend(commanded);
                entry.2.extend(per_step);
            }
        }
    }
    println!("\n| style (A and B, both games) | commanded p95 | commanded max | per step p95 | per step max |");
    println!("|---|---|---|---|---|");
    for (style, commanded, per_step) in by_style {
        let (c, t) = (JerkSummary::of(commanded), JerkSummary::of(per_step));
        println!("| {} | {:.2} | {:.2} | {:.2} | {:.2} |", style.name(), c.p95, c.max, t.p95, t.max);
        csv += &format!("{},{},{},{},{}\n", style.name(), c.p95, c.max, t.p95, t.max);
    }
    if let Some(path) = csv_path {
        std::fs::write(&path, csv).unwrap_or_else(|e| panic!("writing {path}: {e}"));
    }
}
