use super::*;

const DT: f64 = 1e-3;

fn object(m: f64, b1: f64, k2: f64, b2: f64, fc: f64) -> Physical {
    Physical {
        mass_kg: m,
        k_ground_n_per_m: 0.0,
        b_ground_ns_per_m: b1,
        k_contact_n_per_m: k2,
        b_contact_ns_per_m: b2,
        coulomb_n: fc,
    }
}

/// The tool pushing into the object along one axis and dragging it: a ramp of `speed` plus a
/// 3 Hz and a 7 Hz wobble, and the model's own force for `p` (with `noise_n` of
/// deterministic pseudo-noise on it).
fn samples(p: &Physical, speed: f64, phase: f64, noise_n: f64, seconds: f64) -> Vec<Sample> {
    loaded_samples(p, false, 0.0, speed, phase, noise_n, seconds)
}

/// [`samples`] of the object `p` (`massless`: with its mass left out) whose contact already
/// carries `onset_n` on the object at the first sample.
fn loaded_samples(
    p: &Physical,
    massless: bool,
    onset_n: f64,
    speed: f64,
    phase: f64,
    noise_n: f64,
    seconds: f64,
) -> Vec<Sample> {
    let n = (seconds / DT).round() as usize;
    let tau = std::f64::consts::TAU;
    let tool: Vec<(f64, f64)> = (0..n)
        .map(|i| {
            let t = i as f64 * DT;
            let (w1, w2) = (tau * 3.0, tau * 7.0);
            let x = speed * t + 0.004 * (w1 * t + phase).sin() + 0.002 * (w2 * t).sin();
            let v = speed + 0.004 * w1 * (w1 * t + phase).cos() + 0.002 * w2 * (w2 * t).cos();
            (x, v)
        })
        .collect();
    let theta = Vector::from([
        p.mass_kg.ln(),
        p.b_ground_ns_per_m.ln(),
        p.k_contact_n_per_m.ln(),
        p.b_contact_ns_per_m.ln(),
        p.coulomb_n.max(1e-9).ln(),
        onset_n,
        0.0,
    ]);
    let model = Model::new(&theta, p.coulomb_n > 0.0, massless, DT);
    let mut forces = Vec::with_capacity(n);
    // With a measured force of 0 each residual is minus the model's force.
    model.residuals(0, tool.iter().map(|&(x, v)| [x, v, 0.0]), &mut |r| {
        forces.push(-r)
    });
    let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
    tool.iter()
        .zip(forces)
        .map(|(&(x, v), f)| {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            let u = (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            [x, v, f + noise_n * 2.0 * u]
        })
        .collect()
}

/// Runs the fit over two axes' samples, tick by tick; the published sets.
fn run(axes: [&[Sample]; 2], friction: bool, config: &SlideFitConfig) -> Vec<Gated> {
    let mut fit = SlideFit::new(config, 2, DT);
    fit.restart(0.0, true, friction);
    let gates = GateConfig::default();
    let mut out = Vec::new();
    for (i, (a, b)) in axes[0].iter().zip(axes[1]).enumerate() {
        if let Outcome::Publish(g) = fit.step(i as f64 * DT, &[*a, *b], config, &gates, DT) {
            out.push(g);
        }
    }
    out
}

/// The defaults with the velocity as given: the model's own data is fitted exactly (the
/// smoothing is 0.23 % off at the test motion's 7 Hz: `m` 2.7 % off on exp 1's object).
fn exact() -> SlideFitConfig {
    SlideFitConfig {
        velocity_smoothing_s: 0.0,
        ..SlideFitConfig::default()
    }
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a / b - 1.0).abs() <= tol
}

fn assert_recovers(p: &Physical, noise_n: f64, tol: f64) {
    let (a, b) = (
        samples(p, 0.03, 0.0, noise_n, 0.5),
        samples(p, -0.02, 1.0, noise_n, 0.5),
    );
    // Every converged solve is published: the last is the whole window's.
    let config = SlideFitConfig {
        republish_change: 1e-9,
        ..exact()
    };
    let published = run([&a, &b], p.coulomb_n > 0.0, &config);
    let last = published.last().and_then(Gated::sliding_mass);
    let Some(q) = last else {
        panic!("nothing published for {p:?}");
    };
    for (name, got, want) in [
        ("m", q.mass_kg, p.mass_kg),
        ("b1", q.b_ground_ns_per_m, p.b_ground_ns_per_m),
        ("k2", q.k_contact_n_per_m, p.k_contact_n_per_m),
        ("b2", q.b_contact_ns_per_m, p.b_contact_ns_per_m),
    ] {
        assert!(close(got, want, tol), "{name}: {got} vs {want} ({q:?})");
    }
    // Friction, as a force against the RMS force (a small `Fc` is a small share of it).
    if p.coulomb_n > 0.0 && noise_n == 0.0 {
        let f_rms = (a.iter().map(|s| s[2] * s[2]).sum::<f64>() / a.len() as f64).sqrt();
        let dfc = (q.coulomb_n - p.coulomb_n).abs() / f_rms;
        assert!(
            dfc <= tol,
            "Fc: {} vs {} ({dfc:.1e} of the RMS force)",
            q.coulomb_n,
            p.coulomb_n
        );
    }
}

