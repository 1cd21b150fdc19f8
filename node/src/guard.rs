//! The command guard: what stands between the telerobot node's target and **any** robot bridge
//! (`DESIGN.md` §12: "every bridge sits behind the same command limits"), the simulated one
//! included. Pure and stepped with `now`, like the nodes; the daemon's loop applies it around
//! whatever bridge runs.
//!
//! Per tick, in this order ([`CommandGuard::apply`]):
//! 1. **No state, no command.** Until the robot has reported a state
//!    ([`CommandGuard::on_reading`]) nothing is commanded: the robot's position is unknown, and
//!    a target computed without it could be anywhere.
//! 2. **Stale state holds.** When the newest state is older than
//!    [`CommandLimits::state_timeout_ns`] (50 ms), the last commanded pose is held (velocity 0)
//!    and the loop stops estimating (it has nothing to estimate from): a robot that went silent
//!    is not driven blind.
//! 3. **Non-finite targets** hold the last command.
//! 4. **Workspace box** in the base frame: the target is clamped into it, per axis.
//! 5. **Maximum step**: the move from the last command is cut to [`CommandLimits::max_step_m`]
//!    (bounds the first tick after a stall, however long).
//! 6. **Maximum speed**: the move is cut to `max_speed · Δt` (Δt since the last command), and
//!    the commanded velocity to `max_speed`.
//!
//! Each rule that acts clamps, counts ([`GuardStats`], a [`Trip`] per rule: episodes and ticks)
//! and reports its edges so the caller logs once per episode, off the real-time path.
//!
//! Hooks left for the session-level checks of issue 11 (implausible playout times, a session
//! that leaves harmful state): [`CommandGuard::restart`] re-anchors the guard on the robot's
//! position at a session change, and [`Target::command_sample_time_ns`] is what a playout-time
//! check would read.

use mmt::vec3::{self, Vec3};
use serde::{Deserialize, Serialize};

use crate::bridge::Target;

/// The limits every bridge's commands obey.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CommandLimits {
    /// Lower corner of the workspace box, base frame \[m\].
    pub workspace_min_m: Vec3,
    /// Upper corner of the workspace box, base frame \[m\].
    pub workspace_max_m: Vec3,
    /// Largest move between two consecutive commands \[m\]. Default 2 mm: what the speed limit
    /// allows after a 2 ms stall, and 2 m/s at 1 kHz — a move a tracking controller can follow
    /// within a tick, and one a ROS 2 bridge does not refuse as an impossible jump (3 m/s).
    pub max_step_m: f64,
    /// Largest commanded speed \[m/s\]. Default 1 m/s: below a collaborative arm's Cartesian
    /// limit (Franka: 1.7 m/s) and above what teleoperation asks — the exp-1 motion peaks at
    /// 0.32 m/s, and a command played out a tick late doubles one tick's step (0.64 m/s).
    pub max_speed_m_per_s: f64,
    /// A state older than this holds the robot \[ns\]. Default 50 ms (`DESIGN.md` §12).
    pub state_timeout_ns: i64,
}

impl CommandLimits {
    /// Default step limit \[m\].
    pub const MAX_STEP_M: f64 = 0.002;
    /// Default speed limit \[m/s\].
    pub const MAX_SPEED_M_PER_S: f64 = 1.0;
    /// Default state timeout \[ns\].
    pub const STATE_TIMEOUT_NS: i64 = 50_000_000;

    /// The default limits in a cube of half-edge `half_m` \[m\] around `centre_m`.
    pub fn around(centre_m: Vec3, half_m: f64) -> CommandLimits {
        CommandLimits {
            workspace_min_m: centre_m.map(|c| c - half_m),
            workspace_max_m: centre_m.map(|c| c + half_m),
            max_step_m: Self::MAX_STEP_M,
            max_speed_m_per_s: Self::MAX_SPEED_M_PER_S,
            state_timeout_ns: Self::STATE_TIMEOUT_NS,
        }
    }

