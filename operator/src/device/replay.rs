//! The `replay:FILE.csv` backend: a recorded device trajectory played back as a [`Trajectory`]
//! (so it runs on [`super::scripted::ScriptedBackend`]), and [`ReplayWriter`], which records a run
//! in the same format.
//!
//! Format (comma-separated, UTF-8):
//! ```text
//! t_s,x,y,z[,vx,vy,vz]        header, required, exactly these names
//! 0.000,0.0,0.0,0.0           time [s] since the start of the run, position [m], velocity [m/s]
//! ```
//! Blank lines and lines starting with `#` are ignored. Times must increase strictly; every value
//! must be a finite number. Between samples position (and given velocity) is interpolated
//! linearly; without velocity columns the velocity at each sample is a finite difference (central
//! inside, one-sided at the ends). Before the first and after the last sample the end sample is
//! held with zero velocity.
//!
//! Not a general CSV reader: no quoting, no other columns.
//!
//! `replay:FILE.mcap` plays the device trajectory of a recording (`operator run --record`, the
//! demo's or `mmt experiment`'s): the measured device position and velocity of every recorded
//! haptic tick, timed from the run's first tick ([`ReplayTrajectory::from_recording`]).

use std::io::{self, Write};
use std::path::Path;

use sim::trajectory::{Trajectory, TrajectorySample};

use crate::device::DeviceReading;
use mmt::vec3::{self, Vec3};

/// Header without velocity columns.
pub const HEADER_POSITION: &str = "t_s,x,y,z";
/// Header with velocity columns.
pub const HEADER_FULL: &str = "t_s,x,y,z,vx,vy,vz";
/// The first bytes of an MCAP file.
const MCAP_MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";
const NAMES: [&str; 7] = ["t_s", "x", "y", "z", "vx", "vy", "vz"];

/// Why a replay file was refused. Lines and columns count from 1.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The file could not be read.
    ///
    /// The OS error is in the message and deliberately not the error's `source()`: the app
    /// prints error chains (`{:#}`), which would repeat it.
    #[error("cannot read replay file {file}: {error}")]
    Io {
        /// The file.
        file: String,
        /// The OS error.
        error: io::Error,
    },
    /// The first line is not a known header.
    #[error(
        "{file}: line {line}: expected the header '{HEADER_POSITION}' or '{HEADER_FULL}', found '{found}'"
    )]
    Header {
        /// The file.
        file: String,
        /// Line number.
        line: usize,
        /// What the line held.
        found: String,
    },
    /// A line with a column count different from the header's.
    #[error("{file}: line {line}: expected {expected} columns (as in the header), found {found}")]
    ColumnCount {
        /// The file.
        file: String,
        /// Line number.
        line: usize,
        /// Columns in the header.
        expected: usize,
        /// Columns on this line.
        found: usize,
    },
    /// A field that is not a finite number.
    #[error("{file}: line {line}, column {column} ({name}): expected {expected}, found '{found}'")]
    BadValue {
        /// The file.
        file: String,
        /// Line number.
        line: usize,
        /// Column number.
        column: usize,
        /// Column name.
        name: &'static str,
        /// The field's text.
        found: String,
        /// What was expected ("a number", "a finite number").
        expected: &'static str,
    },
    /// Positions so far apart for their times that the velocity differentiated from them is
    /// not a number a device could have (or not finite at all).
    #[error(
        "{file}: the velocity differentiated around t = {t_s} s (next sample at {next_s} s) is over \
         1,000,000 m/s: samples too close in time for the distance between them"
    )]
    TooFast {
        /// The file.
        file: String,
        /// The sample's time [s].
        t_s: f64,
        /// The next sample's time [s].
        next_s: f64,
    },
    /// A time not after the previous one.
    #[error(
        "{file}: line {line}, column 1 (t_s): time {t_s} s is not after the previous sample's {previous_s} s; times must increase strictly"
    )]
    NonMonotonic {
        /// The file.
        file: String,
        /// Line number.
        line: usize,
        /// This line's time [s].
        t_s: f64,
        /// The previous sample's time [s].
        previous_s: f64,
    },
    /// A recording that cannot be replayed (not ours, another version, another kind).
    #[error("{0}")]
    Recording(#[from] record::ReadError),
    /// No header or no sample.
    #[error(
        "{file}: {what}; expected the header '{HEADER_POSITION}' (or '{HEADER_FULL}') and at least one sample line"
    )]
    Empty {
        /// The file.
        file: String,
        /// What is missing.
        what: &'static str,
    },
}

#[derive(Clone, Copy, Debug)]
struct Sample {
    t_s: f64,
    position_m: Vec3,
    velocity_m_per_s: Vec3,
}