#[test]
fn the_fit_recovers_an_exact_object_from_its_first_contact() {
    // The thesis's object, noise-free: the fit is the model's own, so it is exact.
    assert_recovers(&object(1.0, 60.0, 500.0, 60.0, 0.05), 0.0, 1e-3);
    // Without friction: four parameters.
    assert_recovers(&object(1.0, 60.0, 500.0, 60.0, 0.0), 0.0, 1e-3);
}

#[test]
fn the_fit_recovers_stiff_light_and_heavy_soft_objects() {
    // Stiff and light: the mode near 19 Hz.
    assert_recovers(&object(0.2, 20.0, 3000.0, 10.0, 0.3), 0.0, 1e-3);
    // Heavy and soft, with a realistic friction.
    assert_recovers(&object(5.0, 40.0, 200.0, 30.0, 1.0), 0.0, 1e-3);
}

#[test]
fn noise_costs_accuracy_within_the_gates() {
    // 0.05 N of force noise (the Franka-like sensor's order).
    assert_recovers(&object(1.0, 60.0, 500.0, 60.0, 0.05), 0.05, 0.3);
}

/// A tool held still: nothing moves, nothing is identified, nothing is published.
#[test]
fn a_still_tool_publishes_nothing() {
    let still: Vec<Sample> = (0..500).map(|_| [0.01, 0.0, -0.2]).collect();
    assert!(run([&still, &still], true, &SlideFitConfig::default()).is_empty());
}

/// Garbage forces (a force that no object of the structure makes) fail the residual gate.
#[test]
fn a_force_no_object_makes_is_rejected() {
    let p = object(1.0, 60.0, 500.0, 60.0, 0.05);
    let mut a = samples(&p, 0.03, 0.0, 0.0, 0.5);
    for (i, s) in a.iter_mut().enumerate() {
        s[2] = if (i / 37) % 2 == 0 { 3.0 } else { -3.0 };
    }
    let b = a.clone();
    let config = SlideFitConfig::default();
    let mut fit = SlideFit::new(&config, 2, DT);
    fit.restart(0.0, true, true);
    let gates = GateConfig::default();
    let mut rejected = 0;
    for i in 0..a.len() {
        match fit.step(i as f64 * DT, &[a[i], b[i]], &config, &gates, DT) {
            Outcome::Publish(g) => panic!("published {g:?}"),
            Outcome::Rejected(_) | Outcome::NotConverged => rejected += 1,
            Outcome::Working => {}
        }
    }
    assert!(rejected > 0);
}

/// A later contact of the model (not `first`) is not fitted, and the window's memory is
/// reserved once.
#[test]
fn only_the_first_contact_is_fitted_in_the_memory_reserved() {
    let p = object(1.0, 60.0, 500.0, 60.0, 0.05);
    let a = samples(&p, 0.03, 0.0, 0.0, 0.5);
    let config = SlideFitConfig::default();
    let mut fit = SlideFit::new(&config, 2, DT);
    let capacity = fit.samples[0].capacity();
    fit.restart(0.0, false, true);
    let gates = GateConfig::default();
    for (i, s) in a.iter().enumerate() {
        let out = fit.step(i as f64 * DT, &[*s, *s], &config, &gates, DT);
        assert_eq!(out, Outcome::Working);
    }
    fit.restart(0.0, true, true);
    for (i, s) in a.iter().enumerate() {
        fit.step(i as f64 * DT, &[*s, *s], &config, &gates, DT);
    }
    assert_eq!(fit.samples[0].len(), 400, "the 0.4 s window");
    assert_eq!(fit.samples[0].capacity(), capacity);
}

