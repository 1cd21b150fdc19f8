//! The Force Dimension DHD SDK, opened at run time with `libloading` (no link-time dependency, so
//! the app builds and tests without the SDK), and a safe wrapper over the calls the omega backend
//! needs.
//!
//! Which file: the `library` setting (`--fd-sdk-lib`) if given, else the environment variable
//! [`ENV_VAR`] (`MMT_FD_SDK_LIB`) if set, else [`DEFAULT_LIBRARY`] (`libdhd.so`) found through
//! the dynamic loader's search path: `LD_LIBRARY_PATH`, the `ld.so` cache (`/etc/ld.so.conf`,
//! `ldconfig`), then `/lib` and `/usr/lib`. The SDK tarball's `lib/release/lin-*/` holds
//! `libdhd.so.*`; point the variable at it or copy it into a searched directory.
//!
//! **Every symbol in [`REQUIRED_SYMBOLS`] is looked up at load time**; a missing one refuses the
//! library with an error naming all missing symbols (no half-working device).
//!
//! C signatures (`dhdc.h`, SDK 3.17.5; plain C ABI on Linux, `__stdcall` only on Windows): `int`
//! results are ≥ 0 on success and −1 on error (`dhdErrorGetLastStr()` says why); getters return
//! doubles through out-pointers; `char ID` selects the device (−1 = default device).

#![allow(unsafe_code)]

use std::ffi::{CStr, OsStr, OsString, c_char, c_int, c_uchar, c_uint};
use std::path::Path;

use libloading::Library;

use crate::device::DeviceError;

/// Environment variable that overrides the library path.
pub const ENV_VAR: &str = "MMT_FD_SDK_LIB";
/// Library name used when neither the setting nor [`ENV_VAR`] gives one.
pub const DEFAULT_LIBRARY: &str = "libdhd.so";
/// Where [`DEFAULT_LIBRARY`] is searched, in words (for errors and listings).
pub const SEARCH_PATH: &str =
    "the dynamic loader's search path (LD_LIBRARY_PATH, the ld.so cache, /lib, /usr/lib)";

/// The C functions looked up at load time.
pub const REQUIRED_SYMBOLS: &[&str] = &[
    "dhdGetDeviceCount",
    "dhdOpen",
    "dhdOpenID",
    "dhdClose",
    "dhdGetSystemType",
    "dhdGetSystemName",
    "dhdGetPosition",
    "dhdGetLinearVelocity",
    "dhdSetForce",
    "dhdEnableForce",
    "dhdEnableExpertMode",
    "dhdSetWatchdog",
    "dhdGetVelocityThreshold",
    "dhdSetVelocityThreshold",
    "dhdGetStatus",
    "dhdGetButton",
    "dhdErrorGetLastStr",
];

/// Length of the buffer handed to `dhdGetStatus`. The SDK writes `DHD_MAX_STATUS` ints: 16 in
/// `dhdc.h` 3.17.5, more in later releases (17 and up). The buffer is twice the documented size,
/// so a newer SDK that writes a longer array cannot write past it.
pub const STATUS_BUFFER_LEN: usize = 32;

/// `DHD_STATUS_*` indices into the status array (`dhdc.h` 3.17.5) that the backend reads.
mod status_index {
    pub const FORCE: usize = 5;
    pub const BRAKE: usize = 6;
    pub const FORCEOFFCAUSE: usize = 14;
}

/// `dhdGetStatus`'s answer: the device's status flags.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Status(pub [c_int; STATUS_BUFFER_LEN]);

impl Status {
    fn flag(&self, i: usize) -> bool {
        self.0.get(i).is_some_and(|v| *v != 0)
    }

    /// `DHD_STATUS_FORCE`: forces are on.
    #[must_use]
    pub fn forces_on(&self) -> bool {
        self.flag(status_index::FORCE)
    }

    /// `DHD_STATUS_BRAKE`: the electromagnetic brakes are on (the velocity guard brakes).
    #[must_use]
    pub fn brake(&self) -> bool {
        self.flag(status_index::BRAKE)
    }

    /// `DHD_STATUS_FORCEOFFCAUSE`: why forces were last switched off.
    #[must_use]
    pub fn force_off_cause(&self) -> ForceOffCause {
        ForceOffCause::from_code(
            self.0
                .get(status_index::FORCEOFFCAUSE)
                .copied()
                .unwrap_or(0),
        )
    }
}

