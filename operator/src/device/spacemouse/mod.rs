//! The `spacemouse` backend: a 3Dconnexion SpaceMouse read over HID (`hidapi`, pure-Rust Linux
//! backend `linux-native-basic-udev`: no system C library) and turned into a bounded position.
//!
//! A SpaceMouse is a **velocity** input with **no force output**: its capabilities say
//! `outputs_force: false`, `max_force_n: 0`, and the app warns when it is used. Each tick the
//! pending reports are drained (non-blocking), the translation axes are scaled by 1/350 to
//! [−1, 1], passed through a dead band, multiplied by the maximum speed and integrated into a
//! position that is clamped to the configured workspace.
//!
//! Axis convention: the HID reports x to the right, y toward the user and z down (pressing the
//! cap); the device frame here is x right, y away from the user, z up, i.e. `[x, −y, −z]`.
//! Button 0 (the left button) is the **clutch** ([`DeviceReading::clutch`]): held, the tool stays
//! where it is while the position integrates on (the safety layer's clutch, translation only).
//! Rotation and the other buttons are decoded and kept ([`SpaceMouseBackend::rotation`],
//! [`SpaceMouseBackend::buttons`]) but drive nothing yet.
//!
//! Not here: report decoding ([`report`], pure), force rendering (there is none).

pub mod report;

use std::time::Duration;

use serde::Serialize;

use self::report::{Report, known_device, normalise, parse_report};
use super::{Backend, DeviceCapabilities, DeviceError, DeviceReading, Workspace};
use mmt::vec3::{self, Vec3};

/// SpaceMouse settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpaceMouseConfig {
    /// Speed at full deflection [m/s]. Default 0.1 m/s: crossing the 0.15 m workspace takes
    /// 1.5 s, slow enough to place the tool, fast enough not to bore.
    pub max_speed_m_per_s: f64,
    /// Dead band as a fraction of full scale, in [0, 1). Default 0.05: the cap rests a few counts
    /// off zero, which would otherwise drift the position.
    pub deadband: f64,
    /// Where the integrated position may go [m]. Default: the omega.7's sphere of 0.075 m, so
    /// scenes made for the omega fit.
    pub workspace: Workspace,
    /// Largest time step integrated at once. Default 20 ms: a stalled loop does not jump.
    pub max_step: Duration,
}

impl Default for SpaceMouseConfig {
    fn default() -> Self {
        Self {
            max_speed_m_per_s: 0.1,
            deadband: 0.05,
            workspace: Workspace::Sphere {
                center_m: vec3::ZERO,
                radius_m: 0.075,
            },
            max_step: Duration::from_millis(20),
        }
    }
}

impl SpaceMouseConfig {
    /// Checks the settings.
    pub fn validate(&self) -> Result<(), DeviceError> {
        if !(self.max_speed_m_per_s.is_finite() && self.max_speed_m_per_s > 0.0) {
            return Err(DeviceError::InvalidConfig {
                field: "spacemouse max_speed_m_per_s",
                value: self.max_speed_m_per_s.to_string(),
                expected: "a finite speed > 0 m/s",
            });
        }
        if !(0.0..1.0).contains(&self.deadband) {
            return Err(DeviceError::InvalidConfig {
                field: "spacemouse deadband",
                value: self.deadband.to_string(),
                expected: "a fraction in [0, 1)",
            });
        }
        Ok(())
    }
}

/// Where reports come from: the HID device, or recorded bytes in tests.
pub trait ReportSource: Send {
    /// Reads one pending report into `buf` without blocking; `Ok(0)` when none is pending.
    fn read_report(&mut self, buf: &mut [u8]) -> Result<usize, DeviceError>;
}

/// A SpaceMouse opened through hidapi.
pub struct HidReportSource {
    device: hidapi::HidDevice,
}

impl ReportSource for HidReportSource {
    fn read_report(&mut self, buf: &mut [u8]) -> Result<usize, DeviceError> {
        self.device
            .read_timeout(buf, 0)
            .map_err(|error| DeviceError::Hid {
                what: "reading a SpaceMouse report".into(),
                error,
            })
    }
}

