//! Haptic devices: one trait with CRTK-style names ([`HapticDevice`]), one state machine shared by
//! every backend ([`ManagedDevice`]), and the backends themselves.
//!
//! What it is:
//! - [`HapticDevice`] — what the haptic loop talks to: `update(now)` reads the device once per
//!   tick, [`measured_cp`](HapticDevice::measured_cp) / [`measured_cv`](HapticDevice::measured_cv)
//!   return that reading, [`servo_cf`](HapticDevice::servo_cf) commands a force, and
//!   `enable`/`disable`/`reset` drive the state machine
//!   **disabled → enabled → faulted** ([`OperatingState`]).
//! - [`Backend`] — the small interface a driver implements (read, write a force, switch forces
//!   on/off). [`ManagedDevice`] wraps any backend and owns the state machine and the **enable
//!   ramp**, so every backend behaves the same way.
//! - Backends: [`scripted`] (a [`sim::trajectory::Trajectory`], the simulated twin),
//!   [`replay`] (a recorded CSV or MCAP), [`spacemouse`] (HID, input only), [`omega`] (Force Dimension SDK
//!   loaded at run time), [`ros`] (a device on a ROS 2 graph: forcedimension_ros2 by default).
//! - [`DeviceSpec`] / [`open_device`] — the `--device` value, parsed and opened.
//!
//! What it is not: no force shaping beyond the enable ramp and a last non-finite guard. Saturation,
//! rate limits, workspace limits, watchdogs, clutch and scaling live in [`crate::safety`], which sits
//! between the renderer and [`HapticDevice::servo_cf`].
//!
//! Time is always passed in (`now`, a [`Duration`] since the start of the run); nothing here reads
//! a clock, so the layer is tested without one.

pub mod managed;
pub mod omega;
pub mod replay;
pub mod ros;
pub mod scripted;
pub mod select;
pub mod spacemouse;

use std::time::Duration;

use serde::Serialize;

pub use managed::{ForceRecord, ManagedConfig, ManagedDevice};
pub use select::{DeviceSpec, OpenOptions, open_device, scripted_trajectory};

use mmt::vec3::{self, Vec3};

/// What a device can do. Each backend declares one; the safety layer reads its limits.
/// Field meanings follow CHAI3D's `cHapticDeviceInfo`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DeviceCapabilities {
    /// Human-readable model name (e.g. "omega.7 (SDK: …)", "SpaceMouse Compact").
    pub name: String,
    /// Whether forces written reach a human hand. `false` for the SpaceMouse (input only) and for
    /// the scripted and replay twins (forces are recorded, nothing moves).
    pub outputs_force: bool,
    /// Largest force magnitude the device may be commanded [N].
    pub max_force_n: f64,
    /// Largest stiffness the device renders stably [N/m]. Renderers and the workspace spring
    /// must stay below it.
    pub max_stiffness_n_per_m: f64,
    /// Largest damping the device renders stably [N·s/m].
    pub max_damping_n_s_per_m: f64,
    /// Reachable workspace in device coordinates [m].
    pub workspace: Workspace,
}

impl DeviceCapabilities {
    /// Omega.7 limits as coded in CHAI3D 3.3.0 (`CDeltaDevices.cpp`): 12 N, 5000 N/m,
    /// 30 N·s/m, workspace sphere of radius 0.075 m around the device origin.
    #[must_use]
    pub fn omega7(name: impl Into<String>) -> Self {
        Self {
            name: name.into(),
            outputs_force: true,
            max_force_n: 12.0,
            max_stiffness_n_per_m: 5000.0,
            max_damping_n_s_per_m: 30.0,
            workspace: Workspace::Sphere {
                center_m: vec3::ZERO,
                radius_m: 0.075,
            },
        }
    }
}

/// A workspace region in device coordinates [m].
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum Workspace {
    /// A ball of radius `radius_m` around `center_m`.
    Sphere {
        /// Centre [m].
        center_m: Vec3,
        /// Radius [m], > 0.
        radius_m: f64,
    },
    /// An axis-aligned box `center_m ± half_extent_m`.
    Box {
        /// Centre [m].
        center_m: Vec3,
        /// Half side lengths [m], each > 0.
        half_extent_m: Vec3,
    },
}

impl Workspace {
    /// The point of the workspace nearest to `p` (`p` itself when inside).
    #[must_use]
    pub fn clamp(&self, p: Vec3) -> Vec3 {
        match *self {
            Self::Sphere { center_m, radius_m } => {
                let d = vec3::sub(p, center_m);
                vec3::add(center_m, vec3::clamp_norm(d, radius_m))
            }
            Self::Box {
                center_m,
                half_extent_m,
            } => std::array::from_fn(|i| {
                p[i].clamp(
                    center_m[i] - half_extent_m[i],
                    center_m[i] + half_extent_m[i],
                )
            }),
        }
    }

