//! The camera path's cost per frame: a 640×480 organised `sensor_msgs/PointCloud2` (307,200
//! points, `realsense2_camera`'s layout, ~12 % NaN holes) decoded, transformed into the base
//! frame and voxel-downsampled (issue 14's target: ≤ 10 ms per frame on this machine), and each
//! stage alone:
//! - `decode_transform`: decoding alone;
//! - `decode_transform_voxel_3mm`: the pipeline at 3 mm (33,545 points kept, budget idle);
//! - `decode_transform_voxel_4.5mm_budget_20k`: at 4.5 mm (15,170 points, budget idle);
//! - `decode_transform_voxel_3mm_budget_20k`: at 3 mm with the budget acting (two more
//!   rounds, at 3.9 and 4.3 mm: 16,798 points), the worst case of the three;
//! - `decode_transform_voxel_3mm_definition`: decoding and `voxel_downsample` (the sort of
//!   every point that defines the grid's result): the baseline in the same run.
//!
//! ```sh
//! cargo bench -p ros2 --bench pointcloud2
//! ```

use std::hint::black_box;

use cloud_io::voxel::voxel_downsample;
use criterion::{Criterion, criterion_group, criterion_main};
use mmt::cloud::Pose;
use ros2::msg::PointCloud2;
use ros2::pointcloud2::{CloudPipeline, Layout, PipelineConfig, decode_into, encode_xyz};

/// A table 0.6 m below a pinhole camera (615 px focal length), 1 mm of ripple, NaN where a dark
/// patch and a 10 % scatter leave holes.
fn frame() -> PointCloud2 {
    let (w, h) = (640u32, 480u32);
    let mut points = Vec::with_capacity((w * h) as usize);
    for v in 0..h {
        for u in 0..w {
            let patch = (200..260).contains(&u) && (100..180).contains(&v);
            let scatter = (u * 7919 + v * 104_729) % 10 == 0;
            if patch || scatter {
                points.push([f32::NAN; 3]);
                continue;
            }
            let z = 0.6 + 0.001 * ((u as f32) * 0.05).sin();
            let x = (u as f32 - 320.0) / 615.0 * z;
            let y = (v as f32 - 240.0) / 615.0 * z;
            points.push([x, y, z]);
        }
    }
    let mut msg = encode_xyz(&points, "camera_depth_optical_frame", 0);
    // Organised: 480 rows of 640.
    msg.height = h;
    msg.width = w;
    msg.row_step = w * msg.point_step;
    msg
}

fn pointcloud2(c: &mut Criterion) {
    let msg = frame();
    // base ← camera: looking down from 0.6 m, 0.1 m to the side.
    let pose = Pose::from_rotation_vector([std::f64::consts::PI, 0.0, 0.0], [0.1, 0.0, 0.6]);
    let mut group = c.benchmark_group("pointcloud2_307200");
    group.sample_size(20);
    let layout = Layout::of(&msg).expect("a valid layout");
    let mut decoded = Vec::new();
    group.bench_function("decode_transform", |b| {
        b.iter(|| decode_into(black_box(&msg), &layout, &pose, &mut decoded))
    });
    for (name, voxel_m, max_points) in [
        ("decode_transform_voxel_3mm", Some(0.003), 200_000),
        (
            "decode_transform_voxel_4.5mm_budget_20k",
            Some(0.0045),
            20_000,
        ),
        ("decode_transform_voxel_3mm_budget_20k", Some(0.003), 20_000),
    ] {
        let mut pipeline = CloudPipeline::new(PipelineConfig {
            camera_to_base: pose,
            voxel_m,
            max_points,
        });
        let mut out = Vec::new();
        group.bench_function(name, |b| {
            b.iter(|| {
                pipeline
                    .process(black_box(&msg), &mut out)
                    .expect("the frame is valid")
            })
        });
    }
    group.bench_function("decode_transform_voxel_3mm_definition", |b| {
        b.iter(|| {
            decode_into(black_box(&msg), &layout, &pose, &mut decoded);
            voxel_downsample(&decoded, 0.003).expect("finite points")
        })
    });
    group.finish();
}

criterion_group!(benches, pointcloud2);
criterion_main!(benches);
