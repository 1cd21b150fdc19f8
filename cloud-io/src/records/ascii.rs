//! ASCII records: one non-blank line per record, every value checked against its type.

use super::{Ctx, Element, Field, Lines, Scalar, Sink, push_point};
use crate::{Location, ParseError};

/// Reads the ASCII records of `el`, one non-blank line per record: every value is checked
/// against its declared type, the points of the element with `xyz` are kept.
pub(super) fn read_ascii(
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
pub(super) fn expect_ascii_end(
    lines: &mut Lines<'_>,
    ctx: Ctx,
    declared: u64,
) -> Result<(), ParseError> {
    match lines.next_nonblank() {
        Some((line_no, _)) => Err(ParseError::TrailingData {
            format: ctx.format,
            at: Location::Line(line_no),
            declared,
        }),
        None => Ok(()),
    }
}
