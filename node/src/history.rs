//! The operator's short history: each tick's tangential inputs and the renderers' state after the
//! tick, so the renderers can be rewound to a past tick, corrected and replayed to now (state sync,
//! model start). Preallocated; nothing is allocated per tick.

use super::operator::{Tangential, step_tangential};
use mmt::render::{ShearState, SlidingState};

/// Ticks kept: 4.096 s at 1 kHz — a round trip at 400 ms one-way delay with margin, and the
/// first seconds of a contact episode for a model-start replay. A replay walks at most this many
/// ticks (about 0.4 ms of work at 50 ns per axis-step).
pub const CAPACITY: usize = 4096;

#[derive(Clone, Copy, Debug, Default)]
enum Snap {
    #[default]
    None,
    Sliding(SlidingState),
    Shear(ShearState),
}

#[derive(Clone, Copy, Debug, Default)]
struct Entry {
    time_ns: i64,
    in_contact: bool,
    /// `[position, velocity]` along each tangent.
    inputs: [[f64; 2]; 2],
    /// Renderer state after this tick.
    after: [Snap; 2],
}

/// Ring buffer of the last [`CAPACITY`] ticks.
pub(super) struct History {
    entries: Box<[Entry]>,
    /// Index the next entry goes to.
    head: usize,
    len: usize,
}

impl History {
    pub(super) fn new() -> Self {
        History {
            entries: vec![Entry::default(); CAPACITY].into_boxed_slice(),
            head: 0,
            len: 0,
        }
    }

    pub(super) fn push(
        &mut self,
        time_ns: i64,
        in_contact: bool,
        inputs: [[f64; 2]; 2],
        tangential: &[Tangential; 2],
    ) {
        self.entries[self.head] = Entry {
            time_ns,
            in_contact,
            inputs,
            after: tangential.each_ref().map(snapshot),
        };
        self.head = (self.head + 1) % CAPACITY;
        self.len = (self.len + 1).min(CAPACITY);
    }

    /// Ring index of the `k`-th oldest entry.
    fn index(&self, k: usize) -> usize {
        (self.head + CAPACITY - self.len + k) % CAPACITY
    }

    /// Position (0 = oldest) of the entry stamped `time_ns`, found by bisection (times increase).
    fn find(&self, time_ns: i64) -> Option<usize> {
        let (mut lo, mut hi) = (0, self.len);
        while lo < hi {
            let mid = (lo + hi) / 2;
            if self.entries[self.index(mid)].time_ns < time_ns {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        (lo < self.len && self.entries[self.index(lo)].time_ns == time_ns).then_some(lo)
    }

    /// Ticks from the entry stamped `time_ns` to the newest, if it is still held.
    pub(super) fn ticks_since(&self, time_ns: i64) -> Option<usize> {
        self.find(time_ns).map(|k| self.len - 1 - k)
    }

    /// Whether the tick stamped `time_ns` was rendered in contact.
    pub(super) fn in_contact_at(&self, time_ns: i64) -> bool {
        self.find(time_ns)
            .is_some_and(|k| self.entries[self.index(k)].in_contact)
    }

    /// Rewinds the renderers and replays to the newest tick; returns the ticks replayed.
    ///
    /// - With `sync` (per axis: deflection, mass velocity, gain): the renderers are put back to
    ///   their state after the tick stamped `from_ns`, the sync is blended in, and every later
    ///   tick is replayed.
    /// - With `from_onset`: the renderers are put back to their state before the tick stamped
    ///   `from_ns` (or, if it is older than the history, before the oldest tick held) and that tick
    ///   and every later one are replayed — with the parameters they hold now.
    pub(super) fn replay_from(
        &mut self,
        from_ns: i64,
        _now_ns: i64,
        tangential: &mut [Tangential; 2],
        sync: Option<[(f64, f64, f64); 2]>,
        from_onset: bool,
    ) -> usize {
        if self.len < 2 {
            return 0;
        }
        let start = match (self.find(from_ns), from_onset) {
            (Some(k), false) => k,
            (None, false) => return 0,
            // Restore the state after the tick before the onset, replay from the onset.
            (Some(k), true) => k.max(1) - 1,
            (None, true) if self.entries[self.index(0)].time_ns < from_ns => return 0,
            (None, true) => 0,
        };
        let base = self.entries[self.index(start)];
        for (t, snap) in tangential.iter_mut().zip(base.after) {
            restore(t, snap);
        }
        if let Some(sync) = sync {
            for (t, (deflection, velocity, gain)) in tangential.iter_mut().zip(sync) {
                if let Tangential::Sliding(r) = t {
                    r.sync(deflection, velocity, gain);
                }
            }
        }
        let mut replayed = 0;
        for k in start + 1..self.len {
            let idx = self.index(k);
            let e = self.entries[idx];
            for (t, [x, v]) in tangential.iter_mut().zip(e.inputs) {
                step_tangential(t, x, v, e.in_contact);
            }
            self.entries[idx].after = tangential.each_ref().map(snapshot);
            replayed += 1;
        }
        replayed
    }
}

fn snapshot(t: &Tangential) -> Snap {
    match t {
        Tangential::Sliding(r) => Snap::Sliding(r.snapshot()),
        Tangential::Shear(r) => Snap::Shear(r.snapshot()),
        Tangential::Free => Snap::None,
    }
}

fn restore(t: &mut Tangential, snap: Snap) {
    match (t, snap) {
        (Tangential::Sliding(r), Snap::Sliding(s)) => r.restore(s),
        (Tangential::Shear(r), Snap::Shear(s)) => r.restore(s),
        _ => {}
    }
}