    /// How far `p` lies outside the workspace, as the vector from the nearest inside point to
    /// `p` (zero inside). Points outward.
    #[must_use]
    pub fn excess(&self, p: Vec3) -> Vec3 {
        vec3::sub(p, self.clamp(p))
    }

    /// Short description with units, for listings.
    #[must_use]
    pub fn describe(&self) -> String {
        match self {
            Self::Sphere { radius_m, .. } => format!("sphere r = {radius_m} m"),
            Self::Box { half_extent_m, .. } => format!(
                "box {} × {} × {} m",
                2.0 * half_extent_m[0],
                2.0 * half_extent_m[1],
                2.0 * half_extent_m[2]
            ),
        }
    }
}

/// The device state machine (CRTK `operating_state`).
///
/// ```text
///   Disabled ──enable──▶ Enabled ──disable──▶ Disabled
///      ▲                   │ device error, servo watchdog, trip()
///      └──────reset─────── Faulted ◀─┘   (also from Disabled)
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum OperatingState {
    /// Forces off; zero force written. The start state.
    Disabled,
    /// Forces on; commanded forces reach the device (ramped in after enabling).
    Enabled,
    /// A fault happened; zero force written, forces off. Leaving it needs [`HapticDevice::reset`].
    Faulted,
}

/// Why a device went to [`OperatingState::Faulted`].
#[derive(Clone, Debug, PartialEq)]
pub struct Fault {
    /// When it happened (the `now` of the call that faulted).
    pub at: Duration,
    /// What happened.
    pub cause: FaultCause,
}

/// What made a device fault.
#[derive(Clone, Debug, PartialEq)]
pub enum FaultCause {
    /// The backend reported an error (message of the [`DeviceError`]).
    Device(String),
    /// `servo_cf` was not called for longer than the servo watchdog while enabled
    /// (the software twin of the hardware watchdog: the loop stalled).
    ServoWatchdog {
        /// Time between the two calls.
        gap: Duration,
        /// The configured limit.
        limit: Duration,
    },
    /// The caller tripped the device ([`HapticDevice::trip`]), with its reason.
    Requested(String),
}

impl std::fmt::Display for FaultCause {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Device(m) => write!(f, "device error: {m}"),
            Self::ServoWatchdog { gap, limit } => write!(
                f,
                "servo watchdog: no force command for {gap:?} (limit {limit:?})"
            ),
            Self::Requested(m) => write!(f, "tripped: {m}"),
        }
    }
}

/// One reading of the device, taken once per tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DeviceReading {
    /// Position of the handle in device coordinates [m].
    pub position_m: Vec3,
    /// Velocity of the handle [m/s].
    pub velocity_m_per_s: Vec3,
    /// The clutch input is held: SpaceMouse button 0, the omega's button 0. Backends without
    /// buttons (scripted, replay) never press it.
    pub clutch: bool,
}

/// A haptic device as the haptic loop sees it. Implemented by [`ManagedDevice`] over any
/// [`Backend`]; obtained from [`open_device`].
pub trait HapticDevice: Send {
    /// What the device can do (limits, workspace, whether it outputs force).
    fn spec(&self) -> &DeviceCapabilities;
    /// The state machine's state.
    fn operating_state(&self) -> OperatingState;
    /// The fault that put the device into [`OperatingState::Faulted`], if it is there.
    fn fault(&self) -> Option<&Fault>;
    /// Reads the device once for this tick. A read error faults the device.
    fn update(&mut self, now: Duration) -> Result<(), DeviceError>;
    /// Position of the latest reading [m] (CRTK `measured_cp`, translation only).
    fn measured_cp(&self) -> Vec3;
    /// Velocity of the latest reading [m/s] (CRTK `measured_cv`, translation only).
    fn measured_cv(&self) -> Vec3;
    /// The clutch input of the latest reading (true = held).
    fn clutch(&self) -> bool;
    /// Commands a force [N] (CRTK `servo_cf`). Reaches the device only while enabled, multiplied
    /// by the enable ramp; zero is written otherwise. Non-finite forces are written as zero.
    /// Call it every tick, also while disabled (it feeds the watchdogs).
    fn servo_cf(&mut self, now: Duration, force_n: Vec3) -> Result<(), DeviceError>;
    /// The force last written to the device [N].
    fn commanded_cf(&self) -> Vec3;
    /// Disabled → Enabled: writes zero, switches forces on, writes zero; the force then ramps in.
    /// Refused while faulted.
    fn enable(&mut self, now: Duration) -> Result<(), DeviceError>;
    /// Any state → Disabled (Faulted stays Faulted): **always writes zero force first**, then
    /// switches forces off.
    fn disable(&mut self, now: Duration) -> Result<(), DeviceError>;
    /// Faulted → Disabled, after writing zero and switching forces off. No-op otherwise.
    fn reset(&mut self, now: Duration) -> Result<(), DeviceError>;
    /// Puts the device into Faulted (writes zero, forces off) for a reason found outside it.
    fn trip(&mut self, now: Duration, reason: &str);
    /// Statistics of the forces written (for reports).
    fn force_record(&self) -> &ForceRecord;
    /// Times the device entered [`OperatingState::Faulted`] (for reports).
    fn fault_count(&self) -> u64;
    /// The backend's own counters (for reports; may lock, not for the loop).
    fn backend_report(&self) -> Option<BackendReport> {
        None
    }
    /// Ends the run: [`HapticDevice::disable`], then stops the backend's I/O (may block: not
    /// for a tick), so that [`HapticDevice::backend_report`] is final from here. The device is
    /// not used after it: reads fail, writes reach nothing.
    fn close(&mut self, now: Duration) -> Result<(), DeviceError>;
}

