//! The robot bridge: what the telerobot loop moves and reads each tick (`DESIGN.md` §5).
//!
//! [`RobotBridge`] is the interface; [`SimBridge`] (the default) is the scene's simulated world
//! (`sim::world::World`): the robot tracks the commanded position exactly, as in the
//! thesis's set-up 1, and its sensors read through the scene's noise model. A real-robot bridge
//! would implement the same trait behind a cargo feature.

use node::telerobot::Target;
use sim::SimError;
use sim::scene::Scene;
use sim::world::{Sample3, World};

/// What the robot did in one tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BridgeSample {
    /// What the sensors read: position \[m\], velocity \[m/s\], force on the tool \[N\], world frame.
    pub measured: Sample3,
    /// Where the tool is, as well as the bridge knows it \[m\] (the simulated truth; a real robot's
    /// forward kinematics). The loop holds the robot here when commands stop.
    pub tool_m: [f64; 3],
    /// How far the simulated object slid along the surface's tangents \[m\], for the simulated
    /// camera (zero for a real robot).
    pub object_offset_m: [f64; 2],
}

/// A robot the telerobot loop drives once per tick. `step` is called from the real-time thread:
/// it must not block, allocate or log.
pub trait RobotBridge: Send {
    /// Where the tool is now \[m\].
    fn tool_m(&self) -> [f64; 3];
    /// Moves the robot to `target` over one tick and reads its sensors.
    fn step(&mut self, target: &Target) -> BridgeSample;
}

/// The scene's simulated world as the robot.
pub struct SimBridge {
    world: World,
    tool_m: [f64; 3],
}

impl SimBridge {
    /// The world of `scene` with the tool at rest at `tool_m`; sensor noise seeded from `seed`.
    pub fn new(scene: &Scene, tool_m: [f64; 3], seed: u64) -> Result<SimBridge, SimError> {
        Ok(SimBridge {
            world: World::new(scene, tool_m, seed)?,
            tool_m,
        })
    }
}

impl RobotBridge for SimBridge {
    fn tool_m(&self) -> [f64; 3] {
        self.tool_m
    }

    fn step(&mut self, target: &Target) -> BridgeSample {
        let s = self.world.step(target.position_m, target.velocity_m_per_s);
        self.tool_m = s.truth.position_m;
        BridgeSample {
            measured: s.measured,
            tool_m: s.truth.position_m,
            object_offset_m: s.object_offset_m,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_simulated_robot_goes_where_it_is_told_and_feels_the_table() {
        let scene = Scene::exp1();
        let mut bridge = SimBridge::new(&scene, [0.0, 0.0, 0.01], 1).unwrap();
        let target = |z: f64| Target {
            position_m: [0.0, 0.0, z],
            velocity_m_per_s: [0.0; 3],
            command_sample_time_ns: 0,
            holding: false,
        };
        let free = bridge.step(&target(0.01));
        assert!(free.measured.force_n[2].abs() < 0.2, "{free:?}");
        let pressed = bridge.step(&target(-0.004));
        assert_eq!(bridge.tool_m(), [0.0, 0.0, -0.004]);
        // 4 mm into a 500 N/m contact: about 2 N pushing the tool out (+z).
        assert!(
            (pressed.measured.force_n[2] - 2.0).abs() < 0.3,
            "{pressed:?}"
        );
    }
}
