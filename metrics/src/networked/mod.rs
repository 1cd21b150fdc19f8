//! The figures of a networked run (`operator run`, the demo) from what the operator recorded:
//! one [`TickSample`] per haptic-loop tick and every [`MeasurementSample`] the telerobot sent.
//! The operator app computes its report with these functions at the end of a run, and `mmt
//! report FILE.mcap` computes them again from a recording of the same run: the same inputs give
//! the same figures.
//!
//! How the series is built: operator tick `k` is due at `t0 + k·T` and samples its command when
//! it runs (its `sample_time_ns`, later than that after a stall); each measurement names the
//! command it executed (`command_sample_time_ns`), so the force the telerobot measured lines up
//! with the force rendered for the same command — "rendered shifted by the delay", exactly. The
//! telerobot's ground truth is not on the wire: the "true" force is the measured one (sensor
//! noise included), the true contact is the telerobot's tracked contact, and the
//! contact-deflection drift figure is left out. There is no shadow node in the app, so
//! the remote-only contact figures are left out too.

pub mod delay;

use node::operator::OperatorOutput;
use protocol::Header;
use protocol::operator_to_telerobot::Command;
use serde::{Deserialize, Serialize};

use crate::{ExperimentReport, NodeInfo, RunInfo, Series, analyse};
use mmt::vec3;

pub use delay::{DelayEstimate, LagRange};

/// What one haptic-loop tick contributes to the report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TickSample {
    /// Tick number (the tick's deadline is `start + index·period`).
    pub index: u64,
    /// The command's sample time: when the loop read the device [ns, operator clock]; after a
    /// stall, later than the tick's deadline. Absent (recordings made before it): the deadline.
    #[serde(default)]
    pub sample_time_ns: Option<i64>,
    /// The commanded position \[m\], world frame.
    pub position_m: [f64; 3],
    /// The operator node's force \[N\], before the safety layer.
    pub force_n: [f64; 3],
    /// The node is in contact.
    pub in_contact: bool,
    /// The node renders a model.
    pub rendering: bool,
    /// The model rendered is the telerobot's reduced first model (massless), not the whole
    /// structure.
    #[serde(default)]
    pub reduced: bool,
}

/// A telerobot measurement as the operator received it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MeasurementSample {
    /// Sensor time [ns, telerobot clock].
    pub sample_time_ns: i64,
    /// Send time [ns, telerobot clock].
    pub send_time_ns: i64,
    /// Sample time of the command being executed [ns, operator clock].
    pub command_sample_time_ns: i64,
    /// Force the environment exerts on the tool \[N\].
    pub force_on_tool_n: [f64; 3],
    /// The telerobot's tracked contact.
    pub in_contact: bool,
    /// The telerobot's estimators all pass every gate.
    pub estimator_stable: bool,
    /// `[Σ y², Σ (y − ψᵀθ̂)²]` of the tick, while learning and confident.
    pub reconstruction: Option<[f64; 2]>,
    /// When it arrived [ns, operator clock].
    pub received_ns: i64,
    /// The clock-offset estimate when it was taken (telerobot − operator) \[ns\].
    pub offset_ns: Option<i64>,
}

/// What a networked run knew about itself that the figures need.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct NetworkedRun {
    /// `networked` (`operator run`) or `demo`.
    pub experiment: String,
    /// Scene name, from the `Welcome`.
    pub scene: String,
    /// Terms the scene's model leaves out, from the `Welcome`.
    pub left_out: Vec<String>,
    /// The device (`scripted:exp1`, …): the report's trajectory.
    pub device: String,
    /// Seed of the simulated telerobot, if known (0 otherwise).
    pub seed: u64,
    /// The set one-way delay, if known (the demo) \[ms\].
    pub set_delay_ms: Option<f64>,
    /// Tick 0's time [ns, operator clock].
    pub start_ns: i64,
    /// Tick period \[ns\].
    pub period_ns: i64,
    /// The clock offset at the end (telerobot − operator) \[ns\], for measurements taken before
    /// the first estimate.
    pub final_offset_ns: Option<i64>,
    /// The newest surface frame the telerobot reported, `[normal, tangent1, tangent2]`: the
    /// report's axes (the horizontal table's when none came).
    pub frame: Option<[[f64; 3]; 3]>,
}

