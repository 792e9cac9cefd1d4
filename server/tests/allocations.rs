//! The lean step path: the world's ticks allocate nothing once running (every tick
//! reuses the buffers of earlier ones: scene, neighbour index, RK4 fleet, collision
//! sweep), and an env step allocates only what its reply owns (the protocol's messages
//! own their strings and arrays, which Zenoh then sends). Counted by a global allocator
//! that counts per thread, so tests running side by side do not mix.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use arena_protocol::{Action, CreateOptions, ObservationKind};
use arena_server::env::Env;
use arena_sim::builtin_scenario;

struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

fn count() {
    ALLOCATIONS.with(|count| count.set(count.get() + 1));
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static COUNTING: Counting = Counting;

fn allocations_of<T>(work: impl FnOnce() -> T) -> (T, usize) {
    let before = ALLOCATIONS.with(Cell::get);
    let value = work();
    (value, ALLOCATIONS.with(Cell::get) - before)
}

#[test]
fn highway_ticks_allocate_nothing_once_warm() {
    let mut world = builtin_scenario("highway").expect("built in").expect("parses").build(3);
    let mut stepper = arena_sim::Stepper::new();
    stepper.advance(&mut world, 5.0);
    let start = world.time();
    let ((), allocations) = allocations_of(|| stepper.advance(&mut world, 20.0));
    assert!(world.time() > start + 19.0, "the world advanced");
    assert_eq!(allocations, 0, "allocations in 20 simulated seconds of highway.toml");
}

#[test]
fn a_highway_step_allocates_only_what_its_reply_owns() {
    let scenario = builtin_scenario("highway").expect("built in").expect("parses");
    let options = CreateOptions { observation: Some(ObservationKind::Kinematics), ..CreateOptions::default() };
    let mut env = Env::new(scenario, &options, 1).expect("highway makes an env");
    env.reset(Some(4), &arena_protocol::ResetOptions::default()).expect("reset");
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
