//! Findings of the fuzz campaign (`fuzz/README.md`), each with the input that found it.
#![allow(clippy::unwrap_used)]

use byteorder::LittleEndian;
use mmt::cloud::Pose;
use ros2::msg::PointCloud2;
use ros2::pointcloud2::{CloudPipeline, Layout, PipelineConfig};

fn unhex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
        .collect()
}

/// Found by the `pointcloud2` target (a 10 s timeout after 43,000 inputs): a PointCloud2 of
/// width 0 and height 2,164,391,936 declares no point, passes every check, and the decoder
/// walked its two billion empty rows, twice per frame: seconds of the camera thread for a
/// 129-byte message. An empty cloud now has no rows to read.
#[test]
fn an_empty_cloud_with_a_huge_height_reads_no_rows() {
    // The fuzzer's input, as the camera receives it (little-endian CDR): stamp 0, frame "cam",
    // height 0x81020000, width 0, fields x, y, z float32 at 0, 4, 8 and rgb, point_step 16.
    let bytes = unhex(
        "00000000000000000700000063616d000000000000000281000000000400000002000000780000000000\
         000007000000010000000200000079000000040000000700000001000000020000007a00000008000000\
         070000000100000004000000726762000c00000007000000010000000000000010000000000000000000\
         000001",
    );
    let (msg, _) = cdr_encoding::from_bytes::<PointCloud2, LittleEndian>(&bytes).unwrap();
    assert_eq!((msg.width, msg.height), (0, 0x8102_0000));
    let layout = Layout::of(&msg).unwrap();
    assert_eq!(layout.len(), 0);
    assert_eq!(layout.rows(), 0, "an empty cloud has no rows to walk");
    let mut pipeline = CloudPipeline::new(PipelineConfig {
        camera_to_base: Pose::IDENTITY,
        voxel_m: Some(0.01),
        max_points: 100,
    });
    let mut out = vec![[1.0; 3]];
    let frame = pipeline.process(&msg, &mut out).unwrap();
    assert_eq!((frame.decode.declared, frame.kept), (0, 0));
    assert!(out.is_empty());
}
