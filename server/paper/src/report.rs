//! `arena paper`: runs the paper's Scenario A (merge) and B (overtake) in process for the
//! three styles and both games (this crate), prints the counterparts of
//! Tables IV–VII beside the paper's values, draws speed and gap plots (Figs. 8, 9, 12,
//! 13) and optionally writes every figure as JSON.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::{PaperScenario, Record, Trace};
use anyhow::Context;
use arena_sim::Game;
use arena_sim::LaneChange;
use arena_sim::Style;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

/// What `arena paper` is asked for: the CLI's flags (clients/rust/cli/src/paper.rs)
/// without the CLI.
#[derive(Debug, Clone, PartialEq)]
pub struct ReportConfig {
    /// Also write every figure of the tables as JSON to this file.
    pub json: Option<PathBuf>,
    /// Folder for the PNG plots (created if missing).
    pub out: PathBuf,
    /// Parameter preset of every game-theoretic car: a built-in name or a .toml file.
    pub params: String,
    /// Relative tolerance on the Stackelberg follower set of eq. (17b), if not the preset's.
    pub follower_tolerance: Option<f64>,
}

impl Default for ReportConfig {
    fn default() -> Self {
        ReportConfig { json: None, out: "out/paper".into(), params: "default".into(), follower_tolerance: None }
    }
}

/// One run's results.
struct Run {
    scenario: PaperScenario,
    style: Style,
    game: Game,
    record: Record,
    trace: Trace,
}

/// Runs `arena paper`.
pub fn run(args: ReportConfig) -> anyhow::Result<()> {
    let (preset, mut options) = crate::calibrate::options_of(&args.params)?;
    if let Some(tolerance) = args.follower_tolerance {
        anyhow::ensure!(
            tolerance.is_finite() && tolerance >= 0.0,
            "--follower-tolerance must be a number >= 0, not {tolerance}"
        );
        options.params.decision.game.follower_tolerance = tolerance;
    }
    println!("parameters: preset '{}' ({})", preset.name, preset.description);
    let started = std::time::Instant::now();
    let mut runs = Vec::new();
    for scenario in PaperScenario::ALL {
        for style in Style::ALL {
            for game in Game::ALL {
                let (record, trace) = crate::run(scenario, style, game, &options)
                    .with_context(|| format!("building scenario {}", scenario.name()))?;
                runs.push(Run { scenario, style, game, record, trace });
            }
        }
    }
    print!("{}", tables(&runs));
    let records: Vec<Record> = runs.iter().map(|r| r.record.clone()).collect();
    print!("{}", crate::compare::summary(&records));
    println!("\n12 runs simulated in {:.2} s (wall clock; plots follow)", started.elapsed().as_secs_f64());
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular())
        .map_err(|_| anyhow::anyhow!("the embedded DejaVu Sans font did not load"))?;
    for run in &runs {
        let file = args.out.join(format!("{}_{}_{}.png", run.scenario.name(), run.style.name(), run.game.name()));
        plot(run, &file).with_context(|| format!("drawing {}", file.display()))?;
    }
    println!("plots: {}/{{A,B}}_<style>_<game>.png", args.out.display());
    if let Some(path) = &args.json {
        let records: Vec<&Record> = runs.iter().map(|r| &r.record).collect();
        let text = serde_json::to_string_pretty(&records)?;
        std::fs::write(path, text + "\n").with_context(|| format!("writing {}", path.display()))?;
        println!("json: {}", path.display());
    }
    Ok(())
}

fn find(runs: &[Run], scenario: PaperScenario, style: Style, game: Game) -> &Run {
    runs.iter().find(|r| r.scenario == scenario && r.style == style && r.game == game).expect("every run was made")
}

fn cell(value: Option<f64>) -> String {
    value.map_or("-".to_string(), |v| format!("{v:.2}"))
}

/// Ours against the paper's, relative: "+12 %"; blank where either is missing.
fn error(ours: Option<f64>, theirs: Option<f64>) -> String {
    match (ours, theirs) {
        (Some(o), Some(t)) => format!("{:+.0} %", (o - t) / t.abs() * 100.0),
        (None, Some(_)) => "missing".to_string(),
        _ => String::new(),
    }
}

