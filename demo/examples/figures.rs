//! The networked system's figures (issue 5), from full demo runs (the `demo` command's code):
//!
//! 1. loopback without delay and without the shim: command sample → telerobot receipt
//!    (targets p50 ≤ 100 µs, p99 ≤ 1 ms);
//! 2. through the netem shim at 0, 100 and 400 ms one-way: `measured_delay_ms` (target within
//!    2 ms of the set delay), RMS error after stable (≤ 5 %), latency beyond the set delay
//!    (queueing: target ≤ 1 ms);
//! 3. both loops' period (target p99 within 100 µs of 1 ms), overruns, and the shim's release
//!    lateness under this load.
//!
//! ```sh
//! cargo run --release -p demo --example figures [-- SECONDS \[SPIN_US\]]
//! ```

#![allow(clippy::unwrap_used)]

use demo::DemoConfig;
use rt::Shutdown;

fn main() {
    let mut args = std::env::args().skip(1);
    let seconds: f64 = args
        .next()
        .map_or(20.0, |s| s.parse().expect("SECONDS must be a number"));
    let spin_us: f64 = args
        .next()
        .map_or(100.0, |s| s.parse().expect("SPIN_US must be a number"));
    println!(
        "{seconds} s of scripted:exp1 per case, spin {spin_us} µs; all times in ms unless said"
    );
    println!(
        "{:<16} {:>10} {:>8} {:>22} {:>22} {:>22} {:>22} {:>18}",
        "case",
        "delay",
        "RMS %",
        "uplink p50/p99/max",
        "downlink p50/p99/max",
        "haptic µs p50/p99/max",
        "telerobot µs p50/p99/max",
        "shim late µs p50/p99"
    );
    for (name, delay_ms, via_shim) in [
        ("direct", 0.0, false),
        ("shim 0 ms", 0.0, true),
        ("shim 100 ms", 100.0, true),
        ("shim 400 ms", 400.0, true),
    ] {
        let config = DemoConfig {
            delay_ms,
            seconds,
            spin_us,
            via_shim,
            ..DemoConfig::default()
        };
        let outcome = demo::run::run(&config, Shutdown::new()).unwrap();
        let r = &outcome.report;
        let t = &r.telerobot;
        let r_run = &r.run;
        // Latencies beyond the set delay: what the stack adds (queueing, scheduling).
        let extra = |l: &rt::Summary| {
            let d = delay_ms * 1e3;
            format!(
                "{:.3}/{:.3}/{:.3}",
                (l.p50_us - d) / 1e3,
                (l.p99_us - d) / 1e3,
                (l.max_us - d) / 1e3
            )
        };
        let period = |p: &rt::TimingReport| {
            format!(
                "{:.0}/{:.0}/{:.0} ({} ovr)",
                p.period.p50_us, p.period.p99_us, p.period.max_us, p.overruns
            )
        };
        println!(
            "{name:<16} {:>10} {:>8} {:>22} {:>22} {:>22} {:>22} {:>18}",
            r_run
                .measured_delay_ms
                .map_or("—".into(), |d| format!("{d:.2}")),
            r_run
                .experiment
                .rms_error_pct_after_stable
                .map_or("—".into(), |e| format!("{e:.2}")),
            extra(&t.command_latency),
            extra(&r_run.downlink_latency),
            period(&r_run.loop_timing),
            period(&t.timing),
            r.shim.as_ref().map_or("—".into(), |s| format!(
                "{:.1}/{:.1}",
                s.lateness.p50_us, s.lateness.p99_us
            )),
        );
    }
    println!(
        "uplink/downlink: one-way latency minus the set delay (the direct case: the latency itself)."
    );
}
