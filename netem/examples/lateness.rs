//! Measures the shim: sends stamped UDP datagrams at a fixed rate (1 kHz by default) through an
//! in-process shim to a sink for N seconds, then prints the shim's release lateness
//! (p50/p99/max), the measured one-way delay distribution, and the largest gap between arrivals
//! (a stall detector).
//!
//! ```sh
//! cargo run --release -p netem --example lateness -- --seconds 20 --delay 400ms
//! cargo run --release -p netem --example lateness -- --seconds 20 --delay 400ms --jitter 2ms --loss 5%
//! cargo run --release -p netem --example lateness -- --seconds 20 --delay 400ms --rt-priority 10
//! ```
//!
//! The sender, the shim and the sink share one process and one clock ([`rt::monotonic_ns`]), so the
//! one-way delay is exact up to the clock read. These are figures for a report, not a test.

use std::net::UdpSocket;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::Context;
use clap::Parser;
use netem::shim::now_ns;
use netem::units::{parse_duration_ns, parse_percent};
use netem::{Distribution, LinkConfig, Loss, ShimConfig};
use rt::sleep_until_ns;

#[derive(Parser, Debug)]
#[command(about = "Release lateness and one-way delay of a stamped UDP stream through the shim")]
struct Args {
    /// How long to send [s].
    #[arg(long, default_value_t = 10)]
    seconds: u64,
    /// Datagrams per second.
    #[arg(long, default_value_t = 1000)]
    rate_hz: u64,
    /// Datagram size [bytes] (at least 16: sequence number and send time).
    #[arg(long, default_value_t = 64)]
    size: usize,
    /// One-way delay of the shim.
    #[arg(long, default_value = "400ms", value_parser = parse_duration_ns)]
    delay: u64,
    /// Jitter of the shim.
    #[arg(long, default_value = "0", value_parser = parse_duration_ns)]
    jitter: u64,
    /// Jitter distribution (uniform, normal, pareto, paretonormal or a .dist file).
    #[arg(long, default_value = "uniform")]
    distribution: String,
    /// Let jitter reorder (netem's tfifo) instead of keeping order.
    #[arg(long)]
    free_order: bool,
    /// Random loss of the shim.
    #[arg(long, default_value = "0%", value_parser = parse_percent)]
    loss: f64,
    /// The shim's spin window.
    #[arg(long, default_value = "200us", value_parser = parse_duration_ns)]
    spin: u64,
    /// Run the shim's scheduler under SCHED_FIFO at this priority (1..=99).
    #[arg(long)]
    rt_priority: Option<u8>,
    /// Seed of the shim's links.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    anyhow::ensure!(args.size >= 16, "--size must be at least 16 bytes");
    anyhow::ensure!(args.rate_hz > 0, "--rate-hz must be positive");
    let link = LinkConfig {
        delay_ns: args.delay,
        jitter_ns: args.jitter,
        distribution: Distribution::from_name_or_path(&args.distribution)?,
        keep_order: !args.free_order,
        loss: Loss::Random {
            probability: args.loss,
        },
        ..LinkConfig::default()
    };
    let sink = UdpSocket::bind("127.0.0.1:0")?;
    sink.set_read_timeout(Some(Duration::from_millis(50)))?;
    let mut config = ShimConfig::new("127.0.0.1:0".parse()?, sink.local_addr()?);
    config.up = link.clone();
    config.seed = args.seed;
    config.spin_window_ns = args.spin;
    config.realtime_priority = args.rt_priority;
    let shim = netem::shim::start(config)?;
    let sender = UdpSocket::bind("127.0.0.1:0")?;
    sender.connect(shim.local_addr())?;

