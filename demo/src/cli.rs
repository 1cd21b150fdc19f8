//! The `demo` command line: options, the run, the report printed and written.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context as _;
use clap::Parser;
use operator::cli::{PriorArgs, RtArgs};
use rt::Shutdown;

use crate::report::{banner, files, table};
use crate::run::{DemoConfig, run};

/// The whole model-mediated teleoperation system in one process over loopback QUIC/UDP: the
/// telerobot daemon on the built-in exp-1 scene, the netem shim delaying each direction, the
/// operator app with the scripted exp-1 device; then the report, its series and its plots.
#[derive(Clone, Debug, Parser)]
#[command(name = "demo", version, about, allow_negative_numbers = true)]
pub struct Cli {
    /// One-way delay the netem shim adds in each direction [ms].
    #[arg(
        long,
        value_name = "MS",
        default_value_t = 400.0,
        allow_hyphen_values = true
    )]
    pub delay_ms: f64,
    /// Length of the run [s].
    #[arg(
        long,
        value_name = "S",
        default_value_t = 20.0,
        allow_hyphen_values = true
    )]
    pub seconds: f64,
    /// Seed of the simulated telerobot (its sensors' noise and its camera): the same seed gives
    /// the same world, the run differing only by the machine's timing.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub seed: u64,
    /// Where to write report.json, series.csv and the plots.
    #[arg(long, value_name = "DIR", default_value = "out/demo")]
    pub out: PathBuf,
    /// Print the report as JSON instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Loop options (both loops; the shim spins half the window).
    #[command(flatten)]
    pub rt: RtArgs,
    /// What the operator renders before the first model.
    #[command(flatten)]
    pub prior: PriorArgs,
    /// Connect the operator to the telerobot directly, without the netem shim (needs
    /// --delay-ms 0): the loopback latency figure.
    #[arg(long)]
    pub no_shim: bool,
    /// Recording (both sides, one file) and live view.
    #[command(flatten)]
    pub record: record::cli::RecordArgs,
    /// Pause and resume the recorder (file and live view) every S seconds, and print the
    /// haptic-loop period while recording and while paused: what recording costs the loop,
    /// measured in one run (needs --record or --live).
    #[arg(long, value_name = "S")]
    pub record_ab_s: Option<f64>,
}

/// Runs the demo, prints the report and writes its files.
pub fn run_cmd(args: &Cli, shutdown: Shutdown, out: &mut dyn Write) -> anyhow::Result<()> {
    match args.record_ab_s {
        Some(s) if !(s.is_finite() && (0.1..=3600.0).contains(&s)) => {
            anyhow::bail!("--record-ab-s {s}: expected 0.1 to 3600 seconds")
        }
        Some(_) if args.record == record::cli::RecordArgs::default() => {
            anyhow::bail!("--record-ab-s needs --record or --live")
        }
        _ => {}
    }
    let mut config = DemoConfig {
        delay_ms: args.delay_ms,
        seconds: args.seconds,
        spin_us: args.rt.spin_us,
        realtime_priority: args.rt.realtime_priority,
        via_shim: !args.no_shim,
        seed: args.seed,
        node: args.prior.node_config()?,
        ..DemoConfig::default()
    };
    config.validate()?;
    // Checked before the run: a path that cannot be written must not cost the session.
    let dir = rt::OutDir::prepare(&args.out)?;
    config.stream_to = Some(dir.clone());
    // Created (and checked) before the run; finished below, or dropped (closed) on an error.
    let recorder = args.record.start(record::Kind::Demo, rt::monotonic_ns())?;
    config.record = recorder.as_ref().map(record::Recorder::sink);
    let live = recorder.as_ref().and_then(record::Recorder::live_addr);
    say(
        args.json,
        out,
        live.map(|a| format!("live view: open ws://{a} in Foxglove or Lichtblick")),
    )?;
    let toggler = match (args.record_ab_s, &config.record) {
        (Some(s), Some(sink)) => Some(
            record::cli::Toggler::start(sink.clone(), std::time::Duration::from_secs_f64(s))
                .context("starting the record-ab thread")?,
        ),
        _ => None,
    };
    if !args.json {
        writeln!(
            out,
            "{}",
            banner(args.delay_ms, args.seconds, !args.no_shim, args.seed)
        )?;
        out.flush()?;
    }
    let outcome = run(&config, shutdown);
    drop(toggler);
    let outcome = outcome?;
    // A recording that fails to close must not cost the run's report: it is written first.
    let recorded = recorder.map(record::Recorder::finish).transpose();
    for (name, bytes) in files(&outcome.report, &outcome.series)? {
        dir.write_atomic(&name, &bytes)?;
    }
    if args.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&outcome.report)?)?;
    } else {
        write!(out, "{}", table(&outcome.report))?;
        writeln!(
            out,
            "files: {}/report.json, series.csv, force/error/spectrum .svg and .png",
            dir.path().display()
        )?;
    }
    say(args.json, out, recorded?.as_ref().map(record::cli::summary))?;
    if let (Some(_), Some([on, off])) = (args.record_ab_s, outcome.record_periods) {
        let line = format!(
            "haptic loop period, recording: {on}\nhaptic loop period, paused:    {off}\n\
             p99 difference (recording − paused): {:+.1} µs",
            on.p99_us - off.p99_us
        );
        say(args.json, out, Some(line))?;
    }
    Ok(())
}

