//! Evaluation figures: what one episode of one policy came to (read from the
//! `episode_*` infos the server adds to an agent's last step, docs/evaluation.md), and
//! their summaries per policy and scenario with 95 % intervals, as the tables of
//! `arena eval` and `highway_arena.evaluate` print and write them. One implementation for
//! both, so a policy evaluated from Rust and from Python gets the same figures.

use std::fmt::Write as _;

use arena_protocol::info as key;
use arena_protocol::{EndReason, Info};
use serde::Serialize;

/// The figures of an episode, in table order: (key, column heading, what it is).
pub const FIGURES: [(&str, &str, &str); 14] = [
    ("success", "success", "reached the scenario's goal (merged, overtook, or drove on) without a crash, as a rate"),
    ("collision", "collision", "ended in a collision, as a rate"),
    ("at_fault", "at fault", "ended in a collision it was at fault for (`at_fault`), as a rate"),
    ("off_road", "off-road", "left the road or drove past its lane's end, as a rate"),
    ("t_c", "t_c (s)", "when the first lane change began (episodes with one)"),
    ("mean_speed", "speed (m/s)", "mean speed along the lane"),
    ("min_gap", "min gap (m)", "smallest bumper-to-bumper gap to the cars ahead and, changing lanes, behind"),
    ("min_ttc", "min TTC (s)", "smallest time to collision with those cars (episodes where a gap closed)"),
    ("rms_safety", "RMS safety", "RMS of the paper's J_ds over the episode, as `arena paper` (Tables V, VII)"),
    ("rms_comfort", "RMS comfort", "RMS of J_rc"),
    ("rms_efficiency", "RMS efficiency", "RMS of J_pe"),
    ("return", "return", "sum of the rewards"),
    (
        "p95_jerk",
        "p95 jerk (m/s³)",
        "95th percentile of the commanded jerk, the change of acceleration between control periods",
    ),
    ("max_jerk", "max jerk (m/s³)", "largest commanded jerk"),
];

/// Figures that are rates of yes-or-no outcomes (Wilson intervals).
const RATES: usize = 4;

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

/// A figure over many episodes: its mean and 95 % interval over the `n` episodes where it
/// applies.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Estimate {
    /// Mean (a rate for yes-or-no figures).
    pub mean: f64,
    /// Lower end of the 95 % interval.
    pub low: f64,
    /// Upper end.
    pub high: f64,
    /// Episodes it applies to.
    pub n: usize,
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
    /// By `FIGURES` key.
    pub figures: Vec<(String, Estimate)>,
}

/// Summaries per (scenario, policy), in the order each pair first appears.
pub fn summarise(episodes: &[Episode]) -> Vec<Summary> {
    let mut pairs: Vec<(&str, &str)> = Vec::new();
    for e in episodes {
        if !pairs.contains(&(e.scenario.as_str(), e.policy.as_str())) {
            pairs.push((&e.scenario, &e.policy));
        }
    }
    pairs
        .into_iter()
        .map(|(scenario, policy)| {
            let mine: Vec<&Episode> =
                episodes.iter().filter(|e| e.scenario == scenario && e.policy == policy).collect();
            let figures = FIGURES
                .iter()
                .enumerate()
                .map(|(k, (key, ..))| {
                    let values: Vec<f64> = mine.iter().map(|e| e.figures[k]).filter(|v| !v.is_nan()).collect();
                    let estimate = if k < RATES { wilson(&values) } else { t_interval(&values) };
                    (key.to_string(), estimate)
                })
                .collect();
            Summary { scenario: scenario.to_string(), policy: policy.to_string(), episodes: mine.len(), figures }
        })
        .collect()
}

/// The Wilson score interval of a rate (right at 0 and 1, where the normal one collapses).
fn wilson(outcomes: &[f64]) -> Estimate {
    let n = outcomes.len();
    if n == 0 {
        return Estimate { mean: f64::NAN, low: f64::NAN, high: f64::NAN, n };
    }
    let (nf, z) = (n as f64, Z_975);
    let p = outcomes.iter().sum::<f64>() / nf;
    let centre = (p + z * z / (2.0 * nf)) / (1.0 + z * z / nf);
    let half = z / (1.0 + z * z / nf) * (p * (1.0 - p) / nf + z * z / (4.0 * nf * nf)).sqrt();
    Estimate { mean: p, low: (centre - half).max(0.0), high: (centre + half).min(1.0), n }
}

