//! Issue 13: the normal axis renders a prior from the first tick of contact, and hands over to
//! the first model in a bounded linear blend.

use super::super::*;
use crate::model::KelvinVoigt;
use crate::model::Structure;
use crate::model::backsolve::Params;
use crate::model::gates::{Gated, gate_physical};

fn kv(k: f64, b: f64) -> Gated {
    gate_physical(
        Structure::KelvinVoigt,
        &Params::KelvinVoigt(KelvinVoigt {
            k_n_per_m: k,
            b_ns_per_m: b,
        }),
    )
    .unwrap()
}

fn prior() -> Gated {
    kv(800.0, 20.0)
}

/// Immediate smoothing, so that the blend's every tick has an exact answer.
fn config(handover_s: f64) -> RendererConfig {
    RendererConfig {
        smoothing_tau_s: 0.0,
        handover_s,
        ..RendererConfig::default()
    }
}

#[test]
fn the_prior_renders_from_the_first_tick_of_contact_and_nothing_outside_it() {
    let mut without = KelvinVoigtRenderer::new(config(0.4)).unwrap();
    assert_eq!(without.step(0.002, 0.01, true), 0.0);
    let mut r = KelvinVoigtRenderer::new(config(0.4)).unwrap();
    assert!(r.set_prior(&prior()));
    assert_eq!(r.step(0.002, 0.01, false), 0.0);
    assert_eq!(r.step(-0.001, 0.0, true), 0.0);
    // 800·0.002 + 20·0.01 = 1.8 N on the first tick in contact.
    assert!((r.step(0.002, 0.01, true) - 1.8).abs() < 1e-12);
    // Unilateral, like any model: pulling out fast never pulls.
    assert_eq!(r.step(0.002, -1.0, true), 0.0);
    assert_eq!(r.stats().prior_ticks, 4);
    assert!(r.target().is_none());
}

#[test]
fn the_first_model_takes_over_in_a_linear_blend_of_the_configured_length() {
    let mut r = KelvinVoigtRenderer::new(config(0.4)).unwrap();
    assert!(r.set_prior(&prior()));
    r.step(0.001, 0.0, true);
    assert!(r.set_target(&kv(300.0, 60.0)));
    // 400 ticks at 1 kHz: tick j renders k = 800 + (j/400)(300 − 800), b = 20 + (j/400)·40.
    for j in 1..=400 {
        let w = j as f64 / 400.0;
        let (k, b) = (800.0 - 500.0 * w, 20.0 + 40.0 * w);
        let f = r.step(0.002, 0.01, true);
        assert!((f - (k * 0.002 + b * 0.01)).abs() < 1e-12, "tick {j}: {f}");
    }
    // Then the model alone: 300·0.002 + 60·0.01 = 1.2 N.
    for _ in 0..3 {
        assert!((r.step(0.002, 0.01, true) - 1.2).abs() < 1e-12);
    }
    // A later model is smoothed as usual, with no blend from the prior.
    r.set_target(&kv(500.0, 60.0));
    assert!((r.step(0.002, 0.01, true) - 1.6).abs() < 1e-12);
    assert_eq!(r.stats().prior_ticks, 1);
}

#[test]
fn a_zero_handover_switches_at_once_and_a_late_prior_is_ignored() {
    let mut r = KelvinVoigtRenderer::new(config(0.0)).unwrap();
    assert!(r.set_prior(&prior()));
    r.set_target(&kv(300.0, 60.0));
    assert!((r.step(0.002, 0.01, true) - 1.2).abs() < 1e-12);
    assert!(!r.set_prior(&kv(5000.0, 0.0)));
    assert!((r.step(0.002, 0.01, true) - 1.2).abs() < 1e-12);
    // A non-physical prior never passes the gates a prior is installed through.
    let mut bad = KelvinVoigtRenderer::new(config(0.4)).unwrap();
    for (k, b) in [
        (f64::NAN, 1.0),
        (-1.0, 1.0),
        (1.0, f64::INFINITY),
        (1.0, -2.0),
    ] {
        let params = Params::KelvinVoigt(KelvinVoigt {
            k_n_per_m: k,
            b_ns_per_m: b,
        });
        assert!(
            gate_physical(Structure::KelvinVoigt, &params).is_err(),
            "{k} {b}"
        );
    }
    assert_eq!(bad.step(0.002, 0.01, true), 0.0);
    let e = KelvinVoigtRenderer::new(RendererConfig {
        handover_s: -0.1,
        ..RendererConfig::default()
    })
    .unwrap_err();
    assert_eq!(e.field, "handover_s");
}

#[test]
fn colgate_bounds_the_prior_like_any_model() {
    let mut r = KelvinVoigtRenderer::new(RendererConfig {
        device_damping_ns_per_m: Some(4.0),
        ..config(0.4)
    })
    .unwrap();
    assert!(r.set_prior(&kv(5000.0, 2.0)));
    // k ≤ 2(b_dev − b)/T = 4000 N/m.
    assert!((r.step(0.001, 0.0, true) - 4.0).abs() < 1e-12);
    assert_eq!(r.adjustments().stiffness_clipped, Some((5000.0, 4000.0)));
}
