//! Hot paths of the operator and telerobot besides the estimator update: one renderer tick
//! (target ≤ 100 ns median) and one back-solve with gates (target ≤ 50 µs median).

// A benchmark: a broken set-up should stop it loudly.
#![allow(clippy::unwrap_used)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use mmt::model::backsolve::{BackSolveConfig, Params, back_solve};
use mmt::model::gates::{GateConfig, gate, gate_physical};
use mmt::model::{Physical, Structure, Theta};
use mmt::render::{RendererConfig, SlidingMassRenderer};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64;

const EXP1: Structure = Structure::SlidingMass {
    ground_spring: false,
    friction: true,
};
const FULL: Structure = Structure::SlidingMass {
    ground_spring: true,
    friction: true,
};

fn renderer(c: &mut Criterion) {
    let mut r = SlidingMassRenderer::new(RendererConfig::default()).unwrap();
    r.set_target(&gate_physical(EXP1, &Params::SlidingMass(Physical::THESIS_EXP1)).unwrap());
    // Precomputed input so the bench measures the renderer, not sin/cos.
    let w = 2.0 * std::f64::consts::PI * 1.3;
    let input: Vec<(f64, f64)> = (0..4096)
        .map(|k| {
            let t = k as f64 * 1e-3;
            (0.02 * (w * t).sin(), 0.02 * w * (w * t).cos())
        })
        .collect();
    let mut k = 0usize;
    c.bench_function("renderer step (exp-1, in contact, friction)", |b| {
        b.iter(|| {
            let (x, v) = input[k & 4095];
            k += 1;
            black_box(r.step(black_box(x), black_box(v), true))
        })
    });
}

/// θ of a set with 1 % relative noise, as the estimator delivers it.
fn noisy_thetas(p: &Physical, n: usize) -> Vec<Theta> {
    let mut rng = Pcg64::seed_from_u64(5);
    let noise = Normal::new(0.0, 0.01).unwrap();
    (0..n)
        .map(|_| {
            let mut t = p.theta().unwrap();
            for v in t.0.iter_mut() {
                *v *= 1.0 + noise.sample(&mut rng);
            }
            t
        })
        .collect()
}

fn back_solves(c: &mut Criterion) {
    let exp1 = noisy_thetas(&Physical::THESIS_EXP1, 256);
    let full = noisy_thetas(&Physical::TYPICAL, 256);
    let cfg = BackSolveConfig::default();
    let gates = GateConfig::default();
    let mut k = 0usize;
    c.bench_function("back-solve exp-1 structure (7 coefficients)", |b| {
        b.iter(|| {
            k += 1;
            black_box(back_solve(EXP1, black_box(&exp1[k & 255]), None, &cfg))
        })
    });
    c.bench_function("back-solve full structure (8 coefficients)", |b| {
        b.iter(|| {
            k += 1;
            black_box(back_solve(FULL, black_box(&full[k & 255]), None, &cfg))
        })
    });
    c.bench_function("gates incl. back-solve, full structure", |b| {
        b.iter(|| {
            k += 1;
            black_box(gate(FULL, black_box(&full[k & 255]), None, &gates))
        })
    });
}

criterion_group!(benches, renderer, back_solves);
criterion_main!(benches);
