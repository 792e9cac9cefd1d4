//! An env step allocates only what its reply owns (the protocol's messages own their
//! strings and arrays, which Zenoh then sends): the world, the rewards and the
//! observations work in buffers kept between steps. Counted by a global allocator that
//! counts, in a test binary of its own so no other test's allocations mix in.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use arena_protocol::{Action, CreateOptions, ObservationKind};
use arena_server::env::Env;
use arena_sim::scenario::builtin;

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static COUNTING: Counting = Counting;

fn allocations_of<T>(work: impl FnOnce() -> T) -> (T, usize) {
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    let value = work();
    (value, ALLOCATIONS.load(Ordering::Relaxed) - before)
}

#[test]
fn a_highway_step_allocates_only_what_its_reply_owns() {
    let scenario = builtin("highway").expect("built in").expect("parses");
    let options = CreateOptions { observation: Some(ObservationKind::Kinematics), ..CreateOptions::default() };
    let mut env = Env::new(scenario, &options, 1).expect("highway makes an env");
    env.reset(Some(4), &[]).expect("reset");
    let actions = vec![("ego_0".to_string(), Action::Meta(1))];
    // Buffers grow to their working size in the first steps (a lane's neighbour list
    // meets its most cars), then stay.
    for _ in 0..10 {
        env.step(&actions).expect("a warm-up step");
    }
    for step in 0..20 {
        let (reply, allocations) = allocations_of(|| env.step(&actions).expect("step"));
        // A clone allocates exactly what the reply owns: its list, the agent's name,
        // observation and info (each name in it a String of the protocol's).
        let (copy, owned) = allocations_of(|| reply.clone());
        assert_eq!(copy, reply);
        assert!(owned > 0);
        assert_eq!(allocations, owned, "step {step}: allocations beyond the reply's own");
    }
}