/// `DHD_FORCEOFF_*` (`dhdc.h` 3.17.5): why the device switched its forces off.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ForceOffCause {
    /// `DHD_FORCEOFF_NONE` (0).
    None,
    /// `DHD_FORCEOFF_BUTTON` (1): the force button.
    Button,
    /// `DHD_FORCEOFF_VELOCITY` (2): the velocity guard.
    Velocity,
    /// `DHD_FORCEOFF_WATCHDOG` (3): the firmware watchdog.
    Watchdog,
    /// `DHD_FORCEOFF_SOFTWARE` (4): a software request.
    Software,
    /// `DHD_FORCEOFF_USBDISCN` (5): USB disconnection.
    UsbDisconnect,
    /// `DHD_FORCEOFF_DEADMAN` (6): the dead-man switch.
    DeadMan,
    /// A code this wrapper does not know.
    Other(c_int),
}

impl ForceOffCause {
    /// The cause for a `DHD_FORCEOFF_*` code.
    #[must_use]
    pub fn from_code(code: c_int) -> Self {
        match code {
            0 => Self::None,
            1 => Self::Button,
            2 => Self::Velocity,
            3 => Self::Watchdog,
            4 => Self::Software,
            5 => Self::UsbDisconnect,
            6 => Self::DeadMan,
            c => Self::Other(c),
        }
    }
}

impl std::fmt::Display for ForceOffCause {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::None => write!(f, "no cause reported"),
            Self::Button => write!(f, "the force button"),
            Self::Velocity => write!(
                f,
                "the SDK's velocity guard (the handle moved faster than the velocity threshold; brakes on)"
            ),
            Self::Watchdog => write!(
                f,
                "the SDK's watchdog (no force command within the watchdog time)"
            ),
            Self::Software => write!(f, "a software request"),
            Self::UsbDisconnect => write!(f, "USB disconnection"),
            Self::DeadMan => write!(f, "the dead-man switch"),
            Self::Other(c) => write!(f, "DHD_FORCEOFF cause {c}"),
        }
    }
}

/// Why the SDK could not be used.
#[derive(Debug, thiserror::Error)]
pub enum SdkLoadError {
    /// The file could not be loaded.
    #[error(
        "cannot load the Force Dimension SDK library '{library}' (chosen by {chosen_by}; searched {searched}): {reason}. Install the SDK, or set {ENV_VAR}=/path/to/libdhd.so (or pass --fd-sdk-lib)"
    )]
    Library {
        /// The file or name given to the loader.
        library: String,
        /// Which setting chose it.
        chosen_by: &'static str,
        /// Where it was looked for.
        searched: String,
        /// The loader's message.
        reason: String,
    },
    /// The file loaded but lacks symbols.
    #[error(
        "the Force Dimension SDK library '{library}' (chosen by {chosen_by}) lacks {missing}: not a DHD SDK, or one without the expert API. Set {ENV_VAR}=/path/to/libdhd.so (or pass --fd-sdk-lib) to use another file"
    )]
    MissingSymbols {
        /// The file or name given to the loader.
        library: String,
        /// Which setting chose it.
        chosen_by: &'static str,
        /// Comma-separated missing symbols.
        missing: String,
    },
}

/// Chooses the library: explicit setting, else the environment variable's value, else the
/// default name. Returns the name and which of the three chose it.
#[must_use]
pub fn resolve_library(explicit: Option<&Path>, env: Option<OsString>) -> (OsString, &'static str) {
    match (explicit, env) {
        (Some(p), _) => (p.as_os_str().to_owned(), "the --fd-sdk-lib setting"),
        (None, Some(e)) if !e.is_empty() => (e, "the MMT_FD_SDK_LIB environment variable"),
        _ => (OsString::from(DEFAULT_LIBRARY), "default"),
    }
}

type GetXyz = unsafe extern "C" fn(*mut f64, *mut f64, *mut f64, c_char) -> c_int;

