//! The `omega` backend: a Force Dimension omega.x through the vendor DHD SDK, loaded at run time
//! ([`sdk`]). The Omega is not a HID device (vendor-class USB, VID 0x1451, driven by libdhd over
//! libusb), so there is no way around the SDK.
//!
//! Order of calls (tested against the SDK double):
//! - **open**: `dhdGetDeviceCount` → `dhdOpen` → `dhdGetSystemType`/`dhdGetSystemName` →
//!   `dhdEnableExpertMode` → **`dhdSetWatchdog`** (firmware cuts forces when commands stop) →
//!   velocity guard (`dhdGetVelocityThreshold`, or `dhdSetVelocityThreshold` when configured) →
//!   `dhdSetForce(0)` → `dhdEnableForce(off)`;
//! - **enable** (from [`super::ManagedDevice`]): `dhdSetForce(0)` → `dhdEnableForce(on)` →
//!   `dhdSetForce(0)`;
//! - **disable**: `dhdSetForce(0)` → `dhdEnableForce(off)`;
//! - **drop**: `dhdSetForce(0)` → `dhdEnableForce(off)` → `dhdClose`;
//! - **read**, once per tick: `dhdGetStatus` → `dhdGetPosition` → `dhdGetLinearVelocity` →
//!   `dhdGetButton(0)` (the clutch: the button on the handle). While
//!   the app has forces on, a status with forces off (the SDK's watchdog, the velocity guard's
//!   brake, the force button, a disconnection) is a [`DeviceError::ForcesOff`] naming the cause,
//!   which faults the device ([`super::ManagedDevice`] writes zero and switches forces off).
//!
//! The velocity guard: the firmware brakes when an axis moves faster than a threshold. Force
//! Dimension recommends keeping the factory value, so by default it is read and the device is
//! refused if the guard is off (0, e.g. left so by a program that disabled it);
//! [`OmegaConfig::velocity_threshold`] sets it explicitly instead (never to 0).
//!
//! Limits: the omega.x family (omega.3/6/7) gets CHAI3D's omega.7 limits
//! ([`DeviceCapabilities::omega7`]); other Force Dimension devices are refused until their
//! limits are entered here.

pub mod sdk;

use std::ffi::{OsString, c_char};
use std::path::PathBuf;
use std::time::Duration;

use self::sdk::Dhd;
use super::{Backend, DeviceCapabilities, DeviceError, DeviceReading};
use mmt::vec3::{self, Vec3};

/// `DHD_DEVICE_OMEGA3` … `DHD_DEVICE_OMEGA7_LEFT` (dhdc.h).
const OMEGA_FAMILY: std::ops::RangeInclusive<i32> = 33..=37;
/// The button that clutches: 0, the button on the omega's handle (the only one of an omega.3/6).
const CLUTCH_BUTTON: std::ffi::c_int = 0;
/// One watchdog unit of the DHD firmware.
pub const WATCHDOG_UNIT: Duration = Duration::from_micros(125);

/// Force Dimension settings.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OmegaConfig {
    /// SDK library to load; overrides [`sdk::ENV_VAR`]. Default: none (variable, then `libdhd.so`).
    pub library: Option<PathBuf>,
    /// Hardware watchdog: forces go off when no force command arrives within this time.
    /// 125 µs steps, from 125 µs to 31.875 ms. Default 20 ms (20 missed ticks at 1 kHz;
    /// CHAI3D uses the maximum).
    pub watchdog: Duration,
    /// Velocity guard threshold to set (SDK units), > 0. Default `None`: keep the factory value
    /// and refuse a device whose guard is off.
    pub velocity_threshold: Option<u32>,
}

impl Default for OmegaConfig {
    fn default() -> Self {
        Self {
            library: None,
            watchdog: Duration::from_millis(20),
            velocity_threshold: None,
        }
    }
}

/// The watchdog duration in 125 µs units, rounded to the nearest; 1..=255 or an error.
pub fn watchdog_units(watchdog: Duration) -> Result<u8, DeviceError> {
    let units = (watchdog.as_secs_f64() / WATCHDOG_UNIT.as_secs_f64()).round();
    if (1.0..=255.0).contains(&units) {
        // In 1..=255 after the check above.
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        Ok(units as u8)
    } else {
        Err(DeviceError::InvalidConfig {
            field: "omega watchdog",
            value: format!("{watchdog:?}"),
            expected: "125 µs to 31.875 ms (1 to 255 units of 125 µs)",
        })
    }
}