/// The counterparts of Tables IV–VII, ours beside the paper's.
fn tables(runs: &[Run]) -> String {
    let mut out = String::new();
    for scenario in PaperScenario::ALL {
        let (decision, costs, scale) = match scenario {
            PaperScenario::A => ("IV", "V", "x 10^5"),
            PaperScenario::B => ("VI", "VII", "x 10^4"),
        };
        let _ = writeln!(out, "\nScenario {} ({}): Table {decision}, ours | paper\n", scenario.name(), scenario.file());
        let _ = writeln!(
            out,
            "| style | figure | NE ours | NE paper | NE err | SE ours | SE paper | SE err |\n|---|---|---|---|---|---|---|---|"
        );
        for style in Style::ALL {
            let [ne, se] = Game::ALL.map(|game| find(runs, scenario, style, game));
            let [ne_ref, se_ref] = Game::ALL.map(|game| crate::reference(scenario, style, game));
            let mut row = |figure: &str, ours: [Option<f64>; 2], theirs: [Option<f64>; 2]| {
                let _ = writeln!(
                    out,
                    "| {} | {figure} | {} | {} | {} | {} | {} | {} |",
                    style.name(),
                    cell(ours[0]),
                    cell(theirs[0]),
                    error(ours[0], theirs[0]),
                    cell(ours[1]),
                    cell(theirs[1]),
                    error(ours[1], theirs[1])
                );
            };
            row("t_c (s)", [ne.record.t_c, se.record.t_c], [ne_ref.t_c, se_ref.t_c]);
            for role in &ne.trace.roles[1..] {
                let ours = [ne, se].map(|r| r.record.gaps_at_t_c.get(role).copied());
                let theirs = [&ne_ref, &se_ref].map(|r| r.gaps.get(role).copied());
                row(&format!("gap {role} (m)"), ours, theirs);
            }
            for role in &ne.trace.roles {
                let ours = [ne, se].map(|r| r.record.speeds_at_t_c.get(role).copied());
                let theirs = [&ne_ref, &se_ref].map(|r| r.speeds.get(role).copied());
                row(&format!("v {role} (m/s)"), ours, theirs);
            }
            let (side, crash) =
                (|r: &Run| r.record.lane_change.name(), |r: &Run| if r.record.collision { "yes" } else { "no" });
            let paper_side = match (scenario, style) {
                (PaperScenario::B, Style::Conservative) => LaneChange::Keep.name(),
                _ => LaneChange::Left.name(),
            };
            let _ = writeln!(
                out,
                "| {} | lane change | {} | {paper_side} | | {} | {paper_side} | |",
                style.name(),
                side(ne),
                side(se)
            );
            let _ = writeln!(out, "| {} | collision | {} | no | | {} | no | |", style.name(), crash(ne), crash(se));
            let iterations = |r: &Run| r.record.diagnostics.get("EC").map_or(0.0, |report| report.mean_qp_iterations);
            let _ = writeln!(
                out,
                "| {} | EC's QP iterations (mean) | {:.1} | - | | {:.1} | - | |",
                style.name(),
                iterations(ne),
                iterations(se)
            );
            let inexact = |r: &Run| r.record.inexact_decisions;
            let _ = writeln!(
                out,
                "| {} | inexact decisions | {} | - | | {} | - | |",
                style.name(),
                inexact(ne),
                inexact(se)
            );
        }
        let _ =
            writeln!(out, "\nScenario {}: Table {costs}, RMS of EC's costs, ours | paper ({scale})\n", scenario.name());
        let _ = writeln!(out, "| style | cost | NE ours | NE paper | SE ours | SE paper | SE/NE ours | SE/NE paper |");
        let _ = writeln!(out, "|---|---|---|---|---|---|---|---|");
        for style in Style::ALL {
            let [ne, se] = Game::ALL.map(|game| find(runs, scenario, style, game));
            let [ne_ref, se_ref] = Game::ALL.map(|game| crate::reference(scenario, style, game));
            let ours = |r: &Run| [r.record.rms_cost.safety, r.record.rms_cost.comfort, r.record.rms_cost.efficiency];
            for (k, name) in ["safety", "comfort", "efficiency"].iter().enumerate() {
                let (a, b) = (ours(ne)[k], ours(se)[k]);
                let (c, d) = (ne_ref.rms[k], se_ref.rms[k]);
                let _ = writeln!(
                    out,
                    "| {} | {name} | {a:.3} | {c:.0} | {b:.3} | {d:.0} | {:.2} | {:.2} |",
                    style.name(),
                    b / a,
                    d / c
                );
            }
        }
    }
    out
}

