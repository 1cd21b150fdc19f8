//! The networked run's table: `mmt experiment`'s, then the rows only a real link has — the
//! measured delay, the loop's timing, the link's counters and latencies, the safety layer's
//! trips — each section written by its own step.

use std::fmt::Write as _;

use mmt::render::RendererStats;
use rt::{Summary, TimingReport};
use transport::LinkReport;

use super::{NetworkedReport, PeerFigures};
use crate::device::BackendReport;

/// The stdout table: `mmt experiment`'s, then the networked figures (with `peer`'s rows where a
/// run has them).
pub fn table(r: &NetworkedReport, peer: &PeerFigures) -> String {
    let mut out = metrics::table(&r.experiment);
    let _ = write_extras(&mut out, r, peer);
    out
}

fn write_extras(out: &mut String, r: &NetworkedReport, peer: &PeerFigures) -> std::fmt::Result {
    // Without the scene's truth, the parameters as received.
    if let Some(p) = r
        .parameters_received
        .filter(|_| r.experiment.parameters.is_empty())
    {
        for (axes, set) in [("normal", p.normal), ("tangential", p.tangential)] {
            if let Some(set) = set {
                writeln!(out, "parameters received, {axes}: {:.4?}", set.terms)?;
            }
        }
    }
    let mut rows = Rows::default();
    delay_rows(&mut rows, r, peer);
    loop_rows(
        &mut rows,
        "haptic loop period p50 / p99 / max",
        &r.loop_timing,
    );
    link_rows(&mut rows, &r.link, peer);
    outage_rows(&mut rows, r);
    latency_rows(&mut rows, r, peer);
    rows.row("sessions", r.sessions.to_string());
    cloud_rows(&mut rows, r, peer);
    if let Some(t) = &peer.telerobot_timing {
        rows.row("telerobot loop period p50 / p99 / max", us(&t.period));
        rows.row("  ticks, overruns, skipped", count(t));
    }
    if let Some(l) = &peer.shim_lateness {
        rows.row("netem release lateness p50 / p99 / max", us(l));
    }
    safety_rows(&mut rows, r);
    if let Some(BackendReport::Ros2(d)) = &r.device_backend {
        ros2_device_rows(&mut rows, d);
    }
    writeln!(out, "network")?;
    for (name, value) in rows.0 {
        writeln!(out, "{name:<46} {value:>14}")?;
    }
    Ok(())
}

/// The rows of the networked section, in order: name, value.
#[derive(Default)]
struct Rows(Vec<(String, String)>);

impl Rows {
    fn row(&mut self, name: &str, value: String) {
        self.0.push((name.to_owned(), value));
    }
}

fn opt(v: Option<f64>, unit: &str) -> String {
    v.map_or("—".to_string(), |v| format!("{v:.2} {unit}"))
}

/// p50 / p99 / max of a distribution in µs.
fn us(q: &Summary) -> String {
    format!("{:.1} / {:.1} / {:.0} µs", q.p50_us, q.p99_us, q.max_us)
}

/// p50 / p99 / max of a distribution in ms.
fn ms(q: &Summary) -> String {
    format!(
        "{:.2} / {:.2} / {:.2} ms",
        q.p50_us / 1e3,
        q.p99_us / 1e3,
        q.max_us / 1e3
    )
}

fn count(t: &TimingReport) -> String {
    format!("{} / {} / {}", t.ticks, t.overruns, t.skipped_ticks)
}

/// What quinn itself did with the datagrams it was handed: every one on the wire (none held
/// back by a congestion window or pacing), no congestion events.
fn quinn(l: &LinkReport) -> String {
    format!(
        "{} of {} / {} / {}",
        l.quinn_datagrams_transmitted, l.sent, l.quinn_congestion_events, l.quinn_lost_packets
    )
}

