//! Where requests are computed: off Zenoh's receive threads, on the runtime's blocking
//! pool, at most `at_once` of one party's at a time. A party that sends many expensive
//! requests waits in its own queue (an async semaphore: no thread is held while it
//! waits), so another client's request starts at once whatever the first one asks, and
//! Zenoh's threads only ever hand requests over.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use tokio::runtime::Handle;
use tokio::sync::Semaphore;

use super::limits::Party;

/// Parties with a queue of their own before those with nothing in flight are forgotten.
const QUEUES_KEPT: usize = 1024;

/// The queues of requests by party.
pub struct Dispatch {
    runtime: Handle,
    at_once: usize,
    queues: Mutex<HashMap<Party, Arc<Semaphore>>>,
}

impl Dispatch {
    /// Requests run on `runtime`'s blocking pool, `at_once` of one party's at a time.
    pub fn new(runtime: Handle, at_once: usize) -> Dispatch {
        Dispatch { runtime, at_once: at_once.max(1), queues: Mutex::new(HashMap::new()) }
    }

    /// Runs `work` for `party` once fewer than `at_once` of its requests are running.
    /// Returns at once.
    pub fn run(&self, party: Party, work: impl FnOnce() + Send + 'static) {
        let queue = self.queue(party);
        let runtime = self.runtime.clone();
        match Arc::clone(&queue).try_acquire_owned() {
            Ok(turn) => drop(runtime.spawn_blocking(move || {
                work();
                drop(turn);
            })),
            Err(_) => drop(self.runtime.spawn(async move {
                // The semaphore is never closed, so the wait ends with a turn.
                if let Ok(turn) = queue.acquire_owned().await {
                    drop(runtime.spawn_blocking(move || {
                        work();
                        drop(turn);
                    }));
                }
            })),
        }
    }

    fn queue(&self, party: Party) -> Arc<Semaphore> {
        let mut queues = self.queues.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        if queues.len() >= QUEUES_KEPT {
            // A queue someone holds a turn of, or waits on, is shared beyond this map.
            queues.retain(|_, queue| Arc::strong_count(queue) > 1);
        }
        Arc::clone(queues.entry(party).or_insert_with(|| Arc::new(Semaphore::new(self.at_once))))
    }
}
