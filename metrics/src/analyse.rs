//! What the report computes from a run's series.

use crate::spectrum::bands_rms;
use mmt::estimator::EstimatorStats;
use mmt::model::backsolve::{Confidence, Params};
use mmt::model::gates::Gated;
use mmt::model::prior::Prior;
use mmt::vec3;
use node::operator::OperatorStats;

use crate::{Series, onset};
use node::telerobot::TelerobotStats;
use serde::{Deserialize, Serialize};
use sim::scene::Scene;

/// One frequency band of the error.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Band {
    /// Lower edge [Hz].
    pub lo_hz: f64,
    /// Upper edge [Hz].
    pub hi_hz: f64,
    /// RMS error in the band, % of the RMS measured force in the band; `None` (JSON `null`)
    /// when nothing was rendered after the parameters first passed the gates.
    pub rms_error_pct: Option<f64>,
}

/// Delay between a true contact change and the rendered one, on the command time axis [ms].
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ContactLatency {
    /// Operator-side detection on the delayed cloud: mean |latency|.
    pub local: Option<f64>,
    /// The telerobot's contact state only (the thesis): mean latency.
    pub remote_only: Option<f64>,
    /// Worst |latency| of local detection.
    pub local_max: Option<f64>,
    /// True contact changes counted.
    pub switches: usize,
    /// True contact changes local detection did not follow within the 3 s matching window:
    /// not in `local` or `local_max` (a first contact before the first cloud over a link of
    /// seconds, say), so they are counted here.
    pub local_missed: usize,
}

/// An error value over a window.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Window {
    /// Window start [s].
    pub t_s: f64,
    /// RMS error, % of the RMS measured force; `None` out of contact.
    pub rms_error_pct: Option<f64>,
    /// The window contains an outage (no data from the telerobot for 100 ms or more): its
    /// figure is not the model's error alone. Set by whoever knows the arrivals (the networked
    /// operator's report); `false` in-process.
    #[serde(default)]
    pub outage: bool,
}

/// Estimated against true parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParameterReport {
    /// Axis group: `normal` or `tangential`.
    pub axes: String,
    /// `(name, true, estimated, error %)`.
    #[serde(deserialize_with = "nullable::values")]
    pub values: Vec<(String, f64, f64, f64)>,
    /// The back-solve's confidence in the final set: `{"kind":"low","condition":…}` when the
    /// parameters are nearly unobservable (e.g. k1 ≫ k2) and their errors amplified.
    pub confidence: Confidence,
    /// Condition number of `∂ log θ/∂ log φ` at the final set.
    #[serde(deserialize_with = "nullable::f64")]
    pub condition: f64,
    /// Confirmed sets of this group whose back-solve reported low confidence, and all confirmed
    /// sets, when the estimator's counters are at hand (the in-process experiment).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub low_confidence_updates: Option<u64>,
    /// All confirmed sets of this group (with `low_confidence_updates`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub confirmed_updates: Option<u64>,
}

/// The thesis's figures, for the same table.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ThesisFigures {
    /// Exp 1/3 error below 0.3 Hz [%] ("up to 30 %").
    pub rms_error_low_freq_pct: f64,
    /// Exp 1/3 error above 0.3 Hz [%] ("up to 100 %").
    pub rms_error_high_freq_pct: f64,
    /// Exp 2 reconstruction error [%].
    pub reconstruction_error_pct: f64,
    /// Exp 2 time to stable parameters [s].
    pub time_to_stable_s: f64,
    /// Exp 3 contact-switch latency: one round trip [ms].
    pub contact_switch_latency_ms: f64,
}

