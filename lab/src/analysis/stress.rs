//! `mmt stress`: the renderer on extreme and garbage inputs (numerics notes §4.4, §10.5–10.7).
//!
//! Every case renders 5 s of in-contact motion (2 Hz, 5 mm unless the case says otherwise) at
//! 1 kHz through the real renderer, after the parameters went through the real gates: a
//! rejected set is not rendered and the renderer holds the last accepted one (the exp-1 set,
//! given first). Reported per case: max |F|, whether every output was finite, and what the gates
//! and the renderability gate decided.

use mmt::model::backsolve::Params;
use mmt::model::gates::{GateConfig, gate, gate_physical};
use mmt::model::{Physical, Structure, Theta};
use mmt::render::{Renderability, RendererConfig, SlidingMassRenderer};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use serde::Serialize;

/// One case of the report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Case {
    /// What was done.
    pub name: String,
    /// Largest |force| rendered [N].
    pub max_abs_force_n: f64,
    /// Every output finite.
    pub all_finite: bool,
    /// What the gates (and the renderability gate) decided.
    pub gate: String,
    /// A case-specific figure, when there is one.
    pub detail: Option<String>,
}

/// The report: `{"cases":[…]}`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StressReport {
    /// The cases, in order.
    pub cases: Vec<Case>,
}

const FULL: Structure = Structure::SlidingMass {
    ground_spring: true,
    friction: true,
};
const TICKS: usize = 5000;

/// Runs every case.
pub fn stress() -> StressReport {
    let typical = Physical::new(0.5, 200.0, 5.0, 2000.0, 10.0, 0.3);
    let mut cases = vec![
        given(
            "stiff (m = 0.01, k2 = 1e5, b2 = 1)",
            Physical::new(0.01, 0.0, 0.0, 1e5, 1.0, 0.0),
        ),
        near_massless(typical),
        given(
            "massless (m = 0)",
            Physical::new(0.0, 200.0, 5.0, 2000.0, 10.0, 0.3),
        ),
        given("thesis exp-1 set", Physical::THESIS_EXP1),
    ];
    for (name, bad) in [
        (
            "NaN mass",
            Physical::new(f64::NAN, 200.0, 5.0, 2000.0, 10.0, 0.3),
        ),
        (
            "+inf contact stiffness",
            Physical::new(0.5, 200.0, 5.0, f64::INFINITY, 10.0, 0.3),
        ),
        (
            "-inf ground damping",
            Physical::new(0.5, 200.0, f64::NEG_INFINITY, 2000.0, 10.0, 0.3),
        ),
        (
            "negative mass",
            Physical::new(-0.5, 200.0, 5.0, 2000.0, 10.0, 0.3),
        ),
        (
            "negative ground damping",
            Physical::new(0.5, 200.0, -8.0, 2000.0, 10.0, 0.3),
        ),
        (
            "stable but active (k1 = -150 < 0 < k1 + k2)",
            Physical::new(0.5, -150.0, 5.0, 2000.0, 10.0, 0.3),
        ),
    ] {
        cases.push(garbage_theta(name, bad));
    }
    for every in [1usize, 10, 100] {
        cases.push(jumping(every));
    }
    cases.push(random_theta());
    for (name, amp) in [("huge input (1e3 m)", 1e3), ("huge input (1e300 m)", 1e300)] {
        cases.push(run_case(name.to_string(), Physical::THESIS_EXP1, amp, None));
    }
    cases.push(non_finite_input());
    StressReport { cases }
}

/// A physical set given directly: gate, then render.
fn given(name: &str, params: Physical) -> Case {
    run_case(name.to_string(), params, 0.005, None)
}

fn run_case(name: String, params: Physical, amplitude: f64, detail: Option<String>) -> Case {
    let mut r =
        SlidingMassRenderer::new(RendererConfig::default()).unwrap_or_else(|_| unreachable!());
    let gate = match gate_physical(FULL, &Params::SlidingMass(params)) {
        Ok(g) => {
            r.set_target(&g);
            "passed".to_string()
        }
        Err(e) => format!("rejected: {e}"),
    };
    let (max, finite) = drive(&mut r, amplitude, |_, _| {});
    Case {
        gate: with_renderability(gate, &r),
        name,
        max_abs_force_n: max,
        all_finite: finite,
        detail,
    }
}

