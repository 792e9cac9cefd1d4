//! Cross-play: a policy against every game-theoretic driver the AV can be (three styles by
//! two games) and IDM, on the same episodes. Each opponent is a set of `opponents.<what>`
//! overrides, which the scenario loader applies to every opponent of the scenario (every
//! vehicle driven by `gt` and the `[traffic] gt` cars: docs/scenarios.md); the matrices
//! read the summaries of `summarise`, one row per policy and one column per opponent.

use std::fmt::Write as _;

use arena_protocol::{Game, Style};

use super::tables::{number, percent};
use super::{Better, Estimate, FIGURES, Summary, tie};

/// One column of the matrices: who drives the opponents.
#[derive(Debug, Clone, PartialEq)]
pub struct Opponent {
    /// Its column heading: `gt:<style>:<game>` or `idm`, the names `arena eval --policy` takes.
    pub name: String,
    /// The create overrides that make every opponent this driver.
    pub overrides: Vec<(String, String)>,
}

/// The opponents of a cross-play run, in column order: every style and game of the AV,
/// then IDM.
pub fn opponents() -> Vec<Opponent> {
    let mut all = Vec::new();
    for style in Style::ALL.map(Style::name) {
        for game in Game::ALL.map(Game::name) {
            all.push(Opponent {
                name: format!("gt:{style}:{game}"),
                overrides: vec![("opponents.style".into(), style.into()), ("opponents.game".into(), game.into())],
            });
        }
    }
    all.push(Opponent { name: "idm".into(), overrides: vec![("opponents.driver".into(), "idm".into())] });
    all
}

/// The name a policy's episodes against `opponent` are summarised under.
pub fn row_name(policy: &str, opponent: &str) -> String {
    format!("{policy} vs {opponent}")
}

/// The figures of the cross-play matrices (issue 26: success, at-fault collision, return).
pub const MATRIX_FIGURES: [&str; 3] = ["success", "at_fault", "return"];

/// The estimate of `figure` for `policy` against `opponent` on `scenario`: (value, low,
/// high, one distinct episode), the mean and Wilson interval of a rate, the IQM and its
/// bootstrap interval otherwise.
pub fn cell(summaries: &[Summary], scenario: &str, policy: &str, opponent: &str, figure: &str) -> Option<Cell> {
    let name = row_name(policy, opponent);
    let summary = summaries.iter().find(|s| s.scenario == scenario && s.policy == name)?;
    let (_, estimate) = summary.figures.iter().find(|(key, _)| key == figure)?;
    let rate = FIGURES.iter().any(|f| f.key == figure && f.rate);
    let one = summary.distinct == 1;
    Cell::of(estimate, rate, one)
}

/// The cells of `figure` on `scenario`, row by row (`policies`), each row a column per
/// `opponents()`.
pub fn matrix(summaries: &[Summary], scenario: &str, policies: &[String], figure: &str) -> Vec<Option<Cell>> {
    let opponents = opponents();
    policies.iter().flat_map(|p| opponents.iter().map(move |o| cell(summaries, scenario, p, &o.name, figure))).collect()
}

/// One cell of a matrix.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cell {
    /// The estimate (a rate as a fraction).
    pub value: f64,
    /// Its interval's lower end.
    pub low: f64,
    /// Its upper end.
    pub high: f64,
    /// Every episode came out the same (a deterministic scenario): no interval.
    pub one_distinct: bool,
    /// Whether it is a rate.
    pub rate: bool,
}

impl Cell {
    fn of(e: &Estimate, rate: bool, one_distinct: bool) -> Option<Cell> {
        if e.n == 0 {
            return None;
        }
        let (value, low, high) = match (rate, e.iqm) {
            (true, _) => (e.mean, e.low, e.high),
            (false, Some(iqm)) => (iqm.value, iqm.low, iqm.high),
            (false, None) => return None,
        };
        Some(Cell { value, low, high, one_distinct, rate })
    }

    /// The estimate with its interval in brackets (none for a deterministic scenario).
    pub fn label(&self) -> String {
        let show = |v: f64| if self.rate { format!("{} %", percent(v)) } else { number(v) };
        if self.one_distinct {
            show(self.value)
        } else if self.rate {
            format!("{} % [{}, {}]", percent(self.value), percent(self.low), percent(self.high))
        } else {
            format!("{} [{}, {}]", number(self.value), number(self.low), number(self.high))
        }
    }
}

