//! PLY (Stanford polygon format): header parser, data readers, writer.
//!
//! Reads the `x`, `y`, `z` scalar properties of the `vertex` element, of any PLY scalar type.
//! Other properties and other elements (faces, …) are skipped by their declared types, lists
//! included, and checked for truncation; in ASCII data (one record per line) every value is
//! checked against its declared type.

use std::fmt::Write as _;

use super::records::{self, Ctx, Data, Element, Field, Lines, Scalar};
use super::{Format, LoadOptions, LoadedCloud, ParseError};

/// PLY data encodings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlyEncoding {
    /// `format ascii 1.0`.
    Ascii,
    /// `format binary_little_endian 1.0`.
    BinaryLittleEndian,
    /// `format binary_big_endian 1.0`.
    BinaryBigEndian,
}

/// Parses a PLY file's bytes.
pub fn parse_ply(bytes: &[u8], options: LoadOptions) -> Result<LoadedCloud, ParseError> {
    let ctx = Ctx::new(Format::Ply, options);
    let mut lines = Lines::new(bytes);
    let (encoding, elements) = parse_header(&mut lines)?;
    records::read_data(bytes, lines, &elements, encoding.data(), ctx, None)
}

/// Writes `points` as a PLY file with `float` x, y, z.
pub fn encode_ply(points: &[[f32; 3]], encoding: PlyEncoding) -> Vec<u8> {
    let format = match encoding {
        PlyEncoding::Ascii => "ascii",
        PlyEncoding::BinaryLittleEndian => "binary_little_endian",
        PlyEncoding::BinaryBigEndian => "binary_big_endian",
    };
    let mut header = String::new();
    // Writing to a String cannot fail.
    let _ = write!(
        header,
        "ply\nformat {format} 1.0\ncomment written by mmt\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\nend_header\n",
        points.len()
    );
    let mut out = header.into_bytes();
    records::write_points(&mut out, points, encoding.data());
    out
}

impl PlyEncoding {
    fn data(self) -> Data {
        match self {
            PlyEncoding::Ascii => Data::Ascii,
            PlyEncoding::BinaryLittleEndian => Data::Binary { big_endian: false },
            PlyEncoding::BinaryBigEndian => Data::Binary { big_endian: true },
        }
    }
}

fn header_error(at: usize, expected: &str, found: &[u8]) -> ParseError {
    records::header_error(Format::Ply, at, expected, found)
}

fn scalar_type(name: &str) -> Option<Scalar> {
    Some(match name {
        "char" | "int8" => Scalar::I8,
        "uchar" | "uint8" => Scalar::U8,
        "short" | "int16" => Scalar::I16,
        "ushort" | "uint16" => Scalar::U16,
        "int" | "int32" => Scalar::I32,
        "uint" | "uint32" => Scalar::U32,
        "float" | "float32" => Scalar::F32,
        "double" | "float64" => Scalar::F64,
        _ => return None,
    })
}

const TYPE_NAMES: &str = "a PLY type (char, uchar, short, ushort, int, uint, float, double, \
                          int8 … float64)";

fn parse_header(lines: &mut Lines<'_>) -> Result<(PlyEncoding, Vec<Element>), ParseError> {
    match lines.next() {
        Some((_, b"ply")) => {}
        Some((n, other)) => return Err(header_error(n, "`ply`", other)),
        None => return Err(header_error(1, "`ply`", b"")),
    }
    let mut declared = Declared::default();
    loop {
        let Some((n, raw)) = lines.next() else {
            return Err(header_error(lines.line + 1, "`end_header`", b"end of file"));
        };
        let line =
            std::str::from_utf8(raw).map_err(|_| header_error(n, "ASCII header text", raw))?;
        let words: Vec<&str> = line.split_ascii_whitespace().collect();
        match words.as_slice() {
            ["end_header"] => break,
            [] | ["comment", ..] | ["obj_info", ..] => {}
            ["format", kind, version] => declared.encoding = Some(encoding(n, raw, kind, version)?),
            ["element", name, count] => declared.element(n, raw, name, count)?,
            ["property", "list", count, item, name] => {
                declared.list_property(n, raw, count, item, name)?;
            }
            ["property", ty, name] => declared.scalar_property(n, raw, ty, name)?,
            _ => {
                return Err(header_error(
                    n,
                    "format, comment, obj_info, element, property or end_header",
                    raw,
                ));
            }
        }
    }
    declared.finish(lines.line)
}

