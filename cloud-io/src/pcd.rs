//! PCD (Point Cloud Library, v0.7): header parser, data readers, writer.
//!
//! Reads the `x`, `y`, `z` fields (`COUNT 1`, any `TYPE`/`SIZE`); other fields are skipped by
//! their `SIZE × COUNT` (in `DATA ascii`, after checking every value against its `TYPE`/`SIZE`). `DATA ascii` and `DATA binary` (little-endian, as PCL writes it) are
//! read; `binary_compressed` is refused with a clear error. `VIEWPOINT` becomes
//! [`LoadedCloud::viewpoint`].

use std::fmt::Write as _;

use super::records::{self, Ctx, Data, Element, Field, Lines, Scalar};
use super::{Format, LoadOptions, LoadedCloud, Location, ParseError};
use mmt::cloud::Pose;

/// PCD data encodings this crate writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PcdEncoding {
    /// `DATA ascii`.
    Ascii,
    /// `DATA binary` (little-endian records).
    Binary,
}

/// Parses a PCD file's bytes.
pub fn parse_pcd(bytes: &[u8], options: LoadOptions) -> Result<LoadedCloud, ParseError> {
    let ctx = Ctx::new(Format::Pcd, options);
    let mut lines = Lines::new(bytes);
    let header = parse_header(&mut lines)?;
    let elements = std::slice::from_ref(&header.points);
    records::read_data(bytes, lines, elements, header.data, ctx, header.viewpoint)
}

/// Writes `points` as a PCD v0.7 file with `F 4` x, y, z, one row (`HEIGHT 1`).
pub fn encode_pcd(points: &[[f32; 3]], encoding: PcdEncoding) -> Vec<u8> {
    let (keyword, data) = match encoding {
        PcdEncoding::Ascii => ("ascii", Data::Ascii),
        PcdEncoding::Binary => ("binary", Data::Binary { big_endian: false }),
    };
    let n = points.len();
    let mut header = String::new();
    // Writing to a String cannot fail.
    let _ = write!(
        header,
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\n\
         TYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\n\
         DATA {keyword}\n"
    );
    let mut out = header.into_bytes();
    records::write_points(&mut out, points, data);
    out
}

struct Header {
    points: Element,
    data: Data,
    viewpoint: Option<Pose>,
}

fn header_error(at: usize, expected: &str, found: &[u8]) -> ParseError {
    records::header_error(Format::Pcd, at, expected, found)
}

