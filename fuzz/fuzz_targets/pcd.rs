//! Parses arbitrary bytes as PCD. Never a panic; an accepted cloud has finite in-range points
//! that make a `CloudFrame` and a finite viewpoint, both non-finite policies agree, and the points
//! survive a write and read in each PCD encoding bit for bit (`cloud_checks.rs`).
#![no_main]

#[path = "cloud_checks.rs"]
mod cloud_checks;

use cloud_io::{Format, PcdEncoding, encode_pcd, parse_pcd};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    cloud_checks::check(
        data,
        parse_pcd,
        cloud_io::detect(data) == Some(Format::Pcd),
        &[
            |p| encode_pcd(p, PcdEncoding::Ascii),
            |p| encode_pcd(p, PcdEncoding::Binary),
        ],
    );
});
