//! Model structures and identified parameter sets on the wire (`DESIGN.md` §4).
//!
//! Only the terms a structure has go on the wire: a rigid wall sends two numbers, not seven. These
//! mirror `mmt::model::Structure` and its physical parameters (this crate depends on no crate of
//! ours; `mmt` converts). Parameters are in the surface frame of the contact: the normal axis, and
//! the two tangential axes sharing one set.

use serde::{Deserialize, Serialize};

use crate::finite::{self, CheckFinite, NonFinite};

/// The model structure of one axis group, chosen by the scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ModelStructure {
    /// No contact force (`F = 0`); nothing identified.
    Free,
    /// Kelvin–Voigt contact `F_op = k x + b ẋ` (thesis eq. 8).
    KelvinVoigt,
    /// The sliding flexible object of thesis fig. 3 (mass, ground and contact spring–dampers,
    /// Coulomb friction).
    SlidingMass {
        /// Whether the ground spring `k1` is part of the model (left out when the object is free
        /// to slide, `DESIGN.md` §11.7).
        ground_spring: bool,
        /// Whether Coulomb friction `Fc` is part of the model.
        friction: bool,
    },
}

/// One identified, gate-passing parameter set for one axis group.
///
/// Wire size: 1 byte variant + 8 bytes per term + 1 byte per optional term, plus the sample time
/// (varint, ≤ 9 bytes) and the residual (8 bytes): at most 68 bytes for the full sliding mass.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParameterSet {
    /// Sample time of the newest data the set was estimated from [ns, telerobot clock].
    pub sample_time_ns: i64,
    /// Residual of the back-solve from regression coefficients to these terms, relative to the
    /// coefficients' size \[dimensionless\]; 0 is an exact fit. Reported so the operator can gate
    /// or weight a set itself.
    pub residual: f64,
    /// The terms, shaped by the structure.
    pub terms: ModelTerms,
}

/// The physical terms of a structure: only those it has.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum ModelTerms {
    /// [`ModelStructure::KelvinVoigt`].
    KelvinVoigt {
        /// Contact stiffness `k` \[N/m\].
        k_n_per_m: f64,
        /// Contact damping `b` \[N·s/m\].
        b_ns_per_m: f64,
    },
    /// [`ModelStructure::SlidingMass`].
    SlidingMass {
        /// Object mass `m` \[kg\].
        mass_kg: f64,
        /// Ground spring `k1` \[N/m\]; `None` when the structure has no ground spring.
        k_ground_n_per_m: Option<f64>,
        /// Ground damper `b1` \[N·s/m\].
        b_ground_ns_per_m: f64,
        /// Contact spring `k2` \[N/m\].
        k_contact_n_per_m: f64,
        /// Contact damper `b2` \[N·s/m\].
        b_contact_ns_per_m: f64,
        /// Coulomb friction level `Fc` \[N\]; `None` when the structure has no friction.
        coulomb_n: Option<f64>,
    },
}

impl ModelTerms {
    /// The structure these terms belong to, to check a received set against the scene's.
    pub fn structure(&self) -> ModelStructure {
        match self {
            ModelTerms::KelvinVoigt { .. } => ModelStructure::KelvinVoigt,
            ModelTerms::SlidingMass {
                k_ground_n_per_m,
                coulomb_n,
                ..
            } => ModelStructure::SlidingMass {
                ground_spring: k_ground_n_per_m.is_some(),
                friction: coulomb_n.is_some(),
            },
        }
    }
}

impl CheckFinite for ParameterSet {
    fn check_finite(&self) -> Result<(), NonFinite> {
        finite::scalar("residual", self.residual)?;
        match self.terms {
            ModelTerms::KelvinVoigt {
                k_n_per_m,
                b_ns_per_m,
            } => {
                finite::scalar("k_n_per_m", k_n_per_m)?;
                finite::scalar("b_ns_per_m", b_ns_per_m)
            }
            ModelTerms::SlidingMass {
                mass_kg,
                k_ground_n_per_m,
                b_ground_ns_per_m,
                k_contact_n_per_m,
                b_contact_ns_per_m,
                coulomb_n,
            } => {
                finite::scalar("mass_kg", mass_kg)?;
                finite::opt_scalar("k_ground_n_per_m", k_ground_n_per_m)?;
                finite::scalar("b_ground_ns_per_m", b_ground_ns_per_m)?;
                finite::scalar("k_contact_n_per_m", k_contact_n_per_m)?;
                finite::scalar("b_contact_ns_per_m", b_contact_ns_per_m)?;
                finite::opt_scalar("coulomb_n", coulomb_n)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn terms_name_their_structure() {
        let kv = ModelTerms::KelvinVoigt {
            k_n_per_m: 500.0,
            b_ns_per_m: 60.0,
        };
        assert_eq!(kv.structure(), ModelStructure::KelvinVoigt);
        let sliding = ModelTerms::SlidingMass {
            mass_kg: 1.0,
            k_ground_n_per_m: None,
            b_ground_ns_per_m: 60.0,
            k_contact_n_per_m: 500.0,
            b_contact_ns_per_m: 60.0,
            coulomb_n: Some(0.05),
        };
        assert_eq!(
            sliding.structure(),
            ModelStructure::SlidingMass {
                ground_spring: false,
                friction: true
            }
        );
    }

    #[test]
    fn a_nan_term_is_named() {
        let set = ParameterSet {
            sample_time_ns: 0,
            residual: 0.0,
            terms: ModelTerms::SlidingMass {
                mass_kg: 1.0,
                k_ground_n_per_m: Some(f64::NAN),
                b_ground_ns_per_m: 60.0,
                k_contact_n_per_m: 500.0,
                b_contact_ns_per_m: 60.0,
                coulomb_n: None,
            },
        };
        assert_eq!(set.check_finite().unwrap_err().field, "k_ground_n_per_m");
    }
}
