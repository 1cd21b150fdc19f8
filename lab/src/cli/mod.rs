//! The binary's command implementations: argument structs, printing, timing, files.

pub mod benchmark;
pub mod cloud_budget;
pub mod contact_bench;
pub mod estimate;
pub mod experiment;
pub mod plot;
pub mod report;
pub mod stress;
pub mod transfer;
pub mod work_precision;

/// Prints `value` as pretty JSON on stdout.
pub fn print_json<T: serde::Serialize>(value: &T) -> anyhow::Result<()> {
    println!("{}", serde_json::to_string_pretty(value)?);
    Ok(())
}
