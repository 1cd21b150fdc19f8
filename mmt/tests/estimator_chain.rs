//! The estimator chain on the simulated exp-1 scene, through the public API only:
//! sim (Karnopp friction, Franka-like noise) → regressor filter → RLS, with make/break contact.
//! The new-object detector must stay quiet on re-contact with the same object and fire when
//! the object changes.

// A test: unwrapping a broken set-up is the right failure (clippy's in-test allowance does not
// reach the helper functions of an integration test).
#![allow(clippy::unwrap_used)]

use mmt::filter::{RegressorConfig, RegressorFilter};
use mmt::model::{Physical, col};
use mmt::rls::{Mode, Outcome, Rls, RlsConfig};
use rand::SeedableRng;
use rand_pcg::Pcg64;
use sim::{SensorNoise, SimConfig, SlidingObjectSim};

const H: f64 = 1e-3;
/// Skip updates this long after contact onset (`DESIGN.md` §11.3) [ticks].
const GUARD: usize = 300;

/// The feasibility study's excitation: 9 tones 0.1–3.6 Hz, 3 cm falling to 2 mm.
fn excitation(t: f64) -> (f64, f64) {
    (0..9u32).fold((0.0, 0.0), |(x, v), k| {
        let r = f64::from(k) / 8.0;
        let w = 2.0 * std::f64::consts::PI * 0.1 * 36f64.powf(r);
        let a = 0.03 * (0.002f64 / 0.03).powf(r);
        let p = -std::f64::consts::PI * f64::from(k * k.saturating_sub(1)) / 9.0;
        (x + a * (w * t + p).sin(), v + a * w * (w * t + p).cos())
    })
}

struct Run {
    alarms: Vec<f64>,
    theta: [f64; col::COUNT],
    relative_error: f64,
    not_pd: u64,
}

/// Contact over [1, 21) s with `first`, then [23, 43) s with `second`. Out of contact and in the
/// guard the estimator pauses; on an alarm the covariance is reset.
fn run(first: Physical, second: Physical) -> Run {
    let config = |object| SimConfig {
        object,
        noise: SensorNoise::FRANKA_LIKE,
        ..SimConfig::THESIS_EXP1
    };
    let (x0, v0) = excitation(0.0);
    let mut sim = SlidingObjectSim::new(config(first), x0, v0, Pcg64::seed_from_u64(5)).unwrap();
    let mut filt = RegressorFilter::new(RegressorConfig::default()).unwrap();
    let mut rls = Rls::new(RlsConfig::default()).unwrap();
    let (mut tare, mut tare_n) = (0.0, 0);
    let mut onset = 0;
    let mut was_in = false;
    let mut alarms = Vec::new();
    for k in 1..=43_000 {
        let t = k as f64 * H;
        if k == 22_000 {
            // The object is swapped while the tool is away (a new sim: object at rest).
            let (x, v) = excitation(t - H);
            sim = SlidingObjectSim::new(config(second), x, v, Pcg64::seed_from_u64(6)).unwrap();
        }
        let in_contact = (1.0..21.0).contains(&t) || (23.0..43.0).contains(&t);
        let (x, v) = excitation(t);
        let s = sim.step(x, v, in_contact);
        if !in_contact && t < 1.0 {
            // Tare the force offset out of contact, as a bridge would.
            tare_n += 1;
            tare += (s.measured.force_n - tare) / f64::from(tare_n);
        }
        if in_contact && !was_in {
            onset = k;
        }
        was_in = in_contact;
        let m = s.measured;
        let r = filt.step(m.position_m, m.velocity_m_per_s, m.force_n - tare);
        let mode = if in_contact && k - onset >= GUARD {
            Mode::Learn
        } else {
            Mode::Pause
        };
        if let Outcome::Updated {
            new_object: true, ..
        } = rls.update(&r.psi, r.y, mode)
        {
            alarms.push(t);
            rls.reset(RlsConfig::default().initial_covariance).unwrap();
        }
    }
    Run {
        alarms,
        theta: rls.theta().0,
        relative_error: rls.relative_error().unwrap_or(f64::NAN),
        not_pd: rls.counts().not_positive_definite,
    }
}

fn report(name: &str, r: &Run, truth: &Physical) {
    let want = truth.theta().unwrap().0;
    let rel: Vec<String> = (0..col::COUNT)
        .filter(|&i| want[i] != 0.0)
        .map(|i| {
            format!(
                "{} {:+.0}%",
                col::NAMES[i],
                100.0 * (r.theta[i] / want[i] - 1.0)
            )
        })
        .collect();
    eprintln!(
        "{name}: alarms at {:?} s; final θ error {}; a-priori reconstruction error {:.1} %",
        r.alarms,
        rel.join(", "),
        100.0 * r.relative_error
    );
}

#[test]
fn same_object_no_alarm_changed_object_alarm() {
    let a = Physical::THESIS_EXP1;
    let same = run(a, a);
    report("same object", &same, &a);
    assert!(same.alarms.is_empty(), "false alarm: {:?}", same.alarms);
    assert_eq!(same.not_pd, 0);
    assert!(same.relative_error < 0.1, "{}", same.relative_error);

    let b = Physical {
        k_contact_n_per_m: 2.0 * a.k_contact_n_per_m,
        b_contact_ns_per_m: 2.0 * a.b_contact_ns_per_m,
        ..a
    };
    let changed = run(a, b);
    report("k2, b2 doubled at re-contact", &changed, &b);
    assert_eq!(changed.alarms.len(), 1, "{:?}", changed.alarms);
    let delay = changed.alarms[0] - (23.0 + GUARD as f64 * H);
    assert!(
        (0.0..0.2).contains(&delay),
        "alarm {delay} s after the guard"
    );
    assert!(changed.relative_error < 0.1, "{}", changed.relative_error);
}
