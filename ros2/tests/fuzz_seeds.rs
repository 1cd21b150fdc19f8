//! The fuzz seeds of the `pointcloud2` target (`fuzz/seeds/pointcloud2/`: `sensor_msgs/
//! PointCloud2` messages in little-endian CDR), and the CI equivalent of that target: arbitrary
//! bytes and mutated seeds, decoded with `cdr-encoding` (what RustDDS uses) and run through the
//! camera's pipeline, are refused or give finite in-range points within the budget. Never a
//! panic.
//!
//! `MMT_WRITE_FUZZ_SEEDS=1 cargo test -p ros2 --test fuzz_seeds` rewrites the seeds; without it
//! the test checks that the checked-in files are current.
#![allow(clippy::unwrap_used)]

use std::path::PathBuf;

use byteorder::LittleEndian;
use mmt::cloud::{CloudFrame, Pose};
use proptest::prelude::*;
use proptest::sample::Index;
use ros2::msg::{Bytes, Header, PointCloud2, PointField, Time};
use ros2::pointcloud2::{CloudPipeline, PipelineConfig, encode_xyz};

const BUDGET: usize = 2_000;

/// An organised 2 × 2 cloud with `float64` coordinates and a `float32` intensity, big-endian
/// data, rows padded by 4 bytes.
fn organised_f64_big_endian() -> PointCloud2 {
    let field = |name: &str, offset, datatype| PointField {
        name: name.to_owned(),
        offset,
        datatype,
        count: 1,
    };
    let points = [
        [0.1, 0.2, 0.3],
        [f64::NAN; 3],
        [-1.0, 2.0, 0.5],
        [1e3, -1e3, 0.0],
    ];
    let mut data = Vec::new();
    for (i, p) in points.iter().enumerate() {
        for c in p {
            data.extend_from_slice(&c.to_be_bytes());
        }
        data.extend_from_slice(&(i as f32).to_be_bytes());
        if i % 2 == 1 {
            data.extend_from_slice(&[0xAA; 4]);
        }
    }
    PointCloud2 {
        header: Header {
            stamp: Time::from_nanos(1_700_000_000_123_456_789),
            frame_id: "camera_link".to_owned(),
        },
        height: 2,
        width: 2,
        fields: vec![
            field("x", 0, PointField::FLOAT64),
            field("y", 8, PointField::FLOAT64),
            field("z", 16, PointField::FLOAT64),
            field("intensity", 24, PointField::FLOAT32),
        ],
        is_bigendian: true,
        point_step: 28,
        row_step: 60,
        data: Bytes(data),
        is_dense: false,
    }
}

fn seeds() -> Vec<(&'static str, Vec<u8>)> {
    let cdr = |msg: &PointCloud2| cdr_encoding::to_vec::<_, LittleEndian>(msg).unwrap();
    let pts = [
        [0.1f32, -0.2, 0.3],
        [f32::NAN; 3],
        [0.5, 0.5, 1.25],
        [-2.0, 0.0, 4.0],
    ];
    vec![
        (
            "realsense.cdr",
            cdr(&encode_xyz(
                &pts,
                "camera_depth_optical_frame",
                1_500_000_000,
            )),
        ),
        ("empty.cdr", cdr(&encode_xyz(&[], "camera", 0))),
        ("organised_f64_be.cdr", cdr(&organised_f64_big_endian())),
    ]
}

#[test]
fn every_seed_decodes_and_is_checked_in() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fuzz/seeds/pointcloud2");
    let write = std::env::var_os("MMT_WRITE_FUZZ_SEEDS").is_some();
    for (name, bytes) in seeds() {
        let kept = check(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(kept.is_some(), "{name}: the seed must decode");
        let path = dir.join(name);
        if write {
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(&path, &bytes).unwrap();
        }
        let on_disk = std::fs::read(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(
            on_disk == bytes,
            "{name} is stale: rerun with MMT_WRITE_FUZZ_SEEDS=1"
        );
    }
}

/// Decodes `bytes` and runs the pipeline with and without a voxel grid; `Some(points kept)` if
/// the CDR decodes. Kept points must make a frame, within the budget.
fn check(bytes: &[u8]) -> Result<Option<usize>, TestCaseError> {
    let Ok((msg, _)) = cdr_encoding::from_bytes::<PointCloud2, LittleEndian>(bytes) else {
        return Ok(None);
    };
    let _ = msg.header.stamp.to_nanos();
    let camera_to_base = Pose::from_quaternion([0.9, 0.1, -0.3, 0.2], [0.5, -0.25, 1.0]).unwrap();
    let mut kept = 0;
    for voxel_m in [None, Some(0.01)] {
        let mut pipeline = CloudPipeline::new(PipelineConfig {
            camera_to_base,
            voxel_m,
            max_points: BUDGET,
        });
        let mut out = Vec::new();
        if let Ok(frame) = pipeline.process(&msg, &mut out) {
            prop_assert!(out.len() <= BUDGET);
            prop_assert_eq!(frame.kept, out.len());
            kept = out.len();
            prop_assert!(CloudFrame::new(out, 0, Pose::IDENTITY).is_ok());
        }
    }
    Ok(Some(kept))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1024))]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..256)) {
        check(&bytes)?;
    }

    #[test]
    fn mutated_seeds_never_panic(
        which in any::<Index>(),
        edits in prop::collection::vec((any::<Index>(), any::<u8>()), 1..6),
        cut in prop::option::of(any::<Index>()),
    ) {
        let all = seeds();
        let mut bytes = all[which.index(all.len())].1.clone();
        for (at, value) in edits {
            let i = at.index(bytes.len());
            bytes[i] = value;
        }
        if let Some(c) = cut {
            bytes.truncate(c.index(bytes.len() + 1));
        }
        check(&bytes)?;
    }
}
