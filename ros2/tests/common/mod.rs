//! What the loopback tests share: a domain and topic names of their own, so that tests running
//! at once (or another checkout's) never hear each other.

#![allow(clippy::unwrap_used, dead_code)]

use std::sync::atomic::{AtomicU32, Ordering};

use ros2::topics::RobotTopics;
use ros2::{Graph, GraphConfig};

static NEXT: AtomicU32 = AtomicU32::new(0);

/// A fresh namespace `/t<pid>_<n>` and a domain derived from the process id.
pub fn isolated() -> (Graph, RobotTopics, String) {
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    let pid = std::process::id();
    let ns = format!("/t{pid}_{n}");
    let mut topics = RobotTopics::default();
    for (key, name) in [
        ("robot_pose", "robot/pose"),
        ("robot_twist", "robot/twist"),
        ("robot_wrench", "robot/wrench"),
        ("target_pose", "robot/target_pose"),
        ("theta", "theta"),
        ("in_contact", "in_contact"),
        ("camera_points", "camera/points"),
    ] {
        topics.remap(&format!("{key}={ns}/{name}")).unwrap();
    }
    let graph = Graph::join(&GraphConfig {
        domain_id: 100 + (pid % 100) as u16,
        localhost_only: true,
    })
    .unwrap();
    (graph, topics, ns)
}