/// The loaded SDK: the library and one checked function pointer per required symbol.
pub struct Dhd {
    get_device_count: unsafe extern "C" fn() -> c_int,
    open: unsafe extern "C" fn() -> c_int,
    open_id: unsafe extern "C" fn(c_char) -> c_int,
    close: unsafe extern "C" fn(c_char) -> c_int,
    get_system_type: unsafe extern "C" fn(c_char) -> c_int,
    get_system_name: unsafe extern "C" fn(c_char) -> *const c_char,
    get_position: GetXyz,
    get_linear_velocity: GetXyz,
    set_force: unsafe extern "C" fn(f64, f64, f64, c_char) -> c_int,
    enable_force: unsafe extern "C" fn(c_uchar, c_char) -> c_int,
    enable_expert_mode: unsafe extern "C" fn() -> c_int,
    set_watchdog: unsafe extern "C" fn(c_uchar, c_char) -> c_int,
    get_velocity_threshold: unsafe extern "C" fn(*mut c_uint, c_char) -> c_int,
    set_velocity_threshold: unsafe extern "C" fn(c_uint, c_char) -> c_int,
    get_status: unsafe extern "C" fn(*mut c_int, c_char) -> c_int,
    get_button: unsafe extern "C" fn(c_int, c_char) -> c_int,
    error_get_last_str: unsafe extern "C" fn() -> *const c_char,
    /// Keeps the code behind the pointers mapped; never used after the pointers.
    _library: Library,
    path: String,
}

/// Looks `name` up; on failure records it in `missing`.
///
/// # Safety
/// `T` must be the function-pointer type of `name`'s C declaration in `dhdc.h`.
unsafe fn symbol<T: Copy>(
    lib: &Library,
    name: &'static str,
    missing: &mut Vec<&'static str>,
) -> Option<T> {
    // SAFETY: the caller guarantees `T` matches the C declaration; the returned pointer is stored
    // next to `lib` in `Dhd`, which keeps the library loaded for as long as the pointer lives.
    match unsafe { lib.get::<T>(name) } {
        Ok(s) => Some(*s),
        Err(_) => {
            missing.push(name);
            None
        }
    }
}

/// An error's message followed by its source's (libloading puts `dlerror()` in the source).
fn with_source(e: &dyn std::error::Error) -> String {
    match e.source() {
        Some(s) => format!("{e}: {s}"),
        None => e.to_string(),
    }
}

/// Opens `library` (shown as `shown`, chosen by `chosen_by`) with the dynamic loader.
fn open_library(
    library: &OsStr,
    shown: &str,
    chosen_by: &'static str,
) -> Result<Library, SdkLoadError> {
    // dlopen takes a name containing '/' as a path and searches nothing else.
    let searched = if shown.contains('/') {
        "that path only".to_owned()
    } else {
        SEARCH_PATH.to_owned()
    };
    // SAFETY: loading runs the library's initialisers. The file is the vendor SDK (or its test
    // double) chosen by the operator; its initialisers are trusted like the SDK itself.
    unsafe { Library::new(library) }.map_err(|e| SdkLoadError::Library {
        library: shown.to_owned(),
        chosen_by,
        searched,
        reason: with_source(&e),
    })
}

impl Dhd {
    /// Loads the SDK (see the module docs for which file) and checks every required symbol.
    pub fn load(explicit: Option<&Path>, env: Option<OsString>) -> Result<Self, SdkLoadError> {
        let (library, chosen_by) = resolve_library(explicit, env);
        let shown = library.to_string_lossy().into_owned();
        let lib = open_library(&library, &shown, chosen_by)?;
        Self::look_up(lib, shown.clone()).map_err(|missing| SdkLoadError::MissingSymbols {
            library: shown,
            chosen_by,
            missing: format!(
                "symbol{} {}",
                if missing.len() == 1 { "" } else { "s" },
                missing.join(", ")
            ),
        })
    }

