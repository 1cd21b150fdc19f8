use super::*;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

/// Points within `r` of `c`, counted one by one.
fn count_within(points: &[[f32; 3]], c: [f64; 3], r: f64) -> usize {
    points
        .iter()
        .filter(|p| {
            let d: f64 = (0..3).map(|i| (f64::from(p[i]) - c[i]).powi(2)).sum();
            d <= r * r
        })
        .count()
}

/// A square grid of `n × n` points of spacing `s` [m] in the plane `z = 0`, from the origin.
fn grid(n: usize, s: f64) -> Vec<[f32; 3]> {
    (0..n)
        .flat_map(|i| (0..n).map(move |j| [(i as f64 * s) as f32, (j as f64 * s) as f32, 0.0]))
        .collect()
}

#[test]
fn the_grid_bound_is_the_cell_bound_of_a_grid() {
    // R = 2.5 s: cells of 1.2506 s, five span 6.253 s, 7 points per axis: 49. The exact most
    // is 21 at a grid point (Gauss's circle problem: 5 + 2·5 + 2·3).
    assert_eq!(grid_points_in_ball(1.0, 2.5), Ok(49));
    assert_eq!(grid_points_in_ball(0.001, 0.0025), Ok(49));
    let g = grid(20, 0.001);
    assert_eq!(count_within(&g, [0.010, 0.010, 0.0], 0.0025), 21);
    let mut rng = Pcg64::seed_from_u64(3);
    let mut worst = 0;
    for _ in 0..2_000 {
        let c = [0; 3].map(|_| rng.random_range(0.007..0.012));
        worst = worst.max(count_within(&g, [c[0], c[1], 0.0], 0.0025));
    }
    assert!((21..=49).contains(&worst), "{worst}");
    // On real grids the cell bound never exceeds the formula and reaches at least (⌊5c/s⌋)².
    for (n, s, r) in [
        (120, 0.001, 0.0185),
        (200, 0.0005, 0.01),
        (60, 0.0045, 0.04625),
    ] {
        let computed = points_in_ball(&grid(n, s), r).unwrap();
        let formula = grid_points_in_ball(s, r).unwrap();
        let floor = (5.0 * r / 1.999 / s).floor().powi(2) as usize;
        assert!(
            (floor..=formula).contains(&computed),
            "{computed} vs {formula}"
        );
    }
    // The exp-1 window that stalled the loops (0.25 m at 0.113 mm, 4.9 M points): about a
    // million points really in the 61 mm query ball (the wide plane's, 2 r3 + the margin), a
    // bound of 1.8 million.
    let exp1 = ProxyConfig {
        r1_m: 0.004,
        r2_m: 0.006,
        r3_m: 0.03,
        ..ProxyConfig::default()
    };
    let r = query_radius_m(&exp1);
    assert!((r - 0.06125).abs() < 1e-12, "{r}");
    assert_eq!(grid_points_in_ball(0.000113, r), Ok(1356 * 1356));
    // The thesis's proxy (no bridging) queries half a sweep segment + r3: 46.25 mm.
    let points_only = ProxyConfig {
        bridge_holes: false,
        ..exp1
    };
    assert!((query_radius_m(&points_only) - 0.04625).abs() < 1e-12);
}

#[test]
fn the_cell_bound_is_exact_on_simple_clouds() {
    assert_eq!(points_in_ball(&[], 0.01), Ok(0));
    assert_eq!(points_in_ball(&[[0.3, -0.2, 0.1]], 0.01), Ok(1));
    assert_eq!(points_in_ball(&[[0.5; 3]; 7], 0.01), Ok(7));
    // Two points 1 m apart: no ball of 1 cm holds both; 1 mm apart: one does.
    assert_eq!(points_in_ball(&[[0.0; 3], [1.0, 0.0, 0.0]], 0.01), Ok(1));
    assert_eq!(points_in_ball(&[[0.0; 3], [0.001, 0.0, 0.0]], 0.01), Ok(2));
    // A line of 101 points 1 mm apart, R = 10 mm: the 5 cells of 5.0025 mm along it span
    // 25 mm, 25 or 26 points of the line; the true most is 21.
    let line: Vec<[f32; 3]> = (0..101).map(|i| [i as f32 * 0.001, 0.0, 0.0]).collect();
    let b = points_in_ball(&line, 0.01).unwrap();
    assert!((21..=26).contains(&b), "{b}");
}

