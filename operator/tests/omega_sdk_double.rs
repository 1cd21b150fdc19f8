//! The omega backend against the Force Dimension SDK test double (`fdsdk-double`), loaded for real
//! through `libloading`: loading, symbol checks, watchdog and velocity guard at open, enable /
//! disable order, force writes, faults, and the errors for a missing library or symbol.
//!
//! The double's state is global to the loaded library, so the tests here take a lock.
#![allow(unsafe_code, clippy::unwrap_used)]

use std::ffi::{CString, c_char, c_int, c_uint};
use std::path::PathBuf;
use std::sync::{Mutex, MutexGuard};
use std::time::Duration;

use operator::device::omega::{self, OmegaBackend, OmegaConfig};
use operator::device::{HapticDevice, ManagedConfig, ManagedDevice, OperatingState};

static LOCK: Mutex<()> = Mutex::new(());

fn double_path() -> PathBuf {
    let Some(path) = option_env!("FDSDK_DOUBLE") else {
        panic!("the SDK double was not built (see the build script's warning)")
    };
    PathBuf::from(path)
}

/// Test-side handle on the double's control symbols.
struct Double {
    lib: libloading::Library,
    _guard: MutexGuard<'static, ()>,
}

impl Double {
    fn new(devices: c_int) -> Self {
        let guard = LOCK
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        // SAFETY: the double is our own library; its initialisers do nothing.
        let lib = unsafe { libloading::Library::new(double_path()) }.unwrap();
        let d = Self { lib, _guard: guard };
        // SAFETY: signature as exported by fdsdk-double.
        unsafe {
            d.lib
                .get::<unsafe extern "C" fn(c_int)>("fdsdk_double_reset")
                .unwrap()(devices)
        };
        d
    }

    fn log(&self) -> Vec<String> {
        // SAFETY: signature as exported by fdsdk-double; the buffer is sized by the first call.
        unsafe {
            let f = self
                .lib
                .get::<unsafe extern "C" fn(*mut u8, usize) -> usize>("fdsdk_double_log")
                .unwrap();
            let n = f(std::ptr::null_mut(), 0);
            let mut buf = vec![0u8; n];
            f(buf.as_mut_ptr(), n);
            String::from_utf8(buf)
                .unwrap()
                .lines()
                .map(str::to_owned)
                .collect()
        }
    }

    fn fail(&self, name: &str) {
        let name = CString::new(name).unwrap();
        // SAFETY: signature as exported by fdsdk-double; `name` is NUL-terminated.
        unsafe {
            self.lib
                .get::<unsafe extern "C" fn(*const c_char)>("fdsdk_double_fail")
                .unwrap()(name.as_ptr());
        }
    }

    fn set_position(&self, p: [f64; 3], v: [f64; 3]) {
        // SAFETY: signature as exported by fdsdk-double.
        unsafe {
            self.lib
                .get::<unsafe extern "C" fn(f64, f64, f64, f64, f64, f64)>(
                    "fdsdk_double_set_position",
                )
                .unwrap()(p[0], p[1], p[2], v[0], v[1], v[2]);
        }
    }

    /// The device cuts its forces with `DHD_FORCEOFF_*` cause `cause`.
    fn force_off(&self, cause: c_int) {
        // SAFETY: signature as exported by fdsdk-double.
        unsafe {
            self.lib
                .get::<unsafe extern "C" fn(c_int)>("fdsdk_double_force_off")
                .unwrap()(cause);
        }
    }

    fn set_button(&self, index: c_int, pressed: bool) {
        // SAFETY: signature as exported by fdsdk-double.
        unsafe {
            self.lib
                .get::<unsafe extern "C" fn(c_int, c_int)>("fdsdk_double_set_button")
                .unwrap()(index, c_int::from(pressed));
        }
    }

