//! Round trips and rejections of the PLY and PCD readers.

use super::*;

fn sample_points() -> Vec<[f32; 3]> {
    (0..57)
        .map(|i| {
            let f = i as f32;
            [
                f * 0.013 - 0.3,
                (f * 0.7).sin() * 2.5,
                -1.0e-7 * f + 123.456,
            ]
        })
        .collect()
}

fn bits(points: &[[f32; 3]]) -> Vec<[u32; 3]> {
    points.iter().map(|p| p.map(f32::to_bits)).collect()
}

type Encoder = fn(&[[f32; 3]]) -> Vec<u8>;

const ENCODINGS: [(&str, Encoder); 5] = [
    ("ply ascii", |p| encode_ply(p, PlyEncoding::Ascii)),
    ("ply binary le", |p| {
        encode_ply(p, PlyEncoding::BinaryLittleEndian)
    }),
    ("ply binary be", |p| {
        encode_ply(p, PlyEncoding::BinaryBigEndian)
    }),
    ("pcd ascii", |p| encode_pcd(p, PcdEncoding::Ascii)),
    ("pcd binary", |p| encode_pcd(p, PcdEncoding::Binary)),
];

fn parse(bytes: &[u8]) -> Result<LoadedCloud, ParseError> {
    parse_cloud(bytes, LoadOptions::default())
}

