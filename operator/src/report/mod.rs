//! The report of a networked run: the same figures as `mmt experiment`, and what only a real
//! link has — `measured_delay_ms` by cross-correlation, the downlink latency (both computed by
//! [`metrics::networked`] from what the operator recorded, as `mmt report FILE.mcap` computes
//! them again from a recording) — plus what only the end of the run knows: the haptic loop's
//! timing, the link's counters, the safety layer's trips, the device's faults.

use std::fmt::Write as _;

use metrics::networked::{self, NetworkedFigures, NetworkedRun};
use metrics::{ExperimentReport, NodeInfo, Series, parameter_report};
use mmt::render::RendererStats;
use node::gated_from_wire;
use protocol::telerobot_to_operator::{ParameterSet, Parameters};
use rt::{Summary, TimingReport};
use serde::Serialize;
use sim::scene::Scene;
use transport::LinkReport;

use crate::device::{ForceRecord, OperatingState};
use crate::haptic::LoopEnd;
use crate::helper::Recording;
use crate::safety::SafetyStats;

pub use metrics::networked::{DelayEstimate, LagRange};

/// Everything a networked run reports.
#[derive(Clone, Debug, Serialize)]
pub struct NetworkedReport {
    /// The figures of `mmt experiment`.
    #[serde(flatten)]
    pub experiment: ExperimentReport,
    /// Lead of the rendered over the measured tangential force, by cross-correlation \[ms\].
    pub measured_delay_ms: Option<f64>,
    /// The cross-correlation behind it.
    pub delay_estimate: Option<DelayEstimate>,
    /// The one-way delay the run was set up with (the demo's shim), if known \[ms\].
    pub set_delay_ms: Option<f64>,
    /// The newest parameters received, as sent.
    pub parameters_received: Option<Parameters>,
    /// The haptic loop's timing.
    pub loop_timing: TimingReport,
    /// Ticks the loop skipped after stalls (filled with the previous tick in the series).
    pub missing_ticks: u64,
    /// The link as the operator saw it.
    pub link: LinkReport,
    /// Measurement receipt − send time mapped with the clock offset: the downlink's one-way
    /// latency \[µs\].
    pub downlink_latency: Summary,
    /// Measurements received (and lost to a full queue before the report thread took them).
    pub measurements: (u64, u64),
    /// Sessions the haptic loop ran (1 + reconnections).
    pub sessions: u64,
    /// Cloud frames indexed and refused.
    pub clouds: (u64, u64),
    /// What the safety layer did.
    pub safety: SafetyStats,
    /// The operator's renderers (the last session's node): the normal axis first (if the model
    /// has one), then each rendered tangential axis. `unresolved_ticks` counts the
    /// renderability gate acting (a raised mass or the reduced model), `clipped_ticks` the
    /// stiffness clipped by Colgate's bound.
    pub renderers: Vec<RendererStats>,
    /// The forces written to the device.
    pub device_forces: ForceRecord,
    /// The device.
    pub device: String,
    /// The device's operating state at the end of the run (after the loop disabled it:
    /// `Disabled`, or `Faulted` if it faulted).
    pub device_state: OperatingState,
    /// Times the device faulted: servo watchdog, SDK error, forces cut by the device itself
    /// (firmware watchdog, velocity guard), a refused enable.
    pub device_faults: u64,
    /// The fault the device ended in, if any: its cause and when.
    pub device_fault: Option<String>,
    /// Wall-clock length of the haptic loop \[s\].
    pub wall_seconds: f64,
    /// The telerobot daemon's summary (the demo, which runs it).
    pub telerobot: Option<telerobot::Summary>,
    /// The netem shim's figures (the demo).
    pub shim: Option<ShimReport>,
}

impl NetworkedReport {
    /// What the report holds beyond the figures computed from the recorded streams
    /// ([`NetworkedFigures`]): the counters only the end of the run knows, as JSON. A recording
    /// keeps them (`/run/end`), and `mmt report FILE.mcap` joins them to the figures it computes
    /// again.
    pub fn counters(&self) -> serde_json::Value {
        let mut all = serde_json::to_value(self).unwrap_or_default();
        let figures = serde_json::to_value(self.figures()).unwrap_or_default();
        if let (Some(all), Some(figures)) = (all.as_object_mut(), figures.as_object()) {
            for key in figures.keys() {
                all.remove(key);
            }
        }
        all
    }

    /// The figures computed from the recorded streams, as [`metrics::networked::figures`] gave
    /// them.
    pub fn figures(&self) -> NetworkedFigures {
        NetworkedFigures {
            experiment: self.experiment.clone(),
            measured_delay_ms: self.measured_delay_ms,
            delay_estimate: self.delay_estimate,
            missing_ticks: self.missing_ticks,
            downlink_latency: self.downlink_latency,
        }
    }
}

/// The netem shim's figures.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ShimReport {
    /// Release lateness (actual − due send time), both directions \[µs\].
    pub lateness: Summary,
    /// Datagrams forwarded up (operator → telerobot) and down.
    pub forwarded: (u64, u64),
    /// Datagrams dropped by the link model (loss, queue limit), up and down.
    pub dropped: (u64, u64),
}

