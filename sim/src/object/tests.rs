//! Simulator tests: friction behaviour, exact linear response, convergence, determinism
//! (numerics notes §10 item 11).

use rand::SeedableRng;
use rand_pcg::Pcg64;

use super::*;
use mmt::testutil::{Multisine, PhasorCheck, exp1_frictionless, fit_phasor, typical};

const H: f64 = 1e-3;

fn sim(config: SimConfig) -> SlidingObjectSim {
    SlidingObjectSim::new(config, 0.0, 0.0, Pcg64::seed_from_u64(1)).unwrap()
}

/// Drives `sim` along `path(t) = (x, v)` from tick 1 to `ticks`, in contact when `contact(t)`.
fn drive(
    s: &mut SlidingObjectSim,
    ticks: usize,
    path: impl Fn(f64) -> (f64, f64),
    contact: impl Fn(f64) -> bool,
) -> Vec<SimSample> {
    (1..=ticks)
        .map(|k| {
            let t = k as f64 * H;
            let (x, v) = path(t);
            s.step(x, v, contact(t))
        })
        .collect()
}

/// Smooth ramp from 0 to `to` over `[0, t_ramp]`, then held: `(x, v)`.
fn ramp(to: f64, t_ramp: f64) -> impl Fn(f64) -> (f64, f64) {
    move |t: f64| {
        if t >= t_ramp {
            return (to, 0.0);
        }
        let w = std::f64::consts::PI / t_ramp;
        (
            0.5 * to * (1.0 - (w * t).cos()),
            0.5 * to * w * (w * t).sin(),
        )
    }
}

/// Pushing to a static contact force of 0.08 N (< F_s = 0.1 N) over 1 s and holding for 10 s:
/// the object does not move (drift < 1 µm).
#[test]
fn no_motion_below_static_friction() {
    let cfg = SimConfig::THESIS_EXP1;
    let mut s = sim(cfg);
    let push = 0.08 / cfg.object.k_contact_n_per_m;
    let out = drive(&mut s, 11_000, ramp(push, 1.0), |_| true);
    let drift = out
        .iter()
        .map(|o| o.mass_position_m.abs())
        .fold(0.0, f64::max);
    eprintln!("push 0.08 N for 11 s: max object displacement {drift:.1e} m");
    assert!(drift < 1e-6, "drift {drift}");
    let last = out[out.len() - 1];
    assert!(
        (last.truth.force_n + 0.08).abs() < 1e-7,
        "F = {}",
        last.truth.force_n
    );
    assert!(out.iter().all(|o| o.phase == Phase::Stick));
}

/// Pushing slowly (force rising 0.05 N/s): the object breaks away when the push reaches F_s,
/// and in steady sliding at V the contact force is `b1 V + F_d` exactly (k1 = 0).
#[test]
fn breaks_away_at_static_and_slips_at_dynamic_friction() {
    let cfg = SimConfig::THESIS_EXP1;
    let o = cfg.object;
    let mut s = sim(cfg);
    let speed = 1e-4; // tool speed [m/s]; push rises at k2·speed = 0.05 N/s
    let out = drive(&mut s, 3000, |t| (speed * t, speed), |_| true);
    let first_move = out.iter().position(|o| o.phase != Phase::Stick).unwrap();
    // The push on the last stuck tick (the force drops once the object slides at F_d).
    let push_at_break = -out[first_move - 1].truth.force_n;
    eprintln!("break-away at push {push_at_break:.4} N (F_s = 0.1 N) after {first_move} ms");
    assert!(
        (push_at_break - cfg.static_friction_n).abs() < 1e-3,
        "{push_at_break}"
    );
    // Steady sliding at V = 2 cm/s.
    let v = 0.02;
    let mut s = sim(cfg);
    let out = drive(&mut s, 8000, |t| (v * t, v), |_| true);
    let last = out[out.len() - 1];
    let want = o.b_ground_ns_per_m * v + o.coulomb_n;
    assert!(
        (-last.truth.force_n - want).abs() < 1e-9,
        "{} vs {want}",
        -last.truth.force_n
    );
    assert_eq!(last.phase, Phase::Slip);
    assert_eq!(last.friction_n, -o.coulomb_n);
}

