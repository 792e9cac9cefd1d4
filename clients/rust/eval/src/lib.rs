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
    /// (kept for the CSV and JSON; a heavy-tailed figure's t interval says little); the
    /// mean itself when every episode was the same (one distinct episode).
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
    /// Distinct pairs (the two episodes of a pair the same to the bit as another pair's):
    /// the sample the interval and the probability of improvement are computed on, since
    /// copies of one pair are not independent draws.
    pub distinct: usize,
    /// Policy minus reference, pair by pair over the distinct pairs, a difference within
    /// the figures' resolution (`tie`) counted as 0, summarised: the mean of the differences
    /// for a rate, their IQM otherwise; with its bootstrap interval over those pairs (none,
    /// the value alone, from one distinct pair).
    pub difference: Interval,
    /// Whether the difference is significant: its interval, from at least two distinct
    /// pairs, leaves out zero. What the tables mark in bold.
    pub significant: bool,
    /// rliable's probability that the policy's figure is better than the reference's
    /// (`stats::probability_of_improvement`, ties within the resolution counting as equal)
    /// over the distinct pairs' figures, where the figure has a better side and there are
    /// at least two distinct pairs.
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
    /// The share of its episodes that ended in each of `OUTCOMES`, in that order (they sum
    /// to 1).
    pub outcomes: Vec<(String, f64)>,
    /// Where the figures disagree on whether the policy is better than the reference
    /// (`disagreement`): a comparison by one of them alone would mislead.
    pub warnings: Vec<String>,
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
            let warnings = against.and_then(|r| disagreement(r, &differences)).into_iter().collect();
            Summary {
                scenario: scenario.to_string(),
                policy: policy.to_string(),
                episodes: mine.len(),
                distinct,
                figures,
                reference: against.map(str::to_string),
                differences,
                outcomes: outcomes(&mine),
                warnings,
            }
        })
        .collect();
    Ok(summaries)
}

/// Figure `k` of `episodes` where it applies.
fn values(episodes: &[&Episode], k: usize) -> Vec<f64> {
    episodes.iter().map(|e| e.figures[k]).filter(|v| !v.is_nan()).collect()
}

/// An episode's end and figures to the bit: two episodes with the same key are copies.
fn bits(e: &Episode) -> (&str, Vec<u64>) {
    (e.end_reason.as_str(), e.figures.iter().map(|v| v.to_bits()).collect())
}

/// How many of `episodes` differ in their end or in some figure's bits.
fn distinct(episodes: &[&Episode]) -> usize {
    let mut seen: Vec<(&str, Vec<u64>)> = Vec::new();
    for e in episodes {
        let key = bits(e);
        if !seen.contains(&key) {
            seen.push(key);
        }
    }
    seen.len()
}

/// The relative resolution of a figure: two values closer than this share of the larger
/// differ by the rounding of the sums that made them (taken in another order), not by
/// what the policies did, and count as equal.
pub const RESOLUTION: f64 = 1e-9;

/// Whether `a` and `b` are equal within the figures' resolution.
pub fn tie(a: f64, b: f64) -> bool {
    a == b || (a - b).abs() <= RESOLUTION * a.abs().max(b.abs())
}

/// How an episode ended, each in one class: reached its goal, or else how it failed, or
/// that it ran out of time (or reached the road's end) without success. `Summary::outcomes`
/// gives each class's share; the rates plot stacks them, so a policy that just stops shows.
pub const OUTCOMES: [Outcome; 5] = [
    Outcome { key: "success", heading: "success" },
    Outcome { key: "collision", heading: "collision" },
    Outcome { key: "off_road", heading: "off-road" },
    Outcome { key: "lane_end", heading: "lane end" },
    Outcome { key: "no_success", heading: "time-out without success" },
];

/// One class of `OUTCOMES`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outcome {
    /// Its key in `Summary::outcomes` and JSON.
    pub key: &'static str,
    /// Its label in plots.
    pub heading: &'static str,
}

/// The position in `OUTCOMES` of how `e` ended.
fn outcome(e: &Episode) -> usize {
    let success = figure_index("success").is_some_and(|k| e.figures[k] == 1.0);
    let key = match e.end_reason.as_str() {
        _ if success => "success",
        end @ ("collision" | "off_road" | "lane_end") => end,
        _ => "no_success",
    };
    OUTCOMES.iter().position(|o| o.key == key).unwrap_or(OUTCOMES.len() - 1)
}

/// The share of `episodes` in each of `OUTCOMES`.
fn outcomes(episodes: &[&Episode]) -> Vec<(String, f64)> {
    let mut counts = [0usize; OUTCOMES.len()];
    episodes.iter().for_each(|e| counts[outcome(e)] += 1);
    let total = episodes.len().max(1) as f64;
    OUTCOMES.iter().zip(counts).map(|(o, count)| (o.key.to_string(), count as f64 / total)).collect()
}

