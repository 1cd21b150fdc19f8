//! # cloud-io — point clouds from files: PLY, PCD and voxel downsampling
//!
//! What it is: readers and writers of PLY (ASCII, binary little- and big-endian) and PCD (ASCII,
//! binary) point clouds, and voxel-grid downsampling ([`voxel`]). What it is not: no contact
//! logic (that is `mmt::contact`; [`budget`] only voxel-downsamples a cloud to its real-time
//! budget), no camera (the `sim` crate simulates one); the only file
//! system access is [`load_path`].
//!
//!
//! The parsers work on bytes (`&[u8]`, or anything `Read` through [`read_cloud`]) and read the
//! `x`, `y`, `z` of every point; every other property is skipped by its declared type and size
//! (PLY lists, PCD fields of any `SIZE`/`COUNT`) — in text data after checking that it parses
//! as that type (integers in range, floats that parse). Nothing in a file can make them panic or
//! allocate beyond the file's own size: a declared count is checked against the bytes that follow
//! before anything is reserved. Every error names where (line for text, byte offset for binary
//! data) and what was expected; [`load_path`] — the one function here that touches the file
//! system — adds the file name.
//!
//! Writers ([`encode_ply`], [`encode_pcd`]) produce files of the same formats, for recordings and
//! round trips.

pub mod budget;
mod pcd;
mod ply;
mod records;
#[cfg(test)]
mod tests;
pub mod voxel;

pub use pcd::{PcdEncoding, encode_pcd, parse_pcd};
pub use ply::{PlyEncoding, encode_ply, parse_ply};

use std::fmt;
use std::io::Read;
use std::path::{Path, PathBuf};

use thiserror::Error;

use mmt::cloud::Pose;

/// The two file formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Stanford PLY.
    Ply,
    /// Point Cloud Library PCD (v0.7).
    Pcd,
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Format::Ply => "PLY",
            Format::Pcd => "PCD",
        })
    }
}

/// Where in a file something was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Location {
    /// A 1-based line number (headers, ASCII data).
    Line(usize),
    /// A 0-based byte offset from the start of the file (binary data).
    Byte(usize),
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(n) => write!(f, "line {n}"),
            Location::Byte(n) => write!(f, "byte {n}"),
        }
    }
}

/// What to do with a point whose coordinates are NaN or infinite.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum NonFinitePolicy {
    /// Refuse the file, naming the point (the default: a NaN is usually a bug).
    #[default]
    Reject,
    /// Leave the point out and count it (organised depth clouds mark missing pixels with NaN).
    Skip,
}

/// Options for the parsers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoadOptions {
    /// NaN/infinite coordinates: reject (default) or skip.
    pub non_finite: NonFinitePolicy,
}

/// The points read from a file.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadedCloud {
    /// `x, y, z` of each point [file units, normally m], in file order.
    pub points: Vec<[f32; 3]>,
    /// Points left out because a coordinate was not finite ([`NonFinitePolicy::Skip`]).
    pub skipped_non_finite: usize,
    /// The acquisition viewpoint (PCD `VIEWPOINT`), if the file gives one.
    pub viewpoint: Option<Pose>,
}