/// Whether a higher value of `figure` is better (for the colours and the best cell);
/// figures without a better side count as higher-is-better.
pub fn higher_is_better(figure: &str) -> bool {
    FIGURES.iter().find(|f| f.key == figure).is_none_or(|f| f.better != Better::Lower)
}

/// Which of a matrix's `cells` cannot be told apart from its best: their intervals overlap
/// the best cell's (the best itself included; a cell of one distinct episode, without
/// interval, only when it equals the best within the figures' resolution).
pub fn near_best(cells: &[Option<Cell>], figure: &str) -> Vec<bool> {
    let sign = if higher_is_better(figure) { 1.0 } else { -1.0 };
    let best = cells.iter().flatten().max_by(|a, b| (sign * a.value).total_cmp(&(sign * b.value)));
    cells
        .iter()
        .map(|cell| match (cell, best) {
            (Some(c), Some(b)) => tie(c.value, b.value) || (c.low <= b.high && b.low <= c.high),
            _ => false,
        })
        .collect()
}

/// The matrices as Markdown: per scenario and figure, a row per policy and a column per
/// opponent, **bold** the cells whose interval overlaps the best cell's (`near_best`); the
/// heading says so when every cell is one distinct episode (a deterministic scenario),
/// whose cells have no interval.
pub fn markdown(summaries: &[Summary], scenarios: &[String], policies: &[String]) -> String {
    let opponents = opponents();
    let mut out = String::new();
    for scenario in scenarios {
        for figure in MATRIX_FIGURES {
            let heading = FIGURES.iter().find(|f| f.key == figure).map_or(figure, |f| f.heading);
            let mine = || summaries.iter().filter(|s| &s.scenario == scenario);
            let one = mine().next().is_some() && mine().all(|s| s.distinct == 1);
            let note = if one { " (one distinct episode per cell: no intervals)" } else { "" };
            let note = format!("{note}; **bold**: the interval overlaps the best cell's");
            let _ = writeln!(out, "\n### {scenario}: {heading}{note}\n");
            out.push_str("| policy |");
            for opponent in &opponents {
                let _ = write!(out, " vs {} |", opponent.name);
            }
            out.push_str("\n|---|");
            out.push_str(&"---:|".repeat(opponents.len()));
            out.push('\n');
            let cells = matrix(summaries, scenario, policies, figure);
            let near = near_best(&cells, figure);
            for (row, policy) in policies.iter().enumerate() {
                let _ = write!(out, "| {policy} |");
                for col in 0..opponents.len() {
                    let k = row * opponents.len() + col;
                    let text = match cells[k] {
                        None => "-".into(),
                        Some(c) if near[k] => format!("**{}**", c.label()),
                        Some(c) => c.label(),
                    };
                    let _ = write!(out, " {text} |");
                }
                out.push('\n');
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rate(value: f64, low: f64, high: f64) -> Option<Cell> {
        Some(Cell { value, low, high, one_distinct: low == high, rate: true })
    }

    #[test]
    fn cells_whose_interval_overlaps_the_best_are_near_it() {
        // 30 of 30 [89, 100], 28 [79, 98], 21 [52, 83], and a missing cell.
        let cells = [rate(1.0, 0.886, 1.0), rate(0.933, 0.787, 0.982), rate(0.7, 0.521, 0.833), None];
        assert_eq!(near_best(&cells, "success"), [true, true, false, false]);
        // At fault: lower is better, so the best is the 0 % cell.
        let faults = [rate(0.0, 0.0, 0.114), rate(0.3, 0.166, 0.479), rate(0.1, 0.035, 0.256)];
        assert_eq!(near_best(&faults, "at_fault"), [true, false, true]);
    }

    #[test]
    fn cells_without_interval_are_near_the_best_only_when_equal_to_it() {
        let cells = [rate(1.0, 1.0, 1.0), rate(1.0 - 1e-15, 1.0 - 1e-15, 1.0 - 1e-15), rate(0.0, 0.0, 0.0)];
        assert_eq!(near_best(&cells, "success"), [true, true, false]);
    }
}
