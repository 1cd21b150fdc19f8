//! The run-length, loop and report options of `operator run`, the `operator demo` command, and
//! how both print and write their report.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::Context as _;
use clap::Args;
use rt::{PeriodicConfig, Shutdown};

use record::cli::RecordArgs;
use record::{Kind, Recorder, RecorderReport};

use crate::app::{self, Outcome, RunConfig};
use crate::demo::{self, DemoConfig};
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
    /// Write report.json, series.csv and plots (SVG, PNG) into DIR.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Print the report as JSON instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Loop options.
    #[command(flatten)]
    pub rt: RtArgs,
    /// Recording and live view.
    #[command(flatten)]
    pub record: RecordArgs,
}

/// The real-time loop options of `run` and `demo`.
#[derive(Clone, Debug, Args)]
pub struct RtArgs {
    /// Busy-spin before each loop deadline [µs], 0 to 200 (the demo's shim spins half of it).
    #[arg(long, value_name = "US", default_value_t = 100.0)]
    pub spin_us: f64,
    /// Run the loop thread(s) under SCHED_FIFO at this priority (1-99; needs CAP_SYS_NICE).
    #[arg(long, value_name = "PRIO", value_parser = clap::value_parser!(u8).range(1..=99))]
    pub realtime_priority: Option<u8>,
}

/// `operator demo` options.
#[derive(Clone, Debug, Args)]
pub struct DemoArgs {
    /// One-way delay the netem shim adds in each direction [ms].
    #[arg(long, value_name = "MS", default_value_t = 400.0)]
    pub delay_ms: f64,
    /// Length of the run [s].
    #[arg(long, value_name = "S", default_value_t = 20.0)]
    pub seconds: f64,
    /// Where to write report.json, series.csv and the plots.
    #[arg(long, value_name = "DIR", default_value = "out/demo")]
    pub out: PathBuf,
    /// Print the report as JSON instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Loop options (both loops).
    #[command(flatten)]
    pub rt: RtArgs,
    /// Connect the operator to the telerobot directly, without the netem shim (needs
    /// --delay-ms 0): the loopback latency figure.
    #[arg(long)]
    pub no_shim: bool,
    /// Recording (both sides, one file) and live view.
    #[command(flatten)]
    pub record: RecordArgs,
    /// Pause and resume the recorder (file and live view) every S seconds, and print the
    /// haptic-loop period while recording and while paused: what recording costs the loop,
    /// measured in one run (needs --record or --live).
    #[arg(long, value_name = "S")]
    pub record_ab_s: Option<f64>,
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
        node: node::operator::OperatorConfig::default(),
        experiment: "networked".to_owned(),
        known: None,
        record: recorder.as_ref().map(Recorder::sink),
    };
    let outcome = app::run(config, shutdown)?;
    let recorded = recorder.map(Recorder::finish).transpose()?;
    emit(&outcome, args.out.as_deref(), args.json, out)?;
    report_recording(recorded.as_ref(), args.json, out)
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

/// `operator demo`: runs the demo, prints the report and writes its files.
pub fn demo(args: &DemoArgs, shutdown: Shutdown, out: &mut dyn Write) -> anyhow::Result<()> {
    let recorder = args.record.start(Kind::Demo, rt::monotonic_ns())?;
    let config = DemoConfig {
        delay_ms: args.delay_ms,
        seconds: args.seconds,
        spin_us: args.rt.spin_us,
        realtime_priority: args.rt.realtime_priority,
        via_shim: !args.no_shim,
        record: recorder.as_ref().map(Recorder::sink),
        ..DemoConfig::default()
    };
    announce(recorder.as_ref(), args.json, out)?;
    if !args.json {
        let link = if args.no_shim {
            "direct".to_owned()
        } else {
            format!("netem shim ({} ms each way)", args.delay_ms)
        };
        writeln!(
            out,
            "demo: telerobot (exp-1 scene) ⇄ {link} ⇄ operator (scripted:exp1), {} s over loopback QUIC…",
            args.seconds
        )?;
        out.flush()?;
    }
    let toggler = match (args.record_ab_s, &config.record) {
        (None, _) => None,
        (Some(s), Some(sink)) if s.is_finite() && (0.1..=3600.0).contains(&s) => {
            Some(spawn_toggler(sink.clone(), s, shutdown.clone())?)
        }
        (Some(s), Some(_)) => anyhow::bail!("--record-ab-s {s}: expected 0.1 to 3600 seconds"),
        (Some(_), None) => anyhow::bail!("--record-ab-s needs --record or --live"),
    };
    let result = demo::run(&config, shutdown);
    if let Some((stop, thread)) = toggler {
        stop.trigger();
        let _ = thread.join();
    }
    let outcome = result?;
    let recorded = recorder.map(Recorder::finish).transpose()?;
    emit(&outcome, Some(&args.out), args.json, out)?;
    report_recording(recorded.as_ref(), args.json, out)?;
    if args.record_ab_s.is_some()
        && let Some([on, off]) = outcome.record_periods
    {
        let line = format!(
            "haptic loop period, recording: {on}\nhaptic loop period, paused:    {off}\n\
             p99 difference (recording − paused): {:+.1} µs",
            on.p99_us - off.p99_us
        );
        if args.json {
            eprintln!("{line}");
        } else {
            writeln!(out, "{line}")?;
        }
    }
    Ok(())
}

/// Starts the thread that pauses and resumes the recorder every `seconds` (recording first),
/// until the returned stop or `shutdown`.
fn spawn_toggler(
    sink: record::RecordSink,
    seconds: f64,
    shutdown: Shutdown,
) -> anyhow::Result<(Shutdown, std::thread::JoinHandle<()>)> {
    let stop = Shutdown::new();
    let stopped = stop.clone();
    let every = std::time::Duration::from_secs_f64(seconds);
    let thread = std::thread::Builder::new()
        .name("record-ab".to_owned())
        .spawn(move || {
            let mut paused = false;
            while !stopped.wait_timeout(every) && !shutdown.is_triggered() {
                paused = !paused;
                sink.set_paused(paused);
            }
            sink.set_paused(false);
        })
        .context("starting the record-ab thread")?;
    Ok((stop, thread))
}

/// Prints the report (table or JSON) and writes the files.
fn emit(
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
        write!(out, "{}", report::table(&outcome.report))?;
        if let Some(dir) = dir {
            writeln!(
                out,
                "files: {}/report.json, series.csv, force/error/spectrum .svg and .png",
                dir.display()
            )?;
        }
    }
    Ok(())
}
