//! The header every datagram carries (network notes §5.3).

use serde::{Deserialize, Serialize};

/// The first field of every datagram, in both directions.
///
/// It makes each datagram self-contained for the receiver: where it stands in the sender's
/// sequence (loss, reordering and duplicates are visible), when its content was sampled and sent,
/// and — echoed back — enough to measure the round-trip time without synchronised clocks
/// (`RTT = t4 − t1 − echo_hold`, see [`crate::session::RttEstimator`]).
///
/// Times are nanoseconds on the **sender's** clock (a monotonic or realtime clock, chosen by the
/// node; only differences on one clock and the offset estimate of [`crate::clock`] relate the two
/// sides). Fill it with [`crate::session::Session::next_header`] rather than by hand.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Header {
    /// Sequence number of this datagram in its direction, starting at 1 and increasing by one per
    /// datagram sent (all datagram kinds share it). 0 is never sent.
    pub seq: u64,
    /// When the content was sampled or computed [ns, sender's clock]: the sensor time of a
    /// measurement, the device time of a command.
    pub sample_time_ns: i64,
    /// When the datagram was handed to the transport [ns, sender's clock] (`t1` of the RTT).
    pub send_time_ns: i64,
    /// The newest `seq` the sender has accepted from its peer, or [`NO_ECHO`] (0) before the
    /// first.
    pub echo_seq: u64,
    /// How long the sender held `echo_seq` before sending this datagram \[ns\], i.e. `t3 − t2` of
    /// the RTT. Saturates at `u32::MAX` (4.29 s); such a saturated hold gives no RTT sample.
    pub echo_hold_ns: u32,
}

impl Header {
    /// A header that only says when its content was sampled: what a node fills in. The endpoint's
    /// [`crate::session::Session`] stamps the rest ([`crate::session::Session::stamp`]) just
    /// before the datagram is encoded; `seq` 0 is never sent.
    pub const fn unstamped(sample_time_ns: i64) -> Header {
        Header {
            seq: 0,
            sample_time_ns,
            send_time_ns: 0,
            echo_seq: NO_ECHO,
            echo_hold_ns: 0,
        }
    }
}

/// The `echo_seq` of a header sent before anything was received from the peer.
pub const NO_ECHO: u64 = 0;