    /// Checks every field; the error names it, its value and the allowed range.
    pub fn validate(&self) -> Result<(), LimitsError> {
        for k in 0..3 {
            let (lo, hi) = (self.workspace_min_m[k], self.workspace_max_m[k]);
            if !(lo.is_finite() && hi.is_finite() && lo < hi && hi - lo <= 20.0) {
                return Err(LimitsError {
                    field: "workspace",
                    value: format!("{:?} .. {:?}", self.workspace_min_m, self.workspace_max_m),
                    expected: "finite corners with min < max on every axis, at most 20 m apart",
                });
            }
        }
        let positive = |field, v: f64, max: f64, expected| {
            if v.is_finite() && v > 0.0 && v <= max {
                Ok(())
            } else {
                Err(LimitsError {
                    field,
                    value: v.to_string(),
                    expected,
                })
            }
        };
        positive(
            "max_step_m",
            self.max_step_m,
            0.1,
            "0 < max_step_m <= 0.1 m",
        )?;
        positive(
            "max_speed_m_per_s",
            self.max_speed_m_per_s,
            3.0,
            "0 < max_speed_m_per_s <= 3 m/s",
        )?;
        if !(1_000_000..=1_000_000_000).contains(&self.state_timeout_ns) {
            return Err(LimitsError {
                field: "state_timeout",
                value: format!("{} ms", self.state_timeout_ns as f64 * 1e-6),
                expected: "1 to 1000 ms",
            });
        }
        Ok(())
    }
}

/// A command limit out of range.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("command limit {field} = {value}: expected {expected}")]
pub struct LimitsError {
    /// The field.
    pub field: &'static str,
    /// Its value.
    pub value: String,
    /// The allowed range.
    pub expected: &'static str,
}

/// How often one rule acted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Trip {
    /// Times the rule started acting.
    pub episodes: u64,
    /// Ticks on which it acted.
    pub ticks: u64,
    /// Acting now (not serialised).
    #[serde(skip)]
    pub active: bool,
}

impl Trip {
    /// Records one tick; `true` when the rule started acting this tick.
    fn record(&mut self, active: bool) -> bool {
        let rose = active && !self.active;
        if active {
            self.ticks += 1;
        }
        if rose {
            self.episodes += 1;
        }
        self.active = active;
        rose
    }
}

/// What the guard did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct GuardStats {
    /// Ticks guarded.
    pub ticks: u64,
    /// Ticks with nothing commanded: no state had arrived yet.
    pub no_state_ticks: u64,
    /// The state was older than the timeout: the last command held, estimation stopped.
    pub stale_state: Trip,
    /// Non-finite targets (the last command held).
    pub non_finite: Trip,
    /// Targets clamped into the workspace box.
    pub workspace: Trip,
    /// Moves cut to the maximum step.
    pub max_step: Trip,
    /// Moves or velocities cut to the maximum speed.
    pub max_speed: Trip,
}

impl GuardStats {
    /// Every rule with its name, for reports and logs.
    pub fn trips(&self) -> [(&'static str, Trip); 5] {
        [
            ("stale_state", self.stale_state),
            ("non_finite_target", self.non_finite),
            ("workspace", self.workspace),
            ("max_step", self.max_step),
            ("max_speed", self.max_speed),
        ]
    }
}

/// The guard. See the module docs for the rules and their order.
#[derive(Clone, Debug)]
pub struct CommandGuard {
    limits: CommandLimits,
    /// The newest state: its time \[ns, loop clock\] and the tool's position.
    reading: Option<(i64, Vec3)>,
    /// The last command: its time and position.
    last: Option<(i64, Vec3)>,
    stats: GuardStats,
}

impl CommandGuard {
    /// A guard for `limits` (validated).
    pub fn new(limits: CommandLimits) -> Result<CommandGuard, LimitsError> {
        limits.validate()?;
        Ok(CommandGuard {
            limits,
            reading: None,
            last: None,
            stats: GuardStats::default(),
        })
    }

    /// The limits.
    pub fn limits(&self) -> &CommandLimits {
        &self.limits
    }

