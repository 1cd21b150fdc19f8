//! `mmt report FILE.mcap`: a run's report computed again from its recording, by the same code
//! that computed it live — the experiment harness's [`Series`] rebuilt tick by tick and
//! [`metrics::analyse`]d (`mmt experiment`), or [`metrics::networked::figures`] on the recorded
//! haptic ticks and measurements (`operator run`, the demo). What only the end of a run knows
//! (the nodes' counters and final estimates; a networked run's loop timing, link and safety
//! counters) comes from the recording's `/run/end`, as the run wrote it.

use metrics::networked::{NetworkedRun, figures};
use metrics::{ExperimentReport, NodeInfo, RunInfo, Series, analyse};
use node::operator::OperatorOutput;
use protocol::Header;
use protocol::operator_to_telerobot::Command;
use record::schema::{OperatorTick, RunEnd, RunStart, TelerobotTick};
use record::{Kind, Recording, Side};
use thiserror::Error;

/// A report computed from a recording.
#[derive(Clone, Debug)]
pub struct RecordedReport {
    /// `mmt experiment`'s figures (the networked report's included).
    pub experiment: ExperimentReport,
    /// The whole report as the run's `report.json` holds it (a networked run's figures joined
    /// to its recorded counters).
    pub json: serde_json::Value,
    /// The series.
    pub series: Series,
    /// What the caller should know: the file was cut short, messages were dropped.
    pub warnings: Vec<String>,
    /// A networked run's (its `report.json` holds more than [`ExperimentReport`]).
    pub networked: bool,
}