/// Back-and-forth motion slow enough to stick at every reversal (0.2 Hz, 1 cm), and a faster
/// one (2 Hz): fewer than 2 velocity sign changes per stick episode, counted sub-step by sub-step,
/// and zero velocity while stuck.
#[test]
fn no_sign_chatter() {
    for (f_hz, amp) in [(0.2, 0.01), (2.0, 0.005)] {
        let mut s = sim(SimConfig::THESIS_EXP1);
        let w = 2.0 * std::f64::consts::PI * f_hz;
        let out = drive(
            &mut s,
            20_000,
            |t| (amp * (w * t).sin(), amp * w * (w * t).cos()),
            |_| true,
        );
        let st = s.friction_stats();
        eprintln!("{f_hz} Hz: {st:?}");
        // At 0.2 Hz every reversal sticks; at 2 Hz the object mostly reverses without sticking.
        assert!(
            f_hz > 1.0 || st.stick_episodes >= (2.0 * f_hz * 20.0) as u64 - 1,
            "{st:?}"
        );
        assert!(st.max_sign_changes_per_episode < 2, "{st:?}");
        // And no more sign changes than the tool reverses (40 s·2f reversals).
        assert!(st.sign_changes <= (2.0 * f_hz * 20.0) as u64 + 1, "{st:?}");
        assert!(
            out.iter()
                .filter(|o| o.phase == Phase::Stick)
                .all(|o| o.mass_velocity_m_per_s == 0.0)
        );
    }
}

/// Sliding, then the tool stops and holds: the tool does no work, so the stored energy never
/// increases (dampers and friction dissipate), and it is constant while stuck.
#[test]
fn energy_not_increasing_while_stuck() {
    let mut s = sim(SimConfig::THESIS_EXP1);
    let v = 0.03;
    let stop = 2.0;
    let out = drive(
        &mut s,
        6000,
        |t| {
            if t < stop {
                (v * t, v)
            } else {
                (v * stop, 0.0)
            }
        },
        |_| true,
    );
    let hold: Vec<&SimSample> = out.iter().skip((stop / H) as usize + 1).collect();
    let mut stuck = 0;
    for pair in hold.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        assert!(
            b.stored_energy_j <= a.stored_energy_j * (1.0 + 1e-12) + 1e-18,
            "energy rose"
        );
        if a.phase == Phase::Stick && b.phase == Phase::Stick {
            stuck += 1;
            assert!(
                (b.stored_energy_j - a.stored_energy_j).abs()
                    <= 1e-12 * a.stored_energy_j.max(1e-12)
            );
        }
    }
    assert!(stuck > 1000, "the object never stuck ({stuck} ticks)");
}

/// Friction off, in contact throughout: the steady-state force per displacement equals the exact
/// `F/X` within 1e-3 (0.3–20 Hz), for the exp-1 object and one with a ground spring.
#[test]
fn linear_response_matches_exact_transfer_function() {
    let mut check = PhasorCheck::default();
    for object in [exp1_frictionless(), typical()] {
        let cfg = SimConfig {
            object,
            static_friction_n: 0.0,
            ..SimConfig::THESIS_EXP1
        };
        for f_hz in [0.5, 2.0, 5.0, 20.0] {
            let w = 2.0 * std::f64::consts::PI * f_hz;
            let amp = 0.002;
            let mut s = sim(cfg);
            let settle = 8000; // poles at −4.4 s⁻¹ (exp-1): e^{−35}
            let out = drive(
                &mut s,
                settle + 2000,
                |t| (amp * (w * t).sin(), amp * w * (w * t).cos()),
                |_| true,
            );
            let f: Vec<f64> = out[settle..].iter().map(|o| o.truth.force_n).collect();
            // x = Im(amp e^{iωt}) = Re(−i·amp e^{iωt}); samples start at tick settle + 1.
            let got = fit_phasor(&f, w, H, settle + 1) / num_complex::Complex64::new(0.0, -amp);
            check.check(
                got,
                object.force_per_displacement(w),
                1e-3,
                &format!("{f_hz} Hz"),
            );
        }
    }
    eprintln!(
        "sim F/X vs exact, 0.5–20 Hz, two objects: worst relative error {:.1e}",
        check.worst
    );
}

/// With friction and a multisine, 10 sub-steps per sample against 100: relative RMS difference of
/// the force and the object position below 1e-4.
#[test]
fn substeps_converge() {
    let excitation = Multisine::exp1();
    let run = |substeps| {
        let mut s = sim(SimConfig {
            substeps,
            ..SimConfig::THESIS_EXP1
        });
        drive(
            &mut s,
            20_000,
            |t| excitation.position_velocity(t),
            |t| t > 0.5,
        )
    };
    let (coarse, fine) = (run(10), run(100));
    let rel = |get: fn(&SimSample) -> f64| {
        let d: f64 = coarse
            .iter()
            .zip(&fine)
            .map(|(a, b)| (get(a) - get(b)).powi(2))
            .sum();
        let r: f64 = fine.iter().map(|b| get(b).powi(2)).sum();
        (d / r).sqrt()
    };
    let (ef, ex) = (rel(|o| o.truth.force_n), rel(|o| o.mass_position_m));
    eprintln!(
        "10 vs 100 sub-steps, 20 s exp-1 multisine with friction: force {ef:.1e}, position {ex:.1e} (relative RMS)"
    );
    assert!(ef < 1e-4 && ex < 1e-4, "{ef:e} {ex:e}");
}

