//! `mmt contact-bench`: kd-tree build time and proxy step time on the standard workload
//! (`sim::workload`), and the same steps by brute force in the same run.
//!
//! # What the figures mean
//!
//! The proxy queries the cloud only when it leaves the ball of its last query (a margin of
//! `r3/24` beyond the ball it needs), so most ticks reuse that answer and scan no points, on
//! either backend. The reported figures are therefore of three kinds:
//!
//! - `step_us_*`: every tick of the sweep on the kd-tree — the real per-step cost of the proxy,
//!   reuse included (the median is a tick without a query; p99 and the mean carry the queries);
//! - `query_step_us_*`: only the ticks that ran at least one neighbour query — the cost of a
//!   step that actually searches the cloud;
//! - `brute_force_*`: the same figures with every query answered by a scan of all points, timed
//!   on `--brute-steps` ticks spread evenly over the same sweep. Each is stepped from a copy of
//!   the kd-tree proxy's state at that tick, so both backends do the same work apart from the
//!   query (and reuse on the same ticks).
//!
//! The library never reads a clock; the timing is done here, around each call.

use std::cell::Cell;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use mmt::contact::{CloudIndex, ContactOutput, Neighbour, Neighbours, Proxy};
use serde::Serialize;
use sim::workload;

/// Arguments of `mmt contact-bench`.
#[derive(clap::Args, Debug, Clone)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Points in the noisy plane (640×480 = 307200 is one depth frame).
    #[arg(long, default_value_t = 307_200, value_parser = positive)]
    points: usize,
    /// Print the figures as one JSON object instead of a table.
    #[arg(long)]
    json: bool,
    /// Proxy steps timed on the kd-tree (1 kHz ticks along the workload's HIP path).
    #[arg(long, default_value_t = 20_000, value_parser = positive)]
    steps: usize,
    /// Ticks of the same path also timed by brute force, spread evenly over the `--steps`
    /// ticks (1 ..= --steps).
    #[arg(long, default_value_t = 2_000)]
    brute_steps: usize,
    /// Times the kd-tree is built (the median is reported).
    #[arg(long, default_value_t = 5, value_parser = positive)]
    builds: usize,
    /// Noise of the plane [m] (standard deviation per coordinate).
    #[arg(long, default_value_t = 0.0005)]
    noise_m: f64,
    /// Seed of the noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

impl Args {
    /// Checks the knobs that depend on each other; the error names the flag, its value and the
    /// allowed range.
    fn validate(&self) -> Result<()> {
        if !(1..=self.steps).contains(&self.brute_steps) {
            bail!(
                "--brute-steps {}: expected 1 ..= --steps ({})",
                self.brute_steps,
                self.steps
            );
        }
        if !(self.noise_m >= 0.0 && self.noise_m.is_finite()) {
            bail!("--noise-m {}: expected a finite number >= 0", self.noise_m);
        }
        Ok(())
    }
}

/// The figures. The keys (`points`, `build_ms`, `step_us_median`, `step_us_p99`,
/// `brute_force_step_us_median`) are fixed; the query-step figures are `null` when no timed
/// step queried.
#[derive(Serialize, Debug)]
struct Report {
    points: usize,
    build_ms: f64,
    /// Every kd-tree tick, reuse included.
    step_us_median: f64,
    step_us_p99: f64,
    step_us_mean: f64,
    steps: usize,
    /// kd-tree ticks that ran at least one neighbour query.
    query_step_us_median: Option<f64>,
    query_step_us_p99: Option<f64>,
    query_steps: usize,
    /// The brute-force ticks (an even spread of the same path), reuse included.
    brute_force_step_us_median: f64,
    brute_force_step_us_p99: f64,
    brute_force_step_us_mean: f64,
    brute_force_steps: usize,
    /// Brute-force ticks that ran at least one neighbour query (a scan of every point).
    brute_force_query_step_us_median: Option<f64>,
    brute_force_query_step_us_p99: Option<f64>,
    brute_force_query_steps: usize,
}

