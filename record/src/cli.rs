//! The `--record FILE.mcap` and `--live [ADDR]` options, shared by `operator run`, `telerobot
//! run`, the demo and `mmt experiment`.

use std::net::SocketAddr;
use std::path::PathBuf;

use clap::Args;

use crate::{Kind, RecordError, Recorder, RecorderConfig, RecorderReport};

/// Foxglove's usual port, on loopback: what `--live` alone serves on.
pub const DEFAULT_LIVE: &str = "127.0.0.1:8765";

/// Recording and live-view options.
#[derive(Clone, Debug, Default, PartialEq, Eq, Args)]
pub struct RecordArgs {
    /// Record the run to FILE.mcap (chunked, zstd; opens in Foxglove, Lichtblick, PlotJuggler,
    /// the mcap CLI).
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
    /// Serve the live view (Foxglove WebSocket protocol) on ADDR; `--live` alone serves on
    /// 127.0.0.1:8765 (loopback: give 0.0.0.0:PORT to serve other machines).
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = DEFAULT_LIVE,
          value_parser = live_addr)]
    pub live: Option<SocketAddr>,
}

/// `--live`'s value: `IP:PORT`, `HOST:PORT` (resolved: `localhost:8765`), or a bare `PORT` on
/// loopback.
fn live_addr(value: &str) -> Result<SocketAddr, String> {
    if let Ok(port) = value.parse::<u16>() {
        return Ok(SocketAddr::from(([127, 0, 0, 1], port)));
    }
    if let Ok(addr) = value.parse() {
        return Ok(addr);
    }
    let addrs: Vec<SocketAddr> = std::net::ToSocketAddrs::to_socket_addrs(value)
        .map(Iterator::collect)
        .unwrap_or_default();
    // IPv4 first: what a viewer's `ws://localhost:PORT` most often reaches.
    addrs
        .iter()
        .find(|a| a.is_ipv4())
        .or(addrs.first())
        .copied()
        .ok_or_else(|| {
            "expected IP:PORT, HOST:PORT or a port on loopback (e.g. 127.0.0.1:8765, \
             localhost:8765, 8765)"
                .to_owned()
        })
}

impl RecordArgs {
    /// Starts the recorder these options ask for (`None`: neither option given).
    /// `clock_origin_ns`: the producers' clock now (see [`RecorderConfig`]).
    pub fn start(&self, kind: Kind, clock_origin_ns: i64) -> Result<Option<Recorder>, RecordError> {
        if self.record.is_none() && self.live.is_none() {
            return Ok(None);
        }
        Recorder::start(RecorderConfig {
            mcap: self.record.clone(),
            live: self.live,
            kind,
            clock_origin_ns,
        })
        .map(Some)
    }
}

/// One line on what a recorder did: `recording: FILE (N messages, X MB in T s: R MB/s, D
/// dropped); live view: C viewers, S sent, D dropped`.
pub fn summary(r: &RecorderReport) -> String {
    let mut parts = Vec::new();
    if let Some(path) = &r.path {
        parts.push(format!(
            "recording: {} ({} messages, {:.2} MB in {:.1} s: {:.3} MB/s, {} dropped)",
            path.display(),
            r.messages,
            r.bytes as f64 / 1e6,
            r.seconds,
            r.bytes_per_second() / 1e6,
            r.dropped
        ));
    }
    if let Some(l) = &r.live {
        parts.push(format!(
            "live view: {} viewer(s), {} messages sent, {} dropped",
            l.clients, l.sent, l.dropped
        ));
    }
    parts.join("; ")
}

/// The thread of `--record-ab-s`: pauses and resumes a recorder every period (recording first)
/// until stopped, then leaves it recording. What recording costs the loops is measured by
/// comparing the two halves of one run.
pub struct Toggler {
    stop: rt::Shutdown,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Toggler {
    /// Starts toggling `sink` every `every`.
    pub fn start(sink: crate::RecordSink, every: std::time::Duration) -> std::io::Result<Toggler> {
        let stop = rt::Shutdown::new();
        let stopped = stop.clone();
        let thread = std::thread::Builder::new()
            .name("record-ab".to_owned())
            .spawn(move || {
                let mut paused = false;
                while !stopped.wait_timeout(every) {
                    paused = !paused;
                    sink.set_paused(paused);
                }
                sink.set_paused(false);
            })?;
        Ok(Toggler {
            stop,
            thread: Some(thread),
        })
    }
}

impl Drop for Toggler {
    fn drop(&mut self) {
        self.stop.trigger();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Before: `--live` took only IP:PORT; `localhost:8765` and a bare port were refused.
    #[test]
    fn live_takes_an_address_a_host_name_or_a_port() {
        let loopback = |port| SocketAddr::from(([127, 0, 0, 1], port));
        assert_eq!(live_addr("127.0.0.1:9000"), Ok(loopback(9000)));
        assert_eq!(live_addr("9001"), Ok(loopback(9001)));
        assert_eq!(live_addr("localhost:9002"), Ok(loopback(9002)));
        assert_eq!(
            live_addr("0.0.0.0:8765"),
            Ok(SocketAddr::from(([0, 0, 0, 0], 8765)))
        );
        for bad in ["", "127.0.0.1", "99999", "127.0.0.1:port"] {
            let e = live_addr(bad).unwrap_err();
            assert!(e.contains("expected IP:PORT"), "{bad}: {e}");
        }
    }
}
