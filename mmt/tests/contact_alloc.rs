//! Proxy steps allocate nothing once the neighbour buffer has grown (issue 3: "no per-step
//! allocation"). A counting global allocator watches this thread only.

// A global allocator is the one way to observe allocations; the blocks below only forward to
// the system allocator.
#![allow(unsafe_code)]
#![allow(clippy::unwrap_used)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use mmt::contact::{CloudIndex, Neighbours, Proxy, workload};

struct Counting;

thread_local! {
    // `const` initialisation without a destructor: using it never allocates.
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

fn count() {
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
}

fn allocations() -> u64 {
    ALLOCATIONS.with(Cell::get)
}

// SAFETY: every method forwards its arguments, under the same contract, to `System`.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: the caller upholds `GlobalAlloc::alloc`'s contract; passed on unchanged.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: as for `alloc`.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: `ptr` was allocated by `System` (through this allocator) with `layout`.
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `System` (through this allocator) with `layout`.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// One period of the workload's HIP path is 4 s (2 Hz in and out, 0.25 Hz around).
const PERIOD: usize = 4_000;

fn steady_state_allocations<N: Neighbours>(cloud: &N, w: &workload::Workload) -> u64 {
    let mut proxy = Proxy::new(w.config, w.hips[0]).unwrap();
    // Warm up over one period: the buffer grows to the largest neighbourhood of the path.
    for hip in &w.hips[..PERIOD] {
        proxy.step(*hip, cloud);
    }
    let before = allocations();
    let mut touching = 0;
    for hip in &w.hips[PERIOD..] {
        touching += usize::from(proxy.step(*hip, cloud).state.is_touching());
    }
    assert!(
        touching > PERIOD / 4,
        "the path must make contact: {touching}"
    );
    allocations() - before
}

#[test]
fn steady_state_steps_do_not_allocate() {
    let w = workload::plane_sweep(15_000, 2 * PERIOD, 0.0005, 11).unwrap();
    let index = CloudIndex::build(&w.frame).unwrap();
    assert_eq!(steady_state_allocations(&index, &w), 0, "kd-tree");
    assert_eq!(
        steady_state_allocations(&index.brute_force(), &w),
        0,
        "brute force"
    );
    // The counter does see allocations (the test can fail).
    let before = allocations();
    let v: Vec<u8> = Vec::with_capacity(64);
    drop(v);
    assert_eq!(allocations() - before, 1);
}
