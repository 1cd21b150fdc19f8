//! The prior's models, gated as the renderers gate any model: checked once, where the prior is
//! chosen (the scene at load, the operator at the `Welcome`), and again where the node is built;
//! and the tangents' stage with the prior, and their hand-over from it to the first model.

use mmt::model::backsolve::Params;
use mmt::model::gates::{GateRejection, Gated, gate_physical};
use mmt::model::prior::Prior;
use mmt::model::{KelvinVoigt, Structure};

use super::{OperatorNode, Tangential, step_tangential};

/// A prior's models for the scene's structures: `None` for an axis group with no model.
#[derive(Clone, Debug, Default)]
pub struct GatedPrior {
    /// The spring–damper along the normal.
    pub normal: Option<Gated>,
    /// The object along the tangents: a sliding mass as the structure allows, or its contact
    /// element (Kelvin–Voigt).
    pub tangential: Option<Gated>,
}

/// `prior`'s models for the `normal` and `tangential` structures, through the renderers' gates
/// (a passive, physical model of each structure); the first rejection is the error. A prior
/// that passes [`Prior::validate`] may still fail here, e.g. a sliding object with no damping.
pub fn gate_prior(
    prior: &Prior,
    normal: Structure,
    tangential: Structure,
) -> Result<GatedPrior, GateRejection> {
    let gate = |structure, params| gate_physical(structure, &params).map(Some);
    let normal = match normal {
        Structure::Free => None,
        _ => gate(Structure::KelvinVoigt, Params::KelvinVoigt(prior.normal))?,
    };
    let t = prior.tangential;
    let tangential = match tangential {
        Structure::Free => None,
        Structure::KelvinVoigt => gate(
            Structure::KelvinVoigt,
            Params::KelvinVoigt(KelvinVoigt {
                k_n_per_m: t.k_contact_n_per_m,
                b_ns_per_m: t.b_contact_ns_per_m,
            }),
        )?,
        structure => gate(structure, Params::SlidingMass(t))?,
    };
    Ok(GatedPrior { normal, tangential })
}

/// Gives each tangential renderer (the prior's or the model's) `gated` as its target; whether
/// any took it (a renderer refuses a set of another structure).
pub(super) fn set_tangential_targets(axes: &mut [Tangential; 2], gated: &Gated) -> bool {
    let mut any = false;
    for axis in axes {
        any |= match axis {
            Tangential::Sliding(r) => r.set_target(gated),
            Tangential::Shear(r) => r.set_target(gated),
            Tangential::Free => false,
        };
    }
    any
}

/// The tangents' prior (issue 13): rendered until the first model, then handed over.
#[derive(Clone, Debug)]
pub(super) enum PriorStage {
    /// Rendering the prior's renderers (the node's `prior_axes`).
    Prior,
    /// The first model renders, plus an offset per tangent (prior − model at the first tick)
    /// that falls linearly to 0; `done` ticks of it so far.
    HandOver { offsets: [f64; 2], done: u32 },
    /// The model alone (or no prior at all).
    Done,
}

impl OperatorNode {
    /// The tangential forces with the prior: the prior's alone before the first model. On the
    /// first tick the model renders, the difference between the two becomes an offset that
    /// falls linearly to 0 over the hand-over: no jump, and the prior's error stops growing the
    /// moment the model is there.
    pub(super) fn with_prior(
        &mut self,
        f_model: [f64; 2],
        inputs: [[f64; 2]; 2],
        in_contact: bool,
    ) -> [f64; 2] {
        match &mut self.prior_tangential {
            PriorStage::Done => f_model,
            PriorStage::Prior => {
                let mut f_prior = [0.0; 2];
                let axes = self.prior_axes.iter_mut().zip(inputs);
                for (f, (axis, [x, v])) in f_prior.iter_mut().zip(axes) {
                    *f = step_tangential(axis, x, v, in_contact);
                }
                if self.rendering {
                    let offsets = [f_prior[0] - f_model[0], f_prior[1] - f_model[1]];
                    self.prior_tangential = PriorStage::HandOver { offsets, done: 0 };
                }
                f_prior
            }
            PriorStage::HandOver { offsets, done } => {
                let left = 1.0 - f64::from(*done) / f64::from(self.handover_ticks.max(1));
                let left = left.max(0.0);
                [
                    f_model[0] + left * offsets[0],
                    f_model[1] + left * offsets[1],
                ]
            }
        }
    }

    /// One tick of the tangents' hand-over; it ends after its length.
    pub(super) fn advance_handover(&mut self) {
        if let PriorStage::HandOver { done, .. } = &mut self.prior_tangential {
            *done += 1;
            if *done >= self.handover_ticks {
                self.prior_tangential = PriorStage::Done;
            }
        }
    }
}
