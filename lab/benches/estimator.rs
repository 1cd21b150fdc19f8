//! The telerobot's per-sample estimator cost: regressor filter (6th-order SVF on x, F, σ) plus a
//! Bierman U-D RLS update, for the 7-column exp-1 structure. Target ≤ 1 µs median per sample.
//! And the whole [`Estimator::step`] as the telerobot calls it: finite check, tare, filters, RLS,
//! and every 10 ms the back-solve, gates and confidence gate (amortised over the ticks), plus the
//! same with a back-solve on every tick (the cost of a tick that back-solves). And the whole
//! set's informed back-solve beside the massless one (the reduced first model), and a tick of
//! the first contact while the sliding first fit iterates.
//!
//! Inputs are a recorded 10 s of the simulated exp-1 scene with Franka-like noise, replayed
//! cyclically so every iteration sees a fresh, realistic sample.

// A benchmark: a broken set-up should stop it loudly.
#![allow(clippy::unwrap_used)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use mmt::estimator::{AxisSample, Estimator, EstimatorConfig};
use mmt::filter::{RegressorConfig, RegressorFilter};
use mmt::model::Structure;
use mmt::model::backsolve::{BackSolveConfig, back_solve_informed, back_solve_massless};
use mmt::rls::{Mode, Rls, RlsConfig};
use rand::SeedableRng;
use rand_pcg::Pcg64;
use sim::trajectory::Multisine;
use sim::{SensorNoise, SimConfig, SlidingObjectSim};

fn recorded_samples() -> Vec<[f64; 3]> {
    let cfg = SimConfig {
        noise: SensorNoise::FRANKA_LIKE,
        ..SimConfig::THESIS_EXP1
    };
    let motion = |t: f64| {
        let w = 2.0 * std::f64::consts::PI;
        let (x, v) = [(0.3, 0.02), (1.1, 0.008), (2.9, 0.003)]
            .iter()
            .fold((0.0, 0.0), |(x, v), &(f, a)| {
                (x + a * (w * f * t).sin(), v + a * w * f * (w * f * t).cos())
            });
        (x, v)
    };
    let mut sim = SlidingObjectSim::new(cfg, 0.0, motion(0.0).1, Pcg64::seed_from_u64(1)).unwrap();
    (1..=10_000)
        .map(|k| {
            let (x, v) = motion(k as f64 * 1e-3);
            let m = sim.step(x, v, true).measured;
            [m.position_m, m.velocity_m_per_s, m.force_n]
        })
        .collect()
}

fn estimator(c: &mut Criterion) {
    let data = recorded_samples();
    let mut filt = RegressorFilter::new(RegressorConfig::default()).unwrap();
    let mut rls = Rls::new(RlsConfig::default()).unwrap();
    // Warm the estimator up past its start-up transient.
    for s in &data {
        let r = filt.step(s[0], s[1], s[2]);
        let _ = rls.update(&r.psi, r.y, Mode::Learn);
    }
    let mut k = 0;
    c.bench_function("regressor filter + RLS update (7 columns)", |b| {
        b.iter(|| {
            let s = data[k];
            k = (k + 1) % data.len();
            let r = filt.step(black_box(s[0]), black_box(s[1]), black_box(s[2]));
            black_box(rls.update(&r.psi, r.y, Mode::Learn))
        })
    });
    let mut k = 0;
    c.bench_function("regressor filter alone", |b| {
        b.iter(|| {
            let s = data[k];
            k = (k + 1) % data.len();
            black_box(filt.step(black_box(s[0]), black_box(s[1]), black_box(s[2])))
        })
    });
    let regs: Vec<_> = data.iter().map(|s| filt.step(s[0], s[1], s[2])).collect();
    let mut k = 0;
    c.bench_function("RLS update alone (7 columns)", |b| {
        b.iter(|| {
            let r = &regs[k];
            k = (k + 1) % regs.len();
            black_box(rls.update(black_box(&r.psi), black_box(r.y), Mode::Learn))
        })
    });
}

/// The estimator `mmt estimate` runs (exp-1 structure, 5 Hz SVF, λ = 0.9999), past its onset
/// guard and confident.
fn full_estimator(back_solve_period_s: f64) -> Estimator {
    let mut config = EstimatorConfig::new(
        Structure::SlidingMass {
            ground_spring: false,
            friction: true,
        },
        1,
    );
    config.filter.svf.cutoff_hz = 5.0;
    config.forgetting = 0.9999;
    config.back_solve_period_s = back_solve_period_s;
    Estimator::new(config).unwrap()
}

fn sample(s: &[f64; 3]) -> [AxisSample; 1] {
    [AxisSample {
        position_m: s[0],
        velocity_m_per_s: s[1],
        force_n: s[2],
    }]
}

