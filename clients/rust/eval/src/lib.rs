//! Evaluation of highway-arena policies: the tables of `arena eval` and
//! `highway_arena.evaluate`, the estimators behind their intervals (`stats`), cross-play
//! against every opponent the AV can be (`crossplay`), leagues that accumulate
//! evaluations (`league`) and the compute each policy spent deciding (`budget`). One
//! implementation for the CLI and the Python extension, so a policy evaluated from Rust
//! and from Python gets the same figures. A crate of its own beside arena-client, which
//! stays the protocol client: evaluation needs only the infos of finished episodes
//! (`arena-protocol`), whoever played them, and never compiles the simulation
//! (scripts/check-deps).
//!
//! `Episode` is what one episode of one policy came to (read from the `episode_*` infos
//! the server adds to an agent's last step, docs/evaluation.md); `summarise` turns
//! episodes into a `Summary` per policy and scenario: rates with Wilson intervals, other
//! figures as median and IQM with bootstrap intervals (`stats`), and each policy's paired
//! differences from a reference policy over the shared seeds; `markdown`, `csv`, `json`
//! and the rest write them as `arena eval` and `highway_arena.evaluate` do.
//!
//! ```
//! use arena_eval::{Episode, FIGURES, Settings, markdown, summarise};
//! let episodes: Vec<Episode> = (0..10)
//!     .map(|seed| Episode {
//!         policy: "idm".into(),
//!         scenario: "merge".into(),
//!         seed,
//!         agent: "ego".into(),
//!         end_reason: "time_limit".into(),
//!         // Rates are 0 or 1 per episode; the other figures are numbers.
//!         figures: FIGURES.iter().map(|f| if f.rate { (seed % 2) as f64 } else { 10.0 + seed as f64 }).collect(),
//!     })
//!     .collect();
//! let summaries = summarise(&episodes, &Settings::default())?;
//! println!("{}", markdown(&summaries));
//! # Ok::<(), String>(())
//! ```
#![warn(missing_docs)]

use arena_protocol::info as key;
use arena_protocol::{EndReason, Info};
use serde::Serialize;

use crate::stats::{Bootstrap, Interval};

pub mod budget;
pub mod crossplay;
pub mod league;
pub mod stats;
mod tables;
pub use tables::{csv, differences_csv, episodes_csv, json, markdown};

/// Which way a figure is better, for the probability of improvement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Better {
    /// More is better (success, return, gaps).
    Higher,
    /// Less is better (crashes, costs, jerk).
    Lower,
    /// Neither (when a lane change began).
    Neither,
}

/// One figure of an episode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Figure {
    /// Its key in tables and JSON.
    pub key: &'static str,
    /// Its column heading.
    pub heading: &'static str,
    /// What it is.
    pub what: &'static str,
    /// Which way it is better.
    pub better: Better,
    /// Whether it is a rate of yes-or-no outcomes (Wilson intervals, differences as means).
    pub rate: bool,
}

const fn figure(key: &'static str, heading: &'static str, what: &'static str, better: Better, rate: bool) -> Figure {
    Figure { key, heading, what, better, rate }
}

/// The figures of an episode, in table order.
pub const FIGURES: [Figure; 14] = [
    figure(
        "success",
        "success",
        "reached the scenario's goal (merged, overtook, or drove on) without a crash, as a rate",
        Better::Higher,
        true,
    ),
    figure("collision", "collision", "ended in a collision, as a rate", Better::Lower, true),
    figure(
        "at_fault",
        "at fault",
        "ended in a collision it was at fault for (`at_fault`), as a rate",
        Better::Lower,
        true,
    ),
    figure("off_road", "off-road", "left the road or drove past its lane's end, as a rate", Better::Lower, true),
    figure("t_c", "t_c (s)", "when the first lane change began (episodes with one)", Better::Neither, false),
    figure("mean_speed", "speed (m/s)", "mean speed along the lane", Better::Higher, false),
    figure(
        "min_gap",
        "min gap (m)",
        "smallest bumper-to-bumper gap to the cars ahead and, changing lanes, behind",
        Better::Higher,
        false,
    ),
    figure(
        "min_ttc",
        "min TTC (s)",
        "smallest time to collision with those cars (episodes where a gap closed)",
        Better::Higher,
        false,
    ),
    figure(
        "rms_safety",
        "RMS safety",
        "RMS of the paper's J_ds over the episode, as `arena paper` (Tables V, VII)",
        Better::Lower,
        false,
    ),
    figure("rms_comfort", "RMS comfort", "RMS of J_rc", Better::Lower, false),
    figure("rms_efficiency", "RMS efficiency", "RMS of J_pe", Better::Lower, false),
    figure("return", "return", "sum of the rewards", Better::Higher, false),
    figure(
        "p95_jerk",
        "p95 jerk (m/s³)",
        "95th percentile of the commanded jerk, the change of acceleration between control periods",
        Better::Lower,
        false,
    ),
    figure("max_jerk", "max jerk (m/s³)", "largest commanded jerk", Better::Lower, false),
];

