//! SpaceMouse HID input reports: the known vendor/product ids and a pure parser.
//!
//! Layouts (OpenSCAD `hidapi_sm_decode`, spacenavd):
//! - **old layout** — report 1 = translation x, y, z as 3 × i16 little-endian (7 bytes with the id),
//!   report 2 = rotation, same layout;
//! - **new layout** — report 1 = all six axes, translation then rotation (13 bytes);
//! - report 3 = button bitmap, little-endian (16 bits on most models; up to 32 read).
//!
//! Axis values span about ±350 (FreePIE: "values range from 0 to +/-350"; OpenSCAD scales by
//! 1/350). Lengths are checked exactly: anything else is an error, never a panic.

/// Full-scale axis value: raw / 350 ≈ ±1.
pub const AXIS_FULL_SCALE: f64 = 350.0;

/// A known SpaceMouse model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KnownDevice {
    /// USB vendor id.
    pub vendor_id: u16,
    /// USB product id.
    pub product_id: u16,
    /// Model name.
    pub model: &'static str,
}

const fn known(vendor_id: u16, product_id: u16, model: &'static str) -> KnownDevice {
    KnownDevice {
        vendor_id,
        product_id,
        model,
    }
}

/// Logitech-era (0x046d) and 3Dconnexion (0x256f) multi-axis controllers, from spacenavd's
/// `src/dev.c` and OpenSCAD's `HidApiInputDriver.cc` tables.
pub const KNOWN_DEVICES: &[KnownDevice] = &[
    known(0x046d, 0xc603, "SpaceMouse Plus XT"),
    known(0x046d, 0xc605, "CADman"),
    known(0x046d, 0xc606, "SpaceMouse Classic"),
    known(0x046d, 0xc621, "Spaceball 5000"),
    known(0x046d, 0xc623, "SpaceTraveler"),
    known(0x046d, 0xc625, "SpacePilot"),
    known(0x046d, 0xc626, "SpaceNavigator"),
    known(0x046d, 0xc627, "SpaceExplorer"),
    known(0x046d, 0xc628, "SpaceNavigator for Notebooks"),
    known(0x046d, 0xc629, "SpacePilot Pro"),
    known(0x046d, 0xc62b, "SpaceMouse Pro"),
    known(0x256f, 0xc62e, "SpaceMouse Wireless (cable)"),
    known(0x256f, 0xc62f, "SpaceMouse Wireless (receiver)"),
    known(0x256f, 0xc631, "SpaceMouse Pro Wireless (cable)"),
    known(0x256f, 0xc632, "SpaceMouse Pro Wireless (receiver)"),
    known(0x256f, 0xc633, "SpaceMouse Enterprise"),
    known(0x256f, 0xc635, "SpaceMouse Compact"),
    known(0x256f, 0xc636, "SpaceMouse Module"),
    known(0x256f, 0xc63a, "SpaceMouse Wireless BT"),
    known(0x256f, 0xc652, "3Dconnexion Universal Receiver"),
];

/// The model for a vendor/product pair, if known.
#[must_use]
pub fn known_device(vendor_id: u16, product_id: u16) -> Option<&'static KnownDevice> {
    KNOWN_DEVICES
        .iter()
        .find(|d| d.vendor_id == vendor_id && d.product_id == product_id)
}

/// One decoded input report (raw axis counts, HID axis directions).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Report {
    /// Old layout, report 1: translation x, y, z.
    Translation([i16; 3]),
    /// Old layout, report 2: rotation rx, ry, rz.
    Rotation([i16; 3]),
    /// New layout, report 1: translation then rotation.
    SixAxis {
        /// x, y, z.
        translation: [i16; 3],
        /// rx, ry, rz.
        rotation: [i16; 3],
    },
    /// Report 3: button bitmap (bit i = button i pressed).
    Buttons(u32),
}

/// Why a report was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ReportError {
    /// Zero bytes.
    #[error("empty HID report")]
    Empty,
    /// A report id this parser does not know.
    #[error(
        "unknown SpaceMouse report id {0:#04x}; expected 1 (translation or 6 axes), 2 (rotation) or 3 (buttons)"
    )]
    UnknownId(u8),
    /// A known id with the wrong length.
    #[error("SpaceMouse report {id} has {len} bytes; expected {expected}")]
    Length {
        /// Report id.
        id: u8,
        /// Bytes received, id included.
        len: usize,
        /// Allowed lengths.
        expected: &'static str,
    },
}

