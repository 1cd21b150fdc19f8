//! `mmt contact-bench`: kd-tree build time and proxy step time on the standard workload
//! (`mmt::contact::workload`), and the same steps by brute force in the same run.
//!
//! The library never reads a clock; the timing is done here, around each call.

use std::time::Instant;

use anyhow::{Context, Result};
use mmt::contact::{CloudIndex, ContactOutput, Neighbours, Proxy, workload};
use serde::Serialize;

/// Arguments of `mmt contact-bench`.
#[derive(clap::Args, Debug)]
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
    /// Steps timed by brute force (the first ticks of the same path).
    #[arg(long, default_value_t = 200)]
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

/// The figures; the JSON keys are fixed.
#[derive(Serialize, Debug)]
struct Report {
    points: usize,
    build_ms: f64,
    step_us_median: f64,
    step_us_p99: f64,
    step_us_mean: f64,
    brute_force_step_us_median: f64,
    brute_force_step_us_p99: f64,
    brute_force_step_us_mean: f64,
}

/// Runs the benchmark and prints the report.
pub fn run(args: &Args) -> Result<()> {
    let steps = args.steps.max(args.brute_steps);
    let w = workload::plane_sweep(args.points, steps, args.noise_m, args.seed)
        .context("building the workload plane")?;

    let mut build_ns = Vec::with_capacity(args.builds);
    let mut index = None;
    for _ in 0..args.builds {
        let t0 = Instant::now();
        let built = CloudIndex::build(&w.frame)?;
        build_ns.push(t0.elapsed().as_nanos() as f64);
        index = Some(built);
    }
    let index = index.context("no index built")?;

    let (kd_ns, kd_out) = time_steps(&w, &index, args.steps)?;
    let brute = index.brute_force();
    let (brute_ns, brute_out) = time_steps(&w, &brute, args.brute_steps)?;
    let max_gap_m = kd_out
        .iter()
        .zip(&brute_out)
        .map(|(k, b)| {
            (0..3)
                .map(|i| (k.proxy_m[i] - b.proxy_m[i]).abs())
                .fold(0.0, f64::max)
        })
        .fold(0.0, f64::max);
    let touching = kd_out.iter().filter(|o| o.state.is_touching()).count();

    // Nanosecond timings, reported to the nanosecond in ms and µs.
    let report = Report {
        points: args.points,
        build_ms: (percentile(&mut build_ns, 0.5) / 1e3).round() / 1e3,
        step_us_median: percentile(&mut kd_ns.clone(), 0.5).round() / 1e3,
        step_us_p99: percentile(&mut kd_ns.clone(), 0.99).round() / 1e3,
        step_us_mean: mean(&kd_ns).round() / 1e3,
        brute_force_step_us_median: percentile(&mut brute_ns.clone(), 0.5).round() / 1e3,
        brute_force_step_us_p99: percentile(&mut brute_ns.clone(), 0.99).round() / 1e3,
        brute_force_step_us_mean: mean(&brute_ns).round() / 1e3,
    };
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        println!(
            "contact-bench: {} points (plane, 1 mm grid, noise σ = {} mm)",
            report.points,
            args.noise_m * 1e3
        );
        println!(
            "  kd-tree build       {:>10.2} ms  (median of {})",
            report.build_ms, args.builds
        );
        // A step queries the cloud only when the proxy has left the ball of its last query,
        // so the median is a step without a query; p99 and the mean carry the queries.
        println!(
            "  proxy step, kd-tree {:>10.2} µs  median, {:.2} µs p99, {:.2} µs mean ({} steps, \
             {:.0} % touching)",
            report.step_us_median,
            report.step_us_p99,
            report.step_us_mean,
            kd_ns.len(),
            100.0 * touching as f64 / kd_out.len().max(1) as f64
        );
        println!(
            "  proxy step, brute   {:>10.2} µs  median, {:.2} µs p99, {:.2} µs mean ({} steps; \
             proxy within {:.1e} m of the kd-tree run)",
            report.brute_force_step_us_median,
            report.brute_force_step_us_p99,
            report.brute_force_step_us_mean,
            brute_ns.len(),
            max_gap_m
        );
    }
    Ok(())
}

/// Steps a fresh proxy along the first `steps` HIPs, timing each step [ns].
fn time_steps<N: Neighbours>(
    w: &workload::Workload,
    cloud: &N,
    steps: usize,
) -> Result<(Vec<f64>, Vec<ContactOutput>)> {
    let hips = &w.hips[..steps.min(w.hips.len())];
    let mut proxy = Proxy::new(w.config, hips.first().copied().unwrap_or_default())?;
    let mut ns = Vec::with_capacity(hips.len());
    let mut out = Vec::with_capacity(hips.len());
    for hip in hips {
        let t0 = Instant::now();
        let o = proxy.step(*hip, cloud);
        ns.push(t0.elapsed().as_nanos() as f64);
        out.push(o);
    }
    Ok((ns, out))
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
