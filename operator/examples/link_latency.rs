//! Report figures of the QUIC datagram path (issue 5): command sample → telerobot-loop receipt.
//!
//! 1. Loopback without delay: latency p50 / p99 / max (targets p50 ≤ 100 µs, p99 ≤ 1 ms).
//! 2. Through the netem shim with 400 ms one-way delay: extra delay beyond 400 ms, p50 / p99 /
//!    max (the max is the worst queueing observed).
//!
//! Both daemons' network tasks run in this process on a 2-worker tokio runtime; a thread sends
//! commands at 1 kHz and a stand-in telerobot loop drains its command queue every ~100 µs
//! (every command is seen, but is taken up to ~100 µs after it arrived; its receipt is stamped
//! by the network task, so each is timed exactly). Latency is the `Received`
//! stamp minus the command's `sample_time_ns`, one clock (`CLOCK_MONOTONIC`).
//!
//! ```sh
//! cargo run --release -p operator --example link_latency [-- SECONDS]
//! ```

#![allow(clippy::unwrap_used)]

use std::sync::{Arc, Mutex};
use std::time::Duration;

use netem::{LinkConfig, ShimConfig};
use testkit::net::*;
use testkit::*;

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() {
    let seconds: u64 = std::env::args()
        .nth(1)
        .map_or(5, |s| s.parse().expect("SECONDS must be a whole number"));
    println!("1 kHz commands for {seconds} s per case");
    println!(
        "{:<28} {:>9} {:>10} {:>10} {:>10}",
        "case", "arrivals", "p50", "p99", "max"
    );
    run_case("loopback, latency", 0, seconds).await;
    run_case("400 ms shim, extra delay", 400, seconds).await;
}

async fn run_case(name: &str, delay_ms: i64, seconds: u64) {
    let certs = Certs::new();
    let telerobot = TelerobotServer::start(
        &certs.telerobot,
        "127.0.0.1:0".parse().unwrap(),
        &[&certs.operator],
    );
    let shim = (delay_ms > 0).then(|| {
        let mut config = ShimConfig::new("127.0.0.1:0".parse().unwrap(), telerobot.addr);
        config.up = LinkConfig::delay((delay_ms * MS) as u64);
        config.down = LinkConfig::delay((delay_ms * MS) as u64);
        config.spin_window_ns = 50_000;
        netem::shim::start(config).unwrap()
    });
    let addr = shim.as_ref().map_or(telerobot.addr, |s| s.local_addr());
    let operator = OperatorClient::start(addr, &certs.operator, &certs.telerobot, "report");
    eventually(Duration::from_secs(15), || {
        operator.link.status().connected().then_some(())
    })
    .await;
    let delays = Arc::new(Mutex::new(Vec::new()));
    let echo = echo_loop(telerobot.link.clone(), delay_ms * MS, Arc::clone(&delays));
    let source = command_source(
        operator.link.clone(),
        Duration::from_secs(seconds),
        Arc::default(),
    );
    tokio::task::spawn_blocking(move || source.join().unwrap())
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_millis(2 * delay_ms as u64 + 100)).await;
    drop(echo);
    let mut d = delays.lock().unwrap().clone();
    let (p50, p99) = (quantile(&mut d, 0.5), quantile(&mut d, 0.99));
    let us = |ns: i64| format!("{:.1} µs", ns as f64 / 1e3);
    println!(
        "{name:<28} {:>9} {:>10} {:>10} {:>10}",
        d.len(),
        us(p50),
        us(p99),
        us(*d.last().unwrap())
    );
    let s = operator.link.stats();
    println!(
        "{:<28} echo RTT min {:.3} ms, p50 {:.3} ms; clock offset {:.1} µs; operator sent {} (oversized {}, failed {}), outbox overwritten {}",
        "",
        s.rtt_min_ns.unwrap_or(0) as f64 / 1e6,
        s.rtt_p50_ns.unwrap_or(0) as f64 / 1e6,
        s.clock_offset_ns.unwrap_or(0) as f64 / 1e3,
        s.sent,
        s.send_oversized,
        s.send_failed,
        operator.link.outbox_overwritten()
    );
    operator.stop().await.unwrap();
    telerobot.stop().await;
    if let Some(shim) = shim {
        shim.shutdown().unwrap();
    }
}