const COLOURS: [RGBColor; 4] = [RGBColor(200, 30, 30), RGBColor(30, 80, 200), RGBColor(20, 150, 60), BLACK];

/// Speed, gap and EC's lateral position against time for one run, t_c marked; each car
/// keeps its colour in every panel.
fn plot(run: &Run, file: &Path) -> anyhow::Result<()> {
    let root = BitMapBackend::new(file, (900, 1000)).into_drawing_area();
    root.fill(&WHITE)?;
    let title = format!("Scenario {} - {} - {}", run.scenario.name(), run.style.name(), run.game.name());
    let root = root.titled(&title, ("sans-serif", 24))?;
    let panels = root.split_evenly((3, 1));
    let samples = &run.trace.samples;
    let t_end = samples.last().map_or(1.0, |s| s.t + 0.1);
    let t_c = run.record.t_c;
    let speeds: Vec<Vec<(f64, f64)>> =
        (0..run.trace.roles.len()).map(|i| samples.iter().map(|s| (s.t, s.speeds[i])).collect()).collect();
    let gaps: Vec<Vec<(f64, f64)>> =
        (0..run.trace.roles.len() - 1).map(|i| samples.iter().map(|s| (s.t, s.gaps[i])).collect()).collect();
    let names: Vec<String> = run.trace.roles.iter().map(|r| format!("v {r}")).collect();
    panel(&panels[0], "speed (m/s)", t_end, &speeds, &names, 0, t_c)?;
    let names: Vec<String> = run.trace.roles[1..].iter().map(|r| format!("gap EC-{r}")).collect();
    panel(&panels[1], "gap (m), EC ahead > 0", t_end, &gaps, &names, 1, t_c)?;
    // The lane change itself: EC's lateral offset, positive to the left.
    let lateral = vec![samples.iter().map(|s| (s.t, s.d)).collect()];
    panel(&panels[2], "EC lateral position d (m)", t_end, &lateral, &["d EC".to_string()], 0, t_c)?;
    root.present()?;
    Ok(())
}

fn panel(
    area: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    y_label: &str,
    t_end: f64,
    series: &[Vec<(f64, f64)>],
    names: &[String],
    first_colour: usize,
    t_c: Option<f64>,
) -> anyhow::Result<()> {
    let values = series.iter().flatten().map(|&(_, v)| v);
    let (low, high) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| (l.min(v), h.max(v)));
    let pad = ((high - low) * 0.1).max(1.0);
    let mut chart = ChartBuilder::on(area)
        .margin(12)
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(0.0..t_end, (low - pad)..(high + pad))?;
    chart.configure_mesh().light_line_style(WHITE).x_desc("t (s)").y_desc(y_label).draw()?;
    for (k, (points, name)) in series.iter().zip(names).enumerate() {
        let colour = COLOURS[(k + first_colour) % COLOURS.len()];
        chart
            .draw_series(LineSeries::new(points.iter().copied(), colour.stroke_width(2)))?
            .label(name.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
    }
    if let Some(t) = t_c {
        chart
            .draw_series(LineSeries::new([(t, low - pad), (t, high + pad)], BLACK.mix(0.5)))?
            .label(format!("t_c = {t:.1} s"))
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.mix(0.5)));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}
