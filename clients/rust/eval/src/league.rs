//! A league: evaluations that accumulate. A league file (JSON) holds the episodes of every
//! policy ever added to it with the settings they were played under (first seed, episode
//! count, episode length) and the scenarios played; a run is added only when its
//! settings are the file's, so every row of a scenario met the same episodes. A run may
//! bring scenarios the league has not seen (they join its list: a policy trained for one
//! scenario is ranked on that one only). Adding a policy the league already holds on a
//! scenario replaces its episodes there (a re-evaluation). `league.md` ranks the policies
//! of each scenario by one figure with its interval, from the same estimators as the
//! tables (`summarise`).

use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

use super::tables::{number, percent};
use super::{Episode, FIGURES, Settings, Summary, figure_index, summarise};

/// The version of the league file's layout.
pub const LEAGUE_VERSION: u32 = 1;

/// What every run of a league must share.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct LeagueSettings {
    /// Scenario names, in the order the league shows them (a league's list grows as runs
    /// bring scenarios; a run's list is the scenarios it played).
    pub scenarios: Vec<String>,
    /// Seed of the first episode.
    pub seed: u64,
    /// Episodes per policy and scenario.
    pub episodes: u64,
    /// Episode length in steps, when a run set it instead of each scenario's.
    pub max_cycles: Option<u32>,
}

/// One episode as the file stores it (a figure that does not apply is null).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Stored {
    policy: String,
    scenario: String,
    seed: u64,
    agent: String,
    end_reason: String,
    figures: Vec<Option<f64>>,
}

/// The league file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct File {
    version: u32,
    settings: LeagueSettings,
    episodes: Vec<Stored>,
}

/// A league: its settings and every episode of its policies.
#[derive(Debug, Clone, PartialEq)]
pub struct League {
    /// What every run shares.
    pub settings: LeagueSettings,
    /// By scenario, then policy in the order they joined, then seed.
    pub episodes: Vec<Episode>,
}

impl League {
    /// An empty league of these settings.
    pub fn new(settings: LeagueSettings) -> League {
        League { settings, episodes: Vec::new() }
    }

    /// The league a file holds, or what is wrong with it.
    pub fn from_json(text: &str) -> Result<League, String> {
        let file: File = serde_json::from_str(text).map_err(|e| format!("not a league file: {e}"))?;
        if file.version != LEAGUE_VERSION {
            return Err(format!(
                "a league file of version {}; this arena reads version {LEAGUE_VERSION}",
                file.version
            ));
        }
        let mut episodes = Vec::with_capacity(file.episodes.len());
        for (k, e) in file.episodes.into_iter().enumerate() {
            if e.figures.len() != FIGURES.len() {
                return Err(format!("episode {k} has {} figures, not {}", e.figures.len(), FIGURES.len()));
            }
            let figures = e.figures.into_iter().map(|v| v.unwrap_or(f64::NAN)).collect();
            let Stored { policy, scenario, seed, agent, end_reason, .. } = e;
            episodes.push(Episode { policy, scenario, seed, agent, end_reason, figures });
        }
        Ok(League { settings: file.settings, episodes })
    }

    /// The league as a file.
    pub fn to_json(&self) -> String {
        let episodes = self
            .episodes
            .iter()
            .map(|e| Stored {
                policy: e.policy.clone(),
                scenario: e.scenario.clone(),
                seed: e.seed,
                agent: e.agent.clone(),
                end_reason: e.end_reason.clone(),
                figures: e.figures.iter().map(|v| v.is_finite().then_some(*v)).collect(),
            })
            .collect();
        let file = File { version: LEAGUE_VERSION, settings: self.settings.clone(), episodes };
        serde_json::to_string_pretty(&file).unwrap_or_default() + "\n"
    }

