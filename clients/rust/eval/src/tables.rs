//! The summaries as `arena eval` and `highway_arena.evaluate` write them: Markdown tables
//! (IQMs and rates, medians, paired differences, probabilities of improvement), CSV and
//! JSON. Kept apart from the estimators so that a table's layout changes no figure.

use std::fmt::Write as _;

use serde::Serialize;

use super::{Difference, Episode, Estimate, FIGURES, Figure, RESOLUTION, Summary};
use crate::stats::Interval;

/// A number with three significant digits, in scientific notation beyond 1e5 or below 1e-3.
pub(super) fn number(v: f64) -> String {
    if !v.is_finite() {
        return if v.is_nan() { "-".into() } else { format!("{v}") };
    }
    let magnitude = v.abs();
    if v == 0.0 {
        return "0".into();
    }
    if !(1e-3..1e5).contains(&magnitude) {
        return format!("{v:.2e}");
    }
    let decimals = (2 - magnitude.log10().floor() as i32).max(0) as usize;
    format!("{v:.decimals$}")
}

pub(super) fn percent(v: f64) -> String {
    format!("{:.0}", v * 100.0)
}

fn rate_cell(e: &Estimate, distinct: usize) -> String {
    match (e.n, distinct) {
        (0, _) => "-".into(),
        (_, 1) => format!("{} %", percent(e.mean)),
        _ => format!("{} % [{}, {}]", percent(e.mean), percent(e.low), percent(e.high)),
    }
}

fn interval_cell(interval: Option<&Interval>, distinct: usize) -> String {
    match interval {
        None => "-".into(),
        Some(i) if distinct == 1 => number(i.value),
        Some(i) => format!("{} [{}, {}]", number(i.value), number(i.low), number(i.high)),
    }
}

/// A paired difference, bold when it is significant (`Difference::significant`); rates in
/// percentage points.
fn difference_cell(figure: &Figure, d: &Difference) -> String {
    let i = &d.difference;
    if d.n == 0 || i.value.is_nan() {
        return "-".into();
    }
    let show = |v: f64| {
        let text = if figure.rate { percent(v) } else { number(v) };
        if v > 0.0 { format!("+{text}") } else { text }
    };
    let unit = if figure.rate { " pp" } else { "" };
    let text = if i.low == i.high {
        format!("{}{unit}", show(i.value))
    } else {
        format!("{}{unit} [{}, {}]", show(i.value), show(i.low), show(i.high))
    };
    if d.significant { format!("**{text}**") } else { text }
}

fn improvement_cell(d: &Difference) -> String {
    match d.improvement {
        None => "-".into(),
        Some(i) if i.low == i.high => format!("{:.2}", i.value),
        Some(i) => format!("{:.2} [{:.2}, {:.2}]", i.value, i.low, i.high),
    }
}

fn header(out: &mut String, first: &str) {
    let _ = write!(out, "| scenario | policy | {first} |");
    for figure in FIGURES {
        let _ = write!(out, " {} |", figure.heading);
    }
    out.push_str("\n|---|---|---:|");
    out.push_str(&"---:|".repeat(FIGURES.len()));
    out.push('\n');
}

/// The pairs of a policy's comparison: how many, and how many distinct when fewer (one:
/// a deterministic scenario, whose difference is a value without interval or mark).
fn pairs_cell(s: &Summary) -> String {
    let most = |count: fn(&Difference) -> usize| s.differences.iter().map(|(_, d)| count(d)).max().unwrap_or(0);
    match (most(|d| d.n), most(|d| d.distinct)) {
        (n, 1) => format!("{n} (deterministic: 1 distinct pair)"),
        (n, distinct) if distinct < n => format!("{n} ({distinct} distinct)"),
        (n, _) => n.to_string(),
    }
}

fn episodes_cell(s: &Summary) -> String {
    match s.distinct {
        1 if s.episodes > 1 => format!("{} (1 distinct)", s.episodes),
        _ => s.episodes.to_string(),
    }
}

