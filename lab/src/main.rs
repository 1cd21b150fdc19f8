//! `mmt`: analysis commands over the MMT core. Thin: parse, call the library, print.

use lab::cli;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "mmt",
    about = "Model-mediated teleoperation: analysis commands"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Time the kd-tree build and the proxy step on a noisy plane (and the same steps by brute
    /// force).
    ContactBench(cli::contact_bench::Args),
    /// What a point cloud costs the loops: proxy step against points in the query ball, index
    /// build and memory against size (the figures of the point-cloud budget).
    CloudBudget(cli::cloud_budget::Args),
    /// Reproduce thesis experiments 1–3 in-process (exp1, exp2, exp3).
    Experiment(cli::experiment::ExperimentArgs),
    /// The experiment over a seeded class of objects and named corner cases: several motions,
    /// delays and sensor presets, per-case figures and percentiles.
    Benchmark(cli::benchmark::BenchmarkArgs),
    /// The report and plots of a recorded run, computed again from FILE.mcap.
    Report(cli::report::ReportArgs),
    /// Renderer frequency response against the exact |F/X|.
    Transfer(cli::transfer::TransferArgs),
    /// The estimator on the simulated exp-1 object with Franka-like sensor noise.
    Estimate(cli::estimate::EstimateArgs),
    /// The renderer on extreme and garbage inputs.
    Stress(cli::stress::StressArgs),
    /// Draw the force, error and spectrum plots of an `operator run --out DIR` directory.
    Plot(cli::plot::PlotArgs),
    /// Error against run time per integrator and step size, on typical, stiff and extreme sets.
    WorkPrecision(cli::work_precision::WorkPrecisionArgs),
}

/// A user's mistake prints one line (the error and its causes) and exits 1, with no backtrace
/// whatever `RUST_BACKTRACE` says.
fn main() -> ExitCode {
    let result = match Cli::parse().command {
        Command::ContactBench(args) => cli::contact_bench::run(&args),
        Command::CloudBudget(args) => cli::cloud_budget::run(&args),
        Command::Experiment(args) => cli::experiment::run_cmd(args),
        Command::Benchmark(args) => cli::benchmark::run_cmd(args),
        Command::Report(args) => cli::report::run(args),
        Command::Transfer(args) => cli::transfer::run(args),
        Command::Estimate(args) => cli::estimate::run(args),
        Command::Stress(args) => cli::stress::run(args),
        Command::Plot(args) => cli::plot::run(&args),
        Command::WorkPrecision(args) => cli::work_precision::run(args),
    };
    result.map_or_else(
        |e| {
            eprintln!("mmt: {}", rt::exit::message(e.as_ref()));
            ExitCode::FAILURE
        },
        |()| ExitCode::SUCCESS,
    )
}