/// An opened Force Dimension device.
pub struct OmegaBackend {
    sdk: Dhd,
    id: c_char,
    capabilities: DeviceCapabilities,
    /// Forces switched on by the app (the last `dhdEnableForce` that succeeded).
    forces_on: bool,
}

impl OmegaBackend {
    /// Loads the SDK and opens the first device, with watchdog and velocity guard on and forces
    /// off. The library comes from `config.library`, else `MMT_FD_SDK_LIB`, else `libdhd.so`.
    pub fn open(config: &OmegaConfig) -> Result<Self, DeviceError> {
        Self::open_with_env(config, std::env::var_os(sdk::ENV_VAR))
    }

    /// [`Self::open`] with the environment variable's value passed in (for tests).
    pub fn open_with_env(config: &OmegaConfig, env: Option<OsString>) -> Result<Self, DeviceError> {
        let units = watchdog_units(config.watchdog)?;
        if config.velocity_threshold == Some(0) {
            return Err(DeviceError::InvalidConfig {
                field: "omega velocity_threshold",
                value: "0".into(),
                expected: "a threshold > 0 (0 would switch the velocity guard off)",
            });
        }
        let sdk = Dhd::load(config.library.as_deref(), env)?;
        if sdk.device_count()? == 0 {
            return Err(DeviceError::NotFound {
                backend: "Force Dimension",
                detail: format!(
                    "the SDK ({}) sees no device; is it powered and plugged in, and may this user \
                     use it (udev rule: SUBSYSTEM==\"usb\", ATTRS{{idVendor}}==\"1451\", MODE=\"0666\")?",
                    sdk.path()
                ),
            });
        }
        let id = sdk.open()?;
        // From here on, Drop closes the device whatever fails.
        let mut backend = Self {
            sdk,
            id,
            capabilities: DeviceCapabilities::omega7("Force Dimension device"),
            forces_on: false,
        };
        backend.configure(units, config.velocity_threshold)?;
        Ok(backend)
    }

    fn configure(&mut self, watchdog_units: u8, threshold: Option<u32>) -> Result<(), DeviceError> {
        let (sdk, id) = (&self.sdk, self.id);
        let kind = sdk.system_type(id)?;
        let name = sdk.system_name(id)?;
        if !OMEGA_FAMILY.contains(&kind) {
            return Err(DeviceError::InvalidConfig {
                field: "Force Dimension device type",
                value: format!("{name} (DHD type {kind})"),
                expected: "an omega.3, omega.6 or omega.7 (types 33–37); other models need their limits entered",
            });
        }
        sdk.enable_expert_mode()?;
        sdk.set_watchdog(id, watchdog_units)?;
        match threshold {
            Some(v) => sdk.set_velocity_threshold(id, v)?,
            None => {
                if sdk.velocity_threshold(id)? == 0 {
                    return Err(DeviceError::InvalidConfig {
                        field: "omega velocity guard",
                        value: "threshold 0 (guard off)".into(),
                        expected: "the factory threshold; set one explicitly with --fd-velocity-threshold",
                    });
                }
            }
        }
        sdk.set_force(id, vec3::ZERO)?;
        sdk.enable_force(id, false)?;
        self.capabilities = DeviceCapabilities::omega7(format!("{name} (SDK {})", sdk.path()));
        tracing::info!(device = %name, sdk = %sdk.path(), watchdog_units, "Force Dimension device open; forces off");
        Ok(())
    }
}

impl Backend for OmegaBackend {
    fn capabilities(&self) -> &DeviceCapabilities {
        &self.capabilities
    }

