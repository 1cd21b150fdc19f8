//! The safety layer: **one** layer between the renderer and the device, whatever the backend.
//! It runs inside the 1 kHz loop: no allocation, no locks, no per-tick logging (each rule logs a
//! `tracing` event when it starts and stops acting, and counts into [`SafetyStats`]).
//!
//! Position path ([`SafetyLayer::command_position`], [`SafetyLayer::command_velocity`]): clutch
//! and position scaling, translation only, never a jump ([`position`]). A non-finite measured
//! position holds the last command; a non-finite measured velocity is replaced by zero (the
//! velocity feeds the renderer's damping: a NaN there would make the force NaN, and a held
//! velocity would keep damping a motion that may have stopped). Both are counted.
//!
//! Force path ([`SafetyLayer::filter_force`]), in this order, and why:
//! 1. **Non-finite → zero.** A NaN/inf component means the renderer is broken; its last finite
//!    value is not trusted either, so the output goes to zero **at once** (not rate limited —
//!    removing force cannot inject energy) and stays zero while the storm lasts. While the clutch
//!    is engaged the renderer's force is also replaced by zero (then rate limited, no step).
//! 2. **Parameter-age fade** ([`watchdog`]): while a model is rendered from parameters older than
//!    allowed, the renderer's force fades out (and back in after recovery). The renderer's force
//!    only: with no model yet nothing is stale (the telerobot sends parameters only after the
//!    first contact), and an old model never switches off a safety force.
//! 3. **Saturation** of the renderer force at the device's max force (vector norm, direction
//!    kept).
//! 4. **Workspace soft limit**: beyond the device workspace a spring
//!    (`workspace_stiffness_n_per_m` × distance outside) pushes back. It is added *after* the
//!    renderer force was saturated and has **priority**: the sum is kept within max force by
//!    shrinking the renderer force, never the spring, so a renderer pushing outward cannot cancel
//!    the push-back. (Saturating after the sum would let it; adding after without a budget would
//!    exceed max force.)
//! 5. **Loop-overrun fade** ([`watchdog`]): fades everything to zero when the loop misses its
//!    deadline by more than allowed, and back in after recovery. It scales the spring too: when
//!    timing is lost no force computed from the loop's positions is trusted; the device's own
//!    watchdog is the next line.
//! 6. **Force-rate limit** [N/s], so no rule above (clutch, workspace entry, model switch) can
//!    make the output step.
//! 7. **Passivity** ([`passivity`]): the energy observed at the device port over the last tick
//!    (with the force actually written), and the damping that keeps it from going negative,
//!    added last so nothing after it undoes it; then saturation again (a damping force may not
//!    exceed the device either; scaling down keeps the port passive).
//! 8. A final finite check.
//!
//! The enable ramp is not here: it belongs to the device state machine
//! ([`crate::device::ManagedDevice`]), which multiplies this layer's output.

pub mod passivity;
pub mod position;
pub mod stats;
pub mod watchdog;

use std::time::Duration;

pub use passivity::{PassivityConfig, PassivityStats};
pub use position::{InvalidScale, PositionMap, PositionScale};
pub use stats::{Edge, SafetyStats, TripCount};
pub use watchdog::{Model, SoftWatchdog, WatchdogConfig};

use crate::device::{DeviceCapabilities, Workspace};
use mmt::vec3::{self, Vec3};
use watchdog::WatchdogTick;

/// Safety settings. The device's limits come from its [`DeviceCapabilities`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SafetyConfig {
    /// Lower force limit than the device's [N], if wanted. Default none (device max).
    pub force_limit_n: Option<f64>,
    /// Largest change of the output force per second [N/s], > 0. Default 1000 N/s (1 N per tick at
    /// 1 kHz: the omega.7's 12 N in 12 ms — felt as a firm contact, not a kick).
    pub max_force_rate_n_per_s: f64,
    /// Stiffness of the workspace spring [N/m], ≥ 0, capped at the device's max stiffness.
    /// Default 500 N/m (4 N at 8 mm outside: clearly felt, far below the omega's 5000 N/m).
    pub workspace_stiffness_n_per_m: f64,
    /// Software watchdog settings.
    pub watchdog: WatchdogConfig,
    /// Initial position scale (commanded m per device m), finite and > 0. Default 1.
    pub position_scale: f64,
    /// Where the device's origin is in the telerobot's world [m]: commanded = origin + scale ·
    /// measured (translation only; the clutch shifts it further). Finite, each coordinate within
    /// ±10 m. Default the world origin (the scripted devices already move in world coordinates).
    pub device_origin_m: Vec3,
    /// Passivity observer and controller at the device port.
    pub passivity: PassivityConfig,
}