/// The header lines seen, with their line numbers (for errors that span lines).
#[derive(Default)]
struct Seen<'a> {
    fields: Option<(usize, Vec<&'a str>)>,
    size: Option<(usize, Vec<&'a str>)>,
    ty: Option<(usize, Vec<&'a str>)>,
    count: Option<(usize, Vec<&'a str>)>,
    width: Option<u64>,
    height: Option<u64>,
    points: Option<(usize, u64)>,
    viewpoint: Option<Pose>,
}

fn parse_header(lines: &mut Lines<'_>) -> Result<Header, ParseError> {
    let mut seen = Seen::default();
    let (data_line, data) = loop {
        let Some((n, raw)) = lines.next() else {
            return Err(header_error(
                lines.line + 1,
                "a `DATA` line",
                b"end of file",
            ));
        };
        let line =
            std::str::from_utf8(raw).map_err(|_| header_error(n, "ASCII header text", raw))?;
        let mut words = line.split_ascii_whitespace();
        let Some(key) = words.next() else { continue };
        if key.starts_with('#') {
            continue;
        }
        let rest: Vec<&str> = words.collect();
        let single_u64 = |what: &str| -> Result<u64, ParseError> {
            match rest.as_slice() {
                [v] => v.parse().map_err(|_| header_error(n, what, raw)),
                _ => Err(header_error(n, what, raw)),
            }
        };
        match key {
            "VERSION" => {}
            "FIELDS" => seen.fields = Some((n, rest)),
            "SIZE" => seen.size = Some((n, rest)),
            "TYPE" => seen.ty = Some((n, rest)),
            "COUNT" => seen.count = Some((n, rest)),
            "WIDTH" => seen.width = Some(single_u64("WIDTH <integer >= 0>")?),
            "HEIGHT" => seen.height = Some(single_u64("HEIGHT <integer >= 0>")?),
            "POINTS" => seen.points = Some((n, single_u64("POINTS <integer >= 0>")?)),
            "VIEWPOINT" => {
                let v: Vec<f64> = rest.iter().filter_map(|w| w.parse().ok()).collect();
                let expected = "VIEWPOINT tx ty tz qw qx qy qz (7 numbers, non-zero quaternion)";
                let [tx, ty, tz, qw, qx, qy, qz] = v.as_slice() else {
                    return Err(header_error(n, expected, raw));
                };
                let pose = Pose::from_quaternion([*qw, *qx, *qy, *qz], [*tx, *ty, *tz])
                    .filter(|p| p.is_finite())
                    .ok_or_else(|| header_error(n, expected, raw))?;
                seen.viewpoint = Some(pose);
            }
            "DATA" => match rest.as_slice() {
                ["ascii"] => break (n, Data::Ascii),
                ["binary"] => break (n, Data::Binary { big_endian: false }),
                ["binary_compressed"] => {
                    return Err(ParseError::Unsupported {
                        format: Format::Pcd,
                        at: Location::Line(n),
                        what: "DATA binary_compressed".into(),
                    });
                }
                _ => return Err(header_error(n, "DATA ascii or DATA binary", raw)),
            },
            _ => {
                return Err(header_error(
                    n,
                    "VERSION, FIELDS, SIZE, TYPE, COUNT, WIDTH, HEIGHT, VIEWPOINT, POINTS or DATA",
                    raw,
                ));
            }
        }
    };
    let points = points_element(&seen, data_line)?;
    Ok(Header {
        points,
        data,
        viewpoint: seen.viewpoint,
    })
}

fn points_element(seen: &Seen<'_>, data_line: usize) -> Result<Element, ParseError> {
    let Some((fields_line, names)) = &seen.fields else {
        return Err(header_error(
            data_line,
            "a FIELDS line before DATA",
            b"DATA",
        ));
    };
    let fields = fields(seen, names, data_line)?;
    let xyz = records::find_xyz(Format::Pcd, names, &fields)?;
    let count = point_count(seen, *fields_line, data_line)?;
    Ok(Element {
        name: "points".into(),
        count,
        fields,
        names: names.iter().map(|n| (*n).to_owned()).collect(),
        xyz: Some(xyz),
    })
}

/// The layout of a point: one field per name, typed by its `TYPE`/`SIZE` and `COUNT` entries.
fn fields(seen: &Seen<'_>, names: &[&str], data_line: usize) -> Result<Vec<Field>, ParseError> {
    let (size_line, sizes) = per_field(&seen.size, "SIZE", names.len(), data_line)?;
    let (type_line, types) = per_field(&seen.ty, "TYPE", names.len(), data_line)?;
    let (count_line, counts) = match &seen.count {
        None => (data_line, vec!["1".to_owned(); names.len()]),
        Some(_) => per_field(&seen.count, "COUNT", names.len(), data_line)?,
    };
    let mut fields = Vec::with_capacity(names.len());
    for ((size, ty), count) in sizes.iter().zip(&types).zip(&counts) {
        let scalar = scalar_type(ty, size).ok_or_else(|| {
            let line = if matches!(ty.as_str(), "I" | "U" | "F") {
                size_line
            } else {
                type_line
            };
            header_error(
                line,
                "TYPE I or U with SIZE 1, 2, 4 or 8, or TYPE F with SIZE 4 or 8",
                format!("TYPE {ty} SIZE {size}").as_bytes(),
            )
        })?;
        let count: usize = count.parse().ok().filter(|&c| c >= 1).ok_or_else(|| {
            header_error(
                count_line,
                "COUNT entries (integers >= 1)",
                count.as_bytes(),
            )
        })?;
        fields.push(if count == 1 {
            Field::Scalar(scalar)
        } else {
            Field::Array(scalar, count)
        });
    }
    Ok(fields)
}

/// The entries of a `SIZE`, `TYPE` or `COUNT` line (`key`), one per field, with the line's
/// number.
fn per_field(
    entry: &Option<(usize, Vec<&str>)>,
    key: &str,
    fields: usize,
    data_line: usize,
) -> Result<(usize, Vec<String>), ParseError> {
    match entry {
        Some((line, v)) if v.len() == fields => {
            Ok((*line, v.iter().map(|s| (*s).to_owned()).collect()))
        }
        Some((line, v)) => Err(header_error(
            *line,
            &format!("{key} with {fields} entries (one per field)"),
            v.join(" ").as_bytes(),
        )),
        None => Err(header_error(
            data_line,
            &format!("a {key} line before DATA"),
            b"DATA",
        )),
    }
}

/// The scalar type of a field of `TYPE` `ty` and `SIZE` `size`.
fn scalar_type(ty: &str, size: &str) -> Option<Scalar> {
    Some(match (ty, size) {
        ("I", "1") => Scalar::I8,
        ("I", "2") => Scalar::I16,
        ("I", "4") => Scalar::I32,
        ("I", "8") => Scalar::I64,
        ("U", "1") => Scalar::U8,
        ("U", "2") => Scalar::U16,
        ("U", "4") => Scalar::U32,
        ("U", "8") => Scalar::U64,
        ("F", "4") => Scalar::F32,
        ("F", "8") => Scalar::F64,
        _ => return None,
    })
}

/// The number of points, `WIDTH × HEIGHT` (`HEIGHT` 1 when absent), which `POINTS`, when
/// given, must equal.
fn point_count(seen: &Seen<'_>, fields_line: usize, data_line: usize) -> Result<u64, ParseError> {
    let width = seen
        .width
        .ok_or_else(|| header_error(data_line, "a WIDTH line before DATA", b"DATA"))?;
    let height = seen.height.unwrap_or(1);
    let count = width
        .checked_mul(height)
        .ok_or_else(|| header_error(fields_line, "WIDTH × HEIGHT within 64 bits", b"overflow"))?;
    if let Some((line, declared)) = seen.points
        && declared != count
    {
        return Err(header_error(
            line,
            &format!("POINTS equal to WIDTH × HEIGHT = {count}"),
            format!("POINTS {declared}").as_bytes(),
        ));
    }
    Ok(count)
}
