//! The PNG plots of `arena eval`: per scenario, box plots of the RMS of the paper's three
//! cost components per policy, the share of each way its episodes ended (`OUTCOMES`) with
//! the success rate's 95 % interval, and with `--opponents` a heatmap per cross-play
//! matrix. Policies are rows, their names left of the plot, so no count of policies or
//! length of name makes labels collide.

use std::path::Path;

use arena_eval::{Episode, FIGURES, OUTCOMES, Summary, crossplay, figure_index};
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

const BLUE_: RGBColor = RGBColor(30, 80, 200);
/// The smallest cost the log axis shows.
const FLOOR: f64 = 1e-3;
/// Colours of `OUTCOMES`: success, collision, off-road, lane end, time-out without success.
const OUTCOME_COLOURS: [RGBColor; 5] = [
    RGBColor(60, 150, 80),
    RGBColor(200, 40, 40),
    RGBColor(240, 150, 40),
    RGBColor(150, 80, 170),
    RGBColor(150, 150, 150),
];
/// Height of a policy's row (pixels).
const ROW: u32 = 36;

fn font() -> anyhow::Result<()> {
    register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular())
        .map_err(|_| anyhow::anyhow!("the embedded DejaVu Sans font did not load"))
}

fn column(key: &str) -> usize {
    figure_index(key).unwrap_or(0)
}

/// The policies of `scenario`, in the order they ran.
fn policies<'a>(names: impl Iterator<Item = &'a str>) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for name in names {
        if !out.iter().any(|n| n == name) {
            out.push(name.to_string());
        }
    }
    out
}

/// The width in pixels of the widest of `texts` in `style`, plus a margin.
fn widest<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    texts: &[String],
    style: &TextStyle,
) -> u32 {
    texts.iter().filter_map(|t| area.estimate_text_size(t, style).ok()).map(|(w, _)| w).max().unwrap_or(0) + 16
}

/// Box plots of RMS safety, comfort and efficiency per policy, a row each, on log axes.
pub fn costs(file: &Path, scenario: &str, episodes: &[Episode]) -> anyhow::Result<()> {
    font()?;
    let mine: Vec<&Episode> = episodes.iter().filter(|e| e.scenario == scenario).collect();
    let names = policies(mine.iter().map(|e| e.policy.as_str()));
    let panel = 90 + ROW * names.len() as u32;
    let names_width = measure(|probe| widest(probe, &names, &("sans-serif", 15).into_text_style(probe)));
    let root = BitMapBackend::new(file, (1100, 40 + 3 * panel)).into_drawing_area();
    root.fill(&WHITE)?;
    // The y axis counts upwards: the first policy gets the top row.
    let row = |i: usize| names.len() as i32 - 1 - i as i32;
    let root = root.titled(&format!("{scenario}: RMS of the cost components per episode"), ("sans-serif", 22))?;
    for (area, key) in root.split_evenly((3, 1)).iter().zip(["rms_safety", "rms_comfort", "rms_efficiency"]) {
        let k = column(key);
        let values: Vec<Vec<f64>> = names
            .iter()
            .map(|name| {
                mine.iter().filter(|e| &e.policy == name).map(|e| e.figures[k]).filter(|v| v.is_finite()).collect()
            })
            .collect();
        // Costs span orders of magnitude between policies (a lane end's safety field): a
        // log axis, with zeros shown at its floor.
        let all = values.iter().flatten().map(|v| v.max(FLOOR));
        let (low, high) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| (l.min(v), h.max(v)));
        let (low, high) = if low.is_finite() { (low / 1.5, high * 1.5) } else { (FLOOR, 1.0) };
        let mut chart = ChartBuilder::on(area)
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(names_width)
            .build_cartesian_2d((low as f32..high as f32).log_scale(), (0..names.len() as i32 - 1).into_segmented())?;
        chart
            .configure_mesh()
            .light_line_style(WHITE)
            .x_desc(format!("{} (log)", FIGURES[k].heading))
            .x_labels(6)
            .x_label_formatter(&|v| decade(f64::from(*v)))
            .y_label_formatter(&|v| label(v, &names, row))
            .label_style(("sans-serif", 15))
            .draw()?;
        let values: Vec<Vec<f64>> = values.iter().map(|v| v.iter().map(|x| x.max(FLOOR)).collect()).collect();
        chart.draw_series(values.iter().enumerate().filter(|(_, v)| !v.is_empty()).map(|(i, v)| {
            Boxplot::new_horizontal(SegmentValue::CenterOf(row(i)), &Quartiles::new(v)).width(ROW * 2 / 3).style(BLUE_)
        }))?;
    }
    root.present()?;
    Ok(())
}

