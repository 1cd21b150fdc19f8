//! The finiteness check every decoded message passes: a peer must never inject NaN or ±∞ into our
//! loops. The field is named so that the log says where the bad value came from.

use std::fmt;

/// A float field on the wire held NaN or ±∞.
#[derive(Clone, Debug, PartialEq)]
pub struct NonFinite {
    /// The field's path, e.g. `Contact.normal[2]` or `Parameters.tangential.mass_kg`.
    pub field: String,
    /// The value found there (NaN, `inf` or `-inf`).
    pub value: f64,
}

impl fmt::Display for NonFinite {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "field {} is {}, expected a finite number",
            self.field, self.value
        )
    }
}

impl std::error::Error for NonFinite {}

impl NonFinite {
    /// Prefixes the path with the enclosing field, e.g. `normal` → `Parameters.normal`.
    pub(crate) fn within(mut self, outer: &str) -> NonFinite {
        self.field = format!("{outer}.{}", self.field);
        self
    }
}

/// Types whose every float must be finite on the wire.
pub(crate) trait CheckFinite {
    /// The first non-finite float, with its path; `Ok` when all are finite.
    fn check_finite(&self) -> Result<(), NonFinite>;
}

/// Checks one scalar.
pub(crate) fn scalar(field: &str, value: f64) -> Result<(), NonFinite> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(NonFinite {
            field: field.to_owned(),
            value,
        })
    }
}

/// Checks every element of a vector; the path gets the index of the first bad one.
pub(crate) fn vector(field: &str, values: &[f64]) -> Result<(), NonFinite> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(NonFinite {
            field: format!("{field}[{i}]"),
            value: values[i],
        }),
    }
}

/// Checks an optional scalar.
pub(crate) fn opt_scalar(field: &str, value: Option<f64>) -> Result<(), NonFinite> {
    value.map_or(Ok(()), |v| scalar(field, v))
}

/// Checks an optional vector.
pub(crate) fn opt_vector(field: &str, values: &Option<[f64; 3]>) -> Result<(), NonFinite> {
    values.as_ref().map_or(Ok(()), |v| vector(field, v))
}

/// Checks a list of single-precision points; the path gets `[point][coordinate]`.
pub(crate) fn points(field: &str, points: &[[f32; 3]]) -> Result<(), NonFinite> {
    for (i, p) in points.iter().enumerate() {
        if let Some(j) = p.iter().position(|v| !v.is_finite()) {
            return Err(NonFinite {
                field: format!("{field}[{i}][{j}]"),
                value: f64::from(p[j]),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_name_the_index_and_the_enclosing_fields() {
        let e = vector("normal", &[0.0, f64::NAN, f64::INFINITY]).unwrap_err();
        let e = e.within("Contact");
        assert_eq!(e.field, "Contact.normal[1]");
        assert!(e.value.is_nan());
        assert_eq!(
            e.to_string(),
            "field Contact.normal[1] is NaN, expected a finite number"
        );
        let e = points("points", &[[0.0; 3], [0.0, 0.0, f32::NEG_INFINITY]]).unwrap_err();
        assert_eq!(e.field, "points[1][2]");
        assert_eq!(e.value, f64::NEG_INFINITY);
        assert!(opt_scalar("x", None).is_ok());
        assert!(opt_vector("x", &Some([1.0, 2.0, 3.0])).is_ok());
    }
}
