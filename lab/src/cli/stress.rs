//! `mmt stress`.

use crate::analysis::stress::stress;
use anyhow::Result;
use clap::Args;

/// The renderer on extreme and garbage inputs.
#[derive(Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct StressArgs {
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

pub fn run(args: StressArgs) -> Result<()> {
    let report = stress();
    if args.json {
        return super::print_json(&report);
    }
    for c in &report.cases {
        println!(
            "{:<52} max|F| {:>12.4e} N  finite {:<5}  {}",
            c.name, c.max_abs_force_n, c.all_finite, c.gate
        );
        if let Some(d) = &c.detail {
            println!("{:<52} {d}", "");
        }
    }
    Ok(())
}
