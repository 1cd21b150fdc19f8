//! Conversions between the model's types and the wire's (`protocol`, which depends on nothing of
//! ours).

use mmt::cloud::CloudFrame;
use mmt::contact::SurfaceFrame;
use mmt::model::backsolve::Params;
use mmt::model::gates::{GateRejection, Gated, gate_physical};
use mmt::model::prior::{Prior, PriorError, PriorSource};
use mmt::model::{KelvinVoigt, Physical, Structure};
use mmt::vec3;
use protocol::telerobot_to_operator as wire;
use protocol::telerobot_to_operator::{ModelStructure, ModelTerms, ParameterSet};

/// The wire form of a structure.
pub fn structure_to_wire(s: Structure) -> ModelStructure {
    match s {
        Structure::Free => ModelStructure::Free,
        Structure::KelvinVoigt => ModelStructure::KelvinVoigt,
        Structure::SlidingMass {
            ground_spring,
            friction,
        } => ModelStructure::SlidingMass {
            ground_spring,
            friction,
        },
    }
}

/// The model's form of a wire structure.
pub fn structure_from_wire(s: ModelStructure) -> Structure {
    match s {
        ModelStructure::Free => Structure::Free,
        ModelStructure::KelvinVoigt => Structure::KelvinVoigt,
        ModelStructure::SlidingMass {
            ground_spring,
            friction,
        } => Structure::SlidingMass {
            ground_spring,
            friction,
        },
    }
}

/// The wire form of a scene's prior.
pub fn prior_to_wire(p: &Prior) -> wire::ScenePrior {
    let t = &p.tangential;
    wire::ScenePrior {
        normal_k_n_per_m: p.normal.k_n_per_m,
        normal_b_ns_per_m: p.normal.b_ns_per_m,
        mass_kg: t.mass_kg,
        k_ground_n_per_m: t.k_ground_n_per_m,
        b_ground_ns_per_m: t.b_ground_ns_per_m,
        k_contact_n_per_m: t.k_contact_n_per_m,
        b_contact_ns_per_m: t.b_contact_ns_per_m,
        coulomb_n: t.coulomb_n,
    }
}

/// A received scene prior, checked to be passive ([`Prior::validate`]).
pub fn prior_from_wire(p: &wire::ScenePrior) -> Result<Prior, PriorError> {
    let prior = Prior {
        normal: KelvinVoigt {
            k_n_per_m: p.normal_k_n_per_m,
            b_ns_per_m: p.normal_b_ns_per_m,
        },
        tangential: Physical {
            mass_kg: p.mass_kg,
            k_ground_n_per_m: p.k_ground_n_per_m,
            b_ground_ns_per_m: p.b_ground_ns_per_m,
            k_contact_n_per_m: p.k_contact_n_per_m,
            b_contact_ns_per_m: p.b_contact_ns_per_m,
            coulomb_n: p.coulomb_n,
        },
        source: PriorSource::Scene,
    };
    prior.validate()?;
    Ok(prior)
}

/// The wire form of a gated set: only the terms its structure has.
pub fn parameter_set(g: &Gated, sample_time_ns: i64) -> Option<ParameterSet> {
    let terms = match (g.structure(), g.params()) {
        (Structure::KelvinVoigt, Params::KelvinVoigt(kv)) => ModelTerms::KelvinVoigt {
            k_n_per_m: kv.k_n_per_m,
            b_ns_per_m: kv.b_ns_per_m,
        },
        (
            Structure::SlidingMass {
                ground_spring,
                friction,
            },
            Params::SlidingMass(p),
        ) => ModelTerms::SlidingMass {
            mass_kg: p.mass_kg,
            k_ground_n_per_m: ground_spring.then_some(p.k_ground_n_per_m),
            b_ground_ns_per_m: p.b_ground_ns_per_m,
            k_contact_n_per_m: p.k_contact_n_per_m,
            b_contact_ns_per_m: p.b_contact_ns_per_m,
            coulomb_n: friction.then_some(p.coulomb_n),
        },
        _ => return None,
    };
    Some(ParameterSet {
        sample_time_ns,
        residual: g.residual(),
        terms,
    })
}

