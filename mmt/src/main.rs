//! `mmt`: analysis commands over the MMT core. Thin: parse, call the library, print.

use anyhow::Result;
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "mmt",
    about = "Model-mediated teleoperation: analysis commands"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {}

// `Command` has no variant yet, so everything after parsing is unreachable; drop this allow with
// the first subcommand.
#[allow(unreachable_code, unused_variables)]
fn main() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {}
}