impl Default for SafetyConfig {
    fn default() -> Self {
        Self {
            force_limit_n: None,
            max_force_rate_n_per_s: 1000.0,
            workspace_stiffness_n_per_m: 500.0,
            watchdog: WatchdogConfig::default(),
            position_scale: 1.0,
            device_origin_m: vec3::ZERO,
            passivity: PassivityConfig::default(),
        }
    }
}

/// A safety setting out of range.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SafetyError {
    /// A setting out of range.
    #[error("invalid safety setting {field} = {value}: expected {expected}")]
    InvalidConfig {
        /// Which setting.
        field: &'static str,
        /// The value given.
        value: String,
        /// What is allowed.
        expected: &'static str,
    },
    /// A bad position scale.
    #[error(transparent)]
    Scale(#[from] InvalidScale),
}

/// The inputs of one force tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceTick {
    /// Time since the start of the run.
    pub now: Duration,
    /// The device's measured position this tick [m] (device coordinates).
    pub measured_cp: Vec3,
    /// What the renderer renders from: no model, or a model and the age of its parameters.
    pub model: Model,
    /// The renderer's force [N].
    pub force_n: Vec3,
}

/// The safety layer. See the module docs for the rules and their order.
#[derive(Clone, Debug)]
pub struct SafetyLayer {
    max_force_n: f64,
    max_rate_n_per_s: f64,
    workspace: Workspace,
    workspace_k: f64,
    watchdog: SoftWatchdog,
    position: PositionMap,
    passivity: passivity::Passivity,
    last_force: Vec3,
    stats: SafetyStats,
}

fn positive(field: &'static str, v: f64, expected: &'static str) -> Result<f64, SafetyError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(SafetyError::InvalidConfig {
            field,
            value: v.to_string(),
            expected,
        })
    }
}

fn positive_duration(field: &'static str, d: Duration) -> Result<(), SafetyError> {
    if d.is_zero() {
        Err(SafetyError::InvalidConfig {
            field,
            value: format!("{d:?}"),
            expected: "a positive duration",
        })
    } else {
        Ok(())
    }
}

impl SafetyLayer {
    /// A layer for a device with capabilities `device`.
    pub fn new(device: &DeviceCapabilities, config: &SafetyConfig) -> Result<Self, SafetyError> {
        let mut max_force_n = device.max_force_n.max(0.0);
        if let Some(limit) = config.force_limit_n {
            max_force_n =
                max_force_n.min(positive("force_limit_n", limit, "a finite force > 0 N")?);
        }
        let max_rate_n_per_s = positive(
            "max_force_rate_n_per_s",
            config.max_force_rate_n_per_s,
            "a finite rate > 0 N/s",
        )?;
        let k = config.workspace_stiffness_n_per_m;
        if !(k.is_finite() && k >= 0.0) {
            return Err(SafetyError::InvalidConfig {
                field: "workspace_stiffness_n_per_m",
                value: k.to_string(),
                expected: "a finite stiffness ≥ 0 N/m",
            });
        }
        let w = &config.watchdog;
        positive_duration("watchdog.nominal_period", w.nominal_period)?;
        positive_duration("watchdog.fade_out", w.fade_out)?;
        positive_duration("watchdog.fade_in", w.fade_in)?;
        if w.recovery_hold < w.fade_out {
            return Err(SafetyError::InvalidConfig {
                field: "watchdog.recovery_hold",
                value: format!("{:?}", w.recovery_hold),
                expected: "at least watchdog.fade_out, so that every trip reaches zero force",
            });
        }
        let p = &config.passivity;
        let max_damping = match p.max_damping_n_s_per_m {
            None => device.max_damping_n_s_per_m.max(0.0),
            Some(d) if d.is_finite() && d >= 0.0 => d,
            Some(d) => {
                return Err(SafetyError::InvalidConfig {
                    field: "passivity.max_damping_n_s_per_m",
                    value: d.to_string(),
                    expected: "a finite damping ≥ 0 N·s/m",
                });
            }
        };
        positive(
            "passivity.energy_cap_j",
            p.energy_cap_j,
            "a finite energy > 0 J",
        )?;
        if !config
            .device_origin_m
            .iter()
            .all(|c| c.is_finite() && c.abs() <= 10.0)
        {
            return Err(SafetyError::InvalidConfig {
                field: "device_origin_m",
                value: format!("{:?}", config.device_origin_m),
                expected: "three finite coordinates within ±10 m",
            });
        }
        Ok(Self {
            max_force_n,
            max_rate_n_per_s,
            workspace: device.workspace,
            workspace_k: k.min(device.max_stiffness_n_per_m.max(0.0)),
            watchdog: SoftWatchdog::new(*w),
            position: PositionMap::new(PositionScale::new(config.position_scale)?)
                .with_origin(config.device_origin_m),
            passivity: passivity::Passivity::new(p, max_damping),
            last_force: vec3::ZERO,
            stats: SafetyStats::default(),
        })
    }

