//! Jitter distributions: netem's uniform draw, its inverse-CDF tables (built-in and `.dist` files)
//! and its correlated uniform source.
//!
//! # What is exact and what is approximate
//!
//! - **Uniform** is netem's integer draw, `((rnd % 2σ) + μ) − σ`: a delay in `[μ − σ, μ + σ)`.
//! - **Tables** (`normal`, `pareto`, `paretonormal`, custom `.dist`) are looked up with the kernel's
//!   `tabledist` arithmetic (`sch_netem.c`): entry `t = table[rnd % size]`, delay
//!   `μ + σ·t/8192` rounded as the kernel rounds. A table is an inverse CDF of a distribution with
//!   mean 0 and σ 1, scaled by [`DIST_SCALE`] = 8192.
//! - The built-in tables are **built as iproute2 builds them** (`netem/normal.c`, `pareto.c`,
//!   `paretonormal.c`, NIST Net algorithms): 4096 entries; the normal table by the same grid
//!   search over `½ + ½·erf(x/√2)` (x from −10 in steps of 5·10⁻⁵); the Pareto table with shape 3
//!   shifted by its mean 1.5 and scaled by 4/3; paretonormal = (normal + 3·pareto)/4. They are not
//!   exact inverse CDFs: the σ of the Pareto table is 1.15, not 1, and entries are clamped to
//!   `i16`, exactly as in the tables `tc` loads.
//! - **Correlation** is netem's `get_crandom`: `next = (u·(2³²−ρ) + last·ρ) >> 32`, an
//!   exponential smoothing of the uniform variate. It is not a true correlation and it **shrinks
//!   the realised jitter** (tc-netem(8): "an approximation"). Unlike netem, the smoothing state is
//!   seeded from the link's PRNG, so runs are reproducible.
//!
//! After a table is built or parsed every draw is integer arithmetic, so the same seed gives the
//! same delays on every platform.

use std::fmt;
use std::path::Path;
use std::sync::{Arc, OnceLock};

use rand::RngCore;
use thiserror::Error;

/// Scale of a table entry: an entry of 8192 means one σ (`NETEM_DIST_SCALE`).
pub const DIST_SCALE: i64 = 8192;
/// Most entries a table may hold (`NETEM_DIST_MAX`).
pub const DIST_MAX: usize = 16_384;

/// The shape of the jitter around the base delay.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum Distribution {
    /// Uniform over `[delay − jitter, delay + jitter)` (netem's default when no table is given).
    #[default]
    Uniform,
    /// Normal, σ = jitter (iproute2's `normal.dist`).
    Normal,
    /// Pareto with shape 3, shifted to mean 0 (iproute2's `pareto.dist`): a long right tail.
    Pareto,
    /// ¼ normal + ¾ Pareto (iproute2's `paretonormal.dist`).
    ParetoNormal,
    /// A custom inverse-CDF table, e.g. made with iproute2's `maketable` from measured delays.
    Table(Arc<DistTable>),
}

impl Distribution {
    /// Parses a name (`uniform`, `normal`, `pareto`, `paretonormal`) or, for anything else, loads
    /// the netem `.dist` file at that path.
    pub fn from_name_or_path(text: &str) -> Result<Self, DistError> {
        match text {
            "uniform" => Ok(Self::Uniform),
            "normal" => Ok(Self::Normal),
            "pareto" => Ok(Self::Pareto),
            "paretonormal" => Ok(Self::ParetoNormal),
            path => Ok(Self::Table(Arc::new(DistTable::load(Path::new(path))?))),
        }
    }

    /// The inverse-CDF table, or `None` for uniform.
    pub fn table(&self) -> Option<&[i16]> {
        match self {
            Self::Uniform => None,
            Self::Normal => Some(normal_table()),
            Self::Pareto => Some(pareto_table()),
            Self::ParetoNormal => Some(paretonormal_table()),
            Self::Table(table) => Some(table.entries()),
        }
    }
}

impl fmt::Display for Distribution {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Uniform => f.write_str("uniform"),
            Self::Normal => f.write_str("normal"),
            Self::Pareto => f.write_str("pareto"),
            Self::ParetoNormal => f.write_str("paretonormal"),
            Self::Table(table) => f.write_str(table.name()),
        }
    }
}

/// A netem distribution table: 1 to [`DIST_MAX`] signed 16-bit inverse-CDF entries.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DistTable {
    name: String,
    entries: Vec<i16>,
}

