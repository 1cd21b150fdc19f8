use std::collections::VecDeque;

use super::*;

/// Plays recorded reports, a few per tick.
struct Recorded {
    ticks: VecDeque<Vec<Vec<u8>>>,
    current: VecDeque<Vec<u8>>,
}

impl Recorded {
    fn new(ticks: Vec<Vec<Vec<u8>>>) -> Self {
        Self {
            ticks: ticks.into(),
            current: VecDeque::new(),
        }
    }
}

impl ReportSource for Recorded {
    fn read_report(&mut self, buf: &mut [u8]) -> Result<usize, DeviceError> {
        match self.current.pop_front() {
            Some(r) => {
                buf[..r.len()].copy_from_slice(&r);
                Ok(r.len())
            }
            None => {
                // End of this tick's batch: the next tick gets the next batch.
                self.current = self.ticks.pop_front().unwrap_or_default().into();
                Ok(0)
            }
        }
    }
}

fn translation(x: i16, y: i16, z: i16) -> Vec<u8> {
    let mut r = vec![1];
    for v in [x, y, z] {
        r.extend_from_slice(&v.to_le_bytes());
    }
    r
}

fn backend(ticks: Vec<Vec<Vec<u8>>>) -> SpaceMouseBackend<Recorded> {
    let mut source = Recorded::new(ticks);
    // Prime the first batch.
    source.current = source.ticks.pop_front().unwrap_or_default().into();
    SpaceMouseBackend::new(source, &SpaceMouseConfig::default(), "test".into()).unwrap()
}

const MS: Duration = Duration::from_millis(1);

#[test]
fn full_deflection_moves_at_max_speed_in_the_device_frame() {
    // Full right, full toward the user (HID +y → device −y), pressed (HID +z → device −z).
    let mut b = backend(vec![vec![translation(350, 350, 350)]]);
    b.read(Duration::ZERO).unwrap();
    let r = b.read(10 * MS).unwrap();
    let v = 0.1;
    for (got, want) in r.position_m.iter().zip([v * 0.01, -v * 0.01, -v * 0.01]) {
        assert!((got - want).abs() < 1e-12, "{:?}", r.position_m);
    }
    assert!((r.velocity_m_per_s[0] - v).abs() < 1e-9);
}

#[test]
fn position_stays_inside_the_workspace() {
    let mut b = backend(vec![vec![translation(350, 0, 0)]]);
    let mut r = b.read(Duration::ZERO).unwrap();
    for k in 1..=5000u32 {
        r = b.read(k * MS).unwrap();
    }
    assert!(
        (r.position_m[0] - 0.075).abs() < 1e-12,
        "{:?}",
        r.position_m
    );
    assert_eq!(r.velocity_m_per_s, [0.0; 3]);
}

#[test]
fn deadband_keeps_a_resting_cap_still() {
    let mut b = backend(vec![vec![translation(10, -12, 5)]]);
    b.read(Duration::ZERO).unwrap();
    let r = b.read(Duration::from_secs(1)).unwrap();
    assert_eq!(r.position_m, [0.0; 3]);
}

#[test]
fn both_layouts_and_buttons_update_the_state() {
    let six = vec![
        0x01, 0x00, 0x00, 0x00, 0x00, 0x5e, 0x01, 0x5e, 0x01, 0x00, 0x00, 0x00, 0x00,
    ];
    let mut b = backend(vec![
        vec![six, vec![3, 0x05, 0x00]],
        vec![vec![2, 0, 0, 0xa2, 0xfe, 0, 0]],
    ]);
    b.read(Duration::ZERO).unwrap();
    assert_eq!(b.rotation(), [1.0, 0.0, 0.0]);
    assert_eq!(b.buttons(), 5);
    b.read(MS).unwrap();
    assert_eq!(b.rotation(), [0.0, -1.0, 0.0]);
    let r = b.read(11 * MS).unwrap();
    assert!(
        r.position_m[2] < 0.0,
        "z pressed moves down: {:?}",
        r.position_m
    );
}

#[test]
fn button_0_is_the_clutch() {
    // Button reports (id 3, bitmap LE): left (bit 0) pressed, then right only, then none.
    let mut b = backend(vec![
        vec![vec![3, 0x01, 0x00]],
        vec![vec![3, 0x02, 0x00]],
        vec![vec![3, 0x00, 0x00]],
    ]);
    let clutch: Vec<bool> = (0..3u32).map(|k| b.read(k * MS).unwrap().clutch).collect();
    assert_eq!(clutch, [true, false, false]);
}

#[test]
fn garbage_reports_are_counted_not_fatal() {
    let mut b = backend(vec![vec![
        vec![0xff, 1, 2],
        vec![1, 2],
        vec![2, 0, 0],
        translation(0, 0, 0),
    ]]);
    b.read(Duration::ZERO).unwrap();
    assert_eq!(
        b.stats(),
        ReportStats {
            reports: 1,
            parse_errors: 3
        }
    );
}

#[test]
fn no_force_output_is_declared() {
    let b = backend(vec![]);
    assert!(!b.capabilities().outputs_force);
    assert_eq!(b.capabilities().max_force_n, 0.0);
}

#[test]
fn invalid_settings_are_refused() {
    for cfg in [
        SpaceMouseConfig {
            max_speed_m_per_s: 0.0,
            ..SpaceMouseConfig::default()
        },
        SpaceMouseConfig {
            deadband: 1.0,
            ..SpaceMouseConfig::default()
        },
    ] {
        assert!(SpaceMouseBackend::new(Recorded::new(vec![]), &cfg, "x".into()).is_err());
    }
}