#[test]
fn a_bad_configuration_is_refused_naming_the_field() {
    let bad = SlideFitConfig {
        max_window_s: 0.05,
        ..SlideFitConfig::default()
    };
    let e = bad.validate().unwrap_err().to_string();
    assert!(e.contains("slide_fit.max_window_s = 0.05"), "{e}");
    let nan = SlideFitConfig {
        period_s: f64::NAN,
        ..SlideFitConfig::default()
    };
    assert!(
        nan.validate()
            .unwrap_err()
            .to_string()
            .contains("slide_fit.period_s")
    );
}

/// The first 20 ms: the contact element alone, with the mass's terms at the class centre and
/// the mass left out, published as a reduced set; the whole fit follows from 0.1 s.
#[test]
fn the_contact_element_is_fitted_first_as_a_reduced_set() {
    let c = crate::model::prior::SOFT_OBJECTS.centre();
    // The model the stage fits: massless, `b1` and `Fc` the class centre's, its own `k2`, `b2`.
    let p = object(0.0, c.b_ground_ns_per_m, 700.0, 30.0, c.coulomb_n);
    let make = |speed, phase| loaded_samples(&p, true, 0.0, speed, phase, 0.0, 0.5);
    let (a, b) = (make(0.03, 0.0), make(-0.02, 1.0));
    let config = exact();
    let mut fit = SlideFit::new(&config, 2, DT);
    fit.restart(0.0, true, true);
    let gates = GateConfig::default();
    let mut first = None;
    for i in 0..100 {
        if let Outcome::Publish(g) = fit.step(i as f64 * DT, &[a[i], b[i]], &config, &gates, DT) {
            first = Some((i, g));
            break;
        }
    }
    let Some((tick, g)) = first else {
        panic!("no reduced set within 0.1 s")
    };
    assert!(tick <= 40, "published at tick {tick}");
    assert!(g.is_reduced(), "{g:?}");
    let q = g.sliding_mass().unwrap();
    assert_eq!(q.mass_kg, 0.0);
    assert!(close(q.k_contact_n_per_m, 700.0, 1e-3), "{q:?}");
    assert!(close(q.b_contact_ns_per_m, 30.0, 1e-3), "{q:?}");
    assert!(
        close(q.b_ground_ns_per_m, c.b_ground_ns_per_m, 1e-12),
        "{q:?}"
    );
    // Left out (`contact_fit_s` ≥ `min_window_s`): nothing before 0.1 s, and no reduced set.
    let whole_only = SlideFitConfig {
        contact_fit_s: 0.1,
        ..config
    };
    let q = object(1.0, 60.0, 500.0, 60.0, 0.05);
    let (a, b) = (
        samples(&q, 0.03, 0.0, 0.0, 0.5),
        samples(&q, -0.02, 1.0, 0.0, 0.5),
    );
    let mut fit = SlideFit::new(&whole_only, 2, DT);
    fit.restart(0.0, true, true);
    for i in 0..a.len() {
        if let Outcome::Publish(g) = fit.step(i as f64 * DT, &[a[i], b[i]], &whole_only, &gates, DT)
        {
            assert!(i >= 100 && !g.is_reduced(), "tick {i}: {g:?}");
        }
    }
}

/// A contact that already carries a force when the window opens (the contact flag set a tick
/// or more after the touch) is fitted exactly: the onset force is a parameter.
#[test]
fn a_contact_loaded_at_the_windows_start_is_fitted_exactly() {
    let p = object(1.0, 60.0, 500.0, 60.0, 0.05);
    let a = loaded_samples(&p, false, 0.4, 0.03, 0.0, 0.0, 0.5);
    let b = samples(&p, -0.02, 1.0, 0.0, 0.5);
    let config = SlideFitConfig {
        republish_change: 1e-9,
        ..exact()
    };
    let published = run([&a, &b], true, &config);
    let q = published.last().and_then(Gated::sliding_mass).unwrap();
    for (name, got, want) in [
        ("m", q.mass_kg, 1.0),
        ("b1", q.b_ground_ns_per_m, 60.0),
        ("k2", q.k_contact_n_per_m, 500.0),
        ("b2", q.b_contact_ns_per_m, 60.0),
    ] {
        assert!(close(got, want, 1e-3), "{name}: {got} vs {want} ({q:?})");
    }
}

