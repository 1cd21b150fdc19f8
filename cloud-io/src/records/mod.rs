//! The record layer shared by PLY and PCD: scalar types, record layouts, and the readers for
//! binary and ASCII data. Headers are parsed by `ply.rs` and `pcd.rs` into an [`Element`].

use std::fmt::Write as _;

use super::{Format, LoadOptions, LoadedCloud, Location, NonFinitePolicy, ParseError};
use mmt::cloud::{CloudFrame, Pose};

mod ascii;
mod binary;
mod scalar;

pub(super) use scalar::Scalar;

/// One property (PLY) or field (PCD) of a record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Field {
    /// One value.
    Scalar(Scalar),
    /// A fixed number of values (PCD `COUNT` > 1).
    Array(Scalar, usize),
    /// A length, then that many values (PLY `property list`).
    List { count: Scalar, item: Scalar },
}

/// A block of records of the same layout: a PLY element or the PCD points.
#[derive(Clone, Debug)]
pub(super) struct Element {
    pub name: String,
    pub count: u64,
    pub fields: Vec<Field>,
    /// The name of each field (for errors).
    pub names: Vec<String>,
    /// Indices into `fields` of the scalar `x`, `y`, `z`, for the element holding the points.
    pub xyz: Option<[usize; 3]>,
}

/// Where the points go.
#[derive(Debug, Default)]
struct Sink {
    points: Vec<[f32; 3]>,
    skipped_non_finite: usize,
}

/// Reading context: which format, what to do with NaN.
#[derive(Clone, Copy, Debug)]
pub(super) struct Ctx {
    pub format: Format,
    pub policy: NonFinitePolicy,
}

impl Ctx {
    pub(super) fn new(format: Format, options: LoadOptions) -> Self {
        Self {
            format,
            policy: options.non_finite,
        }
    }
}

/// How the data after the header is encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Data {
    /// Text, one record per line.
    Ascii,
    /// Packed records.
    Binary { big_endian: bool },
}

/// Reads every element's records after the header (`lines` stands just after it), keeps the
/// points of the element with `xyz`, and checks that nothing follows the last record.
pub(super) fn read_data(
    bytes: &[u8],
    mut lines: Lines<'_>,
    elements: &[Element],
    data: Data,
    ctx: Ctx,
    viewpoint: Option<Pose>,
) -> Result<LoadedCloud, ParseError> {
    let mut sink = Sink::default();
    let last_count = elements.last().map_or(0, |e| e.count);
    match data {
        Data::Ascii => {
            for el in elements {
                ascii::read_ascii(&mut lines, el, ctx, &mut sink)?;
            }
            ascii::expect_ascii_end(&mut lines, ctx, last_count)?;
        }
        Data::Binary { big_endian } => {
            let mut pos = lines.pos;
            for el in elements {
                binary::read_binary(bytes, &mut pos, el, big_endian, ctx, &mut sink)?;
            }
            binary::expect_binary_end(bytes, pos, ctx, last_count)?;
        }
    }
    Ok(LoadedCloud {
        points: sink.points,
        skipped_non_finite: sink.skipped_non_finite,
        viewpoint,
    })
}

/// Indices in `fields` of the scalar fields named `x`, `y`, `z`.
pub(super) fn find_xyz<S: AsRef<str>>(
    format: Format,
    names: &[S],
    fields: &[Field],
) -> Result<[usize; 3], ParseError> {
    let mut xyz = [0usize; 3];
    for (slot, axis) in xyz.iter_mut().zip(['x', 'y', 'z']) {
        *slot = names
            .iter()
            .zip(fields)
            .position(|(name, f)| {
                let name = name.as_ref();
                name.len() == 1 && name.starts_with(axis) && matches!(f, Field::Scalar(_))
            })
            .ok_or(ParseError::MissingCoordinate { format, axis })?;
    }
    Ok(xyz)
}

