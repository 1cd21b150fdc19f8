//! Trajectory tests: exact velocities, contact schedules, placement, determinism.

use super::*;

/// Velocity is the exact derivative of position (central differences), for every profile.
#[test]
fn velocity_is_the_derivative_of_position() {
    for name in NAMES {
        let tr = by_name(name, 20.0, [0.1, -0.2, 0.3], [1.0, 1.0, 0.5]).unwrap();
        for k in 1..4000 {
            let t = k as f64 * 0.005;
            let h = 1e-6;
            let (a, b) = (tr.sample(t - h), tr.sample(t + h));
            let v = tr.sample(t).velocity_m_per_s;
            for (i, vi) in v.iter().enumerate() {
                let fd = (b.position_m[i] - a.position_m[i]) / (2.0 * h);
                assert!(
                    (fd - vi).abs() < 1e-5 * (1.0 + vi.abs()),
                    "{name} t={t} axis {i}: {fd} vs {vi}",
                );
            }
        }
    }
}

/// exp1 breaks and re-makes contact at least twice, and presses about 4 mm.
#[test]
fn exp1_breaks_and_remakes_contact_twice() {
    let tr = by_name("exp1", 60.0, [0.0; 3], [0.0, 0.0, 1.0]).unwrap();
    let mut onsets = 0;
    let mut was = false;
    let mut deepest = 0.0f64;
    for k in 0..60_000 {
        let z = tr.sample(k as f64 * 1e-3).position_m[2];
        let touching = z < 0.0;
        onsets += usize::from(touching && !was);
        was = touching;
        deepest = deepest.min(z);
    }
    assert_eq!(onsets, 3);
    assert!((-0.0056..-0.0050).contains(&deepest), "{deepest}");
}

/// Placed on a tilted surface, the height is measured along its normal.
#[test]
fn placement_follows_the_surface() {
    let n = [-1.0, 0.0, 0.0];
    let tr = by_name("hold", 10.0, [0.05, 0.0, 0.0], n).unwrap();
    let p = tr.sample(5.0).position_m;
    assert!((p[0] - 0.054).abs() < 1e-12, "{p:?}"); // 4 mm into a wall facing −x
    assert!(by_name("nope", 10.0, [0.0; 3], n).is_err());
}

#[test]
fn profiles_are_deterministic() {
    let a = by_name("exp1", 30.0, [0.0; 3], [0.0, 0.0, 1.0]).unwrap();
    let b = by_name("exp1", 30.0, [0.0; 3], [0.0, 0.0, 1.0]).unwrap();
    for k in 0..1000 {
        assert_eq!(a.sample(k as f64 * 0.0123), b.sample(k as f64 * 0.0123));
    }
}

/// The random profile is fixed by its seed, differs between seeds, and makes and breaks contact
/// several times in a minute.
#[test]
fn human_is_random_but_seeded() {
    let tr = |seed| by_name_seeded("human", 60.0, [0.0; 3], [0.0, 0.0, 1.0], seed).unwrap();
    let (a, b, c) = (tr(3), tr(3), tr(4));
    let mut onsets = 0;
    let mut was = false;
    let mut differs = false;
    for k in 0..60_000 {
        let t = k as f64 * 1e-3;
        assert_eq!(a.sample(t), b.sample(t));
        differs |= a.sample(t) != c.sample(t);
        let touching = a.sample(t).position_m[2] < 0.0;
        onsets += usize::from(touching && !was);
        was = touching;
    }
    assert!(differs);
    assert!((3..=12).contains(&onsets), "{onsets} contact episodes");
}
