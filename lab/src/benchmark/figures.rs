//! The figures of one case, and their percentiles over a group of cases.

use metrics::ExperimentReport;
use mmt::estimator::RejectionCounts;
use mmt::model::{Structure, col};
use serde::Serialize;

/// The figures of one run of one object (from its experiment report).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CaseFigures {
    /// RMS error of the rendered force, from the first tick the operator renders the full model
    /// to the end, % of the RMS measured force (`rms_error_pct_after_stable`).
    pub error_after_stable_pct: Option<f64>,
    /// The same against the true force (sensor noise and bias left out).
    pub error_after_stable_vs_true_pct: Option<f64>,
    /// RMS error from the first contact to the end, % of the RMS measured force.
    pub error_from_first_contact_pct: Option<f64>,
    /// From the first contact until the operator renders any model [s]; `None`: never.
    pub time_to_first_render_s: Option<f64>,
    /// From the first contact until every gate passes and keeps passing [s]; `None`: never.
    pub time_to_stable_s: Option<f64>,
    /// The tangential estimator's a-priori reconstruction error while confident [%].
    pub reconstruction_error_pct: Option<f64>,
    /// `(axes, parameter, true, estimated, error %)` of the last confirmed sets.
    pub parameters: Vec<(String, String, f64, f64, f64)>,
    /// Back-solves run (both estimators).
    pub back_solves: u64,
    /// Back-solves a gate rejected.
    pub gate_rejections: u64,
    /// The same by gate (both estimators).
    pub rejections: RejectionCounts,
    /// Gate-passing back-solves the confidence gate withheld.
    pub withheld: u64,
    /// Sets confirmed and sent.
    pub confirmed: u64,
    /// Confirmed sets of low confidence (e.g. k1 ≫ k2).
    pub low_confidence: u64,
    /// Reduced (massless) sets confirmed and sent while the whole structure was not identified.
    pub reduced: u64,
    /// The tangential structure the estimator chose from the data at its last back-solve
    /// (`mmt benchmark --structure select`); `None` without selection.
    pub selected: Option<Structure>,
    /// Whether that choice has a ground spring exactly when the object has one.
    pub ground_spring_chosen_right: Option<bool>,
}

impl CaseFigures {
    /// The figures of a report.
    pub fn from_report(r: &ExperimentReport) -> CaseFigures {
        let sum = |f: &dyn Fn(&mmt::estimator::EstimatorStats) -> u64| {
            r.estimators.iter().map(|e| f(&e.stats)).sum::<u64>()
        };
        CaseFigures {
            error_after_stable_pct: r.rms_error_pct_after_stable,
            error_after_stable_vs_true_pct: r.rms_error_pct_after_stable_vs_true_force,
            error_from_first_contact_pct: r.rms_error_pct,
            time_to_first_render_s: r.render_start_s,
            time_to_stable_s: r.time_to_stable_s,
            reconstruction_error_pct: r.reconstruction_error_pct,
            parameters: r
                .parameters
                .iter()
                .flat_map(|p| {
                    p.values
                        .iter()
                        .map(|(name, t, e, pct)| (p.axes.to_string(), name.clone(), *t, *e, *pct))
                })
                .collect(),
            back_solves: sum(&|s| s.back_solves),
            gate_rejections: sum(&|s| s.gate_rejections),
            rejections: RejectionCounts {
                non_finite: sum(&|s| s.rejections.non_finite),
                not_eigen_stable: sum(&|s| s.rejections.not_eigen_stable),
                not_passive: sum(&|s| s.rejections.not_passive),
                not_physical: sum(&|s| s.rejections.not_physical),
                too_soft: sum(&|s| s.rejections.too_soft),
                residual: sum(&|s| s.rejections.residual),
                back_solve: sum(&|s| s.rejections.back_solve),
                not_identified: sum(&|s| s.rejections.not_identified),
            },
            withheld: sum(&|s| s.withheld),
            confirmed: sum(&|s| s.confirmed),
            low_confidence: sum(&|s| s.low_confidence_confirmed),
            reduced: sum(&|s| s.reduced_confirmed),
            selected: r
                .estimators
                .iter()
                .find(|e| e.axes == "tangential")
                .and_then(|e| e.stats.selected),
            ground_spring_chosen_right: None,
        }
    }

    /// The largest |error| over the tangential parameters the truth has (k1 and Fc only when
    /// the object has them) [%].
    pub fn worst_tangential_parameter_pct(&self) -> Option<f64> {
        self.parameters
            .iter()
            .filter(|(axes, _, truth, ..)| axes == "tangential" && *truth != 0.0)
            .map(|(.., pct)| pct.abs())
            .filter(|v| v.is_finite())
            .reduce(f64::max)
    }
}

