//! Through the netem shim with 400 ms one-way delay: the datagram path adds no queueing of its
//! own, the echo RTT is the emulated one, and a 2 s outage heals without a restart.
//!
//! The tests run one at a time (they use real time and a busy shim); bounds are loose so they
//! do not flake on a loaded machine. The precise figures come from `examples/link_latency.rs`.

#![allow(clippy::unwrap_used)]

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use netem::{Direction, LinkConfig, Loss, ShimConfig};
use rt::monotonic_ns;
use testkit::net::*;
use testkit::*;

const DELAY_NS: i64 = 400 * MS;

/// Held by each test for its whole run: the tests must not overlap (async-aware, as it is held
/// across awaits; each test has its own runtime).
async fn serial() -> tokio::sync::MutexGuard<'static, ()> {
    static SERIAL: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());
    SERIAL.lock().await
}

/// A telerobot behind a 400 ms shim, with the stand-in loop echoing commands.
struct Rig {
    shim: netem::ShimHandle,
    telerobot: TelerobotServer,
    operator: OperatorClient,
    delays: Arc<Mutex<Vec<i64>>>,
    _echo: Poller,
}

async fn rig() -> Rig {
    let certs = Certs::new();
    let telerobot = TelerobotServer::start(
        &certs.telerobot,
        "127.0.0.1:0".parse().unwrap(),
        &[&certs.operator],
    );
    let mut config = ShimConfig::new("127.0.0.1:0".parse().unwrap(), telerobot.addr);
    config.up = LinkConfig::delay(DELAY_NS as u64);
    config.down = LinkConfig::delay(DELAY_NS as u64);
    config.spin_window_ns = 50_000;
    let shim = netem::shim::start(config).unwrap();
    let operator = OperatorClient::start(
        shim.local_addr(),
        &certs.operator,
        &certs.telerobot,
        "alice",
    );
    eventually(Duration::from_secs(15), || {
        operator.link.status().connected().then_some(())
    })
    .await;
    let delays = Arc::new(Mutex::new(Vec::new()));
    let echo = echo_loop(telerobot.link.clone(), DELAY_NS, Arc::clone(&delays));
    Rig {
        shim,
        telerobot,
        operator,
        delays,
        _echo: echo,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn at_400_ms_datagrams_are_not_queued_and_the_echo_rtt_is_the_link_s() {
    let _serial = serial().await;
    let rig = rig().await;
    // 1 kHz commands for 3 s, starting right after the handshake (where Cubic's small initial
    // window queued datagrams for over a second).
    let source = command_source(
        rig.operator.link.clone(),
        Duration::from_secs(3),
        Arc::default(),
    );
    tokio::task::spawn_blocking(move || source.join().unwrap())
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_millis(600)).await;
    let mut delays = rig.delays.lock().unwrap().clone();
    assert!(delays.len() > 1000, "only {} arrivals seen", delays.len());
    let (p50, p99) = (quantile(&mut delays, 0.5), quantile(&mut delays, 0.99));
    let max = *delays.last().unwrap();
    println!(
        "extra delay beyond 400 ms over {} arrivals: p50 {:.3} ms, p99 {:.3} ms, max {:.3} ms",
        delays.len(),
        p50 as f64 / 1e6,
        p99 as f64 / 1e6,
        max as f64 / 1e6
    );
    assert!(
        p99 < 50 * MS,
        "p99 extra delay {p99} ns: datagrams were queued"
    );

    for (side, stats) in [
        ("operator", rig.operator.link.stats()),
        ("telerobot", rig.telerobot.link.stats()),
    ] {
        let rtt = stats.rtt_min_ns.unwrap();
        println!(
            "{side}: echo RTT min {:.3} ms, latest {:.3} ms, p50 {:?} ms; sent {} received {} late {} lost {}",
            rtt as f64 / 1e6,
            stats.rtt_latest_ns.unwrap() as f64 / 1e6,
            stats.rtt_p50_ns.map(|v| v as f64 / 1e6),
            stats.sent,
            stats.received,
            stats.late,
            stats.lost
        );
        assert!((rtt - 2 * DELAY_NS).abs() < 5 * MS, "{side} RTT {rtt} ns");
    }
    let p50 = rig.operator.link.stats().rtt_p50_ns.unwrap();
    assert!(
        (p50 - 2 * DELAY_NS).abs() < 5 * MS,
        "operator RTT p50 {p50} ns"
    );
    rig.operator.stop().await.unwrap();
    rig.shim.shutdown().unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_two_second_outage_heals_without_a_restart() {
    let _serial = serial().await;
    let rig = rig().await;
    let link = rig.operator.link.clone();
    let stop = Arc::new(AtomicBool::new(false));
    let source = command_source(link.clone(), Duration::from_secs(20), Arc::clone(&stop));
    eventually(Duration::from_secs(5), || {
        (!rig.delays.lock().unwrap().is_empty()).then_some(())
    })
    .await;
    let session_before = link.status().session();

    let lost = LinkConfig {
        loss: Loss::Random { probability: 1.0 },
        ..LinkConfig::delay(DELAY_NS as u64)
    };
    for d in Direction::ALL {
        rig.shim.set_config(d, lost.clone()).unwrap();
    }
    tokio::time::sleep(Duration::from_secs(2)).await;
    for d in Direction::ALL {
        rig.shim
            .set_config(d, LinkConfig::delay(DELAY_NS as u64))
            .unwrap();
    }
    let healed_at = monotonic_ns();
    rig.delays.lock().unwrap().clear();

    // Commands reach the telerobot loop again (everything sent during the outage was lost at
    // the shim, so these were sent after it).
    eventually(Duration::from_secs(8), || {
        (!rig.delays.lock().unwrap().is_empty()).then_some(())
    })
    .await;
    let recovered_after = monotonic_ns() - healed_at;
    let session_after = link.status().session();
    println!(
        "outage healed: commands flow {:.0} ms after the link came back; {}",
        recovered_after as f64 / 1e6,
        if session_after == session_before {
            "the session survived".to_owned()
        } else {
            format!("reconnected (session {session_before} → {session_after})")
        }
    );
    assert!(link.status().connected());
    stop.store(true, Ordering::Relaxed);
    drop(rig._echo);
    tokio::task::spawn_blocking(move || source.join().unwrap())
        .await
        .unwrap();
    rig.operator.stop().await.unwrap();
    rig.shim.shutdown().unwrap();
}