/// White noise on the measured tool velocity (the Franka-like 1 mm/s) is an error in the
/// simulation's input: unsmoothed, the fit lowered `b2` and moved `m` and `k2` to make up.
#[test]
fn velocity_noise_does_not_bias_the_fit() {
    let p = object(1.0, 60.0, 500.0, 60.0, 0.05);
    let mut seed = 0x2545_f491_4f6c_dd1d_u64;
    let mut gaussian = || {
        // The sum of 12 uniforms: unit variance, near-normal.
        (0..12)
            .map(|_| {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                (seed >> 11) as f64 / (1u64 << 53) as f64
            })
            .sum::<f64>()
            - 6.0
    };
    let mut noisy = |mut v: Vec<Sample>| {
        for s in &mut v {
            s[1] += 1e-3 * gaussian();
        }
        v
    };
    let a = noisy(samples(&p, 0.03, 0.0, 0.0, 0.5));
    let b = noisy(samples(&p, -0.02, 1.0, 0.0, 0.5));
    let config = SlideFitConfig {
        republish_change: 1e-9,
        ..SlideFitConfig::default()
    };
    let published = run([&a, &b], true, &config);
    let q = published.last().and_then(Gated::sliding_mass).unwrap();
    for (name, got, want) in [
        ("m", q.mass_kg, 1.0),
        ("k2", q.k_contact_n_per_m, 500.0),
        ("b2", q.b_contact_ns_per_m, 60.0),
    ] {
        assert!(close(got, want, 0.02), "{name}: {got} vs {want} ({q:?})");
    }
}

/// The smoothing keeps a quadratic exactly, at the ends too (symmetric windows), and cuts
/// white noise by the filter's noise gain.
#[test]
fn the_velocity_smoothing_keeps_a_quadratic_and_cuts_noise() {
    let raw: Vec<Sample> = (0..200)
        .map(|i| {
            let t = i as f64 * DT;
            [t, 0.1 + 2.0 * t - 30.0 * t * t, 1.0]
        })
        .collect();
    let mut out = Vec::new();
    smooth_velocity(&raw, 20, &mut out);
    for (r, o) in raw.iter().zip(&out) {
        assert!((r[1] - o[1]).abs() < 1e-12, "{r:?} → {o:?}");
        assert_eq!((r[0], r[2]), (o[0], o[2]));
    }
    // Extending a smoothed prefix gives exactly the smoothing of the whole.
    let noisy: Vec<Sample> = (0..300)
        .map(|i| [0.0, ((i * 7919) % 101) as f64 - 50.0, 0.0])
        .collect();
    let mut grown = Vec::new();
    smooth_velocity(&noisy[..150], 20, &mut grown);
    smooth_velocity(&noisy[..160], 20, &mut grown);
    smooth_velocity(&noisy, 20, &mut grown);
    let mut whole = Vec::new();
    smooth_velocity(&noisy, 20, &mut whole);
    assert_eq!(grown, whole);
    // An alternating ±1 (the fastest noise) in the middle: the quadratic fit of 41 samples.
    let alternating: Vec<Sample> = (0..200)
        .map(|i| [0.0, if i % 2 == 0 { 1.0 } else { -1.0 }, 0.0])
        .collect();
    smooth_velocity(&alternating, 20, &mut out);
    assert!(out[100][1].abs() < 0.1, "{}", out[100][1]);
}

/// A one-axis group: the second axis's buffers stay empty and are never read (smoothing them
/// sliced an empty window and panicked). Fitted exactly without the contact element's stage;
/// with it, this one-axis motion's first solve of every term (started a few ticks later,
/// behind the last solve of the contact element) did not converge in its 40 iterations, and
/// the later solves, each started where the last converged, stalled at `m` 1.12 for 1 kg: the
/// friction's sticking makes the cost non-smooth. Not seen with two axes.
#[test]
fn a_one_axis_group_is_fitted() {
    let p = object(1.0, 60.0, 500.0, 60.0, 0.05);
    let a = samples(&p, 0.03, 0.0, 0.0, 0.5);
    let config = SlideFitConfig {
        republish_change: 1e-9,
        contact_fit_s: 0.1,
        ..exact()
    };
    let mut fit = SlideFit::new(&config, 1, DT);
    fit.restart(0.0, true, true);
    let gates = GateConfig::default();
    let mut last = None;
    for (i, s) in a.iter().enumerate() {
        if let Outcome::Publish(g) = fit.step(i as f64 * DT, &[*s], &config, &gates, DT) {
            last = g.sliding_mass();
        }
    }
    let q = last.expect("a set");
    assert!(close(q.k_contact_n_per_m, 500.0, 1e-3), "{q:?}");
    assert!(fit.window[1].is_empty());
}
