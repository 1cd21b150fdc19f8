//! Strict parsers for the values people type: durations (`400ms`, `2us`, `1.5s`), rates
//! (`10mbit`) and percentages (`1%`). Decimal values are converted exactly (no float rounding
//! for times and rates); a value that needs a unit must have one.

use thiserror::Error;

/// A value that does not parse; says what was expected.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
#[error("`{value}` is not {expected}")]
pub struct UnitError {
    /// The text given.
    pub value: String,
    /// What was expected, with examples.
    pub expected: &'static str,
}

const DURATION: &str = "a duration: a number with a unit ns, us (or µs), ms or s, e.g. 400ms, \
                        2us, 1.5s (0 may stand alone); whole nanoseconds, at most one hour";
const RATE: &str = "a rate: a number with a unit bit, kbit, mbit, gbit or tbit (powers of 1000, \
                    bits per second), e.g. 10mbit, 512kbit, 1.5gbit; whole bits per second";
const RATE_BYTES: &str = "a rate in bits: tc reads `bps`/`kbps`/`mbps` as bytes per second; \
                          write it in bits instead, e.g. 8mbit for 1mbps";
const PERCENT: &str = "a percentage from 0% to 100%, e.g. 1%, 0.5%, 100%";

/// Parses a duration into nanoseconds.
pub fn parse_duration_ns(text: &str) -> Result<u64, UnitError> {
    let fail = || UnitError {
        value: text.to_owned(),
        expected: DURATION,
    };
    if text == "0" {
        return Ok(0);
    }
    let (number, unit) = split_unit(text);
    let scale: u128 = match unit {
        "ns" => 1,
        "us" | "µs" => 1_000,
        "ms" => 1_000_000,
        "s" => 1_000_000_000,
        _ => return Err(fail()),
    };
    let ns = scaled_integer(number, scale).ok_or_else(fail)?;
    u64::try_from(ns)
        .ok()
        .filter(|&ns| ns <= crate::model::config::MAX_DELAY_NS)
        .ok_or_else(fail)
}

/// Parses a rate into bits per second.
pub fn parse_rate_bit_per_s(text: &str) -> Result<u64, UnitError> {
    let (number, unit) = split_unit(text);
    let lower = unit.to_ascii_lowercase();
    let scale: u128 = match lower.as_str() {
        "bit" => 1,
        "kbit" => 1_000,
        "mbit" => 1_000_000,
        "gbit" => 1_000_000_000,
        "tbit" => 1_000_000_000_000,
        "bps" | "kbps" | "mbps" | "gbps" | "tbps" => {
            return Err(UnitError {
                value: text.to_owned(),
                expected: RATE_BYTES,
            });
        }
        _ => 0,
    };
    scaled_integer(number, scale)
        .filter(|_| scale > 0)
        .and_then(|bits| u64::try_from(bits).ok())
        .ok_or_else(|| UnitError {
            value: text.to_owned(),
            expected: RATE,
        })
}

/// Parses a percentage into a fraction (`1%` → 0.01).
pub fn parse_percent(text: &str) -> Result<f64, UnitError> {
    let fail = || UnitError {
        value: text.to_owned(),
        expected: PERCENT,
    };
    let number = text.strip_suffix('%').ok_or_else(fail)?;
    if !is_decimal(number) {
        return Err(fail());
    }
    let percent: f64 = number.parse().map_err(|_| fail())?;
    if !(0.0..=100.0).contains(&percent) {
        return Err(fail());
    }
    Ok(percent / 100.0)
}

/// Splits `12.5ms` into `("12.5", "ms")`.
fn split_unit(text: &str) -> (&str, &str) {
    let end = text
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(text.len());
    text.split_at(end)
}

/// `digits[.digits]`, at least one digit.
fn is_decimal(number: &str) -> bool {
    let mut parts = number.splitn(2, '.');
    let whole = parts.next().unwrap_or_default();
    let fraction = parts.next();
    let all_digits = |s: &str| s.bytes().all(|b| b.is_ascii_digit());
    all_digits(whole)
        && fraction.is_none_or(|f| !f.is_empty() && all_digits(f))
        && (!whole.is_empty() || fraction.is_some())
}

/// `number × scale` as an exact integer, or `None` if malformed, fractional after scaling, or
/// too large.
fn scaled_integer(number: &str, scale: u128) -> Option<u128> {
    if !is_decimal(number) {
        return None;
    }
    let (whole, fraction) = number.split_once('.').unwrap_or((number, ""));
    if whole.len() + fraction.len() > 30 {
        return None;
    }
    let digits: u128 = format!("{whole}{fraction}").parse().ok()?;
    let divisor = 10u128.checked_pow(u32::try_from(fraction.len()).ok()?)?;
    let scaled = digits.checked_mul(scale)?;
    (scaled % divisor == 0).then_some(scaled / divisor)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations() {
        assert_eq!(parse_duration_ns("400ms"), Ok(400_000_000));
        assert_eq!(parse_duration_ns("2us"), Ok(2_000));
        assert_eq!(parse_duration_ns("2µs"), Ok(2_000));
        assert_eq!(parse_duration_ns("1.5s"), Ok(1_500_000_000));
        assert_eq!(parse_duration_ns("0.25ms"), Ok(250_000));
        assert_eq!(parse_duration_ns("7ns"), Ok(7));
        assert_eq!(parse_duration_ns("0"), Ok(0));
        assert_eq!(parse_duration_ns(".5ms"), Ok(500_000));
        for bad in [
            "400", "ms", "4 ms", "1.5", "0.5ns", "-1ms", "1e3ms", "1..2s", "1.ms", "2h", "",
            "3601s",
        ] {
            let err = parse_duration_ns(bad).unwrap_err();
            assert_eq!(err.value, bad);
            assert!(err.to_string().contains("400ms"), "{err}");
        }
    }

    #[test]
    fn rates() {
        assert_eq!(parse_rate_bit_per_s("10mbit"), Ok(10_000_000));
        assert_eq!(parse_rate_bit_per_s("512kbit"), Ok(512_000));
        assert_eq!(parse_rate_bit_per_s("1.5Gbit"), Ok(1_500_000_000));
        assert_eq!(parse_rate_bit_per_s("64bit"), Ok(64));
        assert!(
            parse_rate_bit_per_s("10mbps")
                .unwrap_err()
                .to_string()
                .contains("bytes")
        );
        for bad in ["10", "10m", "mbit", "0.5bit", "ten mbit"] {
            assert!(parse_rate_bit_per_s(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn percents() {
        assert_eq!(parse_percent("1%"), Ok(0.01));
        assert_eq!(parse_percent("100%"), Ok(1.0));
        assert_eq!(parse_percent("0.5%"), Ok(0.005));
        for bad in ["1", "101%", "-1%", "%", "1.5.%", "nan%", "inf%", "1e2%"] {
            let err = parse_percent(bad).unwrap_err();
            assert!(err.to_string().contains("e.g. 1%"), "{err}");
        }
    }
}
