//! The record layer shared by PLY and PCD: scalar types, record layouts, and the readers for
//! binary and ASCII data. Headers are parsed by `ply.rs` and `pcd.rs` into an [`Element`].

use std::fmt::Write as _;

use super::{Format, LoadOptions, LoadedCloud, Location, NonFinitePolicy, ParseError};
use mmt::cloud::{CloudFrame, Pose};

/// A scalar type of a property/field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl Scalar {
    pub(super) fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::I64 | Scalar::U64 | Scalar::F64 => 8,
        }
    }

    pub(super) fn name(self) -> &'static str {
        match self {
            Scalar::I8 => "int8",
            Scalar::U8 => "uint8",
            Scalar::I16 => "int16",
            Scalar::U16 => "uint16",
            Scalar::I32 => "int32",
            Scalar::U32 => "uint32",
            Scalar::I64 => "int64",
            Scalar::U64 => "uint64",
            Scalar::F32 => "float32",
            Scalar::F64 => "float64",
        }
    }

    /// Reads the value from the first `size()` bytes of `b` (the caller checked the length).
    fn read(self, b: &[u8], big_endian: bool) -> Option<f64> {
        macro_rules! get {
            ($t:ty, $n:literal) => {{
                let arr: [u8; $n] = b.get(..$n)?.try_into().ok()?;
                if big_endian {
                    <$t>::from_be_bytes(arr)
                } else {
                    <$t>::from_le_bytes(arr)
                }
            }};
        }
        Some(match self {
            Scalar::I8 => f64::from(get!(i8, 1)),
            Scalar::U8 => f64::from(get!(u8, 1)),
            Scalar::I16 => f64::from(get!(i16, 2)),
            Scalar::U16 => f64::from(get!(u16, 2)),
            Scalar::I32 => f64::from(get!(i32, 4)),
            Scalar::U32 => f64::from(get!(u32, 4)),
            Scalar::I64 => get!(i64, 8) as f64,
            Scalar::U64 => get!(u64, 8) as f64,
            Scalar::F32 => f64::from(get!(f32, 4)),
            Scalar::F64 => get!(f64, 8),
        })
    }

    /// Parses a text value of this type: an integer within the type's range, or for the float
    /// types any number `f64` parses (NaN and infinities included: the caller decides).
    fn parse_text(self, token: &[u8]) -> Option<f64> {
        let t = std::str::from_utf8(token).ok()?;
        match self {
            Scalar::I8 => t.parse::<i8>().ok().map(f64::from),
            Scalar::U8 => t.parse::<u8>().ok().map(f64::from),
            Scalar::I16 => t.parse::<i16>().ok().map(f64::from),
            Scalar::U16 => t.parse::<u16>().ok().map(f64::from),
            Scalar::I32 => t.parse::<i32>().ok().map(f64::from),
            Scalar::U32 => t.parse::<u32>().ok().map(f64::from),
            Scalar::I64 => t.parse::<i64>().ok().map(|v| v as f64),
            Scalar::U64 => t.parse::<u64>().ok().map(|v| v as f64),
            Scalar::F32 | Scalar::F64 => t.parse::<f64>().ok(),
        }
    }

    /// What a text value of this type must look like, for errors.
    fn text_expectation(self) -> &'static str {
        match self {
            Scalar::I8 => "int8 (an integer in -128 ..= 127)",
            Scalar::U8 => "uint8 (an integer in 0 ..= 255)",
            Scalar::I16 => "int16 (an integer in -32768 ..= 32767)",
            Scalar::U16 => "uint16 (an integer in 0 ..= 65535)",
            Scalar::I32 => "int32 (an integer in -2147483648 ..= 2147483647)",
            Scalar::U32 => "uint32 (an integer in 0 ..= 4294967295)",
            Scalar::I64 => "int64 (an integer in -9223372036854775808 ..= 9223372036854775807)",
            Scalar::U64 => "uint64 (an integer in 0 ..= 18446744073709551615)",
            Scalar::F32 => "float32 (a number)",
            Scalar::F64 => "float64 (a number)",
        }
    }

    /// What a list length of this type must look like, for errors.
    fn length_expectation(self) -> &'static str {
        match self {
            Scalar::I8 => "list length (an int8 >= 0)",
            Scalar::I16 => "list length (an int16 >= 0)",
            Scalar::I32 => "list length (an int32 >= 0)",
            Scalar::I64 => "list length (an int64 >= 0)",
            Scalar::U8 => "list length (a uint8: 0 ..= 255)",
            Scalar::U16 => "list length (a uint16: 0 ..= 65535)",
            Scalar::U32 => "list length (a uint32: 0 ..= 4294967295)",
            Scalar::U64 => "list length (a uint64 >= 0)",
            Scalar::F32 | Scalar::F64 => "list length (an integer >= 0)",
        }
    }

    /// Reads a list length: an integer type holding a value >= 0.
    fn read_count(self, b: &[u8], big_endian: bool) -> Option<u64> {
        if matches!(self, Scalar::F32 | Scalar::F64) {
            return None;
        }
        let v = self.read(b, big_endian)?;
        (v >= 0.0).then_some(v as u64)
    }
}

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
                read_ascii(&mut lines, el, ctx, &mut sink)?;
            }
            expect_ascii_end(&mut lines, ctx, last_count)?;
        }
        Data::Binary { big_endian } => {
            let mut pos = lines.pos;
            for el in elements {
                read_binary(bytes, &mut pos, el, big_endian, ctx, &mut sink)?;
            }
            expect_binary_end(bytes, pos, ctx, last_count)?;
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

/// Reads (or, without `xyz`, skips) the binary records of `el` starting at `*pos` of `bytes`;
/// advances `*pos` past them.
fn read_binary(
    bytes: &[u8],
    pos: &mut usize,
    el: &Element,
    big_endian: bool,
    ctx: Ctx,
    sink: &mut Sink,
) -> Result<(), ParseError> {
    let available = bytes.len().saturating_sub(*pos);
    if let Some(size) = el.fixed_size() {
        let needed = u128::from(el.count) * size as u128;
        if needed > available as u128 {
            // `size > 0` here (else nothing is needed); the first incomplete record starts
            // within the data, or right at its end.
            let whole = available / size;
            return Err(ParseError::CountExceedsData {
                format: ctx.format,
                at: Location::Byte(*pos + whole * size),
                element: el.name.clone(),
                record: whole as u64,
                declared: el.count,
                record_bytes: size,
                needed,
                available,
            });
        }
        // `needed <= available <= usize::MAX` from here on.
        let Some(xyz) = el.xyz else {
            *pos += needed as usize;
            return Ok(());
        };
        let offsets = field_offsets(&el.fields);
        let xyz_fields = xyz.map(|i| (offsets[i], field_scalar(el.fields[i])));
        sink.points.reserve(needed as usize / size.max(1));
        for record in 0..el.count {
            let start = *pos;
            let mut p = [0.0f64; 3];
            for (v, (off, scalar)) in p.iter_mut().zip(xyz_fields) {
                let field = bytes.get(start + off..).unwrap_or_default();
                *v = scalar.read(field, big_endian).ok_or_else(|| {
                    el.truncated(
                        ctx,
                        Location::Byte(start + off),
                        record,
                        scalar.name().into(),
                    )
                })?;
            }
            push_point(ctx, Location::Byte(start), record, p, sink)?;
            *pos += size;
        }
        return Ok(());
    }
    // Variable-size records (lists): every record takes at least one byte (a list length),
    // so the loop is bounded by the data, whatever the declared count.
    for record in 0..el.count {
        let start = *pos;
        let mut p = [0.0f64; 3];
        for (i, field) in el.fields.iter().enumerate() {
            let at = *pos;
            let rest = bytes.get(at..).unwrap_or_default();
            let len = match *field {
                Field::Scalar(s) => {
                    let v = s.read(rest, big_endian).ok_or_else(|| {
                        el.truncated(ctx, Location::Byte(at), record, s.name().into())
                    })?;
                    if let Some(axis) = el.xyz.and_then(|xyz| xyz.iter().position(|&j| j == i)) {
                        p[axis] = v;
                    }
                    s.size()
                }
                Field::Array(s, n) => s.size().saturating_mul(n),
                Field::List { count, item } => {
                    let n = count.read_count(rest, big_endian).ok_or_else(|| {
                        el.truncated(ctx, Location::Byte(at), record, "a list length".into())
                    })?;
                    let items = usize::try_from(n).unwrap_or(usize::MAX);
                    count
                        .size()
                        .saturating_add(item.size().saturating_mul(items))
                }
            };
            if len > rest.len() {
                return Err(el.truncated(
                    ctx,
                    Location::Byte(at),
                    record,
                    format!("{len} more bytes"),
                ));
            }
            *pos += len;
        }
        if el.xyz.is_some() {
            push_point(ctx, Location::Byte(start), record, p, sink)?;
        }
    }
    Ok(())
}

fn field_offsets(fields: &[Field]) -> Vec<usize> {
    let mut off = 0;
    fields
        .iter()
        .map(|f| {
            let here = off;
            off += match *f {
                Field::Scalar(s) => s.size(),
                Field::Array(s, n) => s.size() * n,
                Field::List { .. } => 0,
            };
            here
        })
        .collect()
}

fn field_scalar(f: Field) -> Scalar {
    match f {
        Field::Scalar(s) | Field::Array(s, _) => s,
        Field::List { item, .. } => item,
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

/// Reads the ASCII records of `el`, one non-blank line per record: every value is checked
/// against its declared type, the points of the element with `xyz` are kept.
fn read_ascii(
    lines: &mut Lines<'_>,
    el: &Element,
    ctx: Ctx,
    sink: &mut Sink,
) -> Result<(), ParseError> {
    if el.xyz.is_some() {
        // Each point needs at least "0 0 0\n": never reserve more than the text can hold.
        let remaining = lines.bytes.len().saturating_sub(lines.pos) / 6;
        sink.points.reserve(
            usize::try_from(el.count)
                .unwrap_or(usize::MAX)
                .min(remaining),
        );
    }
    let mut tokens: Vec<&[u8]> = Vec::new();
    for record in 0..el.count {
        let Some((line_no, line)) = lines.next_nonblank() else {
            return Err(el.truncated(
                ctx,
                Location::Line(lines.line + 1),
                record,
                "another line".into(),
            ));
        };
        tokens.clear();
        tokens.extend(
            line.split(|b| b.is_ascii_whitespace())
                .filter(|t| !t.is_empty()),
        );
        let mut row = TextRow {
            ctx,
            el,
            at: Location::Line(line_no),
            record,
            tokens: &tokens,
            next: 0,
        };
        let mut p = [0.0f64; 3];
        for (i, field) in el.fields.iter().enumerate() {
            match *field {
                Field::Scalar(s) => {
                    let v = row.value(s, i, None)?;
                    if let Some(axis) = el.xyz.and_then(|xyz| xyz.iter().position(|&j| j == i)) {
                        p[axis] = v;
                    }
                }
                Field::Array(s, n) => {
                    for k in 0..n {
                        row.value(s, i, Some(k))?;
                    }
                }
                Field::List { count, item } => {
                    let n = row.list_length(count, i)?;
                    for k in 0..n {
                        row.value(item, i, Some(k))?;
                    }
                }
            }
        }
        if row.next != tokens.len() {
            return Err(row.wrong_count(row.next));
        }
        if el.xyz.is_some() {
            push_point(ctx, row.at, record, p, sink)?;
        }
    }
    Ok(())
}

/// The values of one text record, taken in order and checked against their types.
struct TextRow<'r, 'a> {
    ctx: Ctx,
    el: &'r Element,
    at: Location,
    record: u64,
    tokens: &'r [&'a [u8]],
    /// Index of the next token.
    next: usize,
}

impl<'a> TextRow<'_, 'a> {
    /// The next value, of type `s`, belonging to field `field` (item `item` of an array or
    /// list).
    fn value(&mut self, s: Scalar, field: usize, item: Option<usize>) -> Result<f64, ParseError> {
        let token = self.take()?;
        s.parse_text(token).ok_or_else(|| {
            let name = self.field_name(field);
            let property = match item {
                Some(k) => format!("{name}[{k}]"),
                None => name.to_owned(),
            };
            self.not_a_number(token, property, s.text_expectation())
        })
    }

    /// The next value as the length of a list of field `field`: an integer of type `s`, >= 0,
    /// at most the tokens left on the line (so a huge length fails here, not in a long loop).
    fn list_length(&mut self, s: Scalar, field: usize) -> Result<usize, ParseError> {
        let token = self.take()?;
        let left = (self.tokens.len() - self.next) as f64;
        match s.parse_text(token) {
            Some(n) if n >= 0.0 && n <= left => Ok(n as usize),
            Some(n) if n >= 0.0 => Err(self.wrong_count(self.next.saturating_add(n as usize))),
            _ => {
                let property = format!("{} (list length)", self.field_name(field));
                Err(self.not_a_number(token, property, s.length_expectation()))
            }
        }
    }

    fn take(&mut self) -> Result<&'a [u8], ParseError> {
        let token = self
            .tokens
            .get(self.next)
            .copied()
            .ok_or_else(|| self.wrong_count(self.next + 1))?;
        self.next += 1;
        Ok(token)
    }

    fn field_name(&self, field: usize) -> &str {
        self.el.names.get(field).map_or("?", String::as_str)
    }

    fn wrong_count(&self, expected: usize) -> ParseError {
        ParseError::WrongValueCount {
            format: self.ctx.format,
            at: self.at,
            element: self.el.name.clone(),
            record: self.record,
            found: self.tokens.len(),
            expected,
        }
    }

    /// The value just taken is not a `expected`.
    fn not_a_number(&self, token: &[u8], property: String, expected: &'static str) -> ParseError {
        let shown = &token[..token.len().min(40)];
        ParseError::NotANumber {
            format: self.ctx.format,
            at: self.at,
            column: self.next,
            property,
            element: self.el.name.clone(),
            record: self.record,
            found: String::from_utf8_lossy(shown).into_owned(),
            expected,
        }
    }
}

/// Fails if anything but whitespace follows the last record.
fn expect_ascii_end(lines: &mut Lines<'_>, ctx: Ctx, declared: u64) -> Result<(), ParseError> {
    match lines.next_nonblank() {
        Some((line_no, _)) => Err(ParseError::TrailingData {
            format: ctx.format,
            at: Location::Line(line_no),
            declared,
        }),
        None => Ok(()),
    }
}

/// Fails if bytes follow the last binary record.
fn expect_binary_end(bytes: &[u8], pos: usize, ctx: Ctx, declared: u64) -> Result<(), ParseError> {
    if pos < bytes.len() {
        Err(ParseError::TrailingData {
            format: ctx.format,
            at: Location::Byte(pos),
            declared,
        })
    } else {
        Ok(())
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
