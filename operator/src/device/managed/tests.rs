use std::sync::{Arc, Mutex};

use super::*;

#[derive(Clone, Debug, PartialEq)]
enum Call {
    Read,
    Force(Vec3),
    Enable(bool),
}

/// A backend that records calls and fails on demand.
struct Mock {
    caps: DeviceCapabilities,
    calls: Arc<Mutex<Vec<Call>>>,
    fail_writes: Arc<Mutex<bool>>,
}

impl Backend for Mock {
    fn capabilities(&self) -> &DeviceCapabilities {
        &self.caps
    }
    fn read(&mut self, _now: Duration) -> Result<DeviceReading, DeviceError> {
        self.calls.lock().unwrap().push(Call::Read);
        Ok(DeviceReading {
            position_m: [0.01, 0.0, 0.0],
            velocity_m_per_s: [0.0; 3],
            clutch: false,
        })
    }
    fn write_force(&mut self, f: Vec3) -> Result<(), DeviceError> {
        self.calls.lock().unwrap().push(Call::Force(f));
        if *self.fail_writes.lock().unwrap() {
            return Err(DeviceError::Sdk {
                call: "dhdSetForce",
                code: -1,
                message: "USB disconnected".into(),
            });
        }
        Ok(())
    }
    fn set_force_enabled(&mut self, on: bool) -> Result<(), DeviceError> {
        self.calls.lock().unwrap().push(Call::Enable(on));
        Ok(())
    }
}

struct Rig {
    dev: ManagedDevice<Mock>,
    calls: Arc<Mutex<Vec<Call>>>,
    fail: Arc<Mutex<bool>>,
}

impl Rig {
    fn new() -> Self {
        Self::with(ManagedConfig::default())
    }
    /// With a servo watchdog long enough for tests that jump in time.
    fn patient() -> Self {
        Self::with(ManagedConfig {
            servo_watchdog: Duration::from_secs(10),
            ..ManagedConfig::default()
        })
    }
    fn with(config: ManagedConfig) -> Self {
        let calls = Arc::new(Mutex::new(Vec::new()));
        let fail = Arc::new(Mutex::new(false));
        let mock = Mock {
            caps: DeviceCapabilities::omega7("mock"),
            calls: calls.clone(),
            fail_writes: fail.clone(),
        };
        Self {
            dev: ManagedDevice::new(mock, config).unwrap(),
            calls,
            fail,
        }
    }
    fn take(&self) -> Vec<Call> {
        std::mem::take(&mut self.calls.lock().unwrap())
    }
}

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

const Z: Call = Call::Force([0.0; 3]);

#[test]
fn starts_disabled_and_writes_only_zero() {
    let mut r = Rig::new();
    assert_eq!(r.dev.operating_state(), OperatingState::Disabled);
    r.dev.servo_cf(ms(0), [5.0, 0.0, 0.0]).unwrap();
    assert_eq!(r.take(), vec![Z]);
}

#[test]
fn enable_writes_zero_around_switching_forces_on() {
    let mut r = Rig::new();
    r.dev.enable(ms(0)).unwrap();
    assert_eq!(r.take(), vec![Z, Call::Enable(true), Z]);
    assert_eq!(r.dev.operating_state(), OperatingState::Enabled);
}

#[test]
fn enable_ramps_force_in_linearly() {
    let mut r = Rig::new();
    r.dev.enable(ms(1000)).unwrap();
    r.take();
    let f = [10.0, 0.0, 0.0];
    for (t, want) in [
        (1000, 0.0),
        (1050, 2.5),
        (1100, 5.0),
        (1150, 7.5),
        (1200, 10.0),
        (1210, 10.0),
    ] {
        r.dev.servo_cf(ms(t), f).unwrap();
        let got = r.dev.commanded_cf()[0];
        assert!((got - want).abs() < 1e-9, "t = {t} ms: {got} ≠ {want}");
    }
}

#[test]
fn disable_always_writes_zero_first() {
    let mut r = Rig::new();
    r.dev.enable(ms(0)).unwrap();
    r.dev.servo_cf(ms(1), [3.0, 0.0, 0.0]).unwrap();
    r.take();
    r.dev.disable(ms(2)).unwrap();
    assert_eq!(r.take(), vec![Z, Call::Enable(false)]);
    assert_eq!(r.dev.operating_state(), OperatingState::Disabled);
    // Also when already disabled.
    r.dev.disable(ms(3)).unwrap();
    assert_eq!(r.take(), vec![Z, Call::Enable(false)]);
}