/// The measured delay, the set one, and how well the signals matched.
fn delay_rows(rows: &mut Rows, r: &NetworkedReport, peer: &PeerFigures) {
    rows.row(
        "measured_delay_ms (rendered leads measured)",
        opt(r.measured_delay_ms, "ms"),
    );
    if let Some(d) = r.set_delay_ms {
        rows.row("  set one-way delay", format!("{d:.2} ms"));
    }
    if let Some(l) = peer.played_lag_ms {
        rows.row(
            "  telerobot played the path at (mean)",
            format!("{l:.2} ms"),
        );
    }
    if let Some(e) = &r.delay_estimate {
        rows.row("  peak correlation", format!("{:.4}", e.peak_correlation));
    }
}

/// Cloud frames on both sides, and those the real-time budget reduced or refused (issue 11: the
/// budget's counts were in the JSON only).
fn cloud_rows(rows: &mut Rows, r: &NetworkedReport, peer: &PeerFigures) {
    let pair = |(a, b): (u64, u64)| format!("{a} / {b}");
    rows.row("cloud frames indexed / refused", pair(r.clouds));
    rows.row(
        "  over the budget: downsampled / refused",
        pair(r.clouds_over_budget),
    );
    if let Some([frames, over]) = peer.telerobot_camera {
        rows.row("telerobot camera frames sent / refused", pair(frames));
        rows.row("  over its budget: downsampled / refused", pair(over));
    }
}

/// The outages over the whole run (across sessions), and how many error windows hold one.
fn outage_rows(rows: &mut Rows, r: &NetworkedReport) {
    let o = &r.outages;
    rows.row(
        "outages (no measurement ≥ 100 ms), all sessions",
        format!(
            "{} · longest {:.0} ms · total {:.0} ms",
            o.count, o.longest_ms, o.total_ms
        ),
    );
    let marked = r
        .experiment
        .error_over_time
        .iter()
        .filter(|w| w.outage)
        .count();
    if marked > 0 {
        rows.row(
            "  1 s error windows with an outage in them",
            format!("{marked} (marked \"outage\" in report.json)"),
        );
    }
}

/// A loop's period, lateness, work and tick counts, under the heading `period`.
fn loop_rows(rows: &mut Rows, period: &str, t: &TimingReport) {
    rows.row(period, us(&t.period));
    rows.row("  lateness p50 / p99 / max", us(&t.lateness));
    rows.row("  work p50 / p99 / max", us(&t.work));
    rows.row("  ticks, overruns, skipped", count(t));
}

/// The link's counters (quinn's for both ends where known), its longest gap, RTT and clock
/// offset.
fn link_rows(rows: &mut Rows, l: &LinkReport, peer: &PeerFigures) {
    rows.row(
        "datagrams sent / received",
        format!("{} / {}", l.sent, l.received),
    );
    rows.row(
        "  late / lost / duplicate / garbage",
        format!("{} / {} / {} / {}", l.late, l.lost, l.duplicates, l.garbage),
    );
    rows.row(
        "  quinn, operator: on the wire / congestion events / lost packets",
        quinn(l),
    );
    if let Some(l) = &peer.telerobot_link {
        rows.row(
            "  quinn, telerobot: on the wire / congestion events / lost packets",
            quinn(l),
        );
    }
    rows.row(
        "  longest gap between accepted datagrams, in a session",
        format!("{:.1} ms", l.max_gap_ms),
    );
    rows.row(
        "RTT smoothed / min",
        format!("{} / {}", opt(l.rtt_ms, "ms"), opt(l.rtt_min_ms, "ms")),
    );
    rows.row(
        "clock offset (telerobot − operator)",
        opt(l.clock_offset_ms, "ms"),
    );
}

/// One-way latencies, and beyond the set delay (what the stack adds: queueing, scheduling).
fn latency_rows(rows: &mut Rows, r: &NetworkedReport, peer: &PeerFigures) {
    let mut latency = |name: &str, l: &Summary| {
        rows.row(name, ms(l));
        if let Some(d) = r.set_delay_ms {
            rows.row(
                "  beyond the set delay p50 / p99 / max",
                us(&l.shifted(-d * 1e3)),
            );
        }
    };
    if let Some(l) = &peer.uplink_latency {
        latency("uplink: command sample → telerobot receipt", l);
    }
    latency(
        "downlink: measurement send → operator receipt",
        &r.downlink_latency,
    );
}

