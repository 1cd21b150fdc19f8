//! `mmt cloud-budget`: what a point cloud costs the loops, measured — the figures behind
//! `mmt::contact::budget` (README "Point-cloud budget").
//!
//! For each grid spacing, a square plane window (`--size-m`, light noise) is indexed and a proxy
//! is stepped on it along two HIP paths:
//!
//! - `sweep`: in and out of the surface at 2 Hz while circling at 0.15 m/s (the contact
//!   workload of `mmt contact-bench`): the cost of ordinary ticks;
//! - `jumps`: the HIP jumps 120 mm across the surface every tick, alternately 5 mm above and
//!   below it, so every tick sweeps its longest and queries fresh balls: the worst tick.
//!
//! It reports the points in the query ball (the most visited by one query, and the budget's
//! bound from `points_in_ball`), the step times (median, p99, max), the index build time, the
//! resident memory of the index per point, and a least-squares line of the worst ticks against
//! the points in the ball. The library reads no clock; the timing is done here.

use std::cell::Cell;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use mmt::cloud::{CloudFrame, Pose};
use mmt::contact::budget::{self, CloudBudget};
use mmt::contact::{CloudIndex, Neighbour, Neighbours, Proxy, ProxyConfig};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use serde::Serialize;

/// Arguments of `mmt cloud-budget`.
#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// Grid spacings to measure [mm], comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "4.5,3,2,1.5,1,0.7,0.5,0.35,0.25"
    )]
    spacings_mm: Vec<f64>,
    /// Side of the square plane window [m] (the exp-1 camera window is 0.25 m).
    #[arg(long, default_value_t = 0.25)]
    size_m: f64,
    /// Proxy radii: `exp1` (r1 4 mm, r2 6 mm, r3 30 mm) or `default` (1, 3, 12 mm).
    #[arg(long, default_value = "exp1")]
    radii: String,
    /// Ticks timed per path and spacing.
    #[arg(long, default_value_t = 3_000)]
    steps: usize,
    /// Print the rows as JSON.
    #[arg(long)]
    json: bool,
}

/// One spacing's figures.
#[derive(Serialize, Debug)]
struct Row {
    spacing_mm: f64,
    points: usize,
    /// Most points one query visited (either path).
    ball_measured: usize,
    /// The budget's bound (`budget::points_in_ball` at the query radius).
    ball_bound: usize,
    build_ms: f64,
    /// Resident memory of the index per point [B] (`None` off Linux).
    index_bytes_per_point: Option<f64>,
    sweep_us: [f64; 3],
    jumps_us: [f64; 3],
    /// Queries in the worst jump tick.
    jumps_queries_max: u64,
}

