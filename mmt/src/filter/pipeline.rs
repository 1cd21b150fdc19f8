//! The regression survives the SVF pipeline and does not survive per-derivative filtering
//! (numerics notes §7, §10 item 10). Exact synthetic data: a sum of sines through the exact
//! model (no noise, no friction), batch least squares on the filtered regressors.

use super::*;
use crate::model::{Columns, Physical, Structure};
use crate::testutil::{Multisine, batch_ls, exp1_frictionless, max_abs_rel, typical};

const H: f64 = 1e-3;
/// Filter start-up transient left out of the fit [s].
const SETTLE_S: f64 = 3.0;

/// Runs `regress(x, v, F)` over `seconds` of the exact response and fits θ on the active columns.
fn fit(
    object: &Physical,
    excitation: &Multisine,
    columns: Columns,
    seconds: f64,
    mut regress: impl FnMut(f64, f64, f64) -> Regression,
) -> [f64; col::COUNT] {
    let mut rows = Vec::new();
    let mut ys = Vec::new();
    let n = (seconds / H) as usize;
    for k in 0..n {
        let t = k as f64 * H;
        let (x, v) = excitation.position_velocity(t);
        let r = regress(x, v, excitation.force(object, t));
        if t >= SETTLE_S {
            rows.push(r.psi);
            ys.push(r.y);
        }
    }
    // Scale columns by their RMS for the reference solve.
    let mut scales = [1.0; col::COUNT];
    for i in columns.indices() {
        scales[i] = (rows.iter().map(|r| r[i] * r[i]).sum::<f64>() / rows.len() as f64).sqrt();
    }
    batch_ls(&rows, &ys, columns, &scales, f64::INFINITY)
}

fn rel_error(got: &[f64; col::COUNT], truth: &Physical, columns: Columns) -> f64 {
    let want = truth.theta().unwrap().0;
    let idx: Vec<usize> = columns.indices().collect();
    let g: Vec<f64> = idx.iter().map(|&i| got[i]).collect();
    let w: Vec<f64> = idx.iter().map(|&i| want[i]).collect();
    max_abs_rel(&g, &w)
}

fn svf_fit(object: &Physical, excitation: &Multisine, columns: Columns) -> f64 {
    let mut filt = RegressorFilter::new(RegressorConfig::default()).unwrap();
    let theta = fit(object, excitation, columns, 30.0, |x, v, f| {
        filt.step(x, v, f)
    });
    rel_error(&theta, object, columns)
}

#[test]
fn svf_pipeline_recovers_theta() {
    let no_friction = |ground_spring| {
        Structure::SlidingMass {
            ground_spring,
            friction: false,
        }
        .columns()
    };
    // Numerics notes §6.2's data set: 0.3–8.9 Hz at 5 mm.
    let e_typ = svf_fit(
        &typical(),
        &Multisine::log_spaced(8, 0.3, 8.9, 0.005, 0.005),
        no_friction(true),
    );
    // The exp-1 object (k1 = 0: the d column left out) under the exp-1 excitation.
    let e_exp1 = svf_fit(&exp1_frictionless(), &Multisine::exp1(), no_friction(false));
    eprintln!("SVF batch-LS max relative θ error: typical {e_typ:.2e}, exp-1 {e_exp1:.2e}");
    assert!(e_typ < 5e-3, "typical set: {e_typ}");
    assert!(e_exp1 < 5e-3, "exp-1 set: {e_exp1}");
}

/// The thesis-like pipeline read literally: x and F unfiltered, each derivative the low-pass of
/// the backward difference of the previous one (§D.2). Same low-pass (the SVF's `u_f`).
#[test]
fn inconsistent_cascade_fails() {
    let object = typical();
    let excitation = Multisine::log_spaced(8, 0.3, 8.9, 0.005, 0.005);
    let columns = Structure::SlidingMass {
        ground_spring: true,
        friction: false,
    }
    .columns();
    let lp = || Svf::new(SvfConfig::default()).unwrap();
    let mut x_lp = [lp(), lp(), lp()];
    let mut f_lp = [lp(), lp()];
    let mut prev_x = [0.0; 3]; // previous x, x′, x″
    let mut prev_f = [0.0; 2]; // previous F, F′
    let theta = fit(&object, &excitation, columns, 30.0, |x, _v, f| {
        let mut xs = [x, 0.0, 0.0, 0.0];
        for k in 0..3 {
            x_lp[k].step((xs[k] - prev_x[k]) / H);
            prev_x[k] = xs[k];
            xs[k + 1] = x_lp[k].derivative(0).unwrap_or(0.0);
        }
        let mut fs = [f, 0.0, 0.0];
        for k in 0..2 {
            f_lp[k].step((fs[k] - prev_f[k]) / H);
            prev_f[k] = fs[k];
            fs[k + 1] = f_lp[k].derivative(0).unwrap_or(0.0);
        }
        Regression {
            psi: [
                -xs[3], -xs[2], -xs[1], -xs[0], -fs[2], -fs[1], 0.0, 0.0, 0.0, 0.0,
            ],
            y: f,
        }
    });
    let err = rel_error(&theta, &object, columns);
    eprintln!("cascaded per-derivative filtering: max relative θ error {err:.2e}");
    assert!(
        err > 0.1,
        "the inconsistent pipeline unexpectedly fits: {err}"
    );
}