/// The driver interface a backend implements. Keep it small: the state machine, the ramp and the
/// recording live in [`ManagedDevice`].
pub trait Backend: Send {
    /// The backend's capabilities.
    fn capabilities(&self) -> &DeviceCapabilities;
    /// Reads position and velocity at `now`.
    fn read(&mut self, now: Duration) -> Result<DeviceReading, DeviceError>;
    /// Writes a force [N] (already finite, ramped and limited).
    fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError>;
    /// Switches the device's force output on or off.
    fn set_force_enabled(&mut self, on: bool) -> Result<(), DeviceError>;
    /// The backend's own counters, if it keeps any (for reports; not for the loop: it may
    /// lock).
    fn report(&self) -> Option<BackendReport> {
        None
    }
    /// Stops the backend's own I/O, once zero is written and forces are off, so that its
    /// report is final (what it wrote while stopping included). Default: it has none.
    fn close(&mut self) {}
}

/// A backend's own counters in the run report.
#[derive(Clone, Debug, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BackendReport {
    /// The ROS 2 device: what arrived, what was refused, what was published.
    Ros2(Box<ros2::haptic::HapticReport>),
}

/// Errors of the device layer. Each says what failed, with the value and what was expected.
#[derive(Debug, thiserror::Error)]
pub enum DeviceError {
    /// A `--device` value that is not one of the allowed forms.
    #[error(
        "invalid device '{value}': {reason}; allowed forms: scripted:NAME, replay:FILE.csv, replay:FILE.mcap, spacemouse, omega, ros2"
    )]
    InvalidSpec {
        /// The value given.
        value: String,
        /// What is wrong with it.
        reason: String,
    },
    /// `scripted:NAME` with an unknown name.
    #[error("unknown scripted trajectory '{name}'; known: {known}")]
    UnknownTrajectory {
        /// The name given.
        name: String,
        /// Comma-separated known names.
        known: String,
    },
    /// A configuration value out of range.
    #[error("invalid {field} = {value}: expected {expected}")]
    InvalidConfig {
        /// Which setting.
        field: &'static str,
        /// The value given.
        value: String,
        /// What is allowed.
        expected: &'static str,
    },
    /// A replay file that cannot be used.
    #[error(transparent)]
    Replay(#[from] replay::ReplayError),
    /// No device of this kind was found.
    #[error("no {backend} device found: {detail}")]
    NotFound {
        /// Backend name.
        backend: &'static str,
        /// What was looked for and where.
        detail: String,
    },
    /// The HID layer failed. (The hidapi error is in the message, not the `source()`, so that
    /// printed error chains do not repeat it.)
    #[error("HID: {what}: {error}")]
    Hid {
        /// What was being done.
        what: String,
        /// The hidapi error.
        error: hidapi::HidError,
    },
    /// The Force Dimension SDK could not be loaded or is incomplete.
    #[error(transparent)]
    SdkLoad(#[from] omega::sdk::SdkLoadError),
    /// An SDK call returned an error.
    #[error("Force Dimension SDK: {call} failed (returned {code}): {message}")]
    Sdk {
        /// The C function.
        call: &'static str,
        /// Its return value.
        code: i32,
        /// `dhdErrorGetLastStr()`.
        message: String,
    },
    /// The device switched its forces off by itself (its firmware watchdog, its velocity guard, a
    /// button, a disconnection), while the app had them on.
    #[error("the device switched its forces off: {cause}")]
    ForcesOff {
        /// Why, as the device reported it.
        cause: String,
    },
    /// The ROS 2 device could not start (the graph, a topic, no pose).
    #[error(transparent)]
    Ros2(#[from] ros2::haptic::HapticError),
    /// The ROS 2 device's pose stopped: the newest valid pose arrived longer ago than the limit.
    #[error(
        "no valid pose on {topic} for {age:?} (limit {limit:?}): forces off; the driver stopped \
         publishing, or refused poses (the report's ros2 device counts say which)"
    )]
    StalePose {
        /// The pose topic.
        topic: std::sync::Arc<str>,
        /// Time since the newest valid pose arrived (the I/O thread's receipt).
        age: Duration,
        /// The limit.
        limit: Duration,
    },
    /// The device is faulted; [`HapticDevice::reset`] it first.
    #[error("device is faulted ({cause}); reset it before enabling")]
    Faulted {
        /// The fault's cause.
        cause: String,
    },
}
