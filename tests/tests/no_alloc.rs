//! The two 1 kHz loops neither allocate nor free once running (`DESIGN.md` §2): the whole system
//! runs over loopback with a 100 ms shim while a counting global allocator (this test binary
//! only) counts the allocations and frees made on the threads named `haptic-loop` and
//! `telerobot-loop`. After a warm-up that covers the first contact, the first model and the
//! first clouds, the counts must not move.
#![allow(unsafe_code)] // the GlobalAlloc impl; see the SAFETY comments
#![allow(clippy::unwrap_used)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::time::Duration;

use testkit::daemons::*;
use testkit::*;

struct Counting;

/// Allocations and frees on the loop threads.
static ON_LOOPS: AtomicU64 = AtomicU64::new(0);

thread_local! {
    /// Whether this thread is a loop thread: unknown until its first allocation.
    static IS_LOOP: Cell<Option<bool>> = const { Cell::new(None) };
    /// Set while the allocator itself looks at the thread (no recursion).
    static BUSY: Cell<bool> = const { Cell::new(false) };
}

fn count() {
    if BUSY.with(Cell::get) {
        return;
    }
    BUSY.with(|b| b.set(true));
    let is_loop = IS_LOOP.with(|l| match l.get() {
        Some(v) => v,
        None => {
            let v = matches!(
                std::thread::current().name(),
                Some("haptic-loop" | "telerobot-loop")
            );
            l.set(Some(v));
            v
        }
    });
    if is_loop {
        ON_LOOPS.fetch_add(1, Relaxed);
    }
    BUSY.with(|b| b.set(false));
}

// SAFETY: every call is forwarded unchanged to the system allocator; the bookkeeping uses
// const-initialised thread-locals and an atomic, and guards against re-entry.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: the caller upholds `alloc`'s contract, which we pass on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        count();
        // SAFETY: `ptr` was allocated by `System` with `layout` (all allocations go through it).
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: as for `dealloc`; the caller upholds `realloc`'s contract.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn neither_loop_allocates_or_frees_once_running() {
    let _serial = serial();
    let (tr, shim, config) = through_shim(&Certs::new(), 100.0, 10.0);
    let operator = spawn_operator(config);
    wait_connected(&tr);
    // Warm-up: contact at 1 s, the first model about 2 s later.
    std::thread::sleep(Duration::from_secs(5));
    let warm = ON_LOOPS.load(Relaxed);
    // The rest of the run: contact episodes end and start again, models and clouds keep coming.
    std::thread::sleep(Duration::from_secs(4));
    let running = ON_LOOPS.load(Relaxed) - warm;
    let outcome = operator.join().unwrap().unwrap();
    tr.stop();
    shim.shutdown().unwrap();
    assert!(outcome.report.experiment.render_start_s.is_some());
    assert_eq!(
        running, 0,
        "allocations or frees on the loop threads while running"
    );
}
