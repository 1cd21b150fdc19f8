//! The voxel grid against its definition: [`voxel_downsample`] and [`VoxelGrid`] against a
//! reference written as plainly as the module doc states it (a map from voxel index to the sum
//! of its points), compared bit for bit.

use std::collections::BTreeMap;

use proptest::prelude::*;

use super::grid::Way;
use super::*;

/// One centroid per voxel `⌊c / s⌋`, summed in `f64` from 0 in input order, in index order;
/// `None` where the definition refuses (a non-finite coordinate, an index beyond 2^53).
fn reference(points: &[[f32; 3]], voxel_m: f64) -> Option<Vec<[f32; 3]>> {
    let mut voxels: BTreeMap<[i64; 3], ([f64; 3], usize)> = BTreeMap::new();
    for p in points {
        let mut key = [0i64; 3];
        for k in 0..3 {
            let q = (f64::from(p[k]) / voxel_m).floor();
            if !(q.abs() <= 9_007_199_254_740_992.0) {
                return None;
            }
            key[k] = q as i64;
        }
        let (sum, n) = voxels.entry(key).or_insert(([0.0; 3], 0));
        for k in 0..3 {
            sum[k] += f64::from(p[k]);
        }
        *n += 1;
    }
    Some(
        voxels
            .values()
            .map(|(sum, n)| sum.map(|s| (s / *n as f64) as f32))
            .collect(),
    )
}

fn bits(points: &[[f32; 3]]) -> Vec<[u32; 3]> {
    points.iter().map(|p| p.map(f32::to_bits)).collect()
}

/// Checks [`voxel_downsample`] and `grid` on `points` against [`reference`], bit for bit (or
/// the same refusal); the way the grid took.
fn check(grid: &mut VoxelGrid, points: &[[f32; 3]], voxel_m: f64) -> &'static str {
    let mut out = vec![[9.0; 3]]; // cleared by the grid
    let got = grid.downsample(points, voxel_m, &mut out);
    let definition = voxel_downsample(points, voxel_m);
    match reference(points, voxel_m) {
        Some(want) => {
            assert_eq!(got, Ok(()), "voxel {voxel_m}: {points:?}");
            assert_eq!(bits(&out), bits(&want), "grid, voxel {voxel_m}: {points:?}");
            let definition = definition.expect("the definition agrees");
            assert_eq!(
                bits(&definition),
                bits(&want),
                "definition, voxel {voxel_m}"
            );
        }
        None => {
            assert!(definition.is_err(), "voxel {voxel_m}: {points:?}");
            // As text: a NaN in the error is not equal to itself.
            let (got, definition) = (format!("{got:?}"), format!("{:?}", definition.map(|_| ())));
            assert_eq!(got, definition, "the grid's error is the definition's");
        }
    }
    match grid.way() {
        Way::Empty => "empty",
        Way::Dense { .. } => "dense",
        Way::Sorted { .. } => "sorted",
        Way::Definition => "definition",
    }
}

/// A camera-like surface: `w × h` points 1 mm apart on a rippled plane, some of them holes
/// (left out).
fn surface(w: usize, h: usize, z_m: f32) -> Vec<[f32; 3]> {
    (0..w * h)
        .filter(|i| i % 11 != 3)
        .map(|i| {
            let (u, v) = ((i % w) as f32, (i / w) as f32);
            [
                u * 0.001 - 0.2,
                0.15 - v * 0.001,
                z_m + 0.001 * (u * 0.05).sin(),
            ]
        })
        .collect()
}

#[test]
fn every_way_gives_the_reference_bit_for_bit() {
    let mut grid = VoxelGrid::new();
    // One grid for every cloud: buffers left from a larger or another-way cloud change nothing.
    let camera = surface(200, 150, 0.6);
    for v in [0.001, 0.003, 0.0045, 0.02, 0.25, 10.0] {
        assert_eq!(check(&mut grid, &camera, v), "dense", "voxel {v}");
    }
    // Sparse: a few points over metres at 1 mm (and 10 µm: 49 key bits).
    let sparse: Vec<[f32; 3]> = camera
        .iter()
        .step_by(97)
        .map(|p| p.map(|c| c * 9.0))
        .collect();
    for v in [0.001, 1e-5] {
        assert_eq!(check(&mut grid, &sparse, v), "sorted", "voxel {v}");
    }
    // Far from the origin: indices beyond ±2^20, where the hash grid this replaced fell back.
    let offset: Vec<[f32; 3]> = camera
        .iter()
        .step_by(13)
        .map(|p| [p[0] + 4.0e5, p[1] - 3.0e5, p[2] * 50.0])
        .collect();
    assert_eq!(check(&mut grid, &offset, 0.01), "dense");
    assert_eq!(check(&mut grid, &offset, 1e-4), "sorted");
    // ±1,000 km: at 100 m, 45 key bits; at 1 mm, 2^31 voxels an axis, more bits than a word
    // holds.
    let far = [[1.0e6, 0.0, 0.0], [-1.0e6, 1.0e6, -1.0e6], [0.5, -0.5, 1e6]];
    assert_eq!(check(&mut grid, &far, 100.0), "sorted");
    assert_eq!(check(&mut grid, &far, 1e-3), "definition");
    // Beyond ±2^51 voxels: the definition's own answer (2^53 still fits it).
    assert_eq!(check(&mut grid, &far, 1e-9), "definition");
    assert_eq!(check(&mut grid, &far, 1e-12), "definition"); // its IndexOverflow
    assert_eq!(check(&mut grid, &[], 0.01), "empty");
    for single in [[0.0; 3], [-0.0; 3], [1.5, -2.5, 1e-40]] {
        assert_eq!(check(&mut grid, &[single], 0.01), "dense");
    }
}

