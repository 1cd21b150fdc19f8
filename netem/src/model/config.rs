//! One direction's link settings, their validation and the named profiles.

use std::fmt;

use thiserror::Error;

use super::distribution::Distribution;
use super::loss::Loss;

/// Largest base delay accepted: one hour [ns].
pub const MAX_DELAY_NS: u64 = 3_600_000_000_000;
/// Largest jitter accepted: `i32::MAX` ns ≈ 2.147 s, netem's cap.
pub const MAX_JITTER_NS: u64 = i32::MAX as u64;
/// Largest queue limit accepted [packets].
pub const MAX_LIMIT_PACKETS: u32 = 10_000_000;
/// Default queue limit [packets]. netem's default of 1000 is too small for kHz streams over
/// hundreds of ms (network notes §1.3 #4); 100 000 holds 100 s of a 1 kHz stream.
pub const DEFAULT_LIMIT_PACKETS: u32 = 100_000;
/// Default per-packet overhead for the rate [bytes]: the IPv4 (20) and UDP (8) headers that a
/// datagram's payload length does not include.
pub const DEFAULT_OVERHEAD_BYTES: i32 = 28;

/// The impairments of one direction of a link. Times in ns, probabilities as fractions
/// (`0.01` = 1 %). [`Default`] is a perfect link: no delay, no loss, order kept.
#[derive(Clone, Debug, PartialEq)]
pub struct LinkConfig {
    /// Base one-way delay [ns]. Default 0. Range `0..=`[`MAX_DELAY_NS`].
    pub delay_ns: u64,
    /// Jitter [ns]: the half-width for uniform, σ for the tables. Default 0.
    /// Range `0..=`[`MAX_JITTER_NS`]. A draw below zero delay is clipped to zero.
    pub jitter_ns: u64,
    /// Correlation of successive jitter draws, `0..=1` (netem's smoothing model, see
    /// [`distribution`](super::distribution); it shrinks the realised jitter). Default 0.
    pub jitter_correlation: f64,
    /// Shape of the jitter. Default uniform (netem's default without a table).
    pub distribution: Distribution,
    /// Loss model. Default none.
    pub loss: Loss,
    /// Probability that a packet is sent twice, `0..=1`. The copy gets its own loss and delay
    /// draws, as in netem (which re-enqueues it). Default 0.
    pub duplicate_probability: f64,
    /// Probability that a packet eligible by [`reorder_gap`](Self::reorder_gap) is sent at once,
    /// ahead of the delayed ones (netem `reorder`), `0..=1`. Needs `delay_ns > 0`. Default 0.
    pub reorder_probability: f64,
    /// netem's `gap`: reordering is considered only once `gap − 1` packets have been delayed
    /// since the last reordered one. `1..`; default 1 (every packet is eligible).
    pub reorder_gap: u32,
    /// Link rate [bit/s]; `None` = unlimited (default). With a rate each packet also waits
    /// `(len + overhead)·8/rate` behind the previous queued packet, measured from that packet's
    /// due time, as netem serialises.
    pub rate_bit_per_s: Option<u64>,
    /// Bytes added to each packet's length for the rate (may be negative, netem's
    /// `packetoverhead`). Default [`DEFAULT_OVERHEAD_BYTES`].
    pub overhead_bytes: i32,
    /// Most packets in flight; a packet offered while this many wait is dropped and counted.
    /// Default [`DEFAULT_LIMIT_PACKETS`]. Range `1..=`[`MAX_LIMIT_PACKETS`].
    pub limit_packets: u32,
    /// Keep arrival order despite jitter: `due_i = max(due_i, due_{i−1})` (netem with a pfifo
    /// child). Default `true`: reordering jitter makes QUIC declare spurious losses (network
    /// notes §3.4). `false` gives netem's tfifo, where jitter wider than the packet spacing
    /// reorders. Packets sent at once by [`reorder_probability`](Self::reorder_probability) jump
    /// the queue in both modes.
    pub keep_order: bool,
}

impl Default for LinkConfig {
    fn default() -> Self {
        Self {
            delay_ns: 0,
            jitter_ns: 0,
            jitter_correlation: 0.0,
            distribution: Distribution::Uniform,
            loss: Loss::None,
            duplicate_probability: 0.0,
            reorder_probability: 0.0,
            reorder_gap: 1,
            rate_bit_per_s: None,
            overhead_bytes: DEFAULT_OVERHEAD_BYTES,
            limit_packets: DEFAULT_LIMIT_PACKETS,
            keep_order: true,
        }
    }
}