/// Why bytes are not a readable point cloud.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ParseError {
    /// The header is malformed at this line.
    #[error("{format} header {at}: expected {expected}, found {found:?}")]
    Header {
        /// File format.
        format: Format,
        /// Where.
        at: Location,
        /// What the format requires here.
        expected: String,
        /// What the file has.
        found: String,
    },
    /// The file uses a feature this reader does not implement.
    #[error("{format} {at}: {what} is not supported")]
    Unsupported {
        /// File format.
        format: Format,
        /// Where.
        at: Location,
        /// The feature.
        what: String,
    },
    /// The points have no `x`, `y` or `z` scalar property.
    #[error("{format} header: no scalar `{axis}` property, expected x, y and z")]
    MissingCoordinate {
        /// File format.
        format: Format,
        /// The missing axis.
        axis: char,
    },
    /// The declared number of fixed-size records cannot fit in the data that follows the
    /// header.
    #[error(
        "{format} {at}: data ends in {element} record {record}: the header declares {declared} \
         records of {record_bytes} bytes ({needed} bytes), but only {available} bytes of data \
         follow"
    )]
    CountExceedsData {
        /// File format.
        format: Format,
        /// Start of the first incomplete record.
        at: Location,
        /// The element (`vertex`, `points`, …).
        element: String,
        /// 0-based index of the first incomplete record.
        record: u64,
        /// Records declared.
        declared: u64,
        /// Bytes per record.
        record_bytes: usize,
        /// Bytes the declaration needs.
        needed: u128,
        /// Bytes present.
        available: usize,
    },
    /// The data ends before the declared number of records.
    #[error(
        "{format} {at}: data ends in {element} record {record} of {declared}, expected {expected}"
    )]
    Truncated {
        /// File format.
        format: Format,
        /// Where the data ran out.
        at: Location,
        /// The element (`vertex`, `points`, …).
        element: String,
        /// 0-based index of the incomplete record.
        record: u64,
        /// Records declared.
        declared: u64,
        /// What was still expected.
        expected: String,
    },
    /// More data follows the last declared record.
    #[error(
        "{format} {at}: data continues after the {declared} declared records, expected end of file"
    )]
    TrailingData {
        /// File format.
        format: Format,
        /// Where the extra data starts.
        at: Location,
        /// Records declared (of the last element).
        declared: u64,
    },
    /// A text record has the wrong number of values.
    #[error("{format} {at}: {element} record {record} has {found} values, expected {expected}")]
    WrongValueCount {
        /// File format.
        format: Format,
        /// Where.
        at: Location,
        /// The element.
        element: String,
        /// 0-based record index.
        record: u64,
        /// Values found.
        found: usize,
        /// Values expected.
        expected: usize,
    },
    /// A value is not a number of its declared type.
    #[error(
        "{format} {at}, column {column} (`{property}`): {element} record {record}: {found:?} is \
         not a valid {expected}"
    )]
    NotANumber {
        /// File format.
        format: Format,
        /// Where.
        at: Location,
        /// 1-based position of the value in its line.
        column: usize,
        /// The property (PLY) or field (PCD) it belongs to; `name[i]` for an array or list item,
        /// `name (list length)` for a list's length.
        property: String,
        /// The element.
        element: String,
        /// 0-based record index.
        record: u64,
        /// The text found.
        found: String,
        /// The expected type.
        expected: &'static str,
    },
    /// A coordinate is NaN or infinite (with [`NonFinitePolicy::Reject`]).
    #[error("{format} {at}: point {point}: {axis} = {value}, expected a finite number")]
    NonFinite {
        /// File format.
        format: Format,
        /// Where.
        at: Location,
        /// 0-based point index.
        point: u64,
        /// The axis.
        axis: char,
        /// The value.
        value: f64,
    },
    /// A coordinate is beyond [`mmt::cloud::CloudFrame::MAX_ABS_COORDINATE_M`].
    #[error("{format} {at}: point {point}: {axis} = {value}, expected |{axis}| <= {limit}")]
    OutOfRange {
        /// File format.
        format: Format,
        /// Where.
        at: Location,
        /// 0-based point index.
        point: u64,
        /// The axis.
        axis: char,
        /// The value.
        value: f64,
        /// The limit.
        limit: f64,
    },
    /// The bytes start like neither format.
    #[error("not a PLY or PCD file: expected `ply` or a PCD header on line 1, found {found:?}")]
    UnknownFormat {
        /// The start of the first line.
        found: String,
    },
}

/// A file that could not be loaded: the path and why.
#[derive(Debug, Error)]
pub enum LoadError {
    /// The file could not be read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file's content is not a valid cloud.
    #[error("{}: {source}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// What is wrong and where.
        source: Box<ParseError>,
    },
}

/// Parses PLY or PCD bytes, telling them apart by their first line.
pub fn parse_cloud(bytes: &[u8], options: LoadOptions) -> Result<LoadedCloud, ParseError> {
    match detect(bytes) {
        Some(Format::Ply) => parse_ply(bytes, options),
        Some(Format::Pcd) => parse_pcd(bytes, options),
        None => {
            let first = bytes.split(|&b| b == b'\n').next().unwrap_or_default();
            let shown = &first[..first.len().min(40)];
            Err(ParseError::UnknownFormat {
                found: String::from_utf8_lossy(shown).into_owned(),
            })
        }
    }
}

/// Reads everything from `reader`, then [`parse_cloud`]. I/O errors are returned as is.
pub fn read_cloud<R: Read>(
    mut reader: R,
    options: LoadOptions,
) -> std::io::Result<Result<LoadedCloud, ParseError>> {
    let mut bytes = Vec::new();
    reader.read_to_end(&mut bytes)?;
    Ok(parse_cloud(&bytes, options))
}

/// Reads a PLY or PCD file. The only function of this crate that opens a file; errors carry
/// the path.
pub fn load_path(path: &Path, options: LoadOptions) -> Result<LoadedCloud, LoadError> {
    let bytes = std::fs::read(path).map_err(|source| LoadError::Io {
        path: path.to_owned(),
        source,
    })?;
    parse_cloud(&bytes, options).map_err(|source| LoadError::Parse {
        path: path.to_owned(),
        source: Box::new(source),
    })
}

/// The format of `bytes` from its first line: `ply`, or a PCD comment/`VERSION`/`FIELDS` line.
pub fn detect(bytes: &[u8]) -> Option<Format> {
    let first = bytes.split(|&b| b == b'\n').next().unwrap_or_default();
    let first = first.strip_suffix(b"\r").unwrap_or(first);
    if first == b"ply" {
        Some(Format::Ply)
    } else if first.starts_with(b"#")
        || first.starts_with(b"VERSION")
        || first.starts_with(b"FIELDS")
    {
        Some(Format::Pcd)
    } else {
        None
    }
}
