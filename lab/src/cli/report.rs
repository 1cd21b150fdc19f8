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
    /// Compare with the live run's report.json: print every value that differs (none: "same
    /// figures"), and exit non-zero if any does.
    #[arg(long, value_name = "REPORT.json")]
    against: Option<PathBuf>,
}

pub fn run(args: ReportArgs) -> Result<()> {
    let started = std::time::Instant::now();
    let dir = args.out.as_deref().map(rt::OutDir::prepare).transpose()?;
    let r = report_file(&args.file)?;
    for w in &r.warnings {
        eprintln!("warning: {w}");
    }
    if let Some(dir) = &dir {
        for (name, bytes) in files(&r)? {
            dir.write_atomic(&name, &bytes)?;
        }
    }
    // On stderr: the report on stdout stays the run's.
    eprintln!(
        "{} read and reported in {:.2} s",
        args.file.display(),
        started.elapsed().as_secs_f64()
    );
    if let Some(live) = &args.against {
        return against(&r.json, live);
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

/// `--against REPORT.json`.
fn against(recorded: &serde_json::Value, live: &std::path::Path) -> Result<()> {
    let text =
        std::fs::read_to_string(live).with_context(|| format!("reading {}", live.display()))?;
    let mut live_json: serde_json::Value = serde_json::from_str(&text)
        .with_context(|| format!("{}: expected a run's report.json", live.display()))?;
    // The run's wall time is not a figure of the run (mmt experiment --json adds it; a
    // networked run's recording has it).
    let mut recorded = recorded.clone();
    for json in [&mut live_json, &mut recorded] {
        if let Some(o) = json.as_object_mut() {
            o.remove("wall_seconds");
        }
    }
    let mut differences = Vec::new();
    differ(&live_json, &recorded, String::new(), &mut differences);
    if differences.is_empty() {
        println!(
            "same figures: every value of {} is the recording's",
            live.display()
        );
        return Ok(());
    }
    for d in &differences {
        println!("{d}");
    }
    anyhow::bail!(
        "{} value(s) of {} differ from the recording's",
        differences.len(),
        live.display()
    )
}

/// Every path where `live` and `recorded` differ.
fn differ(
    live: &serde_json::Value,
    recorded: &serde_json::Value,
    at: String,
    out: &mut Vec<String>,
) {
    use serde_json::Value;
    match (live, recorded) {
        (Value::Object(a), Value::Object(b)) => {
            for (k, v) in a {
                match b.get(k) {
                    Some(w) => differ(v, w, format!("{at}.{k}"), out),
                    None => out.push(format!("{at}.{k}: not in the recording's report")),
                }
            }
            for k in b.keys().filter(|k| !a.contains_key(*k)) {
                out.push(format!("{at}.{k}: only in the recording's report"));
            }
        }
        (Value::Array(a), Value::Array(b)) if a.len() == b.len() => {
            for (i, (v, w)) in a.iter().zip(b).enumerate() {
                differ(v, w, format!("{at}[{i}]"), out);
            }
        }
        (a, b) if a != b => out.push(format!("{at}: live {a}, recording {b}")),
        _ => {}
    }
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