/// Why a distribution table was refused.
#[derive(Debug, Error)]
pub enum DistError {
    /// The file could not be read.
    #[error("cannot read distribution table {path}")]
    Io {
        /// The path given.
        path: String,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// A token is not a signed 16-bit integer.
    #[error(
        "{name}, line {line}: `{token}` is not a table entry: expected a signed 16-bit integer \
         (-32768..=32767, one σ = 8192)"
    )]
    BadEntry {
        /// The table's name (its path for a file).
        name: String,
        /// 1-based line number.
        line: usize,
        /// The offending text.
        token: String,
    },
    /// More entries than netem accepts.
    #[error("{name}, line {line}: more than {DIST_MAX} entries (netem's NETEM_DIST_MAX)")]
    TooLong {
        /// The table's name.
        name: String,
        /// 1-based line number of the first entry past the limit.
        line: usize,
    },
    /// No entries at all.
    #[error("{name}: no table entries (expected 1..={DIST_MAX} whitespace-separated integers)")]
    Empty {
        /// The table's name.
        name: String,
    },
}

impl DistTable {
    /// Parses the text format `tc` reads: whitespace-separated decimal integers; blank lines and
    /// everything after a `#` are ignored. Unlike `tc` (which wraps out-of-range values to 16 bits
    /// silently) an entry outside `i16` is an error naming the line.
    pub fn parse(name: &str, text: &str) -> Result<Self, DistError> {
        let mut entries = Vec::new();
        for (index, raw_line) in text.lines().enumerate() {
            let line = raw_line.split('#').next().unwrap_or_default();
            for token in line.split_whitespace() {
                let entry = token.parse::<i16>().map_err(|_| DistError::BadEntry {
                    name: name.to_owned(),
                    line: index + 1,
                    token: token.to_owned(),
                })?;
                if entries.len() == DIST_MAX {
                    return Err(DistError::TooLong {
                        name: name.to_owned(),
                        line: index + 1,
                    });
                }
                entries.push(entry);
            }
        }
        Self::from_entries(name, entries)
    }

    /// Reads and parses a `.dist` file.
    pub fn load(path: &Path) -> Result<Self, DistError> {
        let shown = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| DistError::Io {
            path: shown.clone(),
            source,
        })?;
        Self::parse(&shown, &text)
    }

    /// A table from entries already in memory.
    pub fn from_entries(name: &str, entries: Vec<i16>) -> Result<Self, DistError> {
        if entries.is_empty() {
            return Err(DistError::Empty {
                name: name.to_owned(),
            });
        }
        if entries.len() > DIST_MAX {
            return Err(DistError::TooLong {
                name: name.to_owned(),
                line: 0,
            });
        }
        Ok(Self {
            name: name.to_owned(),
            entries,
        })
    }

    /// The table's name (the path it was loaded from, for a file).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The entries, scaled so that [`DIST_SCALE`] is one σ.
    pub fn entries(&self) -> &[i16] {
        &self.entries
    }
}

/// netem's `tabledist`: a delay [ns] with mean `mu_ns` and spread `sigma_ns` from the uniform
/// variate `rnd`. May be negative; the caller clips.
pub(crate) fn tabledist(mu_ns: i64, sigma_ns: i32, rnd: u32, table: Option<&[i16]>) -> i64 {
    if sigma_ns <= 0 {
        return mu_ns;
    }
    let sigma = i64::from(sigma_ns);
    let Some(table) = table.filter(|t| !t.is_empty()) else {
        // Two σ fit in a u32 because σ ≤ i32::MAX.
        let span = 2 * sigma;
        return i64::from(rnd) % span + mu_ns - sigma;
    };
    let len = u32::try_from(table.len()).unwrap_or(u32::MAX);
    let index = usize::try_from(rnd % len).unwrap_or(0);
    let t = i64::from(table.get(index).copied().unwrap_or(0));
    let mut x = (sigma % DIST_SCALE) * t;
    x += if x >= 0 {
        DIST_SCALE / 2
    } else {
        -DIST_SCALE / 2
    };
    // `/` truncates toward zero in Rust as in C.
    x / DIST_SCALE + (sigma / DIST_SCALE) * t + mu_ns
}

/// netem's correlated uniform source (`get_crandom`).
#[derive(Clone, Debug)]
pub(crate) struct Correlated {
    rho: u32,
    last: u32,
}

impl Correlated {
    /// `correlation` in `0..=1`; the smoothing state starts from one draw of `rng`.
    pub(crate) fn new(correlation: f64, rng: &mut impl RngCore) -> Self {
        Self {
            rho: correlation_to_rho(correlation),
            last: rng.next_u32(),
        }
    }

    pub(crate) fn set_correlation(&mut self, correlation: f64) {
        self.rho = correlation_to_rho(correlation);
    }