/// Median, 90th percentile and maximum of a figure over a group; a case without the figure
/// (never rendered, never stable) counts as +∞, so it lands in the upper percentiles.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Percentiles {
    /// Cases in the group.
    pub n: usize,
    /// Cases without the figure.
    pub missing: usize,
    /// Median (nearest rank); `None` when it falls on a missing case.
    pub median: Option<f64>,
    /// 90th percentile (nearest rank: the ⌈0.9 n⌉-th smallest).
    pub p90: Option<f64>,
    /// Largest.
    pub max: Option<f64>,
}

impl Percentiles {
    /// Over `values` (`None`: the case has no such figure).
    pub fn of(values: impl IntoIterator<Item = Option<f64>>) -> Percentiles {
        let mut v: Vec<f64> = values
            .into_iter()
            .map(|x| x.filter(|x| x.is_finite()).unwrap_or(f64::INFINITY))
            .collect();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let rank = |q: f64| -> Option<f64> {
            if n == 0 {
                return None;
            }
            let k = ((q * n as f64).ceil() as usize).clamp(1, n);
            Some(v[k - 1]).filter(|x| x.is_finite())
        };
        Percentiles {
            n,
            missing: v.iter().filter(|x| !x.is_finite()).count(),
            median: rank(0.5),
            p90: rank(0.9),
            max: rank(1.0),
        }
    }
}

/// The percentiles of every figure over a group of cases.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Summary {
    /// Trajectory.
    pub motion: String,
    /// One-way delay [ms].
    pub delay_ms: f64,
    /// Sensor preset.
    pub preset: String,
    /// Which objects: `class` or `corner`.
    pub objects: String,
    /// Objects never rendered.
    pub never_rendered: usize,
    /// Objects never stable.
    pub never_stable: usize,
    /// Error after stable [%].
    pub error_after_stable_pct: Percentiles,
    /// Error after stable against the true force [%].
    pub error_after_stable_vs_true_pct: Percentiles,
    /// Error from first contact [%].
    pub error_from_first_contact_pct: Percentiles,
    /// Time to the first rendered model [s].
    pub time_to_first_render_s: Percentiles,
    /// Time to stable [s].
    pub time_to_stable_s: Percentiles,
    /// Reconstruction error [%].
    pub reconstruction_error_pct: Percentiles,
    /// Worst tangential parameter error per object [%].
    pub worst_parameter_pct: Percentiles,
    /// With structure selection: objects whose chosen structure has a ground spring exactly
    /// when the object has one, of those with a choice.
    pub ground_spring_right: Option<(usize, usize)>,
    /// With structure selection: objects whose chosen structure has friction, of those with a
    /// choice.
    pub friction_chosen: Option<(usize, usize)>,
}

impl Summary {
    /// The summary of `cases` (all of one motion, delay, preset and object group).
    pub fn of(
        motion: &str,
        delay_ms: f64,
        preset: &str,
        objects: &str,
        cases: &[&CaseFigures],
    ) -> Summary {
        let p =
            |f: &dyn Fn(&CaseFigures) -> Option<f64>| Percentiles::of(cases.iter().map(|c| f(c)));
        // (true, known) over the cases where `f` is known; `None` when it never is.
        let count = |f: &dyn Fn(&CaseFigures) -> Option<bool>| {
            let known: Vec<bool> = cases.iter().filter_map(|c| f(c)).collect();
            (!known.is_empty()).then(|| (known.iter().filter(|&&v| v).count(), known.len()))
        };
        Summary {
            motion: motion.to_string(),
            delay_ms,
            preset: preset.to_string(),
            objects: objects.to_string(),
            never_rendered: cases
                .iter()
                .filter(|c| c.time_to_first_render_s.is_none())
                .count(),
            never_stable: cases
                .iter()
                .filter(|c| c.time_to_stable_s.is_none())
                .count(),
            error_after_stable_pct: p(&|c| c.error_after_stable_pct),
            error_after_stable_vs_true_pct: p(&|c| c.error_after_stable_vs_true_pct),
            error_from_first_contact_pct: p(&|c| c.error_from_first_contact_pct),
            time_to_first_render_s: p(&|c| c.time_to_first_render_s),
            time_to_stable_s: p(&|c| c.time_to_stable_s),
            reconstruction_error_pct: p(&|c| c.reconstruction_error_pct),
            worst_parameter_pct: p(&|c| c.worst_tangential_parameter_pct()),
            ground_spring_right: count(&|c| c.ground_spring_chosen_right),
            friction_chosen: count(&|c| c.selected.map(|s| s.columns().contains(col::G))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_by_nearest_rank_with_missing_values_last() {
        let p = Percentiles::of((1..=10).map(|v| Some(v as f64)));
        assert_eq!((p.median, p.p90, p.max), (Some(5.0), Some(9.0), Some(10.0)));
        let p = Percentiles::of([Some(1.0), None, Some(3.0), Some(f64::NAN)]);
        assert_eq!(p.missing, 2);
        assert_eq!((p.median, p.p90, p.max), (Some(3.0), None, None));
        let p = Percentiles::of(std::iter::empty());
        assert_eq!((p.n, p.median), (0, None));
    }
}
