//! The motion guard: what every robot bridge goes through, so that the robot stays bounded
//! whatever the operator sends (a wrong `--position-scale`, a replay file in millimetres, a
//! hostile peer).
//!
//! - [`MotionLimits`]: a workspace box in the robot's base frame, a largest commanded step per
//!   tick, a largest commanded speed, and the largest jump of a command's playout clock
//!   (checked by the node, [`crate::telerobot::TelerobotNode::on_command`]). They come from the
//!   scene (`[limits]`) or the bridge's settings, with safe defaults ([`MotionLimits::around`]).
//! - [`MotionGuard`]: clamps a [`Target`] to the limits, counts each limit's ticks and episodes
//!   (an episode is a run of consecutive ticks in which the limit acts: the owner logs once per
//!   episode, off the real-time thread, from [`GuardStats`]).
//! - [`Guarded`]: any [`RobotBridge`] behind a guard. Nothing is commanded before the robot has
//!   reported a state (its position unknown, a target could be anywhere), and a state older than
//!   [`MotionLimits::STATE_TIMEOUT_NS`] (50 ms, `DESIGN.md` §12) holds the last command still (a
//!   robot that went silent is not driven blind; [`Guarded::state_is_stale`] tells the loop to
//!   stop estimating meanwhile). A reading that is not finite is a fault:
//!   the bridge is asked to recover ([`RobotBridge::recover`], the simulated world is rebuilt at
//!   the last finite tool position) and the fault is counted. [`Guarded::begin_session`] checks the
//!   bridge at each new session, so that one session cannot leave state that harms the next.
//!
//! Nothing here allocates, locks or logs: it runs in the 1 kHz loop.

use mmt::vec3::{self, Vec3};
use serde::{Deserialize, Serialize};

use crate::bridge::{BridgeSample, Reading, RobotBridge, Target};

/// Limits on what the robot is told to do.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MotionLimits {
    /// Lower corner of the workspace box, base frame \[m\].
    pub workspace_min_m: Vec3,
    /// Upper corner of the workspace box, base frame \[m\].
    pub workspace_max_m: Vec3,
    /// Largest change of the commanded position in one tick \[m\]. Default 1 mm: 1 m/s at
    /// 1 kHz.
    pub max_step_m: f64,
    /// Largest commanded speed \[m/s\]. Default 1 m/s: below a Franka arm's 1.7 m/s Cartesian
    /// limit, and about three times the fastest motion of the experiments' trajectories.
    pub max_speed_m_per_s: f64,
    /// Largest change of a command's lag (arrival − sample time) from the session's first
    /// command \[ns\]; a command beyond it has an implausible playout time and is refused.
    /// Default 10 s: longer than any link this system is made for, far beyond clock drift.
    pub max_clock_jump_ns: i64,
}

impl MotionLimits {
    /// Default half-width of the workspace box around the scene's surface point \[m\].
    pub const HALF_WIDTH_M: f64 = 0.25;
    /// Default largest step per tick \[m\].
    pub const MAX_STEP_M: f64 = 0.001;
    /// Default largest speed \[m/s\].
    pub const MAX_SPEED_M_PER_S: f64 = 1.0;
    /// Default largest clock jump \[ns\].
    pub const MAX_CLOCK_JUMP_NS: i64 = 10_000_000_000;
    /// The largest step per tick any settings may allow \[m\].
    pub const STEP_CEILING_M: f64 = 0.01;
    /// The largest speed any settings may allow \[m/s\].
    pub const SPEED_CEILING_M_PER_S: f64 = 2.0;
    /// The largest workspace half-width any settings may allow \[m\] (a large arm's reach).
    pub const WORKSPACE_CEILING_M: f64 = 2.0;
    /// A robot state older than this holds the robot (not a setting) \[ns\]: 50 ms
    /// (`DESIGN.md` §12), fifty ticks at 1 kHz and several periods of a robot's state topic
    /// (100 Hz to 1 kHz).
    pub const STATE_TIMEOUT_NS: i64 = 50_000_000;

    /// The defaults: a box [`Self::HALF_WIDTH_M`] either side of `centre_m` on every axis.
    pub fn around(centre_m: Vec3) -> MotionLimits {
        MotionLimits {
            workspace_min_m: centre_m.map(|c| c - Self::HALF_WIDTH_M),
            workspace_max_m: centre_m.map(|c| c + Self::HALF_WIDTH_M),
            max_step_m: Self::MAX_STEP_M,
            max_speed_m_per_s: Self::MAX_SPEED_M_PER_S,
            max_clock_jump_ns: Self::MAX_CLOCK_JUMP_NS,
        }
    }

