//! Our Tables IV and VI against the paper's, cell by cell: every t_c, gap and speed at
//! t_c of a run that changes lanes in the paper, with its relative error. `arena paper`
//! prints these errors, and `arena calibrate` fits to them.

use arena_sim::Game;
use arena_sim::Style;

use crate::{PaperScenario, Record, reference};

/// The band a cell must fall in to count as reproduced (issue 14: ±30 %).
pub const TOLERANCE: f64 = 0.30;

/// What a cell holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Figure {
    /// t_c (s).
    DecisionTime,
    /// Gap to an adjacent car at t_c (m); the index is into `PaperScenario::roles()`.
    Gap(usize),
    /// Speed of a car at t_c (m/s); the index is into `PaperScenario::roles()`.
    Speed(usize),
}

impl Figure {
    /// "t_c (s)", "gap AC (m)", "v EC (m/s)".
    pub fn label(self, scenario: PaperScenario) -> String {
        let role = |k: usize| scenario.roles()[k].1;
        match self {
            Figure::DecisionTime => "t_c (s)".to_string(),
            Figure::Gap(k) => format!("gap {} (m)", role(k)),
            Figure::Speed(k) => format!("v {} (m/s)", role(k)),
        }
    }
}

/// One published figure of Tables IV or VI beside ours.
#[derive(Debug, Clone, PartialEq)]
pub struct Cell {
    /// Which scenario.
    pub scenario: PaperScenario,
    /// Which style.
    pub style: Style,
    /// Which game.
    pub game: Game,
    /// Which figure.
    pub figure: Figure,
    /// Ours; none when our EC did not change lanes.
    pub ours: Option<f64>,
    /// The paper's.
    pub paper: f64,
}

impl Cell {
    /// |ours - paper| / |paper|; infinite when ours is missing.
    pub fn relative_error(&self) -> f64 {
        self.ours.map_or(f64::INFINITY, |ours| (ours - self.paper).abs() / self.paper.abs())
    }

    /// Whether ours is within `TOLERANCE` of the paper's.
    pub fn within(&self) -> bool {
        self.relative_error() <= TOLERANCE
    }
}

/// The figures of one record, paired with the paper's (none for a run the paper has
/// keep its lane: Scenario B's conservative car).
pub fn cells_of(record: &Record, scenario: PaperScenario, style: Style, game: Game) -> Vec<Cell> {
    let paper = reference(scenario, style, game);
    let Some(t_c) = paper.t_c else { return Vec::new() };
    let roles = scenario.roles();
    let cell = |figure, ours, paper| Cell { scenario, style, game, figure, ours, paper };
    let mut cells = vec![cell(Figure::DecisionTime, record.t_c, t_c)];
    for (k, (_, role)) in roles.iter().enumerate().skip(1) {
        cells.push(cell(Figure::Gap(k), record.gaps_at_t_c.get(*role).copied(), paper.gaps[*role]));
    }
    for (k, (_, role)) in roles.iter().enumerate() {
        cells.push(cell(Figure::Speed(k), record.speeds_at_t_c.get(*role).copied(), paper.speeds[*role]));
    }
    cells
}

/// Every cell of the records given (each names its scenario, style and game).
pub fn cells(records: &[Record]) -> Vec<Cell> {
    records
        .iter()
        .flat_map(|r| {
            let scenario = PaperScenario::ALL.into_iter().find(|s| s.name() == r.scenario).expect("a paper scenario");
            let style = Style::ALL.into_iter().find(|s| s.name() == r.style).expect("a style");
            let game = Game::ALL.into_iter().find(|g| g.name() == r.game).expect("a game");
            cells_of(r, scenario, style, game)
        })
        .collect()
}

/// (cells within `TOLERANCE`, all cells).
pub fn score(cells: &[Cell]) -> (usize, usize) {
    (cells.iter().filter(|c| c.within()).count(), cells.len())
}

/// "+12 %" or "-" when ours is missing.
pub fn signed_error(cell: &Cell) -> String {
    match cell.ours {
        Some(ours) => format!("{:+.0} %", (ours - cell.paper) / cell.paper.abs() * 100.0),
        None => "-".to_string(),
    }
}

