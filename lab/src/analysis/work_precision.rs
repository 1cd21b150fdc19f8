//! `mmt work-precision`: error against run time for each integrator and step size (numerics notes
//! §9; Hairer & Wanner's work–precision diagrams).
//!
//! Each problem drives the model with a three-tone tool motion (1, 3.1, 7.7 Hz; 10, 4, 1 mm) for
//! 2 s from rest. The input reaches each method as samples at its own step instants, linearly
//! interpolated within a step — what a renderer running at that rate has. The error is the RMS of
//! the force error at the step instants relative to the RMS force, against the exact solution
//! ([`mmt::render::reference`]: closed form for the linear problems, event-located piecewise
//! closed form with friction), which is accurate to rounding. The cost is measured (the caller
//! passes the clock; this module reads none): median over repeats of the time per step, stepping
//! and output only. A run whose force grows beyond 1000× the reference is reported unstable with
//! no error figure.

use mmt::model::Physical;
use mmt::render::integrators::Method;
use mmt::render::reference::{FrictionReference, LinearReference, Multisine, Tone};
use serde::Serialize;

/// One point of the diagram.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Point {
    /// Problem name.
    pub problem: &'static str,
    /// Method name.
    pub method: &'static str,
    /// Step [s].
    pub step_s: f64,
    /// RMS relative force error; `None` when unstable.
    pub rms_rel_error: Option<f64>,
    /// Measured cost per step [ns].
    pub ns_per_step: f64,
    /// Whether the run stayed bounded.
    pub stable: bool,
}

/// The report: `{"points":[…]}`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WorkPrecisionReport {
    /// Every (problem, method, step), unstable ones included.
    pub points: Vec<Point>,
}

/// A test problem.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Problem {
    /// Report name.
    pub name: &'static str,
    /// Parameters (friction only in the stick–slip problem).
    pub params: Physical,
}

/// The five problems of the study.
pub fn problems() -> [Problem; 5] {
    let p = Physical::new;
    [
        Problem {
            name: "typical",
            params: p(0.5, 200.0, 5.0, 2000.0, 10.0, 0.0),
        },
        Problem {
            name: "thesis-exp1",
            params: p(1.0, 0.0, 60.0, 500.0, 60.0, 0.0),
        },
        Problem {
            name: "stiff",
            params: p(0.01, 0.0, 0.0, 1e5, 1.0, 0.0),
        },
        Problem {
            name: "near-massless",
            params: p(1e-6, 200.0, 5.0, 2000.0, 10.0, 0.0),
        },
        Problem {
            name: "stick-slip",
            params: p(1.0, 0.0, 2.0, 500.0, 5.0, 1.0),
        },
    ]
}

/// Steps from 1/250 s to 1/16000 s.
pub const STEPS_S: [f64; 7] = [
    1.0 / 250.0,
    1.0 / 500.0,
    1.0 / 1000.0,
    1.0 / 2000.0,
    1.0 / 4000.0,
    1.0 / 8000.0,
    1.0 / 16000.0,
];

/// Simulated horizon [s].
pub const HORIZON_S: f64 = 2.0;

/// The tool motion of every problem.
pub fn input() -> Multisine {
    let w = 2.0 * std::f64::consts::PI;
    Multisine(vec![
        Tone {
            amplitude_m: 0.010,
            omega_rad_s: w,
            phase_rad: 0.0,
        },
        Tone {
            amplitude_m: 0.004,
            omega_rad_s: 3.1 * w,
            phase_rad: 0.3,
        },
        Tone {
            amplitude_m: 0.001,
            omega_rad_s: 7.7 * w,
            phase_rad: 1.1,
        },
    ])
}

/// Runs the whole study. `clock_ns` returns a monotonic time in nanoseconds; `repeats` timed runs
/// per point (the median is reported).
pub fn work_precision(clock_ns: &mut dyn FnMut() -> u64, repeats: usize) -> WorkPrecisionReport {
    let input = input();
    let mut points = Vec::new();
    for problem in problems() {
        let p = problem.params;
        let reference: Box<dyn Fn(f64) -> f64> = if p.coulomb_n > 0.0 {
            let r = FrictionReference::new(&p, input.clone(), HORIZON_S);
            Box::new(move |t| r.force(t))
        } else {
            let r = LinearReference::new(&p, input.clone(), [0.0, 0.0]);
            Box::new(move |t| r.force(t))
        };
        for h in STEPS_S {
            let n = (HORIZON_S / h).round() as usize;
            let samples: Vec<[f64; 2]> = (0..=n).map(|k| input.input(k as f64 * h)).collect();
            let exact: Vec<f64> = (1..=n).map(|k| reference(k as f64 * h)).collect();
            for method in Method::ALL {
                let mut forces = vec![0.0; n];
                run(method, &p, h, &samples, &mut forces);
                let (stable, err) = score(&forces, &exact);
                let ns_per_step = time_per_step(clock_ns, repeats, n, || {
                    run(method, &p, h, &samples, &mut forces)
                });
                points.push(Point {
                    problem: problem.name,
                    method: method.name(),
                    step_s: h,
                    rms_rel_error: stable.then_some(err),
                    ns_per_step,
                    stable,
                });
            }
        }
    }
    WorkPrecisionReport { points }
}

