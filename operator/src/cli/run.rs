//! The run-length, loop and report options of `operator run`, and how it prints and writes its
//! report.

use std::io::Write;
use std::path::PathBuf;

use clap::Args;
use rt::{PeriodicConfig, Shutdown};

use record::cli::RecordArgs;
use record::{Kind, Recorder, RecorderReport};

use crate::app::{self, Outcome, RunConfig};
use crate::device::{DeviceSpec, OpenOptions};
use crate::net::NetConfig;
use crate::report;
use crate::safety::SafetyConfig;

/// `operator run`'s run length, loop and report options.
#[derive(Clone, Debug, Args)]
pub struct LoopArgs {
    /// Stop after this many seconds (default: run until Ctrl-C). It bounds the whole run:
    /// waiting for the telerobot (unreachable, or busy) counts, and the haptic loop runs for
    /// what is left.
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
    /// What is rendered before the first model.
    #[command(flatten)]
    pub prior: PriorArgs,
    /// Recording and live view.
    #[command(flatten)]
    pub record: RecordArgs,
}

/// The real-time loop options of `run` (and of the demo, which runs both loops).
#[derive(Clone, Debug, Args)]
pub struct RtArgs {
    /// Busy-spin before each loop deadline [µs], 0 to 200.
    #[arg(long, value_name = "US", default_value_t = 100.0)]
    pub spin_us: f64,
    /// Run the loop thread(s) under SCHED_FIFO at this priority (1-99; needs CAP_SYS_NICE).
    #[arg(long, value_name = "PRIO", value_parser = rt::thread::parse_priority)]
    pub realtime_priority: Option<u8>,
}

/// What the operator renders from the first tick of contact until the telerobot's first model
/// (`operator run`, the demo and the soak).
#[derive(Clone, Debug, Args)]
pub struct PriorArgs {
    /// What to render from the first tick of contact until the telerobot's first model: scene
    /// (the default: the scene's [prior] when the telerobot's scene declares one, else generic),
    /// generic (the centre of the soft-object class), none (free space), or K,B (the normal's
    /// stiffness in N/m and damping in N·s/m; the tangents keep the generic object).
    #[arg(
        long,
        value_name = "PRIOR",
        default_value = "scene",
        allow_hyphen_values = true
    )]
    pub prior: String,
}

impl PriorArgs {
    /// The operator node's settings with this prior; `--prior` checked.
    pub fn node_config(&self) -> anyhow::Result<node::operator::OperatorConfig> {
        let choice = mmt::model::prior::parse(&self.prior)
            .map_err(|e| anyhow::anyhow!("--prior {}: {e}", self.prior))?;
        Ok(node::operator::OperatorConfig::default().with_prior(choice))
    }
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
    /// The loop schedule; `--spin-us` and `--seconds` checked.
    pub(super) fn periodic(&self) -> Result<PeriodicConfig, LoopArgsError> {
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

/// `operator run` with a telerobot: runs the app, prints and writes the report into `dir`
/// (checked before: `--out`).
pub(super) fn run_cmd(
    args: &LoopArgs,
    dir: Option<rt::OutDir>,
    net: NetConfig,
    (device, open): (DeviceSpec, OpenOptions),
    safety: SafetyConfig,
    shutdown: Shutdown,
    out: &mut dyn Write,
) -> anyhow::Result<()> {
    let periodic = args.periodic()?;
    // On every exit from here (an error included) the recorder is finished or dropped, which
    // closes the file.
    let recorder = args.record.start(Kind::Operator, rt::monotonic_ns())?;
    announce(recorder.as_ref(), args.json, out)?;
    let config = RunConfig {
        net,
        device,
        open,
        safety,
        seconds: args.seconds,
        periodic,
        realtime_priority: args.rt.realtime_priority,
        first_session_timeout: None,
        node: args.prior.node_config()?,
        experiment: "networked".to_owned(),
        known: None,
        record: recorder.as_ref().map(Recorder::sink),
        stream_to: dir.clone(),
        tap: None,
    };
    let outcome = app::run(config, shutdown)?;
    // A recording that fails to close must not cost the run's report: it is written first.
    let recorded = recorder.map(Recorder::finish).transpose();
    emit(&outcome, dir.as_ref(), args.json, out)?;
    report_recording(recorded?.as_ref(), args.json, out)
}

/// Says where the live view is, when there is one.
fn announce(recorder: Option<&Recorder>, json: bool, out: &mut dyn Write) -> anyhow::Result<()> {
    if let Some(addr) = recorder.and_then(Recorder::live_addr) {
        let line = format!("live view: open ws://{addr} in Foxglove or Lichtblick");
        if json {
            eprintln!("{line}");
        } else {
            writeln!(out, "{line}")?;
            out.flush()?;
        }
    }
    Ok(())
}

/// One line on what the recorder did (to stderr under `--json`).
fn report_recording(
    report: Option<&RecorderReport>,
    json: bool,
    out: &mut dyn Write,
) -> anyhow::Result<()> {
    if let Some(r) = report {
        let line = record::cli::summary(r);
        if json {
            eprintln!("{line}");
        } else {
            writeln!(out, "{line}")?;
        }
    }
    Ok(())
}

/// Prints the report (table or JSON) and writes the files (each atomically), printing first:
/// a file that cannot be written then costs the file, not the printed report.
pub fn emit(
    outcome: &Outcome,
    dir: Option<&rt::OutDir>,
    json: bool,
    out: &mut dyn Write,
) -> anyhow::Result<()> {
    if json {
        writeln!(out, "{}", serde_json::to_string_pretty(&outcome.report)?)?;
    } else {
        write!(
            out,
            "{}",
            report::table(&outcome.report, &report::PeerFigures::default())
        )?;
    }
    if let Some(dir) = dir {
        for (name, bytes) in report::files(&outcome.report, &outcome.series)? {
            dir.write_atomic(&name, &bytes)?;
        }
        if !json {
            writeln!(
                out,
                "files: {0}/report.json, series.csv (plots: cargo run --release -p lab -- plot {0})",
                dir.path().display()
            )?;
        }
    }
    Ok(())
}