/// Runs the benchmark and prints the report.
pub fn run(args: &Args) -> Result<()> {
    let m = measure(args)?;
    let report = &m.report;
    if args.json {
        println!("{}", serde_json::to_string(report)?);
        return Ok(());
    }
    let opt = |v: Option<f64>| v.map_or_else(|| "–".to_owned(), |v| format!("{v:.2}"));
    println!(
        "contact-bench: {} points (plane, 1 mm grid, noise σ = {} mm)",
        report.points,
        args.noise_m * 1e3
    );
    println!(
        "  kd-tree build        {:>10.2} ms  (median of {})",
        report.build_ms, args.builds
    );
    println!(
        "  proxy step, kd-tree  {:>10.2} µs  median, {:.2} µs p99, {:.2} µs mean ({} steps, \
         {:.0} % touching; the median reuses the last query)",
        report.step_us_median,
        report.step_us_p99,
        report.step_us_mean,
        report.steps,
        100.0 * m.touching as f64 / report.steps.max(1) as f64
    );
    println!(
        "    steps that query   {:>10} µs  median, {} µs p99 ({} steps)",
        opt(report.query_step_us_median),
        opt(report.query_step_us_p99),
        report.query_steps
    );
    let stride = m.brute_ticks.get(1).map_or(1, |t| t - m.brute_ticks[0]);
    let same_queries = m.brute_queried.iter().filter(|(b, k)| b == k).count();
    println!(
        "  proxy step, brute    {:>10.2} µs  median, {:.2} µs p99, {:.2} µs mean ({} ticks, \
         one in {stride} of the same path; queried on the same ticks as the kd-tree on {} of \
         them; proxy within {:.1e} m)",
        report.brute_force_step_us_median,
        report.brute_force_step_us_p99,
        report.brute_force_step_us_mean,
        report.brute_force_steps,
        same_queries,
        m.max_gap_m
    );
    println!(
        "    steps that query   {:>10} µs  median, {} µs p99 ({} steps)",
        opt(report.brute_force_query_step_us_median),
        opt(report.brute_force_query_step_us_p99),
        report.brute_force_query_steps
    );
    Ok(())
}

/// A report and what is needed to judge it.
struct Measured {
    report: Report,
    /// Ticks timed by brute force.
    brute_ticks: Vec<usize>,
    /// Whether each brute-force tick queried, and whether the kd-tree queried on it.
    brute_queried: Vec<(bool, bool)>,
    /// Kd-tree ticks in contact.
    touching: usize,
    /// Largest proxy-position difference [m] between a brute-force tick and the kd-tree's.
    max_gap_m: f64,
}

/// One timed tick.
#[derive(Clone, Copy, Debug)]
struct Tick {
    ns: f64,
    queried: bool,
}

fn measure(args: &Args) -> Result<Measured> {
    args.validate()?;
    let w = workload::plane_sweep(args.points, args.steps, args.noise_m, args.seed)
        .context("building the workload plane")?;
    let (mut build_ns, index) = timed_builds(&w, args.builds)?;
    let kd = Counted::new(&index);
    let brute_index = index.brute_force();
    let brute = Counted::new(&brute_index);
    let (kd_ticks, touching) = kd_pass(&w, &kd)?;
    let brute_ticks: Vec<usize> = (0..args.brute_steps)
        .map(|i| i * args.steps / args.brute_steps)
        .collect();
    let twins = brute_pass(&w, &kd, &brute, &brute_ticks)?;
    let report = Report {
        points: args.points,
        // Nanosecond timings, reported to the nanosecond in ms and µs.
        build_ms: (percentile(&mut build_ns, 0.5) / 1e3).round() / 1e3,
        step_us_median: us(percentile(&mut all(&kd_ticks), 0.5)),
        step_us_p99: us(percentile(&mut all(&kd_ticks), 0.99)),
        step_us_mean: us(mean(&all(&kd_ticks))),
        steps: kd_ticks.len(),
        query_step_us_median: quantile_us(&mut querying(&kd_ticks), 0.5),
        query_step_us_p99: quantile_us(&mut querying(&kd_ticks), 0.99),
        query_steps: querying(&kd_ticks).len(),
        brute_force_step_us_median: us(percentile(&mut all(&twins.timed), 0.5)),
        brute_force_step_us_p99: us(percentile(&mut all(&twins.timed), 0.99)),
        brute_force_step_us_mean: us(mean(&all(&twins.timed))),
        brute_force_steps: twins.timed.len(),
        brute_force_query_step_us_median: quantile_us(&mut querying(&twins.timed), 0.5),
        brute_force_query_step_us_p99: quantile_us(&mut querying(&twins.timed), 0.99),
        brute_force_query_steps: querying(&twins.timed).len(),
    };
    Ok(Measured {
        report,
        brute_ticks,
        brute_queried: twins.queried,
        touching,
        max_gap_m: twins.max_gap_m,
    })
}