/// The position of figure `key` in `FIGURES`.
pub fn figure_index(key: &str) -> Option<usize> {
    FIGURES.iter().position(|f| f.key == key)
}

/// One agent's episode.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Episode {
    /// Policy name.
    pub policy: String,
    /// Scenario name.
    pub scenario: String,
    /// Reset seed.
    pub seed: u64,
    /// The agent.
    pub agent: String,
    /// How it ended (`end_reason`).
    pub end_reason: String,
    /// `FIGURES` in order; NaN where a figure does not apply (no lane change, no closing gap).
    pub figures: Vec<f64>,
}

impl Episode {
    /// The episode whose last info is `info`, or what is missing from it.
    pub fn from_info(policy: &str, scenario: &str, seed: u64, agent: &str, info: &Info) -> Result<Episode, String> {
        let number = |key: &str| {
            info.number(key).ok_or_else(|| {
                format!("the last info of {agent} has no `{key}`: is the server older than this client?")
            })
        };
        if number(key::EPISODE_DONE)? != 1.0 {
            return Err(format!("the info of {agent} is not its episode's last (`episode_done` is false)"));
        }
        let end = info.end_reason().ok_or_else(|| format!("the last info of {agent} has no known `end_reason`"))?;
        let finite = |v: f64| if v.is_finite() { v } else { f64::NAN };
        let figures = vec![
            number(key::EPISODE_SUCCESS)?,
            f64::from(u8::from(end == EndReason::Collision)),
            f64::from(u8::from(end == EndReason::Collision && number(key::AT_FAULT)? == 1.0)),
            f64::from(u8::from(matches!(end, EndReason::OffRoad | EndReason::LaneEnd))),
            // +inf when no lane change began.
            finite(number(key::EPISODE_T_C)?),
            number(key::EPISODE_MEAN_SPEED)?,
            finite(number(key::EPISODE_MIN_GAP)?),
            finite(number(key::EPISODE_MIN_TTC)?),
            number(key::EPISODE_RMS_SAFETY)?,
            number(key::EPISODE_RMS_COMFORT)?,
            number(key::EPISODE_RMS_EFFICIENCY)?,
            number(key::EPISODE_RETURN)?,
            number(key::EPISODE_P95_JERK)?,
            number(key::EPISODE_MAX_JERK)?,
        ];
        Ok(Episode {
            policy: policy.to_string(),
            scenario: scenario.to_string(),
            seed,
            agent: agent.to_string(),
            end_reason: end.name().to_string(),
            figures,
        })
    }
}

/// A figure over the `n` episodes where it applies.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Estimate {
    /// Episodes it applies to.
    pub n: usize,
    /// Mean (a rate for yes-or-no figures).
    pub mean: f64,
    /// Lower end of the mean's 95 % interval: Wilson's for a rate, Student's t otherwise
    /// (kept for the CSV and JSON; a heavy-tailed figure's t interval says little).
    pub low: f64,
    /// Upper end.
    pub high: f64,
    /// The median with its bootstrap interval (figures that are not rates).
    pub median: Option<Interval>,
    /// The interquartile mean with its bootstrap interval (figures that are not rates).
    pub iqm: Option<Interval>,
}