    fn set_velocity_threshold(&self, v: c_uint) {
        // SAFETY: signature as exported by fdsdk-double.
        unsafe {
            self.lib
                .get::<unsafe extern "C" fn(c_uint)>("fdsdk_double_set_velocity_threshold")
                .unwrap()(v);
        }
    }
}

fn config() -> OmegaConfig {
    OmegaConfig {
        library: Some(double_path()),
        ..OmegaConfig::default()
    }
}

/// The error opening the omega backend with `library` (and the variable's value `env`).
fn open_error(library: Option<&str>, env: Option<&str>) -> Option<String> {
    let cfg = OmegaConfig {
        library: library.map(PathBuf::from),
        ..OmegaConfig::default()
    };
    OmegaBackend::open_with_env(&cfg, env.map(Into::into))
        .err()
        .map(|e| e.to_string())
}

/// The omega backend on the double, opened from the loader's path, under the default manager.
fn managed() -> ManagedDevice<OmegaBackend> {
    ManagedDevice::new(
        OmegaBackend::open_with_env(&config(), None).unwrap(),
        ManagedConfig::default(),
    )
    .unwrap()
}

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

const OPEN_SEQUENCE: [&str; 9] = [
    "dhdGetDeviceCount",
    "dhdOpen 0",
    "dhdGetSystemType 0",
    "dhdGetSystemName 0",
    "dhdEnableExpertMode",
    "dhdSetWatchdog 160",
    "dhdGetVelocityThreshold",
    "dhdSetForce 0 0 0",
    "dhdEnableForce 0",
];

#[test]
fn open_sets_watchdog_checks_velocity_guard_and_leaves_forces_off() {
    let d = Double::new(1);
    let backend = OmegaBackend::open_with_env(&config(), None).unwrap();
    assert_eq!(d.log(), OPEN_SEQUENCE);
    drop(backend);
    assert_eq!(
        d.log()[OPEN_SEQUENCE.len()..],
        ["dhdSetForce 0 0 0", "dhdEnableForce 0", "dhdClose 0"]
    );
}

#[test]
fn enable_disable_order_and_force_writes() {
    let d = Double::new(1);
    let backend = OmegaBackend::open_with_env(&config(), None).unwrap();
    let ramp = ManagedConfig {
        enable_ramp: ms(100),
        ..ManagedConfig::default()
    };
    let mut dev = ManagedDevice::new(backend, ramp).unwrap();
    assert!(dev.spec().outputs_force);
    assert!(dev.spec().name.contains("omega.7 (SDK double)"));
    let n = d.log().len();
    dev.enable(ms(0)).unwrap();
    dev.servo_cf(ms(50), [2.0, -4.0, 0.5]).unwrap(); // half-way up the 100 ms ramp
    dev.servo_cf(ms(100), [1.5, -2.0, 0.25]).unwrap();
    dev.disable(ms(101)).unwrap();
    assert_eq!(
        d.log()[n..],
        [
            "dhdSetForce 0 0 0",
            "dhdEnableForce 1",
            "dhdSetForce 0 0 0",
            "dhdSetForce 1 -2 0.25",
            "dhdSetForce 1.5 -2 0.25",
            "dhdSetForce 0 0 0",
            "dhdEnableForce 0",
        ]
    );
}

#[test]
fn reads_position_and_velocity() {
    let d = Double::new(1);
    d.set_position([0.01, -0.02, 0.03], [0.1, 0.0, -0.1]);
    let mut dev = managed();
    dev.update(ms(0)).unwrap();
    assert_eq!(dev.measured_cp(), [0.01, -0.02, 0.03]);
    assert_eq!(dev.measured_cv(), [0.1, 0.0, -0.1]);
    assert!(!dev.clutch());
    let log = d.log();
    assert_eq!(
        log[log.len() - 4..],
        [
            "dhdGetStatus 0",
            "dhdGetPosition 0",
            "dhdGetLinearVelocity 0",
            "dhdGetButton 0"
        ]
    );
}