    /// Every limit finite, positive and below its ceiling; the box not empty.
    pub fn validate(&self) -> Result<(), LimitsError> {
        for i in 0..3 {
            let (lo, hi) = (self.workspace_min_m[i], self.workspace_max_m[i]);
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return Err(LimitsError::Workspace { axis: i, lo, hi });
            }
            if hi - lo > 2.0 * Self::WORKSPACE_CEILING_M {
                return Err(LimitsError::Workspace { axis: i, lo, hi });
            }
        }
        if !(self.max_step_m > 0.0 && self.max_step_m <= Self::STEP_CEILING_M) {
            return Err(LimitsError::Step(self.max_step_m));
        }
        let v = self.max_speed_m_per_s;
        if !(v > 0.0 && v <= Self::SPEED_CEILING_M_PER_S) {
            return Err(LimitsError::Speed(v));
        }
        if !(100_000_000..=60_000_000_000).contains(&self.max_clock_jump_ns) {
            return Err(LimitsError::ClockJump(self.max_clock_jump_ns));
        }
        Ok(())
    }

    /// `position_m` inside the box.
    pub fn contains(&self, position_m: Vec3) -> bool {
        (0..3).all(|i| {
            position_m[i] >= self.workspace_min_m[i] && position_m[i] <= self.workspace_max_m[i]
        })
    }
}

/// Limits that are not limits.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum LimitsError {
    /// The box along one axis.
    #[error(
        "limits.workspace axis {axis}: [{lo}, {hi}] m: expected finite bounds, min < max, at \
         most 4 m wide"
    )]
    Workspace {
        /// 0, 1, 2 for x, y, z.
        axis: usize,
        /// Lower bound \[m\].
        lo: f64,
        /// Upper bound \[m\].
        hi: f64,
    },
    /// The step per tick.
    #[error("limits.max_step_m = {0}: expected > 0 and at most 0.01 m per tick")]
    Step(f64),
    /// The speed.
    #[error("limits.max_speed_m_per_s = {0}: expected > 0 and at most 2 m/s")]
    Speed(f64),
    /// The clock jump.
    #[error("limits.max_clock_jump = {0} ns: expected 0.1 to 60 s")]
    ClockJump(i64),
}

/// How often one limit acted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct LimitCount {
    /// Ticks in which it acted.
    pub ticks: u64,
    /// Episodes: runs of consecutive ticks in which it acted.
    pub episodes: u64,
}

impl LimitCount {
    fn record(&mut self, acting: bool, was_acting: &mut bool) {
        if acting {
            self.ticks += 1;
            if !*was_acting {
                self.episodes += 1;
            }
        }
        *was_acting = acting;
    }
}

/// The guard's counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct GuardStats {
    /// The commanded position was outside the workspace box.
    pub workspace: LimitCount,
    /// The commanded position moved more than the largest step.
    pub step: LimitCount,
    /// The commanded velocity was faster than the largest speed.
    pub speed: LimitCount,
    /// Faults: the bridge read something not finite (or was found so at a session's start).
    pub faults: u64,
    /// Faults the bridge recovered from (the simulated world rebuilt).
    pub recovered: u64,
    /// Ticks with nothing commanded: the robot had not reported a state yet.
    pub no_state_ticks: u64,
    /// The robot's newest state was older than [`MotionLimits::STATE_TIMEOUT_NS`]: the last
    /// command held still.
    pub stale_state: LimitCount,
}

/// Clamps targets to [`MotionLimits`].
#[derive(Clone, Debug)]
pub struct MotionGuard {
    limits: MotionLimits,
    last_m: Option<Vec3>,
    acting: [bool; 3],
    stats: GuardStats,
}

impl MotionGuard {
    /// A guard for `limits` (validated by whoever made them: [`MotionLimits::validate`]).
    pub fn new(limits: MotionLimits) -> MotionGuard {
        MotionGuard {
            limits,
            last_m: None,
            acting: [false; 3],
            stats: GuardStats::default(),
        }
    }

    /// The limits.
    pub fn limits(&self) -> &MotionLimits {
        &self.limits
    }

    /// The counters.
    pub fn stats(&self) -> GuardStats {
        self.stats
    }

