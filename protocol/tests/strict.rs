//! What decoding refuses, and the size bound of datagrams.

mod common;

use common::{hex, telerobot_samples};
use common::{largest_operator_datagrams, largest_telerobot_datagrams, operator_samples};
use protocol::telerobot_to_operator::{CloudFrame, ModelStructure, SceneSummary, Welcome};
use protocol::{
    DecodeError, Direction, MAX_BODY_BYTES, MAX_CLOUD_POINTS, MAX_DATAGRAM_BYTES, PROTOCOL_VERSION,
};

/// `bytes` after this build's version prefix.
fn versioned(bytes: &[u8]) -> Vec<u8> {
    let mut v = PROTOCOL_VERSION.to_le_bytes().to_vec();
    v.extend_from_slice(bytes);
    v
}
use protocol::{operator_to_telerobot as o2t, telerobot_to_operator as t2o};

#[test]
fn another_version_is_refused_naming_both() {
    let (ours, theirs) = (PROTOCOL_VERSION, PROTOCOL_VERSION + 1);
    let mut bytes = o2t::encode(&o2t::Message::Bye);
    bytes[..2].copy_from_slice(&theirs.to_le_bytes());
    let e = o2t::decode(&bytes).unwrap_err();
    assert_eq!(e, DecodeError::Version { ours, theirs });
    assert_eq!(
        e.to_string(),
        format!("protocol version mismatch: this side speaks {ours}, the peer sent {theirs}")
    );
    // The prefix is checked first: even a body this build cannot read names the versions.
    assert_eq!(
        t2o::decode(&[0x02, 0x01, 0xff]),
        Err(DecodeError::Version { ours, theirs: 258 })
    );
}

#[test]
fn too_short_for_the_version() {
    assert_eq!(o2t::decode(&[]), Err(DecodeError::TooShort { len: 0 }));
    let e = t2o::decode(&[1]).unwrap_err();
    assert_eq!(
        e.to_string(),
        "message of 1 bytes is too short: expected at least the 2-byte protocol version"
    );
}

#[test]
fn a_trailing_byte_is_rejected() {
    let e = o2t::decode(&versioned(&[0x03, 0x00])).unwrap_err();
    assert_eq!(
        e,
        DecodeError::TrailingBytes {
            direction: Direction::OperatorToTelerobot,
            message_len: 3,
            trailing: 1
        }
    );
    assert_eq!(
        e.to_string(),
        "1 trailing bytes after a complete operator-to-telerobot message of 3 bytes: expected the \
         datagram to end there"
    );
}

#[test]
fn truncation_and_unknown_variants_say_what_was_expected() {
    let e = o2t::decode(&versioned(&[0x02, 0x07])).unwrap_err();
    assert!(
        matches!(e, DecodeError::Truncated { needed: 1, .. }),
        "{e:?}"
    );
    assert_eq!(
        e.to_string(),
        "truncated operator-to-telerobot message: expected at least 1 more bytes"
    );
    let e = t2o::decode(&versioned(&[0x08])).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("malformed telerobot-to-operator message: "),
        "{e}"
    );
}

/// Positions of `pattern` in `bytes`.
fn find_all(bytes: &[u8], pattern: &[u8]) -> Vec<usize> {
    (0..=bytes.len() - pattern.len())
        .filter(|&i| bytes[i..].starts_with(pattern))
        .collect()
}

/// Replaces each float equal to `marker` in the encoding, one at a time, by NaN and checks that
/// decoding names a field; returns how many were found. In the largest messages every float is
/// `f64::MAX` and no integer encodes to its bytes, so this reaches every float field.
fn every_float_is_checked<M>(
    msg: &M,
    encode: fn(&M) -> Vec<u8>,
    decode: fn(&[u8]) -> Result<M, DecodeError>,
    marker: &[u8],
    nan: &[u8],
) -> usize {
    let bytes = encode(msg);
    let at = find_all(&bytes, marker);
    for &i in &at {
        let mut bad = bytes.clone();
        bad[i..i + nan.len()].copy_from_slice(nan);
        match decode(&bad) {
            Err(DecodeError::NonFinite { source, .. }) => assert!(source.value.is_nan()),
            _ => panic!("NaN at byte {i} of {} not rejected", hex(&bytes)),
        }
    }
    at.len()
}

