//! The report of a networked run: the same figures as `mmt experiment` (computed by
//! `metrics::analyse` from a [`Series`] built out of what the operator recorded), plus
//! what only a real link has — `measured_delay_ms` by cross-correlation ([`delay`]), the haptic
//! loop's timing, the link's counters and latency, the safety layer's trips.
//!
//! How the series is built: operator tick `k` is the command sampled at `t0 + k·T`; each
//! `Measurement` names the command it executed (`command_sample_time_ns`), so the force the
//! telerobot measured lines up with the force rendered for the same command — "rendered shifted
//! by the delay", exactly. The telerobot's ground truth is not on the wire: the "true" force is
//! the measured one (sensor noise included), the true contact is the telerobot's tracked contact,
//! and the contact-deflection drift figure is left out. There is no shadow node in the app, so
//! the remote-only contact figures are left out too.

pub mod delay;
mod table;

use metrics::{
    ExperimentReport, NodeInfo, ParameterReport, RunInfo, Series, analyse, parameter_report,
};
use mmt::render::RendererStats;
use node::gated_from_wire;
use node::operator::OperatorOutput;
use protocol::Header;
use protocol::operator_to_telerobot::Command;
use protocol::telerobot_to_operator::{ParameterSet, Parameters, SurfaceFrame};
use rt::{Summary, TimingReport};
use serde::Serialize;
use sim::scene::Scene;
use transport::{LinkReport, Outages};

use crate::device::{ForceRecord, OperatingState};
use crate::haptic::LoopEnd;
use crate::helper::Recording;
use crate::safety::SafetyStats;
use mmt::vec3;

pub use delay::{DelayEstimate, LagRange};
pub use table::table;

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
    /// Times without measurements from the telerobot (100 ms or more) over the whole run,
    /// across sessions: `link.max_gap_ms` is within a session, and a reconnect restarts it.
    pub outages: Outages,
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
    /// The directions the series' forces are plotted along (`mmt plot` reads them).
    pub series_axes: SeriesAxes,
}

/// The directions a series' forces are plotted along: the surface's second tangent (the thesis's
/// "y") and its normal, unit vectors in the world frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct SeriesAxes {
    /// Second tangent.
    pub tangent: [f64; 3],
    /// Normal.
    pub normal: [f64; 3],
}

/// What another part of a run measured, for the rows of the operator's table that only a run
/// with that part in the same process can fill (the demo: the telerobot daemon and the shim).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PeerFigures {
    /// The telerobot's link counters (quinn's, for its row).
    pub telerobot_link: Option<LinkReport>,
    /// The uplink's one-way latency, command sample → telerobot receipt.
    pub uplink_latency: Option<Summary>,
    /// The telerobot loop's timing.
    pub telerobot_timing: Option<TimingReport>,
    /// The netem shim's release lateness.
    pub shim_lateness: Option<Summary>,
}

/// What a run knew about itself.
#[derive(Clone, Debug)]
pub struct RunFacts {
    /// `networked` (`operator run`) or `demo`.
    pub experiment: String,
    /// Scene name and left-out terms, from the `Welcome`.
    pub scene: String,
    /// Terms the scene's model leaves out, from the `Welcome`.
    pub left_out: Vec<String>,
    /// The device (`scripted:exp1`, …).
    pub device: String,
    /// Seed of the simulated telerobot, if known (0 otherwise).
    pub seed: u64,
    /// The set one-way delay, if known (the demo) \[ms\].
    pub set_delay_ms: Option<f64>,
    /// The scene's ground truth, if known (the demo): the parameter report compares against it.
    pub truth: Option<Scene>,
    /// Tick 0's time [ns, operator clock] and the period \[ns\].
    pub start_ns: i64,
    /// Tick period \[ns\].
    pub period_ns: i64,
    /// The clock offset at the end (telerobot − operator) \[ns\], for measurements taken before
    /// the first estimate.
    pub final_offset_ns: Option<i64>,
    /// Link counters at the end.
    pub link: LinkReport,
    /// Measurements lost to the full queue.
    pub measurements_overwritten: u64,
    /// The loop's timing.
    pub timing: TimingReport,
    /// Wall-clock length \[s\].
    pub wall_seconds: f64,
}