/// Whether a set is a sliding mass with no mass: the telerobot's reduced first model (its
/// estimator never back-solves an exact zero mass for a whole set).
pub fn is_massless(set: &ParameterSet) -> bool {
    matches!(set.terms, ModelTerms::SlidingMass { mass_kg, .. } if mass_kg == 0.0)
}

/// Gates a received set again (defence in depth: the operator renders nothing it has not checked
/// itself).
pub fn gated_from_wire(set: &ParameterSet) -> Result<Gated, GateRejection> {
    match set.terms {
        ModelTerms::KelvinVoigt {
            k_n_per_m,
            b_ns_per_m,
        } => gate_physical(
            Structure::KelvinVoigt,
            &Params::KelvinVoigt(KelvinVoigt {
                k_n_per_m,
                b_ns_per_m,
            }),
        ),
        ModelTerms::SlidingMass {
            mass_kg,
            k_ground_n_per_m,
            b_ground_ns_per_m,
            k_contact_n_per_m,
            b_contact_ns_per_m,
            coulomb_n,
        } => {
            let structure = Structure::SlidingMass {
                ground_spring: k_ground_n_per_m.is_some(),
                friction: coulomb_n.is_some(),
            };
            let p = Physical {
                mass_kg,
                k_ground_n_per_m: k_ground_n_per_m.unwrap_or(0.0),
                b_ground_ns_per_m,
                k_contact_n_per_m,
                b_contact_ns_per_m,
                coulomb_n: coulomb_n.unwrap_or(0.0),
            };
            gate_physical(structure, &Params::SlidingMass(p))
        }
    }
}

/// The wire form of a surface frame.
pub fn surface_frame_to_wire(f: &SurfaceFrame) -> wire::SurfaceFrame {
    wire::SurfaceFrame {
        normal: f.normal,
        tangent1: f.tangent1,
        tangent2: f.tangent2,
    }
}

/// A surface frame from the wire, if it is orthonormal and right-handed (within 1e-6).
pub fn surface_frame_from_wire(f: &wire::SurfaceFrame) -> Option<SurfaceFrame> {
    let unit = |a: [f64; 3]| (vec3::norm2(a) - 1.0).abs() < 1e-6;
    let ok = unit(f.normal)
        && unit(f.tangent1)
        && unit(f.tangent2)
        && vec3::dot(f.normal, f.tangent1).abs() < 1e-6
        && vec3::dot(vec3::cross(f.normal, f.tangent1), f.tangent2) > 1.0 - 1e-6;
    ok.then_some(SurfaceFrame {
        normal: f.normal,
        tangent1: f.tangent1,
        tangent2: f.tangent2,
    })
}

/// The wire form of a camera frame, sent as `frame_id`: its points, capture time and sensor
/// pose. The daemon's camera thread and the in-process harness both send frames this way.
pub fn cloud_to_wire(frame_id: u64, frame: CloudFrame) -> wire::CloudFrame {
    let pose = *frame.sensor_pose();
    wire::CloudFrame {
        frame_id,
        timestamp_ns: frame.timestamp_ns(),
        sensor_position_m: pose.translation_m,
        sensor_orientation_xyzw: pose.quaternion_xyzw(),
        points: frame.into_points(),
    }
}

/// The wire form of a contact state.
pub fn contact_state_to_wire(s: mmt::contact::ContactState) -> wire::ContactState {
    match s {
        mmt::contact::ContactState::Free => wire::ContactState::Free,
        mmt::contact::ContactState::Contact => wire::ContactState::Contact,
        mmt::contact::ContactState::Entrenched => wire::ContactState::Entrenched,
    }
}