/// A recorded trajectory, checked at load.
#[derive(Clone, Debug)]
pub struct ReplayTrajectory {
    name: String,
    samples: Vec<Sample>,
}

impl ReplayTrajectory {
    /// Reads and checks a replay file: a recording if it is named `.mcap` or starts as an MCAP
    /// file does (the `FILE.mcap.partial` a killed run leaves), the CSV format otherwise.
    pub fn open(path: &Path) -> Result<Self, ReplayError> {
        let mut magic = [0u8; 8];
        let is_mcap = path.extension().is_some_and(|e| e == "mcap")
            || std::fs::File::open(path)
                .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut magic))
                .is_ok_and(|()| magic == *MCAP_MAGIC);
        if is_mcap {
            Self::from_recording(path)
        } else {
            Self::load(path)
        }
    }

    /// Reads and checks a replay file.
    pub fn load(path: &Path) -> Result<Self, ReplayError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|error| ReplayError::Io {
            file: file.clone(),
            error,
        })?;
        Self::parse(&text, &file)
    }

    /// Reads the device trajectory of a recording (`.mcap`): one sample per recorded haptic
    /// tick. Ticks out of order or repeated (a second session's restart) are left out, so times
    /// increase strictly.
    pub fn from_recording(path: &Path) -> Result<Self, ReplayError> {
        let rec = record::read(
            path,
            &[
                record::schema::topic::RUN,
                record::schema::topic::OPERATOR_TICK,
            ],
        )?;
        rec.require(
            &[
                record::Kind::Operator,
                record::Kind::Demo,
                record::Kind::Experiment,
            ],
            "replay:FILE.mcap needs a recording with the haptic loop's ticks (operator run, the \
             demo or mmt experiment)",
        )?;
        let file = path.display().to_string();
        let mut samples: Vec<Sample> = Vec::new();
        for (t_s, position_m, velocity_m_per_s) in record::replay::device_trajectory(&rec) {
            let finite = t_s.is_finite()
                && position_m
                    .iter()
                    .chain(&velocity_m_per_s)
                    .all(|v| v.is_finite());
            if finite && samples.last().is_none_or(|p| t_s > p.t_s) {
                samples.push(Sample {
                    t_s,
                    position_m,
                    velocity_m_per_s,
                });
            }
        }
        if samples.is_empty() {
            return Err(ReplayError::Empty {
                file,
                what: "the recording holds no haptic tick",
            });
        }
        let name = path
            .file_name()
            .map_or_else(|| file.clone(), |n| n.to_string_lossy().into_owned());
        Ok(Self { name, samples })
    }

    /// Parses replay text; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<Self, ReplayError> {
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim()))
            .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
        let (header_line, header) = lines.next().ok_or_else(|| ReplayError::Empty {
            file: file.to_owned(),
            what: "the file is empty",
        })?;
        let header: String = header.chars().filter(|c| !c.is_whitespace()).collect();
        let columns = match header.as_str() {
            HEADER_POSITION => 4,
            HEADER_FULL => 7,
            _ => {
                return Err(ReplayError::Header {
                    file: file.to_owned(),
                    line: header_line,
                    found: header,
                });
            }
        };
        let mut samples: Vec<Sample> = Vec::new();
        for (line, text) in lines {
            let v = parse_row(file, line, text, columns)?;
            if let Some(prev) = samples.last()
                && v[0] <= prev.t_s
            {
                return Err(ReplayError::NonMonotonic {
                    file: file.to_owned(),
                    line,
                    t_s: v[0],
                    previous_s: prev.t_s,
                });
            }
            samples.push(Sample {
                t_s: v[0],
                position_m: [v[1], v[2], v[3]],
                velocity_m_per_s: [v[4], v[5], v[6]],
            });
        }
        if samples.is_empty() {
            return Err(ReplayError::Empty {
                file: file.to_owned(),
                what: "no sample after the header",
            });
        }
        if columns == 4 {
            fill_finite_difference_velocity(&mut samples);
            let fast = samples.iter().position(|s| {
                !s.velocity_m_per_s
                    .iter()
                    .all(|c| c.is_finite() && c.abs() <= MAX_ABS)
            });
            if let Some(i) = fast {
                return Err(ReplayError::TooFast {
                    file: file.to_owned(),
                    t_s: samples[i].t_s,
                    next_s: samples[(i + 1).min(samples.len() - 1)].t_s,
                });
            }
        }
        let name = Path::new(file)
            .file_name()
            .map_or_else(|| file.to_owned(), |n| n.to_string_lossy().into_owned());
        Ok(Self { name, samples })
    }

    /// Number of samples.
    #[must_use]
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// Always false: a loaded replay has at least one sample.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }
}

