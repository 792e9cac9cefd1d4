//! Robust statistics of evaluation figures, as Agarwal et al. (2021, "Deep Reinforcement
//! Learning at the Edge of the Statistical Precipice") recommend and rliable implements
//! them: the median and the interquartile mean (IQM) of per-episode values with percentile
//! intervals from a stratified bootstrap (episodes resampled within each scenario), and
//! the probability of improvement. A near miss costs 1e7 where a typical episode costs
//! tens, so a mean with a t interval says little about such figures; these estimators
//! ignore a few extreme episodes by construction.
//!
//! The bootstrap draws from a seeded ChaCha stream, so the same episodes give the same
//! interval ends on every run and machine. Point estimates equal rliable's (but for the
//! probability of improvement's rounding ties, `crate::tie`, which rliable counts as a
//! win or a loss); interval ends agree with rliable's within Monte Carlo error (tests
//! against a fixture rliable computed, `scripts/rliable-fixture`).

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::tie;

/// A point estimate with its 95 % interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Interval {
    /// The estimate on the data itself.
    pub value: f64,
    /// Lower end of the 95 % interval.
    pub low: f64,
    /// Upper end.
    pub high: f64,
}

impl Interval {
    /// An estimate without an interval (one distinct episode: nothing to resample).
    pub fn exact(value: f64) -> Interval {
        Interval { value, low: value, high: value }
    }

    /// Whether the interval leaves out zero on one side.
    pub fn excludes_zero(&self) -> bool {
        self.low > 0.0 || self.high < 0.0
    }
}

/// numpy's `percentile` (linear interpolation) of ascending `sorted` values, `q` in
/// [0, 100]; NaN when there are none.
pub fn percentile(sorted: &[f64], q: f64) -> f64 {
    let Some(last) = sorted.len().checked_sub(1) else { return f64::NAN };
    let position = q / 100.0 * last as f64;
    let (below, above) = (position.floor() as usize, position.ceil() as usize);
    let t = position - below as f64;
    let (a, b) = (sorted[below], sorted[above.min(last)]);
    // numpy's lerp: from the nearer end, so that t = 1 gives b exactly.
    if t >= 0.5 { b - (b - a) * (1.0 - t) } else { a + (b - a) * t }
}

/// The median (numpy's: the mean of the two middle values of an even count) of ascending
/// `sorted` values.
pub fn median(sorted: &[f64]) -> f64 {
    let n = sorted.len();
    match n {
        0 => f64::NAN,
        _ if n % 2 == 1 => sorted[n / 2],
        _ => (sorted[n / 2 - 1] + sorted[n / 2]) / 2.0,
    }
}

/// The interquartile mean of ascending `sorted` values: the mean of what is left when a
/// quarter (rounded down) is cut from each end, as `scipy.stats.trim_mean(x, 0.25)` and
/// rliable's `aggregate_iqm` compute it.
pub fn iqm(sorted: &[f64]) -> f64 {
    let cut = sorted.len() / 4;
    let middle = &sorted[cut..sorted.len() - cut];
    if middle.is_empty() {
        return f64::NAN;
    }
    middle.iter().sum::<f64>() / middle.len() as f64
}

/// The mean.
pub fn mean(values: &[f64]) -> f64 {
    values.iter().sum::<f64>() / values.len() as f64
}

/// An ascending copy of `values`, which hold no NaN.
pub fn sorted(values: &[f64]) -> Vec<f64> {
    let mut out = values.to_vec();
    out.sort_by(f64::total_cmp);
    out
}

/// rliable's probability of improvement of X over Y: per task (stratum), the Mann-Whitney
/// U statistic of X against Y over the product of their counts, P(x > y) + P(x = y) / 2
/// (equal: within the figures' resolution, `crate::tie`)
/// for an x and a y drawn at random; averaged over the tasks. `x[t]` and `y[t]` are task
/// t's values. NaN when a task has no values on one side.
pub fn probability_of_improvement(x: &[Vec<f64>], y: &[Vec<f64>]) -> f64 {
    let tasks: Vec<f64> = x.iter().zip(y).map(|(x, y)| wins(x, &sorted(y))).collect();
    mean(&tasks)
}

/// P(x > y) + P(x = y) / 2 over `x` and ascending `y`, values within the figures'
/// resolution (`crate::tie`) counting as equal.
fn wins(x: &[f64], y: &[f64]) -> f64 {
    if x.is_empty() || y.is_empty() {
        return f64::NAN;
    }
    let mut wins = 0.0;
    for &value in x {
        let below = y.partition_point(|&v| v < value && !tie(v, value));
        let equal = y[below..].partition_point(|&v| v < value || tie(v, value));
        wins += below as f64 + 0.5 * equal as f64;
    }
    wins / (x.len() * y.len()) as f64
}