/// The renderers' gate and clipping counts, the safety layer's episodes, the device's state
/// and the passivity layer's energy.
fn safety_rows(rows: &mut Rows, r: &NetworkedReport) {
    let sum = |f: fn(&RendererStats) -> u64| r.renderers.iter().map(f).sum::<u64>();
    rows.row(
        "renderer ticks: unresolved (gate) / clipped",
        format!(
            "{} / {}",
            sum(|s| s.unresolved_ticks),
            sum(|s| s.clipped_ticks)
        ),
    );
    let s = &r.safety;
    rows.row(
        "safety episodes: watchdog / rate / max / workspace",
        format!(
            "{} / {} / {} / {}",
            s.watchdog_fading.episodes,
            s.rate_limited.episodes,
            s.saturated.episodes,
            s.workspace.episodes
        ),
    );
    rows.row(
        "  loop overrun / stale parameters / clutch",
        format!(
            "{} / {} / {}",
            s.loop_overrun.episodes, s.stale_params.episodes, s.clutch.episodes
        ),
    );
    rows.row(
        "  non-finite force / position / velocity",
        format!(
            "{} / {} / {}",
            s.non_finite_force.episodes,
            s.non_finite_position.episodes,
            s.non_finite_velocity.episodes
        ),
    );
    rows.row(
        "  position-scale changes refused",
        s.scale_rejections.to_string(),
    );
    rows.row(
        "device state, faults",
        format!("{:?} / {}", r.device_state, r.device_faults),
    );
    if let Some(f) = &r.device_fault {
        rows.row("  fault", f.clone());
    }
    let p = &s.passivity;
    rows.row(
        "passivity: min energy / dissipated / ticks",
        format!(
            "{:.2} / {:.2} mJ / {} ({} capped)",
            p.min_energy_j * 1e3,
            p.dissipated_j * 1e3,
            p.controlling.ticks,
            p.capped.ticks
        ),
    );
}

/// The ROS 2 device: the poses it took and refused, the commands it published and zeroed.
fn ros2_device_rows(rows: &mut Rows, d: &ros2::haptic::HapticReport) {
    let g = &d.io.gate;
    let c = &d.io.commands;
    rows.row(
        "ros2 device: poses received / accepted",
        format!("{} / {}", g.poses, g.accepted),
    );
    rows.row(
        "  effective rate, longest stamp gap",
        format!(
            "{:.1} Hz, {:.1} ms",
            d.effective_rate_hz, d.io.longest_stamp_gap_ms
        ),
    );
    rows.row("  stamp → receipt p50 / p99 / max", us(&d.latency));
    rows.row("  velocity from", d.velocity_from.to_owned());
    rows.row(
        "  refused: other frame / from the future",
        format!("{} / {}", g.wrong_frame, g.from_future),
    );
    rows.row(
        "  refused: out of order / duplicate / malformed",
        format!(
            "{} / {} / {}",
            g.out_of_order, g.duplicates, g.malformed_stamps
        ),
    );
    rows.row(
        "  refused: non-finite / out of range / jump",
        format!(
            "{} / {} / {}",
            g.non_finite, g.out_of_range, g.impossible_jumps
        ),
    );
    rows.row(
        "  undecodable messages, twists refused",
        format!("{}, {}", d.io.undecodable, g.twists_refused),
    );
    if !d.writes_force {
        rows.row("  commands", "none: forces NOT written".to_owned());
        return;
    }
    rows.row(
        "  commands published (zero) / errors",
        format!("{} ({}) / {}", c.published, c.zero, c.publish_errors),
    );
    rows.row("  dropped before a pose", c.before_pose.to_string());
    rows.row(
        "  zeroed: stale pose (episodes) / watchdog",
        format!(
            "{} ({}) / {}",
            c.stale_zeroed, c.stale_episodes, c.watchdog_zeroed
        ),
    );
}