/// The report of one run. Everything here is a function of the configuration and the seed:
/// the same seed gives the same bytes (wall-clock time is reported separately by the caller).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ExperimentReport {
    /// Experiment name.
    pub experiment: String,
    /// Scene name.
    pub scene: String,
    /// Trajectory name.
    pub trajectory: String,
    /// Seed.
    pub seed: u64,
    /// One-way delay [ms].
    pub delay_ms: f64,
    /// RMS error of the rendered force from the first contact to the end, % of the RMS measured
    /// force (force vectors, world frame).
    pub rms_error_pct: Option<f64>,
    /// The same from the time the first whole model reaches the operator (a reduced first
    /// model, rendered before, does not start it).
    pub rms_error_pct_after_stable: Option<f64>,
    /// The same on the scene's second tangent only (the thesis's y axis).
    pub tangential_rms_error_pct_after_stable: Option<f64>,
    /// After stable, against the true force instead of the measured one (simulation only): the
    /// error of the model without the sensor's noise and bias.
    pub rms_error_pct_after_stable_vs_true_force: Option<f64>,
    /// After stable, per band.
    pub bands: Vec<Band>,
    /// The shadow node's error after stable: contact from the telerobot's state only.
    pub rms_error_pct_remote_contact: Option<f64>,
    /// 1 s windows.
    pub error_over_time: Vec<Window>,
    /// From the first contact until the parameters pass every gate and keep passing [s].
    pub time_to_stable_s: Option<f64>,
    /// From the first contact until the operator renders a model (the telerobot's reduced first
    /// model included) [s].
    pub render_start_s: Option<f64>,
    /// From the first tick of the operator's local contact to the first tick with a non-zero
    /// rendered force [ms] (0: the force starts on the tick contact does).
    pub first_force_after_local_contact_ms: Option<f64>,
    /// From the first contact until the error stays within 10 % in every 250 ms window to the
    /// end [s] (`onset::settle_s`).
    pub settle_s: Option<f64>,
    /// The error in the 1 s after each re-contact (every contact but the first), pooled [%].
    pub recontact_error_pct: Option<f64>,
    /// What the operator rendered before its first model (`None`: nothing).
    pub prior: Option<Prior>,
    /// The error of each stage: before a model (the prior), the reduced model, the whole one.
    pub stage_errors: onset::StageErrors,
    /// The tangential estimator's a-priori reconstruction error while confident [%].
    pub reconstruction_error_pct: Option<f64>,
    /// Contact-switch latency.
    pub contact_switch_latency_ms: ContactLatency,
    /// Operator contact deflection vs truth: RMS difference in contact [m] (sliding mass).
    pub deflection_rms_error_m: Option<f64>,
    /// Parameters.
    pub parameters: Vec<ParameterReport>,
    /// Each estimator's counters: gate rejections by gate, withheld and confirmed sets.
    pub estimators: Vec<EstimatorReport>,
    /// Terms the scene's model leaves out.
    pub left_out: Vec<String>,
    /// Simulated time [s].
    pub sim_seconds: f64,
    /// The thesis's figures.
    pub thesis: ThesisFigures,
    /// Operator node counters.
    pub operator_stats: OperatorStats,
    /// Shadow node counters.
    pub shadow_stats: OperatorStats,
    /// Telerobot node counters.
    pub telerobot_stats: TelerobotStats,
}

/// The bands of the report [Hz].
pub const BANDS: [(f64, f64); 3] = [(0.0, 0.3), (0.3, 1.0), (1.0, 4.0)];

/// What a run was, for its report.
#[derive(Clone, Debug)]
pub struct RunInfo {
    /// Experiment name (`exp1`, …, or `networked`).
    pub experiment: String,
    /// Scene name.
    pub scene: String,
    /// The physical terms the scene's model leaves out ([`Scene::left_out`]).
    pub left_out: Vec<String>,
    /// Trajectory name.
    pub trajectory: String,
    /// Seed.
    pub seed: u64,
    /// One-way delay [ms].
    pub delay_ms: f64,
}

/// One estimator's counters, for the report.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EstimatorReport {
    /// Axis group (`normal`, `tangential`).
    pub axes: String,
    /// Back-solves, gate rejections by gate, confidence-gate withholdings, confirmed sets.
    pub stats: EstimatorStats,
}

