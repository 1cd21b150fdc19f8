//! The robot bridge: what the telerobot loop moves and reads each tick (`DESIGN.md` §5, §12).
//!
//! A bridge turns the robot's world into the node's measurement type ([`RobotSample`]) and the
//! node's [`Target`] into a motion of the robot. The simulated world (`sim::SimBridge`) is one;
//! a real robot's bridge implements the same trait.

use mmt::vec3::Vec3;

/// What the robot's sensors read at one tick, in the robot's base (world) frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RobotSample {
    /// Tool position \[m\].
    pub position_m: Vec3,
    /// Tool velocity \[m/s\].
    pub velocity_m_per_s: Vec3,
    /// Force the environment exerts on the tool \[N\] (`F = −F_op`, the sign convention of
    /// `mmt::model`).
    pub force_on_tool_n: Vec3,
}

impl RobotSample {
    /// Every value is finite.
    pub fn is_finite(&self) -> bool {
        [self.position_m, self.velocity_m_per_s, self.force_on_tool_n]
            .iter()
            .all(|v| mmt::vec3::is_finite(*v))
    }
}

/// Where the robot is told to go this tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Target {
    /// Position \[m\].
    pub position_m: Vec3,
    /// Velocity \[m/s\] (0 when holding).
    pub velocity_m_per_s: Vec3,
    /// Sample time of the command being executed (the last one when holding) \[ns\].
    pub command_sample_time_ns: i64,
    /// Commands are stale: the robot holds still.
    pub holding: bool,
}

/// What the robot did in one tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BridgeSample {
    /// What the sensors read.
    pub measured: RobotSample,
    /// Where the tool is, as well as the bridge knows it \[m\] (a simulator's truth; a real
    /// robot's forward kinematics). The loop holds the robot here when commands stop.
    pub tool_m: Vec3,
    /// How far the touched object has slid along the surface's two tangents \[m\], where the
    /// bridge knows it: the simulated world, whose simulated camera draws the object there. Zero
    /// for a real robot, whose camera sees the object itself.
    pub object_slide_m: [f64; 2],
}

/// A robot the telerobot loop drives once per tick. `step` is called from the real-time thread:
/// it must not block, allocate or log.
pub trait RobotBridge: Send {
    /// Where the tool is now \[m\].
    fn tool_m(&self) -> Vec3;
    /// Moves the robot to `target` over one tick and reads its sensors.
    fn step(&mut self, target: &Target) -> BridgeSample;
    /// Puts the robot back in a known, finite state with the tool at rest at `tool_m`, after a
    /// fault (a reading that is not finite). Returns whether it could: the simulated world is
    /// rebuilt; a real robot's bridge that cannot (the default) leaves the guard holding still
    /// and the fault reported.
    fn recover(&mut self, tool_m: Vec3) -> bool {
        let _ = tool_m;
        false
    }
}
