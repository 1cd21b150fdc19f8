//! The first fit against exact answers, noise, bad data and a changed object.

use super::super::{AxisSample, Estimator, EstimatorConfig, EstimatorError, ResetPolicy};
use super::*;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64;

const H: f64 = 1e-3;
const K: f64 = 800.0;
const B: f64 = 12.0;

/// A press into the surface from 0.1 s: an approach to 4 mm depth (a first-order rise,
/// 30 ms) with a 2 Hz wobble of 0.5 mm; the position is the signed distance (negative inside).
fn press(t: f64) -> (f64, f64) {
    if t < 0.1 {
        return (0.001, -0.05);
    }
    let (s, w) = (t - 0.1, 2.0 * std::f64::consts::PI * 2.0);
    let x = -0.004 * (1.0 - (-s / 0.03).exp()) - 0.0005 * (w * s).sin();
    let v = -0.004 / 0.03 * (-s / 0.03).exp() - 0.0005 * w * (w * s).cos();
    (x, v)
}

/// Runs `seconds` of a press whose force on the tool is `−(k x + b ẋ)` plus `noise_n` of
/// white noise: every update, with its time.
fn run(config: EstimatorConfig, k: f64, b: f64, noise_n: f64, seconds: f64) -> Estimator {
    let mut est = Estimator::new(config).unwrap();
    let mut rng = Pcg64::seed_from_u64(3);
    let noise = Normal::new(0.0, noise_n.max(1e-300)).unwrap();
    for i in 0..(seconds / H).round() as usize {
        let t = i as f64 * H;
        let (x, v) = press(t);
        let in_contact = x < 0.0;
        let f = if in_contact { -(k * x + b * v) } else { 0.0 };
        let f = f + if noise_n > 0.0 {
            noise.sample(&mut rng)
        } else {
            0.0
        };
        let s = AxisSample {
            position_m: x,
            velocity_m_per_s: v,
            force_n: f,
        };
        let u = est.step(t, &[s], in_contact);
        if let Some(g) = u.confirmed {
            let kv = g.kelvin_voigt().unwrap();
            FIRST.with(|v| v.borrow_mut().push((t, kv, est.stats())));
        }
    }
    est
}