/// What the nodes know, for the report (recorded at the end of a run, so that a report computed
/// again from a recording has it).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct NodeInfo {
    /// Each estimator's counters (the in-process experiment knows them; a remote operator does
    /// not).
    #[serde(default)]
    pub estimators: Vec<EstimatorReport>,
    /// Estimated against true parameters.
    pub parameters: Vec<ParameterReport>,
    /// Operator node counters.
    pub operator: OperatorStats,
    /// Shadow node counters.
    pub shadow: OperatorStats,
    /// Telerobot node counters.
    pub telerobot: TelerobotStats,
    /// The operator's prior (what it rendered before its first model).
    #[serde(default)]
    pub prior: Option<Prior>,
}

/// Computes the report of a run.
pub fn analyse(info: &RunInfo, s: &Series, nodes: NodeInfo) -> ExperimentReport {
    let dt = s.dt_s();
    let first_contact = s.contact_true.iter().position(|c| *c == Some(true));
    let render_start = s.rendering.iter().position(|r| *r);
    let rms_pct = |from: usize, rendered: &[[f64; 3]], proj: Option<[f64; 3]>| {
        rms_pct_vs(&s.measured, from, rendered, proj)
    };
    let after = s.whole_model_start().unwrap_or(s.len());
    ExperimentReport {
        experiment: info.experiment.clone(),
        scene: info.scene.clone(),
        trajectory: info.trajectory.clone(),
        seed: info.seed,
        delay_ms: info.delay_ms,
        rms_error_pct: first_contact.and_then(|fc| rms_pct(fc, &s.rendered, None)),
        rms_error_pct_after_stable: rms_pct(after, &s.rendered, None),
        tangential_rms_error_pct_after_stable: rms_pct(after, &s.rendered, Some(s.axis)),
        rms_error_pct_after_stable_vs_true_force: rms_pct_vs(
            &s.true_force,
            after,
            &s.rendered,
            None,
        ),
        bands: bands(s, after),
        rms_error_pct_remote_contact: rms_pct(after, &s.rendered_remote, None),
        error_over_time: error_over_time(s),
        time_to_stable_s: time_to_stable_s(s, first_contact),
        render_start_s: match (first_contact, render_start) {
            (Some(fc), Some(rs)) => Some(rs.saturating_sub(fc) as f64 * dt),
            _ => None,
        },
        first_force_after_local_contact_ms: onset::first_force_ms(s),
        settle_s: onset::settle_s(s),
        recontact_error_pct: onset::recontact_error_pct(s),
        prior: nodes.prior,
        stage_errors: onset::stage_errors(s),
        reconstruction_error_pct: (s.reconstruction.0 > 0.0)
            .then(|| 100.0 * (s.reconstruction.1 / s.reconstruction.0).sqrt()),
        contact_switch_latency_ms: latency(s),
        deflection_rms_error_m: deflection_error(s),
        parameters: nodes.parameters,
        estimators: nodes.estimators,
        left_out: info.left_out.clone(),
        sim_seconds: s.len() as f64 * dt,
        thesis: ThesisFigures {
            rms_error_low_freq_pct: 30.0,
            rms_error_high_freq_pct: 100.0,
            reconstruction_error_pct: 5.0,
            time_to_stable_s: 16.1,
            contact_switch_latency_ms: 2.0 * info.delay_ms,
        },
        operator_stats: nodes.operator,
        shadow_stats: nodes.shadow,
        telerobot_stats: nodes.telerobot,
    }
}

/// RMS of `rendered − reference` over RMS `reference` from tick `from` on [%], over the ticks
/// with a reference; along `proj` when given, else of the whole vectors.
fn rms_pct_vs(
    reference: &[Option<[f64; 3]>],
    from: usize,
    rendered: &[[f64; 3]],
    proj: Option<[f64; 3]>,
) -> Option<f64> {
    let (mut e2, mut m2) = (0.0, 0.0);
    for (m, r) in reference.iter().zip(rendered).skip(from) {
        let Some(m) = *m else { continue };
        let e = vec3::sub(*r, m);
        match proj {
            Some(a) => {
                e2 += vec3::dot(e, a).powi(2);
                m2 += vec3::dot(m, a).powi(2);
            }
            None => {
                e2 += vec3::norm2(e);
                m2 += vec3::norm2(m);
            }
        }
    }
    (m2 > 0.0).then(|| 100.0 * (e2 / m2).sqrt())
}

