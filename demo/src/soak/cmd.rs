//! The `soak` command line: the options, the monitor that writes a row a minute, the verdict.

use std::io::Write;
use std::path::PathBuf;
use std::sync::mpsc::Receiver;

use anyhow::Context as _;
use clap::Parser;
use operator::cli::{PriorArgs, RtArgs};
use operator::helper::{Tap, Tapped};
use rt::Shutdown;
use serde::Serialize;

use super::{Minute, Minutes, Verdict, process_usage};
use crate::run::{DemoConfig, run};

/// The networked demo for a long time over a lossy, jittery delayed link — the telerobot
/// daemon, the netem shim and the operator app in one process, as `demo` runs them — with a row
/// a minute: memory and CPU of the process, the rendered-force error, the haptic loop's
/// overruns and skipped ticks, the outages.
#[derive(Clone, Debug, Parser)]
#[command(name = "soak", version, about, allow_negative_numbers = true)]
pub struct SoakCli {
    /// Length of the run [min], 1 to 1440.
    #[arg(
        long,
        value_name = "MIN",
        default_value_t = 60.0,
        allow_hyphen_values = true
    )]
    pub minutes: f64,
    /// One-way delay the shim adds in each direction [ms], 0 to 2000.
    #[arg(
        long,
        value_name = "MS",
        default_value_t = 400.0,
        allow_hyphen_values = true
    )]
    pub delay_ms: f64,
    /// Random loss the shim adds in each direction [%], 0 to 50.
    #[arg(
        long,
        value_name = "PCT",
        default_value_t = 2.0,
        allow_hyphen_values = true
    )]
    pub loss_pct: f64,
    /// Uniform jitter (half-width) the shim adds in each direction [ms], 0 to 100.
    #[arg(
        long,
        value_name = "MS",
        default_value_t = 2.0,
        allow_hyphen_values = true
    )]
    pub jitter_ms: f64,
    /// Seed of the simulated telerobot.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Where to write minutes.csv (a row a minute, as the run goes) and soak.json (at the end).
    #[arg(long, value_name = "DIR", default_value = "out/soak")]
    pub out: PathBuf,
    /// Loop options (both loops; the shim spins half the window).
    #[command(flatten)]
    pub rt: RtArgs,
    /// What the operator renders before the first model.
    #[command(flatten)]
    pub prior: PriorArgs,
    /// Run nothing: print the verdict of the rows of an earlier soak's soak.json (as this
    /// version judges them).
    #[arg(long, value_name = "SOAK_JSON")]
    pub verdict: Option<PathBuf>,
}

/// minutes.csv's columns.
const HEADER: &str = "minute,ticks,measurements,in_contact_pct,error_pct,error_after_stable_pct,\
                      outages,longest_outage_ms,overruns,skipped_ticks,rss_mb,cpu_pct,models";

/// What soak.json holds.
#[derive(Debug, Serialize)]
struct SoakFile<'a> {
    minutes_asked: f64,
    delay_ms: f64,
    loss_pct: f64,
    jitter_ms: f64,
    seed: u64,
    /// Full minutes.
    rows: &'a [Minute],
    /// The run's last seconds after the last full minute (figures over fewer ticks, their last
    /// measurements never back): not a minute of the verdict.
    partial: Option<Minute>,
    verdict: &'a Verdict,
    /// The demo's own report: its experiment figures cover the first minute (the run keeps only
    /// that in memory); the loop, link, telerobot and shim counters cover the whole run.
    end_report: Option<&'a crate::DemoReport>,
}

