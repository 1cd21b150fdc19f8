//! Binary records: packed fields of fixed size, read in place, or with lists, walked field by
//! field.

use super::{Ctx, Element, Field, Scalar, Sink, push_point};
use crate::{Location, ParseError};

/// Reads (or, without `xyz`, skips) the binary records of `el` starting at `*pos` of `bytes`;
/// advances `*pos` past them.
pub(super) fn read_binary(
    bytes: &[u8],
    pos: &mut usize,
    el: &Element,
    big_endian: bool,
    ctx: Ctx,
    sink: &mut Sink,
) -> Result<(), ParseError> {
    match el.fixed_size() {
        Some(size) => read_fixed(bytes, pos, el, size, big_endian, ctx, sink),
        None => read_variable(bytes, pos, el, big_endian, ctx, sink),
    }
}

/// Records of `size` bytes each (no lists): the declared count is checked against the bytes
/// left before anything is reserved, then `x`, `y`, `z` are read at their offsets.
fn read_fixed(
    bytes: &[u8],
    pos: &mut usize,
    el: &Element,
    size: usize,
    big_endian: bool,
    ctx: Ctx,
    sink: &mut Sink,
) -> Result<(), ParseError> {
    let available = bytes.len().saturating_sub(*pos);
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
    Ok(())
}

/// Variable-size records (lists), walked field by field: every record takes at least one byte
/// (a list length), so the loop is bounded by the data, whatever the declared count.
fn read_variable(
    bytes: &[u8],
    pos: &mut usize,
    el: &Element,
    big_endian: bool,
    ctx: Ctx,
    sink: &mut Sink,
) -> Result<(), ParseError> {
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

/// Fails if bytes follow the last binary record.
pub(super) fn expect_binary_end(
    bytes: &[u8],
    pos: usize,
    ctx: Ctx,
    declared: u64,
) -> Result<(), ParseError> {
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
