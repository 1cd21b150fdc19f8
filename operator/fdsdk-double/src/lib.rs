//! Test double of the Force Dimension DHD SDK: a shared library exporting the C symbols the
//! operator's omega backend loads (same names, same C signatures as `dhdc.h` 3.17.5), simulating
//! one or more devices and **recording every call** so tests can check loading, symbol checks,
//! call order and the forces written — for real, through `libloading`.
//!
//! How it is built and found: `operator/build.rs` compiles this file with the same `rustc` cargo
//! uses (`--crate-type cdylib`, no dependencies) into the operator's `OUT_DIR`, twice:
//! `libdhd_double.so` (complete) and `libdhd_double_no_watchdog.so` (built with
//! `--cfg fdsdk_double_omit_watchdog`, so `dhdSetWatchdog` is missing). The paths reach the tests
//! as the compile-time variables `FDSDK_DOUBLE` and `FDSDK_DOUBLE_NO_WATCHDOG`. It is also a
//! workspace member so fmt and clippy cover it.
//!
//! Control (test-only symbols, prefixed `fdsdk_double_`): [`fdsdk_double_reset`],
//! [`fdsdk_double_set_position`], [`fdsdk_double_set_velocity_threshold`],
//! [`fdsdk_double_force_off`] (the device cuts its forces: watchdog, velocity guard, …),
//! [`fdsdk_double_set_button`],
//! [`fdsdk_double_fail`], [`fdsdk_double_log`]. The state is global to the loaded library; tests
//! that share one copy must serialise.
//!
//! Not a device simulator: position and velocity are whatever the test sets.

#![allow(unsafe_code)]

use std::ffi::{CStr, c_char, c_int, c_uchar, c_uint};
use std::sync::{Mutex, MutexGuard};

/// `DHD_DEVICE_OMEGA7_RIGHT`.
const OMEGA7_RIGHT: c_int = 35;
/// `DHD_MAX_STATUS` of `dhdc.h` 3.17.5: the ints `dhdGetStatus` writes.
const MAX_STATUS: usize = 16;
/// `DHD_FORCEOFF_VELOCITY`: the velocity guard, which also applies the brakes.
const FORCEOFF_VELOCITY: c_int = 2;

struct State {
    devices: c_int,
    open: Vec<c_char>,
    position: [f64; 3],
    velocity: [f64; 3],
    velocity_threshold: c_uint,
    /// Forces on (`dhdEnableForce`), and not cut since.
    forces_on: bool,
    brake: bool,
    force_off_cause: c_int,
    /// Button bitmap (bit i = button i pressed).
    buttons: u32,
    failing: Vec<String>,
    last_error: &'static CStr,
    log: Vec<String>,
}

static STATE: Mutex<State> = Mutex::new(State {
    devices: 1,
    open: Vec::new(),
    position: [0.0; 3],
    velocity: [0.0; 3],
    velocity_threshold: 40,
    forces_on: false,
    brake: false,
    force_off_cause: 0,
    buttons: 0,
    failing: Vec::new(),
    last_error: c"no error",
    log: Vec::new(),
});

fn state() -> MutexGuard<'static, State> {
    STATE
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

impl State {
    /// Logs `entry`; returns −1 (and sets the error) if `name` was told to fail.
    fn call(&mut self, name: &str, entry: String) -> c_int {
        self.log.push(entry);
        if self.failing.iter().any(|f| f == name) {
            self.last_error = c"injected failure";
            return -1;
        }
        0
    }

    /// Like [`State::call`], also checking that `id` is open.
    fn call_id(&mut self, name: &str, id: c_char, entry: String) -> c_int {
        let r = self.call(name, entry);
        if r == 0 && !self.open.contains(&id) {
            self.last_error = c"device not open";
            return -1;
        }
        r
    }
}

/// Writes `v` through three out-pointers.
///
/// # Safety
/// Each pointer must be null or valid for a write of one `f64`.
unsafe fn write3(p: [*mut f64; 3], v: [f64; 3]) {
    for (dst, x) in p.into_iter().zip(v) {
        if !dst.is_null() {
            // SAFETY: non-null and valid for writes per this function's contract.
            unsafe { *dst = x };
        }
    }
}