    /// Adds a run played under `settings`: its policies join on its scenarios (or replace
    /// their earlier episodes there), and scenarios new to the league join its list.
    /// Refused, naming each difference, when the seeds, episode count or length are not
    /// the league's.
    pub fn add(&mut self, settings: &LeagueSettings, episodes: &[Episode]) -> Result<(), String> {
        let mine = &self.settings;
        let mut differences = Vec::new();
        if settings.seed != mine.seed {
            differences.push(format!("first seed {}, not the league's {}", settings.seed, mine.seed));
        }
        if settings.episodes != mine.episodes {
            differences.push(format!("{} episodes, not the league's {}", settings.episodes, mine.episodes));
        }
        if settings.max_cycles != mine.max_cycles {
            let show = |m: Option<u32>| m.map_or("each scenario's".to_string(), |n| n.to_string());
            differences.push(format!(
                "episode length {}, not the league's {}",
                show(settings.max_cycles),
                show(mine.max_cycles)
            ));
        }
        if !differences.is_empty() {
            return Err(format!(
                "this run cannot join the league: its rows would not have met the same episodes ({}); run it with \
                 the league's settings, or give it a league file of its own",
                differences.join("; ")
            ));
        }
        for scenario in settings.scenarios.iter().chain(episodes.iter().map(|e| &e.scenario)) {
            if !self.settings.scenarios.contains(scenario) {
                self.settings.scenarios.push(scenario.clone());
            }
        }
        let joining = |e: &Episode| episodes.iter().any(|j| j.policy == e.policy && j.scenario == e.scenario);
        self.episodes.retain(|e| !joining(e));
        self.episodes.extend(episodes.iter().cloned());
        let mine = &self.settings;
        let order = |scenario: &str| mine.scenarios.iter().position(|s| s == scenario).unwrap_or(usize::MAX);
        // Stable: policies keep the order they joined in within a scenario.
        self.episodes.sort_by_key(|e| order(&e.scenario));
        Ok(())
    }

    /// The league's summaries (`summarise`).
    pub fn summaries(&self, settings: &Settings) -> Result<Vec<Summary>, String> {
        summarise(&self.episodes, settings)
    }
}

/// The value a league ranks by: a rate's mean, another figure's IQM.
fn ranked_value(summary: &Summary, k: usize) -> (f64, f64, f64) {
    let e = &summary.figures[k].1;
    match e.iqm {
        Some(i) => (i.value, i.low, i.high),
        None => (e.mean, e.low, e.high),
    }
}

