//! The `mmt` subcommands: each parses its arguments, calls the library, times and prints.

pub mod contact_bench;
