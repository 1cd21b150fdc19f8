//! Decodes arbitrary bytes as a ROS 2 `sensor_msgs/PointCloud2` in CDR (little-endian XCDR1,
//! with `cdr-encoding`, what RustDDS uses under the camera's subscription), then runs the
//! camera's pipeline on it: layout check, decode, frame transform, voxel grid, point budget.
//! Never a panic; every point kept is finite and in range (it makes a `CloudFrame`), no more
//! than the budget, and the counts add up.
#![no_main]

use byteorder::LittleEndian;
use libfuzzer_sys::fuzz_target;
use mmt::cloud::{CloudFrame, Pose};
use ros2::msg::PointCloud2;
use ros2::pointcloud2::{CloudPipeline, Layout, PipelineConfig};

const BUDGET: usize = 2_000;

fuzz_target!(|data: &[u8]| {
    let Ok((msg, _)) = cdr_encoding::from_bytes::<PointCloud2, LittleEndian>(data) else {
        return;
    };
    let _ = msg.header.stamp.to_nanos();
    let layout = Layout::of(&msg);
    // A pose with a rotation and an offset, so that the transform is exercised.
    let camera_to_base = Pose::from_quaternion([0.9, 0.1, -0.3, 0.2], [0.5, -0.25, 1.0])
        .expect("a non-zero quaternion");
    for voxel_m in [None, Some(0.01)] {
        let mut pipeline = CloudPipeline::new(PipelineConfig {
            camera_to_base,
            voxel_m,
            max_points: BUDGET,
        });
        let mut out = Vec::new();
        let Ok(frame) = pipeline.process(&msg, &mut out) else {
            continue;
        };
        assert!(
            layout.is_ok(),
            "the pipeline accepted a layout Layout::of refuses"
        );
        let d = frame.decode;
        assert_eq!(
            d.declared as u64,
            u64::from(msg.width) * u64::from(msg.height)
        );
        assert!(d.non_finite + d.out_of_range <= d.declared, "{d:?}");
        assert_eq!(frame.kept, out.len());
        assert!(out.len() <= BUDGET && out.len() <= d.declared - d.non_finite - d.out_of_range);
        if let Err(e) = CloudFrame::new(out, 0, Pose::IDENTITY) {
            panic!("kept points do not make a frame: {e}");
        }
    }
});
