//! The compute budget: what deciding cost each policy per step, beside its figures, so a
//! slow planner and a fast network are compared knowing what each costs. A policy the
//! server drives is timed by the server's own clock (`RequestBody::Statistics`), one a
//! client runs by the client's, one sample per agent and step. Wall time is a
//! measurement of this machine, never part of an episode: it stays out of the episodes'
//! figures, which are the same bits on every run.

use std::fmt::Write as _;

use serde::Serialize;

use super::tables::number;

/// Whose clock timed a policy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Clock {
    /// The server's: a built-in driver in the learner's place.
    Server,
    /// The client's: a policy computed in the evaluating process.
    Client,
}

impl Clock {
    /// Its name in tables.
    pub fn name(self) -> &'static str {
        match self {
            Clock::Server => "server",
            Clock::Client => "client",
        }
    }
}

/// One policy's decision time per step on one scenario.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Budget {
    /// Scenario name.
    pub scenario: String,
    /// Policy name.
    pub policy: String,
    /// Whose clock.
    pub clock: Clock,
    /// Agent-steps timed.
    pub steps: usize,
    /// Median decision time per agent and step (µs); NaN with no steps.
    pub p50_us: f64,
    /// 99th percentile (µs); NaN with no steps.
    pub p99_us: f64,
}

impl Budget {
    /// The budget of `micros`, one decision time per agent and step (µs), in any order.
    pub fn new(scenario: &str, policy: &str, clock: Clock, micros: &[f32]) -> Budget {
        let mut sorted: Vec<f64> = micros.iter().map(|&us| f64::from(us)).collect();
        sorted.sort_by(f64::total_cmp);
        Budget {
            scenario: scenario.to_string(),
            policy: policy.to_string(),
            clock,
            steps: sorted.len(),
            p50_us: nearest_rank(&sorted, 50.0),
            p99_us: nearest_rank(&sorted, 99.0),
        }
    }
}

/// The nearest-rank `p`-th percentile of ascending `sorted`: the smallest sample with at
/// least p % of the samples at or below it; NaN when empty.
pub fn nearest_rank(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let rank = (p / 100.0 * sorted.len() as f64).ceil().max(1.0) as usize;
    sorted[rank.min(sorted.len()) - 1]
}

/// The budgets as a Markdown section, one table per scenario.
pub fn markdown(budgets: &[Budget]) -> String {
    let mut out = String::from(
        "## Compute budget\n\nWall time a policy spent deciding, per agent and step, on this machine: a built-in \
         driver timed by the server's clock (its decision and controller over the step's control periods), a \
         client's policy by the client's (the call that returned its action). Not part of any figure above.\n",
    );
    let mut scenarios: Vec<&str> = Vec::new();
    for budget in budgets {
        if !scenarios.contains(&budget.scenario.as_str()) {
            scenarios.push(&budget.scenario);
        }
    }
    for scenario in scenarios {
        let _ = write!(
            out,
            "\n### {scenario}\n\n| policy | clock | agent-steps | p50 (µs) | p99 (µs) |\n|---|---|---|---|---|\n"
        );
        for b in budgets.iter().filter(|b| b.scenario == scenario) {
            let _ = writeln!(
                out,
                "| {} | {} | {} | {} | {} |",
                b.policy,
                b.clock.name(),
                b.steps,
                number(b.p50_us),
                number(b.p99_us)
            );
        }
    }
    out
}

/// The budgets as CSV: scenario, policy, clock, steps, p50_us, p99_us.
pub fn csv(budgets: &[Budget]) -> String {
    let mut out = String::from("scenario,policy,clock,steps,p50_us,p99_us\n");
    for b in budgets {
        let _ = writeln!(out, "{},{},{},{},{},{}", b.scenario, b.policy, b.clock.name(), b.steps, b.p50_us, b.p99_us);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_are_nearest_rank() {
        let micros: Vec<f32> = (1..=200).rev().map(|k| k as f32).collect();
        let budget = Budget::new("merge", "expert", Clock::Server, &micros);
        // 200 samples 1..=200: the 100th and the 198th smallest.
        assert_eq!((budget.steps, budget.p50_us, budget.p99_us), (200, 100.0, 198.0));
        let one = Budget::new("merge", "idle", Clock::Client, &[7.5]);
        assert_eq!((one.p50_us, one.p99_us), (7.5, 7.5));
        assert!(Budget::new("merge", "idle", Clock::Client, &[]).p50_us.is_nan());
    }

    #[test]
    fn tables_name_each_policy_and_clock() {
        let budgets = [
            Budget::new("merge", "expert", Clock::Server, &[40.0, 60.0]),
            Budget::new("merge", "bc", Clock::Client, &[3.0]),
        ];
        let table = markdown(&budgets);
        assert!(table.contains("| expert | server | 2 | 40.0 | 60.0 |"), "{table}");
        assert!(table.contains("| bc | client | 1 | 3.00 | 3.00 |"), "{table}");
        assert_eq!(csv(&budgets).lines().nth(1), Some("merge,expert,server,2,40,60"));
    }
}
