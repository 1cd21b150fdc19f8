//! PointCloud2 decoding against hand-built messages: the bytes are written field by field here,
//! not by the crate's encoder.

use mmt::cloud::Pose;
use proptest::prelude::*;

use super::*;
use crate::msg::{Bytes, Header, PointCloud2, PointField};

/// How a test message lays out its points.
#[derive(Clone)]
struct Spec {
    /// `(name, offset, datatype, count)` of every field, in message order.
    fields: Vec<(&'static str, u32, u8, u32)>,
    point_step: u32,
    /// Extra bytes at the end of each row.
    row_padding: u32,
    big_endian: bool,
    width: u32,
}

fn put(buf: &mut [u8], offset: usize, datatype: u8, value: f64, big: bool) {
    macro_rules! w {
        ($t:ty) => {{
            let b = if big {
                (value as $t).to_be_bytes()
            } else {
                (value as $t).to_le_bytes()
            };
            buf[offset..offset + b.len()].copy_from_slice(&b);
        }};
    }
    match datatype {
        PointField::INT8 => w!(i8),
        PointField::UINT8 => w!(u8),
        PointField::INT16 => w!(i16),
        PointField::UINT16 => w!(u16),
        PointField::INT32 => w!(i32),
        PointField::UINT32 => w!(u32),
        PointField::FLOAT32 => w!(f32),
        PointField::FLOAT64 => w!(f64),
        _ => unreachable!(),
    }
}

/// A message of `points` (row-major, `spec.width` per row); fields other than x, y, z get
/// recognisable junk (their index), which the decoder must skip.
fn build(points: &[[f64; 3]], spec: &Spec) -> PointCloud2 {
    let width = spec.width as usize;
    assert_eq!(points.len() % width, 0);
    let height = points.len() / width;
    let row_step = spec.width * spec.point_step + spec.row_padding;
    let mut data = vec![0xAAu8; row_step as usize * height];
    for (i, p) in points.iter().enumerate() {
        let base = (i / width) * row_step as usize + (i % width) * spec.point_step as usize;
        for &(name, offset, datatype, count) in &spec.fields {
            let size = PointField::datatype_size(datatype).unwrap() as usize;
            for k in 0..count as usize {
                let value = match name {
                    "x" if k == 0 => p[0],
                    "y" if k == 0 => p[1],
                    "z" if k == 0 => p[2],
                    _ => (i % 100) as f64,
                };
                put(
                    &mut data,
                    base + offset as usize + k * size,
                    datatype,
                    value,
                    spec.big_endian,
                );
            }
        }
    }
    PointCloud2 {
        header: Header::default(),
        height: height as u32,
        width: spec.width,
        fields: spec
            .fields
            .iter()
            .map(|&(name, offset, datatype, count)| PointField {
                name: name.into(),
                offset,
                datatype,
                count,
            })
            .collect(),
        is_bigendian: spec.big_endian,
        point_step: spec.point_step,
        row_step,
        data: Bytes(data),
        is_dense: points.iter().all(|p| p.iter().all(|c| c.is_finite())),
    }
}

fn points(n: usize) -> Vec<[f64; 3]> {
    (0..n)
        .map(|i| {
            let f = i as f64;
            [
                0.001 * f - 0.2,
                (f * 0.37).sin() * 0.3,
                0.5 + (f * 0.11).cos() * 0.1,
            ]
        })
        .collect()
}

fn decode(msg: &PointCloud2, pose: &Pose) -> (Vec<[f32; 3]>, DecodeCounts) {
    let layout = Layout::of(msg).unwrap();
    let mut out = Vec::new();
    let counts = decode_into(msg, &layout, pose, &mut out);
    (out, counts)
}

fn assert_points(got: &[[f32; 3]], want: &[[f64; 3]], tol: f64) {
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(want) {
        for k in 0..3 {
            assert!((f64::from(g[k]) - w[k]).abs() <= tol, "{g:?} vs {w:?}");
        }
    }
}

const F32: u8 = PointField::FLOAT32;
const F64: u8 = PointField::FLOAT64;

fn xyz_packed() -> Spec {
    Spec {
        fields: vec![("x", 0, F32, 1), ("y", 4, F32, 1), ("z", 8, F32, 1)],
        point_step: 12,
        row_padding: 0,
        big_endian: false,
        width: 10,
    }
}

#[test]
fn every_layout_decodes_to_the_same_points() {
    let want = points(60);
    let layouts = [
        ("packed xyz float32", xyz_packed()),
        (
            "PCL PointXYZRGB: padding after z, rgb at 16, 32-byte points",
            Spec {
                fields: vec![
                    ("x", 0, F32, 1),
                    ("y", 4, F32, 1),
                    ("z", 8, F32, 1),
                    ("rgb", 16, F32, 1),
                ],
                point_step: 32,
                ..xyz_packed()
            },
        ),
        (
            "lidar: intensity, ring (u16), time (f64) and padding",
            Spec {
                fields: vec![
                    ("x", 0, F32, 1),
                    ("y", 4, F32, 1),
                    ("z", 8, F32, 1),
                    ("intensity", 16, F32, 1),
                    ("ring", 20, PointField::UINT16, 1),
                    ("t", 24, F64, 1),
                ],
                point_step: 48,
                ..xyz_packed()
            },
        ),
        (
            "fields out of order, z first",
            Spec {
                fields: vec![
                    ("z", 0, F32, 1),
                    ("rgb", 4, PointField::UINT32, 1),
                    ("y", 8, F32, 1),
                    ("x", 12, F32, 1),
                ],
                point_step: 16,
                ..xyz_packed()
            },
        ),
        (
            "float64 coordinates",
            Spec {
                fields: vec![("x", 0, F64, 1), ("y", 8, F64, 1), ("z", 16, F64, 1)],
                point_step: 24,
                ..xyz_packed()
            },
        ),
        (
            "big-endian float32 with an int8 field",
            Spec {
                fields: vec![
                    ("label", 0, PointField::INT8, 1),
                    ("x", 4, F32, 1),
                    ("y", 8, F32, 1),
                    ("z", 12, F32, 1),
                ],
                point_step: 16,
                big_endian: true,
                ..xyz_packed()
            },
        ),
        (
            "big-endian float64",
            Spec {
                fields: vec![
                    ("x", 0, F64, 1),
                    ("y", 8, F64, 1),
                    ("z", 16, F64, 1),
                    ("normal", 24, F32, 3),
                ],
                point_step: 40,
                big_endian: true,
                ..xyz_packed()
            },
        ),
        (
            "row padding (row_step > width · point_step)",
            Spec {
                row_padding: 7,
                ..xyz_packed()
            },
        ),
        (
            "count > 1 on a coordinate: the first element is the coordinate",
            Spec {
                fields: vec![("x", 0, F32, 2), ("y", 8, F32, 1), ("z", 12, F32, 1)],
                point_step: 16,
                ..xyz_packed()
            },
        ),
    ];
    for (what, spec) in layouts {
        let msg = build(&want, &spec);
        let (got, counts) = decode(&msg, &Pose::IDENTITY);
        let tol = if spec.fields.iter().any(|f| f.0 == "x" && f.2 == F64) {
            1e-7
        } else {
            1e-6
        };
        assert_eq!(counts.declared, 60, "{what}");
        assert_eq!(counts.non_finite, 0, "{what}");
        assert_points(&got, &want, tol);
    }
}

#[test]
fn the_camera_pose_maps_points_into_the_base_frame() {
    let want = points(20);
    let msg = build(&want, &xyz_packed());
    // A camera 0.5 m above the base, looking down (rotated π about x), shifted 0.1 m in x.
    let pose = Pose::from_rotation_vector([std::f64::consts::PI, 0.0, 0.0], [0.1, 0.0, 0.5]);
    let (got, _) = decode(&msg, &pose);
    let mapped: Vec<[f64; 3]> = want.iter().map(|p| pose.transform_point(*p)).collect();
    assert_points(&got, &mapped, 1e-6);
}

#[test]
fn nan_points_are_left_out_and_counted_whatever_is_dense_says() {
    let mut want = points(40);
    for i in [0, 7, 8, 39] {
        want[i][i % 3] = f64::NAN;
    }
    want[20][1] = f64::INFINITY;
    let mut msg = build(&want, &xyz_packed());
    assert!(!msg.is_dense);
    let (got, counts) = decode(&msg, &Pose::IDENTITY);
    assert_eq!((counts.non_finite, got.len()), (5, 35));
    let kept: Vec<[f64; 3]> = want
        .iter()
        .filter(|p| p.iter().all(|c| c.is_finite()))
        .copied()
        .collect();
    assert_points(&got, &kept, 1e-6);
    msg.is_dense = true; // a driver that lies
    assert_eq!(decode(&msg, &Pose::IDENTITY).1.non_finite, 5);
}

#[test]
fn an_organised_640_by_480_frame_with_holes() {
    let (w, h) = (640u32, 480u32);
    let mut pts = Vec::with_capacity((w * h) as usize);
    let mut holes = 0;
    for v in 0..h {
        for u in 0..w {
            // A plane 0.6 m away seen by a pinhole camera, NaN where a reflective patch and a
            // random 10 % dropout leave holes.
            let z = 0.6;
            let x = (f64::from(u) - 320.0) / 615.0 * z;
            let y = (f64::from(v) - 240.0) / 615.0 * z;
            let patch = (200..260).contains(&u) && (100..180).contains(&v);
            let random = (u * 7919 + v * 104_729) % 10 == 0;
            if patch || random {
                holes += 1;
                pts.push([f64::NAN; 3]);
            } else {
                pts.push([x, y, z]);
            }
        }
    }
    let spec = Spec {
        fields: vec![
            ("x", 0, F32, 1),
            ("y", 4, F32, 1),
            ("z", 8, F32, 1),
            ("rgb", 16, F32, 1),
        ],
        point_step: 32,
        width: w,
        ..xyz_packed()
    };
    let msg = build(&pts, &spec);
    assert_eq!((msg.width, msg.height), (640, 480));
    let (got, counts) = decode(&msg, &Pose::IDENTITY);
    assert_eq!(counts.declared, 307_200);
    assert_eq!(counts.non_finite, holes);
    assert_eq!(got.len(), 307_200 - holes);
    // Through the whole pipeline: voxel 4.5 mm and a budget.
    let mut pipeline = CloudPipeline::new(PipelineConfig {
        camera_to_base: Pose::from_translation([0.0, 0.0, -0.6]),
        voxel_m: Some(0.0045),
        max_points: 20_000,
    });
    let mut out = Vec::new();
    let frame = pipeline.process(&msg, &mut out).unwrap();
    assert!(frame.kept <= 20_000 && frame.kept > 10_000, "{frame:?}");
    assert!(
        out.iter().all(|p| p[2].abs() < 1e-5),
        "plane at z = 0 in the base frame"
    );
}

#[test]
fn the_packed_loop_and_the_general_one_agree_bit_for_bit() {
    let mut pts = points(60);
    pts[3] = [f64::NAN, 0.0, 0.0];
    pts[10][2] = f64::INFINITY;
    pts[11] = [f64::NEG_INFINITY, f64::NAN, 1.0];
    pts[20] = [2.0e6, 0.0, 0.0]; // beyond the frame limit once transformed
    pts[21] = [-0.0, 0.0, -0.0];
    pts[22] = [1e-40, -1e-45, 3.0e38];
    let pose = Pose::from_rotation_vector([0.3, -0.2, 0.1], [0.1, 0.0, 0.5]);
    let packed = Spec {
        fields: vec![("x", 4, F32, 1), ("y", 8, F32, 1), ("z", 12, F32, 1)],
        point_step: 20,
        ..xyz_packed()
    };
    let (a, counts) = decode(&build(&pts, &packed), &pose);
    let big_endian = Spec {
        big_endian: true,
        ..packed
    };
    let (b, counts_b) = decode(&build(&pts, &big_endian), &pose);
    let bits = |p: &[[f32; 3]]| p.iter().map(|p| p.map(f32::to_bits)).collect::<Vec<_>>();
    assert_eq!((bits(&a), counts), (bits(&b), counts_b));
    assert_eq!(
        (counts.non_finite, counts.out_of_range, a.len()),
        (3, 2, 55)
    );
    // Each kept point is R·p + t in f64, left to right, rounded to f32 once.
    let (r, t) = (pose.rotation, pose.translation_m);
    let want: Vec<[f32; 3]> = pts
        .iter()
        .map(|p| p.map(|c| f64::from(c as f32)))
        .map(|p| std::array::from_fn(|i| r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2] + t[i]))
        .filter(|w: &[f64; 3]| w.iter().all(|c| c.abs() <= 1e6))
        .map(|w| w.map(|c| c as f32))
        .collect();
    assert_eq!(bits(&a), bits(&want));
}