/// Counters of the report stream (for diagnostics and reports).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ReportStats {
    /// Reports decoded.
    pub reports: u64,
    /// Reports refused by the parser.
    pub parse_errors: u64,
}

/// The clutch: button 0 of the button bitmap.
const CLUTCH_BUTTON_MASK: u32 = 1;

/// Reports drained per tick at most (a SpaceMouse sends ~60–120 per second).
const MAX_REPORTS_PER_TICK: usize = 32;

/// The SpaceMouse backend over any [`ReportSource`].
pub struct SpaceMouseBackend<S: ReportSource = HidReportSource> {
    source: S,
    config: SpaceMouseConfig,
    capabilities: DeviceCapabilities,
    translation: Vec3,
    rotation: Vec3,
    buttons: u32,
    position: Vec3,
    last_now: Option<Duration>,
    stats: ReportStats,
    last_parse_failed: bool,
}

impl SpaceMouseBackend<HidReportSource> {
    /// Opens the first known SpaceMouse found over HID.
    pub fn open_hid(config: &SpaceMouseConfig) -> Result<Self, DeviceError> {
        let api = hid_api()?;
        // Among known ids, prefer the multi-axis interface (usage page 1, usage 8) when the
        // backend reports usages; receivers also expose keyboard-like interfaces.
        let info = api
            .device_list()
            .filter(|d| known_device(d.vendor_id(), d.product_id()).is_some())
            .max_by_key(|d| d.usage_page() == 1 && d.usage() == 8)
            .ok_or_else(|| DeviceError::NotFound {
                backend: "SpaceMouse",
                detail: format!(
                    "no HID device with a known 3Dconnexion vendor/product id (046d:c603…c62b, \
                     256f:c62e…c652) among {} HID devices; is it plugged in, and may this user \
                     read /dev/hidraw* (udev rule: KERNEL==\"hidraw*\", ATTRS{{idVendor}}==\"256f\", \
                     MODE=\"0666\")?",
                    api.device_list().count()
                ),
            })?;
        let model =
            known_device(info.vendor_id(), info.product_id()).map_or("SpaceMouse", |k| k.model);
        let name = format!(
            "{model} ({:04x}:{:04x}, {})",
            info.vendor_id(),
            info.product_id(),
            info.path().to_string_lossy()
        );
        let device = info.open_device(&api).map_err(|error| DeviceError::Hid {
            what: format!("opening {name}"),
            error,
        })?;
        Self::new(HidReportSource { device }, config, name)
    }
}

impl<S: ReportSource> SpaceMouseBackend<S> {
    /// A backend over `source`; the position starts at the workspace centre.
    pub fn new(source: S, config: &SpaceMouseConfig, name: String) -> Result<Self, DeviceError> {
        config.validate()?;
        let capabilities = DeviceCapabilities {
            name,
            outputs_force: false,
            max_force_n: 0.0,
            max_stiffness_n_per_m: 0.0,
            max_damping_n_s_per_m: 0.0,
            workspace: config.workspace,
        };
        Ok(Self {
            source,
            config: *config,
            capabilities,
            translation: vec3::ZERO,
            rotation: vec3::ZERO,
            buttons: 0,
            position: config.workspace.clamp(vec3::ZERO),
            last_now: None,
            stats: ReportStats::default(),
            last_parse_failed: false,
        })
    }

    /// Latest rotation axes, normalised to [−1, 1] (HID directions).
    #[must_use]
    pub fn rotation(&self) -> Vec3 {
        self.rotation
    }

    /// Latest button bitmap.
    #[must_use]
    pub fn buttons(&self) -> u32 {
        self.buttons
    }

    /// Report counters.
    #[must_use]
    pub fn stats(&self) -> ReportStats {
        self.stats
    }

    fn apply(&mut self, report: Report) {
        let norm3 = |a: [i16; 3]| a.map(normalise);
        match report {
            Report::Translation(t) => self.translation = norm3(t),
            Report::Rotation(r) => self.rotation = norm3(r),
            Report::SixAxis {
                translation,
                rotation,
            } => {
                self.translation = norm3(translation);
                self.rotation = norm3(rotation);
            }
            Report::Buttons(b) => self.buttons = b,
        }
    }