/// The figures computed from the recorded streams.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NetworkedFigures {
    /// The figures of `mmt experiment`.
    #[serde(flatten)]
    pub experiment: ExperimentReport,
    /// Lead of the rendered over the measured tangential force, by cross-correlation \[ms\].
    pub measured_delay_ms: Option<f64>,
    /// The cross-correlation behind it.
    pub delay_estimate: Option<DelayEstimate>,
    /// Ticks the loop skipped after stalls (filled with the previous tick in the series).
    pub missing_ticks: u64,
    /// Measurement receipt − send time mapped with the clock offset: the downlink's one-way
    /// latency \[µs\].
    pub downlink_latency: rt::Summary,
}

/// The series and figures of a networked run. `nodes` carries what only the nodes know at the
/// end (their counters, the parameters against a known truth).
pub fn figures(
    run: &NetworkedRun,
    ticks: &[TickSample],
    measurements: &[MeasurementSample],
    nodes: NodeInfo,
) -> (Series, NetworkedFigures) {
    let (series, missing_ticks) = series(run, ticks, measurements);
    // The delay takes the run's set delay when known (the demo), else the measured one (a
    // delay, so not below 0: the estimate spreads ±2 ms around a zero delay): the thesis's
    // contact-latency figure is two of it.
    let estimate = measured_delay(run, ticks, measurements, &series);
    let info = RunInfo {
        experiment: run.experiment.clone(),
        scene: run.scene.clone(),
        left_out: run.left_out.clone(),
        trajectory: run.device.clone(),
        seed: run.seed,
        delay_ms: run
            .set_delay_ms
            .or(estimate.map(|e| e.delay_ms.max(0.0)))
            .unwrap_or(0.0),
    };
    let mut experiment = analyse(&info, &series, nodes);
    // No shadow node runs in the app: its figures would repeat the operator's.
    experiment.rms_error_pct_remote_contact = None;
    experiment.contact_switch_latency_ms.remote_only = None;
    let mut downlink: Vec<i64> = measurements
        .iter()
        .filter_map(|m| {
            let offset = m.offset_ns.or(run.final_offset_ns)?;
            Some(m.received_ns - (m.send_time_ns - offset))
        })
        .collect();
    let figures = NetworkedFigures {
        experiment,
        measured_delay_ms: estimate.map(|e| e.delay_ms),
        delay_estimate: estimate,
        missing_ticks,
        downlink_latency: rt::Summary::of_samples(&mut downlink),
    };
    (series, figures)
}

/// The run's outages by the measurements' arrivals, to the end of tick `ticks` (a run that ends
/// in an outage counts it); every 1 s window of `windows` that overlaps one is marked: its
/// error is not the model's alone. The operator's report and `mmt report FILE.mcap` both call
/// it.
pub fn mark_outages(
    run: &NetworkedRun,
    ticks: u64,
    measurements: &[MeasurementSample],
    windows: &mut [crate::Window],
) -> rt::Outages {
    let mut arrivals: Vec<i64> = measurements.iter().map(|m| m.received_ns).collect();
    arrivals.sort_unstable();
    let end_ns = run.start_ns + ticks as i64 * run.period_ns;
    let (outages, spans) = rt::Outages::from_arrivals(&arrivals, end_ns);
    for w in windows {
        let from = run.start_ns + (w.t_s * 1e9).round() as i64;
        let to = from + 1_000_000_000;
        w.outage = spans.iter().any(|&(a, b)| a < to && b > from);
    }
    outages
}