// ---- control symbols (tests only) ----

/// Clears the log, failures and open devices; sets the device count; restores defaults.
#[unsafe(no_mangle)]
pub extern "C" fn fdsdk_double_reset(devices: c_int) {
    let mut s = state();
    s.devices = devices;
    s.open.clear();
    s.position = [0.0; 3];
    s.velocity = [0.0; 3];
    s.velocity_threshold = 40;
    s.forces_on = false;
    s.brake = false;
    s.force_off_cause = 0;
    s.buttons = 0;
    s.failing.clear();
    s.last_error = c"no error";
    s.log.clear();
}

/// Sets what `dhdGetPosition` / `dhdGetLinearVelocity` return [m], [m/s].
#[unsafe(no_mangle)]
pub extern "C" fn fdsdk_double_set_position(x: f64, y: f64, z: f64, vx: f64, vy: f64, vz: f64) {
    let mut s = state();
    s.position = [x, y, z];
    s.velocity = [vx, vy, vz];
}

/// Sets the "factory" velocity threshold (0 = guard off).
#[unsafe(no_mangle)]
pub extern "C" fn fdsdk_double_set_velocity_threshold(v: c_uint) {
    state().velocity_threshold = v;
}

/// The device switches its forces off by itself with `DHD_FORCEOFF_*` cause `cause`
/// (3 = watchdog, 2 = velocity guard, which also sets the brake status), as the firmware does.
/// `dhdEnableForce(1)` clears it.
#[unsafe(no_mangle)]
pub extern "C" fn fdsdk_double_force_off(cause: c_int) {
    let mut s = state();
    s.forces_on = false;
    s.force_off_cause = cause;
    s.brake = cause == FORCEOFF_VELOCITY;
}

/// Presses (`pressed` ≠ 0) or releases button `index` (0 to 15).
#[unsafe(no_mangle)]
pub extern "C" fn fdsdk_double_set_button(index: c_int, pressed: c_int) {
    let Some(bit) = u32::try_from(index).ok().filter(|i| *i < 16) else {
        return;
    };
    let mut s = state();
    if pressed != 0 {
        s.buttons |= 1 << bit;
    } else {
        s.buttons &= !(1 << bit);
    }
}

/// Makes every later call of the SDK function `name` return −1.
///
/// # Safety
/// `name` must be a valid NUL-terminated string.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fdsdk_double_fail(name: *const c_char) {
    if name.is_null() {
        return;
    }
    // SAFETY: non-null and NUL-terminated per this function's contract.
    let name = unsafe { CStr::from_ptr(name) }
        .to_string_lossy()
        .into_owned();
    state().failing.push(name);
}

/// Copies the call log (one call per line) into `buf` (at most `cap` bytes, no NUL) and returns
/// its full length; call with `cap = 0` to size the buffer.
///
/// # Safety
/// `buf` must be valid for writes of `cap` bytes (or null with `cap = 0`).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn fdsdk_double_log(buf: *mut u8, cap: usize) -> usize {
    let text = state().log.join("\n");
    let n = text.len().min(cap);
    if n > 0 && !buf.is_null() {
        // SAFETY: `buf` holds `cap` ≥ n writable bytes per the contract; the regions are distinct.
        unsafe { std::ptr::copy_nonoverlapping(text.as_ptr(), buf, n) };
    }
    text.len()
}

// ---- the SDK symbols (dhdc.h 3.17.5 signatures) ----

/// `int dhdGetDeviceCount()`.
#[unsafe(no_mangle)]
pub extern "C" fn dhdGetDeviceCount() -> c_int {
    let mut s = state();
    let r = s.call("dhdGetDeviceCount", "dhdGetDeviceCount".into());
    if r < 0 { r } else { s.devices }
}

fn open_index(s: &mut State, name: &str, index: c_int) -> c_int {
    let r = s.call(name, format!("{name} {index}"));
    if r < 0 {
        return r;
    }
    match c_char::try_from(index) {
        Ok(id) if index < s.devices && !s.open.contains(&id) => {
            s.open.push(id);
            index
        }
        _ => {
            s.last_error = c"no device found";
            -1
        }
    }
}