    fn drain(&mut self) -> Result<(), DeviceError> {
        let mut buf = [0u8; 64];
        for _ in 0..MAX_REPORTS_PER_TICK {
            let n = self.source.read_report(&mut buf)?;
            if n == 0 {
                break;
            }
            match parse_report(buf.get(..n).unwrap_or(&buf)) {
                Ok(r) => {
                    self.stats.reports += 1;
                    self.last_parse_failed = false;
                    self.apply(r);
                }
                Err(e) => {
                    self.stats.parse_errors += 1;
                    if !self.last_parse_failed {
                        tracing::warn!(error = %e, "SpaceMouse report ignored");
                    }
                    self.last_parse_failed = true;
                }
            }
        }
        Ok(())
    }

    /// Commanded velocity in the device frame [m/s], dead band applied.
    fn velocity_command(&self) -> Vec3 {
        let db = self.config.deadband;
        let shape = |a: f64| {
            if a.abs() <= db {
                0.0
            } else {
                a.signum() * (a.abs() - db) / (1.0 - db)
            }
        };
        let t = self.translation;
        vec3::scale(
            [shape(t[0]), shape(-t[1]), shape(-t[2])],
            self.config.max_speed_m_per_s,
        )
    }
}

impl<S: ReportSource> Backend for SpaceMouseBackend<S> {
    fn capabilities(&self) -> &DeviceCapabilities {
        &self.capabilities
    }

    fn read(&mut self, now: Duration) -> Result<DeviceReading, DeviceError> {
        self.drain()?;
        let dt = self
            .last_now
            .map_or(Duration::ZERO, |prev| now.saturating_sub(prev))
            .min(self.config.max_step)
            .as_secs_f64();
        self.last_now = Some(now);
        let previous = self.position;
        let moved = vec3::add(previous, vec3::scale(self.velocity_command(), dt));
        self.position = self.config.workspace.clamp(moved);
        let velocity = if dt > 0.0 {
            vec3::scale(vec3::sub(self.position, previous), 1.0 / dt)
        } else {
            vec3::ZERO
        };
        Ok(DeviceReading {
            position_m: self.position,
            velocity_m_per_s: velocity,
            clutch: self.buttons & CLUTCH_BUTTON_MASK != 0,
        })
    }

    fn write_force(&mut self, _force_n: Vec3) -> Result<(), DeviceError> {
        Ok(())
    }

    fn set_force_enabled(&mut self, _on: bool) -> Result<(), DeviceError> {
        Ok(())
    }
}

/// A recognised SpaceMouse seen on the HID bus (for `operator devices`).
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct HidEntry {
    /// USB vendor id.
    pub vendor_id: u16,
    /// USB product id.
    pub product_id: u16,
    /// Model from the known-id table.
    pub model: &'static str,
    /// Product string the device reports, if any.
    pub product: Option<String>,
    /// hidraw path.
    pub path: String,
}

/// Lists the recognised SpaceMice, and how many HID devices there are in all.
pub fn list_hid() -> Result<(Vec<HidEntry>, usize), DeviceError> {
    let api = hid_api()?;
    let entries = api
        .device_list()
        .filter_map(|d| {
            known_device(d.vendor_id(), d.product_id()).map(|k| HidEntry {
                vendor_id: d.vendor_id(),
                product_id: d.product_id(),
                model: k.model,
                product: d.product_string().map(str::to_owned),
                path: d.path().to_string_lossy().into_owned(),
            })
        })
        .collect();
    Ok((entries, api.device_list().count()))
}

/// The HID API with the device list enumerated.
fn hid_api() -> Result<hidapi::HidApi, DeviceError> {
    hidapi::HidApi::new().map_err(|error| DeviceError::Hid {
        what: "enumerating HID devices".into(),
        error,
    })
}

#[cfg(test)]
mod tests;