/// Largest magnitude of a position \[m\] or velocity \[m/s\] in a replay: far beyond any device,
/// and small enough that differences and interpolation stay finite.
const MAX_ABS: f64 = 1e6;

/// Parses one data line into 7 values (velocity zero when absent).
fn parse_row(file: &str, line: usize, text: &str, columns: usize) -> Result<[f64; 7], ReplayError> {
    let found = text.split(',').count();
    if found != columns {
        return Err(ReplayError::ColumnCount {
            file: file.to_owned(),
            line,
            expected: columns,
            found,
        });
    }
    let mut v = [0.0; 7];
    for (i, field) in text.split(',').enumerate() {
        let field = field.trim();
        let bad = |expected| ReplayError::BadValue {
            file: file.to_owned(),
            line,
            column: i + 1,
            name: NAMES[i],
            found: field.to_owned(),
            expected,
        };
        let x: f64 = field.parse().map_err(|_| bad("a number"))?;
        if !x.is_finite() {
            return Err(bad("a finite number"));
        }
        if i > 0 && x.abs() > MAX_ABS {
            return Err(bad(
                "a position or velocity of at most 1,000,000 in magnitude (metres, m/s)",
            ));
        }
        v[i] = x;
    }
    Ok(v)
}

/// Central differences inside, one-sided at the ends; zero for a single sample.
fn fill_finite_difference_velocity(samples: &mut [Sample]) {
    let n = samples.len();
    if n < 2 {
        return;
    }
    for i in 0..n {
        let (a, b) = (samples[i.saturating_sub(1)], samples[(i + 1).min(n - 1)]);
        let dt = b.t_s - a.t_s;
        samples[i].velocity_m_per_s = vec3::scale(vec3::sub(b.position_m, a.position_m), 1.0 / dt);
    }
}

fn lerp(a: Vec3, b: Vec3, w: f64) -> Vec3 {
    vec3::add(a, vec3::scale(vec3::sub(b, a), w))
}

impl Trajectory for ReplayTrajectory {
    fn name(&self) -> &str {
        &self.name
    }

    fn sample(&self, t_s: f64) -> TrajectorySample {
        let (first, last) = match (self.samples.first(), self.samples.last()) {
            (Some(f), Some(l)) => (*f, *l),
            _ => return TrajectorySample::default(),
        };
        let hold = |s: Sample| TrajectorySample {
            position_m: s.position_m,
            velocity_m_per_s: [0.0; 3],
        };
        if t_s.is_nan() || t_s <= first.t_s {
            return hold(first);
        }
        if t_s >= last.t_s {
            return hold(last);
        }
        // first.t_s < t_s < last.t_s, so 1 ≤ i ≤ len − 1.
        let i = self.samples.partition_point(|s| s.t_s <= t_s);
        let (a, b) = (self.samples[i - 1], self.samples[i]);
        let w = (t_s - a.t_s) / (b.t_s - a.t_s);
        TrajectorySample {
            position_m: lerp(a.position_m, b.position_m, w),
            velocity_m_per_s: lerp(a.velocity_m_per_s, b.velocity_m_per_s, w),
        }
    }

    fn duration_s(&self) -> Option<f64> {
        match (self.samples.first(), self.samples.last()) {
            (Some(f), Some(l)) => Some(l.t_s - f.t_s),
            _ => None,
        }
    }
}

/// Writes a run in the replay format (header `t_s,x,y,z,vx,vy,vz`). Values are written with
/// Rust's shortest round-trip formatting, so a replay reproduces the recorded bits.
pub struct ReplayWriter<W: Write> {
    out: W,
}

impl<W: Write> ReplayWriter<W> {
    /// Writes the header.
    pub fn new(mut out: W) -> io::Result<Self> {
        writeln!(out, "{HEADER_FULL}")?;
        Ok(Self { out })
    }

    /// Appends one sample. Refuses non-finite values (the file would not load).
    pub fn write(&mut self, t_s: f64, reading: &DeviceReading) -> io::Result<()> {
        let p = reading.position_m;
        let v = reading.velocity_m_per_s;
        if !(t_s.is_finite() && vec3::is_finite(p) && vec3::is_finite(v)) {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("replay sample at t = {t_s} s has a non-finite value"),
            ));
        }
        writeln!(
            self.out,
            "{t_s},{},{},{},{},{},{}",
            p[0], p[1], p[2], v[0], v[1], v[2]
        )
    }

    /// Flushes and returns the writer.
    pub fn finish(mut self) -> io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

#[cfg(test)]
mod tests;