thread_local! {
    static FIRST: std::cell::RefCell<Vec<(f64, KelvinVoigt, super::super::EstimatorStats)>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

fn published() -> Vec<(f64, KelvinVoigt, super::super::EstimatorStats)> {
    FIRST.with(|v| std::mem::take(&mut *v.borrow_mut()))
}

fn kelvin_voigt() -> EstimatorConfig {
    EstimatorConfig::new(Structure::KelvinVoigt, 1)
}

/// Against the exact answer: noise-free data give `k` and `b` to rounding within 0.1 s of
/// contact; the set is published once (later solves agree), and never after the RLS's own
/// set is confirmed.
#[test]
fn a_pressed_kelvin_voigt_contact_is_published_exactly_within_a_tenth_of_a_second() {
    let est = run(kelvin_voigt(), K, B, 0.0, 3.0);
    let sets = published();
    let (t, kv, stats) = sets[0];
    assert!(t - 0.1 <= 0.1, "first set at {t} s");
    assert_eq!(stats.first_fits, 1);
    assert!((kv.k_n_per_m / K - 1.0).abs() < 1e-9, "{kv:?}");
    assert!((kv.b_ns_per_m / B - 1.0).abs() < 1e-9, "{kv:?}");
    let s = est.stats();
    assert!(s.confirmed > 0, "the RLS confirms later: {s:?}");
    assert_eq!(s.first_fits, 1, "{s:?}");
    // Contact from the first tick inside (0.101 s).
    let after = s.first_fit_after_s.unwrap();
    assert!(
        (after - (t - 0.101)).abs() < 1e-9,
        "{after} after onset, set at {t} s"
    );
    assert!(sets[1..].iter().all(|(_, _, s)| s.first_fits == 1));
}

/// With force noise the set waits until the motion pins both terms down, and is then within
/// a few percent of the truth.
#[test]
fn a_noisy_force_publishes_a_set_close_to_the_truth() {
    run(kelvin_voigt(), K, B, 0.05, 1.0);
    let (t, kv, _) = published()[0];
    assert!(t - 0.1 <= 0.15, "first set at {t} s");
    assert!((kv.k_n_per_m / K - 1.0).abs() < 0.03, "{kv:?}");
    assert!((kv.b_ns_per_m / B - 1.0).abs() < 0.15, "{kv:?}");
}

/// No set from data that cannot give one: an active law (a pull, `k < 0`), a still hold
/// (no `ẋ` to tell `b` from `k`), pure noise, or a sliding object's structure.
#[test]
fn an_active_law_a_still_hold_noise_or_a_sliding_object_publish_no_first_fit() {
    let pull = run(kelvin_voigt(), -K, B, 0.0, 0.3);
    assert_eq!(pull.stats().first_fits, 0);
    assert!(pull.stats().first_fit_rejections > 0);
    let noise = run(kelvin_voigt(), 0.0, 0.0, 0.5, 0.3);
    assert_eq!(noise.stats().first_fits, 0);
    let sliding = Structure::SlidingMass {
        ground_spring: false,
        friction: true,
    };
    let slide = run(EstimatorConfig::new(sliding, 1), K, B, 0.0, 0.3);
    assert_eq!(slide.stats().first_fits, 0);
    published();
    let mut fit = FirstFit::default();
    fit.restart(0.0, None);
    for _ in 0..100 {
        fit.push(-0.004, 0.0, 3.2);
    }
    let config = FirstFitConfig::default();
    let solved = fit.solve(&config, &GateConfig::default());
    assert_eq!(solved, Err(Withheld::NotExcited));
    let mut off = kelvin_voigt();
    off.first_fit.enabled = false;
    assert_eq!(run(off, K, B, 0.0, 0.3).stats().first_fits, 0);
}

/// A stiff, barely damped contact whose force lags the position by 1 ms (a sensor's delay):
/// the free fit's damping is `b − k·τ` < 0; the set published holds b at 0 and keeps k.
#[test]
fn a_lagging_force_on_a_stiff_contact_gives_no_damping_not_negative_damping() {
    let (k, b, lag) = (2_000.0, 0.5, 1e-3);
    let mut fit = FirstFit::default();
    fit.restart(0.0, None);
    let mut t = 0.1;
    while t < 0.2 {
        let (x, v) = press(t);
        let (xl, vl) = press(t - lag);
        fit.push(x, v, -(k * xl + b * vl));
        t += H;
    }
    let free = fit.sums;
    let det = free.xx * free.vv - free.xv * free.xv;
    assert!(
        (free.xx * free.vf - free.xv * free.xf) / det < 0.0,
        "the free fit's b"
    );
    let config = FirstFitConfig::default();
    let gates = GateConfig::default();
    // The first solve only primes the check of stillness.
    assert_eq!(fit.solve(&config, &gates), Err(Withheld::Moving));
    let kv = fit.solve(&config, &gates).unwrap().kelvin_voigt().unwrap();
    assert_eq!(kv.b_ns_per_m, 0.0);
    assert!((kv.k_n_per_m / k - 1.0).abs() < 0.02, "{kv:?}");
}

/// Two presses: the first object from 0.1 s to 1.6 s, then `second_k` from 2.0 s to 4.0 s.
/// The updates' times and sets after the second onset, and the estimator.
fn re_touch(second_k: f64) -> (Vec<(f64, bool, Option<KelvinVoigt>)>, Estimator) {
    re_touch_with(kelvin_voigt(), second_k, 0.0, 0.0)
}

/// [`re_touch`] with `config`, force noise `noise_n` [N] and the force lagging the position by
/// `lag_s`.
fn re_touch_with(
    config: EstimatorConfig,
    second_k: f64,
    noise_n: f64,
    lag_s: f64,
) -> (Vec<(f64, bool, Option<KelvinVoigt>)>, Estimator) {
    let mut est = Estimator::new(config).unwrap();
    let mut rng = Pcg64::seed_from_u64(7);
    let noise = Normal::new(0.0, noise_n.max(1e-300)).unwrap();
    let motion = |t: f64| match t {
        t if t < 1.6 => (K, press(t)),
        t if t < 2.0 => (K, (0.001, 0.0)),
        t => (second_k, press(t - 1.9)),
    };
    let mut after = Vec::new();
    for i in 0..4_000 {
        let t = i as f64 * H;
        let (_, (x, v)) = motion(t);
        let (k, (xl, vl)) = motion(t - lag_s);
        let in_contact = x < 0.0;
        let force_n = if in_contact {
            -(k * xl + B * vl) + noise_n.min(1.0) * noise.sample(&mut rng)
        } else {
            0.0
        };
        let s = AxisSample {
            position_m: x,
            velocity_m_per_s: v,
            force_n,
        };
        let u = est.step(t, &[s], in_contact);
        if t >= 2.0 {
            after.push((t, u.new_object, u.confirmed.and_then(|g| g.kelvin_voigt())));
        }
    }
    (after, est)
}

/// The same object re-touched with sensor noise and a force lagging the position by 1 ms is not
/// declared new; under [`ResetPolicy::EveryOnset`] (a new model at every onset, the thesis's
/// way) the re-touch is fitted and published again, counted once.
#[test]
fn a_noisy_lagging_re_touch_of_the_same_object_is_the_same_object() {
    let (after, est) = re_touch_with(kelvin_voigt(), K, 0.05, 1e-3);
    assert!(after.iter().all(|u| !u.1), "{:?}", est.stats());
    assert_eq!(est.stats().first_fit_new_objects, 0);
    let mut every = kelvin_voigt();
    every.reset = ResetPolicy::EveryOnset;
    let (after, est) = re_touch_with(every, K, 0.05, 1e-3);
    let s = est.stats();
    assert_eq!(
        (s.onset_resets, s.new_objects, s.first_fit_new_objects),
        (1, 0, 0),
        "{s:?}"
    );
    let (t_fit, _, kv) = after.iter().find(|u| u.2.is_some()).unwrap();
    assert!(
        t_fit - 2.001 <= 0.1,
        "re-fitted {:.3} s after the onset",
        t_fit - 2.001
    );
    // The 1 ms lag biases the first 30 ms's set (`FirstFitConfig::min_window_s`).
    assert!((kv.unwrap().k_n_per_m / K - 1.0).abs() < 0.1, "{kv:?}");
}

/// Issue 13 item 4, for a Kelvin–Voigt group: a different object at the same place (three
/// times stiffer) is declared new by the re-contact's first fit and rendered from it within
/// 0.1 s of its onset (with the prediction-error detector alone it was never declared new,
/// and the old model adapted by forgetting took 1.9 s to come within 10 %); the same object
/// re-touched keeps its model and publishes no first fit.
#[test]
fn a_different_object_at_the_same_place_is_declared_new_by_its_first_fit() {
    let (after, est) = re_touch(3.0 * K);
    let (t_new, ..) = after.iter().find(|u| u.1).expect("a new object");
    let (t_fit, _, kv) = after.iter().find(|u| u.2.is_some()).unwrap();
    let kv = kv.unwrap();
    assert_eq!(t_fit, t_new, "declared with its set");
    assert!(
        t_fit - 2.001 <= 0.1,
        "fitted {:.3} s after its onset",
        t_fit - 2.001
    );
    assert!((kv.k_n_per_m / (3.0 * K) - 1.0).abs() < 1e-6, "{kv:?}");
    let s = est.stats();
    assert_eq!((s.new_objects, s.first_fit_new_objects), (1, 1), "{s:?}");
    let (after, same) = re_touch(K);
    assert!(after.iter().all(|u| !u.1), "the same object is not new");
    let s = same.stats();
    assert_eq!((s.new_objects, s.first_fits), (0, 1), "{s:?}");
}

#[test]
fn a_bad_threshold_is_named() {
    let mut c = kelvin_voigt();
    c.first_fit.max_residual = f64::NAN;
    match Estimator::new(c) {
        Err(EstimatorError::Field { field, .. }) => assert_eq!(field, "first_fit.max_residual"),
        other => panic!("{other:?}"),
    }
    c.first_fit.max_residual = 0.15;
    c.first_fit.min_window_s = -1.0;
    assert!(Estimator::new(c).is_err());
}
