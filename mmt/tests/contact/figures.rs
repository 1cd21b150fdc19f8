//! The accuracy figures of issue 3: no punch-through, normal error, contact latency,
//! entrenchment cleared in one step, the sticking bound of eq. 23.

use mmt::cloud::Pose;
use mmt::contact::{ContactState, NormalEstimator, ProxyConfig};
use sim::synthetic::{SceneObject, Shape};

use crate::support::*;

/// The normals the plane tests use: a table, a wall, tilted and upside-down planes.
const NORMALS: [[f64; 3]; 4] = [
    [0.0, 0.0, 1.0],
    [1.0, 0.0, 0.0],
    [0.3, -0.2, 0.93],
    [-0.5, 0.5, -0.7],
];

/// In, through and out: from 30 mm above to 30 mm below the surface (diagonally), a slide
/// while deep, and back out.
fn through_path(origin: [f64; 3], n: [f64; 3], speed: f64) -> Vec<[f64; 3]> {
    let (t1, t2) = tangents(n);
    let above = add(origin, add(scale(n, 0.03), scale(t1, -0.01)));
    let deep = add(origin, add(scale(n, -0.03), scale(t1, 0.01)));
    let slid = add(deep, scale(t2, 0.03));
    let out = add(slid, scale(n, 0.06));
    chain(&[
        path(above, deep, speed, 20),
        path(deep, slid, speed, 20),
        path(slid, out, speed, 0),
    ])
}

/// Both normal estimators: the default weighted plane fit, bridging holes and not, and the
/// thesis's literal eq. 14 (which has no plane to bridge with).
fn configs() -> [ProxyConfig; 3] {
    [
        config(),
        points_only(),
        ProxyConfig {
            normal_estimator: NormalEstimator::WeightedDirections,
            ..config()
        },
    ]
}

#[test]
fn no_punch_through_a_plane_at_up_to_1_m_per_s_with_noise_up_to_half_the_band() {
    for c in configs() {
        plane_punch_through(c);
    }
}

/// Four orientations, three noise levels, three seeds of the noisy clouds, two speeds.
fn plane_punch_through(c: ProxyConfig) {
    let max_noise = (c.r2_m - c.r1_m) / 2.0;
    for (k, normal) in NORMALS.iter().enumerate() {
        let n = unit(*normal);
        let origin = [0.01 * k as f64, -0.02, 0.3];
        let object = plane(n, origin, 0.12);
        for (noise, seed) in [0.0, max_noise / 2.0, max_noise]
            .into_iter()
            .flat_map(|noise| (0..3).map(move |s| (noise, s)))
        {
            if noise == 0.0 && seed > 0 {
                continue;
            }
            let sensor = Sensor {
                dropout: if noise > 0.0 { 0.05 } else { 0.0 },
                seed: 10 * k as u64 + seed,
                ..Sensor::noisy(noise)
            };
            let index = index(&object, &sensor);
            for speed in [0.2, 1.0] {
                let out = run(c, &index, &through_path(origin, n, speed));
                let lowest = out
                    .iter()
                    .map(|o| dot(sub(o.proxy_m, origin), n))
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    lowest > 0.0,
                    "{:?}, normal {n:?}, noise {noise}, seed {seed}, {speed} m/s: proxy {lowest} m \
                     below the plane",
                    c.normal_estimator
                );
                // While the HIP is deep, the proxy rests on the surface, not above it — with the
                // default plane fit. The literal eq. 14 tilts on noisy clouds and, at the largest
                // noise and 1 m/s, can leave the proxy lifted off (5 mm above, `Free`) while the
                // HIP is 35 mm deep: measured, and the reason it is not the default.
                let deepest_tick = out.len() / 2;
                let o = &out[deepest_tick];
                assert!(
                    c.normal_estimator == NormalEstimator::WeightedDirections
                        || o.state.is_touching(),
                    "{:?}, normal {n:?}, noise {noise}, seed {seed}, {speed} m/s: {o:?}",
                    c.normal_estimator
                );
                out.iter().for_each(assert_finite);
            }
        }
    }
}

