//! The seeded, pure link model: one [`Link`] per direction decides each packet's fate.
//!
//! Time comes in as `now_ns` (any monotonic nanosecond clock; the model never reads one) and
//! leaves as due times on the same clock. Randomness comes from one `Pcg32` per link, seeded by
//! the caller; after construction every decision is integer arithmetic on its draws, so the same
//! seed, configuration and sequence of offers give the same fates, bit for bit.
//!
//! # Impairment order (netem's `netem_enqueue`, network notes §2.3)
//!
//! 1. **Duplicate** draw.
//! 2. **Loss** draw (Bernoulli or Gilbert–Elliott). A duplicated packet that is "lost" still
//!    sends one copy. Nothing left → [`DropReason::Loss`].
//! 3. **Limit**: when [`limit_packets`](LinkConfig::limit_packets) packets are in flight the packet
//!    (and its copy) is dropped → [`DropReason::Limit`].
//! 4. The **copy** of a duplicated packet goes through the link again, as netem re-enqueues it at
//!    the root: its own loss draw (a lost copy is simply not a duplicate) and its own delay.
//! 5. **Reorder / delay**: if reordering is on, `gap − 1` packets have been delayed since the last
//!    reordered one and the reorder draw hits, the packet is due now (it jumps the queue).
//!    Otherwise its delay is drawn (delay ± jitter from the distribution, clipped at 0); with a
//!    **rate** the packet is due `max(now + delay, last due) + (len + overhead)·8/rate`; with
//!    **order kept** the due time is raised to the previous delayed packet's.
//!
//! Not modelled: netem's `corrupt` (for UDP/QUIC it shows up as loss), `slot`, the 4-state loss
//! model, correlated loss/duplicate/reorder draws (netem marks correlated loss deprecated), ECN
//! marking, and ATM cells in the rate.

pub mod config;
pub mod distribution;
pub mod loss;

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use rand::{RngCore, SeedableRng};
use rand_pcg::Pcg32;

pub use config::{ConfigError, LinkConfig, PROFILES};
pub use distribution::{DistError, DistTable, Distribution};
pub use loss::Loss;

use distribution::{Correlated, tabledist};
use loss::{LossState, Threshold};

/// What the link did with one offered packet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fate {
    /// Nothing gets through.
    Dropped(DropReason),
    /// The packet gets through, possibly twice.
    Delivered {
        /// The offered packet.
        original: Delivery,
        /// A second copy with its own due time, when the packet was duplicated.
        duplicate: Option<Delivery>,
    },
}

impl Fate {
    /// The copies to deliver, in the order the link queued them (a duplicate's copy first, as
    /// netem enqueues it before the original).
    pub fn copies(&self) -> impl Iterator<Item = Delivery> {
        let (first, second) = match *self {
            Fate::Dropped(_) => (None, None),
            Fate::Delivered {
                original,
                duplicate: None,
            } => (Some(original), None),
            Fate::Delivered {
                original,
                duplicate: Some(copy),
            } => (Some(copy), Some(original)),
        };
        first.into_iter().chain(second)
    }
}

/// Why a packet was dropped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DropReason {
    /// The loss model took it.
    Loss,
    /// The queue held [`limit_packets`](LinkConfig::limit_packets) packets.
    Limit,
}

/// One copy of a packet leaving the link.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Delivery {
    /// When it leaves the link [ns, the caller's clock].
    pub due_ns: u64,
    /// Sent at once by the reorder option, ahead of packets still delayed.
    pub reordered: bool,
}

/// Running totals of one link. `offered = (delivered − duplicated) + dropped_loss + dropped_limit`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkCounters {
    /// Packets offered.
    pub offered: u64,
    /// Copies scheduled for delivery (duplicates included).
    pub delivered: u64,
    /// Extra copies scheduled by the duplicate option.
    pub duplicated: u64,
    /// Copies sent at once by the reorder option.
    pub reordered: u64,
    /// Packets of which no copy got through because of the loss model.
    pub dropped_loss: u64,
    /// Packets dropped because the queue was full.
    pub dropped_limit: u64,
}

/// One direction of an emulated link.
#[derive(Clone, Debug)]
pub struct Link {
    config: LinkConfig,
    duplicate: Threshold,
    reorder: Threshold,
    rng: Pcg32,
    jitter_source: Correlated,
    loss: LossState,
    /// netem's `counter`: packets delayed since the last reordered one.
    since_reorder: u32,
    /// Largest due time of a delayed packet: the rate's reference point.
    last_rate_due_ns: u64,
    /// Due time of the previous delayed packet: the order-keeping floor.
    last_ordered_due_ns: u64,
    /// Due times of packets still in flight (min-heap), for the limit.
    in_flight: BinaryHeap<Reverse<u64>>,
    counters: LinkCounters,
}

impl Link {
    /// A link with `config`, its PRNG seeded with `seed`.
    pub fn new(config: LinkConfig, seed: u64) -> Result<Self, ConfigError> {
        config.validate()?;
        let mut rng = Pcg32::seed_from_u64(seed);
        let jitter_source = Correlated::new(config.jitter_correlation, &mut rng);
        Ok(Self {
            duplicate: Threshold::new(config.duplicate_probability),
            reorder: Threshold::new(config.reorder_probability),
            loss: LossState::new(&config.loss),
            config,
            rng,
            jitter_source,
            since_reorder: 0,
            last_rate_due_ns: 0,
            last_ordered_due_ns: 0,
            in_flight: BinaryHeap::new(),
            counters: LinkCounters::default(),
        })
    }