/// Decodes one input report (first byte = report id). Pure; never panics.
pub fn parse_report(bytes: &[u8]) -> Result<Report, ReportError> {
    let (&id, payload) = bytes.split_first().ok_or(ReportError::Empty)?;
    let length = |expected| ReportError::Length {
        id,
        len: bytes.len(),
        expected,
    };
    match id {
        1 if payload.len() == 12 => Ok(Report::SixAxis {
            translation: axes(&payload[0..6]),
            rotation: axes(&payload[6..12]),
        }),
        1 if payload.len() == 6 => Ok(Report::Translation(axes(payload))),
        1 => Err(length("7 (old layout) or 13 (new layout)")),
        2 if payload.len() == 6 => Ok(Report::Rotation(axes(payload))),
        2 => Err(length("7")),
        3 if !payload.is_empty() && payload.len() <= 63 => {
            let mut b = [0u8; 4];
            for (dst, src) in b.iter_mut().zip(payload) {
                *dst = *src;
            }
            Ok(Report::Buttons(u32::from_le_bytes(b)))
        }
        3 => Err(length("2 to 64")),
        other => Err(ReportError::UnknownId(other)),
    }
}

/// Three little-endian i16 from exactly 6 bytes (callers pass 6-byte slices).
fn axes(p: &[u8]) -> [i16; 3] {
    std::array::from_fn(|i| {
        let lo = p.get(2 * i).copied().unwrap_or(0);
        let hi = p.get(2 * i + 1).copied().unwrap_or(0);
        i16::from_le_bytes([lo, hi])
    })
}

/// Raw axis count → [−1, 1] (÷ 350, clamped: some units report slightly past 350).
#[must_use]
pub fn normalise(raw: i16) -> f64 {
    (f64::from(raw) / AXIS_FULL_SCALE).clamp(-1.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    // Byte sequences in the form the devices send them (built from the documented layouts, not
    // captured from hardware: none was at hand). Old layout, as a SpaceNavigator sends:
    // full right, full toward the user, a little down.
    const OLD_TRANSLATION: [u8; 7] = [0x01, 0x5e, 0x01, 0xa2, 0xfe, 0x0a, 0x00];
    const OLD_ROTATION: [u8; 7] = [0x02, 0xf6, 0xff, 0x00, 0x00, 0x2c, 0x01];
    const BUTTONS: [u8; 3] = [0x03, 0x02, 0x00];
    // New layout, as a SpaceMouse Compact sends: all six axes in one report.
    const NEW_SIX_AXIS: [u8; 13] = [
        0x01, 0x10, 0x00, 0xf0, 0xff, 0x5e, 0x01, 0x00, 0x00, 0xa2, 0xfe, 0x01, 0x00,
    ];

    #[test]
    fn old_layout_reports() {
        assert_eq!(
            parse_report(&OLD_TRANSLATION),
            Ok(Report::Translation([350, -350, 10]))
        );
        assert_eq!(
            parse_report(&OLD_ROTATION),
            Ok(Report::Rotation([-10, 0, 300]))
        );
        assert_eq!(parse_report(&BUTTONS), Ok(Report::Buttons(2)));
    }

    #[test]
    fn new_layout_report() {
        assert_eq!(
            parse_report(&NEW_SIX_AXIS),
            Ok(Report::SixAxis {
                translation: [16, -16, 350],
                rotation: [0, -350, 1],
            })
        );
    }

    #[test]
    fn short_unknown_and_garbage_reports_are_errors() {
        assert_eq!(parse_report(&[]), Err(ReportError::Empty));
        assert_eq!(
            parse_report(&OLD_TRANSLATION[..5]),
            Err(ReportError::Length {
                id: 1,
                len: 5,
                expected: "7 (old layout) or 13 (new layout)"
            })
        );
        assert!(parse_report(&NEW_SIX_AXIS[..10]).is_err());
        assert!(parse_report(&[2, 0, 0, 0]).is_err());
        assert!(parse_report(&[3]).is_err());
        assert_eq!(
            parse_report(&[0x17, 1, 2]),
            Err(ReportError::UnknownId(0x17))
        );
        let msg = parse_report(&[0xff; 9]).unwrap_err().to_string();
        assert!(msg.contains("0xff"), "{msg}");
    }

    #[test]
    fn normalise_clamps_to_unit_range() {
        assert_eq!(normalise(350), 1.0);
        assert_eq!(normalise(-700), -1.0);
        assert_eq!(normalise(0), 0.0);
        assert_eq!(normalise(175), 0.5);
    }

    #[test]
    fn known_ids_cover_both_vendor_families() {
        assert_eq!(
            known_device(0x046d, 0xc626).unwrap().model,
            "SpaceNavigator"
        );
        assert_eq!(
            known_device(0x256f, 0xc635).unwrap().model,
            "SpaceMouse Compact"
        );
        assert!(known_device(0x1451, 0x0402).is_none());
    }

    proptest! {
        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..80)) {
            match parse_report(&bytes) {
                Ok(Report::Translation(_) | Report::Rotation(_)) => prop_assert_eq!(bytes.len(), 7),
                Ok(Report::SixAxis { .. }) => prop_assert_eq!(bytes.len(), 13),
                Ok(Report::Buttons(_)) => prop_assert_eq!(bytes[0], 3),
                Err(_) => {}
            }
        }
    }
}