/// The series, one entry per tick; ticks the loop skipped repeat the previous one (counted).
pub fn series(
    run: &NetworkedRun,
    ticks: &[TickSample],
    measurements: &[MeasurementSample],
) -> (Series, u64) {
    let [normal, _, tangent2] =
        run.frame
            .unwrap_or([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    // Up to the last tick recorded (the recording stops after an hour).
    let n = ticks.last().map_or(0, |t| t.index as usize + 1);
    let mut s = Series::with_capacity(n, tangent2, normal, run.period_ns);
    let mut records = ticks.iter().peekable();
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
            reduced: r.reduced,
        };
        s.push_operator(r.position_m, &out, &out);
    }
    // The telerobot's stability by command tick (the first measurement executing command k; ticks
    // without one keep the previous state), so that "time to stable" counts from the first
    // contact on the same time axis.
    let mut stable = vec![None; n];
    let sampled = CommandTicks::of(run, ticks);
    for m in measurements {
        let command_ns = sampled
            .deadline_ns(m.command_sample_time_ns)
            .saturating_sub(run.start_ns);
        s.push_telerobot(
            command_ns,
            m.force_on_tool_n,
            m.in_contact,
            m.estimator_stable,
            m.reconstruction.map(|[y2, e2]| (y2, e2)),
            [(0.0, 0.0); 2],
            [None; 2],
        );
        if let Some(slot) = usize::try_from(command_ns / run.period_ns)
            .ok()
            .filter(|_| command_ns >= 0)
            .and_then(|k| stable.get_mut(k))
        {
            slot.get_or_insert(m.estimator_stable);
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

/// Which tick sampled a command: the ticks' sample times, in tick order.
struct CommandTicks {
    /// `(sample_time_ns, index)` of the ticks that recorded one.
    sampled: Vec<(i64, u64)>,
    start_ns: i64,
    period_ns: i64,
}

impl CommandTicks {
    fn of(run: &NetworkedRun, ticks: &[TickSample]) -> CommandTicks {
        let mut sampled: Vec<(i64, u64)> = ticks
            .iter()
            .filter_map(|t| Some((t.sample_time_ns?, t.index)))
            .collect();
        // A loop's read times never go back; a hand-edited recording's might.
        sampled.sort_unstable();
        CommandTicks {
            sampled,
            start_ns: run.start_ns,
            period_ns: run.period_ns,
        }
    }

    /// The deadline of the tick that sampled the command stamped `command_ns` (a command carries
    /// its tick's sample time exactly). A stamp no recorded tick has (older recordings, whose
    /// stamps are the deadlines; a tick record dropped) is taken as the deadline itself.
    fn deadline_ns(&self, command_ns: i64) -> i64 {
        let at = self.sampled.partition_point(|&(t, _)| t < command_ns);
        match self.sampled.get(at) {
            Some(&(t, index)) if t == command_ns => {
                let k = i64::try_from(index).unwrap_or(i64::MAX);
                self.start_ns
                    .saturating_add(k.saturating_mul(self.period_ns))
            }
            _ => command_ns,
        }
    }
}

/// The cross-correlation of the rendered and the measured tangential force, over the ticks where
/// a model is rendered, each at the time it was rendered: the time the loop read the device,
/// which after a stall is later than the tick's deadline (the lateness is not link delay).
fn measured_delay(
    run: &NetworkedRun,
    ticks: &[TickSample],
    measurements: &[MeasurementSample],
    s: &Series,
) -> Option<DelayEstimate> {
    let period = run.period_ns as f64;
    let rendered: Vec<(f64, f64)> = ticks
        .iter()
        .filter(|t| t.rendering)
        .map(|t| {
            let at = t.sample_time_ns.map_or(t.index as f64, |ns| {
                ns.saturating_sub(run.start_ns) as f64 / period
            });
            (at, vec3::dot(t.force_n, s.axis))
        })
        .collect();
    let measured: Vec<(f64, f64)> = measurements
        .iter()
        .filter_map(|m| {
            let offset = m.offset_ns.or(run.final_offset_ns)?;
            let t = m.sample_time_ns - offset - run.start_ns;
            Some((t as f64 / period, vec3::dot(m.force_on_tool_n, s.axis)))
        })
        .collect();
    delay::estimate(&rendered, &measured, period * 1e-9, LagRange::default())
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: i64 = 1_000_000;

    /// A 1 kHz run whose tick 0 is at `start_ns`.
    fn run_from(start_ns: i64) -> NetworkedRun {
        NetworkedRun {
            start_ns,
            period_ns: MS,
            ..NetworkedRun::default()
        }
    }

    /// With commands stamped when the device is read, a stalled loop's catch-up ticks carry
    /// stamps milliseconds after their deadlines, several within one period: divided by the
    /// period, their measurements landed on later ticks (and all but the first were lost). Each
    /// now lands on the tick that sampled its command.
    #[test]
    fn a_measurement_lands_on_the_tick_that_sampled_its_command() {
        let run = run_from(50 * MS);
        // Ticks 3..=6 stall until 6.5 ms, then run 10 µs apart.
        let read = |k: i64| match k {
            3..=6 => 6 * MS + MS / 2 + (k - 3) * 10_000,
            _ => k * MS,
        };
        let ticks: Vec<TickSample> = (0..10)
            .map(|k| TickSample {
                index: k as u64,
                sample_time_ns: Some(run.start_ns + read(k)),
                ..TickSample::default()
            })
            .collect();
        let sampled = CommandTicks::of(&run, &ticks);
        for k in 0..10 {
            assert_eq!(
                sampled.deadline_ns(run.start_ns + read(k)),
                run.start_ns + k * MS,
                "tick {k}"
            );
        }
        // A stamp no recorded tick has (its record dropped), or one before the run: the stamp.
        let between = run.start_ns + 8 * MS + 1;
        assert_eq!(sampled.deadline_ns(between), between);
        assert_eq!(sampled.deadline_ns(run.start_ns - 1), run.start_ns - 1);
        // A recording's garbage index does not overflow.
        let garbage = CommandTicks::of(
            &run,
            &[TickSample {
                index: u64::MAX,
                sample_time_ns: Some(7),
                ..TickSample::default()
            }],
        );
        assert_eq!(garbage.deadline_ns(7), i64::MAX);
        let unstamped: Vec<TickSample> = ticks
            .iter()
            .map(|t| TickSample {
                sample_time_ns: None,
                ..*t
            })
            .collect();
        let nominal = CommandTicks::of(&run, &unstamped);
        assert_eq!(
            nominal.deadline_ns(run.start_ns + 6_500_000),
            run.start_ns + 6_500_000
        );
    }

    /// `mmt report FILE.mcap` left every window unmarked; the run's report marked them.
    #[test]
    fn windows_an_outage_touches_are_marked_and_no_others() {
        let run = run_from(10_000 * MS);
        // Measurements every ms from 0 to 5 s after the start, except 2.5 s → 3.2 s.
        let measurements: Vec<MeasurementSample> = (0..5_000)
            .filter(|k| !(2_500..3_200).contains(k))
            .map(|k| MeasurementSample {
                received_ns: run.start_ns + k * MS,
                ..MeasurementSample::default()
            })
            .collect();
        let mut windows: Vec<crate::Window> = (0..5)
            .map(|k| crate::Window {
                t_s: k as f64,
                rms_error_pct: Some(1.0),
                outage: false,
            })
            .collect();
        let outages = mark_outages(&run, 5_000, &measurements, &mut windows);
        assert_eq!(outages.count, 1);
        assert_eq!(outages.longest_ms, 701.0);
        let marked: Vec<bool> = windows.iter().map(|w| w.outage).collect();
        assert_eq!(marked, [false, false, true, true, false]);
        // A run that ends in an outage: the last window is marked too.
        let outages = mark_outages(&run, 5_400, &measurements, &mut windows);
        assert_eq!(outages.count, 2);
        assert!(windows[4].outage);
        // Nothing received: the whole run is one outage.
        let outages = mark_outages(&run, 5_000, &[], &mut windows);
        assert_eq!(
            outages.count, 0,
            "no arrival, nothing to measure a gap from"
        );
    }
}
