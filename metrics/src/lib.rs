//! # metrics — a run's figures, computed the same way in-process and over the network
//!
//! What it is: the time series a run records ([`Series`], one row per operator tick, measured
//! and rendered force aligned by the command's sample time, and its CSV form), the report
//! computed from it ([`analyse`] → [`ExperimentReport`]: RMS error from first contact and after
//! stable, per band and over time, time to stable, reconstruction error, contact-switch latency,
//! parameter errors against a known truth), the spectra behind the bands ([`spectrum`]) and the
//! stdout [`table`]. The in-process harness (`lab`) and the networked operator app build the
//! same [`Series`] and print the same report; [`networked`] builds a networked run's series and
//! figures from what the operator recorded, for the app and for `mmt report FILE.mcap` alike.
//!
//! What it is not: no plots (those are `lab`'s), no files, no clock.

mod analyse;
mod csv;
pub mod networked;
pub mod onset;
mod series;
pub mod spectrum;
mod table;

pub use analyse::{
    BANDS, Band, ContactLatency, EstimatorReport, ExperimentReport, NodeInfo, ParameterReport,
    RunInfo, ThesisFigures, Window, analyse, parameter_report,
};
pub use csv::{CSV_HEADER, CsvError};
pub use series::Series;
pub use table::table;