    pub(crate) fn next(&mut self, rng: &mut impl RngCore) -> u32 {
        let value = u64::from(rng.next_u32());
        if self.rho == 0 {
            return value as u32;
        }
        let rho = u64::from(self.rho) + 1;
        // Both products are below 2^32·(2^32 − 1), and so is their sum: no overflow.
        let answer = (value * ((1u64 << 32) - rho) + u64::from(self.last) * rho) >> 32;
        self.last = answer as u32;
        self.last
    }
}

fn correlation_to_rho(correlation: f64) -> u32 {
    (correlation.clamp(0.0, 1.0) * f64::from(u32::MAX)).round() as u32
}

/// iproute2's `normal.dist`, built on first use.
pub fn normal_table() -> &'static [i16] {
    static TABLE: OnceLock<Vec<i16>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let quantiles = normal_quantiles();
        table_rows(|i| rint(quantiles[i] * SCALE))
    })
}

/// iproute2's `pareto.dist`, built on first use.
pub fn pareto_table() -> &'static [i16] {
    static TABLE: OnceLock<Vec<i16>> = OnceLock::new();
    TABLE.get_or_init(|| table_rows(pareto_value))
}

/// iproute2's `paretonormal.dist`, built on first use.
pub fn paretonormal_table() -> &'static [i16] {
    static TABLE: OnceLock<Vec<i16>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let quantiles = normal_quantiles();
        // C integer division truncates toward zero, as `/` on i64 does.
        table_rows(|i| (rint(quantiles[i] * SCALE) + 3 * pareto_value(i)) / 4)
    })
}

/// The 4096 entries iproute2 prints: every 4th of 16 384 quantile indices, clamped to `i16`.
fn table_rows(entry: impl Fn(usize) -> i64) -> Vec<i16> {
    (0..TABLESIZE)
        .step_by(4)
        .map(|i| clamp_i16(entry(i)))
        .collect()
}

const TABLESIZE: usize = 16_384;
const SCALE: f64 = DIST_SCALE as f64;

/// `table[i]` = the last grid point x whose `rint(16384·Φ(x))` is `i` (iproute2 `normal.c`).
fn normal_quantiles() -> Vec<f64> {
    let mut table = vec![0.0; TABLESIZE + 1];
    let mut x: f64 = -10.0;
    while x < 10.05 {
        let i = rint(TABLESIZE as f64 * normal_cdf(x)).clamp(0, TABLESIZE as i64);
        if let Some(slot) = table.get_mut(i as usize) {
            *slot = x;
        }
        x += 0.00005;
    }
    table
}

/// iproute2's `paretovalue`: Pareto shape 3, minus its mean 1.5, times 4/3, at quantile index `i`.
fn pareto_value(i: usize) -> i64 {
    let u = (65_536 - 4 * i) as f64 / 65_536.0;
    let mut value = 1.0 / u.powf(1.0 / 3.0);
    value -= 1.5;
    value *= (4.0 / 3.0) * SCALE;
    rint(value.min(32_767.0))
}

/// Φ(x) written as `normal.c` writes it, `½ + ½·erf(x/√2)`; 0 and 1 beyond ±5, where
/// `rint(16384·Φ)` is 0 and 16384 anyway.
fn normal_cdf(x: f64) -> f64 {
    if x < -5.0 {
        0.0
    } else if x > 5.0 {
        1.0
    } else {
        0.5 + 0.5 * erf(x / std::f64::consts::SQRT_2)
    }
}

/// erf(z) = (2/√π)·e^{−z²}·Σₙ z·(2z²)ⁿ/(2n+1)!! — every term has the sign of z, so the sum has no
/// cancellation and is accurate to a few ulp for |z| ≤ 4.
fn erf(z: f64) -> f64 {
    let z2 = z * z;
    let mut term = z;
    let mut sum = z;
    for n in 1..500 {
        term *= 2.0 * z2 / f64::from(2 * n + 1);
        sum += term;
        if term.abs() <= sum.abs() * 1e-17 {
            break;
        }
    }
    std::f64::consts::FRAC_2_SQRT_PI * (-z2).exp() * sum
}

/// C's `rint` in the default rounding mode: round half to even.
fn rint(x: f64) -> i64 {
    x.round_ties_even() as i64
}

fn clamp_i16(x: i64) -> i16 {
    x.clamp(i64::from(i16::MIN), i64::from(i16::MAX)) as i16
}

#[cfg(test)]
mod tests {
    use super::*;