#[test]
fn points_on_voxel_faces_negative_zero_and_tiny_coordinates() {
    let mut grid = VoxelGrid::new();
    // At 0.25 m (a power of two) `c / s` is exact: points on the faces of voxels, and a hair
    // either side.
    let faces: Vec<[f32; 3]> = (-8..8)
        .flat_map(|n| {
            let c = n as f32 * 0.25;
            [c, c.next_down(), c.next_up()].map(|c| [c, -c, c * 0.5])
        })
        .collect();
    assert_eq!(check(&mut grid, &faces, 0.25), "dense");
    assert_eq!(check(&mut grid, &faces, 0.1), "dense");
    // -0.0 sums to +0.0 from 0 (a grid that started a sum from the first point kept -0.0);
    // subnormal and tiny negative coordinates fall in voxel -1.
    let tiny = [
        [-0.0, 0.0, -0.0],
        [-1e-45, 1e-45, -1e-38],
        [f32::MIN_POSITIVE, -f32::MIN_POSITIVE, 0.0],
    ];
    assert_eq!(check(&mut grid, &tiny, 0.003), "dense");
    assert_eq!(check(&mut grid, &tiny[..1], 0.003), "dense");
}

#[test]
fn garbage_is_refused_as_the_definition_refuses_it_never_a_panic() {
    let mut grid = VoxelGrid::new();
    let mut out = Vec::new();
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let points = [[0.1, 0.2, 0.3], [0.1, bad, 0.3], [bad, 0.0, 0.0]];
        assert_eq!(check(&mut grid, &points, 0.01), "definition");
        let e = grid.downsample(&points, 0.01, &mut out).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!("point 1: coordinate {bad} is not finite")
        );
    }
    // Enormous coordinates at small and huge voxels, subnormal voxels: an error or an answer.
    let huge = [[f32::MAX, f32::MIN, 0.0], [3.0e38, -3.0e38, 1e-45]];
    for v in [1e-300, f64::MIN_POSITIVE, 1e-3, 1.0, 1e30, 1e300, f64::MAX] {
        check(&mut grid, &huge, v);
        check(&mut grid, &[[1.0, -1.0, 0.5]], v);
    }
    for v in [0.0, -0.0, -1.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        assert_eq!(
            grid.downsample(&huge, v, &mut out)
                .map_err(|e| e.to_string()),
            Err(VoxelError::InvalidSize { value: v }.to_string())
        );
    }
}

#[test]
fn centroid_per_voxel_in_index_order() {
    let points = [
        [0.15, 0.05, 0.05],
        [-0.05, 0.05, 0.05], // voxel (-1, 0, 0)
        [0.05, 0.05, 0.05],
        [0.11, 0.01, 0.01], // voxel (1, 0, 0) with the first
        [0.01, 0.03, 0.09],
    ];
    let out = voxel_downsample(&points, 0.1).unwrap();
    assert_eq!(out.len(), 3);
    let expect = [[-0.05, 0.05, 0.05], [0.03, 0.04, 0.07], [0.13, 0.03, 0.03]];
    for (o, e) in out.iter().zip(expect) {
        for k in 0..3 {
            assert!((o[k] - e[k]).abs() < 1e-7, "{out:?}");
        }
    }
}