/// Runs the measurement and prints the table (or JSON).
pub fn run(args: &Args) -> Result<()> {
    let config = match args.radii.as_str() {
        "exp1" => ProxyConfig {
            r1_m: 0.004,
            r2_m: 0.006,
            r3_m: 0.03,
            ..ProxyConfig::default()
        },
        "default" => ProxyConfig::default(),
        other => bail!("--radii {other:?}: expected exp1 or default"),
    };
    if !(args.size_m > 0.0 && args.size_m <= 2.0) {
        bail!("--size-m {}: expected (0, 2] m", args.size_m);
    }
    if args.steps == 0 {
        bail!("--steps 0: expected at least 1");
    }
    let radius = budget::query_radius_m(&config);
    let mut rows = Vec::new();
    for &s in &args.spacings_mm {
        if !(0.1..=50.0).contains(&s) {
            bail!("--spacings-mm {s}: expected each in [0.1, 50] mm");
        }
        rows.push(measure(&config, s * 1e-3, args).with_context(|| format!("spacing {s} mm"))?);
    }
    let (measured, bound) = (fit(&rows, false), fit(&rows, true));
    if args.json {
        let out = serde_json::json!({ "query_radius_m": radius, "rows": rows,
            "worst_step_fit": { "fixed_ns": measured.0, "ns_per_point": measured.1,
                "fixed_ns_bound": bound.0, "ns_per_bound_point": bound.1 } });
        println!("{out}");
        return Ok(());
    }
    println!(
        "cloud-budget: {} m plane, radii {} (query radius {:.2} mm), {} ticks per path",
        args.size_m,
        args.radii,
        radius * 1e3,
        args.steps
    );
    println!(
        "spacing_mm   points  ball_meas ball_bound  build_ms  B/pt   sweep p50/p99/max µs      jumps p50/p99/max µs  q/tick"
    );
    for r in &rows {
        println!(
            "{:>9.2} {:>9} {:>9} {:>10} {:>9.2} {:>5} {:>7.1} {:>7.1} {:>7.1}   {:>7.1} {:>7.1} {:>7.1} {:>5}",
            r.spacing_mm,
            r.points,
            r.ball_measured,
            r.ball_bound,
            r.build_ms,
            r.index_bytes_per_point
                .map_or_else(|| "–".to_owned(), |b| format!("{b:.0}")),
            r.sweep_us[0],
            r.sweep_us[1],
            r.sweep_us[2],
            r.jumps_us[0],
            r.jumps_us[1],
            r.jumps_us[2],
            r.jumps_queries_max
        );
    }
    let b = CloudBudget::default();
    println!(
        "worst tick (jumps median, least squares) ≈ {:.0} ns + {:.1} ns × points in the ball \
         ({:.0} ns + {:.1} ns × the bound); the budget assumes {:.0} ns + {:.1} ns × the bound",
        measured.0, measured.1, bound.0, bound.1, b.step_fixed_ns, b.step_ns_per_point
    );
    println!(
        "budget at {} Hz: at most {} points (bound) in the query ball, {} points per 30 Hz \
         frame, {} per static frame",
        config.rate_hz,
        b.max_points_in_ball(&config),
        b.max_points(Some(30.0)),
        b.max_points(None)
    );
    Ok(())
}

fn measure(config: &ProxyConfig, spacing_m: f64, args: &Args) -> Result<Row> {
    let n = (args.size_m / spacing_m).floor() as usize + 1;
    let half = 0.5 * (n - 1) as f64 * spacing_m;
    let mut rng = Pcg64::seed_from_u64(7);
    let points: Vec<[f32; 3]> = (0..n * n)
        .map(|k| {
            let (i, j) = (k / n, k % n);
            let noise = rng.random_range(-0.0002..0.0002);
            [
                i as f64 * spacing_m - half,
                j as f64 * spacing_m - half,
                noise,
            ]
            .map(|v| v as f32)
        })
        .collect();
    let ball_bound = budget::points_in_ball(&points, budget::query_radius_m(config))?;
    let frame = CloudFrame::new(points, 0, Pose::IDENTITY)?;
    let rss_before = rss_bytes();
    let mut build_ns = Vec::new();
    let mut index = CloudIndex::build(&frame)?;
    let rss_after = rss_bytes();
    for _ in 0..3 {
        let t0 = Instant::now();
        index = CloudIndex::build(&frame)?;
        build_ns.push(t0.elapsed().as_nanos() as f64);
    }
    let per_point = match (rss_before, rss_after) {
        (Some(a), Some(b)) => Some((b.saturating_sub(a)) as f64 / frame.points().len() as f64),
        _ => None,
    };
    let counted = Counted::new(&index);
    let reach = 0.3 * half;
    let sweep: Vec<[f64; 3]> = (0..args.steps)
        .map(|k| {
            let t = k as f64 / config.rate_hz;
            let (s, c) = (std::f64::consts::TAU * t).sin_cos();
            let z = 0.010 * (std::f64::consts::TAU * 2.0 * t).cos();
            [reach.min(0.024) * c, reach.min(0.024) * s, z]
        })
        .collect();
    let jumps: Vec<[f64; 3]> = (0..args.steps)
        .map(|k| {
            let side = if k % 2 == 0 { -1.0 } else { 1.0 };
            let z = if (k / 2) % 2 == 0 { 0.005 } else { -0.005 };
            [side * 0.06, 0.0, z]
        })
        .collect();
    let (sweep_us, _) = run_path(config, &sweep, &counted)?;
    let (jumps_us, jumps_queries_max) = run_path(config, &jumps, &counted)?;
    let ball_measured = counted.most.get() as usize;
    Ok(Row {
        spacing_mm: spacing_m * 1e3,
        points: frame.points().len(),
        ball_measured,
        ball_bound,
        build_ms: median(&mut build_ns) / 1e6,
        index_bytes_per_point: per_point,
        sweep_us,
        jumps_us,
        jumps_queries_max,
    })
}