fn estimate(figure: &Figure, values: &[f64], distinct: usize, settings: &Settings) -> Estimate {
    let (mean, low, high) = match (figure.rate, distinct) {
        // One episode repeated: its figure, with nothing to put an interval on.
        (_, 1) if !values.is_empty() => (values[0], values[0], values[0]),
        (true, _) => wilson(values),
        (false, _) => t_interval(values),
    };
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
    let (mut seen, mut distinct) = (Vec::new(), Vec::new());
    for &(e, r) in &pairs {
        let key = (bits(e), bits(r));
        if !seen.contains(&key) {
            seen.push(key);
            distinct.push((e, r));
        }
    }
    FIGURES
        .iter()
        .enumerate()
        .map(|(k, figure)| {
            let applies = |(e, r): &&(&Episode, &Episode)| !e.figures[k].is_nan() && !r.figures[k].is_nan();
            let n = pairs.iter().filter(applies).count();
            let both: Vec<(f64, f64)> =
                distinct.iter().filter(applies).map(|(e, r)| (e.figures[k], r.figures[k])).collect();
            (figure.key.to_string(), difference(figure, n, &both, settings))
        })
        .collect()
}

/// The difference of one figure over `n` pairs whose distinct values are `both` (policy,
/// reference).
fn difference(figure: &Figure, n: usize, both: &[(f64, f64)], settings: &Settings) -> Difference {
    let gaps: Vec<f64> = both.iter().map(|&(a, b)| if tie(a, b) { 0.0 } else { a - b }).collect();
    let summary: fn(&[f64]) -> f64 = if figure.rate { stats::mean } else { stats::iqm };
    let difference = match gaps.len() {
        0 => Interval::exact(f64::NAN),
        _ if gaps.iter().all(|&g| g == gaps[0]) => Interval::exact(gaps[0]),
        _ => settings.bootstrap.intervals(std::slice::from_ref(&gaps), |sorted| [summary(sorted)])[0],
    };
    let sampled = gaps.len() >= 2;
    let sign = match figure.better {
        Better::Higher => Some(1.0),
        Better::Lower => Some(-1.0),
        Better::Neither => None,
    };
    let improvement = sign.filter(|_| sampled).map(|sign| {
        let (x, y): (Vec<f64>, Vec<f64>) = both.iter().map(|(a, b)| (sign * a, sign * b)).unzip();
        settings.bootstrap.improvement(&[x], &[y])
    });
    Difference { n, distinct: gaps.len(), difference, significant: sampled && difference.excludes_zero(), improvement }
}

/// Which way a difference points for the policy: 1 better, -1 worse, 0 neither (or
/// unknown): the probability of improvement's side of 0.5 where there is one, else the
/// paired difference's sign on the figure's better side.
fn direction(figure: &Figure, d: &Difference) -> f64 {
    let sign = match figure.better {
        Better::Higher => 1.0,
        Better::Lower => -1.0,
        Better::Neither => return 0.0,
    };
    let leaning = match d.improvement {
        Some(p) => p.value - 0.5,
        None => sign * d.difference.value,
    };
    if leaning.is_nan() || leaning.abs() <= RESOLUTION { 0.0 } else { leaning.signum() }
}

