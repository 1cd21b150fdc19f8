//! `mmt plot DIR`: the force, error and spectrum plots of an `operator run --out DIR` directory,
//! drawn from its `report.json` and `series.csv` (the operator app links no plotting library).

use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result, bail};
use clap::Args;
use metrics::{Series, Window};
use serde::Deserialize;

/// Draw the plots of an `operator run --out DIR` directory.
#[derive(Args, Debug)]
pub struct PlotArgs {
    /// The directory holding report.json and series.csv; the plots are written next to them.
    #[arg(value_name = "DIR")]
    dir: PathBuf,
}

/// What the plots need from a networked run's `report.json`.
#[derive(Deserialize)]
struct Report {
    series_axes: Axes,
    loop_timing: Timing,
    error_over_time: Vec<Window>,
}

#[derive(Deserialize)]
struct Axes {
    tangent: [f64; 3],
    normal: [f64; 3],
}

#[derive(Deserialize)]
struct Timing {
    nominal_period_us: f64,
}

pub fn run(args: &PlotArgs) -> Result<()> {
    let files = plot_dir(&args.dir)?;
    println!(
        "wrote {} into {}",
        files
            .iter()
            .map(|p| p
                .file_name()
                .map_or(String::new(), |n| n.to_string_lossy().into()))
            .collect::<Vec<_>>()
            .join(", "),
        args.dir.display()
    );
    Ok(())
}

/// Draws the plots of `dir` and writes them there; returns the files written.
pub fn plot_dir(dir: &Path) -> Result<Vec<PathBuf>> {
    let report_path = dir.join("report.json");
    let text = std::fs::read_to_string(&report_path)
        .with_context(|| format!("reading {}", report_path.display()))?;
    let report: Report = serde_json::from_str(&text).with_context(|| {
        format!(
            "{}: not the report of an `operator run --out` directory (`mmt experiment` \
             writes its own plots)",
            report_path.display()
        )
    })?;
    let period_ns = (report.loop_timing.nominal_period_us * 1e3).round() as i64;
    if !(100_000..=1_000_000_000).contains(&period_ns) {
        bail!(
            "{}: loop_timing.nominal_period_us = {}: expected 100 to 1 000 000 µs",
            report_path.display(),
            report.loop_timing.nominal_period_us
        );
    }
    let series_path = dir.join("series.csv");
    let csv = std::fs::read_to_string(&series_path)
        .with_context(|| format!("reading {}", series_path.display()))?;
    let series = Series::from_csv(
        &csv,
        period_ns,
        report.series_axes.tangent,
        report.series_axes.normal,
    )
    .with_context(|| format!("{}", series_path.display()))?;
    let out = rt::OutDir::prepare(dir)?;
    let mut written = Vec::new();
    for (name, bytes) in crate::report::plots(&series, &report.error_over_time)? {
        written.push(out.write_atomic(&name, &bytes)?);
    }
    Ok(written)
}