#[test]
fn the_handle_button_is_the_clutch() {
    let d = Double::new(1);
    let mut dev = managed();
    d.set_button(1, true);
    dev.update(ms(0)).unwrap();
    assert!(!dev.clutch(), "another button is not the clutch");
    d.set_button(0, true);
    dev.update(ms(1)).unwrap();
    assert!(dev.clutch());
    d.set_button(0, false);
    dev.update(ms(2)).unwrap();
    assert!(!dev.clutch());
}

#[test]
fn sdk_error_faults_the_device_with_the_sdk_message() {
    let d = Double::new(1);
    let mut dev = managed();
    dev.enable(ms(0)).unwrap();
    d.fail("dhdGetPosition");
    let e = dev.update(ms(1)).unwrap_err().to_string();
    assert!(
        e.contains("dhdGetPosition failed") && e.contains("injected failure"),
        "{e}"
    );
    assert_eq!(dev.operating_state(), OperatingState::Faulted);
    assert_eq!(
        d.log()[d.log().len() - 2..],
        ["dhdSetForce 0 0 0", "dhdEnableForce 0"]
    );
}

#[test]
fn failed_configuration_closes_the_device() {
    let d = Double::new(1);
    d.fail("dhdSetWatchdog");
    let e = OmegaBackend::open_with_env(&config(), None)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("dhdSetWatchdog failed"), "{e}");
    assert_eq!(d.log().last().map(String::as_str), Some("dhdClose 0"));
}

#[test]
fn no_device_is_a_clear_error() {
    let _d = Double::new(0);
    let e = OmegaBackend::open_with_env(&config(), None)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("sees no device") && e.contains("1451"), "{e}");
}

#[test]
fn velocity_guard_off_is_refused_unless_set() {
    let d = Double::new(1);
    d.set_velocity_threshold(0);
    let e = OmegaBackend::open_with_env(&config(), None)
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("velocity guard") && e.contains("--fd-velocity-threshold"),
        "{e}"
    );
    let cfg = OmegaConfig {
        velocity_threshold: Some(30),
        ..config()
    };
    let _b = OmegaBackend::open_with_env(&cfg, None).unwrap();
    assert!(d.log().contains(&"dhdSetVelocityThreshold 30".to_owned()));
}

#[test]
fn probe_lists_devices_by_name() {
    let d = Double::new(2);
    let p = omega::probe(&config(), None);
    assert_eq!(p.library.unwrap(), double_path().display().to_string());
    let names: Vec<_> = p.devices.into_iter().map(Result::unwrap).collect();
    assert_eq!(names, ["omega.7 (SDK double)", "omega.7 (SDK double)"]);
    assert_eq!(
        d.log()[1..],
        [
            "dhdOpenID 0",
            "dhdGetSystemName 0",
            "dhdClose 0",
            "dhdOpenID 1",
            "dhdGetSystemName 1",
            "dhdClose 1",
        ]
    );
}

#[test]
fn missing_symbol_is_named() {
    let Some(path) = option_env!("FDSDK_DOUBLE_NO_WATCHDOG") else {
        panic!("the SDK double variant was not built (see the build script's warning)")
    };
    let e = open_error(Some(path), None).unwrap();
    assert!(e.contains("lacks symbol dhdSetWatchdog"), "{e}");
    assert!(e.contains(path) && e.contains("MMT_FD_SDK_LIB"), "{e}");
}

#[test]
fn missing_library_names_it_the_search_path_and_the_variable() {
    let e = open_error(Some("/nonexistent/libdhd.so"), None).unwrap();
    assert!(e.contains("'/nonexistent/libdhd.so'"), "{e}");
    assert!(
        e.contains("--fd-sdk-lib") && e.contains("that path only"),
        "{e}"
    );
    assert!(e.contains("MMT_FD_SDK_LIB"), "{e}");

    // Chosen by the environment variable.
    let e = open_error(None, Some("/nowhere/x.so")).unwrap();
    assert!(
        e.contains("'/nowhere/x.so'") && e.contains("MMT_FD_SDK_LIB environment variable"),
        "{e}"
    );

    // The default name, searched on the loader's path (unless this machine has the real SDK).
    if let Some(e) = open_error(None, None) {
        assert!(
            e.contains("'libdhd.so'") && e.contains("LD_LIBRARY_PATH"),
            "{e}"
        );
        assert!(e.contains("MMT_FD_SDK_LIB"), "{e}");
    }
}