/// `int dhdOpen()`: the first device not yet open.
#[unsafe(no_mangle)]
pub extern "C" fn dhdOpen() -> c_int {
    let mut s = state();
    let first_free = (0..s.devices)
        .find(|i| c_char::try_from(*i).is_ok_and(|id| !s.open.contains(&id)))
        .unwrap_or(s.devices);
    open_index(&mut s, "dhdOpen", first_free)
}

/// `int dhdOpenID(char ID)`.
#[unsafe(no_mangle)]
pub extern "C" fn dhdOpenID(id: c_char) -> c_int {
    open_index(&mut state(), "dhdOpenID", c_int::from(id))
}

/// `int dhdClose(char ID)`.
#[unsafe(no_mangle)]
pub extern "C" fn dhdClose(id: c_char) -> c_int {
    let mut s = state();
    let r = s.call_id("dhdClose", id, format!("dhdClose {id}"));
    s.open.retain(|o| *o != id);
    r
}

/// `int dhdGetSystemType(char ID)`.
#[unsafe(no_mangle)]
pub extern "C" fn dhdGetSystemType(id: c_char) -> c_int {
    let r = state().call_id("dhdGetSystemType", id, format!("dhdGetSystemType {id}"));
    if r < 0 { r } else { OMEGA7_RIGHT }
}

/// `const char* dhdGetSystemName(char ID)`.
#[unsafe(no_mangle)]
pub extern "C" fn dhdGetSystemName(id: c_char) -> *const c_char {
    let r = state().call_id("dhdGetSystemName", id, format!("dhdGetSystemName {id}"));
    if r < 0 {
        std::ptr::null()
    } else {
        c"omega.7 (SDK double)".as_ptr()
    }
}

/// Logs a getter call and writes the value `pick` selects through the out-pointers.
///
/// # Safety
/// Pointers null or valid for one `f64` write each.
unsafe fn get_xyz(
    name: &str,
    id: c_char,
    out: [*mut f64; 3],
    pick: fn(&State) -> [f64; 3],
) -> c_int {
    let mut s = state();
    let r = s.call_id(name, id, format!("{name} {id}"));
    if r == 0 {
        // SAFETY: per this function's contract.
        unsafe { write3(out, pick(&s)) };
    }
    r
}

/// `int dhdGetPosition(double *px, double *py, double *pz, char ID)`.
///
/// # Safety
/// Pointers null or valid for one `f64` write each.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn dhdGetPosition(
    px: *mut f64,
    py: *mut f64,
    pz: *mut f64,
    id: c_char,
) -> c_int {
    // SAFETY: the same contract.
    unsafe { get_xyz("dhdGetPosition", id, [px, py, pz], |s| s.position) }
}

/// `int dhdGetLinearVelocity(double *vx, double *vy, double *vz, char ID)`.
///
/// # Safety
/// Pointers null or valid for one `f64` write each.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn dhdGetLinearVelocity(
    vx: *mut f64,
    vy: *mut f64,
    vz: *mut f64,
    id: c_char,
) -> c_int {
    // SAFETY: the same contract.
    unsafe { get_xyz("dhdGetLinearVelocity", id, [vx, vy, vz], |s| s.velocity) }
}

/// `int dhdSetForce(double fx, double fy, double fz, char ID)`.
#[unsafe(no_mangle)]
pub extern "C" fn dhdSetForce(fx: f64, fy: f64, fz: f64, id: c_char) -> c_int {
    state().call_id("dhdSetForce", id, format!("dhdSetForce {fx} {fy} {fz}"))
}

/// `int dhdEnableForce(uchar val, char ID)`.
#[unsafe(no_mangle)]
pub extern "C" fn dhdEnableForce(val: c_uchar, id: c_char) -> c_int {
    let mut s = state();
    let r = s.call_id("dhdEnableForce", id, format!("dhdEnableForce {val}"));
    if r == 0 {
        s.forces_on = val != 0;
        if s.forces_on {
            s.brake = false;
            s.force_off_cause = 0;
        } else if s.force_off_cause == 0 {
            s.force_off_cause = 4; // DHD_FORCEOFF_SOFTWARE
        }
    }
    r
}