#[test]
fn every_encoding_round_trips_bit_for_bit() {
    let points = sample_points();
    for (name, encode) in ENCODINGS {
        let bytes = encode(&points);
        let cloud = parse(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(bits(&cloud.points), bits(&points), "{name}");
        assert_eq!(cloud.skipped_non_finite, 0);
        let empty = parse(&encode(&[])).unwrap();
        assert!(empty.points.is_empty(), "{name}");
    }
    let pcd = parse(&encode_pcd(&points, PcdEncoding::Ascii)).unwrap();
    assert_eq!(pcd.viewpoint, Some(mmt::cloud::Pose::IDENTITY));
}

#[test]
fn truncated_files_are_rejected_with_the_position() {
    let points = sample_points();
    for (name, encode) in ENCODINGS {
        let bytes = encode(&points);
        // Cut inside the last record: one byte for binary, the last value for text.
        let cut = if name.contains("ascii") {
            let text = std::str::from_utf8(&bytes).unwrap().trim_end();
            text.as_bytes()[..text.rfind(' ').unwrap()].to_vec()
        } else {
            bytes[..bytes.len() - 1].to_vec()
        };
        let err = parse(&cut).unwrap_err();
        let msg = err.to_string();
        match err {
            ParseError::CountExceedsData {
                declared: 57,
                record: 56,
                at,
                ..
            } => {
                // The last record starts 12 bytes before the end of the uncut file.
                let offset = bytes.len() - 12;
                assert_eq!(at, Location::Byte(offset), "{name}");
                assert!(
                    msg.contains(&format!("byte {offset}: data ends in"))
                        && msg.contains("record 56")
                        && msg.contains("57 records of 12 bytes"),
                    "{name}: {msg}"
                )
            }
            ParseError::WrongValueCount {
                record: 56,
                found: 2,
                expected: 3,
                at,
                ..
            } => {
                assert!(matches!(at, Location::Line(_)), "{name}");
                assert!(msg.contains("line"), "{msg}");
            }
            other => panic!("{name}: unexpected {other:?}"),
        }
        // Cut 30 bytes into the data's end: records 54 to 56 are incomplete, 54 first.
        if !name.contains("ascii") {
            let err = parse(&bytes[..bytes.len() - 30]).unwrap_err();
            let offset = bytes.len() - 3 * 12;
            assert!(
                matches!(err, ParseError::CountExceedsData { record: 54, at, .. } if at == Location::Byte(offset)),
                "{name}: {err:?}"
            );
            let msg = err.to_string();
            assert!(msg.contains(&format!("byte {offset}")), "{name}: {msg}");
        }
        // Cut after a whole record: a missing line / missing bytes.
        if name.contains("ascii") {
            let text = std::str::from_utf8(&bytes).unwrap().trim_end();
            let cut = &text[..text.rfind('\n').unwrap()];
            let err = parse(cut.as_bytes()).unwrap_err();
            assert!(
                matches!(
                    err,
                    ParseError::Truncated {
                        record: 56,
                        declared: 57,
                        ..
                    }
                ),
                "{name}: {err}"
            );
        }
    }
}

/// The header text (through its last line) and the data after it.
fn split_header(bytes: &[u8]) -> (String, &[u8]) {
    let end = ["end_header\n", "DATA ascii\n", "DATA binary\n"]
        .iter()
        .find_map(|m| {
            bytes
                .windows(m.len())
                .position(|w| w == m.as_bytes())
                .map(|i| i + m.len())
        })
        .unwrap();
    (
        String::from_utf8(bytes[..end].to_vec()).unwrap(),
        &bytes[end..],
    )
}

#[test]
fn wrong_counts_are_rejected() {
    let points = sample_points();
    for (name, encode) in ENCODINGS {
        let file = encode(&points);
        let (header, data) = split_header(&file);
        // Declare one point more, then one point fewer, than the data holds.
        for declared in [58u64, 56] {
            let mut bytes = header
                .replace("vertex 57\n", &format!("vertex {declared}\n"))
                .replace("WIDTH 57\n", &format!("WIDTH {declared}\n"))
                .replace("POINTS 57\n", &format!("POINTS {declared}\n"))
                .into_bytes();
            bytes.extend_from_slice(data);
            let err = parse(&bytes).unwrap_err();
            if declared == 58 {
                assert!(
                    matches!(
                        err,
                        ParseError::CountExceedsData { declared: 58, .. }
                            | ParseError::Truncated {
                                declared: 58,
                                record: 57,
                                ..
                            }
                    ),
                    "{name}: {err}"
                );
            } else {
                assert!(
                    matches!(err, ParseError::TrailingData { declared: 56, .. }),
                    "{name}: {err}"
                );
            }
        }
    }
}

#[test]
fn non_numeric_values_are_rejected_with_line_and_text() {
    let ply = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
               property float z\nend_header\n1 2 3\n4 five 6\n";
    let pcd = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nPOINTS 1\nDATA ascii\n\
               0,5 1 2\n";
    for (text, line, record, token) in [(ply, 9, 1, "five"), (pcd, 8, 0, "0,5")] {
        let err = parse(text.as_bytes()).unwrap_err();
        let ParseError::NotANumber {
            at,
            record: r,
            ref found,
            ..
        } = err
        else {
            panic!("{err:?}");
        };
        assert_eq!(
            (at, r, found.as_str()),
            (Location::Line(line), record, token)
        );
        let msg = err.to_string();
        assert!(
            msg.contains(&format!("line {line}")) && msg.contains(token),
            "{msg}"
        );
    }
}

/// Regression: only x, y and z were parsed; other values and list items were counted, so
/// `1 2 3 abc` under `property uchar red` loaded.
#[test]
fn every_text_value_is_checked_against_its_declared_type() {
    let ply = |props: &str, row: &str| {
        format!(
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
             property float z\n{props}end_header\n{row}\n"
        )
    };
    let red = "property uchar red\n";
    let list = "property list uchar int idx\n";
    let pcd = |row: &str| {
        format!(
            "FIELDS x y z rgb fpfh\nSIZE 4 4 4 4 4\nTYPE F F F U F\nCOUNT 1 1 1 1 3\nWIDTH 1\n\
             DATA ascii\n{row}\n"
        )
    };
    // (file, line, column, property, found, expected)
    let cases = [
        (
            ply(red, "1 2 3 abc"),
            9,
            4,
            "red",
            "abc",
            "uint8 (an integer in 0 ..= 255)",
        ),
        (ply(red, "1 2 3 256"), 9, 4, "red", "256", "0 ..= 255"),
        (ply(red, "1 2 3 -1"), 9, 4, "red", "-1", "0 ..= 255"),
        (ply(red, "1 2 3 1.5"), 9, 4, "red", "1.5", "uint8"),
        (ply(list, "1 2 3 2 5 x"), 9, 6, "idx[1]", "x", "int32"),
        (ply(list, "1 2 3 2 5 6e3"), 9, 6, "idx[1]", "6e3", "int32"),
        (
            ply(list, "1 2 3 -2 5 6"),
            9,
            4,
            "idx (list length)",
            "-2",
            "list length (a uint8: 0 ..= 255)",
        ),
        (
            ply(list, "1 2 3 300"),
            9,
            4,
            "idx (list length)",
            "300",
            "uint8",
        ),
        (
            ply("property double intensity\n", "1 2 3 1.2.3"),
            9,
            4,
            "intensity",
            "1.2.3",
            "float64 (a number)",
        ),
        (
            pcd("1 2 3 4294967296 0 0 0"),
            7,
            4,
            "rgb",
            "4294967296",
            "uint32",
        ),
        (pcd("1 2 3 7 0 zero 0"), 7, 6, "fpfh[1]", "zero", "float32"),
    ];
    for (text, line, column, property, found, expected) in cases {
        let err = parse(text.as_bytes()).unwrap_err();
        let msg = err.to_string();
        let ParseError::NotANumber {
            at,
            column: c,
            property: ref p,
            found: ref f,
            ..
        } = err
        else {
            panic!("{text:?}: {err:?}");
        };
        assert_eq!(
            (at, c, p.as_str(), f.as_str()),
            (Location::Line(line), column, property, found),
            "{text:?}"
        );
        assert!(
            msg.contains(&format!("line {line}, column {column} (`{property}`)"))
                && msg.contains(expected),
            "{msg}"
        );
    }
    // Other float columns only need to parse: NaN there is a value like any other.
    let fine = parse(ply("property float intensity\n", "1 2 3 nan").as_bytes()).unwrap();
    assert_eq!(fine.points, vec![[1.0, 2.0, 3.0]]);
    let fine = parse(ply(red, "1 2 3 255").as_bytes()).unwrap();
    assert_eq!(fine.points, vec![[1.0, 2.0, 3.0]]);
    // Integer coordinates are integers too.
    let int_x = ply("", "1 2 3").replace("property float x", "property int x");
    assert!(parse(int_x.as_bytes()).is_ok());
    let err = parse(int_x.replace("\n1 2 3", "\n1.5 2 3").as_bytes()).unwrap_err();
    assert!(err.to_string().contains("column 1 (`x`)"), "{err}");
}

#[test]
fn nan_coordinates_are_rejected_with_the_position_or_skipped_on_request() {
    let mut points = sample_points();
    points[3][1] = f32::NAN;
    for (name, encode) in ENCODINGS {
        let bytes = encode(&points);
        let err = parse(&bytes).unwrap_err();
        let ParseError::NonFinite {
            point: 3,
            axis: 'y',
            at,
            ..
        } = err
        else {
            panic!("{name}: {err:?}");
        };
        if name.contains("ascii") {
            let header_lines = if name.starts_with("ply") { 8 } else { 11 };
            assert_eq!(at, Location::Line(header_lines + 4), "{name}");
        } else {
            let header = bytes.len() - 12 * points.len();
            assert_eq!(at, Location::Byte(header + 3 * 12), "{name}");
        }
        assert!(err.to_string().contains("point 3"), "{name}: {err}");
        let skip = LoadOptions {
            non_finite: NonFinitePolicy::Skip,
        };
        let cloud = parse_cloud(&bytes, skip).unwrap();
        assert_eq!(cloud.points.len(), points.len() - 1, "{name}");
        assert_eq!(cloud.skipped_non_finite, 1);
    }
}

#[test]
fn ply_skips_other_properties_lists_and_elements() {
    // A camera element before the vertices, extra vertex properties of every size, a list
    // inside the vertex, and faces after: binary little-endian, built by hand.
    let mut b = b"ply\nformat binary_little_endian 1.0\ncomment test\nelement camera 1\n\
        property list uchar int ids\nproperty double focal\nelement vertex 2\n\
        property uchar red\nproperty double x\nproperty short s\nproperty float y\n\
        property list uchar int idx\nproperty int z\nelement face 1\n\
        property list uchar int vertex_indices\nend_header\n"
        .to_vec();
    b.push(2);
    b.extend(7i32.to_le_bytes());
    b.extend(8i32.to_le_bytes());
    b.extend(1.5f64.to_le_bytes());
    for (i, (x, y, z)) in [(0.25f64, -1.5f32, 3i32), (10.0, 20.0, -4)]
        .into_iter()
        .enumerate()
    {
        b.push(200);
        b.extend(x.to_le_bytes());
        b.extend((-3i16).to_le_bytes());
        b.extend(y.to_le_bytes());
        b.push(i as u8);
        for k in 0..i {
            b.extend((k as i32).to_le_bytes());
        }
        b.extend(z.to_le_bytes());
    }
    b.push(3);
    for k in 0..3i32 {
        b.extend(k.to_le_bytes());
    }
    let cloud = parse(&b).unwrap();
    assert_eq!(cloud.points, vec![[0.25, -1.5, 3.0], [10.0, 20.0, -4.0]]);
    // One byte short inside the face list: truncation named at its byte offset.
    let err = parse(&b[..b.len() - 1]).unwrap_err();
    assert!(
        matches!(err, ParseError::Truncated { ref element, at: Location::Byte(_), .. } if element == "face"),
        "{err:?}"
    );

    let ascii = "ply\nformat ascii 1.0\nelement vertex 2\nproperty uchar red\nproperty float x\n\
                 property list uchar int idx\nproperty float y\nproperty float z\nelement face 1\n\
                 property list uchar int v\nend_header\n9 1.5 2 5 6 2.5 3.5\n\n9 -1 0 4 5\n3 0 1 2\n";
    let cloud = parse(ascii.as_bytes()).unwrap();
    assert_eq!(cloud.points, vec![[1.5, 2.5, 3.5], [-1.0, 4.0, 5.0]]);
}

#[test]
fn pcd_skips_other_fields_of_any_size_and_count() {
    let header = "# .PCD v0.7\nVERSION 0.7\nFIELDS rgb x _ y z fpfh\nSIZE 4 8 1 4 2 4\n\
                  TYPE U F U F I F\nCOUNT 1 1 3 1 1 4\nWIDTH 2\nHEIGHT 1\n\
                  VIEWPOINT 1 2 3 1 0 0 0\nPOINTS 2\nDATA binary\n";
    let mut b = header.as_bytes().to_vec();
    for (x, y, z) in [(0.5f64, 1.5f32, 7i16), (-2.0, 0.0, -8)] {
        b.extend(0xffu32.to_le_bytes());
        b.extend(x.to_le_bytes());
        b.extend([1, 2, 3]);
        b.extend(y.to_le_bytes());
        b.extend(z.to_le_bytes());
        for k in 0..4 {
            b.extend((k as f32).to_le_bytes());
        }
    }
    let cloud = parse(&b).unwrap();
    assert_eq!(cloud.points, vec![[0.5, 1.5, 7.0], [-2.0, 0.0, -8.0]]);
    assert_eq!(cloud.viewpoint.unwrap().translation_m, [1.0, 2.0, 3.0]);

    let ascii = header.replace("DATA binary", "DATA ascii")
        + "1 0.5 1 2 3 1.5 7 0 1 2 3\n2 -2 1 2 3 0 -8 0 1 2 3\n";
    assert_eq!(parse(ascii.as_bytes()).unwrap().points, cloud.points);
    let short = header.replace("DATA binary", "DATA ascii") + "1 0.5 1 2 3 1.5 7 0 1 2\n";
    assert!(matches!(
        parse(short.as_bytes()).unwrap_err(),
        ParseError::WrongValueCount {
            found: 10,
            expected: 11,
            ..
        }
    ));
}

#[test]
fn huge_declared_counts_fail_before_allocating() {
    let ply = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nend_header\n0123456789ab",
        u64::MAX
    );
    let err = parse(ply.as_bytes()).unwrap_err();
    assert!(
        matches!(err, ParseError::CountExceedsData { available: 12, .. }),
        "{err:?}"
    );
    let ascii = ply
        .replace("binary_little_endian", "ascii")
        .replace("0123456789ab", "1 2 3\n");
    let err = parse(ascii.as_bytes()).unwrap_err();
    assert!(
        matches!(err, ParseError::Truncated { record: 1, .. }),
        "{err:?}"
    );
    let pcd =
        "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 4294967296\nHEIGHT 4294967295\nDATA binary\n";
    assert!(matches!(
        parse(pcd.as_bytes()).unwrap_err(),
        ParseError::CountExceedsData { .. }
    ));
    // A list element declaring 2^64 records of one byte each is bounded by the data too.
    let lists = "ply\nformat binary_little_endian 1.0\nelement junk 18446744073709551615\n\
                 property list uchar uchar v\nelement vertex 0\nproperty float x\nproperty float y\n\
                 property float z\nend_header\n\x00\x00";
    assert!(matches!(
        parse(lists.as_bytes()).unwrap_err(),
        ParseError::Truncated { record: 2, .. }
    ));
}

