//! Analyses behind the `mmt` commands. Pure: they return report structs; the binary prints them,
//! writes files and (where a figure is a time) passes in the clock.

pub mod estimate;
pub mod estimate_from;
pub mod stress;
pub mod work_precision;