#[test]
fn output_does_not_depend_on_input_order_beyond_rounding() {
    let points: Vec<[f32; 3]> = (0..1000)
        .map(|i| {
            let f = i as f32;
            [(f * 0.37).sin(), (f * 0.11).cos(), (f * 0.07).sin() * 0.5]
        })
        .collect();
    let a = voxel_downsample(&points, 0.25).unwrap();
    let mut reversed = points.clone();
    reversed.reverse();
    let b = voxel_downsample(&reversed, 0.25).unwrap();
    assert_eq!(a.len(), b.len());
    for (p, q) in a.iter().zip(&b) {
        for k in 0..3 {
            assert!((p[k] - q[k]).abs() < 1e-6);
        }
    }
    assert!(a.len() < points.len());
}

#[test]
fn rejects_bad_voxel_sizes() {
    for v in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            voxel_downsample(&[[0.0; 3]], v),
            Err(VoxelError::InvalidSize { .. })
        ));
    }
    assert!(matches!(
        voxel_downsample(&[[1.0e6, 0.0, 0.0]], 1e-12),
        Err(VoxelError::IndexOverflow { index: 0, .. })
    ));
    assert_eq!(voxel_downsample(&[], 0.1).unwrap(), Vec::<[f32; 3]>::new());
}

#[test]
fn the_grid_gives_the_sorted_result_bit_for_bit() {
    let points: Vec<[f32; 3]> = (0..20_000)
        .map(|i| {
            let f = i as f32;
            [
                (f * 0.37).sin() * 0.3,
                (f * 0.11).cos() * 0.2,
                (f * 0.07).sin() * 0.05 - 0.5,
            ]
        })
        .collect();
    let mut grid = VoxelGrid::new();
    let mut out = Vec::new();
    for v in [0.001, 0.0045, 0.02, 0.25, 10.0] {
        grid.downsample(&points, v, &mut out).unwrap();
        assert_eq!(out, voxel_downsample(&points, v).unwrap(), "voxel {v}");
    }
    // Beyond the packed range: the sorting path, same answer.
    let far = [[9.0e5, 0.0, 0.0], [9.0e5, 1e-4, 0.0], [-9.0e5, 0.0, 0.0]];
    grid.downsample(&far, 0.001, &mut out).unwrap();
    assert_eq!(out, voxel_downsample(&far, 0.001).unwrap());
    assert!(matches!(
        grid.downsample(&[[f32::NAN, 0.0, 0.0]], 0.01, &mut out),
        Err(VoxelError::NonFinite { index: 0, .. })
    ));
    assert!(matches!(
        grid.downsample(&points, 0.0, &mut out),
        Err(VoxelError::InvalidSize { .. })
    ));
}

#[test]
fn the_budget_coarsens_until_the_cloud_fits() {
    // A 1 mm grid of 200 × 200 points on a plane.
    let points: Vec<[f32; 3]> = (0..40_000)
        .map(|i| [(i % 200) as f32 * 0.001, (i / 200) as f32 * 0.001, 0.0])
        .collect();
    let mut grid = VoxelGrid::new();
    let mut out = Vec::new();
    let (v, acted) = grid
        .downsample_to_budget(&points, Some(0.002), 50_000, &mut out)
        .unwrap();
    assert_eq!((v, acted, out.len()), (Some(0.002), false, 10_000));
    let (v, acted) = grid
        .downsample_to_budget(&points, Some(0.002), 1_000, &mut out)
        .unwrap();
    assert!(
        acted && out.len() <= 1_000 && out.len() > 300,
        "{v:?} {}",
        out.len()
    );
    let (v, acted) = grid
        .downsample_to_budget(&points, None, 2_000, &mut out)
        .unwrap();
    assert!(
        acted && v.is_some() && out.len() <= 2_000,
        "{v:?} {}",
        out.len()
    );
    let (v, acted) = grid
        .downsample_to_budget(&points, None, 40_000, &mut out)
        .unwrap();
    assert_eq!((v, acted, out.len()), (None, false, 40_000));
}

/// A coordinate: on a face of a 0.25 m voxel or a hair beside it, in a 10 cm cluster, or
/// anywhere in ±10 m.
fn coordinate() -> impl Strategy<Value = f32> {
    prop_oneof![
        2 => (-40i32..40, -1i32..=1).prop_map(|(n, hair)| {
            let c = n as f32 * 0.25;
            [c.next_down(), c, c.next_up()][(hair + 1) as usize]
        }),
        8 => -0.05f32..0.05,
        1 => -10.0f32..10.0,
    ]
}

fn voxel() -> impl Strategy<Value = f64> {
    prop_oneof![
        prop::sample::select(vec![0.25, 0.003, 0.01, 0.1, 1e-6, 7.0]),
        1e-4f64..2.0,
    ]
}

