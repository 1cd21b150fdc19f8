//! `mmt estimate`.

use crate::analysis::estimate::{EstimateConfig, EstimateReport, estimate};
use anyhow::Result;
use clap::Args;
use mmt::model::backsolve::Confidence;

/// The estimator on the simulated exp-1 object with Franka-like sensor noise.
#[derive(Args, Debug)]
pub struct EstimateArgs {
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// Contact time simulated [s].
    #[arg(long, default_value_t = EstimateConfig::default().seconds)]
    seconds: f64,
    /// Sensor-noise seed.
    #[arg(long, default_value_t = EstimateConfig::default().seed)]
    seed: u64,
    /// State-variable filter cut-off [Hz].
    #[arg(long, default_value_t = EstimateConfig::default().cutoff_hz)]
    cutoff_hz: f64,
    /// Forgetting factor per 1 ms tick.
    #[arg(long, default_value_t = EstimateConfig::default().forgetting)]
    forgetting: f64,
}

pub fn run(args: EstimateArgs) -> Result<()> {
    let report = estimate(&EstimateConfig {
        seconds: args.seconds,
        seed: args.seed,
        cutoff_hz: args.cutoff_hz,
        forgetting: args.forgetting,
    })?;
    if args.json {
        return super::print_json(&report);
    }
    print_summary(&report);
    print_parameters(&report);
    Ok(())
}

/// The run's set-up, its figures against the thesis's, and the back-solve's confidence.
fn print_summary(report: &EstimateReport) {
    let opt =
        |v: Option<f64>, unit: &str| v.map_or("never".to_string(), |v| format!("{v:.3} {unit}"));
    println!(
        "exp-1 object, Franka-like noise, {} s of contact, SVF {} Hz",
        report.seconds, report.cutoff_hz
    );
    println!(
        "reconstruction error after stable: {}   (thesis exp 2: ~5 %)",
        opt(report.reconstruction_error_pct, "%")
    );
    println!(
        "time to stable parameters:         {}   (thesis exp 2: 16.1 s)",
        opt(report.time_to_stable_s, "s")
    );
    let confidence = match report.confidence {
        None => "-".to_string(),
        Some(Confidence::Identified) => "identified".to_string(),
        Some(Confidence::Low { .. }) => "LOW (parameter errors amplified)".to_string(),
    };
    println!(
        "back-solve confidence:             {confidence}, condition {}; {} of {} confirmed sets low-confidence",
        report
            .condition
            .map_or("-".to_string(), |c| format!("{c:.1}")),
        report.low_confidence_updates,
        report.confirmed_updates
    );
}

/// True and estimated parameters, with the relative error of each.
fn print_parameters(report: &EstimateReport) {
    let t = report.truth;
    println!(
        "{:<22} {:>12} {:>12} {:>9}",
        "parameter", "true", "estimated", "error"
    );
    let rows: [(&str, f64, Option<f64>, Option<f64>); 5] = [
        (
            "m [kg]",
            t.mass_kg,
            report.estimated.map(|e| e.mass_kg),
            report.error_pct.map(|e| e.mass),
        ),
        (
            "b1 [N·s/m]",
            t.b_ground_ns_per_m,
            report.estimated.map(|e| e.b_ground_ns_per_m),
            report.error_pct.map(|e| e.b_ground),
        ),
        (
            "k2 [N/m]",
            t.k_contact_n_per_m,
            report.estimated.map(|e| e.k_contact_n_per_m),
            report.error_pct.map(|e| e.k_contact),
        ),
        (
            "b2 [N·s/m]",
            t.b_contact_ns_per_m,
            report.estimated.map(|e| e.b_contact_ns_per_m),
            report.error_pct.map(|e| e.b_contact),
        ),
        (
            "Fc [N]",
            t.coulomb_n,
            report.estimated.map(|e| e.coulomb_n),
            report.error_pct.map(|e| e.coulomb),
        ),
    ];
    for (name, truth, est, err) in rows {
        let est = est.map_or("-".to_string(), |v| format!("{v:.4}"));
        let err = err.map_or("-".to_string(), |v| format!("{v:+.1} %"));
        println!("{name:<22} {truth:>12.4} {est:>12} {err:>9}");
    }
}