/// `int dhdGetButton(int index, char ID)`: `DHD_ON` (1) if pressed, `DHD_OFF` (0) if not, −1 for
/// an index outside 0 to 15 (`DHD_MAX_BUTTONS`).
#[unsafe(no_mangle)]
pub extern "C" fn dhdGetButton(index: c_int, id: c_char) -> c_int {
    let mut s = state();
    let r = s.call_id("dhdGetButton", id, format!("dhdGetButton {index}"));
    if r < 0 {
        return r;
    }
    match u32::try_from(index).ok().filter(|i| *i < 16) {
        Some(bit) => c_int::from(s.buttons & (1 << bit) != 0),
        None => {
            s.last_error = c"invalid button index";
            -1
        }
    }
}

/// `int dhdGetStatus(int status[DHD_MAX_STATUS], char ID)`: writes `DHD_MAX_STATUS` (16) ints:
/// power, connected, started (1), force, brake, force-off cause; the rest 0.
///
/// # Safety
/// `status` null or valid for 16 `c_int` writes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn dhdGetStatus(status: *mut c_int, id: c_char) -> c_int {
    let mut s = state();
    let r = s.call_id("dhdGetStatus", id, format!("dhdGetStatus {id}"));
    if r == 0 && !status.is_null() {
        let mut v = [0 as c_int; MAX_STATUS];
        v[0] = 1; // DHD_STATUS_POWER
        v[1] = 1; // DHD_STATUS_CONNECTED
        v[2] = 1; // DHD_STATUS_STARTED
        v[5] = c_int::from(s.forces_on); // DHD_STATUS_FORCE
        v[6] = c_int::from(s.brake); // DHD_STATUS_BRAKE
        v[14] = s.force_off_cause; // DHD_STATUS_FORCEOFFCAUSE
        // SAFETY: valid for MAX_STATUS writes per this function's contract; distinct regions.
        unsafe { std::ptr::copy_nonoverlapping(v.as_ptr(), status, MAX_STATUS) };
    }
    r
}

/// `int dhdEnableExpertMode()`.
#[unsafe(no_mangle)]
pub extern "C" fn dhdEnableExpertMode() -> c_int {
    state().call("dhdEnableExpertMode", "dhdEnableExpertMode".into())
}

/// `int dhdSetWatchdog(unsigned char val, char ID)`. Absent from the `no_watchdog` variant.
#[cfg(not(fdsdk_double_omit_watchdog))]
#[unsafe(no_mangle)]
pub extern "C" fn dhdSetWatchdog(val: c_uchar, id: c_char) -> c_int {
    state().call_id("dhdSetWatchdog", id, format!("dhdSetWatchdog {val}"))
}

/// `int dhdGetVelocityThreshold(uint *val, char ID)`.
///
/// # Safety
/// `val` null or valid for one `c_uint` write.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn dhdGetVelocityThreshold(val: *mut c_uint, id: c_char) -> c_int {
    let mut s = state();
    let r = s.call_id(
        "dhdGetVelocityThreshold",
        id,
        "dhdGetVelocityThreshold".into(),
    );
    if r == 0 && !val.is_null() {
        // SAFETY: non-null and valid for a write per this function's contract.
        unsafe { *val = s.velocity_threshold };
    }
    r
}

/// `int dhdSetVelocityThreshold(uint val, char ID)`.
#[unsafe(no_mangle)]
pub extern "C" fn dhdSetVelocityThreshold(val: c_uint, id: c_char) -> c_int {
    let mut s = state();
    let r = s.call_id(
        "dhdSetVelocityThreshold",
        id,
        format!("dhdSetVelocityThreshold {val}"),
    );
    if r == 0 {
        s.velocity_threshold = val;
    }
    r
}

/// `const char* dhdErrorGetLastStr()`.
#[unsafe(no_mangle)]
pub extern "C" fn dhdErrorGetLastStr() -> *const c_char {
    state().last_error.as_ptr()
}
