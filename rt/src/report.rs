//! Report forms (serialisable, in µs and ms) of latency histograms and link counters, shared by
//! both daemons' reports.

use netem::stats::LatencySummary;
use serde::Serialize;
use transport::LinkSnapshot;

use crate::timing::Quantiles;

/// A latency distribution \[µs\].
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct LatencyReport {
    /// Samples.
    pub count: u64,
    /// Median \[µs\].
    pub p50_us: f64,
    /// 99th percentile \[µs\].
    pub p99_us: f64,
    /// Largest \[µs\].
    pub max_us: f64,
}

impl LatencyReport {
    /// From a netem histogram's summary (e.g. the shim's release lateness).
    pub fn of_summary(s: &LatencySummary) -> LatencyReport {
        LatencyReport {
            count: s.count,
            p50_us: s.p50_ns as f64 / 1e3,
            p99_us: s.p99_ns as f64 / 1e3,
            max_us: s.max_ns as f64 / 1e3,
        }
    }

    /// The three quantiles.
    pub fn quantiles(&self) -> Quantiles {
        Quantiles {
            p50_us: self.p50_us,
            p99_us: self.p99_us,
            max_us: self.max_us,
        }
    }

    /// From samples \[ns\] (sorts them).
    pub fn of_samples(samples: &mut [i64]) -> LatencyReport {
        samples.sort_unstable();
        let n = samples.len();
        let at = |q: f64| {
            let rank = ((q * n as f64).ceil() as usize).clamp(1, n.max(1)) - 1;
            samples.get(rank).map_or(0.0, |v| *v as f64 / 1e3)
        };
        LatencyReport {
            count: n as u64,
            p50_us: at(0.5),
            p99_us: at(0.99),
            max_us: samples.last().map_or(0.0, |v| *v as f64 / 1e3),
        }
    }
}

/// [`LinkSnapshot`] for reports.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct LinkReport {
    /// Datagrams handed to quinn.
    pub sent: u64,
    /// Datagrams not sent: too large, or refused by quinn.
    pub send_failed: u64,
    /// Datagrams received from the peer with a header.
    pub received: u64,
    /// ... of which reordered behind a newer one.
    pub late: u64,
    /// ... of which seen before.
    pub duplicates: u64,
    /// Sequence numbers never received.
    pub lost: u64,
    /// Datagrams that were not valid messages of the direction (counted, ignored).
    pub garbage: u64,
    /// Smoothed RTT from header echoes \[ms\].
    pub rtt_ms: Option<f64>,
    /// Smallest RTT sample \[ms\].
    pub rtt_min_ms: Option<f64>,
    /// Clock offset, peer minus ours \[ms\] (operator side).
    pub clock_offset_ms: Option<f64>,
    /// Datagram frames quinn put on the wire (`sent` minus this were held back or dropped inside
    /// quinn).
    pub quinn_datagrams_transmitted: u64,
    /// Congestion events quinn's controller saw.
    pub quinn_congestion_events: u64,
    /// Packets quinn declared lost.
    pub quinn_lost_packets: u64,
    /// Longest time between two accepted datagrams within a session \[ms\]: the largest stall
    /// of the stream.
    pub max_gap_ms: f64,
}

impl From<LinkSnapshot> for LinkReport {
    fn from(s: LinkSnapshot) -> Self {
        let ms = |v: Option<i64>| v.map(|ns| ns as f64 / 1e6);
        LinkReport {
            sent: s.sent,
            send_failed: s.send_oversized + s.send_failed,
            received: s.received,
            late: s.late,
            duplicates: s.duplicates,
            lost: s.lost,
            garbage: s.garbage,
            rtt_ms: ms(s.rtt_smoothed_ns),
            rtt_min_ms: ms(s.rtt_min_ns),
            clock_offset_ms: ms(s.clock_offset_ns),
            quinn_datagrams_transmitted: s.quinn_datagrams_transmitted,
            quinn_congestion_events: s.quinn_congestion_events,
            quinn_lost_packets: s.quinn_lost_packets,
            max_gap_ms: s.max_gap_ns as f64 / 1e6,
        }
    }
}