impl From<&netem::ShimStats> for ShimReport {
    fn from(s: &netem::ShimStats) -> Self {
        ShimReport {
            lateness: s.lateness,
            forwarded: (s.up.forwarded, s.down.forwarded),
            dropped: (
                s.up.dropped_loss + s.up.dropped_limit,
                s.down.dropped_loss + s.down.dropped_limit,
            ),
        }
    }
}

/// What a run knew about itself.
#[derive(Clone, Debug)]
pub struct RunFacts {
    /// What the figures need: names, seed, set delay, tick 0 and period, the final clock offset
    /// (its `frame` is taken from the loop's end).
    pub run: NetworkedRun,
    /// The scene's ground truth, if known (the demo): the parameter report compares against it.
    pub truth: Option<Scene>,
    /// Link counters at the end.
    pub link: LinkReport,
    /// Measurements lost to the full queue.
    pub measurements_overwritten: u64,
    /// The loop's timing.
    pub timing: TimingReport,
    /// Wall-clock length \[s\].
    pub wall_seconds: f64,
}

/// What the nodes know at the end of a run: the operator's counters, and the parameters received
/// last against the scene's truth when it is known.
pub fn node_info(truth: Option<&Scene>, end: &LoopEnd) -> NodeInfo {
    let parameters = match (truth, end.parameters) {
        (Some(scene), Some(p)) => {
            let gated = |s: Option<ParameterSet>| s.and_then(|s| gated_from_wire(&s).ok());
            let (n, t) = (gated(p.normal), gated(p.tangential));
            parameter_report(scene, [n.as_ref(), t.as_ref()])
        }
        _ => Vec::new(),
    };
    NodeInfo {
        parameters,
        operator: end.node,
        ..NodeInfo::default()
    }
}

/// Builds the series and the report of a run.
pub fn build(facts: &RunFacts, rec: &Recording, end: &LoopEnd) -> (Series, NetworkedReport) {
    let mut run = facts.run.clone();
    run.frame = end.frame.map(|f| [f.normal, f.tangent1, f.tangent2]);
    let nodes = node_info(facts.truth.as_ref(), end);
    let (series, figures) = networked::figures(&run, &rec.ticks, &rec.measurements, nodes);
    let report = NetworkedReport {
        experiment: figures.experiment,
        measured_delay_ms: figures.measured_delay_ms,
        delay_estimate: figures.delay_estimate,
        set_delay_ms: run.set_delay_ms,
        parameters_received: end.parameters,
        loop_timing: facts.timing,
        missing_ticks: figures.missing_ticks,
        link: facts.link,
        downlink_latency: figures.downlink_latency,
        measurements: (
            rec.measurements.len() as u64,
            facts.measurements_overwritten,
        ),
        sessions: end.sessions,
        clouds: rec.clouds,
        safety: end.safety,
        renderers: end.renderers.clone(),
        device_forces: end.force_record,
        device: run.device.clone(),
        device_state: end.device.operating_state(),
        device_faults: end.device.fault_count(),
        device_fault: end
            .device
            .fault()
            .map(|f| format!("{} (at {:.3} s)", f.cause, f.at.as_secs_f64())),
        wall_seconds: facts.wall_seconds,
        telerobot: None,
        shim: None,
    };
    (series, report)
}

/// The stdout table: `mmt experiment`'s, then the networked figures.
pub fn table(r: &NetworkedReport) -> String {
    let mut out = metrics::table(&r.experiment);
    let _ = write_extras(&mut out, r);
    out
}

