//! `mmt estimate`.

use crate::analysis::estimate::{EstimateConfig, EstimateReport, estimate};
use anyhow::Result;
use clap::Args;
use mmt::model::backsolve::Confidence;

/// The estimator on the simulated exp-1 object with Franka-like sensor noise.
#[derive(Args, Debug)]
#[command(allow_negative_numbers = true)]
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
    /// Run the estimator on a recorded telerobot measurement stream instead (a telerobot, demo
    /// or experiment recording; the replay robot bridge). Takes the recorded scene's cut-off
    /// and forgetting factor unless --cutoff-hz or --forgetting is given.
    #[arg(long, value_name = "FILE.mcap")]
    from: Option<std::path::PathBuf>,
}

pub fn run(args: EstimateArgs) -> Result<()> {
    if let Some(path) = &args.from {
        return from(path, &args);
    }
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

/// `mmt estimate --from FILE.mcap`.
fn from(path: &std::path::Path, args: &EstimateArgs) -> Result<()> {
    use crate::analysis::estimate_from::{EstimateFromConfig, estimate_from};
    // Only the options given on the command line override the recorded scene's settings.
    let defaults = EstimateConfig::default();
    let config = EstimateFromConfig {
        cutoff_hz: (args.cutoff_hz != defaults.cutoff_hz).then_some(args.cutoff_hz),
        forgetting: (args.forgetting != defaults.forgetting).then_some(args.forgetting),
    };
    let r = estimate_from(path, &config)?;
    if args.json {
        return super::print_json(&r);
    }
    let opt =
        |v: Option<f64>, unit: &str| v.map_or("never".to_string(), |v| format!("{v:.3} {unit}"));
    println!("{}", r.recording);
    println!(
        "replayed {} ticks ({:.1} s) of scene {}, SVF {} Hz, forgetting {}; {} contact episode(s), {} camera frames ({} missing)",
        r.ticks,
        r.seconds,
        r.scene,
        r.cutoff_hz,
        r.forgetting,
        r.contact_onsets,
        r.clouds.0,
        r.clouds.1
    );
    println!(
        "reconstruction error while confident: {}",
        opt(r.reconstruction_error_pct, "%")
    );
    println!(
        "time to stable parameters:           {}",
        opt(r.time_to_stable_s, "s")
    );
    println!(
        "parameters published: {}; the same as the recorded run's: {}",
        r.parameter_messages,
        if r.same_as_recorded {
            "yes, bit for bit"
        } else {
            "no"
        }
    );
    for p in &r.parameters {
        let values: Vec<String> = p
            .values
            .iter()
            .map(|(name, truth, est, err)| {
                format!("{name} {est:.4} (true {truth:.4}, {err:+.1} %)")
            })
            .collect();
        println!("parameters, {}: {}", p.axes, values.join(", "));
    }
    Ok(())
}
