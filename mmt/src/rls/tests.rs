//! Estimator tests against exact answers (numerics notes §10 item 9).

use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64;

use super::*;
use crate::filter::{Regression, RegressorConfig, RegressorFilter};
use crate::model::{Physical, Structure};
use crate::testutil::{Multisine, batch_ls, exp1_frictionless, max_abs_rel, typical};

const H: f64 = 1e-3;

fn no_friction(ground_spring: bool) -> Columns {
    Structure::SlidingMass {
        ground_spring,
        friction: false,
    }
    .columns()
}

/// SVF regressions of the exact response to `excitation` from `t0` for `seconds`, with seeded
/// white noise on x (2 µm) and F (0.02 N) when `noisy`. The filter is started at `t0 − 3 s` and
/// its transient dropped.
fn regressions(
    object: &Physical,
    excitation: &Multisine,
    t0: f64,
    seconds: f64,
    noisy: bool,
) -> Vec<Regression> {
    let mut filt = RegressorFilter::new(RegressorConfig::default()).unwrap();
    let mut rng = Pcg64::seed_from_u64(7);
    let nx = Normal::new(0.0, if noisy { 2e-6 } else { 0.0 }).unwrap();
    let nf = Normal::new(0.0, if noisy { 0.02 } else { 0.0 }).unwrap();
    let settle = 3000;
    let total = settle + (seconds / H) as usize;
    let mut out = Vec::with_capacity(total - settle);
    for k in 0..total {
        let t = t0 - 3.0 + k as f64 * H;
        let (x, v) = excitation.position_velocity(t);
        let f = excitation.force(object, t);
        let r = filt.step(x + nx.sample(&mut rng), v, f + nf.sample(&mut rng));
        if k >= settle {
            out.push(r);
        }
    }
    out
}

/// The numerics notes' §6.2 data: the typical object under 0.3–8.9 Hz at 5 mm, with noise.
fn typical_data(seconds: f64) -> Vec<Regression> {
    regressions(&typical(), &typical_excitation(), 0.0, seconds, true)
}

fn typical_excitation() -> Multisine {
    Multisine::log_spaced(8, 0.3, 8.9, 0.005, 0.005)
}

/// Scales matching [`typical_excitation`].
fn typical_scales() -> ColumnScales {
    ColumnScales::for_excitation(0.005, 10.0, 20.0).unwrap()
}

fn config(columns: Columns, scales: ColumnScales, forgetting: f64, p0: f64) -> RlsConfig {
    RlsConfig {
        columns,
        forgetting,
        initial_covariance: p0,
        max_mean_variance: p0,
        scales,
        ..RlsConfig::default()
    }
}

fn learn_all(rls: &mut Rls, data: &[Regression]) {
    for r in data {
        let out = rls.update(&r.psi, r.y, Mode::Learn);
        assert!(matches!(out, Outcome::Updated { .. }), "{out:?}");
    }
}

fn active_rel_error(got: &Theta, want: &[f64; col::COUNT], columns: Columns) -> f64 {
    let g: Vec<f64> = columns.indices().map(|i| got.0[i]).collect();
    let w: Vec<f64> = columns.indices().map(|i| want[i]).collect();
    max_abs_rel(&g, &w)
}

/// The numeric state, bit for bit (the counters left out).
fn state_bits(r: &Rls) -> Vec<u64> {
    let mut v: Vec<f64> = r.theta_s.to_vec();
    v.extend(r.u.iter().flatten());
    v.extend(r.d);
    v.extend([r.err2, r.out2, r.last_error, r.cusum.statistic()]);
    let mut bits: Vec<u64> = v.iter().map(|x| x.to_bits()).collect();
    bits.extend(format!("{:?}", r.cusum).bytes().map(u64::from));
    bits
}