    /// First and last eight entries of iproute2 6.1's shipped tables
    /// (`/usr/lib/x86_64-linux-gnu/tc/*.dist`; a one-off comparison found all 4096 entries of
    /// each table equal).
    #[test]
    fn built_in_tables_match_iproute2() {
        let cases: [(&[i16], [i16; 8], [i16; 8]); 3] = [
            (
                normal_table(),
                [
                    -32768, -28307, -26871, -25967, -25298, -24765, -24320, -23937,
                ],
                [23679, 24027, 24424, 24888, 25450, 26164, 27159, 28858],
            ),
            (
                pareto_table(),
                [-5461, -5460, -5460, -5459, -5458, -5457, -5456, -5455],
                [32767; 8],
            ),
            (
                paretonormal_table(),
                [
                    -12305, -11171, -10812, -10586, -10418, -10284, -10172, -10075,
                ],
                [30495, 30582, 30681, 30797, 30937, 31116, 31365, 31789],
            ),
        ];
        for (table, head, tail) in cases {
            assert_eq!(table.len(), 4096);
            assert_eq!(&table[..8], &head);
            assert_eq!(&table[4088..], &tail);
        }
    }

    #[test]
    fn normal_table_has_unit_sigma() {
        let table = normal_table();
        let n = table.len() as f64;
        let mean = table.iter().map(|&t| f64::from(t)).sum::<f64>() / n;
        let var = table
            .iter()
            .map(|&t| (f64::from(t) - mean).powi(2))
            .sum::<f64>()
            / n;
        assert!(mean.abs() < 0.01 * SCALE, "mean {mean}");
        assert!(
            (var.sqrt() / SCALE - 1.0).abs() < 0.01,
            "sigma {}",
            var.sqrt()
        );
    }

    #[test]
    fn tabledist_rounds_as_the_kernel() {
        // σ = 10 000 ns, t = 8192 (one σ): 1808·8192 + 4096 → 1808 + 1·8192 → μ + σ.
        let table = [8192i16, -8192];
        assert_eq!(tabledist(1_000, 10_000, 0, Some(&table)), 11_000);
        assert_eq!(tabledist(1_000, 10_000, 1, Some(&table)), -9_000);
        // Uniform: rnd % 2σ + μ − σ.
        assert_eq!(tabledist(1_000, 10, 0, None), 990);
        assert_eq!(tabledist(1_000, 10, 19, None), 1_009);
        assert_eq!(tabledist(1_000, 0, 19, None), 1_000);
    }

    #[test]
    fn parses_dist_text_with_comments() {
        let table = DistTable::parse("t", "# comment\n\n 1 -2\t3 # tail\n-32768 32767\n").unwrap();
        assert_eq!(table.entries(), &[1, -2, 3, -32768, 32767]);
    }

    #[test]
    fn dist_errors_name_the_line() {
        let err = DistTable::parse("my.dist", "1 2\n3 x4\n").unwrap_err();
        assert!(matches!(err, DistError::BadEntry { line: 2, ref token, .. } if token == "x4"));
        assert!(err.to_string().contains("my.dist, line 2"), "{err}");

        let err = DistTable::parse("my.dist", "1\n40000\n").unwrap_err();
        assert!(matches!(err, DistError::BadEntry { line: 2, .. }), "{err}");

        let err = DistTable::parse("my.dist", "# only a comment\n").unwrap_err();
        assert!(matches!(err, DistError::Empty { .. }), "{err}");

        let too_long = "0\n".repeat(DIST_MAX + 1);
        let err = DistTable::parse("my.dist", &too_long).unwrap_err();
        assert!(
            matches!(err, DistError::TooLong { line, .. } if line == DIST_MAX + 1),
            "{err}"
        );

        let err = Distribution::from_name_or_path("/nonexistent/x.dist").unwrap_err();
        assert!(err.to_string().contains("/nonexistent/x.dist"), "{err}");
    }

    #[test]
    fn correlation_smooths_the_uniform_source() {
        use rand::SeedableRng;
        let mut rng = rand_pcg::Pcg32::seed_from_u64(7);
        let mut plain = Correlated::new(0.0, &mut rng);
        let mut smooth = Correlated::new(0.9, &mut rng);
        let spread = |c: &mut Correlated, rng: &mut rand_pcg::Pcg32| {
            let xs: Vec<f64> = (0..20_000).map(|_| f64::from(c.next(rng))).collect();
            let mean = xs.iter().sum::<f64>() / xs.len() as f64;
            (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / xs.len() as f64).sqrt()
        };
        let s_plain = spread(&mut plain, &mut rng);
        let s_smooth = spread(&mut smooth, &mut rng);
        // ρ = 0.9 shrinks σ by √((1−ρ)/(1+ρ)) ≈ 0.23 (netem's documented variance loss).
        assert!(s_smooth < 0.3 * s_plain, "{s_smooth} vs {s_plain}");
    }
}
