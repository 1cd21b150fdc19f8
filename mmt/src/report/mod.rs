//! Reports people can look at: plots (SVG text and PNG bytes, built in memory; the binary writes
//! the files).

pub mod experiment;
pub mod plot;
pub mod spectrum;