/// A HIP jump of any length is swept in segments of `r3`, at most four per tick (so no query
/// grows with the jump): a 1 m jump through a plane never leaves the proxy on the far side, and
/// an unobstructed 30 cm jump is followed at `4 r3` per tick until the proxy is at the HIP.
#[test]
fn long_jumps_are_swept_in_bounded_pieces_without_punching_through() {
    let c = config();
    let per_tick = 4.0 * c.r3_m;
    for (k, normal) in NORMALS.iter().enumerate() {
        let n = unit(*normal);
        let origin = [0.0, 0.01 * k as f64, 0.1];
        let object = plane(n, origin, 0.12);
        let index = index(&object, &Sensor::noisy((c.r2_m - c.r1_m) / 2.0));
        let (above, below) = (add(origin, scale(n, 0.5)), add(origin, scale(n, -0.5)));
        let mut hips = vec![above; 2];
        hips.extend(std::iter::repeat_n(below, 30));
        let out = run(c, &index, &hips);
        for (tick, o) in out.iter().enumerate() {
            let height = dot(sub(o.proxy_m, origin), n);
            assert!(height > 0.0, "normal {n:?}, tick {tick}: {height} m");
            assert_finite(o);
        }
        // It reaches the surface: ⌈0.5 m / 4 r3⌉ ticks of free sweeping.
        let reached = (0.5 / per_tick).ceil() as usize;
        assert!(
            out[2 + reached].state.is_touching(),
            "{:?}",
            out[2 + reached]
        );

        // Sideways, parallel to the plane 50 mm above it: nothing in the way.
        let (t1, _) = tangents(n);
        let start = add(origin, scale(n, 0.05));
        let end = add(start, scale(t1, 0.3));
        let mut hips = vec![start];
        hips.extend(std::iter::repeat_n(end, 10));
        let out = run(c, &index, &hips);
        let needed = (0.3 / per_tick).ceil() as usize;
        for (tick, o) in out.iter().enumerate().skip(1) {
            let remaining = norm(sub(end, o.proxy_m));
            let expected = (0.3 - per_tick * tick as f64).max(0.0);
            assert!(
                (remaining - expected).abs() < 1e-9,
                "tick {tick}: {remaining}"
            );
        }
        assert_eq!(out[needed].proxy_m, end);
    }
}

fn test_box() -> SceneObject {
    SceneObject::fixed(
        Shape::Box {
            size_m: [0.06, 0.05, 0.04],
        },
        Pose::from_rotation_vector([0.1, -0.2, 0.3], [0.0, 0.0, 0.5]),
    )
}

#[test]
fn no_punch_through_a_box_through_faces_edges_and_corners() {
    for c in configs() {
        box_punch_through(c);
    }
}

/// Faces, edges and corners, exact and at the largest noise (three seeds), two speeds.
fn box_punch_through(c: ProxyConfig) {
    let object = test_box();
    let centre = object.pose.translation_m;
    let world = |local: [f64; 3]| object.pose.transform_point(local);
    // Straight through the top and out of the bottom, through a side, across an edge, at a
    // corner: each from 40 mm outside, to beyond the far side, and back.
    let targets = [
        ([0.0, 0.0, 0.06], [0.005, 0.0, -0.06]),
        ([0.07, 0.01, 0.0], [-0.07, 0.0, 0.01]),
        ([0.05, 0.0, 0.05], [-0.03, 0.005, -0.03]),
        ([0.05, 0.045, 0.045], [-0.03, -0.02, -0.02]),
    ];
    let max_noise = (c.r2_m - c.r1_m) / 2.0;
    for (noise, seed) in [(0.0, 0), (max_noise, 1), (max_noise, 2), (max_noise, 3)] {
        let index = index(
            &object,
            &Sensor {
                seed,
                ..Sensor::noisy(noise)
            },
        );
        for (from, to) in targets {
            for speed in [0.3, 1.0] {
                let (from, to) = (world(from), world(to));
                let hips = chain(&[path(from, to, speed, 30), path(to, from, speed, 0)]);
                let out = run(c, &index, &hips);
                for (k, o) in out.iter().enumerate() {
                    let d = object.signed_distance(0.0, o.proxy_m);
                    assert!(
                        d > 0.0,
                        "{:?}, noise {noise}, seed {seed}, {from:?} → {to:?} at {speed} m/s, tick \
                         {k}: proxy {d} m inside the box (centre {centre:?})",
                        c.normal_estimator
                    );
                    assert_finite(o);
                }
                assert!(out.iter().any(|o| o.state.is_touching()));
            }
        }
    }
}

