//! The PNG plots of `arena eval`: per scenario, box plots of the RMS of the paper's three
//! cost components per policy, bars of the success and collision rates with their 95 %
//! intervals, and with `--opponents` a heatmap per cross-play matrix.

use std::path::Path;

use arena_eval::{Episode, FIGURES, Summary, crossplay, figure_index};
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

const BLUE_: RGBColor = RGBColor(30, 80, 200);
const RED_: RGBColor = RGBColor(200, 30, 30);
/// The smallest cost the log axis shows.
const FLOOR: f64 = 1e-3;

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

/// Box plots of RMS safety, comfort and efficiency per policy.
pub fn costs(file: &Path, scenario: &str, episodes: &[Episode]) -> anyhow::Result<()> {
    font()?;
    let mine: Vec<&Episode> = episodes.iter().filter(|e| e.scenario == scenario).collect();
    let names = policies(mine.iter().map(|e| e.policy.as_str()));
    let root = BitMapBackend::new(file, (300 + 110 * names.len() as u32, 900)).into_drawing_area();
    root.fill(&WHITE)?;
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
            .x_label_area_size(30)
            .y_label_area_size(70)
            .build_cartesian_2d((0..names.len() as i32 - 1).into_segmented(), (low as f32..high as f32).log_scale())?;
        chart
            .configure_mesh()
            .light_line_style(WHITE)
            .y_desc(format!("{} (log)", FIGURES[k].heading))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .x_label_formatter(&|v| label(v, &names))
            .draw()?;
        let values: Vec<Vec<f64>> = values.iter().map(|v| v.iter().map(|x| x.max(FLOOR)).collect()).collect();
        chart.draw_series(values.iter().enumerate().filter(|(_, v)| !v.is_empty()).map(|(i, v)| {
            Boxplot::new_vertical(SegmentValue::CenterOf(i as i32), &Quartiles::new(v)).width(30).style(BLUE_)
        }))?;
    }
    root.present()?;
    Ok(())
}

/// Success and collision rates per policy, with their Wilson intervals.
pub fn rates(file: &Path, scenario: &str, summaries: &[Summary]) -> anyhow::Result<()> {
    font()?;
    let mine: Vec<&Summary> = summaries.iter().filter(|s| s.scenario == scenario).collect();
    let names = policies(mine.iter().map(|s| s.policy.as_str()));
    let root = BitMapBackend::new(file, (300 + 110 * names.len() as u32, 650)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(&format!("{scenario}: rates per policy, 95 % intervals"), ("sans-serif", 22))?;
    for (area, (key, colour)) in root.split_evenly((2, 1)).iter().zip([("success", BLUE_), ("collision", RED_)]) {
        let estimates: Vec<_> =
            mine.iter().map(|s| s.figures.iter().find(|(k, _)| k == key).map(|(_, e)| *e)).collect();
        let mut chart = ChartBuilder::on(area)
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(70)
            .build_cartesian_2d((0..names.len() as i32 - 1).into_segmented(), 0f32..1.05f32)?;
        chart
            .configure_mesh()
            .light_line_style(WHITE)
            .y_desc(format!("{key} rate"))
            .x_label_formatter(&|v| label(v, &names))
            .draw()?;
        let bars = estimates.iter().enumerate().filter_map(|(i, e)| e.map(|e| (i as i32, e.mean as f32)));
        chart.draw_series(Histogram::vertical(&chart).style(colour.mix(0.6).filled()).margin(20).data(bars))?;
        chart.draw_series(estimates.iter().enumerate().filter_map(|(i, e)| {
            let e = e.filter(|e| e.n > 0)?;
            let point = SegmentValue::CenterOf(i as i32);
            Some(ErrorBar::new_vertical(point, e.low as f32, e.mean as f32, e.high as f32, BLACK.stroke_width(2), 12))
        }))?;
    }
    root.present()?;
    Ok(())
}

fn label(value: &SegmentValue<i32>, names: &[String]) -> String {
    match value {
        SegmentValue::CenterOf(i) => names.get(*i as usize).cloned().unwrap_or_default(),
        _ => String::new(),
    }
}

/// A cross-play matrix of `figure` on `scenario` as a heatmap: a row per policy, a column
/// per opponent, each cell coloured from the worst to the best value of the matrix and
/// labelled with its estimate (and interval, unless the scenario is deterministic).
pub fn crossplay(
    file: &Path,
    scenario: &str,
    figure: &str,
    policies: &[String],
    summaries: &[Summary],
) -> anyhow::Result<()> {
    font()?;
    let opponents = crossplay::opponents();
    let cells: Vec<Vec<Option<crossplay::Cell>>> = policies
        .iter()
        .map(|p| opponents.iter().map(|o| crossplay::cell(summaries, scenario, p, &o.name, figure)).collect())
        .collect();
    let values: Vec<f64> = cells.iter().flatten().flatten().map(|c| c.value).collect();
    let (low, high) = values.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
    let better_high = FIGURES.iter().find(|f| f.key == figure).is_none_or(|f| f.better != arena_eval::Better::Lower);
    // Drawn in pixels: a cell per (policy, opponent), names at the rows' and columns' centres.
    let (left, top, cell_w, cell_h) = (210i32, 70i32, 190i32, 46i32);
    let width = (left + cell_w * opponents.len() as i32 + 20) as u32;
    let height = (top + cell_h * policies.len() as i32 + 30) as u32;
    let root = BitMapBackend::new(file, (width, height)).into_drawing_area();
    root.fill(&WHITE)?;
    let heading = FIGURES.iter().find(|f| f.key == figure).map_or(figure, |f| f.heading);
    let title = format!("{scenario}: {heading}, policy (rows) against opponents (columns)");
    root.draw_text(&title, &("sans-serif", 20).into_font().color(&BLACK), (10, 10))?;
    let text = ("sans-serif", 14).into_font().color(&BLACK);
    for (col, opponent) in opponents.iter().enumerate() {
        root.draw_text(&opponent.name, &text, (left + cell_w * col as i32 + 8, top - 22))?;
    }
    for (row, line) in cells.iter().enumerate() {
        let y = top + cell_h * row as i32;
        root.draw_text(&policies[row], &text, (10, y + cell_h / 2 - 7))?;
        for (col, cell) in line.iter().enumerate() {
            let x = left + cell_w * col as i32;
            let colour = match cell {
                None => RGBColor(220, 220, 220),
                Some(c) => {
                    let t = if high > low { (c.value - low) / (high - low) } else { 0.5 };
                    let good = if better_high { t } else { 1.0 - t };
                    // From red (the matrix's worst) to green (its best).
                    RGBColor((230.0 - 150.0 * good) as u8, (90.0 + 130.0 * good) as u8, 90)
                }
            };
            root.draw(&Rectangle::new([(x, y), (x + cell_w - 2, y + cell_h - 2)], colour.filled()))?;
            let label = cell.map_or("-".to_string(), |c| c.label());
            root.draw_text(&label, &text, (x + 8, y + cell_h / 2 - 7))?;
        }
    }
    root.present()?;
    Ok(())
}