    /// Forgets the last commanded position: the next target's step is measured from where the
    /// robot is (after a fault, or at a new session).
    pub fn reseat(&mut self) {
        self.last_m = None;
    }

    /// `target` within the limits, the robot's tool at `tool_m`: inside the box, at most one
    /// step from the last commanded position (from `tool_m` for the first), at most the largest
    /// speed. A position that is not finite holds the last one.
    pub fn limit(&mut self, target: &Target, tool_m: Vec3) -> Target {
        let l = self.limits;
        let from = self
            .last_m
            .or_else(|| vec3::is_finite(tool_m).then_some(tool_m))
            .unwrap_or_else(|| centre(&l));
        let wanted = if vec3::is_finite(target.position_m) {
            target.position_m
        } else {
            from
        };
        let boxed: Vec3 =
            std::array::from_fn(|i| wanted[i].clamp(l.workspace_min_m[i], l.workspace_max_m[i]));
        let in_box = boxed == wanted;
        let step = vec3::sub(boxed, from);
        let length = vec3::norm(step);
        let step_ok = length <= l.max_step_m;
        let position = if step_ok {
            boxed
        } else {
            vec3::add(from, vec3::scale(step, l.max_step_m / length))
        };
        let mut velocity = target.velocity_m_per_s;
        if !vec3::is_finite(velocity) {
            velocity = [0.0; 3];
        }
        for i in 0..3 {
            // No velocity out through a face the position was clamped to.
            if (wanted[i] > boxed[i] && velocity[i] > 0.0)
                || (wanted[i] < boxed[i] && velocity[i] < 0.0)
            {
                velocity[i] = 0.0;
            }
        }
        let speed = vec3::norm(velocity);
        let speed_ok = speed <= l.max_speed_m_per_s;
        if !speed_ok {
            velocity = vec3::scale(velocity, l.max_speed_m_per_s / speed);
        }
        let [w, s, v] = &mut self.acting;
        self.stats.workspace.record(!in_box, w);
        self.stats.step.record(!step_ok, s);
        self.stats.speed.record(!speed_ok, v);
        self.last_m = Some(position);
        Target {
            position_m: position,
            velocity_m_per_s: velocity,
            ..*target
        }
    }

    /// Holds the last commanded position (the robot's `tool_m` if none) at rest: what a stale
    /// state commands. The limits do not act meanwhile.
    pub fn hold(&mut self, target: &Target, tool_m: Vec3) -> Target {
        let position = self
            .last_m
            .or_else(|| vec3::is_finite(tool_m).then_some(tool_m))
            .unwrap_or_else(|| centre(&self.limits));
        let [w, s, v] = &mut self.acting;
        self.stats.workspace.record(false, w);
        self.stats.step.record(false, s);
        self.stats.speed.record(false, v);
        self.last_m = Some(position);
        Target {
            position_m: position,
            velocity_m_per_s: [0.0; 3],
            command_sample_time_ns: target.command_sample_time_ns,
            holding: true,
        }
    }

    fn fault(&mut self, recovered: bool) {
        self.stats.faults += 1;
        self.stats.recovered += u64::from(recovered);
        self.last_m = None;
    }
}

fn centre(l: &MotionLimits) -> Vec3 {
    std::array::from_fn(|i| 0.5 * (l.workspace_min_m[i] + l.workspace_max_m[i]))
}

/// A robot bridge behind a [`MotionGuard`].
pub struct Guarded<B> {
    bridge: B,
    guard: MotionGuard,
    /// The last finite tool position inside the box (where a recovered robot starts).
    safe_m: Vec3,
    /// The last reading was finite.
    healthy: bool,
    /// When the newest finite state was read \[ns, loop clock\].
    state_ns: Option<i64>,
    /// The state is stale now (for the episode count).
    stale: bool,
    /// What the bridge was told on the last tick (`None`: nothing).
    commanded: Option<Target>,
    /// The last tick's time \[ns, loop clock\].
    tick_ns: i64,
}

impl<B: RobotBridge> Guarded<B> {
    /// `bridge` behind a guard for `limits`.
    pub fn new(bridge: B, limits: MotionLimits) -> Guarded<B> {
        let tool = bridge.tool_m();
        let safe_m = match tool {
            Some(t) if vec3::is_finite(t) && limits.contains(t) => t,
            _ => centre(&limits),
        };
        Guarded {
            bridge,
            guard: MotionGuard::new(limits),
            safe_m,
            healthy: tool.is_none_or(vec3::is_finite),
            state_ns: None,
            stale: false,
            commanded: None,
            tick_ns: 0,
        }
    }