/// `league.md`: per scenario, the policies ranked by figure `rank` (best first by the
/// figure's better side; a rate by its mean with its Wilson interval, another figure by
/// its IQM with its bootstrap interval), beside success, at-fault collisions and return.
pub fn league_markdown(league: &League, summaries: &[Summary], rank: &str) -> Result<String, String> {
    let k = figure_index(rank).ok_or_else(|| {
        let keys: Vec<&str> = FIGURES.iter().map(|f| f.key).collect();
        format!("unknown figure '{rank}' to rank by (figures: {})", keys.join(", "))
    })?;
    let figure = &FIGURES[k];
    let sign = match figure.better {
        super::Better::Higher => -1.0,
        super::Better::Lower => 1.0,
        super::Better::Neither => return Err(format!("'{rank}' has no better side to rank by")),
    };
    let s = &league.settings;
    let mut out = format!(
        "# League\n\n{} episodes per policy and scenario, seeds {}..{}{}, every policy on the same episodes; ranked \
         by {} ({}), best first. Rates: mean [95 % Wilson]; other figures: IQM [95 % bootstrap].\n",
        s.episodes,
        s.seed,
        s.seed.saturating_add(s.episodes.saturating_sub(1)),
        s.max_cycles.map_or(String::new(), |n| format!(", {n} steps per episode")),
        figure.heading,
        if sign < 0.0 { "higher is better" } else { "lower is better" },
    );
    // Beside the ranked figure, these, less the ranked one (no column twice).
    let shown: Vec<usize> =
        ["success", "at_fault", "return"].iter().filter_map(|key| figure_index(key)).filter(|&j| j != k).collect();
    for scenario in &s.scenarios {
        let mut rows: Vec<&Summary> = summaries.iter().filter(|x| &x.scenario == scenario).collect();
        if rows.is_empty() {
            continue;
        }
        rows.sort_by(|a, b| (sign * ranked_value(a, k).0).total_cmp(&(sign * ranked_value(b, k).0)));
        let _ = write!(out, "\n## {scenario}\n\n| rank | policy | {} |", figure.heading);
        for &j in &shown {
            let _ = write!(out, " {} |", FIGURES[j].heading);
        }
        out.push_str("\n|---:|---|---:|");
        out.push_str(&"---:|".repeat(shown.len()));
        out.push('\n');
        for (place, row) in rows.iter().enumerate() {
            let _ = write!(out, "| {} | {} |", place + 1, row.policy);
            for j in std::iter::once(k).chain(shown.iter().copied()) {
                let (value, low, high) = ranked_value(row, j);
                let show = if FIGURES[j].rate { |v: f64| format!("{} %", percent(v)) } else { number };
                let cell = if row.distinct == 1 || low == high {
                    show(value)
                } else {
                    format!("{} [{}, {}]", show(value), show(low), show(high))
                };
                let _ = write!(out, " {cell} |");
            }
            out.push('\n');
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(seed: u64) -> LeagueSettings {
        LeagueSettings { scenarios: vec!["s".into()], seed, episodes: 3, max_cycles: None }
    }

    fn run(policy: &str, ret: f64) -> Vec<Episode> {
        (0..3)
            .map(|seed| Episode {
                policy: policy.into(),
                scenario: "s".into(),
                seed,
                agent: "a".into(),
                end_reason: "time_limit".into(),
                figures: vec![
                    1.0,
                    0.0,
                    0.0,
                    0.0,
                    f64::NAN,
                    20.0,
                    5.0,
                    f64::NAN,
                    1.0,
                    1.0,
                    1.0,
                    ret + seed as f64,
                    2.0,
                    3.0,
                ],
            })
            .collect()
    }

    #[test]
    fn a_run_whose_seeds_differ_is_refused_and_one_that_matches_joins() {
        let mut league = League::new(settings(0));
        league.add(&settings(0), &run("a", 10.0)).expect("the first run joins");
        let refused = league.add(&settings(5), &run("b", 20.0)).expect_err("other seeds");
        assert!(refused.contains("first seed 5, not the league's 0"), "{refused}");
        let longer = LeagueSettings { max_cycles: Some(40), episodes: 4, ..settings(0) };
        let refused = league.add(&longer, &run("b", 20.0)).expect_err("other settings");
        assert!(
            refused.contains("4 episodes, not the league's 3") && refused.contains("episode length 40"),
            "{refused}"
        );
        assert_eq!(league.episodes.len(), 3, "a refused run adds nothing");
        league.add(&settings(0), &run("b", 20.0)).expect("matching settings join");
        assert_eq!(league.episodes.len(), 6);
        // Re-evaluating a policy replaces its episodes.
        league.add(&settings(0), &run("a", 30.0)).expect("a again");
        assert_eq!(league.episodes.len(), 6);
        // A policy of another scenario joins there only, and the scenario joins the list.
        let other: Vec<Episode> = run("a", 50.0).into_iter().map(|e| Episode { scenario: "t".into(), ..e }).collect();
        let on_t = LeagueSettings { scenarios: vec!["t".into()], ..settings(0) };
        league.add(&on_t, &other).expect("another scenario joins");
        assert_eq!(league.settings.scenarios, ["s", "t"]);
        assert_eq!(league.episodes.len(), 9, "a's episodes on s stay beside its new ones on t");
        let summaries = league.summaries(&Settings::default()).expect("summaries");
        let table = league_markdown(&league, &summaries, "return").expect("a table");
        let (first_a, first_b) = (table.find("| a |").expect("a ranked"), table.find("| b |").expect("b ranked"));
        assert!(first_a < first_b, "a (31 on average) ranks above b (21): {table}");
        assert!(table.contains("| 1 | a | 31.0 [30.0, 32.0]"), "{table}");
        let t = table.find("## t").expect("t has its own ranking");
        assert!(table[t..].contains("| 1 | a | 51.0 [50.0, 52.0]") && !table[t..].contains("| b |"), "{table}");
    }

    #[test]
    fn a_league_survives_its_file_bit_for_bit() {
        let mut league = League::new(settings(0));
        league.add(&settings(0), &run("a", 10.0)).expect("joins");
        let text = league.to_json();
        let back = League::from_json(&text).expect("reads back");
        assert_eq!(back.to_json(), text);
        assert_eq!(back.episodes[0].figures[11].to_bits(), league.episodes[0].figures[11].to_bits());
        assert!(back.episodes[0].figures[4].is_nan(), "a figure that does not apply stays NaN");
        assert!(League::from_json("{}").expect_err("not a league").contains("not a league file"));
        let future = text.replace("\"version\": 1", "\"version\": 9");
        assert!(League::from_json(&future).expect_err("newer").contains("version 9"));
        let summaries = back.summaries(&Settings::default()).expect("summaries");
        let error = league_markdown(&back, &summaries, "t_c").expect_err("no better side");
        assert!(error.contains("no better side"), "{error}");
        assert!(league_markdown(&back, &summaries, "speedy").expect_err("unknown").contains("unknown figure 'speedy'"));
    }
}