/// Builds the kd-tree of the workload's frame `builds` times: each build's time [ns] and the
/// last index.
fn timed_builds(w: &workload::Workload, builds: usize) -> Result<(Vec<f64>, CloudIndex)> {
    let mut build_ns = Vec::with_capacity(builds);
    let mut index = None;
    for _ in 0..builds {
        let t0 = Instant::now();
        let built = CloudIndex::build(&w.frame)?;
        build_ns.push(t0.elapsed().as_nanos() as f64);
        index = Some(built);
    }
    let index = index.context("no index built")?;
    Ok((build_ns, index))
}

/// Pass 1: every tick on the kd-tree, timed; with the number of ticks in contact.
fn kd_pass(w: &workload::Workload, kd: &Counted<'_, CloudIndex>) -> Result<(Vec<Tick>, usize)> {
    let mut proxy = Proxy::new(w.config, w.hips[0])?;
    proxy.prepare(kd);
    let mut kd_ticks = Vec::with_capacity(w.hips.len());
    let mut touching = 0;
    for hip in &w.hips {
        let (tick, out) = timed_step(&mut proxy, *hip, kd);
        kd_ticks.push(tick);
        touching += usize::from(out.state.is_touching());
    }
    Ok((kd_ticks, touching))
}

/// The brute-force twins' ticks, and how they compare with the kd-tree's.
struct Twins {
    /// Each twin's tick.
    timed: Vec<Tick>,
    /// Whether each twin queried, and whether the kd-tree queried on that tick.
    queried: Vec<(bool, bool)>,
    /// Largest proxy-position difference [m] between a twin and the kd-tree proxy.
    max_gap_m: f64,
}

/// Pass 2: the same path again (untimed, same bits); at the chosen ticks a copy of the
/// proxy takes the tick by brute force, timed. Separate passes keep the brute-force scans
/// from evicting the kd-tree's caches in the timed run.
fn brute_pass<B: Neighbours>(
    w: &workload::Workload,
    kd: &Counted<'_, CloudIndex>,
    brute: &Counted<'_, B>,
    brute_ticks: &[usize],
) -> Result<Twins> {
    let mut proxy = Proxy::new(w.config, w.hips[0])?;
    proxy.prepare(kd);
    let mut twins = Twins {
        timed: Vec::with_capacity(brute_ticks.len()),
        queried: Vec::with_capacity(brute_ticks.len()),
        max_gap_m: 0.0,
    };
    let mut picks = brute_ticks.iter().peekable();
    for (k, hip) in w.hips.iter().enumerate() {
        let twin = picks.next_if_eq(&&k).map(|_| {
            // A clone's buffer holds only what it contains: reserve, so the timed step does
            // not allocate.
            let mut twin = proxy.clone();
            twin.prepare(brute);
            twin
        });
        let (kd_tick, kd_out) = timed_step(&mut proxy, *hip, kd);
        if let Some(mut twin) = twin {
            let (tick, out) = timed_step(&mut twin, *hip, brute);
            twins.timed.push(tick);
            twins.queried.push((tick.queried, kd_tick.queried));
            let gap = (0..3)
                .map(|i| (kd_out.proxy_m[i] - out.proxy_m[i]).abs())
                .fold(0.0, f64::max);
            twins.max_gap_m = twins.max_gap_m.max(gap);
        }
    }
    Ok(twins)
}

/// One proxy step, timed [ns], and whether it queried the cloud.
fn timed_step<N: Neighbours>(
    proxy: &mut Proxy,
    hip: [f64; 3],
    cloud: &Counted<'_, N>,
) -> (Tick, ContactOutput) {
    let before = cloud.queries.get();
    let t0 = Instant::now();
    let out = proxy.step(hip, cloud);
    let ns = t0.elapsed().as_nanos() as f64;
    let queried = cloud.queries.get() > before;
    (Tick { ns, queried }, out)
}

/// A backend that counts its queries, so a tick that queried can be told from one that reused
/// the last answer. Same points, same id, same answers as the backend it wraps.
struct Counted<'a, N> {
    inner: &'a N,
    queries: Cell<u64>,
}

impl<'a, N> Counted<'a, N> {
    fn new(inner: &'a N) -> Self {
        Self {
            inner,
            queries: Cell::new(0),
        }
    }
}

impl<N: Neighbours> Neighbours for Counted<'_, N> {
    fn for_each_within<F: FnMut(Neighbour)>(&self, centre_m: [f64; 3], radius_m: f64, visit: F) {
        self.queries.set(self.queries.get() + 1);
        self.inner.for_each_within(centre_m, radius_m, visit);
    }

    fn cloud_id(&self) -> u64 {
        self.inner.cloud_id()
    }

    fn len(&self) -> usize {
        self.inner.len()
    }

    fn max_within(&self, radius_m: f64) -> usize {
        self.inner.max_within(radius_m)
    }
}