/// A warning when success, the primary figure, and the return disagree on whether the
/// policy beats `reference`: the return of a policy that runs off its lane's end can
/// still be higher, so a comparison by return alone would hide the failures.
fn disagreement(reference: &str, differences: &[(String, Difference)]) -> Option<String> {
    let of = |key: &str| {
        let figure = FIGURES.iter().find(|f| f.key == key)?;
        let (_, d) = differences.iter().find(|(k, _)| k == key)?;
        Some((direction(figure, d), d))
    };
    let ((success, s), (ret, r)) = (of("success")?, of("return")?);
    if success * ret >= 0.0 {
        return None;
    }
    let word = |direction: f64| if direction > 0.0 { "better" } else { "worse" };
    let how = |d: &Difference| match d.improvement {
        Some(p) => format!("probability of improvement {:.2}", p.value),
        None => format!("difference {}", tables::number(d.difference.value)),
    };
    Some(format!(
        "success says {} than `{reference}` ({}) but return says {} ({}): compare them by success first; the \
         return alone hides how episodes ended",
        word(success),
        how(s),
        word(ret),
        how(r)
    ))
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

    /// Two policies on a scenario without randomness: every seed gives each the same
    /// episode, so 50 pairs are one, whatever their difference.
    #[test]
    fn one_distinct_pair_gets_a_value_without_interval_mark_or_probability() {
        let mut episodes: Vec<Episode> = (0..50).map(|s| episode("nash", s, 2.0, 97.0)).collect();
        episodes.extend((0..50).map(|s| episode("stackelberg", s, 2.5, 95.42)));
        let summaries = summarise(&episodes, &Settings::default()).expect("summaries");
        let ret = difference(&summaries[1], "return");
        assert_eq!((ret.n, ret.distinct), (50, 1));
        assert!((ret.difference.value - (95.42 - 97.0)).abs() < 1e-12, "{ret:?}");
        assert_eq!(ret.difference.low, ret.difference.high, "no interval from one pair");
        assert!(!ret.significant && ret.improvement.is_none(), "{ret:?}");
        let table = markdown(&summaries);
        assert!(!table.contains("| **"), "nothing is significant from one distinct pair:\n{table}");
        let improvement = table.split("Probability of improvement").nth(1).expect("the table");
        assert!(improvement.contains("| s | stackelberg | 50 (deterministic: 1 distinct pair) | - | - |"), "{table}");
        assert!(table.contains("| 50 (1 distinct) | 100 % |"), "{table}");
    }

    /// A rate's Wilson interval from 50 copies of one episode would claim [93, 100].
    #[test]
    fn one_distinct_episode_has_no_rate_interval() {
        let episodes: Vec<Episode> = (0..50).map(|s| episode("p", s, 2.0, 120.0)).collect();
        let success = get(&summarise(&episodes, &Settings::default()).expect("summaries")[0], "success").to_owned();
        assert_eq!((success.mean, success.low, success.high), (1.0, 1.0, 1.0));
    }

    #[test]
    fn differences_within_the_resolution_are_ties() {
        let a: Vec<Episode> = (0..30).map(|s| episode("a", s, 2.0, 10.0 * s as f64)).collect();
        let mut b = a.clone();
        for e in &mut b {
            e.policy = "b".into();
            // 3 + 8.88e-16: two units in the last place, what a sum in another order gives.
            e.figures[13] += 8.88e-16;
            assert_ne!(e.figures[13], 3.0);
        }
        let summaries = summarise(&[a, b].concat(), &Settings::default()).expect("summaries");
        let jerk = difference(&summaries[1], "max_jerk");
        assert_eq!((jerk.distinct, jerk.difference.value, jerk.difference.high), (30, 0.0, 0.0), "{jerk:?}");
        assert!(!jerk.significant, "{jerk:?}");
        assert_eq!(jerk.improvement.map(|p| p.value), Some(0.5), "tied episodes are neither better nor worse");
        let table = markdown(&summaries);
        assert!(!table.contains("| **"), "no bold cell:\n{table}");
        assert!(tie(1e6, 1e6 + 1e-4) && !tie(1e6, 1e6 + 1e-2) && !tie(0.0, 1e-300) && tie(-0.0, 0.0));
    }

    /// A policy that runs off its lane's end on a third of the seeds but earns more on
    /// every step of the others: by return alone it looks better.
    #[test]
    fn success_and_return_that_disagree_are_warned_of() {
        let a: Vec<Episode> = (0..30).map(|s| episode("expert", s, 2.0, 100.0 + s as f64)).collect();
        let mut b: Vec<Episode> = (0..30).map(|s| episode("bc", s, 2.0, 120.0 + s as f64)).collect();
        for e in b.iter_mut().take(10) {
            e.end_reason = "lane_end".into();
            (e.figures[0], e.figures[3]) = (0.0, 1.0);
        }
        let summaries = summarise(&[a, b].concat(), &Settings::default()).expect("summaries");
        let bc = &summaries[1];
        assert!(difference(bc, "success").improvement.expect("success").value < 0.5);
        assert!(difference(bc, "return").improvement.expect("return").value > 0.5);
        assert_eq!(bc.warnings.len(), 1, "{:?}", bc.warnings);
        assert!(bc.warnings[0].starts_with("success says worse than `expert`"), "{}", bc.warnings[0]);
        let table = markdown(&summaries);
        assert!(table.contains("- **Warning**, bc on s: success says worse"), "{table}");
        assert!(summaries[0].warnings.is_empty(), "the reference compares with nothing");
        let shares: Vec<f64> = bc.outcomes.iter().map(|(_, share)| *share).collect();
        assert_eq!(shares, [20.0 / 30.0, 0.0, 0.0, 10.0 / 30.0, 0.0], "{:?}", bc.outcomes);
    }

    #[test]
    fn a_policy_that_stops_shows_as_time_out_without_success() {
        let mut stopped = episode("stop", 0, f64::NAN, 0.0);
        stopped.figures[0] = 0.0;
        let summary = &summarise(&[stopped], &Settings::default()).expect("summaries")[0];
        let timeout = summary.outcomes.iter().find(|(key, _)| key == "no_success").expect("the class");
        assert_eq!(timeout.1, 1.0, "{:?}", summary.outcomes);
    }

    #[test]
    fn a_reference_that_was_not_evaluated_is_refused_by_name() {
        let episodes = [episode("p", 0, 2.0, 1.0)];
        let settings = Settings { reference: Some("ppo".into()), ..Settings::default() };
        let error = summarise(&episodes, &settings).expect_err("no such policy");
        assert!(error.contains("'ppo'") && error.contains("policies: p"), "{error}");
    }
}