/// A setting outside its allowed range.
#[derive(Clone, Debug, Error, PartialEq)]
#[error("{field} = {value}: expected {expected}")]
pub struct ConfigError {
    /// The [`LinkConfig`] field, e.g. `jitter_ns` or `loss.p`.
    pub field: &'static str,
    /// The value given.
    pub value: String,
    /// What is allowed, and why where it is not obvious.
    pub expected: &'static str,
}

impl LinkConfig {
    /// A link with only a fixed delay.
    pub fn delay(delay_ns: u64) -> Self {
        Self {
            delay_ns,
            ..Self::default()
        }
    }

    /// Checks every field; the error names the first field out of range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let fail = |field, value: String, expected| ConfigError {
            field,
            value,
            expected,
        };
        if self.delay_ns > MAX_DELAY_NS {
            return Err(fail(
                "delay_ns",
                self.delay_ns.to_string(),
                "0..=3600000000000 ns (one hour)",
            ));
        }
        if self.jitter_ns > MAX_JITTER_NS {
            return Err(fail(
                "jitter_ns",
                self.jitter_ns.to_string(),
                "0..=2147483647 ns (netem caps jitter at i32::MAX ns, about 2.147 s)",
            ));
        }
        let mut probabilities = vec![
            ("jitter_correlation", self.jitter_correlation),
            ("duplicate_probability", self.duplicate_probability),
            ("reorder_probability", self.reorder_probability),
        ];
        probabilities.extend(self.loss.probabilities());
        for (field, value) in probabilities {
            if !(0.0..=1.0).contains(&value) {
                return Err(fail(
                    field,
                    value.to_string(),
                    "a probability in 0..=1 (1 % = 0.01)",
                ));
            }
        }
        if self.reorder_probability > 0.0 && self.delay_ns == 0 {
            return Err(fail(
                "reorder_probability",
                self.reorder_probability.to_string(),
                "0 while delay_ns is 0: reordering sends packets ahead of delayed ones, so it \
                 needs a delay (netem: \"reordering not possible without specifying some delay\")",
            ));
        }
        if self.reorder_gap == 0 {
            return Err(fail("reorder_gap", "0".into(), "1 or more packets"));
        }
        if self.rate_bit_per_s == Some(0) {
            return Err(fail(
                "rate_bit_per_s",
                "0".into(),
                "1 bit/s or more (None for an unlimited rate)",
            ));
        }
        if !(-65_535..=65_535).contains(&self.overhead_bytes) {
            return Err(fail(
                "overhead_bytes",
                self.overhead_bytes.to_string(),
                "-65535..=65535 bytes",
            ));
        }
        if !(1..=MAX_LIMIT_PACKETS).contains(&self.limit_packets) {
            return Err(fail(
                "limit_packets",
                self.limit_packets.to_string(),
                "1..=10000000 packets",
            ));
        }
        Ok(())
    }

    /// A named profile (see [`PROFILES`]), or `None` for an unknown name.
    pub fn profile(name: &str) -> Option<Self> {
        const MS: u64 = 1_000_000;
        const US: u64 = 1_000;
        let config = match name {
            "lan" => Self {
                delay_ns: 250 * US,
                jitter_ns: 50 * US,
                ..Self::default()
            },
            "wifi" => Self {
                delay_ns: 3 * MS,
                jitter_ns: 2 * MS,
                distribution: Distribution::Normal,
                loss: Loss::GilbertElliott {
                    p: 0.002,
                    r: 0.5,
                    one_minus_h: 1.0,
                    one_minus_k: 0.0,
                },
                rate_bit_per_s: Some(100_000_000),
                ..Self::default()
            },
            "4g" => Self {
                delay_ns: 25 * MS,
                jitter_ns: 8 * MS,
                distribution: Distribution::ParetoNormal,
                loss: Loss::Random { probability: 0.005 },
                rate_bit_per_s: Some(20_000_000),
                ..Self::default()
            },
            "satellite" => Self {
                delay_ns: 300 * MS,
                jitter_ns: 5 * MS,
                distribution: Distribution::Normal,
                loss: Loss::Random { probability: 0.01 },
                rate_bit_per_s: Some(10_000_000),
                ..Self::default()
            },
            "thesis-400ms" => Self::delay(400 * MS),
            _ => return None,
        };
        Some(config)
    }
}