/// Runs the soak, printing a row a minute to `rows` and the verdict to `out`.
pub fn run_cmd(
    args: &SoakCli,
    shutdown: Shutdown,
    rows: Box<dyn Write + Send>,
    out: &mut dyn Write,
) -> anyhow::Result<()> {
    if let Some(path) = &args.verdict {
        return verdict_of(path, out);
    }
    let (to, from) = std::sync::mpsc::channel();
    // A minute's figures wait for its measurements: a round trip, the jitter and a margin. The
    // run goes on that long after its last minute, so that the last minute is a full one.
    let lag_s = 2.0 * (args.delay_ms + args.jitter_ms).max(0.0) / 1e3 + 2.0;
    let mut config = DemoConfig {
        delay_ms: args.delay_ms,
        seconds: args.minutes * 60.0 + lag_s + 1.0,
        spin_us: args.rt.spin_us,
        realtime_priority: args.rt.realtime_priority,
        seed: args.seed,
        node: args.prior.node_config()?,
        loss_pct: args.loss_pct,
        jitter_ms: args.jitter_ms,
        tap: Some(Tap {
            to,
            keep_ticks: 60_000,
        }),
        ..DemoConfig::default()
    };
    if !(1.0..=1440.0).contains(&args.minutes) {
        anyhow::bail!(
            "--minutes = {} is out of range: expected 1 to 1440 minutes",
            args.minutes
        );
    }
    config.validate()?;
    // Checked before the run; minutes.csv is written as it goes.
    let dir = rt::OutDir::prepare(&args.out)?;
    let stream = dir.stream("minutes.csv", HEADER)?;
    let minutes = Minutes::new("soak", args.delay_ms, lag_s);
    let monitor = std::thread::Builder::new()
        .name("soak-monitor".to_owned())
        .spawn(move || monitor(&from, minutes, stream, rows))?;
    let outcome = run(&config, shutdown);
    // The helper's sender went with the run; this one goes now, and the monitor ends.
    config.tap = None;
    let (full, partial) = monitor
        .join()
        .map_err(|_| anyhow::anyhow!("the soak monitor panicked"))?;
    let verdict = Verdict::of(&full);
    let outcome = outcome?;
    let file = SoakFile {
        minutes_asked: args.minutes,
        delay_ms: args.delay_ms,
        loss_pct: args.loss_pct,
        jitter_ms: args.jitter_ms,
        seed: args.seed,
        rows: &full,
        partial,
        verdict: &verdict,
        end_report: Some(&outcome.report),
    };
    dir.write_atomic("soak.json", &serde_json::to_vec_pretty(&file)?)?;
    write!(out, "{}", summary(&verdict, Some(&outcome.report)))?;
    writeln!(
        out,
        "files: {}/minutes.csv, soak.json",
        dir.path().display()
    )?;
    Ok(())
}

/// The verdict of an earlier soak's rows.
fn verdict_of(path: &std::path::Path, out: &mut dyn Write) -> anyhow::Result<()> {
    #[derive(serde::Deserialize)]
    struct Rows {
        rows: Vec<Minute>,
    }
    let text = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let file: Rows = serde_json::from_slice(&text)
        .with_context(|| format!("{}: not a soak.json (its \"rows\")", path.display()))?;
    write!(out, "{}", summary(&Verdict::of(&file.rows), None))?;
    Ok(())
}

/// Takes the tapped samples until the run ends; writes and prints a row per full minute.
/// Returns the full minutes and the last partial one.
fn monitor(
    from: &Receiver<Tapped>,
    mut minutes: Minutes,
    mut stream: rt::out::Stream,
    mut rows: Box<dyn Write + Send>,
) -> (Vec<Minute>, Option<Minute>) {
    let mut full = Vec::new();
    let mut last = (
        std::time::Instant::now(),
        process_usage().map_or(0.0, |u| u.1),
    );
    let _ = writeln!(
        rows,
        "minute  ticks   contact  error   after-stable  outages (longest)  overruns  skipped  RSS       CPU      models"
    );
    let mut stamp = |mut m: Minute| {
        let (rss, cpu) = process_usage().unwrap_or_default();
        let wall = last.0.elapsed().as_secs_f64().max(1e-3);
        m.rss_mb = rss;
        m.cpu_pct = 100.0 * (cpu - last.1) / wall;
        last = (std::time::Instant::now(), cpu);
        m
    };
    while let Ok(tapped) = from.recv() {
        for m in minutes.take(tapped) {
            let m = stamp(m);
            stream.line(&csv_row(&m));
            stream.flush();
            let _ = writeln!(rows, "{}", table_row(&m));
            let _ = rows.flush();
            full.push(m);
        }
    }
    let partial = minutes.finish().map(&mut stamp);
    (full, partial)
}

fn opt(v: Option<f64>) -> String {
    v.map_or(String::new(), |v| format!("{v:.3}"))
}

fn csv_row(m: &Minute) -> String {
    format!(
        "{},{},{},{:.2},{},{},{},{:.1},{},{},{:.1},{:.1},{}",
        m.minute,
        m.ticks,
        m.measurements,
        m.in_contact_pct,
        opt(m.error_pct),
        opt(m.error_after_stable_pct),
        m.outages,
        m.longest_outage_ms,
        m.overruns,
        m.skipped_ticks,
        m.rss_mb,
        m.cpu_pct,
        m.models
    )
}