#[test]
fn nan_is_rejected_in_every_float_field() {
    let (max, nan) = (f64::MAX.to_le_bytes(), f64::NAN.to_le_bytes());
    let floats = |m| every_float_is_checked(m, o2t::encode, o2t::decode, &max, &nan);
    let counts: Vec<usize> = largest_operator_datagrams().iter().map(floats).collect();
    assert_eq!(counts, [6, 0], "Command, Ping");
    let floats = |m| every_float_is_checked(m, t2o::encode, t2o::decode, &max, &nan);
    let counts: Vec<usize> = largest_telerobot_datagrams().iter().map(floats).collect();
    assert_eq!(
        counts,
        [14, 19, 4, 11, 0],
        "Parameters, Contact, StateSync, Measurement, Pong"
    );

    let cloud = t2o::Message::Cloud(CloudFrame {
        frame_id: 0,
        timestamp_ns: 0,
        sensor_position_m: [f64::MAX; 3],
        sensor_orientation_xyzw: [f64::MAX; 4],
        points: vec![[f32::MAX; 3]; 2],
    });
    assert_eq!(
        every_float_is_checked(&cloud, t2o::encode, t2o::decode, &max, &nan),
        7
    );
    let (max32, nan32) = (f32::MAX.to_le_bytes(), f32::NAN.to_le_bytes());
    assert_eq!(
        every_float_is_checked(&cloud, t2o::encode, t2o::decode, &max32, &nan32),
        6,
        "2 points × 3 coordinates"
    );
    let welcome = t2o::Message::Welcome(Welcome {
        version: 1,
        scene: SceneSummary {
            name: String::new(),
            normal: ModelStructure::Free,
            tangential: ModelStructure::Free,
            control_rate_hz: f64::MAX,
            cloud_rate_hz: Some(f64::MAX),
            left_out: vec![],
            proxy_radii_m: [f64::MAX; 3],
            prior: None,
            cloud_follows_object: false,
        },
    });
    assert_eq!(
        every_float_is_checked(&welcome, t2o::encode, t2o::decode, &max, &nan),
        5
    );
}

#[test]
fn the_non_finite_field_is_named() {
    let mut samples = telerobot_samples();
    let t2o::Message::Contact(c) = &mut samples[3] else {
        panic!("sample 3 is a Contact");
    };
    c.normal = Some([0.0, f64::INFINITY, 1.0]);
    let e = t2o::decode(&t2o::encode(&samples[3])).unwrap_err();
    assert_eq!(
        e.to_string(),
        "telerobot-to-operator message rejected: field Contact.normal[1] is inf, expected a \
         finite number"
    );
    let t2o::Message::Parameters(p) = &mut samples[2] else {
        panic!("sample 2 is Parameters");
    };
    p.normal = p.normal.map(|mut s| {
        s.residual = f64::NEG_INFINITY;
        s
    });
    let e = t2o::decode(&t2o::encode(&samples[2])).unwrap_err();
    assert!(
        e.to_string()
            .contains("field Parameters.normal.residual is -inf"),
        "{e}"
    );
    let t2o::Message::StateSync(s) = &mut samples[4] else {
        panic!("sample 4 is a StateSync");
    };
    s.tangential[1].mass_velocity_m_per_s = f64::NAN;
    assert_eq!(
        samples[4].check_finite().unwrap_err().field,
        "StateSync.tangential[1].mass_velocity_m_per_s"
    );
    let mut ops = operator_samples();
    let o2t::Message::Command(c) = &mut ops[1] else {
        panic!("sample 1 is a Command");
    };
    c.velocity_m_per_s[2] = f64::NAN;
    let e = o2t::decode(&o2t::encode(&ops[1])).unwrap_err();
    assert!(
        e.to_string()
            .contains("field Command.velocity_m_per_s[2] is NaN"),
        "{e}"
    );
}

#[test]
fn every_datagram_fits_the_bound() {
    let sizes = largest_operator_datagrams()
        .into_iter()
        .map(|m| (m.kind(), o2t::encode(&m).len()))
        .chain(
            largest_telerobot_datagrams()
                .into_iter()
                .map(|m| (m.kind(), t2o::encode(&m).len())),
        );
    for (kind, len) in sizes {
        println!("largest {kind}: {len} bytes");
        assert!(
            len <= MAX_DATAGRAM_BYTES,
            "{kind}: {len} > {MAX_DATAGRAM_BYTES}"
        );
    }
}

#[test]
fn a_garbage_length_prefix_does_not_allocate() {
    // Hello whose name claims 2^40 bytes: refused by the limit before allocating.
    let mut bytes = versioned(&[0x00, 0x01, 0xfd]);
    bytes.extend_from_slice(&(1u64 << 40).to_le_bytes());
    let e = o2t::decode(&bytes).unwrap_err();
    assert_eq!(
        e,
        DecodeError::TooLarge {
            direction: Direction::OperatorToTelerobot,
            limit: MAX_BODY_BYTES
        }
    );
    // A cloud claiming 2^61 points: serde grows the vector as points arrive, so it runs out
    // of bytes instead.
    let mut bytes = t2o::encode(&telerobot_samples()[6]);
    let count_at = bytes.len() - 13; // one point of 12 bytes, after its 1-byte count
    bytes.truncate(count_at);
    bytes.push(0xfd);
    bytes.extend_from_slice(&(1u64 << 61).to_le_bytes());
    bytes.extend_from_slice(&[0; 24]);
    assert!(matches!(
        t2o::decode(&bytes),
        Err(DecodeError::Truncated { .. })
    ));
}

#[test]
fn the_largest_cloud_fits_the_limit() {
    let cloud = t2o::Message::Cloud(CloudFrame {
        frame_id: u64::MAX,
        timestamp_ns: i64::MIN,
        sensor_position_m: [1.0; 3],
        sensor_orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
        points: vec![[0.5, -0.5, 1.5]; MAX_CLOUD_POINTS],
    });
    let bytes = t2o::encode(&cloud);
    assert!(bytes.len() > 12 * MAX_CLOUD_POINTS);
    assert_eq!(t2o::decode(&bytes), Ok(cloud));
}