fn refused(msg: &PointCloud2) -> DecodeError {
    Layout::of(msg).unwrap_err()
}

#[test]
fn malformed_messages_are_refused_naming_the_field() {
    let good = build(&points(20), &xyz_packed());
    let mut short = good.clone();
    short.data.0.truncate(good.data.0.len() - 1);
    let e = refused(&short);
    assert!(
        matches!(
            e,
            DecodeError::DataTooShort {
                len: 239,
                needed: 240,
                ..
            }
        ),
        "{e}"
    );
    assert!(
        e.to_string()
            .contains("data has 239 bytes, expected at least 240"),
        "{e}"
    );

    let mut no_z = good.clone();
    no_z.fields.retain(|f| f.name != "z");
    let e = refused(&no_z);
    assert!(e.to_string().contains("no `z` field (fields: x, y)"), "{e}");

    for datatype in [PointField::UINT16, PointField::INT32, 0, 9, 255] {
        let mut bad = good.clone();
        bad.fields[1].datatype = datatype;
        let e = refused(&bad);
        assert_eq!(
            e,
            DecodeError::FieldType {
                axis: 'y',
                datatype
            },
            "{e}"
        );
        assert!(
            e.to_string()
                .contains("expected 7 (float32) or 8 (float64)")
        );
    }

    let mut zero = good.clone();
    zero.fields[0].count = 0;
    assert_eq!(refused(&zero), DecodeError::FieldCount { axis: 'x' });

    let mut outside = good.clone();
    outside.fields[2].offset = 9; // 9 + 4 > 12
    let e = refused(&outside);
    assert!(
        e.to_string()
            .contains("field `z` at offset 9 (4 bytes) does not fit in point_step 12"),
        "{e}"
    );

    let mut f64_outside = good.clone();
    f64_outside.fields[2].datatype = F64; // 8 + 8 > 12
    assert!(matches!(
        refused(&f64_outside),
        DecodeError::FieldOutsidePoint { .. }
    ));

    let mut rows = good.clone();
    rows.row_step = 119;
    assert!(
        refused(&rows)
            .to_string()
            .contains("row_step 119 < width 10 × point_step 12")
    );

    let mut huge = good.clone();
    huge.width = u32::MAX;
    huge.height = u32::MAX;
    assert!(matches!(refused(&huge), DecodeError::TooManyPoints { .. }));

    // The data length check is done in 64 bits: a step product that would wrap in 32 bits.
    let mut wrap = good.clone();
    wrap.height = 2;
    wrap.width = 1;
    wrap.point_step = 12;
    wrap.row_step = u32::MAX;
    assert!(matches!(refused(&wrap), DecodeError::DataTooShort { .. }));

    // An empty cloud is a valid cloud of no points.
    let mut empty = good.clone();
    empty.width = 0;
    empty.data.0.clear();
    let (got, counts) = decode(&empty, &Pose::IDENTITY);
    assert!(got.is_empty() && counts.declared == 0);
}