    /// Whether the robot's newest state is older than [`MotionLimits::STATE_TIMEOUT_NS`] at
    /// `now_ns`: the guard holds the robot, and the loop estimates nothing from it. A bridge
    /// that has not read yet but knows its tool (a simulator before its first tick) is not
    /// stale.
    pub fn state_is_stale(&self, now_ns: i64) -> bool {
        self.state_ns
            .is_some_and(|t| now_ns.saturating_sub(t) > MotionLimits::STATE_TIMEOUT_NS)
    }

    /// What the bridge was told on the last tick, after the limits (`None`: nothing).
    pub fn commanded(&self) -> Option<&Target> {
        self.commanded.as_ref()
    }

    /// The guard's counters.
    pub fn stats(&self) -> GuardStats {
        self.guard.stats
    }

    /// The bridge.
    pub fn bridge(&self) -> &B {
        &self.bridge
    }

    /// A new session starts: the step is measured from the robot again, and a bridge whose
    /// state is not finite is recovered (and the fault counted). Returns whether the bridge was
    /// found faulty.
    pub fn begin_session(&mut self) -> bool {
        self.guard.reseat();
        self.guard.acting = [false; 3];
        let faulty = !self.healthy || self.bridge.tool_m().is_some_and(|t| !vec3::is_finite(t));
        if faulty {
            self.recover();
        }
        faulty
    }

    fn recover(&mut self) {
        let recovered = self.bridge.recover(self.safe_m);
        self.guard.fault(recovered);
        self.healthy = recovered;
    }

    /// A sample the bridge returned at `now_ns`: a new finite one is the robot's newest state; a
    /// new one not finite is a fault; a repeated one, or none, says nothing.
    fn observe(&mut self, now_ns: i64, sample: &BridgeSample) {
        let time_ns = match sample.reading {
            Reading::ThisTick => now_ns,
            Reading::Stamped { sample_time_ns, .. } => sample_time_ns,
            Reading::Repeated | Reading::Nothing => return,
        };
        if sample.measured.is_finite() && vec3::is_finite(sample.tool_m) {
            self.healthy = true;
            self.state_ns = Some(time_ns);
            if self.guard.limits.contains(sample.tool_m) {
                self.safe_m = sample.tool_m;
            }
        } else {
            self.recover();
        }
    }
}

impl<B: RobotBridge> RobotBridge for Guarded<B> {
    fn tool_m(&self) -> Option<Vec3> {
        let tool = self.bridge.tool_m()?;
        Some(if vec3::is_finite(tool) {
            tool
        } else {
            self.safe_m
        })
    }

    fn step(&mut self, now_ns: i64, target: Option<&Target>) -> BridgeSample {
        let tool = self.bridge.tool_m();
        self.commanded = match (tool, target) {
            (Some(tool), Some(target)) => {
                let stale = self.state_is_stale(now_ns);
                self.guard.stats.stale_state.record(stale, &mut self.stale);
                Some(if stale {
                    self.guard.hold(target, tool)
                } else {
                    self.guard.limit(target, tool)
                })
            }
            (None, _) => {
                self.guard.stats.no_state_ticks += 1;
                None
            }
            (Some(_), None) => None,
        };
        self.tick_ns = now_ns;
        let sample = self.bridge.step(now_ns, self.commanded.as_ref());
        self.observe(now_ns, &sample);
        sample
    }

    fn next_reading(&mut self) -> Option<BridgeSample> {
        let sample = self.bridge.next_reading()?;
        self.observe(self.tick_ns, &sample);
        Some(sample)
    }

    fn recover(&mut self, tool_m: Vec3) -> bool {
        self.bridge.recover(tool_m)
    }
}

impl RobotBridge for Box<dyn RobotBridge> {
    fn tool_m(&self) -> Option<Vec3> {
        self.as_ref().tool_m()
    }

    fn step(&mut self, now_ns: i64, target: Option<&Target>) -> BridgeSample {
        self.as_mut().step(now_ns, target)
    }

    fn next_reading(&mut self) -> Option<BridgeSample> {
        self.as_mut().next_reading()
    }

    fn recover(&mut self, tool_m: Vec3) -> bool {
        self.as_mut().recover(tool_m)
    }
}

#[cfg(test)]
#[path = "guard_tests.rs"]
mod tests;
