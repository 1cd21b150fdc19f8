//! The report of a networked run: the same figures as `mmt experiment`, and what only a real
//! link has — `measured_delay_ms` by cross-correlation, the downlink latency (both computed by
//! [`metrics::networked`] from what the operator recorded, as `mmt report FILE.mcap` computes
//! them again from a recording) — plus what only the end of the run knows: the haptic loop's
//! timing, the link's counters, the safety layer's trips, the device's faults.

mod table;

use metrics::networked::{self, NetworkedFigures, NetworkedRun};
use metrics::{ExperimentReport, NodeInfo, Series, parameter_report};
use mmt::render::RendererStats;
use node::gated_from_wire;
use protocol::telerobot_to_operator::{ParameterSet, Parameters};
use rt::{Summary, TimingReport};
use serde::Serialize;
use sim::scene::Scene;
use transport::{LinkReport, Outages};

use crate::device::{BackendReport, ForceRecord, OperatingState};
use crate::haptic::LoopEnd;
use crate::helper::Recording;
use crate::safety::SafetyStats;

pub use metrics::networked::{DelayEstimate, LagRange};
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
    /// Cloud frames over the real-time budget (`mmt::contact::budget`): downsampled to fit, and
    /// refused (counted in `clouds` too).
    pub clouds_over_budget: (u64, u64),
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
    /// The device backend's own counters (the ROS 2 device's: poses refused, commands
    /// published and zeroed), if it keeps any.
    pub device_backend: Option<BackendReport>,
    /// Wall-clock length of the haptic loop \[s\].
    pub wall_seconds: f64,
    /// The directions the series' forces are plotted along (`mmt plot` reads them).
    pub series_axes: SeriesAxes,
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
    /// The telerobot's camera frames `[sent, refused]` and, of them, over the real-time budget
    /// `[downsampled, refused]`.
    pub telerobot_camera: Option<[(u64, u64); 2]>,
    /// The mean delay at which the telerobot played the operator's path \[ms\]: the link's, plus
    /// what its playout added for the link's jitter.
    pub played_lag_ms: Option<f64>,
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
        prior: end.prior,
        ..NodeInfo::default()
    }
}

/// Builds the series and the report of a run.
pub fn build(facts: &RunFacts, rec: &Recording, end: &LoopEnd) -> (Series, NetworkedReport) {
    let mut run = facts.run.clone();
    run.frame = end.frame.map(|f| [f.normal, f.tangent1, f.tangent2]);
    let nodes = node_info(facts.truth.as_ref(), end);
    let (series, figures) = networked::figures(&run, &rec.ticks, &rec.measurements, nodes);
    let mut experiment = figures.experiment;
    let ticks = rec.ticks.last().map_or(0, |t| t.index + 1);
    let outages = networked::mark_outages(
        &run,
        ticks,
        &rec.measurements,
        &mut experiment.error_over_time,
    );
    let report = NetworkedReport {
        experiment,
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
        outages,
        clouds: rec.clouds,
        clouds_over_budget: rec.clouds_over_budget,
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
        device_backend: end.device.backend_report(),
        wall_seconds: facts.wall_seconds,
        series_axes: SeriesAxes {
            tangent: series.axis,
            normal: series.normal,
        },
    };
    (series, report)
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