/// Renders `TICKS` ticks of `amplitude·sin(2π·2t)`; `each(tick, renderer)` runs before each tick.
fn drive(
    r: &mut SlidingMassRenderer,
    amplitude: f64,
    mut each: impl FnMut(usize, &mut SlidingMassRenderer),
) -> (f64, bool) {
    let w = 2.0 * std::f64::consts::PI * 2.0;
    let (mut max, mut finite) = (0.0f64, true);
    for k in 0..TICKS {
        each(k, r);
        let t = k as f64 * 1e-3;
        let f = r.step(
            amplitude * (w * t).sin(),
            amplitude * w * (w * t).cos(),
            true,
        );
        finite &= f.is_finite();
        if f.is_finite() {
            max = max.max(f.abs());
        }
    }
    (max, finite)
}

fn with_renderability(gate: String, r: &SlidingMassRenderer) -> String {
    match r.adjustments().renderability {
        Renderability::Resolved => gate,
        Renderability::RaisedMass { from_kg, to_kg } => {
            format!("{gate}; renderability gate: ω_n·h > 1, mass raised {from_kg} → {to_kg:.4} kg")
        }
        Renderability::Reduced { mass_kg } => {
            format!(
                "{gate}; renderability gate: ω_n·h > 1, mass {mass_kg} kg dropped (massless model)"
            )
        }
    }
}

/// m = 1e-6 rendered by SDIRK2 itself (renderability gate off) against m = 0: the largest
/// relative difference after the first 5 ticks.
fn near_massless(typical: Physical) -> Case {
    let ungated = RendererConfig {
        max_omega_h: f64::INFINITY,
        ..RendererConfig::default()
    };
    let mut near = typical;
    near.mass_kg = 1e-6;
    let mut zero = typical;
    zero.mass_kg = 0.0;
    let mk = |p: Physical| {
        let mut r = SlidingMassRenderer::new(ungated).unwrap_or_else(|_| unreachable!());
        if let Ok(g) = gate_physical(FULL, &Params::SlidingMass(p)) {
            r.set_target(&g);
        }
        r
    };
    let (mut rn, mut rz) = (mk(near), mk(zero));
    let w = 2.0 * std::f64::consts::PI * 2.0;
    let (mut worst, mut max, mut finite) = (0.0f64, 0.0f64, true);
    for k in 0..TICKS {
        let t = k as f64 * 1e-3;
        let (x, v) = (0.005 * (w * t).sin(), 0.005 * w * (w * t).cos());
        let (a, b) = (rn.step(x, v, true), rz.step(x, v, true));
        finite &= a.is_finite() && b.is_finite();
        max = max.max(a.abs());
        if k >= 5 {
            worst = worst.max((a - b).abs() / b.abs().max(1e-3));
        }
    }
    let gated = run_case(String::new(), near, 0.005, None);
    Case {
        name: "near-massless (m = 1e-6)".into(),
        max_abs_force_n: max,
        all_finite: finite && gated.all_finite,
        gate: gated.gate,
        detail: Some(format!(
            "SDIRK2 without the renderability gate vs the massless model after 5 ticks: max relative difference {worst:.2e}"
        )),
    }
}

/// A garbage set arriving as θ while the exp-1 set is rendered: rejected, the renderer holds.
fn garbage_theta(name: &str, bad: Physical) -> Case {
    let mut r =
        SlidingMassRenderer::new(RendererConfig::default()).unwrap_or_else(|_| unreachable!());
    if let Ok(g) = gate_physical(FULL, &Params::SlidingMass(Physical::THESIS_EXP1)) {
        r.set_target(&g);
    }
    let theta = bad
        .theta()
        .unwrap_or(Theta([f64::NAN; mmt::model::col::COUNT]));
    let gate = match gate(FULL, &theta, None, &GateConfig::default()) {
        Ok(g) => {
            r.set_target(&g);
            "passed".to_string()
        }
        Err(e) => format!("rejected ({e}); holding the last accepted set"),
    };
    let (max, finite) = drive(&mut r, 0.005, |_, _| {});
    Case {
        name: name.into(),
        max_abs_force_n: max,
        all_finite: finite,
        gate,
        detail: None,
    }
}

