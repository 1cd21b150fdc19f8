//! [`Channel`]: an in-process, deterministic link carrying values of any type through a [`Link`].
//!
//! The experiment harness carries encoded messages through one `Channel` per direction on its
//! simulated clock: `send` at the sender's step time, `recv_due` at the receiver's. Same seed,
//! same sends → same fates and the same delivery order, because the link's draws are seeded and
//! the queue releases by `(due, seq)`. After warm-up it allocates only when the number in flight
//! exceeds its previous maximum (the heap keeps its capacity).

use crate::model::{ConfigError, Fate, Link, LinkConfig};
use crate::queue::DueQueue;

/// A one-way, in-process link.
#[derive(Debug)]
pub struct Channel<T> {
    link: Link,
    queue: DueQueue<T>,
    next_seq: u64,
}

impl<T: Clone> Channel<T> {
    /// A channel applying `config`, its link seeded with `seed`.
    pub fn new(config: LinkConfig, seed: u64) -> Result<Self, ConfigError> {
        Ok(Self::with_link(Link::new(config, seed)?))
    }

    /// A channel around an existing link.
    pub fn with_link(link: Link) -> Self {
        Self {
            link,
            queue: DueQueue::new(),
            next_seq: 0,
        }
    }

    /// Offers `payload` (counted as `len_bytes` for the rate) at `now_ns`; returns its fate. A
    /// duplicated payload is cloned.
    pub fn send(&mut self, now_ns: u64, payload: T, len_bytes: usize) -> Fate {
        let fate = self.link.offer(now_ns, len_bytes);
        if let Fate::Delivered {
            original,
            duplicate,
        } = fate
        {
            if let Some(copy) = duplicate {
                self.push(copy.due_ns, payload.clone());
            }
            self.push(original.due_ns, payload);
        }
        fate
    }

    /// The next payload due at `now_ns`, if any, in `(due, seq)` order.
    pub fn recv_due(&mut self, now_ns: u64) -> Option<T> {
        self.recv_due_at(now_ns).map(|(_, payload)| payload)
    }

    /// Like [`recv_due`](Self::recv_due), with the payload's due time [ns].
    pub fn recv_due_at(&mut self, now_ns: u64) -> Option<(u64, T)> {
        self.queue.pop_due(now_ns).map(|d| (d.due_ns, d.item))
    }

    /// When the next payload is due, if one is in flight.
    pub fn next_due_ns(&self) -> Option<u64> {
        self.queue.next_due_ns()
    }

    /// Payloads in flight.
    pub fn in_flight(&self) -> usize {
        self.queue.len()
    }

    /// The link (settings and counters).
    pub fn link(&self) -> &Link {
        &self.link
    }

    /// The link, to change its settings mid-run.
    pub fn link_mut(&mut self) -> &mut Link {
        &mut self.link
    }

    fn push(&mut self, due_ns: u64, payload: T) {
        self.queue.push(due_ns, self.next_seq, payload);
        self.next_seq += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Distribution, Loss};

    const MS: u64 = 1_000_000;

    fn run(seed: u64) -> Vec<(u64, u64, Vec<u8>)> {
        let config = LinkConfig {
            delay_ns: 30 * MS,
            jitter_ns: 10 * MS,
            distribution: Distribution::Normal,
            loss: Loss::Random { probability: 0.1 },
            duplicate_probability: 0.05,
            keep_order: false,
            ..LinkConfig::default()
        };
        let mut channel = Channel::new(config, seed).unwrap();
        let mut out = Vec::new();
        for tick in 0..3_000u64 {
            let now = tick * MS;
            channel.send(now, tick.to_le_bytes().to_vec(), 8);
            while let Some((due, bytes)) = channel.recv_due_at(now) {
                assert!(due <= now);
                out.push((now, due, bytes));
            }
        }
        out
    }

    #[test]
    fn same_seed_same_deliveries_in_the_same_order() {
        let a = run(5);
        assert_eq!(a, run(5));
        assert_ne!(a, run(6));
        // Loss, duplicates and reordering all happened.
        let seqs: Vec<u64> = a
            .iter()
            .map(|(_, _, b)| u64::from_le_bytes(b.as_slice().try_into().unwrap()))
            .collect();
        assert!(seqs.len() < 3_000);
        assert!(seqs.windows(2).any(|w| w[0] == w[1]));
        assert!(seqs.windows(2).any(|w| w[0] > w[1]));
    }

    #[test]
    fn fixed_delay_delivers_exactly_on_time_in_order() {
        let mut channel = Channel::new(LinkConfig::delay(400 * MS), 0).unwrap();
        for i in 0..10u64 {
            channel.send(i * MS, i, 64);
        }
        assert_eq!(channel.next_due_ns(), Some(400 * MS));
        assert_eq!(channel.recv_due(400 * MS - 1), None);
        assert_eq!(channel.recv_due(400 * MS), Some(0));
        assert_eq!(channel.recv_due(400 * MS), None);
        let rest: Vec<u64> = std::iter::from_fn(|| channel.recv_due(410 * MS)).collect();
        assert_eq!(rest, (1..10).collect::<Vec<_>>());
        assert_eq!(channel.in_flight(), 0);
    }
}
