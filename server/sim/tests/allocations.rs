//! The world step allocates nothing once running: every tick of highway.toml's traffic
//! (IDM/MOBIL decisions, scene, neighbour index, RK4 fleet, collision sweep) reuses the
//! buffers of earlier ticks. Counted by a global allocator that counts, in a test binary
//! of its own so no other test's allocations mix in.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use arena_sim::scenario;

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

#[test]
fn highway_ticks_allocate_nothing_once_warm() {
    let highway = scenario::builtin("highway").expect("highway is built in").expect("highway.toml parses");
    let mut world = highway.build(3);
    world.advance(5.0);
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    let start = world.time();
    world.advance(20.0);
    let allocations = ALLOCATIONS.load(Ordering::Relaxed) - before;
    assert!(world.time() > start + 19.0, "the world advanced");
    assert_eq!(allocations, 0, "allocations in 20 simulated seconds of highway.toml");
}