    let stop = Arc::new(AtomicBool::new(false));
    let receiving = {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || receive(&sink, &stop))
    };

    let count = args.seconds * args.rate_hz;
    let period_ns = 1_000_000_000 / args.rate_hz;
    let mut payload = vec![0u8; args.size];
    let start = now_ns() + 10_000_000;
    let mut max_send_gap_ns = 0;
    let mut last_send = None;
    for seq in 0..count {
        sleep_until_ns((start + seq * period_ns) as i64, 50_000);
        let sent_ns = now_ns();
        payload[..8].copy_from_slice(&seq.to_le_bytes());
        payload[8..16].copy_from_slice(&sent_ns.to_le_bytes());
        sender.send(&payload).context("send")?;
        if let Some(last) = last_send {
            max_send_gap_ns = max_send_gap_ns.max(sent_ns - last);
        }
        last_send = Some(sent_ns);
    }
    std::thread::sleep(
        Duration::from_nanos(args.delay + 2 * args.jitter) + Duration::from_millis(300),
    );
    stop.store(true, Ordering::Relaxed);
    let arrivals = receiving
        .join()
        .map_err(|_| anyhow::anyhow!("the receive thread panicked"))?;
    let stats = shim.shutdown()?;

    println!(
        "link: {link}; {count} datagrams of {} B at {} Hz",
        args.size, args.rate_hz
    );
    println!("shim release lateness: {}", stats.up.lateness);
    report_delays(&arrivals, count, args.delay);
    let max_gap = arrivals
        .windows(2)
        .map(|w| w[1].received_ns - w[0].received_ns)
        .max()
        .unwrap_or(0);
    println!(
        "max inter-arrival gap: {:.3} ms (sender's max inter-send gap {:.3} ms)",
        ms(max_gap),
        ms(max_send_gap_ns)
    );
    println!("\nshim counters:\n{stats}");
    Ok(())
}

#[derive(Clone, Copy, Debug)]
struct Arrival {
    seq: u64,
    sent_ns: u64,
    received_ns: u64,
}

fn receive(sink: &UdpSocket, stop: &AtomicBool) -> Vec<Arrival> {
    let mut buf = vec![0u8; 65_536];
    let mut arrivals = Vec::with_capacity(1 << 16);
    while !stop.load(Ordering::Relaxed) {
        let Ok(len) = sink.recv(&mut buf) else {
            continue;
        };
        let received_ns = now_ns();
        let field = |at: usize| {
            buf.get(at..at + 8)
                .and_then(|b| b.try_into().ok())
                .map(u64::from_le_bytes)
        };
        if let (true, Some(seq), Some(sent_ns)) = (len >= 16, field(0), field(8)) {
            arrivals.push(Arrival {
                seq,
                sent_ns,
                received_ns,
            });
        }
    }
    arrivals
}

fn report_delays(arrivals: &[Arrival], sent: u64, delay_ns: u64) {
    let mut delays: Vec<u64> = arrivals.iter().map(|a| a.received_ns - a.sent_ns).collect();
    delays.sort_unstable();
    let out_of_order = arrivals
        .iter()
        .scan(None, |highest: &mut Option<u64>, a| {
            let late = highest.is_some_and(|h| a.seq < h);
            *highest = Some(highest.map_or(a.seq, |h| h.max(a.seq)));
            Some(late)
        })
        .filter(|&late| late)
        .count();
    println!(
        "received {} of {sent} ({:.2} % lost), {out_of_order} out of order",
        delays.len(),
        100.0 * (1.0 - delays.len() as f64 / sent as f64)
    );
    if delays.is_empty() {
        return;
    }
    let quantile = |q: f64| {
        let rank = ((q * delays.len() as f64).ceil() as usize).clamp(1, delays.len());
        delays[rank - 1]
    };
    println!("one-way delay [ms]        min      p1     p50     p90     p99    p99.9      max");
    let row = |label: &str, f: &dyn Fn(u64) -> f64| {
        println!(
            "{label:<22} {:>7.3} {:>7.3} {:>7.3} {:>7.3} {:>7.3} {:>8.3} {:>8.3}",
            f(delays[0]),
            f(quantile(0.01)),
            f(quantile(0.5)),
            f(quantile(0.9)),
            f(quantile(0.99)),
            f(quantile(0.999)),
            f(delays[delays.len() - 1])
        );
    };
    row("measured", &|d| ms(d));
    println!("extra over the delay [µs]  min      p1     p50     p90     p99    p99.9      max");
    row("measured − delay", &|d| {
        (d as f64 - delay_ns as f64) / 1_000.0
    });
}

fn ms(ns: u64) -> f64 {
    ns as f64 / 1e6
}
