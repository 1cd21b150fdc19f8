//! The run-length, loop and report options of `operator run`, and how it prints and writes its
//! report.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::Context as _;
use clap::Args;
use rt::{PeriodicConfig, Shutdown};

use crate::app::{self, Outcome, RunConfig};
use crate::device::{DeviceSpec, OpenOptions};
use crate::net::NetConfig;
use crate::report;
use crate::safety::SafetyConfig;

/// `operator run`'s run length, loop and report options.
#[derive(Clone, Debug, Args)]
pub struct LoopArgs {
    /// Stop after this many seconds of haptic loop (default: run until Ctrl-C).
    #[arg(long, value_name = "S")]
    pub seconds: Option<f64>,
    /// Write report.json and series.csv into DIR (`mmt plot DIR` draws the plots).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Print the report as JSON instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Loop options.
    #[command(flatten)]
    pub rt: RtArgs,
}

/// The real-time loop options of `run` (and of the demo, which runs both loops).
#[derive(Clone, Debug, Args)]
pub struct RtArgs {
    /// Busy-spin before each loop deadline [µs], 0 to 200.
    #[arg(long, value_name = "US", default_value_t = 100.0)]
    pub spin_us: f64,
    /// Run the loop thread(s) under SCHED_FIFO at this priority (1-99; needs CAP_SYS_NICE).
    #[arg(long, value_name = "PRIO", value_parser = clap::value_parser!(u8).range(1..=99))]
    pub realtime_priority: Option<u8>,
}

/// Why the loop options are refused.
#[derive(Debug, thiserror::Error)]
pub enum LoopArgsError {
    /// `--seconds` out of range.
    #[error("--seconds {0}: expected 1 to 86 400 s")]
    Seconds(f64),
    /// `--spin-us` out of range.
    #[error("--spin-us {0}: expected 0 to 200 µs")]
    Spin(f64),
}

impl LoopArgs {
    fn periodic(&self) -> Result<PeriodicConfig, LoopArgsError> {
        let spin = self.rt.spin_us;
        if !(spin.is_finite() && (0.0..=200.0).contains(&spin)) {
            return Err(LoopArgsError::Spin(spin));
        }
        if let Some(s) = self.seconds
            && !(s.is_finite() && (1.0..=86_400.0).contains(&s))
        {
            return Err(LoopArgsError::Seconds(s));
        }
        Ok(PeriodicConfig {
            spin_ns: (spin * 1e3).round() as i64,
            ..PeriodicConfig::default()
        })
    }
}

/// `operator run` with a telerobot: runs the app, prints and writes the report.
pub(super) fn run_cmd(
    args: &LoopArgs,
    net: NetConfig,
    device: DeviceSpec,
    open: OpenOptions,
    safety: SafetyConfig,
    shutdown: Shutdown,
    out: &mut dyn Write,
) -> anyhow::Result<()> {
    let config = RunConfig {
        net,
        device,
        open,
        safety,
        seconds: args.seconds,
        periodic: args.periodic()?,
        realtime_priority: args.rt.realtime_priority,
        first_session_timeout: None,
        node: node::operator::OperatorConfig::default(),
        experiment: "networked".to_owned(),
        known: None,
    };
    let outcome = app::run(config, shutdown)?;
    emit(&outcome, args.out.as_deref(), args.json, out)
}

/// Prints the report (table or JSON) and writes the files.
pub fn emit(
    outcome: &Outcome,
    dir: Option<&Path>,
    json: bool,
    out: &mut dyn Write,
) -> anyhow::Result<()> {
    if let Some(dir) = dir {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        for (name, bytes) in report::files(&outcome.report, &outcome.series)? {
            let path = dir.join(name);
            std::fs::write(&path, bytes).with_context(|| format!("writing {}", path.display()))?;
        }
    }
    if json {
        writeln!(out, "{}", serde_json::to_string_pretty(&outcome.report)?)?;
    } else {
        write!(
            out,
            "{}",
            report::table(&outcome.report, &report::PeerFigures::default())
        )?;
        if let Some(dir) = dir {
            writeln!(
                out,
                "files: {0}/report.json, series.csv (plots: cargo run --release -p lab -- plot {0})",
                dir.display()
            )?;
        }
    }
    Ok(())
}