/// Mean +- t_{0.975, n-1} s / sqrt(n).
fn t_interval(values: &[f64]) -> Estimate {
    let n = values.len();
    let mean = values.iter().sum::<f64>() / n as f64;
    if n < 2 {
        let (low, high) = if n == 1 { (f64::NEG_INFINITY, f64::INFINITY) } else { (f64::NAN, f64::NAN) };
        return Estimate { mean: if n == 0 { f64::NAN } else { mean }, low, high, n };
    }
    let variance = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1) as f64;
    let half = t_975(n - 1) * (variance / n as f64).sqrt();
    Estimate { mean, low: mean - half, high: mean + half, n }
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

fn cell(estimate: &Estimate, rate: bool) -> String {
    match (estimate.n, rate) {
        (0, _) => "-".to_string(),
        (_, true) => {
            format!("{:.0} % [{:.0}, {:.0}]", estimate.mean * 100.0, estimate.low * 100.0, estimate.high * 100.0)
        }
        (1, false) => format!("{:.3}", estimate.mean),
        (_, false) => format!("{:.3} ± {:.3}", estimate.mean, (estimate.high - estimate.low) / 2.0),
    }
}

/// The summaries as a Markdown table: rates with their 95 % Wilson interval in brackets,
/// other figures as mean ± the half-width of their 95 % t interval.
pub fn markdown(summaries: &[Summary]) -> String {
    let mut out = String::from("| scenario | policy | episodes |");
    for (_, heading, _) in FIGURES {
        let _ = write!(out, " {heading} |");
    }
    out.push_str("\n|---|---|---:|");
    out.push_str(&"---:|".repeat(FIGURES.len()));
    out.push('\n');
    for summary in summaries {
        let _ = write!(out, "| {} | {} | {} |", summary.scenario, summary.policy, summary.episodes);
        for (k, (_, estimate)) in summary.figures.iter().enumerate() {
            let _ = write!(out, " {} |", cell(estimate, k < RATES));
        }
        out.push('\n');
    }
    out
}

/// The summaries as CSV: per figure its mean, interval ends and count.
pub fn csv(summaries: &[Summary]) -> String {
    let mut out = String::from("scenario,policy,episodes");
    for (key, ..) in FIGURES {
        let _ = write!(out, ",{key},{key}_low,{key}_high,{key}_n");
    }
    out.push('\n');
    for summary in summaries {
        let _ = write!(out, "{},{},{}", summary.scenario, summary.policy, summary.episodes);
        for (_, e) in &summary.figures {
            let _ = write!(out, ",{},{},{},{}", e.mean, e.low, e.high, e.n);
        }
        out.push('\n');
    }
    out
}

/// Every episode as CSV, one row each.
pub fn episodes_csv(episodes: &[Episode]) -> String {
    let mut out = String::from("scenario,policy,seed,agent,end_reason");
    for (key, ..) in FIGURES {
        let _ = write!(out, ",{key}");
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
    let figures = FIGURES.iter().map(|(key, _, what)| (*key, *what)).collect();
    serde_json::to_string_pretty(&Document { figures, summaries, episodes }).unwrap_or_default() + "\n"
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
        let none = wilson(&[0.0; 20]);
        assert_eq!((none.mean, none.low), (0.0, 0.0));
        // 0 of 20: the upper end is z^2 / (n + z^2) = 0.1611.
        assert!((none.high - 0.161_13).abs() < 1e-4, "{none:?}");
        let half = wilson(&[0.0, 1.0].repeat(10));
        assert!((half.low - 0.299_3).abs() < 1e-3 && (half.high - 0.700_7).abs() < 1e-3, "{half:?}");
    }

    #[test]
    fn figures_that_do_not_apply_are_left_out_of_their_mean_only() {
        let episode = |t_c: f64, ret: f64| Episode {
            policy: "p".into(),
            scenario: "s".into(),
            seed: 0,
            agent: "a".into(),
            end_reason: "time_limit".into(),
            figures: vec![1.0, 0.0, 0.0, 0.0, t_c, 20.0, 5.0, f64::NAN, 1.0, 1.0, 1.0, ret, 2.0, 3.0],
        };
        let summary = &summarise(&[episode(2.0, 10.0), episode(f64::NAN, 20.0), episode(4.0, 30.0)])[0];
        let get = |key: &str| summary.figures.iter().find(|(k, _)| k == key).unwrap().1;
        assert_eq!((get("t_c").mean, get("t_c").n), (3.0, 2));
        assert_eq!((get("return").mean, get("return").n), (20.0, 3));
        // s = 10, n = 3: half-width t_{0.975,2} * 10 / sqrt(3) = 24.84.
        assert!((get("return").high - 20.0 - 4.302_653 * 10.0 / 3f64.sqrt()).abs() < 1e-9);
        assert_eq!(get("min_ttc").n, 0);
        assert!(
            markdown(std::slice::from_ref(summary)).contains("| s | p | 3 | 100 % [44, 100] |"),
            "{}",
            markdown(std::slice::from_ref(summary))
        );
    }
}
