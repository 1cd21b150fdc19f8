//! Same inputs, same bits; both neighbour backends agree; no NaN at the edges of the domain.

use mmt::cloud::{CloudFrame, Pose};
use mmt::contact::{BruteForce, CloudIndex, ContactState, Proxy};

use crate::support::*;

fn noisy_run(seed: u64) -> Vec<mmt::contact::ContactOutput> {
    let n = unit([0.1, -0.2, 1.0]);
    let index = index(
        &plane(n, [0.0; 3], 0.08),
        &Sensor {
            seed,
            dropout: 0.1,
            ..Sensor::noisy(0.0007)
        },
    );
    let (t1, _) = tangents(n);
    let hips = chain(&[
        path(scale(n, 0.02), scale(n, -0.005), 0.5, 5),
        path(
            scale(n, -0.005),
            add(scale(n, -0.005), scale(t1, 0.02)),
            0.2,
            0,
        ),
        path(
            add(scale(n, -0.005), scale(t1, 0.02)),
            scale(n, 0.02),
            1.0,
            0,
        ),
    ]);
    run(config(), &index, &hips)
}

fn bits(out: &[mmt::contact::ContactOutput]) -> Vec<u64> {
    out.iter()
        .flat_map(|o| {
            let mut v: Vec<u64> = o.proxy_m.iter().map(|x| x.to_bits()).collect();
            v.extend(o.normal.into_iter().flatten().map(f64::to_bits));
            v.extend(o.penetration_m.map(f64::to_bits));
            v.push(o.state as u64);
            v
        })
        .collect()
}

#[test]
fn same_seed_same_trajectory_bits() {
    let a = noisy_run(5);
    let b = noisy_run(5);
    assert_eq!(bits(&a), bits(&b));
    assert_ne!(bits(&a), bits(&noisy_run(6)));
}

#[test]
fn kd_tree_and_brute_force_proxies_agree() {
    let n = unit([0.3, 0.0, 1.0]);
    let kd = index(&plane(n, [0.0; 3], 0.06), &Sensor::noisy(0.0005));
    let brute = kd.brute_force();
    let hips = chain(&[
        path(scale(n, 0.02), scale(n, -0.004), 0.5, 5),
        path(scale(n, -0.004), [0.02, 0.01, -0.01], 0.3, 0),
        path([0.02, 0.01, -0.01], scale(n, 0.02), 1.0, 0),
    ]);
    let mut p_kd = Proxy::new(config(), hips[0]).unwrap();
    let mut p_bf = Proxy::new(config(), hips[0]).unwrap();
    for h in &hips {
        let (a, b) = (p_kd.step(*h, &kd), p_bf.step(*h, &brute));
        assert_eq!(a.state, b.state);
        assert_eq!(a.points_used, b.points_used);
        assert!(norm(sub(a.proxy_m, b.proxy_m)) < 1e-12, "{a:?} vs {b:?}");
    }
    // A standalone scan over the same points answers the same too.
    let standalone = BruteForce::new(kd.points());
    let mut p = Proxy::new(config(), hips[0]).unwrap();
    let last = hips.iter().map(|h| p.step(*h, &standalone)).last().unwrap();
    assert!(norm(sub(last.proxy_m, p_kd.position())) < 1e-12);
}

#[test]
fn free_space_and_empty_clouds_give_none_not_nan() {
    let empty =
        CloudIndex::build(&CloudFrame::new(Vec::new(), 0, Pose::IDENTITY).unwrap()).unwrap();
    let far = index(
        &plane([0.0, 0.0, 1.0], [0.0, 0.0, -1.0], 0.05),
        &Sensor::exact(),
    );
    for cloud in [&empty, &far] {
        let hips = path([0.0; 3], [0.3, -0.2, 0.1], 2.0, 0);
        let out = run(config(), cloud, &hips);
        for (o, h) in out.iter().zip(&hips) {
            assert_eq!(o.state, ContactState::Free);
            assert_eq!(o.proxy_m, *h, "in free space the proxy is the HIP");
            assert_eq!(
                (o.normal, o.penetration_m, o.surface_point_m),
                (None, None, None)
            );
            assert_eq!(o.points_used, 0);
        }
    }
}

#[test]
fn a_non_finite_hip_holds_the_proxy() {
    let index = index(&plane([0.0, 0.0, 1.0], [0.0; 3], 0.05), &Sensor::exact());
    let mut proxy = Proxy::new(config(), [0.0, 0.0, 0.02]).unwrap();
    for h in &path([0.0, 0.0, 0.02], [0.0, 0.0, -0.003], 0.2, 5) {
        proxy.step(*h, &index);
    }
    let before = proxy.position();
    for bad in [[f64::NAN, 0.0, 0.0], [0.0, f64::INFINITY, 0.0]] {
        let o = proxy.step(bad, &index);
        assert_finite(&o);
        assert_eq!(o.proxy_m, before);
        assert_eq!(o.penetration_m, None);
        assert!(o.normal.is_some());
    }
    assert!(Proxy::new(config(), [f64::NAN, 0.0, 0.0]).is_err());
    assert!(proxy.reset([0.0, f64::NAN, 0.0]).is_err());
}