/// How many episodes a row of the rates plot has, and that they have no interval when
/// every one was the same.
fn episodes_note(summary: &Summary) -> String {
    match summary.distinct {
        1 if summary.episodes > 1 => format!("{} episodes, 1 distinct: no interval", summary.episodes),
        _ => format!("{} episodes", summary.episodes),
    }
}

/// What `measure` finds of texts on a scratch canvas: a picture's size depends on the
/// texts it holds.
fn measure<T>(measure: impl FnOnce(&DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>) -> T) -> T {
    let mut scratch = vec![0u8; 3];
    let probe = BitMapBackend::with_buffer(&mut scratch, (1, 1)).into_drawing_area();
    measure(&probe)
}

/// A log axis's label: the value with two significant digits, without trailing zeros.
fn decade(v: f64) -> String {
    if !(1e-2..1e4).contains(&v.abs()) {
        return format!("{v:.0e}");
    }
    let text = format!("{v:.2}");
    text.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// How each policy's episodes ended, a stacked bar per policy of the `OUTCOMES` shares
/// (so a policy that only stops shows as time-out), with the success rate's 95 % Wilson
/// interval where the sample has more than one distinct episode.
pub fn rates(file: &Path, scenario: &str, summaries: &[Summary]) -> anyhow::Result<()> {
    font()?;
    let mine: Vec<&Summary> = summaries.iter().filter(|s| s.scenario == scenario).collect();
    let (top, bar_width) = (84i32, 720i32);
    let text = ("sans-serif", 15).into_font().color(&BLACK);
    let names: Vec<String> = mine.iter().map(|s| s.policy.clone()).collect();
    let notes: Vec<String> = mine.iter().map(|s| episodes_note(s)).collect();
    let (left, right) = measure(|probe| (widest(probe, &names, &text).max(60), widest(probe, &notes, &text)));
    let (left, width) = (left as i32, left + bar_width as u32 + 12 + right);
    let height = top as u32 + ROW * mine.len() as u32 + 60;
    let root = BitMapBackend::new(file, (width.max(900), height)).into_drawing_area();
    root.fill(&WHITE)?;
    let title = format!("{scenario}: how the episodes ended (share per policy; bar: success's 95 % interval)");
    root.draw_text(&title, &("sans-serif", 20).into_font().color(&BLACK), (10, 10))?;
    let mut x = left;
    for (outcome, colour) in OUTCOMES.iter().zip(OUTCOME_COLOURS) {
        root.draw(&Rectangle::new([(x, 46), (x + 14, 60)], colour.filled()))?;
        root.draw_text(outcome.heading, &text, (x + 18, 45))?;
        x += 18 + root.estimate_text_size(outcome.heading, &text).map_or(120, |(w, _)| w as i32) + 22;
    }
    let at = |share: f64| left + (share.clamp(0.0, 1.0) * f64::from(bar_width)).round() as i32;
    let bottom = top + ROW as i32 * mine.len() as i32;
    for tick in 0..=4 {
        let x = at(f64::from(tick) / 4.0);
        root.draw(&PathElement::new(vec![(x, top - 4), (x, bottom + 4)], RGBColor(200, 200, 200)))?;
        root.draw_text(&format!("{} %", tick * 25), &text, (x - 14, bottom + 10))?;
    }
    for (row, summary) in mine.iter().enumerate() {
        let y = top + ROW as i32 * row as i32;
        root.draw_text(&summary.policy, &text, (8, y + ROW as i32 / 2 - 8))?;
        let mut from = 0.0;
        for ((_, share), colour) in summary.outcomes.iter().zip(OUTCOME_COLOURS) {
            let (x0, x1) = (at(from), at(from + share));
            if x1 > x0 {
                root.draw(&Rectangle::new([(x0, y + 5), (x1, y + ROW as i32 - 5)], colour.filled()))?;
            }
            if x1 - x0 >= 44 {
                root.draw_text(
                    &format!("{:.0} %", share * 100.0),
                    &text.color(&WHITE),
                    (x0 + 5, y + ROW as i32 / 2 - 8),
                )?;
            }
            from += share;
        }
        let success = summary.figures.iter().find(|(k, _)| k == "success").map(|(_, e)| *e);
        if let Some(e) = success.filter(|e| e.n > 0 && summary.distinct > 1) {
            let (x0, x1, middle) = (at(e.low), at(e.high), y + ROW as i32 / 2);
            root.draw(&PathElement::new(vec![(x0, middle), (x1, middle)], BLACK.stroke_width(2)))?;
            for x in [x0, x1] {
                root.draw(&PathElement::new(vec![(x, middle - 7), (x, middle + 7)], BLACK.stroke_width(2)))?;
            }
        }
        root.draw_text(&notes[row], &text, (left + bar_width + 12, y + ROW as i32 / 2 - 8))?;
    }
    root.present()?;
    Ok(())
}

/// The name of the policy drawn at `value` of a segmented axis whose row `row(i)` holds
/// policy i.
fn label(value: &SegmentValue<i32>, names: &[String], row: impl Fn(usize) -> i32) -> String {
    match value {
        SegmentValue::CenterOf(at) => {
            (0..names.len()).find(|&i| row(i) == *at).map(|i| names[i].clone()).unwrap_or_default()
        }
        _ => String::new(),
    }
}

/// A cross-play matrix of `figure` on `scenario` as a heatmap: a row per policy, a column
/// per opponent, each cell labelled with its estimate (and interval, unless the scenario
/// is deterministic) and framed when its interval overlaps the best cell's
/// (`crossplay::near_best`). Rates are coloured on a fixed scale from 0 % to 100 %, the
/// return from the matrix's worst to its best cell (returns have no fixed range).
pub fn crossplay(
    file: &Path,
    scenario: &str,
    figure: &str,
    policies: &[String],
    summaries: &[Summary],
) -> anyhow::Result<()> {
    font()?;
    let opponents = crossplay::opponents();
    let cells = crossplay::matrix(summaries, scenario, policies, figure);
    let near = crossplay::near_best(&cells, figure);
    let rate = FIGURES.iter().any(|f| f.key == figure && f.rate);
    let (low, high) = if rate {
        (0.0, 1.0)
    } else {
        let values = cells.iter().flatten().map(|c| c.value);
        values.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| (l.min(v), h.max(v)))
    };
    let better_high = crossplay::higher_is_better(figure);
    let text = ("sans-serif", 14).into_font().color(&BLACK);
    let labels: Vec<String> = cells.iter().map(|c| c.map_or("-".to_string(), |c| c.label())).collect();
    let headings: Vec<String> = opponents.iter().map(|o| format!("vs {}", o.name)).collect();
    let (cell_w, left) = measure(|probe| {
        // A heading's end and the next one's start apart by more than the cells' own margin.
        let cell_w = widest(probe, &labels, &text).max(widest(probe, &headings, &text) + 12) as i32;
        (cell_w, widest(probe, policies, &text) as i32 + 10)
    });
    let (top, cell_h) = (96i32, 46i32);
    let width = (left + cell_w * opponents.len() as i32 + 20) as u32;
    let height = (top + cell_h * policies.len() as i32 + 30) as u32;
    let root = BitMapBackend::new(file, (width, height)).into_drawing_area();
    root.fill(&WHITE)?;
    let heading = FIGURES.iter().find(|f| f.key == figure).map_or(figure, |f| f.heading);
    let title = format!("{scenario}: {heading}, policy (rows) against opponents (columns)");
    root.draw_text(&title, &("sans-serif", 20).into_font().color(&BLACK), (10, 10))?;
    let scale = match (rate, better_high) {
        (true, true) => "colour: 0 % red to 100 % green",
        (true, false) => "colour: 0 % green to 100 % red (lower is better)",
        (false, _) => "colour: this matrix's worst (red) to best (green)",
    };
    let legend = format!("{scale}; framed: the interval overlaps the best cell's");
    root.draw_text(&legend, &text, (10, 38))?;
    for (col, name) in headings.iter().enumerate() {
        root.draw_text(name, &text, (left + cell_w * col as i32 + 8, top - 24))?;
    }
    for (row, policy) in policies.iter().enumerate() {
        let y = top + cell_h * row as i32;
        root.draw_text(policy, &text, (10, y + cell_h / 2 - 7))?;
        for col in 0..opponents.len() {
            let k = row * opponents.len() + col;
            let x = left + cell_w * col as i32;
            let colour = match cells[k] {
                None => RGBColor(220, 220, 220),
                Some(c) => {
                    let t = if high > low { ((c.value - low) / (high - low)).clamp(0.0, 1.0) } else { 0.5 };
                    let good = if better_high { t } else { 1.0 - t };
                    RGBColor((230.0 - 150.0 * good) as u8, (90.0 + 130.0 * good) as u8, 90)
                }
            };
            root.draw(&Rectangle::new([(x, y), (x + cell_w - 2, y + cell_h - 2)], colour.filled()))?;
            if near[k] {
                let frame = [(x + 1, y + 1), (x + cell_w - 3, y + cell_h - 3)];
                root.draw(&Rectangle::new(frame, BLACK.stroke_width(3)))?;
            }
            root.draw_text(&labels[k], &text, (x + 8, y + cell_h / 2 - 7))?;
        }
    }
    root.present()?;
    Ok(())
}
