//! `mmt transfer`.

use anyhow::Result;
use clap::Args;
use mmt::model::Physical;
use mmt::render::transfer::transfer;

/// Renderer frequency response against the exact |F/X|.
#[derive(Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct TransferArgs {
    /// Object mass m [kg].
    #[arg(long = "mass")]
    mass_kg: f64,
    /// Ground spring k1 [N/m].
    #[arg(long = "k-ground")]
    k_ground: f64,
    /// Ground damper b1 [N·s/m].
    #[arg(long = "b-ground")]
    b_ground: f64,
    /// Contact spring k2 [N/m].
    #[arg(long = "k-contact")]
    k_contact: f64,
    /// Contact damper b2 [N·s/m].
    #[arg(long = "b-contact")]
    b_contact: f64,
    /// Renderer rate [Hz].
    #[arg(long, default_value_t = 1000.0)]
    rate: f64,
    /// Angular frequencies [rad/s], comma separated.
    #[arg(long, value_delimiter = ',', required = true)]
    omega: Vec<f64>,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

pub fn run(args: TransferArgs) -> Result<()> {
    let p = Physical {
        mass_kg: args.mass_kg,
        k_ground_n_per_m: args.k_ground,
        b_ground_ns_per_m: args.b_ground,
        k_contact_n_per_m: args.k_contact,
        b_contact_ns_per_m: args.b_contact,
        coulomb_n: 0.0,
    };
    let report = transfer(&p, args.rate, &args.omega)?;
    if args.json {
        return super::print_json(&report);
    }
    println!(
        "{:>12} {:>14} {:>14} {:>11}",
        "omega rad/s", "exact |F/X|", "rendered", "rel error"
    );
    for r in &report.rows {
        println!(
            "{:>12.4} {:>14.6} {:>14.6} {:>11.2e}",
            r.omega, r.expected, r.rendered, r.rel_error
        );
    }
    let s = report.accuracy_scope;
    println!(
        "accuracy scope: ρ = h·max|λ| = {:.3}, ζ = {:.3}: {}",
        s.rho,
        s.damping_ratio,
        if s.within {
            "inside (≤ 1e-3 up to a tenth of the rate)"
        } else {
            "outside"
        }
    );
    if let Some(note) = &report.note {
        println!("note: {note}");
    }
    Ok(())
}
