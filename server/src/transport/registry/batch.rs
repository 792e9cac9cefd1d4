//! Steps of many envs in one request: checked as a whole, then spread over a pool of one
//! thread per core (built once, by the first batch), each env's result its own. The pool
//! gives way to single requests, so one client's big batch does not hold up another's step.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use arena_protocol::{BatchItem, BatchStep, ClientId, EnvId, ErrorCode, ErrorReply, ReplyBody};
use rayon::prelude::*;

use super::{Registry, error};

/// The longest a batch worker waits, before each env, for single requests to be answered.
const GIVE_WAY_AT_MOST: Duration = Duration::from_millis(2);

/// The batch pool: as many threads as cores; `None` (batches step on the caller's
/// thread) if no thread can be started.
pub(super) fn batch_workers() -> Option<rayon::ThreadPool> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    rayon::ThreadPoolBuilder::new().num_threads(threads).thread_name(|i| format!("batch-{i}")).build().ok()
}

/// Counts a single request as being answered for as long as it lives.
pub(super) struct Single<'a>(&'a AtomicUsize);

impl<'a> Single<'a> {
    pub(super) fn begin(count: &'a AtomicUsize) -> Single<'a> {
        count.fetch_add(1, Ordering::SeqCst);
        Single(count)
    }
}

impl Drop for Single<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

impl Registry {
    /// A batch names each env once and no more envs than one client may hold, so its
    /// reply (one result per env) stays bounded whatever a request asks.
    pub(super) fn check_batch(&self, steps: &[BatchStep]) -> Result<(), ErrorReply> {
        let most = self.limits.max_envs_per_client.min(self.limits.max_envs);
        if steps.len() > most {
            return Err(error(
                ErrorCode::MalformedRequest,
                format!(
                    "a batch of {} steps is more than the {most} envs a client may hold on this server",
                    steps.len()
                ),
                true,
            ));
        }
        let mut envs: Vec<EnvId> = steps.iter().map(|step| step.env).collect();
        envs.sort_unstable();
        if let Some(pair) = envs.windows(2).find(|pair| pair[0] == pair[1]) {
            return Err(error(
                ErrorCode::MalformedRequest,
                format!("env {} appears twice in one batch: step each env once per batch", pair[0]),
                true,
            ));
        }
        Ok(())
    }

    /// Sleeps while single requests are being answered (up to `GIVE_WAY_AT_MOST`), so
    /// the cores go to them first. Before that, the worker yields its core once: a Zenoh
    /// thread woken by a single request that has not reached the server yet runs then,
    /// not when the scheduler would next preempt a busy worker (milliseconds later).
    fn give_way(&self) {
        std::thread::yield_now();
        let started = Instant::now();
        while self.singles.load(Ordering::SeqCst) > 0 && started.elapsed() < GIVE_WAY_AT_MOST {
            std::thread::sleep(Duration::from_micros(50));
        }
    }

    pub(super) fn step_batch(&self, client: ClientId, steps: &[BatchStep]) -> Vec<BatchItem> {
        let one = |step: &BatchStep| -> BatchItem {
            let body = self.sequenced(client, step.env, step.seq, |env| {
                self.step_reply(env, step.seq, &step.actions).map(ReplyBody::Step)
            });
            match body {
                Ok(ReplyBody::Step(step)) => BatchItem::Ok(step),
                Ok(ReplyBody::Error(err)) | Err(err) => BatchItem::Err(err),
                // The seq last answered a reset of this env: report it, step nothing.
                Ok(_) => BatchItem::Err(error(
                    ErrorCode::StaleSequence,
                    format!("sequence number {} was used by a reset of this env", step.seq),
                    true,
                )),
            }
        };
        let guarded = |step: &BatchStep| {
            self.give_way();
            one(step)
        };
        match self.batch_workers.get_or_init(batch_workers) {
            Some(workers) if steps.len() >= 4 && workers.current_num_threads() > 1 => {
                workers.install(|| steps.par_iter().map(guarded).collect())
            }
            _ => steps.iter().map(guarded).collect(),
        }
    }
}