/// A seeded stratified bootstrap: each resample draws, within every stratum, as many
/// values as it holds, with replacement; a statistic's interval is the 2.5th and 97.5th
/// percentiles of its values over the resamples (rliable's `percentile` method).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Bootstrap {
    /// Resamples.
    pub reps: usize,
    /// Seed of the resampling.
    pub seed: u64,
}

impl Default for Bootstrap {
    /// 5 000 resamples, seed 0: interval ends within about 1 % of their width of
    /// rliable's 50 000 on 100 episodes, in well under a second per table.
    fn default() -> Self {
        Bootstrap { reps: 5_000, seed: 0 }
    }
}

impl Bootstrap {
    /// The intervals of `K` statistics computed together on each resample: `statistics`
    /// gets the resample's values (stratum after stratum, each sorted ascending within
    /// its stratum, so that one stratum's order statistics need no sort of their own) and
    /// returns the K figures. The point estimates are the statistics of the data itself.
    pub fn intervals<const K: usize>(
        &self,
        strata: &[Vec<f64>],
        statistics: impl Fn(&[f64]) -> [f64; K],
    ) -> [Interval; K] {
        let data: Vec<f64> = strata.iter().flat_map(|s| sorted(s)).collect();
        let values = statistics(&data);
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        let mut draws: [Vec<f64>; K] = std::array::from_fn(|_| Vec::with_capacity(self.reps));
        let mut resample = Vec::with_capacity(data.len());
        for _ in 0..self.reps {
            resample.clear();
            for stratum in strata.iter().filter(|s| !s.is_empty()) {
                let start = resample.len();
                resample.extend((0..stratum.len()).map(|_| stratum[rng.random_range(0..stratum.len())]));
                resample[start..].sort_by(f64::total_cmp);
            }
            for (draw, value) in draws.iter_mut().zip(statistics(&resample)) {
                draw.push(value);
            }
        }
        std::array::from_fn(|k| {
            let draw = sorted(&draws[k]);
            Interval { value: values[k], low: percentile(&draw, 2.5), high: percentile(&draw, 97.5) }
        })
    }

    /// The median and IQM of one stratum's values with their intervals.
    pub fn median_and_iqm(&self, values: &[f64]) -> [Interval; 2] {
        self.intervals(&[values.to_vec()], |sorted| [median(sorted), iqm(sorted)])
    }