/// The summaries as Markdown: rates with their Wilson interval and the other figures' IQM
/// with its bootstrap interval; the medians; each policy's paired differences from the
/// reference (bold: the interval leaves out zero); and rliable's probability of improvement.
pub fn markdown(summaries: &[Summary]) -> String {
    let mut out = String::from("Rates, and the interquartile mean (IQM) of the other figures:\n\n");
    header(&mut out, "episodes");
    for s in summaries {
        let _ = write!(out, "| {} | {} | {} |", s.scenario, s.policy, episodes_cell(s));
        for (figure, (_, e)) in FIGURES.iter().zip(&s.figures) {
            let cell = if figure.rate { rate_cell(e, s.distinct) } else { interval_cell(e.iqm.as_ref(), s.distinct) };
            let _ = write!(out, " {cell} |");
        }
        out.push('\n');
    }
    out.push_str("\nMedians:\n\n");
    header(&mut out, "episodes");
    for s in summaries {
        let _ = write!(out, "| {} | {} | {} |", s.scenario, s.policy, episodes_cell(s));
        for (figure, (_, e)) in FIGURES.iter().zip(&s.figures) {
            let cell =
                if figure.rate { rate_cell(e, s.distinct) } else { interval_cell(e.median.as_ref(), s.distinct) };
            let _ = write!(out, " {cell} |");
        }
        out.push('\n');
    }
    let compared: Vec<&Summary> = summaries.iter().filter(|s| s.reference.is_some()).collect();
    if compared.is_empty() {
        return out;
    }
    let reference = compared[0].reference.as_deref().unwrap_or_default();
    let _ = write!(
        out,
        "\nPaired differences from `{reference}` (policy minus reference on the same seeds, over the distinct \
         pairs; rates: mean, in percentage points; others: IQM; differences within {RESOLUTION:e} of the values \
         count as 0; **bold**: the 95 % interval over at least two distinct pairs leaves out 0):\n\n"
    );
    header(&mut out, "pairs");
    for s in &compared {
        let _ = write!(out, "| {} | {} | {} |", s.scenario, s.policy, pairs_cell(s));
        for (figure, (_, d)) in FIGURES.iter().zip(&s.differences) {
            let _ = write!(out, " {} |", difference_cell(figure, d));
        }
        out.push('\n');
    }
    let _ = write!(
        out,
        "\nProbability of improvement over `{reference}` (rliable's: P(policy better) + P(equal) / 2 for an \
         episode of each of the distinct pairs drawn at random; none from one distinct pair, a deterministic \
         scenario's):\n\n"
    );
    header(&mut out, "pairs");
    for s in &compared {
        let _ = write!(out, "| {} | {} | {} |", s.scenario, s.policy, pairs_cell(s));
        for (_, d) in &s.differences {
            let _ = write!(out, " {} |", improvement_cell(d));
        }
        out.push('\n');
    }
    let warnings: Vec<String> = compared
        .iter()
        .flat_map(|s| s.warnings.iter().map(move |w| format!("- **Warning**, {} on {}: {w}\n", s.policy, s.scenario)))
        .collect();
    if !warnings.is_empty() {
        out.push_str("\nSuccess and return disagree:\n\n");
        warnings.iter().for_each(|w| out.push_str(w));
    }
    out
}

fn fields(interval: Option<&Interval>) -> String {
    interval.map_or(",,".into(), |i| format!("{},{},{}", i.value, i.low, i.high))
}

/// The summaries as CSV: per figure its count, mean and the mean's interval, median and
/// IQM with their intervals (empty for rates).
pub fn csv(summaries: &[Summary]) -> String {
    let mut out = String::from("scenario,policy,episodes,distinct");
    for figure in FIGURES {
        let key = figure.key;
        let _ = write!(
            out,
            ",{key}_n,{key},{key}_low,{key}_high,{key}_median,{key}_median_low,{key}_median_high,{key}_iqm,\
             {key}_iqm_low,{key}_iqm_high"
        );
    }
    out.push('\n');
    for s in summaries {
        let _ = write!(out, "{},{},{},{}", s.scenario, s.policy, s.episodes, s.distinct);
        for (_, e) in &s.figures {
            let _ = write!(out, ",{},{},{},{},", e.n, e.mean, e.low, e.high);
            let _ = write!(out, "{},{}", fields(e.median.as_ref()), fields(e.iqm.as_ref()));
        }
        out.push('\n');
    }
    out
}

/// The paired differences as CSV, one row per (scenario, policy, figure).
pub fn differences_csv(summaries: &[Summary]) -> String {
    let mut out = String::from(
        "scenario,policy,reference,figure,pairs,distinct_pairs,difference,difference_low,difference_high,\
         significant,improvement,improvement_low,improvement_high\n",
    );
    for s in summaries {
        let Some(reference) = &s.reference else { continue };
        for (key, d) in &s.differences {
            let i = &d.difference;
            let _ = writeln!(
                out,
                "{},{},{reference},{key},{},{},{},{},{},{},{}",
                s.scenario,
                s.policy,
                d.n,
                d.distinct,
                i.value,
                i.low,
                i.high,
                d.significant,
                fields(d.improvement.as_ref())
            );
        }
    }
    out
}

/// Every episode as CSV, one row each (docs/evaluation.md lists the columns).
pub fn episodes_csv(episodes: &[Episode]) -> String {
    let mut out = String::from("scenario,policy,seed,agent,end_reason");
    for figure in FIGURES {
        let _ = write!(out, ",{}", figure.key);
    }
    out.push('\n');
    for e in episodes {
        let _ = write!(out, "{},{},{},{},{}", e.scenario, e.policy, e.seed, e.agent, e.end_reason);
        for v in &e.figures {
            let _ = write!(out, ",{v}");
        }
        out.push('\n');
    }
    out
}

/// Summaries and episodes as one JSON document (NaN and infinities as null).
pub fn json(summaries: &[Summary], episodes: &[Episode]) -> String {
    #[derive(Serialize)]
    struct Document<'a> {
        figures: Vec<(&'a str, &'a str)>,
        summaries: &'a [Summary],
        episodes: &'a [Episode],
    }
    let figures = FIGURES.iter().map(|f| (f.key, f.what)).collect();
    serde_json::to_string_pretty(&Document { figures, summaries, episodes }).unwrap_or_default() + "\n"
}