/// Builds the series and the report of a run.
pub fn build(facts: &RunFacts, rec: &Recording, end: &LoopEnd) -> (Series, NetworkedReport) {
    let frame = end.frame.unwrap_or(SurfaceFrame {
        normal: [0.0, 0.0, 1.0],
        tangent1: [1.0, 0.0, 0.0],
        tangent2: [0.0, 1.0, 0.0],
    });
    let (series, missing_ticks) = series(facts, rec, frame);
    // The delay takes the run's set delay when known (the demo), else the measured one (a
    // delay, so not below 0: the estimate spreads ±2 ms around a zero delay): the thesis's
    // contact-latency figure is two of it.
    let estimate = measured_delay(facts, rec, &series);
    let info = RunInfo {
        experiment: facts.experiment.clone(),
        scene: facts.scene.clone(),
        left_out: facts.left_out.clone(),
        trajectory: facts.device.clone(),
        seed: facts.seed,
        delay_ms: facts
            .set_delay_ms
            .or(estimate.map(|e| e.delay_ms.max(0.0)))
            .unwrap_or(0.0),
    };
    let nodes = NodeInfo {
        parameters: parameters(facts, end),
        operator: end.node,
        ..NodeInfo::default()
    };
    let mut experiment = analyse(&info, &series, nodes);
    // No shadow node runs in the app: its figures would repeat the operator's.
    experiment.rms_error_pct_remote_contact = None;
    experiment.contact_switch_latency_ms.remote_only = None;
    let outages = mark_outages(facts, rec, &mut experiment.error_over_time);
    let report = NetworkedReport {
        experiment,
        measured_delay_ms: estimate.map(|e| e.delay_ms),
        delay_estimate: estimate,
        set_delay_ms: facts.set_delay_ms,
        parameters_received: end.parameters,
        loop_timing: facts.timing,
        missing_ticks,
        link: facts.link,
        downlink_latency: downlink_latency(facts, rec),
        measurements: (
            rec.measurements.len() as u64,
            facts.measurements_overwritten,
        ),
        sessions: end.sessions,
        outages,
        clouds: rec.clouds,
        safety: end.safety,
        renderers: end.renderers.clone(),
        device_forces: end.force_record,
        device: facts.device.clone(),
        device_state: end.device.operating_state(),
        device_faults: end.device.fault_count(),
        device_fault: end
            .device
            .fault()
            .map(|f| format!("{} (at {:.3} s)", f.cause, f.at.as_secs_f64())),
        wall_seconds: facts.wall_seconds,
        series_axes: SeriesAxes {
            tangent: series.axis,
            normal: series.normal,
        },
    };
    (series, report)
}

/// The run's outages (from the measurements' arrivals, to the last tick), and each 1 s window
/// of `windows` that overlaps one marked.
fn mark_outages(facts: &RunFacts, rec: &Recording, windows: &mut [metrics::Window]) -> Outages {
    let mut arrivals: Vec<i64> = rec.measurements.iter().map(|m| m.received_ns).collect();
    arrivals.sort_unstable();
    let ticks = rec.ticks.last().map_or(0, |t| t.index as i64 + 1);
    let end_ns = facts.start_ns + ticks * facts.period_ns;
    let (outages, spans) = Outages::from_arrivals(&arrivals, end_ns);
    for w in windows {
        let from = facts.start_ns + (w.t_s * 1e9).round() as i64;
        let to = from + 1_000_000_000;
        w.outage = spans.iter().any(|&(a, b)| a < to && b > from);
    }
    outages
}

/// The last parameters received against the scene's truth, when the run knows it.
fn parameters(facts: &RunFacts, end: &LoopEnd) -> Vec<ParameterReport> {
    match (&facts.truth, end.parameters) {
        (Some(scene), Some(p)) => {
            let gated = |s: Option<ParameterSet>| s.and_then(|s| gated_from_wire(&s).ok());
            let (n, t) = (gated(p.normal), gated(p.tangential));
            parameter_report(scene, [n.as_ref(), t.as_ref()])
        }
        _ => Vec::new(),
    }
}