/// A policy against the reference policy on one figure, over the (seed, agent) pairs
/// where the figure applies to both.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Difference {
    /// Pairs.
    pub n: usize,
    /// Policy minus reference, pair by pair, summarised: the mean of the differences for a
    /// rate, their IQM otherwise; with its bootstrap interval over the pairs.
    pub difference: Interval,
    /// rliable's probability that the policy's figure is better than the reference's
    /// (`stats::probability_of_improvement`), where the figure has a better side.
    pub improvement: Option<Interval>,
}

/// One policy on one scenario.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    /// Scenario name.
    pub scenario: String,
    /// Policy name.
    pub policy: String,
    /// Episodes.
    pub episodes: usize,
    /// Distinct episodes (same end and figures to the bit): 1 when a deterministic scenario
    /// repeated one episode, whose figures then have no interval.
    pub distinct: usize,
    /// By `FIGURES` key.
    pub figures: Vec<(String, Estimate)>,
    /// The policy the differences are against; `None` for the reference itself.
    pub reference: Option<String>,
    /// By `FIGURES` key, against `reference`.
    pub differences: Vec<(String, Difference)>,
}

/// How summaries are computed.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Settings {
    /// The policy others are compared with; `None`: the first evaluated.
    pub reference: Option<String>,
    /// The resampling of every interval but Wilson's.
    pub bootstrap: Bootstrap,
}

/// Summaries per (scenario, policy), in the order each pair first appears, or why the
/// reference policy cannot be used.
pub fn summarise(episodes: &[Episode], settings: &Settings) -> Result<Vec<Summary>, String> {
    let mut pairs: Vec<(&str, &str)> = Vec::new();
    for e in episodes {
        if !pairs.contains(&(e.scenario.as_str(), e.policy.as_str())) {
            pairs.push((&e.scenario, &e.policy));
        }
    }
    let reference = match &settings.reference {
        Some(name) if !episodes.iter().any(|e| &e.policy == name) => {
            let names: Vec<&str> = pairs.iter().map(|p| p.1).collect();
            return Err(format!("the reference policy '{name}' was not evaluated (policies: {})", names.join(", ")));
        }
        Some(name) => Some(name.as_str()),
        None => episodes.first().map(|e| e.policy.as_str()),
    };
    let of = |scenario: &str, policy: &str| -> Vec<&Episode> {
        episodes.iter().filter(|e| e.scenario == scenario && e.policy == policy).collect()
    };
    let summaries = pairs
        .iter()
        .map(|&(scenario, policy)| {
            let mine = of(scenario, policy);
            let distinct = distinct(&mine);
            let figures = FIGURES
                .iter()
                .enumerate()
                .map(|(k, figure)| (figure.key.to_string(), estimate(figure, &values(&mine, k), distinct, settings)))
                .collect();
            let against = reference.filter(|&r| r != policy);
            let differences = match against {
                Some(r) => differences(&mine, &of(scenario, r), settings),
                None => Vec::new(),
            };
            Summary {
                scenario: scenario.to_string(),
                policy: policy.to_string(),
                episodes: mine.len(),
                distinct,
                figures,
                reference: against.map(str::to_string),
                differences,
            }
        })
        .collect();
    Ok(summaries)
}

/// Figure `k` of `episodes` where it applies.
fn values(episodes: &[&Episode], k: usize) -> Vec<f64> {
    episodes.iter().map(|e| e.figures[k]).filter(|v| !v.is_nan()).collect()
}

/// How many of `episodes` differ in their end or in some figure's bits.
fn distinct(episodes: &[&Episode]) -> usize {
    let mut seen: Vec<(&str, Vec<u64>)> = Vec::new();
    for e in episodes {
        let key = (e.end_reason.as_str(), e.figures.iter().map(|v| v.to_bits()).collect());
        if !seen.contains(&key) {
            seen.push(key);
        }
    }
    seen.len()
}

fn estimate(figure: &Figure, values: &[f64], distinct: usize, settings: &Settings) -> Estimate {
    let (mean, low, high) = if figure.rate { wilson(values) } else { t_interval(values) };
    let n = values.len();
    let (median, iqm) = match (figure.rate, n, distinct) {
        (true, ..) | (false, 0, _) => (None, None),
        (false, _, 1) => {
            let sorted = stats::sorted(values);
            (Some(Interval::exact(stats::median(&sorted))), Some(Interval::exact(stats::iqm(&sorted))))
        }
        (false, ..) => {
            let [median, iqm] = settings.bootstrap.median_and_iqm(values);
            (Some(median), Some(iqm))
        }
    };
    Estimate { n, mean, low, high, median, iqm }
}