/// The error from tick `after` on, per band of [`BANDS`]: each band's error and measured
/// energy summed over the three axes.
fn bands(s: &Series, after: usize) -> Vec<Band> {
    let dt = s.dt_s();
    let measured = |i: usize| s.measured[i].unwrap_or(s.rendered[i]);
    let (mut e2, mut m2) = ([0.0; BANDS.len()], [0.0; BANDS.len()]);
    for c in 0..3 {
        let err: Vec<f64> = (after..s.len())
            .map(|i| s.rendered[i][c] - measured(i)[c])
            .collect();
        let meas: Vec<f64> = (after..s.len()).map(|i| measured(i)[c]).collect();
        let (be, bm) = (bands_rms(&err, dt, &BANDS), bands_rms(&meas, dt, &BANDS));
        for b in 0..BANDS.len() {
            e2[b] += be[b] * be[b];
            m2[b] += bm[b] * bm[b];
        }
    }
    BANDS
        .iter()
        .enumerate()
        .map(|(b, &(lo, hi))| Band {
            lo_hz: lo,
            hi_hz: hi,
            rms_error_pct: (m2[b] > 0.0).then(|| 100.0 * (e2[b] / m2[b]).sqrt()),
        })
        .collect()
}

/// The error per 1 s window; none where the measured force's RMS is 0.05 N or less.
fn error_over_time(s: &Series) -> Vec<Window> {
    let dt = s.dt_s();
    let per_window = (1.0 / dt).round() as usize;
    (0..s.len())
        .step_by(per_window)
        .map(|start| Window {
            t_s: start as f64 * dt,
            rms_error_pct: onset::window_pct(s, start, (start + per_window).min(s.len())),
            outage: false,
        })
        .collect()
}

/// From the first contact until the parameters pass every gate and keep passing to the end
/// [s]; `None` without contact or if they do not pass at the end.
fn time_to_stable_s(s: &Series, first_contact: Option<usize>) -> Option<f64> {
    let stable_from = s.stable.iter().rposition(|st| !st).map_or(0, |i| i + 1);
    match first_contact {
        Some(fc) if stable_from < s.stable.len() => {
            Some((stable_from.max(fc) - fc) as f64 * s.dt_s())
        }
        _ => None,
    }
}

/// Transition times (tick index, new state) of a boolean series.
fn transitions(v: impl Iterator<Item = Option<bool>>) -> Vec<(usize, bool)> {
    let mut out = Vec::new();
    let mut last: Option<bool> = None;
    for (i, c) in v.enumerate() {
        let Some(c) = c else { continue };
        if last.is_some_and(|l| l != c) {
            out.push((i, c));
        }
        last = Some(c);
    }
    out
}

fn latency(s: &Series) -> ContactLatency {
    let dt_ms = s.dt_s() * 1e3;
    let truth = transitions(s.contact_true.iter().copied());
    let local = transitions(s.contact_local.iter().map(|c| Some(*c)));
    let remote = transitions(s.contact_remote.iter().map(|c| Some(*c)));
    // The nearest change of the same polarity within 3 s.
    let match_each = |candidates: &[(usize, bool)]| -> Vec<f64> {
        truth
            .iter()
            .filter_map(|&(t, state)| {
                candidates
                    .iter()
                    .filter(|(_, c)| *c == state)
                    .map(|&(i, _)| (i as f64 - t as f64) * dt_ms)
                    .filter(|d| d.abs() <= 3000.0)
                    .min_by(|a, b| a.abs().total_cmp(&b.abs()))
            })
            .collect()
    };
    let l = match_each(&local);
    let r = match_each(&remote);
    let mean = |v: &[f64], abs: bool| {
        (!v.is_empty()).then(|| {
            v.iter()
                .map(|x| if abs { x.abs() } else { *x })
                .sum::<f64>()
                / v.len() as f64
        })
    };
    ContactLatency {
        local: mean(&l, true),
        remote_only: mean(&r, false),
        local_max: l.iter().map(|x| x.abs()).reduce(f64::max),
        switches: truth.len(),
        local_missed: truth.len() - l.len(),
    }
}

