//! The stepper's only clock: wall time, which nothing in a world's state reads. It
//! measures how long each driver took to decide (a compute budget for `arena eval`, and
//! the order the next period's decisions are handed out in) and how long a decision
//! helper spins before it sleeps. Results never depend on it: the same state and inputs
//! give the same bits whatever it reads.

use std::time::{Duration, Instant};

/// A running measurement of wall time.
#[derive(Debug, Clone, Copy)]
pub(super) struct Stopwatch(Instant);

impl Stopwatch {
    pub(super) fn start() -> Stopwatch {
        Stopwatch(Instant::now())
    }

    pub(super) fn elapsed(&self) -> Duration {
        self.0.elapsed()
    }
}

/// `f`'s result and its wall time, when `timed`; zero, unmeasured, otherwise.
pub(super) fn timed<T>(timed: bool, f: impl FnOnce() -> T) -> (T, Duration) {
    if !timed {
        return (f(), Duration::ZERO);
    }
    let watch = Stopwatch::start();
    let value = f();
    (value, watch.elapsed())
}

/// Wall time each vehicle's driver spent deciding: since it was last taken, a
/// measurement for a compute budget (`arena eval`, when `on`); in its last decision, the
/// order the next ones are taken in.
#[derive(Debug, Clone, Default)]
pub(super) struct DecisionClock {
    pub(super) on: bool,
    spent: Vec<Duration>,
    last: Vec<Duration>,
}

impl DecisionClock {
    /// Notes that vehicle `index` (of `vehicles`) spent `spent` deciding.
    pub(super) fn note(&mut self, index: usize, vehicles: usize, spent: Duration) {
        self.last.resize(vehicles, Duration::ZERO);
        self.last[index] = spent;
        if self.on {
            self.spent.resize(vehicles, Duration::ZERO);
            self.spent[index] += spent;
        }
    }

    /// How long vehicle `index` took in its last decision (zero if unknown).
    pub(super) fn last(&self, index: usize) -> Duration {
        self.last.get(index).copied().unwrap_or_default()
    }

    pub(super) fn switch(&mut self, on: bool) {
        self.on = on;
        self.spent.clear();
    }

    /// The time vehicle `index` spent since the last call.
    pub(super) fn take(&mut self, index: usize) -> Duration {
        self.spent.get_mut(index).map_or(Duration::ZERO, std::mem::take)
    }
}
