//! Reads arbitrary bytes as a recording (`record::read_bytes`: MCAP, zstd chunks, our header
//! metadata, JSON and protobuf messages), then runs what replay does with one: the replay robot
//! bridge, the telerobot's cloud frames, the operator's device trajectory, `describe`. Never a
//! panic; a recording read has a header and counts that add up.
#![no_main]

use libfuzzer_sys::fuzz_target;
use node::RobotBridge;
use record::replay::{ReplayBridge, device_trajectory, telerobot_clouds};

fuzz_target!(|data: &[u8]| {
    let Ok(rec) = record::read_bytes(data, "fuzz.mcap", &[]) else {
        return;
    };
    assert!(rec.header.is_some());
    assert!(
        rec.skipped <= rec.messages,
        "{} skipped of {}",
        rec.skipped,
        rec.messages
    );
    let _ = rec.describe();
    let _ = rec.kind();
    let recorded = rec.clouds.len();
    assert!(telerobot_clouds(&rec).len() <= recorded);
    let trajectory = device_trajectory(&rec);
    assert_eq!(trajectory.len(), rec.operator_ticks.len());
    let mut bridge = ReplayBridge::new(rec.telerobot_ticks.clone());
    let _ = bridge.tool_m();
    for k in 0..rec.telerobot_ticks.len().min(64) + 1 {
        let _ = bridge.step(k as i64, None);
    }
    assert!(bridge.finished() || rec.telerobot_ticks.len() > 64);
});
