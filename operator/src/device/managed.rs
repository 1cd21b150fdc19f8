//! [`ManagedDevice`]: the state machine, the enable ramp and the force record, shared by every
//! backend.
//!
//! Where the enable ramp lives: **here**, not in the safety layer. It belongs to the transition
//! Disabled → Enabled, which only the device knows about; the safety layer shapes the renderer's
//! force (saturation, rate, workspace, watchdogs) and hands the result to
//! [`HapticDevice::servo_cf`], which multiplies it by the ramp gain
//! `clamp((now − enabled_at) / ramp, 0, 1)` before writing.
//!
//! The servo watchdog is also here: while enabled, two `servo_cf` calls further apart than
//! [`ManagedConfig::servo_watchdog`] fault the device (the loop stalled; the fading software
//! watchdog of the safety layer covers the milder cases). It mirrors the hardware watchdog of the
//! Force Dimension firmware, which switches forces off and stays off.

use std::time::Duration;

use serde::Serialize;

use super::{
    Backend, DeviceCapabilities, DeviceError, DeviceReading, Fault, FaultCause, HapticDevice,
    OperatingState,
};
use mmt::vec3::{self, Vec3};

/// Settings of the state machine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ManagedConfig {
    /// Time over which force ramps from 0 to 100 % after enabling. Default 200 ms: long enough
    /// that a held contact force does not kick the hand, short enough not to be noticed.
    /// Zero means no ramp.
    pub enable_ramp: Duration,
    /// Largest gap between two `servo_cf` calls while enabled before the device faults.
    /// Default 50 ms (50 missed ticks at 1 kHz; the omega's hardware watchdog is set shorter).
    pub servo_watchdog: Duration,
}

impl Default for ManagedConfig {
    fn default() -> Self {
        Self {
            enable_ramp: Duration::from_millis(200),
            servo_watchdog: Duration::from_millis(50),
        }
    }
}

impl ManagedConfig {
    /// Checks the settings: the servo watchdog must be positive.
    pub fn validate(&self) -> Result<(), DeviceError> {
        if self.servo_watchdog.is_zero() {
            return Err(DeviceError::InvalidConfig {
                field: "servo_watchdog",
                value: format!("{:?}", self.servo_watchdog),
                expected: "a positive duration",
            });
        }
        Ok(())
    }
}

/// Statistics of the forces written to the device, without storing them (no allocation in the
/// loop). Serialised into run reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ForceRecord {
    /// Number of `servo_cf` calls.
    pub ticks: u64,
    /// Ticks on which a non-zero force was written.
    pub nonzero_ticks: u64,
    /// Last force written [N].
    pub last_n: Vec3,
    /// Largest force magnitude written [N].
    pub max_norm_n: f64,
    /// Sum of squared magnitudes [N²] (for the RMS).
    pub sum_sq_n2: f64,
}

impl ForceRecord {
    fn record(&mut self, f: Vec3) {
        let n = vec3::norm(f);
        self.ticks += 1;
        if n > 0.0 {
            self.nonzero_ticks += 1;
        }
        self.last_n = f;
        self.max_norm_n = self.max_norm_n.max(n);
        self.sum_sq_n2 += n * n;
    }

    /// RMS of the force magnitude over all ticks [N].
    #[must_use]
    pub fn rms_n(&self) -> f64 {
        if self.ticks == 0 {
            0.0
        } else {
            // Precision loss only past 2^53 ticks (285 000 years at 1 kHz).
            #[allow(clippy::cast_precision_loss)]
            let n = self.ticks as f64;
            (self.sum_sq_n2 / n).sqrt()
        }
    }
}

enum State {
    Disabled,
    Enabled { since: Duration },
    Faulted(Fault),
}

/// A [`Backend`] wrapped in the shared state machine. See the module docs.
pub struct ManagedDevice<B: Backend> {
    backend: B,
    config: ManagedConfig,
    state: State,
    reading: DeviceReading,
    last_servo: Option<Duration>,
    record: ForceRecord,
    faults: u64,
}

impl<B: Backend> ManagedDevice<B> {
    /// Wraps an opened backend. The device starts Disabled; nothing is written until the first
    /// call (backends leave the hardware with forces off and zero force at open).
    pub fn new(backend: B, config: ManagedConfig) -> Result<Self, DeviceError> {
        config.validate()?;
        Ok(Self {
            backend,
            config,
            state: State::Disabled,
            reading: DeviceReading::default(),
            last_servo: None,
            record: ForceRecord::default(),
            faults: 0,
        })
    }

    /// The wrapped backend (for tests and backend-specific diagnostics).
    pub fn backend(&self) -> &B {
        &self.backend
    }

    fn ramp_gain(&self, now: Duration, since: Duration) -> f64 {
        if self.config.enable_ramp.is_zero() {
            return 1.0;
        }
        let t = now.saturating_sub(since).as_secs_f64();
        (t / self.config.enable_ramp.as_secs_f64()).clamp(0.0, 1.0)
    }

    /// Writes `f`, recording it. Backend errors are returned, not handled.
    fn write(&mut self, f: Vec3) -> Result<(), DeviceError> {
        self.backend.write_force(f)?;
        self.record.record(f);
        Ok(())
    }