/// λ = 1 recursive least squares is batch least squares with the prior term `θᵀP0⁻¹θ`, on
/// scaled and on raw (cond 1e12) regressors; the covariance equals `(ΨᵀΨ + P0⁻¹)⁻¹`.
#[test]
fn equals_batch_least_squares_without_forgetting() {
    let object = typical();
    let cols = no_friction(true);
    let data = typical_data(20.0);
    let rows: Vec<_> = data.iter().map(|r| r.psi).collect();
    let ys: Vec<_> = data.iter().map(|r| r.y).collect();
    let scaled = typical_scales();
    for (name, scales, p0) in [
        ("scaled", scaled, 1e3),
        ("unscaled", ColumnScales::UNIT, 1e6),
    ] {
        let mut rls = Rls::new(config(cols, scales, 1.0, p0)).unwrap();
        learn_all(&mut rls, &data);
        let want = batch_ls(&rows, &ys, cols, &scales.0, p0);
        let err = active_rel_error(&rls.theta(), &want, cols);
        let truth = active_rel_error(&rls.theta(), &object.theta().unwrap().0, cols);
        eprintln!("λ = 1, {name}: RLS vs batch LS {err:.1e} (vs truth {truth:.1e})");
        assert!(err < 1e-6, "{name}: {err}");
        assert_eq!(rls.counts().updates, data.len() as u64);
    }
    // Covariance against the explicit inverse, scaled (the raw one is not invertible in f64).
    let mut rls = Rls::new(config(cols, scaled, 1.0, 1e3)).unwrap();
    learn_all(&mut rls, &data[..2000]);
    let idx: Vec<usize> = cols.indices().collect();
    let n = idx.len();
    let mut info = nalgebra::DMatrix::<f64>::identity(n, n) / 1e3;
    for r in &data[..2000] {
        let phi = nalgebra::DVector::from_iterator(n, idx.iter().map(|&i| r.psi[i] / scaled.0[i]));
        info += &phi * phi.transpose();
    }
    let p_s = info.try_inverse().unwrap();
    let p = rls.covariance();
    let mut worst: f64 = 0.0;
    for (a, &ia) in idx.iter().enumerate() {
        for (c, &ic) in idx.iter().enumerate() {
            let got = p[(ia, ic)] * scaled.0[ia] * scaled.0[ic];
            let scale = (p_s[(a, a)] * p_s[(c, c)]).sqrt();
            worst = worst.max((got - p_s[(a, c)]).abs() / scale);
        }
    }
    assert!(worst < 1e-6, "covariance {worst:e}");
}

/// The scales are an exact change of variables: with power-of-two scales and the same prior
/// (`p0·I` scaled ≙ `diag(p0/s²)` raw), the U-D recursion gives the same bits, forgetting on.
#[test]
fn power_of_two_scaling_changes_no_bits() {
    let cols = no_friction(true);
    let data = typical_data(10.0);
    let scales = typical_scales();
    let cfg = |scales| RlsConfig {
        max_mean_variance: 1e30, // keep the bound inactive: it compares traces, which scaling changes
        ..config(cols, scales, 0.999, 1e3)
    };
    let mut scaled = Rls::new(cfg(scales)).unwrap();
    let mut raw = Rls::new(cfg(ColumnScales::UNIT)).unwrap();
    for (k, i) in cols.indices().enumerate() {
        raw.d[k] = 1e3 / (scales.0[i] * scales.0[i]);
    }
    learn_all(&mut scaled, &data);
    learn_all(&mut raw, &data);
    assert_eq!(
        scaled.theta().0.map(f64::to_bits),
        raw.theta().0.map(f64::to_bits)
    );
    assert_eq!(scaled.prior_error().to_bits(), raw.prior_error().to_bits());
}

/// Raw regressors (cond 1e12) with λ = 0.999 for 30 s, then a single tone (rank-2 excitation of
/// 6 columns: four directions wind up to the bound) for 30 s: `D > 0` and finite after every
/// update, no reset needed.
#[test]
fn factor_stays_positive_definite_on_ill_conditioned_data() {
    let object = typical();
    let cols = no_friction(true);
    let mut data = typical_data(30.0);
    data.extend(regressions(
        &object,
        &Multisine::log_spaced(2, 2.0, 2.0, 0.005, 0.0),
        0.0,
        30.0,
        true,
    ));
    let mut rls = Rls::new(config(cols, ColumnScales::UNIT, 0.999, 1e6)).unwrap();
    let mut min_d = f64::INFINITY;
    for r in &data {
        let out = rls.update(&r.psi, r.y, Mode::Learn);
        assert!(matches!(out, Outcome::Updated { .. }), "{out:?}");
        let d = rls.min_d();
        assert!(d > 0.0 && d.is_finite() && rls.trace().is_finite());
        min_d = min_d.min(d);
    }
    assert_eq!(rls.counts().not_positive_definite, 0);
    eprintln!(
        "raw regressors, 60 s: min D = {min_d:.1e}, final tr P = {:.1e}",
        rls.trace()
    );
}