/// Each measurement's receipt minus its send time on the operator's clock (mapped with the
/// clock offset of its time, else the final one): the downlink's one-way latency.
fn downlink_latency(facts: &RunFacts, rec: &Recording) -> Summary {
    let mut downlink: Vec<i64> = rec
        .measurements
        .iter()
        .filter_map(|m| {
            let offset = m.offset_ns.or(facts.final_offset_ns)?;
            Some(m.received_ns - (m.message.header.send_time_ns - offset))
        })
        .collect();
    Summary::of_samples(&mut downlink)
}

/// The series, one entry per tick; ticks the loop skipped repeat the previous one (counted).
fn series(facts: &RunFacts, rec: &Recording, frame: SurfaceFrame) -> (Series, u64) {
    // Up to the last tick recorded (the recording stops after an hour).
    let n = rec.ticks.last().map_or(0, |t| t.index as usize + 1);
    let mut s = Series::with_capacity(n, frame.tangent2, frame.normal, facts.period_ns);
    let mut records = rec.ticks.iter().peekable();
    let mut previous = None;
    let mut missing = 0;
    for k in 0..n as u64 {
        let record = match records.next_if(|r| r.index == k) {
            Some(r) => Some(*r),
            None => {
                missing += 1;
                previous
            }
        };
        previous = record;
        let r = record.unwrap_or_default();
        let out = OperatorOutput {
            force_n: r.force_n,
            command: Command {
                header: Header::default(),
                position_m: r.position_m,
                velocity_m_per_s: [0.0; 3],
            },
            in_contact: r.in_contact,
            rendering: r.rendering,
        };
        s.push_operator(r.position_m, &out, &out);
    }
    // The telerobot's stability by command tick (the first measurement executing command k; ticks
    // without one keep the previous state), so that "time to stable" counts from the first
    // contact on the same time axis.
    let mut stable = vec![None; n];
    for m in &rec.measurements {
        let msg = &m.message;
        let command_ns = msg.command_sample_time_ns - facts.start_ns;
        s.push_telerobot(
            command_ns,
            msg.force_on_tool_n,
            msg.in_contact,
            msg.estimator_stable,
            msg.reconstruction.map(|[y2, e2]| (y2, e2)),
            [(0.0, 0.0); 2],
            [None; 2],
        );
        if let Some(slot) = usize::try_from(command_ns / facts.period_ns)
            .ok()
            .filter(|_| command_ns >= 0)
            .and_then(|k| stable.get_mut(k))
        {
            slot.get_or_insert(msg.estimator_stable);
        }
    }
    let mut last = false;
    s.stable = stable
        .into_iter()
        .map(|st| {
            last = st.unwrap_or(last);
            last
        })
        .collect();
    (s, missing)
}

/// The cross-correlation of the rendered and the measured tangential force, over the ticks where
/// a model is rendered.
fn measured_delay(facts: &RunFacts, rec: &Recording, s: &Series) -> Option<DelayEstimate> {
    let rendered: Vec<f64> = s.rendered.iter().map(|f| vec3::dot(*f, s.axis)).collect();
    let period = facts.period_ns as f64;
    let measured: Vec<(f64, f64)> = rec
        .measurements
        .iter()
        .filter_map(|m| {
            let offset = m.offset_ns.or(facts.final_offset_ns)?;
            let t = m.message.header.sample_time_ns - offset - facts.start_ns;
            Some((
                t as f64 / period,
                vec3::dot(m.message.force_on_tool_n, s.axis),
            ))
        })
        .collect();
    delay::estimate(
        &rendered,
        &s.rendering,
        &measured,
        period * 1e-9,
        LagRange::default(),
    )
}

/// The files of `--out DIR`: `report.json` with every figure of [`NetworkedReport`], and the
/// series as `series.csv`. The plots are `lab`'s (`mmt plot DIR` draws them from these two
/// files): the daemons link no plotting library.
pub fn files(r: &NetworkedReport, s: &Series) -> Result<Vec<(String, Vec<u8>)>, serde_json::Error> {
    Ok(vec![
        ("report.json".to_owned(), serde_json::to_vec_pretty(r)?),
        ("series.csv".to_owned(), s.to_csv().into_bytes()),
    ])
}

#[cfg(test)]
mod tests;