/// The count within ±30 %, per table and overall, and how every Stackelberg lane change
/// compares with its Nash twin (later? larger gap?), as `arena paper` prints them.
pub fn summary(records: &[Record]) -> String {
    let all = cells(records);
    let mut out = String::from("\nWithin ±30 % of the paper (t_c, gaps and speeds at t_c):\n");
    for scenario in PaperScenario::ALL {
        let ours: Vec<Cell> = all.iter().filter(|c| c.scenario == scenario).cloned().collect();
        let decisive: Vec<Cell> = ours.iter().filter(|c| !matches!(c.figure, Figure::Speed(_))).cloned().collect();
        let ((w, n), (dw, dn)) = (score(&ours), score(&decisive));
        out += &format!("  Scenario {}: {w} of {n} cells; t_c and gaps {dw} of {dn}\n", scenario.name());
    }
    let (w, n) = score(&all);
    out += &format!("  both: {w} of {n} cells\n\nStackelberg against its Nash twin (paper: later, larger gap):\n");
    for (scenario, style, ne, se) in twins(records) {
        let (Some(t_ne), Some(t_se)) = (ne.t_c, se.t_c) else { continue };
        let gaps = |r: &Record| r.gaps_at_t_c.values().map(|g| format!("{g:.2}")).collect::<Vec<_>>().join("/");
        out += &format!(
            "  {} {}: t_c {t_ne:.2} -> {t_se:.2} s ({}), gap {} -> {} m ({})\n",
            scenario.name(),
            style.name(),
            if t_se > t_ne {
                "later"
            } else if t_se == t_ne {
                "same"
            } else {
                "earlier"
            },
            gaps(ne),
            gaps(se),
            if larger_gaps(ne, se) { "larger" } else { "not larger" }
        );
    }
    out
}

/// (scenario, style, Nash record, Stackelberg record) for every pair in `records`.
pub fn twins(records: &[Record]) -> Vec<(PaperScenario, Style, &Record, &Record)> {
    let mut out = Vec::new();
    for scenario in PaperScenario::ALL {
        for style in Style::ALL {
            let find = |game: Game| {
                records
                    .iter()
                    .find(|r| r.scenario == scenario.name() && r.style == style.name() && r.game == game.name())
            };
            if let (Some(ne), Some(se)) = (find(Game::Nash), find(Game::Stackelberg)) {
                out.push((scenario, style, ne, se));
            }
        }
    }
    out
}

/// Whether every gap of `se` at its t_c is larger in size (more room, ahead or behind)
/// than the same car's gap in `ne`.
pub fn larger_gaps(ne: &Record, se: &Record) -> bool {
    !ne.gaps_at_t_c.is_empty()
        && ne.gaps_at_t_c.iter().all(|(role, g)| se.gaps_at_t_c.get(role).is_some_and(|s| s.abs() > g.abs()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    fn record(t_c: Option<f64>, gap: f64) -> Record {
        Record {
            scenario: "A".into(),
            style: "normal".into(),
            game: "nash".into(),
            t_c,
            gaps_at_t_c: BTreeMap::from([("AC".to_string(), gap)]),
            speeds_at_t_c: BTreeMap::from([("EC".to_string(), 23.25), ("AC".to_string(), 20.76)]),
            lane_change: arena_sim::LaneChange::Left,
            collision: false,
            rms_cost: Default::default(),
            inexact_decisions: 0,
            diagnostics: BTreeMap::new(),
        }
    }

    #[test]
    fn a_merge_run_has_four_cells_and_errors_relative_to_the_paper() {
        // Table IV, normal NE: t_c 5.04 s, gap 18.06 m, EC 23.25 m/s, AC 20.76 m/s.
        let cells = cells(&[record(Some(6.552), 18.06 * 1.31)]);
        assert_eq!(cells.len(), 4);
        assert!((cells[0].relative_error() - 0.3).abs() < 1e-9 && cells[0].within());
        assert!(!cells[1].within(), "31 % off is out");
        assert_eq!(score(&cells), (3, 4));
        assert_eq!(signed_error(&cells[0]), "+30 %");
        let missing = super::cells(&[record(None, 0.0)]);
        assert!(missing[0].relative_error().is_infinite() && signed_error(&missing[0]) == "-");
    }
}
