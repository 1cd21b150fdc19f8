//! [`LinkReport`]: the report form of [`LinkSnapshot`] (counts, RTT and clock in ms), shared by both
//! daemons' reports.

use serde::{Deserialize, Serialize};

use crate::stats::LinkSnapshot;

/// [`LinkSnapshot`] for reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
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