    /// rliable's probability of improvement of `x` over `y` (task by task, as
    /// `probability_of_improvement`) with its interval, `x` and `y` resampled independently
    /// within each task (rliable's `StratifiedIndependentBootstrap`).
    pub fn improvement(&self, x: &[Vec<f64>], y: &[Vec<f64>]) -> Interval {
        let value = probability_of_improvement(x, y);
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        let draw = |values: &[f64], rng: &mut ChaCha8Rng| -> Vec<f64> {
            (0..values.len()).map(|_| values[rng.random_range(0..values.len())]).collect()
        };
        let mut draws = Vec::with_capacity(self.reps);
        for _ in 0..self.reps {
            let tasks: Vec<f64> = x
                .iter()
                .zip(y)
                .map(|(x, y)| {
                    let (x, y) = (draw(x, &mut rng), draw(y, &mut rng));
                    wins(&x, &sorted(&y))
                })
                .collect();
            draws.push(mean(&tasks));
        }
        let draws = sorted(&draws);
        Interval { value, low: percentile(&draws, 2.5), high: percentile(&draws, 97.5) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What rliable computed on fixed heavy-tailed figures (`scripts/rliable-fixture`).
    fn fixture() -> serde_json::Value {
        let text = include_str!("../tests/fixtures/rliable.json");
        serde_json::from_str(text).expect("the fixture is JSON")
    }

    fn tasks(value: &serde_json::Value) -> Vec<Vec<f64>> {
        let tasks = value.as_array().expect("tasks");
        // As text: `str::parse` rounds correctly, serde_json's own float parsing may not.
        let value = |v: &serde_json::Value| v.as_str().expect("a number as text").parse::<f64>().expect("a number");
        tasks.iter().map(|t| t.as_array().expect("runs").iter().map(value).collect()).collect()
    }

    fn number(value: &serde_json::Value) -> f64 {
        value.as_f64().expect("a number")
    }

    /// Equal up to the order of a sum's terms (numpy sums pairwise).
    fn same(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * a.abs().max(b.abs())
    }

    /// Interval ends of two bootstraps of the same data (ours 5 000 resamples, rliable's
    /// 50 000 or 20 000) differ by Monte Carlo error: within `share` of the interval's width.
    fn near(ours: &Interval, theirs: &serde_json::Value, share: f64, what: &str) {
        let (low, high) = (number(&theirs[0]), number(&theirs[1]));
        let width = high - low;
        assert!(
            (ours.low - low).abs() <= share * width && (ours.high - high).abs() <= share * width,
            "{what}: ours [{}, {}], rliable's [{low}, {high}]",
            ours.low,
            ours.high
        );
    }

    #[test]
    fn median_and_iqm_equal_rliables_and_their_intervals_agree() {
        let f = fixture();
        for (name, key) in [("x", "x"), ("y", "y")] {
            let all = tasks(&f[key]);
            for (case, strata) in [("one_task", vec![all[0].clone()]), ("two_tasks", all.clone())] {
                let expected = &f[case][name];
                let [median, iqm] = Bootstrap::default().intervals(&strata, |s| {
                    let pooled = sorted(s);
                    [super::median(&pooled), super::iqm(&pooled)]
                });
                let what = format!("{case} {name}");
                assert!(same(median.value, number(&expected["median"])), "{what}: median {median:?}");
                assert!(same(iqm.value, number(&expected["iqm"])), "{what}: IQM {iqm:?}");
                near(&median, &expected["median_interval"], 0.05, &format!("{what} median"));
                near(&iqm, &expected["iqm_interval"], 0.05, &format!("{what} IQM"));
            }
        }
    }

    #[test]
    fn probability_of_improvement_equals_rliables_and_its_interval_agrees() {
        let f = fixture();
        let (x, y) = (tasks(&f["x"]), tasks(&f["y"]));
        let expected = &f["improvement_y_over_x"];
        let ours = Bootstrap::default().improvement(&y, &x);
        // rliable compares exactly, so 34.800000000000004 beats 34.8 there (twice in the
        // fixture); here such rounding ties are equal, each worth half a win, not a win.
        let shift: f64 = y
            .iter()
            .zip(&x)
            .map(|(y, x)| {
                let ties = y.iter().flat_map(|a| x.iter().map(move |b| (a, b)));
                let rounding = ties.filter(|(a, b)| a != b && (*a - *b).abs() <= 1e-9 * a.abs().max(b.abs()));
                rounding.map(|(a, b)| -0.5 * (a - b).signum()).sum::<f64>() / (y.len() * x.len()) as f64
            })
            .sum::<f64>()
            / y.len() as f64;
        assert!(shift != 0.0, "the fixture holds rounding ties");
        let theirs = number(&expected["value"]) + shift;
        assert!(same(ours.value, theirs), "{ours:?} vs {theirs} (rliable's {})", expected["value"]);
        near(&ours, &expected["interval"], 0.05, "probability of improvement");
    }

    #[test]
    fn order_statistics_match_numpys_on_small_cases() {
        // numpy: median([1, 2, 3, 4]) = 2.5, percentile([1, 2, 3, 4], 2.5) = 1.075,
        // percentile(..., 97.5) = 3.925; trim_mean([1..=9], 0.25) cuts 2 each side: 5.
        assert_eq!(median(&[1.0, 2.0, 3.0, 4.0]), 2.5);
        assert!((percentile(&[1.0, 2.0, 3.0, 4.0], 2.5) - 1.075).abs() < 1e-15);
        assert!((percentile(&[1.0, 2.0, 3.0, 4.0], 97.5) - 3.925).abs() < 1e-15);
        let nine: Vec<f64> = (1..=9).map(f64::from).collect();
        assert_eq!(iqm(&nine), 5.0);
        assert_eq!(iqm(&[1.0, 2.0, 3.0, 1e9]), 2.5, "a quarter of 4 is cut from each end");
    }

    #[test]
    fn the_same_data_and_seed_give_the_same_bits() {
        let values: Vec<f64> = (0..57).map(|i| f64::from(i * i % 17) * 1.5).collect();
        let a = Bootstrap::default().median_and_iqm(&values);
        let b = Bootstrap::default().median_and_iqm(&values);
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
        let other = Bootstrap { seed: 1, ..Bootstrap::default() }.median_and_iqm(&values);
        assert_ne!(format!("{a:?}"), format!("{other:?}"), "the seed is what the resampling draws from");
    }
}