impl fmt::Display for LinkConfig {
    /// The settings that differ from a perfect link, in netem's words, e.g.
    /// `delay 400ms jitter 2ms normal loss 1%`; `perfect` when none do.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let ms = |ns: u64| ns as f64 / 1e6;
        let pct = |p: f64| p * 100.0;
        let mut parts = Vec::new();
        if self.delay_ns > 0 {
            parts.push(format!("delay {}ms", ms(self.delay_ns)));
        }
        if self.jitter_ns > 0 {
            parts.push(format!(
                "jitter {}ms {}",
                ms(self.jitter_ns),
                self.distribution
            ));
            if self.jitter_correlation > 0.0 {
                parts.push(format!("correlation {}%", pct(self.jitter_correlation)));
            }
            if !self.keep_order {
                parts.push("order free".into());
            }
        }
        match self.loss {
            Loss::None => {}
            Loss::Random { probability } => parts.push(format!("loss {}%", pct(probability))),
            Loss::GilbertElliott {
                p,
                r,
                one_minus_h,
                one_minus_k,
            } => parts.push(format!(
                "loss gemodel {}% {}% {}% {}%",
                pct(p),
                pct(r),
                pct(one_minus_h),
                pct(one_minus_k)
            )),
        }
        if self.duplicate_probability > 0.0 {
            parts.push(format!("duplicate {}%", pct(self.duplicate_probability)));
        }
        if self.reorder_probability > 0.0 {
            parts.push(format!(
                "reorder {}% gap {}",
                pct(self.reorder_probability),
                self.reorder_gap
            ));
        }
        if let Some(rate) = self.rate_bit_per_s {
            parts.push(format!("rate {rate}bit overhead {}B", self.overhead_bytes));
        }
        if self.limit_packets != DEFAULT_LIMIT_PACKETS {
            parts.push(format!("limit {}", self.limit_packets));
        }
        if parts.is_empty() {
            return f.write_str("perfect");
        }
        f.write_str(&parts.join(" "))
    }
}

/// Names accepted by [`LinkConfig::profile`], with what each is. One-way figures, illustrative
/// orders of magnitude rather than measurements; jitter never reorders (order kept).
pub const PROFILES: &[(&str, &str)] = &[
    ("lan", "0.25 ms ± 0.05 ms uniform"),
    (
        "wifi",
        "3 ms ± 2 ms normal, bursty loss ≈ 0.4 % (Gilbert p 0.2 %, r 50 %), 100 Mbit/s",
    ),
    ("4g", "25 ms, σ 8 ms paretonormal, 0.5 % loss, 20 Mbit/s"),
    ("satellite", "300 ms, σ 5 ms normal, 1 % loss, 10 Mbit/s"),
    (
        "thesis-400ms",
        "400 ms fixed, no loss (the thesis's delayed condition)",
    ),
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_and_profiles_are_valid() {
        LinkConfig::default().validate().unwrap();
        for (name, _) in PROFILES {
            LinkConfig::profile(name).unwrap().validate().unwrap();
        }
        assert!(LinkConfig::profile("dialup").is_none());
        assert_eq!(LinkConfig::default().to_string(), "perfect");
        assert_eq!(
            LinkConfig::profile("4g").unwrap().to_string(),
            "delay 25ms jitter 8ms paretonormal loss 0.5% rate 20000000bit overhead 28B"
        );
    }

    #[test]
    fn errors_name_field_value_and_range() {
        let err = LinkConfig {
            jitter_ns: 3_000_000_000,
            ..LinkConfig::default()
        }
        .validate()
        .unwrap_err();
        assert_eq!(err.field, "jitter_ns");
        assert_eq!(err.value, "3000000000");
        assert!(err.to_string().contains("0..=2147483647"), "{err}");

        let err = LinkConfig {
            loss: Loss::GilbertElliott {
                p: 0.1,
                r: 1.5,
                one_minus_h: 1.0,
                one_minus_k: 0.0,
            },
            ..LinkConfig::default()
        }
        .validate()
        .unwrap_err();
        assert_eq!((err.field, err.value.as_str()), ("loss.r", "1.5"));

        let err = LinkConfig {
            reorder_probability: 0.25,
            ..LinkConfig::default()
        }
        .validate()
        .unwrap_err();
        assert_eq!(err.field, "reorder_probability");
        assert!(err.to_string().contains("needs a delay"), "{err}");

        let err = LinkConfig {
            duplicate_probability: f64::NAN,
            ..LinkConfig::default()
        }
        .validate()
        .unwrap_err();
        assert_eq!(err.field, "duplicate_probability");

        for (config, field) in [
            (
                LinkConfig {
                    rate_bit_per_s: Some(0),
                    ..LinkConfig::default()
                },
                "rate_bit_per_s",
            ),
            (
                LinkConfig {
                    limit_packets: 0,
                    ..LinkConfig::default()
                },
                "limit_packets",
            ),
            (
                LinkConfig {
                    reorder_gap: 0,
                    ..LinkConfig::default()
                },
                "reorder_gap",
            ),
        ] {
            assert_eq!(config.validate().unwrap_err().field, field);
        }
    }
}
