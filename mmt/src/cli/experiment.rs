//! `mmt experiment`: the thesis's experiments in-process.

use anyhow::{Context, Result};
use clap::Args;
use mmt::experiment::{ExperimentConfig, Kind, run};
use mmt::scene::Scene;
use std::path::PathBuf;
use std::time::Instant;

/// Reproduce thesis experiments 1–3 in-process (deterministic, faster than real time).
#[derive(Args, Debug)]
pub struct ExperimentArgs {
    /// exp1 (no delay), exp2 (estimator, Franka-like sensors), exp3 (400 ms one-way delay).
    name: String,
    /// Scene file (TOML); default: the built-in exp-1 scene.
    #[arg(long)]
    scene: Option<PathBuf>,
    /// One-way delay each way [ms] (default: 0, or 400 for exp3).
    #[arg(long)]
    delay_ms: Option<f64>,
    /// Simulated time [s].
    #[arg(long, default_value_t = 60.0)]
    seconds: f64,
    /// Seed of all noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output directory for report.json, series.csv and plots.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
    /// Scripted trajectory (exp1, exp2, chirp, steps, probe, hold).
    #[arg(long)]
    trajectory: Option<String>,
    /// Detect contact from the telerobot's state only (the thesis's way).
    #[arg(long)]
    remote_contact: bool,
    /// Disable state sync.
    #[arg(long)]
    no_sync: bool,
}

pub fn run_cmd(args: ExperimentArgs) -> Result<()> {
    let kind = Kind::parse(&args.name)?;
    let scene = match &args.scene {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading scene {}", path.display()))?;
            Scene::from_toml(&text, &path.display().to_string())?
        }
        None => Scene::exp1(),
    };
    let mut config = ExperimentConfig::new(kind, scene);
    if let Some(d) = args.delay_ms {
        config.delay_ms = d;
    }
    config.seconds = args.seconds;
    config.seed = args.seed;
    if let Some(t) = args.trajectory {
        config.trajectory = t;
    }
    config.operator.local_contact = !args.remote_contact;
    config.operator.state_sync = !args.no_sync;
    let started = Instant::now();
    let (series, report) = run(&config, &mut |_| {})?;
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir)?;
        std::fs::write(dir.join("series.csv"), series.to_csv())?;
        std::fs::write(
            dir.join("report.json"),
            serde_json::to_string_pretty(&report)?,
        )?;
    }
    let wall = started.elapsed().as_secs_f64();
    if args.json {
        let mut v = serde_json::to_value(&report)?;
        v["wall_seconds"] = serde_json::json!(wall);
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!("{}", serde_json::to_string_pretty(&report)?);
        println!(
            "wall {wall:.2} s ({:.0}× real time)",
            report.sim_seconds / wall
        );
    }
    Ok(())
}
