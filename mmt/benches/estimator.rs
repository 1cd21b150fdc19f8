//! The telerobot's per-sample estimator cost: regressor filter (6th-order SVF on x, F, σ) plus a
//! Bierman U-D RLS update, for the 7-column exp-1 structure. Target ≤ 1 µs median per sample.
//!
//! Inputs are a recorded 10 s of the simulated exp-1 scene with Franka-like noise, replayed
//! cyclically so every iteration sees a fresh, realistic sample.

// A benchmark: a broken set-up should stop it loudly.
#![allow(clippy::unwrap_used)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use mmt::filter::{RegressorConfig, RegressorFilter};
use mmt::rls::{Mode, Rls, RlsConfig};
use mmt::sim::{SensorNoise, SimConfig, SlidingObjectSim};
use rand::SeedableRng;
use rand_pcg::Pcg64;

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

criterion_group!(benches, estimator);
criterion_main!(benches);