/// The report of a run whose loop ended with `device`.
fn report_of(device: Box<dyn HapticDevice>) -> operator::report::NetworkedReport {
    use operator::report::{self, RunFacts};
    let facts = RunFacts {
        run: metrics::networked::NetworkedRun {
            experiment: "networked".into(),
            scene: "exp1".into(),
            device: "omega".into(),
            period_ns: 1_000_000,
            ..Default::default()
        },
        truth: None,
        link: Default::default(),
        measurements_overwritten: 0,
        timing: Default::default(),
        wall_seconds: 0.0,
    };
    let end = operator::haptic::LoopEnd {
        force_record: *device.force_record(),
        device,
        safety: Default::default(),
        node: Default::default(),
        renderers: Vec::new(),
        ticks: 0,
        frame: None,
        parameters: None,
        sessions: 1,
        prior: None,
    };
    report::build(&facts, &Default::default(), &end).1
}

/// The device cuts its forces by itself while the app has them on: the backend faults with the
/// cause, zero is written and forces switched off, and the run report counts the fault.
#[test]
fn forces_cut_by_the_sdk_watchdog_or_velocity_guard_fault_the_device_and_are_reported() {
    for (cause, words) in [(3, "watchdog"), (2, "velocity guard")] {
        let d = Double::new(1);
        let mut dev = managed();
        dev.enable(ms(0)).unwrap();
        dev.update(ms(1)).unwrap();
        dev.servo_cf(ms(1), [1.0, 0.0, 0.0]).unwrap();
        assert_eq!(dev.operating_state(), OperatingState::Enabled);
        d.force_off(cause);
        let e = dev.update(ms(2)).unwrap_err().to_string();
        assert!(
            e.contains("switched its forces off") && e.contains(words),
            "{e}"
        );
        assert_eq!(dev.operating_state(), OperatingState::Faulted);
        let log = d.log();
        assert_eq!(
            log[log.len() - 3..],
            ["dhdGetStatus 0", "dhdSetForce 0 0 0", "dhdEnableForce 0"]
        );
        // Faulted: only zero is written from now on.
        dev.servo_cf(ms(3), [2.0, 0.0, 0.0]).unwrap();
        assert_eq!(d.log().last().unwrap(), "dhdSetForce 0 0 0");
        assert_eq!(dev.fault_count(), 1);

        let r = report_of(Box::new(dev));
        assert_eq!(r.device_faults, 1);
        assert_eq!(r.device_state, OperatingState::Faulted);
        assert!(r.device_fault.as_deref().unwrap().contains(words));
        let json = serde_json::to_value(&r).unwrap();
        assert_eq!(json["device_faults"], 1);
        assert_eq!(json["device_state"], "Faulted");
        let table = operator::report::table(&r, &operator::report::PeerFigures::default());
        assert!(table.contains("device state, faults"), "{table}");
        assert!(table.contains("Faulted / 1"), "{table}");
    }
}

#[test]
fn forces_off_while_disabled_is_no_fault() {
    let d = Double::new(1);
    let mut dev = managed();
    d.force_off(3);
    dev.update(ms(1)).unwrap();
    assert_eq!(dev.operating_state(), OperatingState::Disabled);
    // Enabling clears the cut; a healthy enabled read passes.
    dev.enable(ms(2)).unwrap();
    dev.update(ms(3)).unwrap();
    assert_eq!(dev.operating_state(), OperatingState::Enabled);
}