#[test]
fn normal_error_is_within_2_degrees_on_a_noisy_plane() {
    let c = config();
    // A quarter of the band r2 − r1: the noise the defaults are designed for.
    let noise = (c.r2_m - c.r1_m) / 4.0;
    let mut worst: f64 = 0.0;
    for (k, normal) in NORMALS.iter().enumerate() {
        let n = unit(*normal);
        let origin = [0.0, 0.01 * k as f64, 0.2];
        let object = plane(n, origin, 0.12);
        for seed in 0..3 {
            let index = index(
                &object,
                &Sensor {
                    seed,
                    ..Sensor::noisy(noise)
                },
            );
            let (t1, t2) = tangents(n);
            let pressed = add(origin, scale(n, -0.004));
            let hips = chain(&[
                path(add(origin, scale(n, 0.02)), pressed, 0.2, 0),
                path(
                    pressed,
                    add(pressed, add(scale(t1, 0.03), scale(t2, 0.02))),
                    0.1,
                    0,
                ),
            ]);
            let out = run(c, &index, &hips);
            let mut touching = 0;
            for o in out.iter().filter(|o| o.state.is_touching()) {
                worst = worst.max(angle_deg(o.normal.unwrap(), n));
                touching += 1;
            }
            assert!(touching > 300);
        }
    }
    assert!(
        worst <= 2.0,
        "worst normal error {worst}° at noise {noise} m"
    );
}

/// The thesis's proxy (points only): contact the tick the HIP comes within `r2` of a point.
#[test]
fn contact_is_reported_within_one_tick_of_the_hip_crossing_r2() {
    let c = points_only();
    for (k, normal) in NORMALS.iter().enumerate() {
        let n = unit(*normal);
        let origin = [0.0, 0.0, 0.1 * k as f64];
        let object = plane(n, origin, 0.08);
        for noise in [0.0, 0.00025] {
            let index = index(&object, &Sensor::noisy(noise));
            for speed in [0.02, 0.1, 1.0] {
                let hips = path(
                    add(origin, scale(n, 0.02)),
                    add(origin, scale(n, -0.002)),
                    speed,
                    0,
                );
                let out = run(c, &index, &hips);
                let contact = out.iter().position(|o| o.state.is_touching()).unwrap();
                // Against the cloud (the surface the proxy sees): in the very tick the HIP
                // comes within r2 of a point, since the free proxy is at the HIP.
                let cloud_cross = hips
                    .iter()
                    .position(|h| nearest_point_distance(&index, *h) <= c.r2_m)
                    .unwrap();
                assert_eq!(
                    contact, cloud_cross,
                    "normal {n:?}, noise {noise}, {speed} m/s"
                );
                // Against the true plane: within one tick when a tick moves the HIP more than
                // the grid's sag between points (δ²/2r2 ≈ 0.08 mm at 1 mm spacing).
                let true_cross = hips
                    .iter()
                    .position(|h| dot(sub(*h, origin), n) <= c.r2_m)
                    .unwrap();
                if noise == 0.0 && speed >= 0.1 {
                    assert!(contact <= true_cross + 1, "{contact} vs {true_cross}");
                    assert!(contact >= true_cross, "{contact} vs {true_cross}");
                }
            }
        }
    }
}

