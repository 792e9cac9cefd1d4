//! The process-wide decision pool the stepper hands game-theoretic decisions to: one
//! thread fewer than the cores, kept warm between control periods, and the spin-waits
//! that keep a period's calling thread from sleeping while its helpers finish. Machinery
//! only: which thread decides a car never changes what it decides.

use std::sync::OnceLock;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::time::Duration;

use super::clock::Stopwatch;

/// The threads that help the calling thread decide a world's game-theoretic cars
/// (`Stepper::in_parallel`): one fewer than the cores, built on first use; `None` on one
/// core or if the threads cannot be made (the cars are then decided in turn).
pub(super) fn decision_pool() -> Option<&'static rayon::ThreadPool> {
    static POOL: OnceLock<Option<rayon::ThreadPool>> = OnceLock::new();
    POOL.get_or_init(|| {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let builder = rayon::ThreadPoolBuilder::new().num_threads(cores.checked_sub(1).filter(|&n| n > 0)?);
        builder.thread_name(|i| format!("decide-{i}")).build().ok()
    })
    .as_ref()
}

/// How many parallel sections have started in the process: a helper kept warm
/// (`keep_warm`) stops spinning when it changes.
static SECTIONS: AtomicU64 = AtomicU64::new(0);

/// How long a decision helper spins for the next control period's work before it may
/// sleep: 100 µs, several times the sequential part of a period (about 20 µs in
/// highway-gt). A sleeping rayon worker took about 25 µs to wake on this machine, once
/// per period, while the calling thread decided alone.
const WARM: Duration = Duration::from_micros(100);

/// Keeps each of `pool`'s threads busy spinning until the next parallel section starts or
/// `WARM` has passed, so that it takes that section's job at once rather than from sleep.
pub(super) fn keep_warm(pool: &rayon::ThreadPool) {
    let section = SECTIONS.load(Ordering::Relaxed);
    for _ in 0..pool.current_num_threads() {
        pool.spawn(move || {
            let watch = Stopwatch::start();
            while SECTIONS.load(Ordering::Relaxed) == section && watch.elapsed() < WARM {
                std::hint::spin_loop();
            }
        });
    }
}

/// Runs `job` on the decision pool's thread, which is still spinning from the last
/// control period and so starts it at once (`Stepper::decide_ahead` while a reply
/// travels); here if the process has no pool (one core).
pub fn beside_decisions(job: impl FnOnce() + Send + 'static) {
    match decision_pool() {
        Some(pool) => {
            pool.spawn(job);
            // Ends the spin it would otherwise wait behind, once the job is there to take.
            SECTIONS.fetch_add(1, Ordering::Relaxed);
        }
        None => job(),
    }
}

/// How many of a parallel section's helper jobs started its work and how many left it.
#[derive(Default)]
pub(super) struct Helpers {
    started: AtomicUsize,
    left: AtomicUsize,
}

/// Counts a helper out of a parallel section's work when dropped, on a panic too.
struct Leaving<'a>(&'a AtomicUsize);

impl Drop for Leaving<'_> {
    fn drop(&mut self) {
        self.0.fetch_add(1, Ordering::Release);
    }
}

/// Runs `work` on this thread and on `helpers` jobs of `scope`'s pool, and spins until
/// every helper that started has left it. rayon would otherwise park a calling thread
/// from outside the pool on a condition variable until its helpers' jobs end, and
/// waking it took about 25 µs on this machine, in every control period whose last
/// decision a helper made.
pub(super) fn alongside<'scope>(
    scope: &rayon::Scope<'scope>,
    helpers: usize,
    work: &'scope (impl Fn() + Sync),
    count: &'scope Helpers,
) {
    for _ in 0..helpers {
        scope.spawn(move |_| {
            count.started.fetch_add(1, Ordering::AcqRel);
            // Dropped when the work ends or panics (the scope then carries the panic here).
            let _leaving = Leaving(&count.left);
            work();
        });
    }
    // Ends the spin of a helper kept warm (`keep_warm`) now that its job is queued: it
    // takes the job at once rather than looking for work before it is there.
    SECTIONS.fetch_add(1, Ordering::Relaxed);
    work();
    // A helper not started by now finds no task left and ends at once; the scope waits
    // for it.
    while count.left.load(Ordering::Acquire) < count.started.load(Ordering::Acquire) {
        std::hint::spin_loop();
    }
}