/// Each figure of `mine` against `reference`'s, over the (seed, agent) pairs both played.
fn differences(mine: &[&Episode], reference: &[&Episode], settings: &Settings) -> Vec<(String, Difference)> {
    let pairs: Vec<(&Episode, &Episode)> = mine
        .iter()
        .filter_map(|e| Some((*e, *reference.iter().find(|r| r.seed == e.seed && r.agent == e.agent)?)))
        .collect();
    FIGURES
        .iter()
        .enumerate()
        .map(|(k, figure)| {
            let both: Vec<(f64, f64)> = pairs
                .iter()
                .map(|(e, r)| (e.figures[k], r.figures[k]))
                .filter(|(a, b)| !a.is_nan() && !b.is_nan())
                .collect();
            let gaps: Vec<f64> = both.iter().map(|(a, b)| a - b).collect();
            let summary: fn(&[f64]) -> f64 = if figure.rate { stats::mean } else { stats::iqm };
            let difference = match gaps.len() {
                0 => Interval::exact(f64::NAN),
                _ if gaps.iter().all(|&g| g == gaps[0]) => Interval::exact(gaps[0]),
                _ => settings.bootstrap.intervals(std::slice::from_ref(&gaps), |sorted| [summary(sorted)])[0],
            };
            let sign = match figure.better {
                Better::Higher => Some(1.0),
                Better::Lower => Some(-1.0),
                Better::Neither => None,
            };
            let improvement = sign.filter(|_| !both.is_empty()).map(|sign| {
                let (x, y): (Vec<f64>, Vec<f64>) = both.iter().map(|(a, b)| (sign * a, sign * b)).unzip();
                settings.bootstrap.improvement(&[x], &[y])
            });
            (figure.key.to_string(), Difference { n: gaps.len(), difference, improvement })
        })
        .collect()
}

/// The Wilson score interval of a rate (right at 0 and 1, where the normal one collapses).
fn wilson(outcomes: &[f64]) -> (f64, f64, f64) {
    let n = outcomes.len();
    if n == 0 {
        return (f64::NAN, f64::NAN, f64::NAN);
    }
    let (nf, z) = (n as f64, Z_975);
    let p = outcomes.iter().sum::<f64>() / nf;
    let centre = (p + z * z / (2.0 * nf)) / (1.0 + z * z / nf);
    let half = z / (1.0 + z * z / nf) * (p * (1.0 - p) / nf + z * z / (4.0 * nf * nf)).sqrt();
    (p, (centre - half).max(0.0), (centre + half).min(1.0))
}

/// Mean +- t_{0.975, n-1} s / sqrt(n).
fn t_interval(values: &[f64]) -> (f64, f64, f64) {
    let n = values.len();
    let mean = values.iter().sum::<f64>() / n as f64;
    if n < 2 {
        let (low, high) = if n == 1 { (f64::NEG_INFINITY, f64::INFINITY) } else { (f64::NAN, f64::NAN) };
        return (if n == 0 { f64::NAN } else { mean }, low, high);
    }
    let variance = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1) as f64;
    let half = t_975(n - 1) * (variance / n as f64).sqrt();
    (mean, mean - half, mean + half)
}

/// The 97.5 % quantile of the standard normal.
const Z_975: f64 = 1.959_963_984_540_054;