    /// The counters so far.
    #[must_use]
    pub fn stats(&self) -> SafetyStats {
        SafetyStats {
            passivity: *self.passivity.stats(),
            ..self.stats
        }
    }

    /// The rules acting at the last tick, one bit each in the order of
    /// `record::schema::SafetyFlags::NAMES` (for the recording: no allocation, no copy of the
    /// counters).
    #[must_use]
    pub fn active_bits(&self) -> u32 {
        let s = &self.stats;
        [
            s.non_finite_force.active,
            s.non_finite_position.active,
            s.non_finite_velocity.active,
            s.saturated.active,
            s.rate_limited.active,
            s.workspace.active,
            s.loop_overrun.active,
            s.stale_params.active,
            s.watchdog_fading.active,
            s.clutch.active,
            self.passivity.stats().controlling.active,
        ]
        .iter()
        .enumerate()
        .fold(0, |bits, (i, on)| bits | (u32::from(*on) << i))
    }

    /// The force limit in use [N].
    #[must_use]
    pub fn max_force_n(&self) -> f64 {
        self.max_force_n
    }

    /// The watchdog's gain on the renderer's force now, in [0, 1] (both rules).
    #[must_use]
    pub fn watchdog_gain(&self) -> f64 {
        self.watchdog.gain()
    }

    /// The nominal loop period the overrun rule measures against.
    #[must_use]
    pub fn loop_period(&self) -> Duration {
        self.watchdog.config().nominal_period
    }

    /// Sets the nominal loop period to the session's tick period (the telerobot's control rate
    /// is only known from its `Welcome`); the overrun allowance stays
    /// [`WatchdogConfig::max_overrun`]. Refuses a zero period.
    pub fn set_loop_period(&mut self, period: Duration) -> Result<(), SafetyError> {
        positive_duration("watchdog.nominal_period", period)?;
        self.watchdog.set_nominal_period(period);
        Ok(())
    }

    /// The clutch and scale state.
    #[must_use]
    pub fn position_map(&self) -> &PositionMap {
        &self.position
    }

    /// Changes the position scale without moving the commanded position. Refuses zero, negative,
    /// NaN and infinite factors (counted, logged, the old scale kept).
    pub fn set_position_scale(&mut self, factor: f64) -> Result<(), InvalidScale> {
        match PositionScale::new(factor) {
            Ok(s) => {
                tracing::info!(scale = factor, "position scale changed");
                self.position.set_scale(s);
                Ok(())
            }
            Err(e) => {
                self.stats.scale_rejections += 1;
                tracing::warn!(error = %e, "position scale change refused");
                Err(e)
            }
        }
    }

    /// Position path, once per tick: the commanded position [m] for the measured device position
    /// and the clutch button (true = engaged).
    pub fn command_position(&mut self, measured_cp: Vec3, clutch: bool) -> Vec3 {
        let finite = vec3::is_finite(measured_cp);
        log_edge(
            self.stats.non_finite_position.record(!finite),
            "non-finite position",
            "measured position not finite; commanded position held",
        );
        if !finite {
            return self.position.hold();
        }
        let commanded = self.position.update(measured_cp, clutch);
        log_edge(
            self.stats.clutch.record(self.position.clutched()),
            "clutch",
            "clutch engaged; commanded position held",
        );
        commanded
    }

    /// Velocity path, once per tick after [`Self::command_position`]: the commanded velocity
    /// [m/s] for the measured device velocity — scaled, zero while clutched, and zero when not
    /// finite (counted, logged once per episode).
    pub fn command_velocity(&mut self, measured_cv: Vec3) -> Vec3 {
        let finite = vec3::is_finite(measured_cv);
        log_edge(
            self.stats.non_finite_velocity.record(!finite),
            "non-finite velocity",
            "measured velocity not finite; zero velocity commanded",
        );
        if !finite || self.position.clutched() {
            return vec3::ZERO;
        }
        vec3::scale(measured_cv, self.position.scale().get())
    }