#[test]
fn the_cell_bound_holds_on_grids_and_noise_and_is_within_three_times() {
    let mut rng = Pcg64::seed_from_u64(11);
    let g = grid(120, 0.001);
    let noisy: Vec<[f32; 3]> = g
        .iter()
        .map(|p| p.map(|v| v + rng.random_range(-0.0005f32..0.0005)))
        .collect();
    for points in [&g, &noisy] {
        for r in [0.003, 0.0125, 0.0185] {
            let bound = points_in_ball(points, r).unwrap();
            let mut worst = 0;
            for _ in 0..300 {
                let c = [0; 3].map(|_| rng.random_range(0.02..0.1));
                worst = worst.max(count_within(points, [c[0], c[1], c[2] * 0.01], r));
            }
            assert!(worst <= bound, "r {r}: {worst} > {bound}");
            assert!(bound <= 3 * worst, "r {r}: {bound} vs {worst}");
        }
    }
}

#[test]
fn garbage_gives_errors_that_name_the_value() {
    for r in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            points_in_ball(&[[0.0; 3]], r),
            Err(BudgetError::NotPositive {
                field: "radius_m",
                ..
            })
        ));
        assert!(grid_points_in_ball(0.001, r).is_err());
        assert!(grid_points_in_ball(r, 0.01).is_err());
    }
    let e = points_in_ball(&[[0.0; 3], [0.0, f32::NAN, 0.0]], 0.01).unwrap_err();
    assert!(
        matches!(e, BudgetError::NonFinitePoint { index: 1, point } if point[1].is_nan()),
        "{e:?}"
    );
    assert!(e.to_string().contains("point 1"), "{e}");
    assert!(
        grid_points_in_ball(-0.001, 0.01)
            .unwrap_err()
            .to_string()
            .contains("spacing_m = -0.001 m")
    );
}

#[test]
fn the_budget_refuses_the_finding_and_passes_the_scenes() {
    let b = CloudBudget::default();
    let exp1 = ProxyConfig {
        r1_m: 0.004,
        r2_m: 0.006,
        r3_m: 0.03,
        ..ProxyConfig::default()
    };
    let r = query_radius_m(&exp1);
    // The limit follows the figures: (share · tick − fixed) / per point.
    let limit = ((b.step_share * 1e6 - b.step_fixed_ns) / b.step_ns_per_point) as usize;
    assert_eq!(b.max_points_in_ball(&exp1), limit);
    // The shipped scenes: 0.25 m at 4.5 mm, 30 Hz.
    let ok = b.load(
        &exp1,
        56 * 56,
        grid_points_in_ball(0.0045, r).unwrap(),
        Some(30.0),
    );
    assert_eq!(b.check(&exp1, &ok), Ok(()));
    assert_eq!(b.spacing_factor(&exp1, &ok), 1.0);
    // The finding: 4.9 M points and 1 M points at 30 Hz.
    for (spacing, points) in [(0.000113, 4_900_000), (0.00025, 1_000_000)] {
        let load = b.load(
            &exp1,
            points,
            grid_points_in_ball(spacing, r).unwrap(),
            Some(30.0),
        );
        let e = b.check(&exp1, &load).unwrap_err();
        assert!(matches!(e, OverBudget::Step { .. }), "{e}");
        assert!(e.to_string().contains("61.2 mm query radius"), "{e}");
        // Growing the spacing by the factor brings both parts in.
        let f = b.spacing_factor(&exp1, &load);
        let s = spacing * f * 1.001;
        let fitted = b.load(
            &exp1,
            (points as f64 / (f * f)) as usize,
            grid_points_in_ball(s, r).unwrap(),
            Some(30.0),
        );
        assert!(fitted.points_in_ball <= b.max_points_in_ball(&exp1) * 11 / 10);
        assert!(fitted.points <= b.max_points(Some(30.0)));
    }
    // Frames: the rate divides the index share; a static cloud is held to `max_points`.
    let per_frame = (b.index_share * 1e9 / (30.0 * b.build_ns_per_point)) as usize;
    assert_eq!(b.max_points(Some(30.0)), per_frame.min(b.max_points));
    assert_eq!(b.max_points(None), b.max_points);
    let big = b.load(&exp1, b.max_points + 1, 10, None);
    assert!(matches!(
        b.check(&exp1, &big),
        Err(OverBudget::Frame { .. })
    ));
}
