//! # testkit — the scaffolding every test package shares
//!
//! What it is (test-only, `publish = false`, a dev-dependency of each package that uses it):
//! - [`Certs`] and [`tuning`]: both sides' certificates and the link tuning the tests use;
//! - [`wall_summary`]: a scene summary the network tests welcome operators with;
//! - [`serial`]: the guard that keeps the tests whose real-time loops spin from overlapping (the
//!   machine has two cores);
//! - [`wait_for`] and [`eventually`]: polling a condition with a deadline (threads, tasks);
//! - [`udp_junk`] and [`shim`]: raw UDP junk, and the netem shim in front of an address;
//! - [`peers`]: hand-made peers for what a correct daemon never sends (another version, garbage);
//! - [`net`]: the two daemons' network tasks alone, with stand-in loops;
//! - [`daemons`]: the whole daemons, started through the functions the binaries run;
//! - [`process`]: the binaries as processes (Ctrl-C, a bounded wait for the exit).
//!
//! What it is not: no test of its own, and nothing a daemon links.

#![allow(clippy::unwrap_used, clippy::missing_panics_doc)]

pub mod daemons;
pub mod net;
pub mod peers;
pub mod process;

use std::net::{SocketAddr, UdpSocket};
use std::sync::{Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use netem::{LinkConfig, ShimConfig, ShimHandle};
use protocol::telerobot_to_operator::{ModelStructure, SceneSummary};
use transport::{Identity, LinkTuning};

/// One millisecond \[ns\].
pub const MS: i64 = 1_000_000;

/// Spin window of the loops and the shim in the tests \[ns\]: short, the machine has 2 cores.
pub const SPIN_NS: i64 = 50_000;

/// Held by each test that runs spinning real-time loops, for its whole run (poison-tolerant: one
/// failed test does not fail the rest).
pub fn serial() -> MutexGuard<'static, ()> {
    static SERIAL: Mutex<()> = Mutex::new(());
    SERIAL.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Certificates of both sides (in memory; the CLI tests cover the files).
pub struct Certs {
    /// The telerobot's.
    pub telerobot: Identity,
    /// The operator's.
    pub operator: Identity,
}

impl Certs {
    /// Fresh certificates.
    pub fn new() -> Certs {
        Certs {
            telerobot: Identity::generate(&["telerobot"]).unwrap(),
            operator: Identity::generate(&["operator"]).unwrap(),
        }
    }
}

impl Default for Certs {
    fn default() -> Self {
        Certs::new()
    }
}

/// A fresh certificate named `name` (a third operator, a stranger).
pub fn identity(name: &str) -> Identity {
    Identity::generate(&[name]).unwrap()
}

/// The link tuning both sides use: the defaults with the delay hint (at least 1 ms).
pub fn tuning(delay_ms: f64) -> LinkTuning {
    LinkTuning::with_expected_delay_ms(delay_ms.max(1.0)).unwrap()
}

/// A compliant wall: Kelvin–Voigt along the normal, nothing along the tangents, 1 kHz, no cloud.
pub fn wall_summary() -> SceneSummary {
    SceneSummary {
        name: "wall".into(),
        normal: ModelStructure::KelvinVoigt,
        tangential: ModelStructure::Free,
        control_rate_hz: 1000.0,
        cloud_rate_hz: None,
        left_out: vec![],
        proxy_radii_m: [0.004, 0.006, 0.03],
        prior: None,
        cloud_follows_object: false,
    }
}

/// Polls `f` every 5 ms until it gives a value or `timeout` passes (blocking).
pub fn wait_for<T>(timeout: Duration, mut f: impl FnMut() -> Option<T>) -> Option<T> {
    let start = Instant::now();
    loop {
        if let Some(v) = f() {
            return Some(v);
        }
        if start.elapsed() > timeout {
            return None;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Polls `f` every 5 ms until it gives a value; panics after `timeout` (async).
pub async fn eventually<T>(timeout: Duration, mut f: impl FnMut() -> Option<T>) -> T {
    let deadline = tokio::time::Instant::now() + timeout;
    loop {
        if let Some(v) = f() {
            return v;
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "condition not met within {timeout:?}"
        );
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

/// Sends `count` datagrams of raw UDP junk (not QUIC) to `addr`.
pub fn udp_junk(addr: SocketAddr, count: usize) {
    let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
    for i in 0..count {
        let junk = [0xde, 0xad, 0xbe, 0xef, i as u8, 0, 0, 0, 0x55];
        let _ = socket.send_to(&junk[..1 + i % junk.len()], addr);
    }
}

/// The netem shim in front of `forward`, `delay_ms` each way, spinning [`SPIN_NS`].
pub fn shim(forward: SocketAddr, delay_ms: f64) -> ShimHandle {
    let mut config = ShimConfig::new("127.0.0.1:0".parse().unwrap(), forward);
    let delay = LinkConfig::delay((delay_ms * 1e6).round() as u64);
    config.up = delay.clone();
    config.down = delay;
    config.spin_window_ns = SPIN_NS as u64;
    netem::shim::start(config).unwrap()
}

/// The p-quantile of `values` (sorted in place; nearest rank).
pub fn quantile(values: &mut [i64], p: f64) -> i64 {
    values.sort_unstable();
    let i = ((values.len() as f64 - 1.0) * p).round() as usize;
    values[i.min(values.len() - 1)]
}