    /// Looks every required symbol up in `lib` (loaded from `path`); the names of those missing
    /// if any is.
    fn look_up(lib: Library, path: String) -> Result<Self, Vec<&'static str>> {
        let mut missing = Vec::new();
        let m = &mut missing;
        // SAFETY (all lookups below): each type is transcribed from the declaration of the same
        // name in dhdc.h 3.17.5 (`char ID` → c_char, `uchar` → c_uchar, `uint` → c_uint).
        let loaded = unsafe {
            (
                symbol(&lib, "dhdGetDeviceCount", m),
                symbol(&lib, "dhdOpen", m),
                symbol(&lib, "dhdOpenID", m),
                symbol(&lib, "dhdClose", m),
                symbol(&lib, "dhdGetSystemType", m),
                symbol(&lib, "dhdGetSystemName", m),
                symbol(&lib, "dhdGetPosition", m),
                symbol(&lib, "dhdGetLinearVelocity", m),
                symbol(&lib, "dhdSetForce", m),
                symbol(&lib, "dhdEnableForce", m),
                symbol(&lib, "dhdEnableExpertMode", m),
                symbol(&lib, "dhdSetWatchdog", m),
                symbol(&lib, "dhdGetVelocityThreshold", m),
                symbol(&lib, "dhdSetVelocityThreshold", m),
                symbol(&lib, "dhdGetStatus", m),
                symbol(&lib, "dhdGetButton", m),
                symbol(&lib, "dhdErrorGetLastStr", m),
            )
        };
        match loaded {
            (
                Some(get_device_count),
                Some(open),
                Some(open_id),
                Some(close),
                Some(get_system_type),
                Some(get_system_name),
                Some(get_position),
                Some(get_linear_velocity),
                Some(set_force),
                Some(enable_force),
                Some(enable_expert_mode),
                Some(set_watchdog),
                Some(get_velocity_threshold),
                Some(set_velocity_threshold),
                Some(get_status),
                Some(get_button),
                Some(error_get_last_str),
            ) => Ok(Self {
                get_device_count,
                open,
                open_id,
                close,
                get_system_type,
                get_system_name,
                get_position,
                get_linear_velocity,
                set_force,
                enable_force,
                enable_expert_mode,
                set_watchdog,
                get_velocity_threshold,
                set_velocity_threshold,
                get_status,
                get_button,
                error_get_last_str,
                _library: lib,
                path,
            }),
            _ => Err(missing),
        }
    }

    /// The file or name the SDK was loaded from.
    #[must_use]
    pub fn path(&self) -> &str {
        &self.path
    }

    /// `dhdErrorGetLastStr()`, or a placeholder when it returns null.
    #[must_use]
    pub fn last_error(&self) -> String {
        // SAFETY: no arguments; the SDK returns a pointer to a static, NUL-terminated string or null.
        let p = unsafe { (self.error_get_last_str)() };
        if p.is_null() {
            return "(no error text)".to_owned();
        }
        // SAFETY: non-null, NUL-terminated, static per the SDK documentation; copied at once.
        unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
    }

    /// Maps a C `int` result: negative → [`DeviceError::Sdk`] with the SDK's message.
    fn check(&self, call: &'static str, code: c_int) -> Result<c_int, DeviceError> {
        if code < 0 {
            Err(DeviceError::Sdk {
                call,
                code,
                message: self.last_error(),
            })
        } else {
            Ok(code)
        }
    }

    /// `dhdGetDeviceCount()`: number of Force Dimension devices connected.
    pub fn device_count(&self) -> Result<c_int, DeviceError> {
        // SAFETY: no arguments.
        let r = unsafe { (self.get_device_count)() };
        self.check("dhdGetDeviceCount", r)
    }

    /// `dhdOpen()`: opens the first available device; returns its ID.
    pub fn open(&self) -> Result<c_char, DeviceError> {
        // SAFETY: no arguments.
        let r = unsafe { (self.open)() };
        self.id("dhdOpen", r)
    }

    /// `dhdOpenID(index)`: opens device `index` (0-based); returns its ID.
    pub fn open_id(&self, index: c_char) -> Result<c_char, DeviceError> {
        // SAFETY: plain value argument.
        let r = unsafe { (self.open_id)(index) };
        self.id("dhdOpenID", r)
    }

    fn id(&self, call: &'static str, r: c_int) -> Result<c_char, DeviceError> {
        let r = self.check(call, r)?;
        c_char::try_from(r).map_err(|_| DeviceError::Sdk {
            call,
            code: r,
            message: "device ID out of the char range".into(),
        })
    }

    /// `dhdClose(id)`.
    pub fn close(&self, id: c_char) -> Result<(), DeviceError> {
        // SAFETY: plain value argument.
        let r = unsafe { (self.close)(id) };
        self.check("dhdClose", r).map(drop)
    }

    /// `dhdGetSystemType(id)`: the `DHD_DEVICE_*` constant.
    pub fn system_type(&self, id: c_char) -> Result<c_int, DeviceError> {
        // SAFETY: plain value argument.
        let r = unsafe { (self.get_system_type)(id) };
        self.check("dhdGetSystemType", r)
    }

    /// `dhdGetSystemName(id)`, e.g. "omega.7".
    pub fn system_name(&self, id: c_char) -> Result<String, DeviceError> {
        // SAFETY: plain value argument; returns a static string or null.
        let p = unsafe { (self.get_system_name)(id) };
        if p.is_null() {
            return Err(DeviceError::Sdk {
                call: "dhdGetSystemName",
                code: -1,
                message: self.last_error(),
            });
        }
        // SAFETY: non-null, NUL-terminated, static per the SDK documentation; copied at once.
        Ok(unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned())
    }

    fn xyz(&self, call: &'static str, f: GetXyz, id: c_char) -> Result<[f64; 3], DeviceError> {
        let mut v = [0.0f64; 3];
        let [x, y, z] = &mut v;
        // SAFETY: three valid, distinct, writable f64 locations that outlive the call.
        let r = unsafe { f(x, y, z, id) };
        self.check(call, r)?;
        Ok(v)
    }

    /// `dhdGetPosition(id)` [m]. `DHD_TIMEGUARD` (1) counts as success.
    pub fn position(&self, id: c_char) -> Result<[f64; 3], DeviceError> {
        self.xyz("dhdGetPosition", self.get_position, id)
    }

    /// `dhdGetLinearVelocity(id)` [m/s] (the SDK's windowed estimate, 20 ms by default).
    pub fn linear_velocity(&self, id: c_char) -> Result<[f64; 3], DeviceError> {
        self.xyz("dhdGetLinearVelocity", self.get_linear_velocity, id)
    }

    /// `dhdSetForce(fx, fy, fz, id)` [N]. `DHD_MOTOR_SATURATED` (2) counts as success.
    pub fn set_force(&self, id: c_char, f: [f64; 3]) -> Result<(), DeviceError> {
        // SAFETY: plain value arguments.
        let r = unsafe { (self.set_force)(f[0], f[1], f[2], id) };
        self.check("dhdSetForce", r).map(drop)
    }

    /// `dhdEnableForce(on, id)`.
    pub fn enable_force(&self, id: c_char, on: bool) -> Result<(), DeviceError> {
        // SAFETY: plain value arguments.
        let r = unsafe { (self.enable_force)(c_uchar::from(on), id) };
        self.check("dhdEnableForce", r).map(drop)
    }

    /// `dhdEnableExpertMode()`: needed for the watchdog and velocity-threshold calls.
    pub fn enable_expert_mode(&self) -> Result<(), DeviceError> {
        // SAFETY: no arguments.
        let r = unsafe { (self.enable_expert_mode)() };
        self.check("dhdEnableExpertMode", r).map(drop)
    }

    /// `dhdSetWatchdog(units, id)`: firmware switches forces off when no force command arrives
    /// within `units` × 125 µs (0 disables it; this wrapper's callers never pass 0).
    pub fn set_watchdog(&self, id: c_char, units: u8) -> Result<(), DeviceError> {
        // SAFETY: plain value arguments.
        let r = unsafe { (self.set_watchdog)(units, id) };
        self.check("dhdSetWatchdog", r).map(drop)
    }

    /// `dhdGetVelocityThreshold(&val, id)`: the velocity guard (0 = off).
    pub fn velocity_threshold(&self, id: c_char) -> Result<u32, DeviceError> {
        let mut v: c_uint = 0;
        // SAFETY: one valid, writable c_uint that outlives the call.
        let r = unsafe { (self.get_velocity_threshold)(&mut v, id) };
        self.check("dhdGetVelocityThreshold", r)?;
        Ok(v)
    }

    /// `dhdGetStatus(status, id)`: the device's status flags.
    pub fn status(&self, id: c_char) -> Result<Status, DeviceError> {
        let mut s = [0 as c_int; STATUS_BUFFER_LEN];
        // SAFETY: the SDK writes DHD_MAX_STATUS (16 in 3.17.5) ints; the buffer holds
        // STATUS_BUFFER_LEN = 32, writable and alive for the call.
        let r = unsafe { (self.get_status)(s.as_mut_ptr(), id) };
        self.check("dhdGetStatus", r)?;
        Ok(Status(s))
    }

    /// `dhdGetButton(index, id)`: whether button `index` is pressed (`DHD_ON`).
    pub fn button(&self, id: c_char, index: c_int) -> Result<bool, DeviceError> {
        // SAFETY: plain value arguments.
        let r = unsafe { (self.get_button)(index, id) };
        Ok(self.check("dhdGetButton", r)? != 0)
    }

    /// `dhdSetVelocityThreshold(val, id)`: above it the device brakes.
    pub fn set_velocity_threshold(&self, id: c_char, v: u32) -> Result<(), DeviceError> {
        // SAFETY: plain value arguments.
        let r = unsafe { (self.set_velocity_threshold)(v, id) };
        self.check("dhdSetVelocityThreshold", r).map(drop)
    }
}
