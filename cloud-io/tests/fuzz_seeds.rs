//! The fuzz seeds of the `ply` and `pcd` targets (`fuzz/seeds/{ply,pcd}/`), and the CI
//! equivalent of those targets: every seed, mutated (bytes overwritten, inserted, removed, the
//! file cut), is refused or read as finite in-range points, never a panic.
//!
//! The seeds are written by this file: `MMT_WRITE_FUZZ_SEEDS=1 cargo test -p cloud-io --test
//! fuzz_seeds` rewrites them; without it the test checks that the checked-in files are current.
#![allow(clippy::unwrap_used)]

use std::path::PathBuf;

use cloud_io::{
    LoadOptions, NonFinitePolicy, PcdEncoding, PlyEncoding, encode_pcd, encode_ply, parse_cloud,
};
use mmt::cloud::CloudFrame;
use proptest::prelude::*;
use proptest::sample::Index;

const POINTS: [[f32; 3]; 5] = [
    [0.0, 0.0, 0.0],
    [0.125, -0.25, 1.5],
    [-3.0e-3, 7.5, -0.0],
    [1.0e-7, -2.5e3, 0.333_333_34],
    [42.0, 0.5, -1.0],
];

/// A PLY in ASCII with colours, a double coordinate and a face list after the vertices.
const PLY_COLOUR_FACES: &str = "ply\nformat ascii 1.0\ncomment colour, normals and faces\n\
element vertex 4\nproperty double x\nproperty float y\nproperty float z\n\
property uchar red\nproperty uchar green\nproperty uchar blue\nproperty float intensity\n\
element face 2\nproperty list uchar int vertex_indices\nend_header\n\
0 0 0 255 0 0 0.5\n1 0 0 0 255 0 0.25\n0 1 0 0 0 255 1\n0 0 1.5 9 9 9 0\n\
3 0 1 2\n3 0 2 3\n";

/// A PCD in ASCII, organised 2 × 2 with a packed colour and one NaN hole.
const PCD_ORGANISED: &str = "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n\
FIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\nWIDTH 2\nHEIGHT 2\n\
VIEWPOINT 0.1 0.2 0.3 1 0 0 0\nPOINTS 4\nDATA ascii\n\
0.1 0.2 0.3 4278190080\nnan nan nan 0\n-0.5 0.25 1 16777215\n2 -2 0.001 65280\n";

/// A binary PLY (little-endian) with integer coordinates' neighbours: a uchar list per vertex.
fn ply_binary_list() -> Vec<u8> {
    let mut out = b"ply\nformat binary_little_endian 1.0\nelement vertex 2\n\
property float x\nproperty float y\nproperty float z\n\
property list uchar ushort neighbours\nelement edge 1\nproperty int a\nproperty int b\n\
end_header\n"
        .to_vec();
    for (p, neighbours) in [
        ([0.5f32, -1.0, 2.0], &[1u16][..]),
        ([1.0, 1.0, 1.0], &[0, 0]),
    ] {
        for c in p {
            out.extend_from_slice(&c.to_le_bytes());
        }
        out.push(neighbours.len() as u8);
        for n in neighbours {
            out.extend_from_slice(&n.to_le_bytes());
        }
    }
    out.extend_from_slice(&0i32.to_le_bytes());
    out.extend_from_slice(&1i32.to_le_bytes());
    out
}