/// A header error at a 1-based line, quoting at most 60 bytes of what was found.
pub(super) fn header_error(
    format: Format,
    line: usize,
    expected: &str,
    found: &[u8],
) -> ParseError {
    let shown = &found[..found.len().min(60)];
    ParseError::Header {
        format,
        at: Location::Line(line),
        expected: expected.to_owned(),
        found: String::from_utf8_lossy(shown).into_owned(),
    }
}

/// Appends `points` as `x y z` text lines or packed `f32` triples.
pub(super) fn write_points(out: &mut Vec<u8>, points: &[[f32; 3]], data: Data) {
    match data {
        Data::Ascii => {
            let mut text = String::with_capacity(points.len() * 30);
            for p in points {
                // Writing to a String cannot fail.
                let _ = writeln!(text, "{} {} {}", p[0], p[1], p[2]);
            }
            out.extend_from_slice(text.as_bytes());
        }
        Data::Binary { big_endian: false } => {
            out.extend(points.iter().flatten().flat_map(|c| c.to_le_bytes()));
        }
        Data::Binary { big_endian: true } => {
            out.extend(points.iter().flatten().flat_map(|c| c.to_be_bytes()));
        }
    }
}

impl Element {
    /// Bytes per record when no field is a list.
    fn fixed_size(&self) -> Option<usize> {
        self.fields.iter().try_fold(0usize, |acc, f| match *f {
            Field::Scalar(s) => acc.checked_add(s.size()),
            Field::Array(s, n) => acc.checked_add(s.size().checked_mul(n)?),
            Field::List { .. } => None,
        })
    }

    fn truncated(&self, ctx: Ctx, at: Location, record: u64, expected: String) -> ParseError {
        ParseError::Truncated {
            format: ctx.format,
            at,
            element: self.name.clone(),
            record,
            declared: self.count,
            expected,
        }
    }
}

/// Text lines of a file: 1-based number, start offset, content without `\n`/`\r\n`.
#[derive(Clone, Debug)]
pub(super) struct Lines<'a> {
    bytes: &'a [u8],
    pub pos: usize,
    pub line: usize,
}

impl<'a> Lines<'a> {
    pub(super) fn new(bytes: &'a [u8]) -> Self {
        Self {
            bytes,
            pos: 0,
            line: 0,
        }
    }

    /// The next non-blank line.
    fn next_nonblank(&mut self) -> Option<(usize, &'a [u8])> {
        self.by_ref().find(|(_, l)| !l.trim_ascii().is_empty())
    }
}

impl<'a> Iterator for Lines<'a> {
    type Item = (usize, &'a [u8]);

    fn next(&mut self) -> Option<Self::Item> {
        let rest = self.bytes.get(self.pos..).filter(|r| !r.is_empty())?;
        let (line, advance) = match rest.iter().position(|&b| b == b'\n') {
            Some(i) => (&rest[..i], i + 1),
            None => (rest, rest.len()),
        };
        self.pos += advance;
        self.line += 1;
        Some((self.line, line.strip_suffix(b"\r").unwrap_or(line)))
    }
}

/// Checks a point's coordinates and stores it (or counts it as skipped).
fn push_point(
    ctx: Ctx,
    at: Location,
    point: u64,
    p: [f64; 3],
    sink: &mut Sink,
) -> Result<(), ParseError> {
    let limit = f64::from(CloudFrame::MAX_ABS_COORDINATE_M);
    for (&value, axis) in p.iter().zip(['x', 'y', 'z']) {
        if !value.is_finite() {
            if ctx.policy == NonFinitePolicy::Skip {
                sink.skipped_non_finite += 1;
                return Ok(());
            }
            return Err(ParseError::NonFinite {
                format: ctx.format,
                at,
                point,
                axis,
                value,
            });
        }
        if value.abs() > limit {
            return Err(ParseError::OutOfRange {
                format: ctx.format,
                at,
                point,
                axis,
                value,
                limit,
            });
        }
    }
    sink.points.push(p.map(|v| v as f32));
    Ok(())
}
