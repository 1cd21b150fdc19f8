//! Golden bytes: the wire format of one message of each kind, pinned. A failure here means the
//! format changed: if on purpose, bump `PROTOCOL_VERSION` and update the literals.

mod common;

use common::{hex, operator_samples, telerobot_samples};
use protocol::{operator_to_telerobot as o2t, telerobot_to_operator as t2o};

/// Hex of the samples in `common`, in the same order.
///
/// How to read them, e.g. `Ping { id: 7, t1_ns: 1000 }` = `0500 02 07 fbd007`: version 5 as u16
/// LE; variant index 2; id 7 as a one-byte varint; t1 zig-zagged to 2000, which is above 250 so
/// it takes the marker `fb` and a u16 LE. Floats are their 8 IEEE bytes LE (`000000000000e03f` =
/// 0.5); `Option` is a `00`/`01` byte before the value; strings and vectors a varint length.
const OPERATOR: [&str; 4] = [
    // Hello { version: 1, operator_name: "ab", want_clouds: true }
    "0500000102616201",
    // Command { header: 1,2,3,4,5, position_m: [0.5, -0.25, 1], velocity_m_per_s: [0, 2, -1.5] }
    "0500010104060405000000000000e03f000000000000d0bf000000000000f03f0000000000000000000000000000\
     0040000000000000f8bf",
    // Ping { id: 7, t1_ns: 1000 }
    "05000207fbd007",
    // Bye
    "050003",
];

const TELEROBOT: [&str; 8] = [
    // Welcome { version: 1, scene: "e1", KelvinVoigt, SlidingMass { false, true }, 1000 Hz,
    // Some(30 Hz), ["k1"], radii [0.5, 1, 2], prior Some(2, 0.5, 1, 0, 0.5, 2, 0.5, 0.25),
    // cloud_follows_object: true }
    "05000001026531010200010000000000408f40010000000000003e4001026b31000000000000e03f000000000000\
     f03f0000000000000040010000000000000040000000000000e03f000000000000f03f0000000000000000000000\
     000000e03f0000000000000040000000000000e03f000000000000d03f01",
    // Refused { VersionMismatch { ours: 1, theirs: 2 } }
    "050001000102",
    // Parameters { model_id: 3, normal: Some(KelvinVoigt 500, 60; t 10, residual 0.5), None }
    "0500020104060405030114000000000000e03f000000000000407f400000000000004e4000",
    // Contact { -1, Contact, proxy [0, 0, 0.5], normal Some([0, 0, 1]), None, None, Some(0.25) }
    "0500030104060405010100000000000000000000000000000000000000000000e03f0100000000000000000000\
     000000000000000000000000f03f000001000000000000d03f",
    // StateSync { 6, [(0.125, -0.5), (0, 0)], in contact, onset Some(-2) }
    "05000401040604050c000000000000c03f000000000000e0bf000000000000000000000000000000000101\
     03",
    // Measurement { 6, [1, 0, 0], [0, 0, 0], [0, 0, -2], false, stable, Some([4, 0.25]) }
    "05000501040604050c000000000000f03f000000000000000000000000000000000000000000000000000000\
     000000000000000000000000000000000000000000000000000000000000000000000000c00001010000000000\
     001040000000000000d03f",
    // Cloud { 9, 8, [0, 0, 1], [0, 0, 0, 1], [[1, -1, 0.5]] }
    "050006091000000000000000000000000000000000000000000000f03f00000000000000000000000000000000\
     0000000000000000000000000000f03f010000803f000080bf0000003f",
    // Pong { 7, 1000, -3, 4 }
    "05000707fbd0070508",
];

fn unhex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).expect("hex digits"))
        .collect()
}

#[test]
fn operator_messages_have_pinned_bytes() {
    for (msg, golden) in operator_samples().iter().zip(OPERATOR) {
        assert_eq!(hex(&o2t::encode(msg)), golden, "{}", msg.kind());
        assert_eq!(&o2t::decode(&unhex(golden)).unwrap(), msg, "{}", msg.kind());
    }
}

#[test]
fn telerobot_messages_have_pinned_bytes() {
    for (msg, golden) in telerobot_samples().iter().zip(TELEROBOT) {
        assert_eq!(hex(&t2o::encode(msg)), golden, "{}", msg.kind());
        assert_eq!(&t2o::decode(&unhex(golden)).unwrap(), msg, "{}", msg.kind());
    }
}

#[test]
fn every_kind_is_pinned() {
    assert_eq!(operator_samples().len(), OPERATOR.len());
    assert_eq!(telerobot_samples().len(), TELEROBOT.len());
}

/// The telerobot node's datagrams are encoded without building a `Message`, to the same pinned
/// bytes.
#[test]
fn datagrams_encode_to_the_pinned_bytes_of_their_message() {
    let mut buf = Vec::new();
    let mut seen = 0;
    for (msg, golden) in telerobot_samples().iter().zip(TELEROBOT) {
        let datagram = match msg.clone() {
            t2o::Message::Parameters(m) => t2o::Datagram::Parameters(m),
            t2o::Message::Contact(m) => t2o::Datagram::Contact(m),
            t2o::Message::StateSync(m) => t2o::Datagram::StateSync(m),
            t2o::Message::Measurement(m) => t2o::Datagram::Measurement(m),
            _ => continue,
        };
        t2o::encode_datagram_into(&datagram, &mut buf);
        assert_eq!(hex(&buf), golden, "{}", msg.kind());
        assert_eq!(&t2o::Message::from(datagram), msg);
        assert_eq!(datagram.header(), msg.header().unwrap());
        seen += 1;
    }
    assert_eq!(seen, 4, "every datagram kind");
}

/// The `decode` fuzz target's seeds (`fuzz/seeds/decode/`) are these golden bytes, so that they
/// carry this build's version prefix and reach the body decoders (seeds of an older version are
/// refused at the prefix and teach the fuzzer nothing). `MMT_WRITE_FUZZ_SEEDS=1` rewrites them.
#[test]
fn fuzz_seeds_are_the_golden_bytes() {
    const OPERATOR_NAMES: [&str; 4] = ["hello", "command", "ping", "bye"];
    const TELEROBOT_NAMES: [&str; 8] = [
        "welcome",
        "refused",
        "parameters",
        "contact",
        "state_sync",
        "measurement",
        "cloud",
        "pong",
    ];
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/seeds/decode");
    let seeds = OPERATOR_NAMES
        .iter()
        .zip(OPERATOR)
        .map(|(n, g)| (format!("o2t_{n}.bin"), g))
        .chain(
            TELEROBOT_NAMES
                .iter()
                .zip(TELEROBOT)
                .map(|(n, g)| (format!("t2o_{n}.bin"), g)),
        );
    let write = std::env::var_os("MMT_WRITE_FUZZ_SEEDS").is_some();
    for (name, golden) in seeds {
        let golden: String = golden.split_whitespace().collect();
        let path = dir.join(&name);
        if write {
            std::fs::write(&path, unhex(&golden)).unwrap();
        }
        let on_disk = std::fs::read(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(
            hex(&on_disk) == golden,
            "{name} is not the golden bytes: rerun with MMT_WRITE_FUZZ_SEEDS=1"
        );
    }
}