    /// Force path, once per tick: the force to hand to `servo_cf` [N]. See the module docs.
    pub fn filter_force(&mut self, tick: &ForceTick) -> Vec3 {
        self.stats.ticks += 1;
        let wd = self.watch(tick);

        // The energy of the interval that just ended, with the force that was written.
        self.passivity.observe(tick.measured_cp, self.last_force);

        // 1. Non-finite: zero at once, bypassing the rate limit.
        let finite = vec3::is_finite(tick.force_n);
        log_edge(
            self.stats.non_finite_force.record(!finite),
            "non-finite force",
            "renderer force not finite; zero written",
        );
        if !finite {
            log_edge(self.stats.rate_limited.record(false), "rate limit", "");
            self.last_force = vec3::ZERO;
            return vec3::ZERO;
        }
        let renderer = if self.position.clutched() {
            vec3::ZERO
        } else {
            tick.force_n
        };

        // 2. Parameter-age fade, on the renderer's force only.
        let renderer = vec3::scale(renderer, wd.model_gain);

        // 3. Saturation and 4. the workspace spring.
        let total = self.within_budget(renderer, tick.measured_cp);

        // 5. Loop-overrun fade, on everything.
        let faded = vec3::scale(total, wd.timing_gain);

        // 6. Rate limit.
        let out = self.rate_limit(faded, wd.dt_s);

        // 7. Passivity, then the device limit again.
        let out = self.passive(out, wd.dt_s);

        // 8. Final guard.
        let out = if vec3::is_finite(out) {
            out
        } else {
            vec3::ZERO
        };
        self.last_force = out;
        out
    }

    /// The watchdog's tick, with its three rules' state changes logged.
    fn watch(&mut self, tick: &ForceTick) -> WatchdogTick {
        let s = &mut self.stats;
        let wd = self.watchdog.step(tick.now, tick.model);
        log_edge(
            s.loop_overrun.record(wd.overrun),
            "loop overrun",
            "haptic loop missed its deadline; fading force out",
        );
        log_edge(
            s.stale_params.record(wd.stale),
            "stale parameters",
            "model parameters too old; fading the renderer's force out",
        );
        log_edge(
            s.watchdog_fading.record(wd.renderer_gain() < 1.0),
            "watchdog",
            "force below full strength",
        );
        wd
    }

    /// Steps 3 and 4: the renderer's force saturated, plus the workspace spring at the device
    /// position `measured_cp` with priority in the force budget.
    fn within_budget(&mut self, renderer: Vec3, measured_cp: Vec3) -> Vec3 {
        let s = &mut self.stats;
        // 3. Saturation of the renderer force.
        let mut saturated = vec3::norm(renderer) > self.max_force_n;
        let renderer = vec3::clamp_norm(renderer, self.max_force_n);

        // 4. Workspace spring with priority in the force budget.
        let outside = if vec3::is_finite(measured_cp) {
            self.workspace.excess(measured_cp)
        } else {
            vec3::ZERO
        };
        let outside_now = vec3::norm(outside) > 0.0;
        log_edge(
            s.workspace.record(outside_now),
            "workspace",
            "device outside its workspace; spring pushing back",
        );
        let spring = vec3::clamp_norm(vec3::scale(outside, -self.workspace_k), self.max_force_n);
        let alpha = budget(spring, renderer, self.max_force_n);
        saturated |= alpha < 1.0;
        log_edge(
            s.saturated.record(saturated),
            "saturation",
            "force limited to the device maximum",
        );
        vec3::add(spring, vec3::scale(renderer, alpha))
    }

    /// Step 6: the force `target` reached from the last one written at no more than the rate
    /// limit over `dt_s` [s].
    fn rate_limit(&mut self, target: Vec3, dt_s: f64) -> Vec3 {
        let step = vec3::sub(target, self.last_force);
        let max_step = self.max_rate_n_per_s * dt_s;
        let limited = vec3::norm(step) > max_step;
        log_edge(
            self.stats.rate_limited.record(limited),
            "rate limit",
            "force change limited",
        );
        vec3::add(self.last_force, vec3::clamp_norm(step, max_step))
    }

    /// Step 7: the passivity controller's damping added to `out`, then the device limit again.
    fn passive(&mut self, out: Vec3, dt_s: f64) -> Vec3 {
        // The controller's own episodes are counted, not logged: they can be many short ones.
        let (out, _, capped) = self.passivity.control(out, dt_s);
        log_edge(
            capped,
            "passivity cap",
            "passivity damping capped at the device's limit",
        );
        vec3::clamp_norm(out, self.max_force_n)
    }
}

/// Largest α in [0, 1] with |spring + α·renderer| ≤ max (|spring| ≤ max is given).
fn budget(spring: Vec3, renderer: Vec3, max: f64) -> f64 {
    let a = vec3::dot(renderer, renderer);
    if a == 0.0 {
        return 1.0;
    }
    let b = vec3::dot(spring, renderer);
    let c = (vec3::dot(spring, spring) - max * max).min(0.0);
    let alpha = (-b + (b * b - a * c).max(0.0).sqrt()) / a;
    alpha.clamp(0.0, 1.0)
}

/// Logs a rule's state change (never per tick).
fn log_edge(edge: Edge, rule: &'static str, what: &'static str) {
    match edge {
        Edge::Rose => tracing::warn!(rule, "{what}"),
        Edge::Fell => tracing::info!(rule, "safety rule no longer active"),
        Edge::Steady => {}
    }
}

#[cfg(test)]
mod tests;