    /// Changes the settings, keeping the PRNG, the counters, the packets in flight, the
    /// Gilbert–Elliott state (if the model stays Gilbert–Elliott) and the order-keeping floor: a
    /// link whose delay drops from 400 ms to 10 ms still releases in order.
    pub fn set_config(&mut self, config: LinkConfig) -> Result<(), ConfigError> {
        config.validate()?;
        self.duplicate = Threshold::new(config.duplicate_probability);
        self.reorder = Threshold::new(config.reorder_probability);
        self.loss.reconfigure(&config.loss);
        self.jitter_source
            .set_correlation(config.jitter_correlation);
        self.config = config;
        Ok(())
    }

    /// The current settings.
    pub fn config(&self) -> &LinkConfig {
        &self.config
    }

    /// Totals so far.
    pub fn counters(&self) -> LinkCounters {
        self.counters
    }

    /// Packets in flight at `now_ns` (due later than `now_ns`).
    pub fn in_flight(&mut self, now_ns: u64) -> usize {
        self.retire(now_ns);
        self.in_flight.len()
    }

    /// Decides the fate of a packet of `len_bytes` offered at `now_ns`. `now_ns` should not go
    /// backwards; if it does, nothing panics and due times are never before the `now_ns` given.
    pub fn offer(&mut self, now_ns: u64, len_bytes: usize) -> Fate {
        self.counters.offered += 1;
        self.retire(now_ns);
        let duplicated = !self.duplicate.is_zero() && self.duplicate.hit(self.rng.next_u32());
        let lost = self.loss.lose(&mut self.rng);
        if lost && !duplicated {
            self.counters.dropped_loss += 1;
            return Fate::Dropped(DropReason::Loss);
        }
        if self.in_flight.len() >= self.limit() {
            self.counters.dropped_limit += 1;
            return Fate::Dropped(DropReason::Limit);
        }
        // The copy of a duplicated packet (one that was not lost) re-enters the link.
        let duplicate = if duplicated && !lost && !self.loss.lose(&mut self.rng) {
            self.counters.duplicated += 1;
            Some(self.schedule(now_ns, len_bytes))
        } else {
            None
        };
        let original = self.schedule(now_ns, len_bytes);
        Fate::Delivered {
            original,
            duplicate,
        }
    }

    fn limit(&self) -> usize {
        usize::try_from(self.config.limit_packets).unwrap_or(usize::MAX)
    }

    fn retire(&mut self, now_ns: u64) {
        while let Some(&Reverse(due)) = self.in_flight.peek() {
            if due > now_ns {
                break;
            }
            self.in_flight.pop();
        }
    }

    /// Step 5: reorder or delay one copy, and queue it.
    fn schedule(&mut self, now_ns: u64, len_bytes: usize) -> Delivery {
        self.counters.delivered += 1;
        let gap = self.config.reorder_gap;
        let reorder_now = !self.reorder.is_zero()
            && self.since_reorder >= gap.saturating_sub(1)
            && self.reorder.hit(self.rng.next_u32());
        if reorder_now {
            self.since_reorder = 0;
            self.counters.reordered += 1;
            self.in_flight.push(Reverse(now_ns));
            return Delivery {
                due_ns: now_ns,
                reordered: true,
            };
        }
        let delay_ns = self.draw_delay_ns();
        let mut due_ns = now_ns.saturating_add(delay_ns);
        if let Some(rate) = self.config.rate_bit_per_s {
            due_ns = due_ns
                .max(self.last_rate_due_ns)
                .saturating_add(self.packet_time_ns(len_bytes, rate));
            self.last_rate_due_ns = self.last_rate_due_ns.max(due_ns);
        }
        if self.config.keep_order {
            due_ns = due_ns.max(self.last_ordered_due_ns);
        }
        self.last_ordered_due_ns = due_ns;
        self.since_reorder = self.since_reorder.saturating_add(1);
        self.in_flight.push(Reverse(due_ns));
        Delivery {
            due_ns,
            reordered: false,
        }
    }

    /// Base delay plus a jitter draw [ns], clipped at 0.
    fn draw_delay_ns(&mut self) -> u64 {
        let delay = i64::try_from(self.config.delay_ns).unwrap_or(i64::MAX);
        if self.config.jitter_ns == 0 {
            return self.config.delay_ns;
        }
        let jitter = i32::try_from(self.config.jitter_ns).unwrap_or(i32::MAX);
        let rnd = self.jitter_source.next(&mut self.rng);
        let sample = tabledist(delay, jitter, rnd, self.config.distribution.table());
        u64::try_from(sample).unwrap_or(0)
    }

    /// Serialisation time of one packet [ns] (netem `packet_time_ns`, rate in bit/s).
    fn packet_time_ns(&self, len_bytes: usize, rate_bit_per_s: u64) -> u64 {
        let len = i128::try_from(len_bytes).unwrap_or(i128::MAX);
        let wire_bits = (len + i128::from(self.config.overhead_bytes)).max(0) * 8;
        let ns = wire_bits * 1_000_000_000 / i128::from(rate_bit_per_s.max(1));
        u64::try_from(ns).unwrap_or(u64::MAX)
    }
}

#[cfg(test)]
mod tests;