    /// The robot reported its tool at `tool_m` at `time_ns` (loop clock). A non-finite position
    /// is not a state.
    pub fn on_reading(&mut self, time_ns: i64, tool_m: Vec3) {
        if vec3::is_finite(tool_m) {
            self.reading = Some((time_ns, tool_m));
        }
    }

    /// A new session: the next command is limited from where the robot is, not from where the
    /// last session left its commands (and the place for issue 11's per-session checks).
    pub fn restart(&mut self) {
        self.last = None;
    }

    /// Whether the newest state is older than the timeout at `now_ns` (or none came yet).
    pub fn state_is_stale(&self, now_ns: i64) -> bool {
        self.reading
            .is_none_or(|(t, _)| now_ns - t > self.limits.state_timeout_ns)
    }

    /// The command for this tick, or `None` when nothing may be commanded (no state yet).
    /// Returns the rules that started acting this tick (for the caller's log).
    pub fn apply(&mut self, now_ns: i64, target: &Target) -> (Option<Target>, Started) {
        self.stats.ticks += 1;
        let mut started = Started::default();
        let Some((_, tool)) = self.reading else {
            self.stats.no_state_ticks += 1;
            return (None, started);
        };
        let (last_ns, last) = self.last.unwrap_or((now_ns, tool));
        let stale = self.state_is_stale(now_ns);
        started.stale_state = self.stats.stale_state.record(stale);
        let finite = vec3::is_finite(target.position_m) && vec3::is_finite(target.velocity_m_per_s);
        started.non_finite = self.stats.non_finite.record(!stale && !finite);
        if stale || !finite {
            for t in [
                &mut self.stats.workspace,
                &mut self.stats.max_step,
                &mut self.stats.max_speed,
            ] {
                t.record(false);
            }
            self.last = Some((now_ns, last));
            return (
                Some(Target {
                    position_m: last,
                    velocity_m_per_s: [0.0; 3],
                    command_sample_time_ns: target.command_sample_time_ns,
                    holding: true,
                }),
                started,
            );
        }
        let l = self.limits;
        // 4. The workspace box.
        let boxed: Vec3 = std::array::from_fn(|k| {
            target.position_m[k].clamp(l.workspace_min_m[k], l.workspace_max_m[k])
        });
        started.workspace = self.stats.workspace.record(boxed != target.position_m);
        // 5. The step.
        let mut delta = vec3::sub(boxed, last);
        let len = vec3::norm(delta);
        let step_cut = len > l.max_step_m;
        if step_cut {
            delta = vec3::scale(delta, l.max_step_m / len);
        }
        started.max_step = self.stats.max_step.record(step_cut);
        // 6. The speed, over the time since the last command.
        let dt = ((now_ns - last_ns) as f64 * 1e-9).max(0.0);
        let allowed = l.max_speed_m_per_s * dt;
        let len = vec3::norm(delta);
        let move_cut = len > allowed && self.last.is_some();
        if move_cut {
            delta = vec3::scale(delta, allowed / len);
        }
        let mut velocity = target.velocity_m_per_s;
        let speed = vec3::norm(velocity);
        let velocity_cut = speed > l.max_speed_m_per_s;
        if velocity_cut {
            velocity = vec3::scale(velocity, l.max_speed_m_per_s / speed);
        }
        started.max_speed = self.stats.max_speed.record(move_cut || velocity_cut);
        let position = vec3::add(last, delta);
        self.last = Some((now_ns, position));
        (
            Some(Target {
                position_m: position,
                velocity_m_per_s: velocity,
                ..*target
            }),
            started,
        )
    }

    /// What the guard did so far.
    pub fn stats(&self) -> GuardStats {
        self.stats
    }
}

/// The rules that started acting this tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Started {
    /// The state went stale.
    pub stale_state: bool,
    /// A non-finite target.
    pub non_finite: bool,
    /// The workspace box.
    pub workspace: bool,
    /// The step limit.
    pub max_step: bool,
    /// The speed limit.
    pub max_speed: bool,
}

#[cfg(test)]
mod tests;
