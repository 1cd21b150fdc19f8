//! The ROS 2 camera source over real DDS on loopback: a publisher plays a camera driver on the
//! graph; the source turns its PointCloud2 into base-frame frames, counts malformed and stale
//! clouds, and never panics.

mod common;

use std::time::{Duration, Instant};

use mmt::cloud::Pose;
use ros2::msg::{Bytes, PointCloud2};
use ros2::pointcloud2::{PipelineConfig, encode_xyz};
use ros2::{CameraConfig, CameraSource, Graph, Qos};

/// Polls `source` until `done` holds for its counters or 10 s pass, republishing `msg` while
/// waiting (discovery takes a moment; the QoS is best-effort).
fn pump(
    source: &mut CameraSource,
    publish: &dyn Fn(),
    done: impl Fn(&ros2::CameraReport) -> bool,
) -> Vec<mmt::cloud::CloudFrame> {
    let start = Instant::now();
    let counters = source.counters();
    let mut frames = Vec::new();
    while !done(&counters.report()) {
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "{:?}",
            counters.report()
        );
        publish();
        std::thread::sleep(Duration::from_millis(20));
        if let Some(f) = source.poll(rt::monotonic_ns()) {
            frames.push(f);
        }
    }
    frames
}

#[test]
fn clouds_become_base_frame_frames_and_bad_ones_are_counted() {
    let (graph, topics, _) = common::isolated();
    let driver = Graph::join(graph.config()).unwrap();
    let mut node = driver.node("fake_camera").unwrap();
    let publisher =
        ros2::graph::advertise::<PointCloud2>(&mut node, &topics.camera_points, Qos::STREAM)
            .unwrap();
    let mut source = CameraSource::start(
        &graph,
        CameraConfig {
            topic: topics.camera_points.clone(),
            qos: Qos::STREAM,
            // The camera 1 m above the base, looking down (x kept, y and z flipped).
            pipeline: PipelineConfig {
                camera_to_base: Pose::from_quaternion([0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0])
                    .unwrap(),
                voxel_m: None,
                max_points: 100_000,
            },
            stale_ns: 200_000_000,
        },
    )
    .unwrap();

    // A 2×2 patch 1 m in front of the camera, one hole.
    let points = [
        [0.0, 0.0, 1.0],
        [0.01, 0.0, 1.0],
        [f32::NAN, f32::NAN, f32::NAN],
        [0.01, 0.01, 1.0],
    ];
    let wall = || ros2::graph::ros_now_ns();
    let good = || {
        let _ = publisher.publish(encode_xyz(&points, "camera", wall()));
    };
    let frames = pump(&mut source, &good, |r| r.frames >= 3);
    let f = frames.last().unwrap();
    assert_eq!(f.points().len(), 3);
    for p in f.points() {
        // On the table (z = 0 in the base frame), y flipped.
        assert!(p[2].abs() < 1e-6 && p[1] <= 0.0, "{p:?}");
    }
    // Stamped with the message's time on the loop clock: a few ms ago at most.
    let age = rt::monotonic_ns() - f.timestamp_ns();
    assert!((0..2_000_000_000).contains(&age), "{age}");
    let before = source.counters().report();
    assert_eq!(
        (before.refused, before.stale, before.undecodable),
        (0, 0, 0)
    );
    assert!(before.non_finite_points >= 3, "{before:?}");

    // Data shorter than width·height·point_step: refused, counted, no frame.
    let short = || {
        let mut m = encode_xyz(&points, "camera", wall());
        m.data = Bytes(m.data.0[..20].to_vec());
        let _ = publisher.publish(m);
    };
    pump(&mut source, &short, |r| r.refused >= 2);
    // No z field: refused.
    let no_z = || {
        let mut m = encode_xyz(&points, "camera", wall());
        m.fields.retain(|f| f.name != "z");
        let _ = publisher.publish(m);
    };
    let refused = source.counters().report().refused;
    pump(&mut source, &no_z, |r| r.refused >= refused + 2);
    // A cloud stamped 1 s ago: used, and counted stale.
    let old = || {
        let _ = publisher.publish(encode_xyz(&points, "camera", wall() - 1_000_000_000));
    };
    let frames_before = source.counters().report().frames;
    pump(&mut source, &old, |r| r.stale >= 2);
    let after = source.counters().report();
    assert!(after.frames >= frames_before + 2, "{after:?}");
    assert!(after.max_age_ms >= 1000.0, "{after:?}");
}
