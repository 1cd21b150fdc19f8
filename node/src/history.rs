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

    /// Rewinds the renderers as `replay` says and replays every later tick held, with the
    /// parameters the renderers hold now; returns the ticks replayed (0 when the tick to start
    /// from is no longer held, or fewer than two ticks are).
    pub(super) fn replay(&mut self, replay: Replay, tangential: &mut [Tangential; 2]) -> usize {
        if self.len < 2 {
            return 0;
        }
        let start = match replay {
            Replay::Correct { at_ns, .. } => match self.find(at_ns) {
                Some(k) => k,
                None => return 0,
            },
            // The state after the tick before the onset; the onset tick is replayed too. An
            // onset older than the history replays all it holds; a newer one not held, nothing.
            Replay::FromOnset { onset_ns } => match self.find(onset_ns) {
                Some(k) => k.max(1) - 1,
                None if self.entries[self.index(0)].time_ns < onset_ns => return 0,
                None => 0,
            },
        };
        let base = self.entries[self.index(start)];
        for (t, snap) in tangential.iter_mut().zip(base.after) {
            restore(t, snap);
        }
        if let Replay::Correct { correction, .. } = replay {
            for (t, axis) in tangential.iter_mut().zip(correction.axes) {
                if let Tangential::Sliding(r) = t {
                    r.sync(
                        axis.deflection_m,
                        axis.mass_velocity_m_per_s,
                        correction.gain,
                    );
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

/// Where a replay starts and what it changes there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Replay {
    /// State sync: the renderers go back to their state after the tick stamped `at_ns`, the
    /// correction is blended in, and every later tick is replayed.
    Correct {
        /// Sample time of the tick the correction belongs to \[ns\].
        at_ns: i64,
        /// The telerobot's estimate of the state then.
        correction: Correction,
    },
    /// Model start: the renderers go back to their state before the tick stamped `onset_ns` (the
    /// contact episode's first), or before the oldest tick held, and the episode is rendered
    /// again with the parameters they hold now.
    FromOnset {
        /// Sample time of the episode's first tick \[ns\].
        onset_ns: i64,
    },
}

/// A state-sync correction of the sliding-mass renderers (`DESIGN.md` §6, §11.6).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Correction {
    /// Per tangential axis.
    pub(super) axes: [AxisCorrection; 2],
    /// Blending gain in (0, 1]: the fraction of the difference taken (§11.6: about 0.1).
    pub(super) gain: f64,
}

/// The telerobot's estimate of one tangential axis's state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct AxisCorrection {
    /// Contact deflection `δ = x − L − x_m` \[m\].
    pub(super) deflection_m: f64,
    /// Mass velocity \[m/s\].
    pub(super) mass_velocity_m_per_s: f64,
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

#[cfg(test)]
mod tests {
    use super::*;

    fn history(times: impl IntoIterator<Item = i64>) -> History {
        let mut h = History::new();
        for t in times {
            h.push(
                t,
                true,
                [[0.0; 2]; 2],
                &[Tangential::Free, Tangential::Free],
            );
        }
        h
    }

    fn correct(at_ns: i64) -> Replay {
        let axis = AxisCorrection {
            deflection_m: 0.0,
            mass_velocity_m_per_s: 0.0,
        };
        Replay::Correct {
            at_ns,
            correction: Correction {
                axes: [axis; 2],
                gain: 0.1,
            },
        }
    }

    #[test]
    fn each_mode_starts_where_it_says() {
        let mut t = [Tangential::Free, Tangential::Free];
        let mut h = history((10..20).map(|k| k * 1_000));
        // A correction applies after its tick: the 8 later ticks are replayed.
        assert_eq!(h.replay(correct(11_000), &mut t), 8);
        assert_eq!(h.replay(correct(19_000), &mut t), 0);
        assert_eq!(h.replay(correct(5_000), &mut t), 0, "no longer held");
        // A model start replays the onset tick too.
        assert_eq!(h.replay(Replay::FromOnset { onset_ns: 12_000 }, &mut t), 8);
        assert_eq!(
            h.replay(Replay::FromOnset { onset_ns: 1_000 }, &mut t),
            9,
            "older than the history: everything held after the oldest"
        );
        assert_eq!(
            h.replay(Replay::FromOnset { onset_ns: 15_500 }, &mut t),
            0,
            "a time inside the history but not a tick of it"
        );
        assert_eq!(history([1]).replay(correct(1), &mut t), 0, "one tick held");
    }
}