/// 10 s of learning, then 20 s paused (out of contact: whatever ψ is, even 0 or NaN): the state
/// is bit-identical; then 20 s of a static hold (constant ψ, forgetting on): `tr P` and the
/// largest eigenvalue stay under the bound `n·p̄`.
#[test]
fn bounded_through_pause_and_static_hold() {
    let object = typical();
    let cols = no_friction(true);
    let data = typical_data(10.0);
    let mut rls = Rls::new(config(cols, typical_scales(), 0.999, 1e3)).unwrap();
    learn_all(&mut rls, &data);
    let before = state_bits(&rls);
    let trace_after_learning = rls.trace();
    for k in 0..20_000 {
        let psi = if k % 2 == 0 {
            [0.0; col::COUNT]
        } else {
            [f64::NAN; col::COUNT]
        };
        assert_eq!(rls.update(&psi, 0.0, Mode::Pause), Outcome::Paused);
    }
    assert_eq!(state_bits(&rls), before, "a pause changed the estimator");
    assert_eq!(rls.counts().paused, 20_000);
    // Static hold at x = 4 mm: the filter settles to ψ = [0, 0, 0, −x, 0, 0, 0, 0].
    let mut filt = RegressorFilter::new(RegressorConfig::default()).unwrap();
    let x = 0.004;
    let f = object.force_per_displacement(0.0).re * x;
    filt.reset_steady(x, 0.0, f);
    let bound = cols.len() as f64 * 1e3;
    let mut max_trace: f64 = 0.0;
    for _ in 0..20_000 {
        let r = filt.step(x, 0.0, f);
        let _ = rls.update(&r.psi, r.y, Mode::Learn);
        max_trace = max_trace.max(rls.trace());
        assert!(
            rls.trace() <= bound * (1.0 + 1e-12),
            "tr P = {}",
            rls.trace()
        );
    }
    let max_eig = rls.covariance_scaled_max_eigenvalue();
    eprintln!(
        "static hold 20 s: tr P {trace_after_learning:.2e} → max {max_trace:.2e} (bound {bound:.0e}), max eig {max_eig:.2e}"
    );
    assert!(max_eig <= bound * (1.0 + 1e-9));
    assert!(
        max_trace > 0.5 * bound,
        "the hold should have wound P up to the bound"
    );
}

impl Rls {
    fn covariance_scaled_max_eigenvalue(&self) -> f64 {
        let p = self.covariance();
        let s = &self.config.scales.0;
        let scaled = SMatrix::<f64, N, N>::from_fn(|i, j| p[(i, j)] * s[i] * s[j]);
        scaled.symmetric_eigenvalues().max()
    }
}