/// Why no report could be computed.
#[derive(Debug, Error)]
pub enum RecordedError {
    /// The file was refused (not ours, another version, another kind).
    #[error(transparent)]
    Read(#[from] record::ReadError),
    /// Something the report needs is not in the file.
    #[error("{path}: {what}")]
    Missing {
        /// The file.
        path: String,
        /// What is missing.
        what: String,
    },
}

/// The topics a report needs.
pub const TOPICS: [&str; 5] = [
    record::schema::topic::RUN,
    record::schema::topic::RUN_END,
    record::schema::topic::OPERATOR_TICK,
    record::schema::topic::OPERATOR_MEASUREMENT,
    record::schema::topic::TELEROBOT_TICK,
];

/// Reads `path` and computes its report.
pub fn report_file(path: &std::path::Path) -> Result<RecordedReport, RecordedError> {
    let rec = record::read(path, &TOPICS)?;
    rec.require(
        &[Kind::Operator, Kind::Demo, Kind::Experiment],
        "mmt report needs an operator, demo or experiment recording (one with the haptic loop's \
         ticks); `mmt estimate --from` reads a telerobot recording",
    )?;
    report(&rec)
}

/// The report of a recording already read.
pub fn report(rec: &Recording) -> Result<RecordedReport, RecordedError> {
    let missing = |what: &str| RecordedError::Missing {
        path: rec.path.display().to_string(),
        what: what.to_owned(),
    };
    let run = rec
        .run(Side::Operator)
        .ok_or_else(|| missing("no /run of the operator side: the run never started"))?;
    let end = rec.end(Side::Operator);
    let mut warnings = Vec::new();
    if let Some(why) = &rec.truncated {
        warnings.push(format!(
            "the recording is cut short ({why}): figures up to its end"
        ));
    }
    if let (Some(first), Some(last)) = (rec.operator_ticks.first(), rec.operator_ticks.last()) {
        let span = last.index.saturating_sub(first.index) + 1;
        let missing = span.saturating_sub(rec.operator_ticks.len() as u64);
        if missing > 0 {
            warnings.push(format!(
                "{missing} of {span} haptic ticks are not in the recording (paused or dropped): \
                 figures differ from the run's"
            ));
        }
    }
    if end.is_none() {
        warnings.push(
            "no /run/end: the run did not finish; its end-of-run counters are unknown".to_owned(),
        );
    }
    if let Some(e) = end.filter(|e| e.recorder_dropped > 0) {
        warnings.push(format!(
            "{} messages were dropped while recording: figures may differ from the run's",
            e.recorder_dropped
        ));
    }
    let nodes = end.and_then(|e| e.nodes.clone()).unwrap_or_default();
    let networked = rec.kind() != Some(Kind::Experiment);
    let (experiment, json, series) = if !networked {
        let (series, report) = experiment(rec, run, nodes).map_err(|w| missing(&w))?;
        let json = serde_json::to_value(&report).unwrap_or_default();
        (report, json, series)
    } else {
        networked_report(rec, run, end, nodes)
    };
    Ok(RecordedReport {
        experiment,
        json,
        series,
        warnings,
        networked,
    })
}

/// An experiment's series, rebuilt as the harness built it: per tick, the operator's row, the
/// true force and the telerobot's row, in that order.
fn experiment(
    rec: &Recording,
    run: &RunStart,
    nodes: NodeInfo,
) -> Result<(Series, ExperimentReport), String> {
    let [axis, normal] = run
        .axes
        .ok_or("the experiment's /run has no axes".to_owned())?;
    let n = rec.operator_ticks.len().min(rec.telerobot_ticks.len());
    let mut series = Series::with_capacity(n, axis, normal, run.period_ns);
    for (op, tr) in rec.operator_ticks.iter().zip(&rec.telerobot_ticks) {
        push_experiment_tick(&mut series, op, tr);
    }
    let info = RunInfo {
        experiment: run.experiment.clone(),
        scene: run.scene_name.clone(),
        left_out: run.left_out.clone(),
        trajectory: run.device.clone().unwrap_or_default(),
        seed: run.seed.unwrap_or(0),
        delay_ms: run.set_delay_ms.unwrap_or(0.0),
    };
    let report = analyse(&info, &series, nodes);
    Ok((series, report))
}

fn push_experiment_tick(series: &mut Series, op: &OperatorTick, tr: &TelerobotTick) {
    let output = |force_n, in_contact| OperatorOutput {
        force_n,
        command: Command {
            header: Header::default(),
            position_m: op.command_position_m,
            velocity_m_per_s: op.command_velocity_m_per_s,
        },
        in_contact,
        rendering: op.rendering,
        reduced: op.reduced,
    };
    let out = output(op.force_rendered_n, op.in_contact);
    let remote = output(
        op.remote_force_n.unwrap_or(op.force_rendered_n),
        op.remote_in_contact.unwrap_or(op.in_contact),
    );
    series.push_operator(op.command_position_m, &out, &remote);
    if let Some(f) = tr.true_force_n {
        series.push_true_force(tr.command_sample_time_ns, f);
    }
    series.push_telerobot(
        tr.command_sample_time_ns,
        tr.force_on_tool_n,
        tr.true_in_contact.unwrap_or(tr.in_contact),
        tr.estimator_stable,
        tr.reconstruction.map(|[a, b]| (a, b)),
        tr.true_state
            .map_or([(0.0, 0.0); 2], |s| s.map(|[a, b]| (a, b))),
        op.tangential_state.map(|s| s.map(|[a, b]| (a, b))),
    );
}

/// A networked run's figures, joined to its recorded counters.
fn networked_report(
    rec: &Recording,
    run: &RunStart,
    end: Option<&RunEnd>,
    nodes: NodeInfo,
) -> (ExperimentReport, serde_json::Value, Series) {
    let facts = NetworkedRun {
        experiment: run.experiment.clone(),
        scene: run.scene_name.clone(),
        left_out: run.left_out.clone(),
        device: run.device.clone().unwrap_or_default(),
        seed: run.seed.unwrap_or(0),
        set_delay_ms: run.set_delay_ms,
        start_ns: run.start_ns,
        period_ns: run.period_ns,
        final_offset_ns: end.and_then(|e| e.final_offset_ns),
        frame: end
            .and_then(|e| e.frame)
            .map(|f| [f.normal, f.tangent1, f.tangent2]),
    };
    let ticks: Vec<_> = rec
        .operator_ticks
        .iter()
        .map(OperatorTick::sample)
        .collect();
    let measurements: Vec<_> = rec.measurements.iter().map(|m| m.sample()).collect();
    let (series, mut figures) = figures(&facts, &ticks, &measurements, nodes);
    // The windows an outage touched, marked as the run's report marks them.
    let last = ticks.last().map_or(0, |t| t.index + 1);
    let windows = &mut figures.experiment.error_over_time;
    metrics::networked::mark_outages(&facts, last, &measurements, windows);
    let mut json = serde_json::to_value(&figures).unwrap_or_default();
    if let (Some(all), Some(serde_json::Value::Object(counters))) =
        (json.as_object_mut(), end.and_then(|e| e.counters.clone()))
    {
        all.extend(counters);
    }
    (figures.experiment, json, series)
}

/// The files of `mmt report --out DIR`: those of the run (`report.json`, `series.csv`, plots).
/// An experiment's `report.json` is the harness's, byte for byte; a networked run's holds the
/// same values (its keys in another order).
pub fn files(r: &RecordedReport) -> Result<Vec<(String, Vec<u8>)>, crate::plot::PlotError> {
    let mut files = crate::report::files(&r.experiment, &r.series)?;
    if !r.networked {
        return Ok(files);
    }
    let json = serde_json::to_string_pretty(&r.json)
        .map_err(|e| crate::plot::PlotError::Draw(e.to_string()))?;
    for (name, bytes) in &mut files {
        if name == "report.json" {
            *bytes = json.clone().into_bytes();
        }
    }
    Ok(files)
}