#[test]
fn device_error_faults_writes_zero_and_requires_reset() {
    let mut r = Rig::new();
    r.dev.enable(ms(0)).unwrap();
    r.take();
    *r.fail.lock().unwrap() = true;
    assert!(r.dev.servo_cf(ms(1), [3.0, 0.0, 0.0]).is_err());
    assert_eq!(r.dev.operating_state(), OperatingState::Faulted);
    // The failed write, then zero and forces off.
    let calls = r.take();
    assert!(matches!(calls[0], Call::Force([x, _, _]) if (x - 0.015).abs() < 1e-12));
    assert_eq!(calls[1..], [Z, Call::Enable(false)]);
    let fault = r.dev.fault().unwrap();
    assert_eq!(fault.at, ms(1));
    assert!(matches!(&fault.cause, FaultCause::Device(m) if m.contains("USB disconnected")));
    *r.fail.lock().unwrap() = false;
    // Enabling is refused until reset; servo keeps writing zero.
    let e = r.dev.enable(ms(2)).unwrap_err().to_string();
    assert!(e.contains("reset"), "{e}");
    r.dev.servo_cf(ms(3), [3.0, 0.0, 0.0]).unwrap();
    assert_eq!(r.take(), vec![Z]);
    r.dev.reset(ms(4)).unwrap();
    assert_eq!(r.dev.operating_state(), OperatingState::Disabled);
    assert_eq!(r.take(), vec![Z, Call::Enable(false)]);
    r.dev.enable(ms(5)).unwrap();
    assert_eq!(r.dev.operating_state(), OperatingState::Enabled);
}

#[test]
fn servo_watchdog_trip_faults() {
    let mut r = Rig::new();
    r.dev.enable(ms(0)).unwrap();
    r.dev.servo_cf(ms(10), [1.0, 0.0, 0.0]).unwrap();
    r.take();
    let e = r
        .dev
        .servo_cf(ms(61), [1.0, 0.0, 0.0])
        .unwrap_err()
        .to_string();
    assert!(e.contains("servo watchdog"), "{e}");
    assert_eq!(r.dev.operating_state(), OperatingState::Faulted);
    assert_eq!(r.take(), vec![Z, Call::Enable(false)]);
    // Disable does not leave Faulted.
    r.dev.disable(ms(62)).unwrap();
    assert_eq!(r.dev.operating_state(), OperatingState::Faulted);
}

#[test]
fn trip_faults_from_any_state() {
    let mut r = Rig::new();
    r.dev.trip(ms(5), "operator pressed stop");
    assert_eq!(r.dev.operating_state(), OperatingState::Faulted);
    assert_eq!(r.take(), vec![Z, Call::Enable(false)]);
    assert_eq!(
        r.dev.fault().unwrap().cause,
        FaultCause::Requested("operator pressed stop".into())
    );
    assert_eq!(r.dev.fault_count(), 1);
    // Tripping a faulted device is not a second fault; a fault after a reset is.
    r.dev.trip(ms(6), "again");
    assert_eq!(r.dev.fault_count(), 1);
    r.dev.reset(ms(7)).unwrap();
    r.dev.trip(ms(8), "third time");
    assert_eq!(r.dev.fault_count(), 2);
}

#[test]
fn non_finite_force_is_written_as_zero() {
    let mut r = Rig::patient();
    r.dev.enable(ms(0)).unwrap();
    r.take();
    r.dev.servo_cf(ms(300), [f64::NAN, 1.0, 0.0]).unwrap();
    r.dev.servo_cf(ms(301), [f64::INFINITY, 1.0, 0.0]).unwrap();
    assert_eq!(r.take(), vec![Z, Z]);
}

#[test]
fn update_reads_and_records_force_stats() {
    let mut r = Rig::patient();
    r.dev.update(ms(0)).unwrap();
    assert_eq!(r.dev.measured_cp(), [0.01, 0.0, 0.0]);
    r.dev.enable(ms(0)).unwrap();
    r.dev.servo_cf(ms(200), [3.0, 4.0, 0.0]).unwrap();
    let rec = r.dev.force_record();
    assert_eq!(rec.max_norm_n, 5.0);
    assert_eq!(rec.nonzero_ticks, 1);
    assert_eq!(rec.ticks, 3);
}