/// Steps `method` through the sampled input, writing the force at each step instant.
pub fn run(method: Method, p: &Physical, h: f64, samples: &[[f64; 2]], forces: &mut [f64]) {
    let mm = p.mass_matrix_form();
    let mut stepper = method.stepper(&mm, h);
    let mut z = [0.0, 0.0];
    for (k, f) in forces.iter_mut().enumerate() {
        let (u0, u1) = (samples[k], samples[k + 1]);
        z = stepper.step(z, u0, u1);
        *f = mm.force_on_tool(z, u1);
    }
}

/// `(stable, rms relative error)`.
fn score(forces: &[f64], exact: &[f64]) -> (bool, f64) {
    let max_ref = exact.iter().fold(0.0f64, |m, f| m.max(f.abs()));
    let stable = forces
        .iter()
        .all(|f| f.is_finite() && f.abs() <= 1e3 * max_ref);
    let (e2, r2) = forces.iter().zip(exact).fold((0.0, 0.0), |(e, r), (f, x)| {
        (e + (f - x) * (f - x), r + x * x)
    });
    (stable, (e2 / r2).sqrt())
}

/// Median over `repeats` of the time per step, each measurement long enough (≥ 2 ms) for the
/// clock's resolution not to matter.
fn time_per_step(
    clock_ns: &mut dyn FnMut() -> u64,
    repeats: usize,
    steps: usize,
    mut work: impl FnMut(),
) -> f64 {
    let t0 = clock_ns();
    work();
    let once = (clock_ns() - t0).max(1);
    let inner = (2_000_000 / once).clamp(1, 10_000) as usize;
    let mut samples: Vec<f64> = (0..repeats.max(1))
        .map(|_| {
            let t0 = clock_ns();
            for _ in 0..inner {
                work();
            }
            (clock_ns() - t0) as f64 / (inner * steps) as f64
        })
        .collect();
    samples.sort_by(f64::total_cmp);
    samples[samples.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn error_of(method: Method, problem: &str, h: f64) -> (bool, f64) {
        let p = problems()
            .into_iter()
            .find(|p| p.name == problem)
            .unwrap()
            .params;
        let input = input();
        let n = (HORIZON_S / h).round() as usize;
        let samples: Vec<[f64; 2]> = (0..=n).map(|k| input.input(k as f64 * h)).collect();
        let r = LinearReference::new(&p, input.clone(), [0.0, 0.0]);
        let exact: Vec<f64> = (1..=n).map(|k| r.force(k as f64 * h)).collect();
        let mut forces = vec![0.0; n];
        run(method, &p, h, &samples, &mut forces);
        score(&forces, &exact)
    }

    #[test]
    fn explicit_methods_are_unstable_on_the_stiff_set_at_1khz_and_implicit_ones_are_not() {
        for m in [Method::ExplicitEuler, Method::Rk4] {
            assert!(!error_of(m, "stiff", 1e-3).0, "{m:?}");
        }
        for m in [Method::Trapezoid, Method::BackwardEuler, Method::Sdirk2] {
            assert!(error_of(m, "stiff", 1e-3).0, "{m:?}");
        }
    }

    #[test]
    fn second_order_error_falls_four_times_per_halving_on_the_thesis_set() {
        for m in [Method::Sdirk2, Method::Trapezoid, Method::ExactFoh] {
            let (_, e1) = error_of(m, "thesis-exp1", 1.0 / 2000.0);
            let (_, e2) = error_of(m, "thesis-exp1", 1.0 / 4000.0);
            assert!((e1 / e2 - 4.0).abs() < 0.6, "{m:?}: {e1} / {e2}");
        }
    }

    #[test]
    fn fake_clock_gives_a_report_with_every_point() {
        // Each reading advances 10 ms: every measurement is "long enough" after one run.
        let mut t = 0u64;
        let mut clock = move || {
            t += 10_000_000;
            t
        };
        let report = work_precision(&mut clock, 1);
        assert_eq!(report.points.len(), 5 * 6 * STEPS_S.len());
        assert!(report.points.iter().any(|p| !p.stable));
        assert!(
            report
                .points
                .iter()
                .all(|p| p.stable == p.rms_rel_error.is_some())
        );
    }
}