/// The 97.5 % quantile of Student's t with `df` degrees of freedom: a table to 30, then
/// the Cornish-Fisher expansion (error below 1e-5 there).
fn t_975(df: usize) -> f64 {
    const TABLE: [f64; 30] = [
        12.706_205, 4.302_653, 3.182_446, 2.776_445, 2.570_582, 2.446_912, 2.364_624, 2.306_004, 2.262_157, 2.228_139,
        2.200_985, 2.178_813, 2.160_369, 2.144_787, 2.131_450, 2.119_905, 2.109_816, 2.100_922, 2.093_024, 2.085_963,
        2.079_614, 2.073_873, 2.068_658, 2.063_899, 2.059_539, 2.055_529, 2.051_831, 2.048_407, 2.045_230, 2.042_272,
    ];
    if (1..=30).contains(&df) {
        return TABLE[df - 1];
    }
    let (z, v) = (Z_975, df.max(1) as f64);
    let (z3, z5, z7) = (z.powi(3), z.powi(5), z.powi(7));
    z + (z3 + z) / (4.0 * v)
        + (5.0 * z5 + 16.0 * z3 + 3.0 * z) / (96.0 * v * v)
        + (3.0 * z7 + 19.0 * z5 + 17.0 * z3 - 15.0 * z) / (384.0 * v.powi(3))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn t_quantiles_match_published_tables() {
        // Student's t, 97.5 %: 2.0423 (30), 2.0211 (40), 2.0003 (60), 1.9799 (120).
        for (df, t) in [(30, 2.042_272), (40, 2.021_075), (60, 2.000_298), (120, 1.979_930)] {
            assert!((t_975(df) - t).abs() < 2e-5, "df {df}: {} vs {t}", t_975(df));
        }
    }

    #[test]
    fn wilson_intervals_stay_inside_zero_one_and_match_a_worked_case() {
        let (mean, low, high) = wilson(&[0.0; 20]);
        assert_eq!((mean, low), (0.0, 0.0));
        // 0 of 20: the upper end is z^2 / (n + z^2) = 0.1611.
        assert!((high - 0.161_13).abs() < 1e-4, "{high}");
        let (_, low, high) = wilson(&[0.0, 1.0].repeat(10));
        assert!((low - 0.299_3).abs() < 1e-3 && (high - 0.700_7).abs() < 1e-3, "{low} {high}");
    }

    fn episode(policy: &str, seed: u64, t_c: f64, ret: f64) -> Episode {
        Episode {
            policy: policy.into(),
            scenario: "s".into(),
            seed,
            agent: "a".into(),
            end_reason: "time_limit".into(),
            figures: vec![1.0, 0.0, 0.0, 0.0, t_c, 20.0, 5.0, f64::NAN, 1.0, 1.0, 1.0, ret, 2.0, 3.0],
        }
    }

    fn get<'a>(summary: &'a Summary, key: &str) -> &'a Estimate {
        &summary.figures.iter().find(|(k, _)| k == key).expect("a figure").1
    }

    fn difference<'a>(summary: &'a Summary, key: &str) -> &'a Difference {
        &summary.differences.iter().find(|(k, _)| k == key).expect("a figure").1
    }

    #[test]
    fn figures_that_do_not_apply_are_left_out_of_their_estimates_only() {
        let episodes = [episode("p", 0, 2.0, 10.0), episode("p", 1, f64::NAN, 20.0), episode("p", 2, 4.0, 30.0)];
        let summary = &summarise(&episodes, &Settings::default()).expect("summaries")[0];
        assert_eq!((get(summary, "t_c").mean, get(summary, "t_c").n), (3.0, 2));
        assert_eq!((get(summary, "return").mean, get(summary, "return").n), (20.0, 3));
        // s = 10, n = 3: half-width t_{0.975,2} * 10 / sqrt(3) = 24.84.
        assert!((get(summary, "return").high - 20.0 - 4.302_653 * 10.0 / 3f64.sqrt()).abs() < 1e-9);
        // Three values: trim_mean cuts none (3 / 4 rounds to 0); the median is the middle.
        let (median, iqm) = (get(summary, "return").median.unwrap(), get(summary, "return").iqm.unwrap());
        assert_eq!((median.value, iqm.value), (20.0, 20.0));
        assert!(median.low >= 10.0 && median.high <= 30.0 && median.low < median.high, "{median:?}");
        assert_eq!(get(summary, "min_ttc").n, 0);
        assert!(get(summary, "min_ttc").iqm.is_none());
        let table = markdown(std::slice::from_ref(summary));
        assert!(table.contains("| s | p | 3 | 100 % [44, 100] |"), "{table}");
    }

    #[test]
    fn a_policy_against_itself_differs_by_exactly_zero() {
        let mut episodes: Vec<Episode> = (0..20).map(|s| episode("a", s, 1.0 + s as f64, (s * s) as f64)).collect();
        episodes.extend((0..20).map(|s| episode("b", s, 1.0 + s as f64, (s * s) as f64)));
        let summaries = summarise(&episodes, &Settings::default()).expect("summaries");
        let b = &summaries[1];
        assert_eq!(b.reference.as_deref(), Some("a"));
        for (key, d) in &b.differences {
            if key == "min_ttc" {
                assert_eq!(d.n, 0);
                continue;
            }
            assert_eq!(d.n, 20, "{key}");
            assert_eq!((d.difference.value, d.difference.low, d.difference.high), (0.0, 0.0, 0.0), "{key}");
            assert!(!d.difference.excludes_zero(), "{key}");
            if let Some(p) = d.improvement {
                assert_eq!(p.value, 0.5, "{key}: equal episodes are neither better nor worse");
            }
        }
        assert!(summaries[0].differences.is_empty(), "the reference has no difference from itself");
    }

    #[test]
    fn known_differences_on_known_seeds_are_found() {
        // b returns 5 more than a on every seed; a's returns spread widely, so the two
        // intervals of their own overlap while the paired difference is exact.
        let a: Vec<Episode> = (0..30).map(|s| episode("a", s, 2.0, 100.0 * s as f64)).collect();
        let mut b: Vec<Episode> = (0..30).map(|s| episode("b", s, 2.0, 100.0 * s as f64 + 5.0)).collect();
        // On seeds 0..10, b also changes lanes 1 s later.
        b.iter_mut().take(10).for_each(|e| e.figures[4] = 3.0);
        let episodes: Vec<Episode> = b.iter().chain(&a).cloned().collect();
        let settings = Settings { reference: Some("a".into()), ..Settings::default() };
        let summaries = summarise(&episodes, &settings).expect("summaries");
        let b = summaries.iter().find(|s| s.policy == "b").expect("b");
        let ret = difference(b, "return");
        assert_eq!((ret.n, ret.difference.value, ret.difference.low, ret.difference.high), (30, 5.0, 5.0, 5.0));
        assert!(ret.difference.excludes_zero());
        let own = (get(b, "return").iqm.unwrap(), get(&summaries[1], "return").iqm.unwrap());
        assert!(own.0.low < own.1.high, "the unpaired intervals overlap: {own:?}");
        // 10 of the 30 pairs differ by 1 s: the IQM keeps the middle 16 of the sorted
        // differences (7 cut from each end), 3 of which are 1: 3/16.
        let t_c = difference(b, "t_c");
        assert!((t_c.difference.value - 3.0 / 16.0).abs() < 1e-12, "{t_c:?}");
        assert!(t_c.improvement.is_none(), "a lane change's time has no better side");
        // Higher returns on every seed but from the same spread: rliable's P(b > a)
        // counts b's 100 s + 5 above a's 100 t for t <= s: (30 * 31 / 2) / 900.
        let p = ret.improvement.expect("return has a better side");
        assert!((p.value - 465.0 / 900.0).abs() < 1e-12, "{p:?}");
        let table = markdown(&summaries);
        assert!(table.contains("| s | b | 30 |") && table.contains("**+5.00**"), "{table}");
    }

    #[test]
    fn a_deterministic_scenario_says_it_repeated_one_episode() {
        let episodes: Vec<Episode> = (0..50).map(|s| episode("p", s, 2.0, 120.0)).collect();
        let summary = &summarise(&episodes, &Settings::default()).expect("summaries")[0];
        assert_eq!(summary.distinct, 1);
        assert_eq!(get(summary, "return").iqm, Some(Interval::exact(120.0)));
        let table = markdown(std::slice::from_ref(summary));
        assert!(table.contains("| s | p | 50 (1 distinct) | 100 % |"), "{table}");
        assert!(!table.contains("[93, 100]"), "{table}");
    }

    #[test]
    fn a_reference_that_was_not_evaluated_is_refused_by_name() {
        let episodes = [episode("p", 0, 2.0, 1.0)];
        let settings = Settings { reference: Some("ppo".into()), ..Settings::default() };
        let error = summarise(&episodes, &settings).expect_err("no such policy");
        assert!(error.contains("'ppo'") && error.contains("policies: p"), "{error}");
    }
}
