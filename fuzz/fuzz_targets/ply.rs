//! Parses arbitrary bytes as PLY. Never a panic; an accepted cloud has finite in-range points
//! that make a `CloudFrame`, both non-finite policies agree, and the points survive a write and
//! read in each PLY encoding bit for bit (`cloud_checks.rs`).
#![no_main]

#[path = "cloud_checks.rs"]
mod cloud_checks;

use cloud_io::{Format, PlyEncoding, encode_ply, parse_ply};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    cloud_checks::check(
        data,
        parse_ply,
        cloud_io::detect(data) == Some(Format::Ply),
        &[
            |p| encode_ply(p, PlyEncoding::Ascii),
            |p| encode_ply(p, PlyEncoding::BinaryLittleEndian),
            |p| encode_ply(p, PlyEncoding::BinaryBigEndian),
        ],
    );
});