/// Steps a prepared proxy along `hips`: the median, p99 and max tick [µs], and the most
/// queries one tick ran.
fn run_path(
    config: &ProxyConfig,
    hips: &[[f64; 3]],
    cloud: &Counted<'_>,
) -> Result<([f64; 3], u64)> {
    let mut proxy = Proxy::new(*config, [0.0, 0.0, 0.05])?;
    proxy.prepare(cloud);
    let mut ns = Vec::with_capacity(hips.len());
    let mut most_queries = 0;
    for hip in hips {
        let before = cloud.queries.get();
        let t0 = Instant::now();
        std::hint::black_box(proxy.step(*hip, cloud));
        ns.push(t0.elapsed().as_nanos() as f64);
        most_queries = most_queries.max(cloud.queries.get() - before);
    }
    let q = |v: &mut Vec<f64>, q: f64| {
        v.sort_by(f64::total_cmp);
        let k = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
        (v[k - 1] / 10.0).round() / 100.0
    };
    Ok((
        [q(&mut ns, 0.5), q(&mut ns, 0.99), q(&mut ns, 1.0)],
        most_queries,
    ))
}

/// Least-squares line `fixed + per_point · x` through the rows' median jump ticks [ns] (every
/// jump tick is a worst one; the median is robust to preemption on a shared machine), `x` the
/// most points one query visited (`bound` false) or the budget's bound (`bound` true).
fn fit(rows: &[Row], bound: bool) -> (f64, f64) {
    let n = rows.len() as f64;
    if rows.len() < 2 {
        return (0.0, 0.0);
    }
    let xs: Vec<f64> = rows
        .iter()
        .map(|r| if bound { r.ball_bound } else { r.ball_measured } as f64)
        .collect();
    let ys: Vec<f64> = rows.iter().map(|r| r.jumps_us[0] * 1e3).collect();
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx).powi(2)).sum();
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    (my - slope * mx, slope)
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

/// Resident set size [B] from `/proc/self/statm` (Linux), `None` elsewhere.
fn rss_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/statm").ok()?;
    let pages: u64 = text.split_whitespace().nth(1)?.parse().ok()?;
    Some(pages * 4096)
}

/// The index, counting queries and the most points one query visited.
struct Counted<'a> {
    inner: &'a CloudIndex,
    queries: Cell<u64>,
    most: Cell<u64>,
}

impl<'a> Counted<'a> {
    fn new(inner: &'a CloudIndex) -> Self {
        Self {
            inner,
            queries: Cell::new(0),
            most: Cell::new(0),
        }
    }
}

impl Neighbours for Counted<'_> {
    fn for_each_within<F: FnMut(Neighbour)>(
        &self,
        centre_m: [f64; 3],
        radius_m: f64,
        mut visit: F,
    ) {
        self.queries.set(self.queries.get() + 1);
        let mut n = 0;
        self.inner.for_each_within(centre_m, radius_m, |nb| {
            n += 1;
            visit(nb);
        });
        self.most.set(self.most.get().max(n));
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