/// A line for the user: on stdout, or on stderr under `--json` (stdout is the report).
fn say(json: bool, out: &mut dyn Write, line: Option<String>) -> anyhow::Result<()> {
    if let Some(line) = line {
        if json {
            eprintln!("{line}");
        } else {
            writeln!(out, "{line}")?;
            out.flush()?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_and_the_ranges_are_checked() {
        let args = Cli::try_parse_from(["demo"]).unwrap();
        assert_eq!((args.delay_ms, args.seconds), (400.0, 20.0));
        assert_eq!(args.out, PathBuf::from("out/demo"));
        assert_eq!(args.seed, 1);
        assert_eq!(
            Cli::try_parse_from(["demo", "--seed", "7"]).unwrap().seed,
            7
        );
        for bad in ["-1", "x", "1.5"] {
            let e = Cli::try_parse_from(["demo", "--seed", bad]).unwrap_err();
            assert!(e.to_string().contains("--seed"), "{bad}: {e}");
        }
        for (flags, expected) in [
            (&["--seconds", "1"][..], "--seconds = 1 is out of range"),
            (&["--delay-ms", "-5"][..], "--delay-ms = -5 is out of range"),
            (&["--delay-ms", "5", "--no-shim"][..], "without the shim"),
            // Issue 11: a negative value was taken for a flag ("unexpected argument '-1'").
            (&["--record-ab-s", "-1"][..], "--record-ab-s -1: expected"),
            (&["--spin-us", "-3"][..], "--spin-us = -3 is out of range"),
        ] {
            let args =
                Cli::try_parse_from(std::iter::once("demo").chain(flags.iter().copied())).unwrap();
            let mut printed = Vec::new();
            let e = run_cmd(&args, Shutdown::new(), &mut printed).unwrap_err();
            assert!(e.to_string().contains(expected), "{flags:?}: {e}");
            assert!(
                printed.is_empty(),
                "nothing printed before the check: {flags:?}"
            );
        }
        let e = Cli::try_parse_from(["demo", "--realtime-priority", "100"]).unwrap_err();
        assert!(e.to_string().contains("--realtime-priority"), "{e}");
    }

    /// Before: `--out` naming a file was found after the whole run, and the run was lost.
    #[test]
    fn an_out_path_that_is_a_file_is_refused_before_the_run() {
        let file = std::env::temp_dir().join(format!("demo-out-file-{}", std::process::id()));
        std::fs::write(&file, "x").unwrap();
        let args = Cli::try_parse_from(["demo", "--out", file.to_str().unwrap()]).unwrap();
        let mut printed = Vec::new();
        let started = std::time::Instant::now();
        let e = run_cmd(&args, Shutdown::new(), &mut printed).unwrap_err();
        assert!(
            e.to_string().ends_with("exists and is not a directory"),
            "{e}"
        );
        assert!(printed.is_empty(), "the banner came before the check");
        assert!(started.elapsed().as_secs() < 5, "the demo ran first");
        std::fs::remove_file(&file).unwrap();
    }
}
