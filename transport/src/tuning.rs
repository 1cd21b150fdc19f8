//! quinn's transport settings for 1 kHz datagrams over long delays (network notes §3.3–3.5).
//!
//! quinn's defaults are made for bulk transfer on the internet; three of them wreck a 1 kHz
//! control stream on a 400 ms link (network notes §0.4, §3.4):
//! - Cubic's 12 kB initial window is far below the ≈ 80 kB bandwidth-delay product, so datagrams
//!   wait in quinn's send queue for **1.0–1.4 s** until slow start catches up;
//! - emulated random loss is read as congestion: Cubic shrinks to ≈ 9 kB and datagrams queue for
//!   **tens of seconds** (or are dropped locally);
//! - reordering jitter beyond 3 packets is read as loss (`packet_threshold` 3): spurious loss,
//!   congestion events, 2 s of latency.
//!
//! [`LinkTuning`] fixes these; [`Congestion`] says which controller and why.

use std::any::Any;
use std::sync::Arc;
use std::time::{Duration, Instant};

use quinn::congestion::{Controller, ControllerFactory, CubicConfig};
use quinn::{IdleTimeout, TransportConfig, VarInt};

/// Which congestion controller the connection runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Congestion {
    /// A window that never changes, whatever loss is seen (network notes §3.5 sketch). The
    /// default: the rig's link is dedicated or emulated, where loss is not congestion and Cubic's
    /// reaction to it only delays the datagrams that matter (measured: Cubic 11–24 s extra delay at
    /// 5 % loss, fixed window 70–90 µs). It does not back off: on a shared network it is not a
    /// good citizen.
    FixedWindow {
        /// Bytes that may be in flight \[B\]; also sets the pacing rate (≈ 1.25 × window / RTT).
        window_bytes: u64,
    },
    /// quinn's Cubic with a large initial window: starts above the bandwidth-delay product, so no
    /// start-up queueing, but backs off on loss. For links shared with other traffic.
    Cubic {
        /// Initial congestion window \[B\].
        initial_window_bytes: u64,
    },
}

/// Default window of either controller \[B\]: 2 MiB covers 1 kHz control in both directions
/// (≈ 0.1 MB/s) plus ≈ 1 MB/s of point clouds over an 800 ms round trip, twice over.
pub const DEFAULT_WINDOW_BYTES: u64 = 2 * 1024 * 1024;

impl Default for Congestion {
    fn default() -> Self {
        Congestion::FixedWindow {
            window_bytes: DEFAULT_WINDOW_BYTES,
        }
    }
}

/// Everything tunable about a connection, with defaults for the rig. Both sides should use the
/// same values (the idle timeout is the minimum of the two).
#[derive(Clone, Debug, PartialEq)]
pub struct LinkTuning {
    /// Expected one-way delay of the link. Default 20 ms. Sets quinn's `initial_rtt` to
    /// `2 × this + 10 ms`, so that the handshake does not retransmit spuriously on a slow link
    /// (quinn's default 333 ms is too short for the 400 ms experiments).
    pub expected_one_way_delay: Duration,
    /// Congestion controller. Default [`Congestion::FixedWindow`] of [`DEFAULT_WINDOW_BYTES`].
    pub congestion: Congestion,
    /// The connection is closed after this long without hearing from the peer. Default 5 s:
    /// long enough to ride out a short outage (keep-alives resume it), short enough that a
    /// telerobot frees the controlling slot and an operator reconnects within seconds.
    pub idle_timeout: Duration,
    /// A keep-alive packet is sent after this long without sending. Default 500 ms; must stay
    /// well below `idle_timeout`.
    pub keep_alive: Duration,
    /// Datagrams quinn may hold waiting for the congestion window \[B\]. Default 16 KiB (≈ 40 ms
    /// of the telerobot's 1 kHz state): when full, the **oldest** is dropped, so a backlog costs
    /// freshness briefly instead of queueing stale state (quinn's default is 1 MiB).
    pub datagram_send_buffer_bytes: usize,
    /// Received datagrams quinn holds until the network task reads them \[B\]. Default 64 KiB;
    /// the task drains at once, so this only bounds memory (quinn's default 1.25 MB).
    pub datagram_receive_buffer_bytes: usize,
    /// RFC 9002 reordering threshold in packets. Default 1000 (≈ 1 s at 1 kHz; quinn's 3):
    /// jitter that reorders packets must not be read as loss.
    pub packet_threshold: u32,
    /// RFC 9002 time threshold, a multiple of the RTT. Default 1.2 (quinn's 9/8); must be > 1.
    pub time_threshold: f32,
    /// Flow-control window of one stream \[B\]. Default 8 MiB: a point-cloud stream sustains
    /// window / RTT, 10 MB/s at an 800 ms round trip (quinn's 1.25 MB allows 1.56 MB/s).
    pub stream_window_bytes: u32,
}

impl Default for LinkTuning {
    fn default() -> Self {
        LinkTuning {
            expected_one_way_delay: Duration::from_millis(20),
            congestion: Congestion::default(),
            idle_timeout: Duration::from_secs(5),
            keep_alive: Duration::from_millis(500),
            datagram_send_buffer_bytes: 16 * 1024,
            datagram_receive_buffer_bytes: 64 * 1024,
            packet_threshold: 1000,
            time_threshold: 1.2,
            stream_window_bytes: 8 * 1024 * 1024,
        }
    }
}

/// A tuning value quinn cannot take.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("link tuning: {field} = {value}: expected {expected}")]
pub struct TuningError {
    /// The [`LinkTuning`] field.
    pub field: &'static str,
    /// The value given.
    pub value: String,
    /// What is allowed.
    pub expected: &'static str,
}