/// Contact with object A for 10 s, 20 s out of contact, then re-contact with B = A with k2 and
/// b2 doubled. The detector flags B within tens of milliseconds of the end of the onset guard;
/// after the covariance reset θ̂ is within 5 % of B's θ within a few seconds.
#[test]
fn reconverges_after_contact_parameters_double() {
    let a = exp1_frictionless();
    let b = Physical {
        k_contact_n_per_m: 2.0 * a.k_contact_n_per_m,
        b_contact_ns_per_m: 2.0 * a.b_contact_ns_per_m,
        ..a
    };
    let cols = no_friction(false);
    let excitation = Multisine::exp1();
    let mut rls = Rls::new(RlsConfig {
        columns: cols,
        ..RlsConfig::default()
    })
    .unwrap();
    let phase_a = regressions(&a, &excitation, 0.0, 10.0, true);
    for r in &phase_a {
        let out = rls.update(&r.psi, r.y, Mode::Learn);
        assert!(
            matches!(
                out,
                Outcome::Updated {
                    new_object: false,
                    ..
                }
            ),
            "false alarm: {out:?}"
        );
    }
    let err_a = active_rel_error(&rls.theta(), &a.theta().unwrap().0, cols);
    // Out of contact 20 s: paused (the filter's state is irrelevant: the B data restarts it).
    for _ in 0..20_000 {
        let _ = rls.update(&[0.0; col::COUNT], 0.0, Mode::Pause);
    }
    let guard = 300; // 0.3 s onset guard (DESIGN §11.3)
    let phase_b = regressions(&b, &excitation, 30.0, 10.0, true);
    let truth_b = b.theta().unwrap().0;
    let mut alarm_at = None;
    // Time from re-contact until the error stays below `tol` [s].
    let stays_within = |tol: f64, errs: &[f64]| {
        errs.iter().rposition(|&e| e >= tol).map_or(0, |k| k + 1) as f64 * H
    };
    let mut errs = Vec::new();
    for (k, r) in phase_b.iter().enumerate() {
        let mode = if k < guard { Mode::Pause } else { Mode::Learn };
        if let Outcome::Updated {
            new_object: true, ..
        } = rls.update(&r.psi, r.y, mode)
        {
            assert!(alarm_at.is_none(), "second alarm at {k}");
            alarm_at = Some(k);
            rls.reset(1e3).unwrap();
        }
        errs.push(active_rel_error(&rls.theta(), &truth_b, cols));
    }
    let alarm = alarm_at.expect("no new-object alarm");
    let first5 = errs.iter().position(|&e| e < 0.05).unwrap_or(errs.len()) as f64 * H;
    let t10 = stays_within(0.10, &errs);
    let worst_late = errs[5000..].iter().copied().fold(0.0, f64::max);
    eprintln!(
        "object A error after 10 s {err_a:.1e}; B: alarm {} ms after the guard; from re-contact: first within 5 % after {first5:.2} s, stays within 10 % after {t10:.2} s; worst error over the last 5 s {worst_late:.1e} (noise-driven wander, 1 s memory)",
        alarm - guard
    );
    assert!(err_a < 0.02, "A not identified: {err_a}");
    assert!(alarm - guard < 200, "alarm too late: {alarm}");
    assert!(
        first5 < 2.0 && t10 < 3.0,
        "not re-converged: {first5} s, {t10} s"
    );
    assert!(worst_late < 0.08, "{worst_late}");
}

/// Non-finite samples are rejected and counted; the state is bit-identical afterwards.
#[test]
fn non_finite_samples_rejected() {
    let data = typical_data(2.0);
    let mut rls = Rls::new(config(no_friction(true), ColumnScales::UNIT, 0.999, 1e6)).unwrap();
    learn_all(&mut rls, &data);
    let before = state_bits(&rls);
    let good = data[data.len() - 1];
    let mut bad = Vec::new();
    for v in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        for i in rls.columns().indices() {
            let mut psi = good.psi;
            psi[i] = v;
            bad.push((psi, good.y));
        }
        bad.push((good.psi, v));
    }
    for (psi, y) in &bad {
        assert_eq!(rls.update(psi, *y, Mode::Learn), Outcome::RejectedNonFinite);
    }
    assert_eq!(state_bits(&rls), before);
    assert_eq!(rls.counts().rejected_non_finite, bad.len() as u64);
    // Inactive columns are ignored, finite or not (g, h are not in this structure).
    let mut psi = good.psi;
    psi[col::G] = f64::NAN;
    assert!(matches!(
        rls.update(&psi, good.y, Mode::Learn),
        Outcome::Updated { .. }
    ));
}

#[test]
fn invalid_configs_are_named() {
    let base = RlsConfig::default();
    let err = |c: RlsConfig| Rls::new(c).unwrap_err();
    assert_eq!(
        err(RlsConfig {
            columns: Columns::NONE,
            ..base
        }),
        RlsError::NoColumns
    );
    for (cfg, field) in [
        (
            RlsConfig {
                forgetting: 1.5,
                ..base
            },
            "forgetting",
        ),
        (
            RlsConfig {
                forgetting: f64::NAN,
                ..base
            },
            "forgetting",
        ),
        (
            RlsConfig {
                initial_covariance: 2e3,
                ..base
            },
            "initial_covariance",
        ),
        (
            RlsConfig {
                scales: ColumnScales([0.0; N]),
                ..base
            },
            "scales",
        ),
        (
            RlsConfig {
                cusum: CusumConfig {
                    clip: 1.0,
                    ..base.cusum
                },
                ..base
            },
            "cusum.clip",
        ),
    ] {
        match err(cfg) {
            RlsError::Field { field: f, .. } => assert_eq!(f, field),
            other => panic!("{other:?}"),
        }
    }
    let msg = err(RlsConfig {
        forgetting: 1.5,
        ..base
    })
    .to_string();
    assert!(
        msg.contains("forgetting") && msg.contains("1.5") && msg.contains("(0, 1]"),
        "{msg}"
    );
    let mut rls = Rls::new(base).unwrap();
    assert!(rls.reset(-1.0).is_err() && rls.reset(1e9).is_err() && rls.reset(10.0).is_ok());
}