fn write_extras(out: &mut String, r: &NetworkedReport) -> std::fmt::Result {
    let opt =
        |v: Option<f64>, unit: &str| v.map_or("—".to_string(), |v| format!("{v:.2} {unit}"));
    // p50 / p99 / max of a distribution in µs, or in ms.
    let us = |q: &Summary| format!("{:.1} / {:.1} / {:.0} µs", q.p50_us, q.p99_us, q.max_us);
    let ms = |q: &Summary| {
        format!(
            "{:.2} / {:.2} / {:.2} ms",
            q.p50_us / 1e3,
            q.p99_us / 1e3,
            q.max_us / 1e3
        )
    };
    let count = |t: &TimingReport| format!("{} / {} / {}", t.ticks, t.overruns, t.skipped_ticks);
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
    let mut rows: Vec<(String, String)> = Vec::new();
    let mut row = |name: &str, value: String| rows.push((name.to_owned(), value));
    row(
        "measured_delay_ms (rendered leads measured)",
        opt(r.measured_delay_ms, "ms"),
    );
    if let Some(d) = r.set_delay_ms {
        row("  set one-way delay", format!("{d:.2} ms"));
    }
    if let Some(e) = &r.delay_estimate {
        row("  peak correlation", format!("{:.4}", e.peak_correlation));
    }
    let t = &r.loop_timing;
    row("haptic loop period p50 / p99 / max", us(&t.period));
    row("  lateness p50 / p99 / max", us(&t.lateness));
    row("  work p50 / p99 / max", us(&t.work));
    row("  ticks, overruns, skipped", count(t));
    let l = &r.link;
    row(
        "datagrams sent / received",
        format!("{} / {}", l.sent, l.received),
    );
    row(
        "  late / lost / duplicate / garbage",
        format!("{} / {} / {} / {}", l.late, l.lost, l.duplicates, l.garbage),
    );
    // What quinn itself did with the datagrams it was handed: every one on the wire (none held
    // back by a congestion window or pacing), no congestion events.
    let quinn = |l: &LinkReport| {
        format!(
            "{} of {} / {} / {}",
            l.quinn_datagrams_transmitted, l.sent, l.quinn_congestion_events, l.quinn_lost_packets
        )
    };
    row(
        "  quinn, operator: on the wire / congestion events / lost packets",
        quinn(l),
    );
    if let Some(t) = &r.telerobot {
        row(
            "  quinn, telerobot: on the wire / congestion events / lost packets",
            quinn(&t.link),
        );
    }
    row(
        "  longest gap between accepted datagrams",
        format!("{:.1} ms", l.max_gap_ms),
    );
    row(
        "RTT smoothed / min",
        format!("{} / {}", opt(l.rtt_ms, "ms"), opt(l.rtt_min_ms, "ms")),
    );
    row(
        "clock offset (telerobot − operator)",
        opt(l.clock_offset_ms, "ms"),
    );
    // One-way latencies, and beyond the set delay (what the stack adds: queueing, scheduling).
    let mut latency = |name: &str, l: &Summary| {
        row(name, ms(l));
        if let Some(d) = r.set_delay_ms {
            row(
                "  beyond the set delay p50 / p99 / max",
                us(&l.shifted(-d * 1e3)),
            );
        }
    };
    if let Some(t) = &r.telerobot {
        latency(
            "uplink: command sample → telerobot receipt",
            &t.command_latency,
        );
    }
    latency(
        "downlink: measurement send → operator receipt",
        &r.downlink_latency,
    );
    row("sessions", r.sessions.to_string());
    if let Some(t) = &r.telerobot {
        row(
            "telerobot loop period p50 / p99 / max",
            us(&t.timing.period),
        );
        row("  ticks, overruns, skipped", count(&t.timing));
    }
    if let Some(s) = &r.shim {
        row("netem release lateness p50 / p99 / max", us(&s.lateness));
    }
    let sum = |f: fn(&RendererStats) -> u64| r.renderers.iter().map(f).sum::<u64>();
    row(
        "renderer ticks: unresolved (gate) / clipped",
        format!(
            "{} / {}",
            sum(|s| s.unresolved_ticks),
            sum(|s| s.clipped_ticks)
        ),
    );
    let s = &r.safety;
    row(
        "safety episodes: watchdog / rate / max / workspace",
        format!(
            "{} / {} / {} / {}",
            s.watchdog_fading.episodes,
            s.rate_limited.episodes,
            s.saturated.episodes,
            s.workspace.episodes
        ),
    );
    row(
        "  loop overrun / stale parameters / clutch",
        format!(
            "{} / {} / {}",
            s.loop_overrun.episodes, s.stale_params.episodes, s.clutch.episodes
        ),
    );
    row(
        "  non-finite force / position / velocity",
        format!(
            "{} / {} / {}",
            s.non_finite_force.episodes,
            s.non_finite_position.episodes,
            s.non_finite_velocity.episodes
        ),
    );
    row(
        "  position-scale changes refused",
        s.scale_rejections.to_string(),
    );
    row(
        "device state, faults",
        format!("{:?} / {}", r.device_state, r.device_faults),
    );
    if let Some(f) = &r.device_fault {
        row("  fault", f.clone());
    }
    let p = &s.passivity;
    row(
        "passivity: min energy / dissipated / ticks",
        format!(
            "{:.2} / {:.2} mJ / {} ({} capped)",
            p.min_energy_j * 1e3,
            p.dissipated_j * 1e3,
            p.controlling.ticks,
            p.capped.ticks
        ),
    );
    writeln!(out, "network")?;
    for (name, value) in rows {
        writeln!(out, "{name:<46} {value:>14}")?;
    }
    Ok(())
}

/// The files of `--out DIR`: `mmt experiment`'s series and plots, and `report.json` with every
/// figure of [`NetworkedReport`].
pub fn files(
    r: &NetworkedReport,
    s: &Series,
) -> Result<Vec<(String, Vec<u8>)>, lab::plot::PlotError> {
    let mut files = lab::report::files(&r.experiment, s)?;
    let json =
        serde_json::to_string_pretty(r).map_err(|e| lab::plot::PlotError::Draw(e.to_string()))?;
    for (name, bytes) in &mut files {
        if name == "report.json" {
            *bytes = json.clone().into_bytes();
        }
    }
    Ok(files)
}

#[cfg(test)]
mod tests;