/// A binary PCD with double coordinates and a 3-float normal (`COUNT 3`).
fn pcd_binary_normals() -> Vec<u8> {
    let mut out = b"VERSION 0.7\nFIELDS x y z normal\nSIZE 8 8 8 4\nTYPE F F F F\n\
COUNT 1 1 1 3\nWIDTH 2\nPOINTS 2\nDATA binary\n"
        .to_vec();
    for (p, n) in [
        ([0.5f64, -1.0, 2.0], [0.0f32, 0.0, 1.0]),
        ([-4.0, 3.0, 0.0], [1.0, 0.0, 0.0]),
    ] {
        for c in p {
            out.extend_from_slice(&c.to_le_bytes());
        }
        for c in n {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    out
}

fn seeds() -> Vec<(&'static str, Vec<u8>)> {
    vec![
        ("ply/ascii.ply", encode_ply(&POINTS, PlyEncoding::Ascii)),
        (
            "ply/binary_le.ply",
            encode_ply(&POINTS, PlyEncoding::BinaryLittleEndian),
        ),
        (
            "ply/binary_be.ply",
            encode_ply(&POINTS, PlyEncoding::BinaryBigEndian),
        ),
        ("ply/empty.ply", encode_ply(&[], PlyEncoding::Ascii)),
        ("ply/colour_faces.ply", PLY_COLOUR_FACES.as_bytes().to_vec()),
        ("ply/binary_list.ply", ply_binary_list()),
        ("pcd/ascii.pcd", encode_pcd(&POINTS, PcdEncoding::Ascii)),
        ("pcd/binary.pcd", encode_pcd(&POINTS, PcdEncoding::Binary)),
        ("pcd/empty.pcd", encode_pcd(&[], PcdEncoding::Binary)),
        ("pcd/organised.pcd", PCD_ORGANISED.as_bytes().to_vec()),
        ("pcd/binary_normals.pcd", pcd_binary_normals()),
    ]
}

fn seed_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fuzz/seeds")
}

const SKIP: LoadOptions = LoadOptions {
    non_finite: NonFinitePolicy::Skip,
};

#[test]
fn every_seed_reads_and_is_checked_in() {
    let write = std::env::var_os("MMT_WRITE_FUZZ_SEEDS").is_some();
    for (name, bytes) in seeds() {
        let cloud = parse_cloud(&bytes, SKIP).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(cloud.points.len() <= POINTS.len(), "{name}");
        let path = seed_dir().join(name);
        if write {
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(&path, &bytes).unwrap();
        }
        let on_disk = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert!(
            on_disk == bytes,
            "{name} is stale: rerun with MMT_WRITE_FUZZ_SEEDS=1"
        );
    }
}

/// What the fuzz targets check of an accepted cloud, short of the round trips.
fn check(bytes: &[u8]) -> Result<(), TestCaseError> {
    let reject = parse_cloud(bytes, LoadOptions::default());
    let skip = parse_cloud(bytes, SKIP);
    if let Ok(cloud) = &reject {
        prop_assert_eq!(skip.as_ref(), Ok(cloud));
    }
    if let Ok(cloud) = skip {
        let limit = CloudFrame::MAX_ABS_COORDINATE_M;
        for p in &cloud.points {
            prop_assert!(
                p.iter().all(|c| c.is_finite() && c.abs() <= limit),
                "{:?}",
                p
            );
        }
    }
    Ok(())
}

/// One edit of a file: overwrite, insert or remove a byte at a position.
#[derive(Clone, Debug)]
enum Edit {
    Set(Index, u8),
    Insert(Index, u8),
    Remove(Index),
}

fn edit() -> impl Strategy<Value = Edit> {
    // Bytes that matter to the parsers more often than chance would give them.
    let byte = prop_oneof![
        any::<u8>(),
        prop::sample::select(b"0123456789 \n\r-.eEnaif+x".to_vec()),
    ];
    prop_oneof![
        (any::<Index>(), byte.clone()).prop_map(|(i, b)| Edit::Set(i, b)),
        (any::<Index>(), byte).prop_map(|(i, b)| Edit::Insert(i, b)),
        any::<Index>().prop_map(Edit::Remove),
    ]
}

fn apply(mut bytes: Vec<u8>, edits: &[Edit], cut: Option<Index>) -> Vec<u8> {
    for e in edits {
        match e {
            Edit::Set(i, b) if !bytes.is_empty() => {
                let at = i.index(bytes.len());
                bytes[at] = *b;
            }
            Edit::Insert(i, b) => bytes.insert(i.index(bytes.len() + 1), *b),
            Edit::Remove(i) if !bytes.is_empty() => {
                bytes.remove(i.index(bytes.len()));
            }
            _ => {}
        }
    }
    if let Some(c) = cut {
        bytes.truncate(c.index(bytes.len() + 1));
    }
    bytes
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1024))]

    #[test]
    fn mutated_seeds_never_panic(
        which in any::<Index>(),
        edits in prop::collection::vec(edit(), 1..8),
        cut in prop::option::of(any::<Index>()),
    ) {
        let all = seeds();
        let (_, seed) = &all[which.index(all.len())];
        check(&apply(seed.clone(), &edits, cut))?;
    }
}