/// The contact figure off the grid points: descending over a grid-cell centre and at random
/// lateral offsets within a cell.
///
/// Against the cloud the figure holds exactly: the free proxy is at the HIP, so contact is
/// reported in the very tick the HIP comes within `r2` of the nearest point. Against the true
/// surface it cannot: between grid points the nearest point is up to `ρ = spacing/√2` to the
/// side (a cell centre), so the HIP reaches `r2` of the cloud only at a height of
/// `√(r2² − ρ²)` above the surface. The honest bound is that **grid sag**,
/// `r2 − √(r2² − spacing²/2)` (0.085 mm at 1 mm spacing and r2 = 3 mm): contact comes no earlier
/// than the HIP crossing `r2` of the true surface (exact cloud), and no later than one tick
/// after it crosses `r2 − sag` — within one tick of the crossing whenever a tick moves the HIP
/// more than the sag (here at 0.1 and 1 m/s; at 0.02 m/s the sag spans about four ticks). On a
/// noisy cloud, points stand up to about 4σ off the surface, which widens the band by as much.
#[test]
fn contact_off_grid_points_is_within_the_grid_sag_of_r2() {
    use rand::{Rng, SeedableRng};
    let c = points_only();
    let spacing = Sensor::exact().spacing;
    let sag = c.r2_m - (c.r2_m * c.r2_m - spacing * spacing / 2.0).sqrt();
    assert!((sag - 8.5e-5).abs() < 1e-6, "{sag}");
    let mut rng = rand_pcg::Pcg64::seed_from_u64(23);
    for (k, normal) in NORMALS.iter().enumerate() {
        let n = unit(*normal);
        let origin = [0.0, 0.0, 0.1 * k as f64];
        let object = plane(n, origin, 0.08);
        // A cell centre, then random offsets within a cell (plane-local x, y [m]).
        let mut offsets = vec![[0.5 * spacing, 0.5 * spacing]];
        offsets.extend((0..6).map(|_| [0; 2].map(|_| rng.random_range(0.0..spacing))));
        for noise in [0.0, 0.00025] {
            let index = index(&object, &Sensor::noisy(noise));
            for (j, [dx, dy]) in offsets.iter().copied().enumerate() {
                let at = |h: f64| object.pose.transform_point([dx, dy, h]);
                if noise == 0.0 && j == 0 {
                    // The scenario does descend over a cell centre.
                    let side = nearest_point_distance(&index, at(0.0));
                    assert!((side - spacing / 2f64.sqrt()).abs() < 1e-6, "{side}");
                }
                for speed in [0.02, 0.1, 1.0] {
                    let hips = path(at(0.02), at(-0.002), speed, 0);
                    let out = run(c, &index, &hips);
                    let contact = out.iter().position(|o| o.state.is_touching()).unwrap();
                    let case = format!("normal {n:?}, offset {dx:.5} {dy:.5}, {speed} m/s");
                    // Against the cloud: exactly the tick the HIP comes within r2 of a point.
                    let cloud_cross = hips
                        .iter()
                        .position(|h| nearest_point_distance(&index, *h) <= c.r2_m)
                        .unwrap();
                    assert_eq!(contact, cloud_cross, "{case}, noise {noise}");
                    // Against the true plane: between crossing r2 and one tick after crossing
                    // r2 − sag (widened by the noise).
                    let band = sag + 4.0 * noise;
                    let height = |h: &[f64; 3]| dot(sub(*h, origin), n);
                    let early = hips
                        .iter()
                        .position(|h| height(h) <= c.r2_m + 4.0 * noise)
                        .unwrap();
                    let late = hips
                        .iter()
                        .position(|h| height(h) <= c.r2_m - band)
                        .unwrap();
                    assert!(
                        (early..=late + 1).contains(&contact),
                        "{case}, noise {noise}: contact at tick {contact}, HIP within r2 + 4σ \
                         at {early}, within r2 − sag − 4σ at {late}"
                    );
                    if noise == 0.0 && speed * 1e-3 > sag {
                        let true_cross = hips.iter().position(|h| height(h) <= c.r2_m).unwrap();
                        assert!(
                            (true_cross..=true_cross + 1).contains(&contact),
                            "{case}: {contact} vs {true_cross}"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn entrenchment_is_cleared_in_one_step() {
    for c in [config(), points_only()] {
        entrenchment_after_a_jump(c);
        entrenchment_along_noisy_runs(c);
    }
}

/// The cloud jumps toward the resting proxy between frames, leaving the nearest point (straight
/// below: the HIP descended onto a grid point) 0.8, 0.5 or 0.1 mm away: the proxy is
/// entrenched, and one step puts every point at least `(r1 + r2)/2` away — exactly that far
/// from the nearest point (points only) or from the plane (bridged; on exact points the fit is
/// the plane).
fn entrenchment_after_a_jump(c: ProxyConfig) {
    let n = unit([0.2, 0.1, 1.0]);
    let sensor = Sensor::exact();
    let rest = index(&plane(n, [0.0; 3], 0.1), &sensor);
    let hips = path(scale(n, 0.02), scale(n, -0.003), 0.2, 10);
    let mut proxy = mmt::contact::Proxy::new(c, hips[0]).unwrap();
    for h in &hips {
        proxy.step(*h, &rest);
    }
    let rest_height = nearest_point_distance(&rest, proxy.position());
    assert!(rest_height > c.rest_distance_m() - 1e-12 && rest_height <= c.r2_m);
    for left in [0.0008, 0.0005, 0.0001] {
        let jump = rest_height - left;
        let moved = index(&plane(n, scale(n, jump), 0.1), &sensor);
        let mut p = proxy.clone();
        let o = p.step(*hips.last().unwrap(), &moved);
        assert_eq!(o.step_state, ContactState::Entrenched, "jump {jump}");
        assert_eq!(o.state, ContactState::Contact, "jump {jump}");
        let cleared = if c.bridge_holes {
            dot(o.proxy_m, n) - jump
        } else {
            nearest_point_distance(&moved, o.proxy_m)
        };
        assert!((cleared - c.rest_distance_m()).abs() < 1e-9, "{cleared}");
        assert!(nearest_point_distance(&moved, o.proxy_m) >= c.rest_distance_m() - 1e-9);
        assert!(dot(o.proxy_m, n) > jump);
    }
}

/// Along whole runs over noisy planes and boxes, an entrenched step never ends entrenched. The
/// thesis's proxy is entrenched by the noise (half the band) as it slides over fresh points;
/// where the plane bridges the points, only the rare noisy point that stands out of it as an
/// obstacle does.
fn entrenchment_along_noisy_runs(c: ProxyConfig) {
    let n = unit([0.2, 0.1, 1.0]);
    for object in [plane(n, [0.0; 3], 0.1), test_box()] {
        let index = index(&object, &Sensor::noisy((c.r2_m - c.r1_m) / 2.0));
        let centre = object.pose.translation_m;
        let hips = chain(&[
            path(
                add(centre, scale(n, 0.06)),
                add(centre, scale(n, -0.01)),
                0.5,
                0,
            ),
            path(
                add(centre, scale(n, -0.01)),
                add(centre, [0.04, 0.03, -0.01]),
                0.5,
                0,
            ),
        ]);
        let out = run(c, &index, &hips);
        let entrenched: Vec<_> = out
            .iter()
            .filter(|o| o.step_state == ContactState::Entrenched)
            .collect();
        // The thesis's proxy does entrench on these runs (seed 1: two steps on the plane, one
        // on the box), else the check below would hold vacuously for it. Bridging, only a noisy
        // point standing out of the fitted plane as an obstacle can (0–2 steps).
        if !c.bridge_holes {
            assert!(
                !entrenched.is_empty(),
                "{object:?}: no entrenched step in {} ticks",
                out.len()
            );
        }
        assert!(
            entrenched
                .iter()
                .all(|o| o.state != ContactState::Entrenched)
        );
    }
}

#[test]
fn the_sticking_bound_of_eq_23_holds() {
    for (zeta, base) in [0.2, 0.5, 0.9]
        .into_iter()
        .flat_map(|zeta| [(zeta, config()), (zeta, points_only())])
    {
        let c = ProxyConfig { zeta, ..base };
        for noise in [0.0, 0.0005] {
            let n = unit([0.0, -0.3, 1.0]);
            let index = index(&plane(n, [0.0; 3], 0.1), &Sensor::noisy(noise));
            let pressed = scale(n, -0.005);
            let mut hips = path(scale(n, 0.02), pressed, 0.2, 20);
            let press_ticks = hips.len();
            // Pulled straight out, far, in one tick.
            hips.extend(std::iter::repeat_n(scale(n, 0.05), 50));
            let out = run(c, &index, &hips);
            assert!(out[press_ticks - 1].state.is_touching());
            let stuck = out[press_ticks..]
                .iter()
                .take_while(|o| o.state.is_touching())
                .count();
            let bound = c.sticking_steps() as usize;
            assert!(stuck <= bound, "ζ {zeta}, noise {noise}: {stuck} > {bound}");
            if noise == 0.0 || c.bridge_holes {
                // Resting exactly (r1 + r2)/2 from the points (or, bridging, settled to that
                // height above the fitted plane, noise or not), it does stick. (The thesis's
                // proxy on a noisy cloud may rest near r2 and leave at once: eq. 23 is an upper
                // bound.)
                assert!(
                    stuck >= 1,
                    "ζ {zeta}: the proxy should stick for at least a step"
                );
            }
            // Then free, and at the HIP.
            let last = out.last().unwrap();
            assert_eq!(last.state, ContactState::Free);
            assert!(norm(sub(last.proxy_m, scale(n, 0.05))) < 1e-12);
        }
    }
}

/// Regression: on a 5 mm grid with 0.5 mm noise, the holes between points open to ~4.2 mm, wider
/// than the 4 mm stop radius of r1 = 3, r2 = 5 mm, and a slow press with tangential motion let
/// the proxy slip through in 0.7 % of trials. Within the noise-aware spacing bound the scenes
/// now enforce, `s < √2·((r1+r2)/2 − 3σ)`, it never does.
#[test]
fn no_punch_through_between_noisy_grid_points_within_the_noise_aware_spacing() {
    use mmt::cloud::Pose;
    use mmt::contact::{CloudIndex, Proxy, ProxyConfig};
    use rand::{Rng, SeedableRng};
    use sim::synthetic::{SceneObject, Shape, SyntheticCloud};
    let cfg = ProxyConfig {
        r1_m: 0.004,
        r2_m: 0.006,
        r3_m: 0.03,
        ..ProxyConfig::default()
    };
    let (spacing, noise) = (0.0045, 0.0005);
    assert!(spacing < std::f64::consts::SQRT_2 * ((cfg.r1_m + cfg.r2_m) / 2.0 - 3.0 * noise));
    let src = SyntheticCloud {
        objects: vec![SceneObject::fixed(
            Shape::Plane {
                size_x_m: 0.3,
                size_y_m: 0.3,
            },
            Pose::default(),
        )],
        spacing_m: spacing,
        noise_std_m: noise,
        dropout_fraction: 0.0,
        sensor_pose: Pose::default(),
    };
    let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
    for trial in 0..300 {
        let cloud = CloudIndex::build(&src.frame(trial, &mut rng).unwrap()).unwrap();
        let (x, y) = (rng.random_range(-0.05..0.05), rng.random_range(-0.05..0.05));
        let mut proxy = Proxy::new(cfg, [x, y, 0.01]).unwrap();
        for k in 0..2000 {
            let t = k as f64 * 1e-3;
            let z = (0.01 - 0.014 * (t / 0.5).min(1.0)).max(-0.004);
            let hip = [x + 0.02 * (3.0 * t).sin(), y + 0.03 * (1.7 * t).sin(), z];
            let out = proxy.step(hip, &cloud);
            assert!(
                out.proxy_m[2] > 0.0,
                "trial {trial} tick {k}: proxy at {:?}",
                out.proxy_m
            );
        }
    }
}