/// Contact onset sets the rest length so the force starts at 0: with the tool at rest the first
/// sample reads exactly 0; moving at 5 cm/s it reads only what one tick of motion builds up,
/// not the `b2·v` = 3 N jump of a spring at rest. Out of contact the force is 0.
#[test]
fn contact_onset_starts_at_zero_force() {
    let cfg = SimConfig::THESIS_EXP1;
    let mut s = sim(cfg);
    assert_eq!(s.step(0.0, 0.0, true).truth.force_n, 0.0);
    let v = 0.05;
    let mut s = SlidingObjectSim::new(cfg, 0.0, v, Pcg64::seed_from_u64(1)).unwrap();
    let first = s.step(v * H, v, true);
    assert!(
        first.truth.force_n.abs() < 0.05 * cfg.object.b_contact_ns_per_m * v,
        "{first:?}"
    );
    let free = s.step(2.0 * v * H, v, false);
    assert_eq!(free.truth.force_n, 0.0);
    assert!(!free.in_contact && free.stored_energy_j >= 0.0);
}

/// Same seed: identical bits. Different seed: different noise, same truth.
#[test]
fn deterministic_per_seed() {
    let cfg = SimConfig {
        noise: SensorNoise::FRANKA_LIKE,
        ..SimConfig::THESIS_EXP1
    };
    let excitation = Multisine::exp1();
    let run = |seed| {
        let mut s = SlidingObjectSim::new(cfg, 0.0, 0.0, Pcg64::seed_from_u64(seed)).unwrap();
        drive(
            &mut s,
            5000,
            |t| excitation.position_velocity(t),
            |t| t > 0.2,
        )
    };
    let bits = |v: &[SimSample], get: fn(&SimSample) -> [f64; 3]| -> Vec<u64> {
        v.iter().flat_map(|o| get(o).map(f64::to_bits)).collect()
    };
    let measured = |o: &SimSample| {
        [
            o.measured.position_m,
            o.measured.velocity_m_per_s,
            o.measured.force_n,
        ]
    };
    let truth = |o: &SimSample| [o.truth.force_n, o.mass_position_m, o.mass_velocity_m_per_s];
    let (a, b, c) = (run(11), run(11), run(12));
    assert_eq!(bits(&a, measured), bits(&b, measured));
    assert_eq!(bits(&a, truth), bits(&b, truth));
    assert_eq!(bits(&a, truth), bits(&c, truth));
    let differ = a
        .iter()
        .zip(&c)
        .filter(|(x, y)| x.measured.force_n != y.measured.force_n)
        .count();
    assert!(differ > 4900, "{differ}");
}

#[test]
fn invalid_configs_are_named() {
    let base = SimConfig::THESIS_EXP1;
    let field = |c: SimConfig| match SlidingObjectSim::new(c, 0.0, 0.0, Pcg64::seed_from_u64(0)) {
        Err(SimError::Field { field, .. }) => field,
        other => panic!("{other:?}"),
    };
    let mut massless = base;
    massless.object.mass_kg = 0.0;
    assert_eq!(field(massless), "object.mass_kg");
    assert_eq!(
        field(SimConfig {
            static_friction_n: 0.01,
            ..base
        }),
        "static_friction_n"
    );
    assert_eq!(
        field(SimConfig {
            substeps: 5,
            ..base
        }),
        "substeps"
    );
    assert_eq!(
        field(SimConfig {
            stick_band_m_per_s: f64::NAN,
            ..base
        }),
        "stick_band_m_per_s"
    );
    let noisy = SimConfig {
        noise: SensorNoise {
            position_sd_m: -1.0,
            ..SensorNoise::CLEAN
        },
        ..base
    };
    assert_eq!(field(noisy), "noise.position_sd_m");
    let msg = SlidingObjectSim::new(
        SimConfig {
            substeps: 5,
            ..base
        },
        0.0,
        0.0,
        Pcg64::seed_from_u64(0),
    )
    .unwrap_err()
    .to_string();
    assert!(
        msg.contains("substeps") && msg.contains('5') && msg.contains("10 kHz"),
        "{msg}"
    );
}
