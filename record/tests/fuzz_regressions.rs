//! Findings of the fuzz campaign (`fuzz/README.md`), each with the input that found it, rebuilt
//! here byte by byte.
#![allow(clippy::unwrap_used)]

use std::path::PathBuf;

use record::read_bytes;

/// A real recording (the `mcap` target's empty seed: our header metadata, schemas, channels, the
/// runs' start and end) with `raw` bytes inserted just before its `DataEnd` record.
fn with_raw(raw: &[u8]) -> Vec<u8> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fuzz/seeds/mcap/empty.mcap");
    let file = std::fs::read(path).unwrap();
    // Top-level records from the 8-byte magic on: opcode u8, length u64 LE, content.
    let mut at = 8;
    while file[at] != 0x0F {
        let len = u64::from_le_bytes(file[at + 1..at + 9].try_into().unwrap());
        at += 9 + usize::try_from(len).unwrap();
    }
    let mut out = file[..at].to_vec();
    out.extend_from_slice(raw);
    out.extend_from_slice(&file[at..]);
    out
}

/// [`with_raw`] of a chunk record with `chunk` as its content.
fn with_chunk(chunk: &[u8]) -> Vec<u8> {
    let mut raw = vec![0x06];
    raw.extend_from_slice(&(chunk.len() as u64).to_le_bytes());
    raw.extend_from_slice(chunk);
    with_raw(&raw)
}

/// A chunk's content: times, uncompressed size, CRC 0 (not checked), compression, records.
fn chunk(uncompressed_size: u64, compression: &str, records: &[u8]) -> Vec<u8> {
    let mut c = Vec::new();
    c.extend_from_slice(&0u64.to_le_bytes());
    c.extend_from_slice(&0u64.to_le_bytes());
    c.extend_from_slice(&uncompressed_size.to_le_bytes());
    c.extend_from_slice(&0u32.to_le_bytes());
    c.extend_from_slice(&(compression.len() as u32).to_le_bytes());
    c.extend_from_slice(compression.as_bytes());
    c.extend_from_slice(&(records.len() as u64).to_le_bytes());
    c.extend_from_slice(records);
    c
}

/// A record header inside a chunk: a Message (opcode 5) declaring `len` bytes.
fn message_header(len: u64) -> Vec<u8> {
    let mut r = vec![0x05];
    r.extend_from_slice(&len.to_le_bytes());
    r
}

/// `content` as a zstd frame of one raw (stored) block: magic, a single-segment descriptor with
/// a 1-byte content size, a last-block header of type raw.
fn zstd_raw(content: &[u8]) -> Vec<u8> {
    assert!(content.len() < 256);
    let mut f = vec![0x28, 0xB5, 0x2F, 0xFD, 0x20, content.len() as u8];
    let block = 1 | (content.len() as u32) << 3;
    f.extend_from_slice(&block.to_le_bytes()[..3]);
    f.extend_from_slice(content);
    f
}

/// Found by `corrupted_seeds_never_panic` (`record/tests/fuzz_seeds.rs`): a damaged length of a
/// record inside a zstd chunk was trusted by `mcap::MessageStream`, which reserved it before
/// decompressing: "memory allocation of 3834031346506215745 bytes failed", an abort of `mmt
/// report` or of a replay on a damaged file. The reader now limits record lengths and reports
/// the file as damaged.
#[test]
fn a_huge_record_length_inside_a_zstd_chunk_is_damage_not_an_abort() {
    let inner = message_header(3_834_031_346_506_215_745);
    let bytes = with_chunk(&chunk(inner.len() as u64, "zstd", &zstd_raw(&inner)));
    let rec = read_bytes(&bytes, "damaged.mcap", &[]).unwrap();
    let why = rec.truncated.expect("reported as damaged");
    assert!(why.contains("length exceeds limit"), "{why}");
}

/// Found by the `mcap` fuzz target (after 810 inputs): a top-level record length near
/// `u64::MAX` overflowed `mcap`'s `OPCODE_LEN_SIZE + len` (a panic with overflow checks, a wrapped
/// length without). The same limit makes it damage.
#[test]
fn a_record_length_near_u64_max_is_damage_not_an_overflow() {
    let bytes = with_raw(&message_header(u64::MAX - 3));
    let rec = read_bytes(&bytes, "damaged.mcap", &[]).unwrap();
    let why = rec.truncated.expect("reported as damaged");
    assert!(why.contains("length exceeds limit"), "{why}");
}

/// The same inside an uncompressed chunk.
#[test]
fn a_record_length_near_u64_max_inside_a_chunk_is_damage_not_an_overflow() {
    let inner = message_header(u64::MAX - 3);
    let bytes = with_chunk(&chunk(inner.len() as u64, "", &inner));
    let rec = read_bytes(&bytes, "damaged.mcap", &[]).unwrap();
    let why = rec.truncated.expect("reported as damaged");
    assert!(why.contains("length exceeds limit"), "{why}");
}
