//! `mmt report FILE.mcap`: the report of the run that made a recording, computed again from it.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;

use crate::recorded::{files, report_file};

/// The report and plots of a recorded run (operator, demo or experiment recording).
#[derive(Args, Debug)]
pub struct ReportArgs {
    /// The recording.
    file: PathBuf,
    /// Write report.json, series.csv and the plots into DIR.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Print the report as JSON instead of the table.
    #[arg(long)]
    json: bool,
}

pub fn run(args: ReportArgs) -> Result<()> {
    let r = report_file(&args.file)?;
    for w in &r.warnings {
        eprintln!("warning: {w}");
    }
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        for (name, bytes) in files(&r)? {
            let path = dir.join(name);
            std::fs::write(&path, bytes).with_context(|| format!("writing {}", path.display()))?;
        }
    }
    if args.json {
        return super::print_json(&r.json);
    }
    print!("{}", metrics::table(&r.experiment));
    if r.networked {
        print!("{}", networked_rows(&r.json));
    }
    if let Some(dir) = &args.out {
        println!(
            "files: {}/report.json, series.csv, force/error/spectrum .svg and .png",
            dir.display()
        );
    }
    Ok(())
}

/// A networked run's own figures, from its report's JSON.
fn networked_rows(j: &serde_json::Value) -> String {
    let num = |v: &serde_json::Value| v.as_f64().map_or("—".to_owned(), |x| format!("{x:.2}"));
    let q = |v: &serde_json::Value| {
        format!(
            "{} / {} / {}",
            num(&v["p50_us"]),
            num(&v["p99_us"]),
            num(&v["max_us"])
        )
    };
    let rows = [
        (
            "measured_delay_ms (rendered leads measured)",
            num(&j["measured_delay_ms"]),
        ),
        ("  set one-way delay [ms]", num(&j["set_delay_ms"])),
        (
            "downlink latency p50 / p99 / max [µs]",
            q(&j["downlink_latency"]),
        ),
        (
            "haptic loop period p50 / p99 / max [µs]",
            q(&j["loop_timing"]["period"]),
        ),
        (
            "datagrams sent / received / lost",
            format!(
                "{} / {} / {}",
                j["link"]["sent"], j["link"]["received"], j["link"]["lost"]
            ),
        ),
        ("missing ticks", j["missing_ticks"].to_string()),
        ("sessions", j["sessions"].to_string()),
        (
            "device state, faults",
            format!("{} / {}", j["device_state"], j["device_faults"]),
        ),
    ];
    let mut out = String::from("network (from the recording)\n");
    for (name, value) in rows {
        out.push_str(&format!("{name:<46} {value:>14}\n"));
    }
    out
}