    fn read(&mut self, _now: Duration) -> Result<DeviceReading, DeviceError> {
        let status = self.sdk.status(self.id)?;
        if self.forces_on && !status.forces_on() {
            let cause = match status.force_off_cause() {
                sdk::ForceOffCause::None if status.brake() => sdk::ForceOffCause::Velocity,
                c => c,
            };
            return Err(DeviceError::ForcesOff {
                cause: cause.to_string(),
            });
        }
        Ok(DeviceReading {
            position_m: self.sdk.position(self.id)?,
            velocity_m_per_s: self.sdk.linear_velocity(self.id)?,
            clutch: self.sdk.button(self.id, CLUTCH_BUTTON)?,
        })
    }

    fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError> {
        self.sdk.set_force(self.id, force_n)
    }

    fn set_force_enabled(&mut self, on: bool) -> Result<(), DeviceError> {
        // Off counts as off even if the call failed (nothing is expected from the device then).
        if !on {
            self.forces_on = false;
        }
        self.sdk.enable_force(self.id, on)?;
        self.forces_on = on;
        Ok(())
    }
}

impl Drop for OmegaBackend {
    fn drop(&mut self) {
        // Best effort: zero, forces off, close. Errors cannot be returned from drop; log them.
        let steps = [
            self.sdk.set_force(self.id, vec3::ZERO),
            self.sdk.enable_force(self.id, false),
            self.sdk.close(self.id),
        ];
        for e in steps.into_iter().filter_map(Result::err) {
            tracing::warn!(error = %e, "closing the Force Dimension device");
        }
    }
}

/// What the SDK reports, for `operator devices`.
#[derive(Debug)]
pub struct SdkProbe {
    /// The library loaded, or why not.
    pub library: Result<String, DeviceError>,
    /// Devices seen: name, or the error opening it.
    pub devices: Vec<Result<String, DeviceError>>,
}

/// Loads the SDK and lists its devices (opening each briefly to read its name; forces are not
/// touched). Never fails: errors are part of the answer.
#[must_use]
pub fn probe(config: &OmegaConfig, env: Option<OsString>) -> SdkProbe {
    let sdk = match Dhd::load(config.library.as_deref(), env) {
        Ok(s) => s,
        Err(e) => {
            return SdkProbe {
                library: Err(e.into()),
                devices: Vec::new(),
            };
        }
    };
    let count = match sdk.device_count() {
        Ok(n) => n,
        Err(e) => {
            return SdkProbe {
                library: Ok(sdk.path().to_owned()),
                devices: vec![Err(e)],
            };
        }
    };
    let devices = (0..count)
        .map(|i| {
            let index = c_char::try_from(i).map_err(|_| DeviceError::Sdk {
                call: "dhdGetDeviceCount",
                code: count,
                message: "more devices than IDs".into(),
            })?;
            let id = sdk.open_id(index)?;
            let name = sdk.system_name(id);
            let closed = sdk.close(id);
            let name = name?;
            closed?;
            Ok(name)
        })
        .collect();
    SdkProbe {
        library: Ok(sdk.path().to_owned()),
        devices,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn watchdog_converts_to_125_us_units() {
        assert_eq!(watchdog_units(Duration::from_millis(20)).unwrap(), 160);
        assert_eq!(watchdog_units(Duration::from_micros(125)).unwrap(), 1);
        assert_eq!(watchdog_units(Duration::from_micros(31_875)).unwrap(), 255);
        for bad in [
            Duration::ZERO,
            Duration::from_millis(32),
            Duration::from_secs(1),
        ] {
            let e = watchdog_units(bad).unwrap_err().to_string();
            assert!(e.contains("31.875 ms"), "{e}");
        }
    }

    #[test]
    fn library_resolution_order() {
        use std::path::Path;
        let (lib, by) = sdk::resolve_library(Some(Path::new("/a/libdhd.so")), Some("/b".into()));
        assert_eq!(
            (lib.to_str(), by),
            (Some("/a/libdhd.so"), "the --fd-sdk-lib setting")
        );
        let (lib, by) = sdk::resolve_library(None, Some("/b/libdhd.so".into()));
        assert_eq!(lib.to_str(), Some("/b/libdhd.so"));
        assert!(by.contains("MMT_FD_SDK_LIB"));
        let (lib, by) = sdk::resolve_library(None, Some("".into()));
        assert_eq!((lib.to_str(), by), (Some("libdhd.so"), "default"));
    }
}