#[test]
fn points_beyond_the_frame_limit_are_left_out_and_counted() {
    let mut pts = points(10);
    pts[3] = [2.0e6, 0.0, 0.0];
    let msg = build(
        &pts,
        &Spec {
            fields: vec![("x", 0, F64, 1), ("y", 8, F64, 1), ("z", 16, F64, 1)],
            point_step: 24,
            ..xyz_packed()
        },
    );
    let (got, counts) = decode(&msg, &Pose::IDENTITY);
    assert_eq!((counts.out_of_range, got.len()), (1, 9));
}

#[test]
fn the_encoder_writes_what_realsense2_camera_sends() {
    let pts = [[0.1f32, -0.2, 0.3], [f32::NAN, 0.0, 0.0]];
    let msg = encode_xyz(&pts, "camera_depth_optical_frame", 1_500_000_000);
    assert_eq!(msg.point_step, 16);
    assert!(!msg.is_dense);
    assert_eq!(msg.header.stamp.sec, 1);
    let (got, counts) = decode(&msg, &Pose::IDENTITY);
    assert_eq!(got, vec![[0.1f32, -0.2, 0.3]]);
    assert_eq!(counts.non_finite, 1);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// Whatever the header fields say, decoding never panics: it refuses, or it reads inside
    /// the data.
    #[test]
    fn arbitrary_layouts_never_panic(
        width in 0u32..40,
        height in 0u32..6,
        point_step in 0u32..64,
        row_step in 0u32..2_000,
        big in any::<bool>(),
        fields in proptest::collection::vec((0usize..5, 0u32..70, 0u8..10, 0u32..4), 0..6),
        data_len in 0usize..4_000,
        fill in any::<u8>(),
    ) {
        let names = ["x", "y", "z", "rgb", "ring"];
        let msg = PointCloud2 {
            header: Header::default(),
            height,
            width,
            fields: fields
                .iter()
                .map(|&(n, offset, datatype, count)| PointField {
                    name: names[n].into(),
                    offset,
                    datatype,
                    count,
                })
                .collect(),
            is_bigendian: big,
            point_step,
            row_step,
            data: Bytes(vec![fill; data_len]),
            is_dense: false,
        };
        let mut pipeline = CloudPipeline::new(PipelineConfig {
            camera_to_base: Pose::IDENTITY,
            voxel_m: Some(0.01),
            max_points: 50,
        });
        let mut out = Vec::new();
        if let Ok(frame) = pipeline.process(&msg, &mut out) {
            prop_assert!(frame.kept <= 50);
            prop_assert!(frame.decode.declared == (width * height) as usize);
        }
    }
}