fn deflection_error(s: &Series) -> Option<f64> {
    let (mut e2, mut n) = (0.0, 0usize);
    for (i, op) in s.operator_state.iter().enumerate() {
        let (Some(Some(truth)), Some(Some(true))) = (s.true_state.get(i), s.contact_true.get(i))
        else {
            continue;
        };
        if !s.contact_local.get(i).copied().unwrap_or(false)
            || !s.rendering.get(i).copied().unwrap_or(false)
        {
            continue;
        }
        for (axis, t) in op.iter().zip(truth) {
            if let Some((d, _)) = axis {
                e2 += (d - t.0).powi(2);
                n += 1;
            }
        }
    }
    (n > 0).then(|| (e2 / n as f64).sqrt())
}

/// Estimated against the scene's true parameters, for the sets given (normal, tangential).
pub fn parameter_report(scene: &Scene, sets: [Option<&Gated>; 2]) -> Vec<ParameterReport> {
    let env = scene.environment;
    let rel = |est: f64, truth: f64| {
        if truth != 0.0 {
            100.0 * (est - truth) / truth
        } else {
            f64::NAN
        }
    };
    let row = |name: &str, truth: f64, est: f64| (name.to_string(), truth, est, rel(est, truth));
    let mut out = Vec::new();
    for (axes, latest) in ["normal", "tangential"].into_iter().zip(sets) {
        let Some(latest) = latest else { continue };
        let values = match latest.params() {
            Params::KelvinVoigt(kv) => vec![
                row("k", env.k_contact_n_per_m, kv.k_n_per_m),
                row("b", env.b_contact_ns_per_m, kv.b_ns_per_m),
            ],
            Params::SlidingMass(p) => vec![
                row("m", env.mass_kg, p.mass_kg),
                row("k1", env.k_ground_n_per_m, p.k_ground_n_per_m),
                row("b1", env.b_ground_ns_per_m, p.b_ground_ns_per_m),
                row("k2", env.k_contact_n_per_m, p.k_contact_n_per_m),
                row("b2", env.b_contact_ns_per_m, p.b_contact_ns_per_m),
                row("Fc", env.coulomb_friction_n, p.coulomb_n),
            ],
            Params::Free => vec![],
        };
        out.push(ParameterReport {
            axes: axes.to_owned(),
            values,
            confidence: latest.confidence(),
            condition: latest.condition(),
            low_confidence_updates: None,
            confirmed_updates: None,
        });
    }
    out
}

/// JSON has no NaN or infinity: `serde_json` writes them as `null`. A report read back (from a
/// recording's `/run/end`) takes `null` as NaN: the value was not a finite number.
mod nullable {
    use serde::{Deserialize, Deserializer};

    pub(super) fn f64<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
    }

    type Row = (String, Option<f64>, Option<f64>, Option<f64>);
    type Value = (String, f64, f64, f64);

    pub(super) fn values<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Value>, D::Error> {
        let nan = |v: Option<f64>| v.unwrap_or(f64::NAN);
        Ok(Vec::<Row>::deserialize(d)?
            .into_iter()
            .map(|(name, a, b, c)| (name, nan(a), nan(b), nan(c)))
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Before: a true switch that local detection followed only after more than 3 s (a first
    /// contact before the first cloud over a 5 s link) was left out of the latency silently.
    #[test]
    fn a_switch_not_followed_within_3_s_is_counted_as_missed() {
        let n = 10_000;
        let mut s = Series::with_capacity(n, [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], 1_000_000);
        // True contact from 1 s to 8 s; local from 4.5 s (3.5 s late) to 8.002 s.
        s.contact_true = (0..n).map(|i| Some((1000..8000).contains(&i))).collect();
        s.contact_local = (0..n).map(|i| (4500..8002).contains(&i)).collect();
        s.contact_remote = vec![false; n];
        let l = latency(&s);
        assert_eq!((l.switches, l.local_missed), (2, 1), "{l:?}");
        assert_eq!(l.local, Some(2.0));
        assert_eq!(l.local_max, Some(2.0));
    }
}