    /// Enters Faulted (once), writing zero and switching forces off on a best-effort basis.
    fn enter_fault(&mut self, now: Duration, cause: FaultCause) {
        if let State::Faulted(_) = self.state {
            return;
        }
        tracing::error!(at = ?now, %cause, device = %self.backend.capabilities().name, "device faulted; forces off");
        // Best effort: the backend may be what failed. The fault is recorded either way.
        let _zero = self.write(vec3::ZERO);
        let _off = self.backend.set_force_enabled(false);
        self.faults += 1;
        self.state = State::Faulted(Fault { at: now, cause });
    }

    /// Runs a backend operation; an error faults the device and is returned. (Once faulted,
    /// a failing backend's message is not formatted again: no allocation per tick.)
    fn guarded<T>(
        &mut self,
        now: Duration,
        op: impl FnOnce(&mut Self) -> Result<T, DeviceError>,
    ) -> Result<T, DeviceError> {
        op(self).inspect_err(|e| {
            if !matches!(self.state, State::Faulted(_)) {
                self.enter_fault(now, FaultCause::Device(e.to_string()));
            }
        })
    }
}

impl<B: Backend> HapticDevice for ManagedDevice<B> {
    fn spec(&self) -> &DeviceCapabilities {
        self.backend.capabilities()
    }

    fn operating_state(&self) -> OperatingState {
        match self.state {
            State::Disabled => OperatingState::Disabled,
            State::Enabled { .. } => OperatingState::Enabled,
            State::Faulted(_) => OperatingState::Faulted,
        }
    }

    fn fault(&self) -> Option<&Fault> {
        match &self.state {
            State::Faulted(f) => Some(f),
            _ => None,
        }
    }

    fn update(&mut self, now: Duration) -> Result<(), DeviceError> {
        let reading = self.guarded(now, |d| d.backend.read(now))?;
        self.reading = reading;
        Ok(())
    }

    fn measured_cp(&self) -> Vec3 {
        self.reading.position_m
    }

    fn measured_cv(&self) -> Vec3 {
        self.reading.velocity_m_per_s
    }

    fn clutch(&self) -> bool {
        self.reading.clutch
    }

    fn servo_cf(&mut self, now: Duration, force_n: Vec3) -> Result<(), DeviceError> {
        let previous = self.last_servo.replace(now);
        match self.state {
            State::Enabled { since } => {
                if let Some(prev) = previous {
                    let gap = now.saturating_sub(prev);
                    if gap > self.config.servo_watchdog {
                        let limit = self.config.servo_watchdog;
                        self.enter_fault(now, FaultCause::ServoWatchdog { gap, limit });
                        return Err(DeviceError::Faulted {
                            cause: FaultCause::ServoWatchdog { gap, limit }.to_string(),
                        });
                    }
                }
                let f = if vec3::is_finite(force_n) {
                    vec3::scale(force_n, self.ramp_gain(now, since))
                } else {
                    vec3::ZERO
                };
                self.guarded(now, |d| d.write(f))
            }
            State::Disabled => self.guarded(now, |d| d.write(vec3::ZERO)),
            // The backend may be broken; keep trying to hold zero, ignore its errors.
            State::Faulted(_) => {
                let _zero = self.write(vec3::ZERO);
                Ok(())
            }
        }
    }

    fn commanded_cf(&self) -> Vec3 {
        self.record.last_n
    }

    fn enable(&mut self, now: Duration) -> Result<(), DeviceError> {
        match &self.state {
            State::Enabled { .. } => Ok(()),
            State::Faulted(f) => Err(DeviceError::Faulted {
                cause: f.cause.to_string(),
            }),
            State::Disabled => {
                self.guarded(now, |d| {
                    d.write(vec3::ZERO)?;
                    d.backend.set_force_enabled(true)?;
                    d.write(vec3::ZERO)
                })?;
                tracing::info!(at = ?now, ramp = ?self.config.enable_ramp, "device enabled");
                self.state = State::Enabled { since: now };
                self.last_servo = Some(now);
                Ok(())
            }
        }
    }

    fn disable(&mut self, now: Duration) -> Result<(), DeviceError> {
        let faulted = matches!(self.state, State::Faulted(_));
        let result = self.guarded(now, |d| {
            d.write(vec3::ZERO)?;
            d.backend.set_force_enabled(false)
        });
        if !faulted && result.is_ok() {
            if matches!(self.state, State::Enabled { .. }) {
                tracing::info!(at = ?now, "device disabled");
            }
            self.state = State::Disabled;
        }
        result
    }

    fn reset(&mut self, now: Duration) -> Result<(), DeviceError> {
        if !matches!(self.state, State::Faulted(_)) {
            return Ok(());
        }
        self.write(vec3::ZERO)?;
        self.backend.set_force_enabled(false)?;
        tracing::info!(at = ?now, "device fault reset; disabled");
        self.state = State::Disabled;
        Ok(())
    }

    fn trip(&mut self, now: Duration, reason: &str) {
        self.enter_fault(now, FaultCause::Requested(reason.to_owned()));
    }

    fn force_record(&self) -> &ForceRecord {
        &self.record
    }

    fn fault_count(&self) -> u64 {
        self.faults
    }

    fn backend_report(&self) -> Option<super::BackendReport> {
        self.backend.report()
    }

    fn close(&mut self, now: Duration) -> Result<(), DeviceError> {
        let disabled = self.disable(now);
        self.backend.close();
        disabled
    }
}

#[cfg(test)]
mod tests;
