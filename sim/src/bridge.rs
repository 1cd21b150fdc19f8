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
    /// The time of the last [`RobotBridge::step`] [ns].
    last_step_ns: Option<i64>,
}

/// Most periods one [`RobotBridge::step`] moves the world over (a loop held up longer is a
/// fault of its own; the world does not make up more).
pub const MAX_CATCH_UP_PERIODS: u64 = 100;

impl SimBridge {
    /// The world of `scene` with the tool at rest at `tool_m`; sensor noise seeded from `seed`.
    pub fn new(scene: &Scene, tool_m: [f64; 3], seed: u64) -> Result<SimBridge, SimError> {
        Ok(SimBridge {
            world: World::new(scene, tool_m, seed)?,
            tool_m,
            scene: scene.clone(),
            seed,
            rebuilds: 0,
            last_step_ns: None,
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

    /// `periods` sample periods of the world towards `target` (one: [`Self::step_world`]). Over
    /// more, the tool goes along the straight line from where it is to the target at the speed
    /// that takes, and the last period's sample is returned: what a robot whose own controller
    /// kept running would report after a caller's loop was held up for those periods. The
    /// world's time is then the caller's: stepped once whatever the time that passed, the world
    /// fell behind the stamps of its samples, and the tool jumped to the target in one period
    /// at the commanded velocity (forces no contact model gives).
    pub fn step_periods(&mut self, target: &Target, periods: u64) -> WorldSample {
        let periods = periods.clamp(1, MAX_CATCH_UP_PERIODS);
        if periods == 1 {
            return self.step_world(target);
        }
        let from = self.tool_m;
        let to = target.position_m;
        let n = periods as f64;
        let span_s = n / self.scene.rates.control_hz;
        let velocity = std::array::from_fn(|k| (to[k] - from[k]) / span_s);
        let along = |a: f64| Target {
            position_m: std::array::from_fn(|k| from[k] + a * (to[k] - from[k])),
            velocity_m_per_s: velocity,
            ..*target
        };
        for j in 1..periods {
            self.step_world(&along(j as f64 / n));
        }
        self.step_world(&along(1.0))
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

    /// With no target the simulated robot holds still where it is. The world moves on by the
    /// periods since the last step ([`SimBridge::step_periods`]): a loop held up does not stop
    /// the robot's time.
    fn step(&mut self, now_ns: i64, target: Option<&Target>) -> BridgeSample {
        let hold = Target {
            position_m: self.tool_m,
            velocity_m_per_s: [0.0; 3],
            command_sample_time_ns: 0,
            holding: true,
        };
        let period_ns = 1e9 / self.scene.rates.control_hz;
        let periods = self.last_step_ns.map_or(1.0, |last| {
            ((now_ns - last) as f64 / period_ns)
                .round()
                .clamp(1.0, MAX_CATCH_UP_PERIODS as f64)
        });
        self.last_step_ns = Some(now_ns);
        let s = self.step_periods(target.unwrap_or(&hold), periods as u64);
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

    /// The telerobot's loop held up for four periods in five: the world still passes the time
    /// (the robot's own controller does not stall), going along the commanded path. Before, it
    /// stepped once per call: after 1 s of calls every 5 ms the object had lived 0.2 s.
    #[test]
    fn a_loop_held_up_does_not_stop_the_world() {
        let scene = Scene::exp1();
        let start = [0.0, 0.0, -0.004];
        let mut every = SimBridge::new(&scene, start, 1).unwrap();
        let mut held_up = SimBridge::new(&scene, start, 1).unwrap();
        let target = |k: i64| Target {
            position_m: [0.0, 0.05 * k as f64 * 1e-3, -0.004],
            velocity_m_per_s: [0.0, 0.05, 0.0],
            command_sample_time_ns: 0,
            holding: false,
        };
        let (mut a, mut b) = (None, None);
        for k in 0..=1000 {
            a = Some(every.step(k * 1_000_000, Some(&target(k))));
            if k % 5 == 0 {
                b = Some(held_up.step(k * 1_000_000, Some(&target(k))));
            }
        }
        let (a, b) = (a.unwrap(), b.unwrap());
        assert_eq!(a.tool_m, b.tool_m);
        let slid = a.object_slide_m[1];
        assert!(slid > 0.02, "the object slid {slid} m");
        assert!(
            (b.object_slide_m[1] - slid).abs() < 0.01 * slid,
            "{:?} against {:?}",
            b.object_slide_m,
            a.object_slide_m
        );
    }
}