fn table_row(m: &Minute) -> String {
    let pct = |v: Option<f64>| v.map_or("–".to_owned(), |v| format!("{v:.2} %"));
    format!(
        "{:>6}  {:>6}  {:>5.1} %  {:>7}  {:>12}  {:>7} ({:>5.0} ms)  {:>8}  {:>7}  {:>6.1} MB  {:>5.1} %  {:>6}",
        m.minute,
        m.ticks,
        m.in_contact_pct,
        pct(m.error_pct),
        pct(m.error_after_stable_pct),
        m.outages,
        m.longest_outage_ms,
        m.overruns,
        m.skipped_ticks,
        m.rss_mb,
        m.cpu_pct,
        m.models
    )
}

/// The verdict, for the terminal; the whole run's outages from its end report, if at hand.
fn summary(v: &Verdict, end: Option<&crate::DemoReport>) -> String {
    let pts = |x: Option<f64>| x.map_or("–".to_owned(), |x| format!("{x:.2}"));
    let whole = end.map_or(String::new(), |e| {
        let o = e.run.outages;
        format!(" (whole run: {}, longest {:.0} ms)", o.count, o.longest_ms)
    });
    format!(
        "soak: {} full minutes, {} of them in contact for {:.0} % of their ticks or more\n\
         memory: {:.1} MB after minute 1, {:.1} MB at the end, {:.1} MB at most; \
         trend {:+.1} MB/h\n\
         CPU (whole process): median {:.1} % of one core\n\
         error after stable per minute in contact: median {} %, largest distance from it {} \
         points, {} minutes more than 1 point away\n\
         haptic loop: {} overruns, {} skipped ticks; outages: {}{whole}\n",
        v.minutes,
        v.minutes_in_contact,
        Verdict::CONTACT_PCT,
        v.rss_mb.0,
        v.rss_mb.1,
        v.rss_max_mb,
        v.rss_growth_mb_per_h,
        v.cpu_median_pct,
        pts(v.error_median_pct),
        pts(v.error_max_deviation_pts),
        v.minutes_beyond_1_pt,
        v.overruns,
        v.skipped_ticks,
        v.outages,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_options_are_refused_before_anything_runs() {
        for (flags, expected) in [
            (&["--minutes", "0"][..], "--minutes = 0 is out of range"),
            (
                &["--loss-pct", "150"][..],
                "--loss-pct = 150 is out of range",
            ),
            (
                &["--jitter-ms", "-1"][..],
                "--jitter-ms = -1 is out of range",
            ),
            (
                &["--delay-ms", "3000"][..],
                "--delay-ms = 3000 is out of range",
            ),
        ] {
            let args =
                SoakCli::try_parse_from(std::iter::once("soak").chain(flags.iter().copied()))
                    .unwrap();
            let mut printed = Vec::new();
            let e = run_cmd(
                &args,
                Shutdown::new(),
                Box::new(std::io::sink()),
                &mut printed,
            )
            .unwrap_err();
            assert!(e.to_string().contains(expected), "{flags:?}: {e}");
            assert!(printed.is_empty());
        }
    }

    #[test]
    fn the_verdict_of_a_file_is_printed_and_garbage_refused() {
        let dir = std::env::temp_dir().join(format!("soak-verdict-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("soak.json");
        let rows: Vec<Minute> = (0..3)
            .map(|k| Minute {
                minute: k,
                in_contact_pct: 100.0,
                error_after_stable_pct: Some(3.0 + k as f64),
                ..Minute::default()
            })
            .collect();
        std::fs::write(&file, serde_json::json!({ "rows": rows }).to_string()).unwrap();
        let args = SoakCli::try_parse_from(["soak", "--verdict", file.to_str().unwrap()]).unwrap();
        let mut printed = Vec::new();
        run_cmd(
            &args,
            Shutdown::new(),
            Box::new(std::io::sink()),
            &mut printed,
        )
        .unwrap();
        let printed = String::from_utf8(printed).unwrap();
        assert!(printed.contains("median 4.00 %"), "{printed}");
        assert!(printed.contains("1.00 points, 0 minutes"), "{printed}");
        std::fs::write(&file, "{\"rows\": 3}").unwrap();
        let e = run_cmd(
            &args,
            Shutdown::new(),
            Box::new(std::io::sink()),
            &mut Vec::new(),
        );
        assert!(e.unwrap_err().to_string().contains("not a soak.json"));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_row_has_every_column_of_the_header() {
        let m = Minute {
            error_pct: Some(3.0),
            ..Minute::default()
        };
        assert_eq!(csv_row(&m).split(',').count(), HEADER.split(',').count());
        assert_eq!(
            csv_row(&Minute::default()).split(',').count(),
            HEADER.split(',').count()
        );
    }
}
