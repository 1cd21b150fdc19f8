//! The prior's models, gated as the renderers gate any model: checked once, where the prior is
//! chosen (the scene at load, the operator at the `Welcome`), and again where the node is built.

use mmt::model::backsolve::Params;
use mmt::model::gates::{GateRejection, Gated, gate_physical};
use mmt::model::prior::Prior;
use mmt::model::{KelvinVoigt, Structure};

use super::Tangential;

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

/// Gives each tangential prior renderer its gated model.
pub(super) fn prior_targets(axes: &mut [Tangential; 2], gated: &Gated) {
    for axis in axes {
        match axis {
            Tangential::Sliding(r) => r.set_target(gated),
            Tangential::Shear(r) => r.set_target(gated),
            Tangential::Free => false,
        };
    }
}