/// What `mmt estimate` feeds the estimator: 0.5 s at rest out of contact (tare), then 40 s of
/// the exp-1 excitation in contact (two of its 20 s periods: the second replays seamlessly).
fn estimate_samples() -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let cfg = SimConfig {
        noise: SensorNoise::FRANKA_LIKE,
        ..SimConfig::THESIS_EXP1
    };
    let excitation = Multisine::exp1_tangential();
    let (x0, v0) = excitation.eval(0.0);
    let mut sim = SlidingObjectSim::new(cfg, x0, v0, Pcg64::seed_from_u64(1)).unwrap();
    let mut measure = |x: f64, v: f64, contact: bool| {
        let m = sim.step(x, v, contact).measured;
        [m.position_m, m.velocity_m_per_s, m.force_n]
    };
    let free = (0..500).map(|_| measure(x0, 0.0, false)).collect();
    let contact = (0..40_000)
        .map(|k| {
            let (x, v) = excitation.eval(k as f64 * 1e-3);
            measure(x, v, true)
        })
        .collect();
    (free, contact)
}

/// [`full_estimator`] tared out of contact and run over the first exp-1 period in contact: past
/// its guard and confident. Returns it, the samples it took, and the second period's samples.
fn warmed_estimator(back_solve_period_s: f64) -> (Estimator, u64, Vec<[f64; 3]>) {
    let (free, mut contact) = estimate_samples();
    let data = contact.split_off(20_000);
    let mut est = full_estimator(back_solve_period_s);
    let mut n = 0u64;
    let samples = free.iter().map(|s| (s, false));
    for (s, in_contact) in samples.chain(contact.iter().map(|s| (s, true))) {
        est.step(n as f64 * 1e-3, &sample(s), in_contact);
        n += 1;
    }
    assert!(est.is_confident(), "not confident after warm-up");
    (est, n, data)
}

fn estimator_step(c: &mut Criterion) {
    for (name, period) in [
        ("Estimator::step (exp-1, back-solve every 10 ms)", 0.01),
        ("Estimator::step (exp-1, back-solve every tick)", 1e-3),
    ] {
        let (mut est, mut n, data) = warmed_estimator(period);
        let mut k = 0;
        c.bench_function(name, |b| {
            b.iter(|| {
                let s = &data[k];
                k = (k + 1) % data.len();
                n += 1;
                black_box(est.step(n as f64 * 1e-3, black_box(&sample(s)), true))
            })
        });
    }
}

/// The whole set's informed back-solve against the massless one the estimator adds while the
/// whole set is not confirmed (both at the back-solve rate, 100 Hz, inside the 1 kHz loop), on
/// the information of the first exp-1 period.
fn back_solves(c: &mut Criterion) {
    let (est, _, _) = warmed_estimator(0.01);
    let (structure, theta) = (est.config().structure, est.theta());
    let info = est.information().unwrap();
    let config = BackSolveConfig::default();
    c.bench_function("back_solve_informed (exp-1, whole set)", |b| {
        b.iter(|| {
            black_box(back_solve_informed(
                structure,
                black_box(&theta),
                &info,
                &config,
            ))
        })
    });
    c.bench_function("back_solve_massless (exp-1, reduced set)", |b| {
        b.iter(|| {
            black_box(back_solve_massless(
                structure,
                black_box(&theta),
                &info,
                &config,
            ))
        })
    });
}

/// A tick of the first contact while the sliding first fit iterates (`mmt::estimator::
/// SlideFitConfig`): one Levenberg–Marquardt iteration over the full 0.4 s window, seven
/// simulations of it (one per term and the axis's onset force, one more) plus the normal
/// equations. Each tick is measured on a copy of the estimator
/// taken just after the full window's solve started (the copy is made outside the timing).
fn slide_fit_tick(c: &mut Criterion) {
    let (free, contact) = estimate_samples();
    let mut config = *full_estimator(0.01).config();
    // Without the contact element's stage, whose solves shift the start of the full window's.
    config.slide_fit.contact_fit_s = config.slide_fit.min_window_s;
    let mut est = Estimator::new(config).unwrap();
    let mut n = 0u64;
    let samples = free.iter().map(|s| (s, false));
    // 0.404 s of contact: the window is full, its solve started at 0.402 s (due 50 ms after the
    // one at 0.352 s) and the tick timed is its second iteration. Solves begun from the last
    // converged set take 3 or 4 iterations.
    for (s, in_contact) in samples.chain(contact[..404].iter().map(|s| (s, true))) {
        est.step(n as f64 * 1e-3, &sample(s), in_contact);
        n += 1;
    }
    let next = contact[404];
    c.bench_function(
        "Estimator::step (exp-1, first contact, sliding fit iterating over 0.4 s)",
        |b| {
            b.iter_batched(
                || est.clone(),
                |mut e| black_box(e.step(n as f64 * 1e-3, black_box(&sample(&next)), true)),
                criterion::BatchSize::SmallInput,
            )
        },
    );
}

criterion_group!(
    benches,
    estimator,
    estimator_step,
    back_solves,
    slide_fit_tick
);
criterion_main!(benches);