#[test]
fn header_errors_name_the_line_and_what_was_expected() {
    let cases: [(&str, &str); 9] = [
        (
            "ply\nformat ascii 2.0\nend_header\n",
            "line 2: expected format version 1.0",
        ),
        (
            "ply\nformat text 1.0\nend_header\n",
            "ascii, binary_little_endian",
        ),
        (
            "ply\nformat ascii 1.0\nproperty float x\nend_header\n",
            "line 3: expected an `element` line",
        ),
        (
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float64x x\nend_header\n",
            "line 4: expected a PLY type",
        ),
        (
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n",
            "no scalar `z` property",
        ),
        (
            "ply\nformat ascii 1.0\nelement vertex 1\n",
            "expected `end_header`",
        ),
        (
            "FIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n",
            "line 2: expected SIZE with 3 entries",
        ),
        (
            "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nPOINTS 3\nDATA ascii\n",
            "line 5: expected POINTS equal to WIDTH × HEIGHT = 2",
        ),
        (
            "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA binary_compressed\n",
            "not supported",
        ),
    ];
    for (text, expected) in cases {
        let msg = parse(text.as_bytes()).unwrap_err().to_string();
        assert!(msg.contains(expected), "{text:?}: {msg}");
    }
    assert!(matches!(
        parse(b"hello\n").unwrap_err(),
        ParseError::UnknownFormat { .. }
    ));
}

