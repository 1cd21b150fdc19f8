//! `mmt`: analysis commands over the MMT core. Thin: parse, call the library, print.

mod cli;

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
enum Command {
    /// Time the kd-tree build and the proxy step on a noisy plane (and the same steps by brute
    /// force).
    ContactBench(cli::contact_bench::Args),
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::ContactBench(args) => cli::contact_bench::run(&args),
    }
}