fn all(ticks: &[Tick]) -> Vec<f64> {
    ticks.iter().map(|t| t.ns).collect()
}

fn querying(ticks: &[Tick]) -> Vec<f64> {
    ticks.iter().filter(|t| t.queried).map(|t| t.ns).collect()
}

/// Nanoseconds to microseconds, to the nanosecond.
fn us(ns: f64) -> f64 {
    ns.round() / 1e3
}

/// The `q`-quantile of `ns` in µs; `None` for no samples.
fn quantile_us(ns: &mut [f64], q: f64) -> Option<f64> {
    (!ns.is_empty()).then(|| us(percentile(ns, q)))
}

/// Parses a count that must be at least 1.
fn positive(s: &str) -> std::result::Result<usize, String> {
    match s.parse::<usize>() {
        Ok(n) if n > 0 => Ok(n),
        _ => Err(format!("expected an integer >= 1, found {s:?}")),
    }
}

/// Arithmetic mean; 0 for an empty slice.
fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        0.0
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

/// The `q`-quantile (nearest rank) of `v`; 0 for an empty slice.
fn percentile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let rank = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
    v[rank - 1]
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        args: Args,
    }

    fn args(extra: &[&str]) -> Args {
        let argv = ["contact-bench"].iter().chain(extra);
        Cli::try_parse_from(argv).unwrap().args
    }

    /// Regression: brute force was timed on the first 200 ticks only, against 20,000 on the
    /// kd-tree, and could not tell a tick that scanned the cloud from one that reused its
    /// last query.
    #[test]
    fn brute_force_is_timed_on_ticks_spread_over_the_same_path() {
        let a = args(&[
            "--points",
            "3000",
            "--steps",
            "2000",
            "--brute-steps",
            "100",
        ]);
        let m = measure(&a).unwrap();
        let r = &m.report;
        assert_eq!((r.points, r.steps, r.brute_force_steps), (3000, 2000, 100));
        // Evenly spread over the whole path, not its first ticks.
        assert_eq!(m.brute_ticks.len(), 100);
        assert_eq!(m.brute_ticks[0], 0);
        assert!(m.brute_ticks.windows(2).all(|w| w[1] - w[0] == 20));
        // The same state on both backends: they query on the same ticks, land in the same
        // place, and the query-step figures count only the ticks that queried.
        assert!(m.brute_queried.iter().all(|(b, k)| b == k));
        assert!(m.max_gap_m < 1e-9, "{}", m.max_gap_m);
        let queried = m.brute_queried.iter().filter(|(b, _)| *b).count();
        assert_eq!(r.brute_force_query_steps, queried);
        assert!(queried > 0 && queried < 100, "{queried}");
        assert!(r.query_steps > 0 && r.query_steps < r.steps);
        assert!(r.query_step_us_median.is_some() && r.brute_force_query_step_us_p99.is_some());
        // The keys are present.
        let json = serde_json::to_value(r).unwrap();
        for key in [
            "points",
            "build_ms",
            "step_us_median",
            "step_us_p99",
            "brute_force_step_us_median",
        ] {
            assert!(json[key].is_number(), "{key}");
        }
    }

    /// Regression: `--brute-steps 0` printed a brute-force median of 0.0.
    #[test]
    fn knobs_out_of_range_are_refused_naming_flag_value_and_range() {
        for (extra, expected) in [
            (
                &["--brute-steps", "0"][..],
                "--brute-steps 0: expected 1 ..= --steps (20000)",
            ),
            (
                &["--steps", "10", "--brute-steps", "11"][..],
                "--brute-steps 11: expected 1 ..= --steps (10)",
            ),
            (&["--noise-m=-1"][..], "--noise-m -1: expected"),
        ] {
            let msg = measure(&args(extra)).err().unwrap().to_string();
            assert!(msg.contains(expected), "{msg}");
        }
        let err = Cli::try_parse_from(["contact-bench", "--points", "0"])
            .err()
            .unwrap()
            .to_string();
        assert!(err.contains("--points") && err.contains(">= 1"), "{err}");
    }

    /// Regression: one or two points failed with `plane.size_x_m = 0`.
    #[test]
    fn one_and_two_points_run() {
        for points in ["1", "2"] {
            let a = args(&["--points", points, "--steps", "50", "--brute-steps", "5"]);
            let m = measure(&a).unwrap();
            assert_eq!(m.report.points.to_string(), points);
        }
    }
}
