//! The simulated world as a robot bridge (`node::RobotBridge`, `DESIGN.md` §5): the robot
//! tracks the commanded position exactly, as in the thesis's set-up 1, and its sensors read
//! through the scene's noise model.

use node::{BridgeSample, Reading, RobotBridge, Target};

use crate::SimError;
use crate::scene::Scene;
use crate::world::{World, WorldSample};

/// The scene's simulated world as the robot.
pub struct SimBridge {
    world: World,
    tool_m: [f64; 3],
    scene: Scene,
    seed: u64,
    /// Times the world was rebuilt after a fault ([`RobotBridge::recover`]).
    rebuilds: u64,
}

impl SimBridge {
    /// The world of `scene` with the tool at rest at `tool_m`; sensor noise seeded from `seed`.
    pub fn new(scene: &Scene, tool_m: [f64; 3], seed: u64) -> Result<SimBridge, SimError> {
        Ok(SimBridge {
            world: World::new(scene, tool_m, seed)?,
            tool_m,
            scene: scene.clone(),
            seed,
            rebuilds: 0,
        })
    }
}

impl SimBridge {
    /// One tick of the world with everything it knows (the truth too): what the in-process
    /// harness records; [`RobotBridge::step`] is this, as a robot would report it.
    pub fn step_world(&mut self, target: &Target) -> WorldSample {
        let s = self.world.step(target.position_m, target.velocity_m_per_s);
        self.tool_m = s.truth.position_m;
        s
    }

    /// The world (its surface frame, for the camera and the reports).
    pub fn world(&self) -> &World {
        &self.world
    }

    /// Times the world was rebuilt after a fault.
    pub fn rebuilds(&self) -> u64 {
        self.rebuilds
    }
}

impl RobotBridge for SimBridge {
    fn tool_m(&self) -> Option<[f64; 3]> {
        Some(self.tool_m)
    }

    /// With no target the simulated robot holds still where it is.
    fn step(&mut self, _now_ns: i64, target: Option<&Target>) -> BridgeSample {
        let hold = Target {
            position_m: self.tool_m,
            velocity_m_per_s: [0.0; 3],
            command_sample_time_ns: 0,
            holding: true,
        };
        let s = self.step_world(target.unwrap_or(&hold));
        BridgeSample {
            measured: s.measured,
            tool_m: s.truth.position_m,
            object_slide_m: s.object_offset_m,
            reading: Reading::ThisTick,
        }
    }

    /// Rebuilds the world as the scene starts it, the tool at rest at `tool_m`, with the same
    /// noise seed (what a fresh daemon would run). Runs once per fault: the allocation is the
    /// price of a world that was not finite any more.
    fn recover(&mut self, tool_m: [f64; 3]) -> bool {
        if !mmt::vec3::is_finite(tool_m) {
            return false;
        }
        match World::new(&self.scene, tool_m, self.seed) {
            Ok(world) => {
                self.world = world;
                self.tool_m = tool_m;
                self.rebuilds += 1;
                true
            }
            Err(_) => false,
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
        let free = bridge.step(0, Some(&target(0.01)));
        assert!(free.measured.force_on_tool_n[2].abs() < 0.2, "{free:?}");
        let pressed = bridge.step(1_000_000, Some(&target(-0.004)));
        assert_eq!(bridge.tool_m(), Some([0.0, 0.0, -0.004]));
        assert_eq!(pressed.reading, Reading::ThisTick);
        // 4 mm into a 500 N/m contact: about 2 N pushing the tool out (+z).
        assert!(
            (pressed.measured.force_on_tool_n[2] - 2.0).abs() < 0.3,
            "{pressed:?}"
        );
    }
}