/// Random physical sets (log-uniform, notes §4.4) jumping every `every` ticks, smoothed.
fn jumping(every: usize) -> Case {
    let mut rng = Pcg64::seed_from_u64(every as u64);
    let mut r =
        SlidingMassRenderer::new(RendererConfig::default()).unwrap_or_else(|_| unreachable!());
    let mut accepted = 0;
    let lu = |rng: &mut Pcg64, lo: f64, hi: f64| rng.random_range(f64::ln(lo)..f64::ln(hi)).exp();
    let (max, finite) = drive(&mut r, 0.005, |k, r| {
        if k % every == 0 {
            let set = Physical::new(
                lu(&mut rng, 1e-3, 1.0),
                lu(&mut rng, 1.0, 1e3),
                lu(&mut rng, 0.1, 10.0),
                lu(&mut rng, 1e2, 1e5),
                lu(&mut rng, 0.1, 10.0),
                0.0,
            );
            if let Ok(g) = gate_physical(FULL, &Params::SlidingMass(set)) {
                r.set_target(&g);
                accepted += 1;
            }
        }
    });
    Case {
        name: format!("parameters jumping every {every} ms (smoothed, τ = 20 ms)"),
        max_abs_force_n: max,
        all_finite: finite,
        gate: format!("{accepted} random physical sets passed"),
        detail: Some(format!("physical scale k2max·|x|max = {} N", 1e5 * 0.005)),
    }
}

/// Random θ vectors (signs and magnitudes anywhere) every 10 ms: most are rejected.
fn random_theta() -> Case {
    let mut rng = Pcg64::seed_from_u64(99);
    let mut r =
        SlidingMassRenderer::new(RendererConfig::default()).unwrap_or_else(|_| unreachable!());
    if let Ok(g) = gate_physical(FULL, &Params::SlidingMass(Physical::THESIS_EXP1)) {
        r.set_target(&g);
    }
    let (mut passed, mut rejected) = (0, 0);
    let (max, finite) = drive(&mut r, 0.005, |k, r| {
        if k % 10 == 0 {
            let t = Theta(std::array::from_fn(|_| {
                let mag = 10f64.powf(rng.random_range(-6.0..4.0));
                if rng.random_bool(0.3) { -mag } else { mag }
            }));
            match gate(FULL, &t, None, &GateConfig::default()) {
                Ok(g) => {
                    r.set_target(&g);
                    passed += 1;
                }
                Err(_) => rejected += 1,
            }
        }
    });
    Case {
        name: "random θ every 10 ms".into(),
        max_abs_force_n: max,
        all_finite: finite,
        gate: format!("{passed} passed, {rejected} rejected"),
        detail: None,
    }
}

/// NaN and infinite tool positions and velocities mixed into the input.
fn non_finite_input() -> Case {
    let mut r =
        SlidingMassRenderer::new(RendererConfig::default()).unwrap_or_else(|_| unreachable!());
    if let Ok(g) = gate_physical(FULL, &Params::SlidingMass(Physical::THESIS_EXP1)) {
        r.set_target(&g);
    }
    let garbage = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e308, -1e308];
    let (mut max, mut finite) = (0.0f64, true);
    for k in 0..TICKS {
        let t = k as f64 * 1e-3;
        let (x, v) = if k % 7 == 3 {
            (garbage[k % 5], garbage[(k / 5) % 5])
        } else {
            (0.005 * (12.0 * t).sin(), 0.06 * (12.0 * t).cos())
        };
        let f = r.step(x, v, true);
        finite &= f.is_finite();
        if f.is_finite() {
            max = max.max(f.abs());
        }
    }
    let s = r.stats();
    Case {
        name: "NaN/inf/1e308 tool positions and velocities".into(),
        max_abs_force_n: max,
        all_finite: finite,
        gate: "passed (exp-1 set)".into(),
        detail: Some(format!(
            "{} inputs rejected, {} state resets",
            s.rejected_inputs, s.state_resets
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_case_is_finite_and_the_decisions_are_right() {
        let r = stress();
        for c in &r.cases {
            assert!(c.all_finite, "{c:?}");
            assert!(c.max_abs_force_n.is_finite());
        }
        let case = |prefix: &str| r.cases.iter().find(|c| c.name.starts_with(prefix)).unwrap();
        assert!(
            case("stiff").gate.contains("renderability gate"),
            "{:?}",
            case("stiff")
        );
        assert!(case("near-massless").gate.contains("massless model"));
        let detail = case("near-massless").detail.clone().unwrap();
        let worst: f64 = detail.rsplit(' ').next().unwrap().parse().unwrap();
        assert!(worst <= 1e-3, "{detail}");
        for bad in [
            "NaN mass",
            "+inf",
            "-inf",
            "negative mass",
            "negative ground",
            "stable but active",
        ] {
            assert!(case(bad).gate.starts_with("rejected"), "{:?}", case(bad));
        }
        assert!(case("stable but active").gate.contains("not passive"));
        for every in ["1 ms", "10 ms", "100 ms"] {
            let c = r
                .cases
                .iter()
                .find(|c| c.name.contains(&format!("every {every}")))
                .unwrap();
            assert!(c.max_abs_force_n <= 1e5 * 0.005, "{c:?}");
        }
    }
}