#[test]
fn load_path_names_the_file() {
    let dir = std::env::temp_dir().join(format!("mmt-cloud-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let good = dir.join("good.ply");
    std::fs::write(
        &good,
        encode_ply(&sample_points(), PlyEncoding::BinaryLittleEndian),
    )
    .unwrap();
    assert_eq!(
        load_path(&good, LoadOptions::default()).unwrap().points,
        sample_points()
    );
    let bad = dir.join("bad.pcd");
    std::fs::write(
        &bad,
        b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 nan\n",
    )
    .unwrap();
    let msg = load_path(&bad, LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("bad.pcd") && msg.contains("line 6") && msg.contains("z = NaN"),
        "{msg}"
    );
    let typed = dir.join("typed.ply");
    std::fs::write(
        &typed,
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
         property float z\nproperty uchar red\nend_header\n1 2 3 abc\n",
    )
    .unwrap();
    let msg = load_path(&typed, LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("typed.ply")
            && msg.contains("line 9, column 4 (`red`)")
            && msg.contains("\"abc\" is not a valid uint8"),
        "{msg}"
    );
    let missing = dir.join("missing.ply");
    let msg = load_path(&missing, LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(msg.contains("missing.ply"), "{msg}");
    std::fs::remove_dir_all(&dir).unwrap();
}

mod never_panic {
    use super::*;
    use proptest::prelude::*;

    fn valid_files() -> impl Strategy<Value = Vec<u8>> {
        (0usize..5, prop::collection::vec(any::<[f32; 3]>(), 0..8))
            .prop_map(|(which, points)| (ENCODINGS[which].1)(&points))
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]

        #[test]
        fn arbitrary_bytes(bytes in prop::collection::vec(any::<u8>(), 0..512)) {
            let _ = parse(&bytes);
            let _ = parse_ply(&bytes, LoadOptions::default());
            let _ = parse_pcd(&bytes, LoadOptions::default());
        }

        #[test]
        fn arbitrary_headers_with_plausible_words(
            words in prop::collection::vec(prop::sample::select(vec![
                "ply", "format", "ascii", "binary_little_endian", "1.0", "element", "vertex",
                "property", "list", "uchar", "float", "double", "int", "x", "y", "z", "end_header",
                "FIELDS", "SIZE", "TYPE", "COUNT", "WIDTH", "HEIGHT", "POINTS", "DATA", "binary",
                "F", "U", "I", "4", "8", "1", "0", "3", "99999999999", "\n", "\n", "\n", "nan",
            ]), 0..60),
            tail in prop::collection::vec(any::<u8>(), 0..64),
        ) {
            let mut bytes = words.join(" ").into_bytes();
            bytes.extend(tail);
            let _ = parse(&bytes);
            let _ = parse_ply(&bytes, LoadOptions::default());
            let _ = parse_pcd(&bytes, LoadOptions::default());
        }

        #[test]
        fn corrupted_valid_files(
            file in valid_files(),
            flips in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..4),
            cut in any::<prop::sample::Index>(),
        ) {
            let mut bytes = file;
            if !bytes.is_empty() {
                for (at, value) in flips {
                    let i = at.index(bytes.len());
                    bytes[i] = value;
                }
                bytes.truncate(cut.index(bytes.len() + 1));
            }
            let _ = parse(&bytes);
        }
    }
}