#[test]
fn scales_are_powers_of_two() {
    let s = ColumnScales::exp1();
    for v in s.0 {
        assert_eq!(v.log2().fract(), 0.0, "{v}");
    }
    assert!(ColumnScales::for_excitation(0.0, 1.0, 1.0).is_none());
}

/// Regressions of a spring-mounted object in two contact episodes: the second begins `x0` away
/// from where the ground spring rests, so its measured positions are shifted by `x0` (the SVF's
/// DC gain is 1: `ψ_d = −x_f` shifts by `−x0`, its derivatives not at all). Each row carries its
/// axis' constant column.
fn two_episodes(x0: f64) -> (Vec<Regression>, Vec<Regression>) {
    let object = typical();
    let first = regressions(&object, &typical_excitation(), 0.0, 10.0, false);
    let mut second = regressions(&object, &typical_excitation(), 20.0, 10.0, false);
    for r in &mut second {
        r.psi[col::D] -= x0;
    }
    let axis0 = |v: Vec<Regression>| v.into_iter().map(|r| r.with_constant(0)).collect();
    (axis0(first), axis0(second))
}

/// Issue 12, the spring-mounted object: a contact that begins away from the ground spring's
/// rest adds `d·x0` to the force, which no physical column can represent. Without a constant
/// column θ is bent to absorb it; with one, restarted at the second onset, θ is exact — and
/// the restart leaves the other coefficients' covariance as it was.
#[test]
fn spring_mounted_offset_per_episode_is_absorbed_by_the_intercept() {
    let object = typical();
    assert!(object.k_ground_n_per_m > 0.0);
    let truth = object.theta().unwrap().0;
    let cols = no_friction(true);
    let (first, second) = two_episodes(0.02);
    let scales = typical_scales();

    let mut plain = Rls::new(config(cols, scales, 0.9995, 1e3)).unwrap();
    learn_all(&mut plain, &first);
    learn_all(&mut plain, &second);
    let bent = active_rel_error(&plain.theta(), &truth, cols);

    let with = cols.with(col::I).with(col::J);
    let mut rls = Rls::new(config(with, scales, 0.9995, 1e3)).unwrap();
    learn_all(&mut rls, &first);
    let before = rls.covariance();
    let d = rls.theta().0[col::D];
    let onset = -d * second[0].psi[col::D];
    rls.reset_intercepts([onset, f64::NAN], 1e3);
    let after = rls.covariance();
    for a in cols.indices() {
        for c in cols.indices() {
            let (x, y) = (before[(a, c)], after[(a, c)]);
            assert!(
                (x - y).abs() <= 1e-9 * (x.abs() + y.abs()) + 1e-300,
                "P[{a},{c}] {x} → {y}"
            );
        }
        assert_eq!(
            after[(a, col::I)],
            0.0,
            "cross-covariance with i kept at {a}"
        );
    }
    learn_all(&mut rls, &second);
    let err = active_rel_error(&rls.theta(), &truth, cols);
    eprintln!("offset 2 cm: θ error without intercept {bent:.2e}, with {err:.2e}");
    assert!(
        bent > 0.05,
        "without an intercept θ should be bent, error {bent}"
    );
    assert!(err < 1e-3, "with the intercept θ error {err}");
    let i = rls.theta().0[col::I];
    let want = truth[col::D] * 0.02;
    assert!(
        (i - want).abs() < 1e-3 * want,
        "intercept {i} vs d·x0 {want}"
    );
}

