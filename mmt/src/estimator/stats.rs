//! The estimator's counters, for reports.

use crate::model::Structure;
use crate::model::gates::GateRejection;
use serde::{Deserialize, Serialize};

/// Counters for reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct EstimatorStats {
    /// Samples with a non-finite value, dropped before the filters.
    pub rejected_samples: u64,
    /// Back-solves run.
    pub back_solves: u64,
    /// Back-solves rejected by a gate.
    pub gate_rejections: u64,
    /// Sets confirmed and published.
    pub confirmed: u64,
    /// Confirmed sets whose back-solve reported low confidence (`Confidence::Low`: e.g. k1 ≫ k2,
    /// where noise on θ is amplified many times in φ). They are published like the others; the
    /// count and [`Gated::confidence`] let reports say so.
    pub low_confidence_confirmed: u64,
    /// Massless reduced sets confirmed and published while the whole structure was not
    /// identified ([`super::EstimatorConfig::reduced_model`]); not in `confirmed`.
    pub reduced_confirmed: u64,
    /// Back-solves rejected, by the gate that rejected them.
    pub rejections: RejectionCounts,
    /// Back-solves that passed every gate but not (yet) the confidence gate: withheld.
    pub withheld: u64,
    /// New-object resets.
    pub new_objects: u64,
    /// Onset resets (policy `EveryOnset`).
    pub onset_resets: u64,
    /// The structure chosen from the data at the last back-solve
    /// ([`super::EstimatorConfig::select_structure`]); `None` when selection is off or has not
    /// run.
    #[serde(default)]
    pub selected: Option<Structure>,
    /// Times the structure in use changed by selection.
    #[serde(default)]
    pub structure_changes: u64,
    /// Sample periods with no sample (lost in transport) that the filters were stepped over
    /// with the interpolated input ([`super::MAX_FILLED_PERIODS`]).
    #[serde(default)]
    pub filled_samples: u64,
    /// Gaps longer than [`super::MAX_FILLED_PERIODS`] periods: the filters restarted at the
    /// next sample and, in contact, learning waited out the onset guard again.
    #[serde(default)]
    pub gap_restarts: u64,
    /// Samples, while learning, whose position contradicts the last sample's and the two
    /// velocities ([`super::MOTION_TOLERANCE_M`]: the robot stopped unseen over a gap, or
    /// jumped), or that end a gap whose two velocities leave room for such a stop: learning
    /// waited for the filters to settle and the new-object detector was muted.
    #[serde(default)]
    pub motion_settles: u64,
    /// Gaps, while learning, over which the measured speed changed more than the straight fill
    /// follows ([`super::GAP_MUTE_M`]): the new-object detector was muted, learning went on.
    #[serde(default)]
    pub gap_mutes: u64,
    /// First fits published before the group's RLS set: a Kelvin–Voigt group's
    /// ([`super::FirstFitConfig`]) or a sliding object's first contact's
    /// ([`super::SlideFitConfig`]); not in `confirmed`.
    #[serde(default)]
    pub first_fits: u64,
    /// New objects declared by a re-contact's first fit ([`super::FirstFitConfig::
    /// new_object_change`]); also in `new_objects`.
    #[serde(default)]
    pub first_fit_new_objects: u64,
    /// First-fit solves (of either kind) a gate rejected.
    #[serde(default)]
    pub first_fit_rejections: u64,
    /// Contact time [s] from the onset to the run's first published first fit.
    #[serde(default)]
    pub first_fit_after_s: Option<f64>,
    /// Sliding first fits of the contact element alone, published as reduced sets (`k2`, `b2`
    /// of the massless model, `b1` and `Fc` at the class centre:
    /// [`super::SlideFitConfig::contact_fit_s`]); also in `first_fits`.
    #[serde(default)]
    pub contact_fits: u64,
    /// Contact time [s] from the onset to the run's first sliding first fit of every term.
    #[serde(default)]
    pub whole_fit_after_s: Option<f64>,
}

/// Back-solves rejected, per gate ([`GateRejection`]'s variants).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct RejectionCounts {
    /// A coefficient or parameter not finite.
    pub non_finite: u64,
    /// A pole of F/X not in the open left half-plane.
    pub not_eigen_stable: u64,
    /// Stable but not passive.
    pub not_passive: u64,
    /// A physical parameter negative.
    pub not_physical: u64,
    /// The contact spring too soft for the force measured.
    #[serde(default)]
    pub too_soft: u64,
    /// θ too far off the model manifold.
    pub residual: u64,
    /// The back-solve refused (e.g. the mass not identifiable).
    pub back_solve: u64,
    /// A parameter not pinned down by the data.
    pub not_identified: u64,
}

impl RejectionCounts {
    /// Counts one rejection.
    pub fn count(&mut self, r: &GateRejection) {
        let c = match r {
            GateRejection::NonFinite { .. } | GateRejection::Free => &mut self.non_finite,
            GateRejection::NotEigenStable { .. } => &mut self.not_eigen_stable,
            GateRejection::NotPassive { .. } => &mut self.not_passive,
            GateRejection::NotPhysical { .. } => &mut self.not_physical,
            GateRejection::TooSoft { .. } => &mut self.too_soft,
            GateRejection::Residual { .. } => &mut self.residual,
            GateRejection::BackSolve(_) => &mut self.back_solve,
            GateRejection::NotIdentified { .. } => &mut self.not_identified,
        };
        *c += 1;
    }
}