/// Streams each side may open towards the other.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StreamLimits {
    /// Bidirectional streams the peer may open (the operator opens one: the control stream).
    pub peer_bidi: u32,
    /// Unidirectional streams the peer may have open at once (the telerobot opens one per cloud
    /// frame).
    pub peer_uni: u32,
}

impl LinkTuning {
    /// The defaults with [`expected_one_way_delay`](Self::expected_one_way_delay) set from a
    /// command-line value in milliseconds (0 to 60 000).
    pub fn with_expected_delay_ms(ms: f64) -> Result<LinkTuning, TuningError> {
        let delay = Duration::try_from_secs_f64(ms / 1000.0)
            .ok()
            .filter(|d| *d <= Duration::from_secs(60))
            .ok_or(TuningError {
                field: "expected_one_way_delay",
                value: format!("{ms} ms"),
                expected: "a delay from 0 to 60000 ms",
            })?;
        Ok(LinkTuning {
            expected_one_way_delay: delay,
            ..LinkTuning::default()
        })
    }

    /// quinn's transport configuration for these settings, letting the peer open `limits`.
    pub fn transport_config(&self, limits: StreamLimits) -> Result<TransportConfig, TuningError> {
        let fail = |field, value: String, expected| TuningError {
            field,
            value,
            expected,
        };
        if self.keep_alive.is_zero() || self.keep_alive >= self.idle_timeout {
            return Err(fail(
                "keep_alive",
                format!(
                    "{:?} (idle timeout {:?})",
                    self.keep_alive, self.idle_timeout
                ),
                "more than zero and below the idle timeout",
            ));
        }
        if !(self.time_threshold > 1.0 && self.time_threshold.is_finite()) {
            return Err(fail(
                "time_threshold",
                self.time_threshold.to_string(),
                "a finite multiple of the RTT above 1",
            ));
        }
        if self.packet_threshold < 3 {
            return Err(fail(
                "packet_threshold",
                self.packet_threshold.to_string(),
                "at least 3 (RFC 9002's minimum)",
            ));
        }
        let idle = IdleTimeout::try_from(self.idle_timeout).map_err(|_| {
            fail(
                "idle_timeout",
                format!("{:?}", self.idle_timeout),
                "below 2^62 ms",
            )
        })?;
        let rtt = self
            .expected_one_way_delay
            .saturating_mul(2)
            .saturating_add(Duration::from_millis(10));
        let mut t = TransportConfig::default();
        t.max_idle_timeout(Some(idle))
            .keep_alive_interval(Some(self.keep_alive))
            .initial_rtt(rtt)
            .datagram_send_buffer_size(self.datagram_send_buffer_bytes)
            .datagram_receive_buffer_size(Some(self.datagram_receive_buffer_bytes))
            .packet_threshold(self.packet_threshold)
            .time_threshold(self.time_threshold)
            .stream_receive_window(VarInt::from_u32(self.stream_window_bytes))
            .send_window(u64::from(self.stream_window_bytes) * 4)
            .max_concurrent_bidi_streams(VarInt::from_u32(limits.peer_bidi))
            .max_concurrent_uni_streams(VarInt::from_u32(limits.peer_uni));
        match self.congestion {
            Congestion::FixedWindow { window_bytes } => {
                t.congestion_controller_factory(Arc::new(FixedWindow(window_bytes)));
            }
            Congestion::Cubic {
                initial_window_bytes,
            } => {
                let mut cubic = CubicConfig::default();
                cubic.initial_window(initial_window_bytes);
                t.congestion_controller_factory(Arc::new(cubic));
            }
        }
        Ok(t)
    }
}

/// A congestion controller whose window is a constant \[B\] (network notes §3.5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FixedWindow(pub u64);

impl Controller for FixedWindow {
    fn on_congestion_event(
        &mut self,
        _now: Instant,
        _sent: Instant,
        _persistent: bool,
        _lost: u64,
    ) {
    }

    fn on_mtu_update(&mut self, _new_mtu: u16) {}

    fn window(&self) -> u64 {
        self.0
    }

    fn clone_box(&self) -> Box<dyn Controller> {
        Box::new(*self)
    }

    fn initial_window(&self) -> u64 {
        self.0
    }

    fn into_any(self: Box<Self>) -> Box<dyn Any> {
        self
    }
}

impl ControllerFactory for FixedWindow {
    fn build(self: Arc<Self>, _now: Instant, _current_mtu: u16) -> Box<dyn Controller> {
        Box::new(*self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_build_and_bad_values_are_named() {
        let limits = StreamLimits {
            peer_bidi: 1,
            peer_uni: 0,
        };
        assert!(LinkTuning::default().transport_config(limits).is_ok());
        let bad = LinkTuning {
            keep_alive: Duration::from_secs(6),
            ..LinkTuning::default()
        };
        let e = bad.transport_config(limits).unwrap_err();
        assert_eq!(e.field, "keep_alive");
        let bad = LinkTuning {
            time_threshold: 1.0,
            ..LinkTuning::default()
        };
        assert_eq!(
            bad.transport_config(limits).unwrap_err().field,
            "time_threshold"
        );
    }

    #[test]
    fn the_delay_hint_is_checked() {
        let t = LinkTuning::with_expected_delay_ms(400.0).unwrap();
        assert_eq!(t.expected_one_way_delay, Duration::from_millis(400));
        for bad in [-1.0, f64::NAN, 1e9] {
            assert!(LinkTuning::with_expected_delay_ms(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn the_fixed_window_ignores_congestion() {
        let mut w = FixedWindow(1000);
        let now = Instant::now();
        w.on_congestion_event(now, now, true, 500);
        assert_eq!(w.window(), 1000);
    }
}