/// The information the RLS reports is the data's: `δᵀP⁻¹δ` is how much worse `θ̂ + δ` predicts
/// the very data it was learnt from (λ = 1, a weak prior), and the output energy is `Σ y²`.
#[test]
fn information_distance_is_the_added_squared_error_on_the_data() {
    let cols = no_friction(true);
    let data = typical_data(5.0);
    let mut rls = Rls::new(config(cols, typical_scales(), 1.0, 1e6)).unwrap();
    learn_all(&mut rls, &data);
    let info = rls.information().unwrap();
    let theta = rls.theta().0;
    let sse = |t: &[f64; col::COUNT]| -> f64 {
        data.iter()
            .map(|r| {
                let p: f64 = (0..col::COUNT).map(|i| r.psi[i] * t[i]).sum();
                (r.y - p).powi(2)
            })
            .sum()
    };
    let energy: f64 = data.iter().map(|r| r.y * r.y).sum();
    assert!((info.output_energy() - energy).abs() < 1e-9 * energy);
    for (k, scale) in [(0usize, 0.01), (3, 0.03), (5, -0.02)] {
        let mut delta = [0.0; col::COUNT];
        for i in cols.indices() {
            delta[i] = scale * theta[i] * if (i + k) % 2 == 0 { 1.0 } else { -0.5 };
        }
        let moved: [f64; col::COUNT] = std::array::from_fn(|i| theta[i] + delta[i]);
        let want = sse(&moved) - sse(&theta);
        let got = info.distance2(&delta);
        assert!(
            (got - want).abs() < 1e-4 * want,
            "δ {k}: information {got} vs added error {want}"
        );
        let rel = info.relative(&delta);
        assert!((rel - (want / energy).sqrt()).abs() < 1e-4 * rel);
    }
}

/// A discount by ρ between two blocks of data is least squares with the first block (and the
/// prior) weighted by ρ: λ = 1, exact against the weighted batch solve.
#[test]
fn a_discount_is_least_squares_with_the_data_before_it_weighted() {
    let cols = no_friction(true);
    let data = typical_data(20.0);
    let (before, after) = data.split_at(data.len() / 2);
    let scales = typical_scales();
    let (p0, rho) = (1e3, 0.3);
    let mut rls = Rls::new(config(cols, scales, 1.0, p0)).unwrap();
    learn_all(&mut rls, before);
    rls.discount(rho);
    learn_all(&mut rls, after);
    let w = rho.sqrt();
    let rows: Vec<_> = before
        .iter()
        .map(|r| r.psi.map(|v| v * w))
        .chain(after.iter().map(|r| r.psi))
        .collect();
    let ys: Vec<_> = before
        .iter()
        .map(|r| r.y * w)
        .chain(after.iter().map(|r| r.y))
        .collect();
    let want = batch_ls(&rows, &ys, cols, &scales.0, p0 / rho);
    let err = active_rel_error(&rls.theta(), &want, cols);
    assert!(
        err < 1e-6,
        "RLS with a discount against weighted batch LS: {err:e}"
    );
    // Without it the first block counts fully: a different answer.
    let plain = batch_ls(
        &data.iter().map(|r| r.psi).collect::<Vec<_>>(),
        &data.iter().map(|r| r.y).collect::<Vec<_>>(),
        cols,
        &scales.0,
        p0,
    );
    assert!(active_rel_error(&Theta(plain), &want, cols) > 1e3 * err.max(1e-12));
}

/// A discount never takes the covariance past the bound the forgetting keeps (`tr P ≤ n·p̄`),
/// and a factor outside (0, 1) changes nothing.
#[test]
fn a_discount_is_bounded_and_garbage_factors_change_nothing() {
    let cols = no_friction(true);
    let data = typical_data(2.0);
    let mut rls = Rls::new(config(cols, typical_scales(), 0.999, 1e3)).unwrap();
    learn_all(&mut rls, &data);
    let bits = state_bits(&rls);
    for rho in [f64::NAN, 0.0, -0.5, 1.0, 2.0, f64::INFINITY] {
        rls.discount(rho);
        assert_eq!(state_bits(&rls), bits, "ρ = {rho}");
    }
    let theta = rls.theta();
    let n = cols.indices().count() as f64;
    rls.discount(1e-300);
    assert!(rls.trace() <= n * 1e3 * (1.0 + 1e-12), "{}", rls.trace());
    assert!(rls.trace() > n * 1e3 * (1.0 - 1e-9));
    assert_eq!(rls.theta(), theta);
}