/// Clouds of up to 300 points; one in eight with an extreme coordinate somewhere (zeros,
/// subnormals, ±3·10^38, 10^6), one in eight with a NaN or an infinity.
fn cloud() -> impl Strategy<Value = Vec<[f32; 3]>> {
    let points = prop::collection::vec([coordinate(), coordinate(), coordinate()], 0..300);
    let value = |values: Vec<f32>| {
        let at = (
            any::<prop::sample::Index>(),
            0usize..3,
            prop::sample::select(values),
        );
        prop::option::weighted(0.125, at)
    };
    let extreme = value(vec![0.0, -0.0, 1e-45, -1e-38, 3.0e38, -3.0e38, 1e6]);
    let poison = value(vec![f32::NAN, f32::INFINITY, f32::NEG_INFINITY]);
    (points, extreme, poison).prop_map(|(mut points, extreme, poison)| {
        for (at, k, c) in [extreme, poison].into_iter().flatten() {
            if !points.is_empty() {
                let at = at.index(points.len());
                points[at][k] = c;
            }
        }
        points
    })
}

/// The budget as it was first written (and as its doc states it): every round a full
/// [`voxel_downsample`] from the points, the edge grown by `√(n / max)`, at least 10 %.
fn budget_reference(
    points: &[[f32; 3]],
    voxel_m: Option<f64>,
    max_points: usize,
) -> Result<(Option<f64>, Vec<[f32; 3]>), VoxelError> {
    let mut voxel = voxel_m;
    let mut kept = match voxel {
        Some(v) => voxel_downsample(points, v)?,
        None => points.to_vec(),
    };
    for _ in 0..16 {
        if kept.len() <= max_points.max(1) {
            break;
        }
        let grow = (kept.len() as f64 / max_points.max(1) as f64)
            .sqrt()
            .max(1.1);
        let coarser = voxel.unwrap_or_else(|| initial_voxel(points)) * grow;
        kept = voxel_downsample(points, coarser)?;
        voxel = Some(coarser);
    }
    Ok((voxel, kept))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1024))]

    #[test]
    fn random_clouds_give_the_reference_bit_for_bit(points in cloud(), v in voxel()) {
        check(&mut VoxelGrid::new(), &points, v);
    }

    /// The budget's answer is the downsample at the edge it reports, within the budget unless
    /// its 16 rounds ran out, and coarser than the edge configured only if it acted.
    #[test]
    fn the_budget_is_honoured(
        points in cloud(),
        v in prop::option::of(voxel()),
        max_points in 0usize..300,
    ) {
        let mut grid = VoxelGrid::new();
        let mut out = vec![[9.0; 3]]; // cleared by the grid
        let got = grid.downsample_to_budget(&points, v, max_points, &mut out);
        match (&got, budget_reference(&points, v, max_points)) {
            (Ok((voxel, _)), Ok((want_voxel, want))) => {
                prop_assert_eq!(voxel.map(f64::to_bits), want_voxel.map(f64::to_bits));
                prop_assert_eq!(bits(&out), bits(&want));
            }
            (Err(e), Err(want)) => {
                prop_assert_eq!(format!("{e:?}"), format!("{want:?}"));
                prop_assert!(out.is_empty());
            }
            (got, want) => prop_assert!(false, "{got:?} vs {want:?}"),
        }
        let Ok((voxel, acted)) = got else {
            prop_assert!(v.is_some_and(|v| voxel_downsample(&points, v).is_err()) || points.len() > max_points.max(1));
            return Ok(());
        };
        let want = match voxel {
            Some(voxel) => voxel_downsample(&points, voxel).unwrap(),
            None => points.clone(),
        };
        prop_assert_eq!(bits(&out), bits(&want));
        prop_assert_eq!(acted, voxel != v);
        if !acted {
            prop_assert!(out.len() <= max_points.max(1));
        }
        if out.len() > max_points.max(1) {
            // Only after 16 rounds of growth by 10 % or more.
            let grown = voxel.unwrap() / v.unwrap_or_else(|| initial_voxel(&points));
            prop_assert!(grown >= 1.1f64.powi(15), "{grown}");
        }
    }
}

#[test]
fn a_camera_frame_is_held_to_its_budget() {
    let camera = surface(640, 480, 0.6);
    let mut grid = VoxelGrid::new();
    let mut out = Vec::new();
    for (max, acts) in [(20_000, true), (5_000, true), (200_000, false)] {
        let (voxel, acted) = grid
            .downsample_to_budget(&camera, Some(0.003), max, &mut out)
            .unwrap();
        assert!(out.len() <= max && acted == acts, "{max}: {}", out.len());
        assert_eq!(
            bits(&out),
            bits(&reference(&camera, voxel.unwrap()).unwrap())
        );
    }
}