/// The encoding a `format <kind> <version>` line names.
fn encoding(n: usize, raw: &[u8], kind: &str, version: &str) -> Result<PlyEncoding, ParseError> {
    if version != "1.0" {
        return Err(header_error(n, "format version 1.0", raw));
    }
    Ok(match kind {
        "ascii" => PlyEncoding::Ascii,
        "binary_little_endian" => PlyEncoding::BinaryLittleEndian,
        "binary_big_endian" => PlyEncoding::BinaryBigEndian,
        _ => {
            return Err(header_error(
                n,
                "ascii, binary_little_endian or binary_big_endian",
                raw,
            ));
        }
    })
}

/// What the header lines read so far declared: the encoding, the elements and the names of
/// their properties.
#[derive(Default)]
struct Declared {
    encoding: Option<PlyEncoding>,
    elements: Vec<Element>,
    names: Vec<Vec<String>>,
}

impl Declared {
    /// An `element <name> <count>` line.
    fn element(&mut self, n: usize, raw: &[u8], name: &str, count: &str) -> Result<(), ParseError> {
        let count = count
            .parse::<u64>()
            .map_err(|_| header_error(n, "an element count (integer >= 0)", raw))?;
        self.elements.push(Element {
            name: name.to_owned(),
            count,
            fields: Vec::new(),
            names: Vec::new(),
            xyz: None,
        });
        self.names.push(Vec::new());
        Ok(())
    }

    /// A `property list <count type> <item type> <name>` line.
    fn list_property(
        &mut self,
        n: usize,
        raw: &[u8],
        count: &str,
        item: &str,
        name: &str,
    ) -> Result<(), ParseError> {
        let (el, el_names) = self.last_element(n, raw)?;
        let count = scalar_type(count)
            .filter(|s| !matches!(s, Scalar::F32 | Scalar::F64))
            .ok_or_else(|| header_error(n, "an integer list-length type", raw))?;
        let item = scalar_type(item).ok_or_else(|| header_error(n, TYPE_NAMES, raw))?;
        el.fields.push(Field::List { count, item });
        el_names.push(name.to_owned());
        Ok(())
    }

    /// A `property <type> <name>` line.
    fn scalar_property(
        &mut self,
        n: usize,
        raw: &[u8],
        ty: &str,
        name: &str,
    ) -> Result<(), ParseError> {
        let (el, el_names) = self.last_element(n, raw)?;
        let ty = scalar_type(ty).ok_or_else(|| header_error(n, TYPE_NAMES, raw))?;
        el.fields.push(Field::Scalar(ty));
        el_names.push(name.to_owned());
        Ok(())
    }

    /// The element a `property` line adds to, with its property names.
    fn last_element(
        &mut self,
        n: usize,
        raw: &[u8],
    ) -> Result<(&mut Element, &mut Vec<String>), ParseError> {
        let (Some(el), Some(el_names)) = (self.elements.last_mut(), self.names.last_mut()) else {
            return Err(header_error(n, "an `element` line before `property`", raw));
        };
        Ok((el, el_names))
    }

    /// At `end_header` (line `end_line`): the encoding, and the elements with the vertex
    /// element's `x`, `y`, `z` found.
    fn finish(self, end_line: usize) -> Result<(PlyEncoding, Vec<Element>), ParseError> {
        let Declared {
            encoding,
            mut elements,
            names,
        } = self;
        let Some(encoding) = encoding else {
            return Err(header_error(
                end_line,
                "a `format` line before `end_header`",
                b"end_header",
            ));
        };
        let Some(vertex) = elements.iter().position(|e| e.name == "vertex") else {
            return Err(header_error(
                end_line,
                "an `element vertex` before `end_header`",
                b"end_header",
            ));
        };
        let el = &mut elements[vertex];
        el.xyz = Some(records::find_xyz(Format::Ply, &names[vertex], &el.fields)?);
        for (el, names) in elements.iter_mut().zip(names) {
            el.names = names;
        }
        Ok((encoding, elements))
    }
}
