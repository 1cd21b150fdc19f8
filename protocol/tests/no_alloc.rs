//! The 1 kHz loops must not allocate: encoding into a reused buffer, decoding a datagram, and the
//! session and clock bookkeeping allocate nothing per message. A counting global allocator (this
//! test binary only) checks it on the current thread.
#![allow(unsafe_code)] // the GlobalAlloc impl; see the SAFETY comments

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use protocol::clock::{ClockOffsetEstimator, answer_ping};
use protocol::session::Session;
use protocol::{operator_to_telerobot as o2t, telerobot_to_operator as t2o};

struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

// SAFETY: every call is forwarded unchanged to the system allocator; the counter is a
// const-initialised thread-local `Cell`, which itself never allocates.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        // SAFETY: the caller upholds `alloc`'s contract, which we pass on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `System` with `layout` (all allocations go through it).
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        // SAFETY: as for `dealloc`; the caller upholds `realloc`'s contract.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// How many allocations `f` makes on this thread.
fn allocations(f: impl FnOnce()) -> u64 {
    let before = ALLOCATIONS.with(Cell::get);
    f();
    ALLOCATIONS.with(Cell::get) - before
}

#[test]
fn the_counter_sees_allocations() {
    assert_eq!(allocations(|| drop(std::hint::black_box(vec![1u8]))), 1);
}

#[test]
fn a_tick_of_either_loop_does_not_allocate() {
    let (mut op, mut tr) = (Session::new(), Session::new());
    let mut clock = ClockOffsetEstimator::new();
    let mut buf = Vec::with_capacity(2048);
    let commands = common::operator_samples();
    let o2t::Message::Command(command) = commands[1] else {
        panic!("sample 1 is a Command");
    };
    let datagrams = common::largest_telerobot_datagrams();
    let n = allocations(|| {
        for tick in 0..2_000_i64 {
            let now = tick * 1_000_000;
            // Operator: command out, telerobot datagrams in.
            let msg = o2t::Message::Command(o2t::Command {
                header: op.next_header(now, now),
                ..command
            });
            o2t::encode_into(&msg, &mut buf);
            let received = o2t::decode(&buf).unwrap();
            tr.on_receive(received.header().unwrap(), now + 400_000);
            for _ in 0..4 {
                let header = tr.next_header(now, now + 500_000);
                op.on_receive(&header, now + 900_000);
            }
            t2o::encode_into(&datagrams[tick as usize % datagrams.len()], &mut buf);
            std::hint::black_box(t2o::decode(&buf).unwrap());
            // Clock offset at 10 Hz.
            if tick % 100 == 0 {
                let ping = clock.ping(now);
                clock.on_pong(&answer_ping(&ping, now + 5, now + 6), now + 10);
            }
        }
    });
    assert_eq!(n, 0);
    assert!(op.rtt().samples() > 0 && clock.offset_ns().is_some());
}
