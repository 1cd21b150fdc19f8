//! `mmt benchmark`: the object-class benchmark — tables, JSON, the error-against-parameters plot.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Result, bail};
use clap::Args;
use sim::scene::SensorPreset;

use crate::benchmark::{
    BenchmarkConfig, BenchmarkReport, MOTIONS, Percentiles, StructureMode, Summary, run,
};
use crate::plot::{Panel, Series as Line, png, svg};

/// Run the pipeline over a seeded class of objects and named corner cases.
#[derive(Args, Debug)]
pub struct BenchmarkArgs {
    /// Objects drawn from the class.
    #[arg(long, default_value_t = 30)]
    objects: usize,
    /// Seed of the class draw (and of each case's noise and random motion).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Motions, comma-separated (exp1, chirp, steps, slow, human; any `mmt experiment` name).
    #[arg(long, value_delimiter = ',', default_values_t = MOTIONS.map(String::from))]
    motions: Vec<String>,
    /// One-way delays [ms], comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [0.0, 400.0])]
    delays_ms: Vec<f64>,
    /// Sensor presets, comma-separated (franka-like, arm-wrench, wrist-ft, clean), or `all`.
    #[arg(long, value_delimiter = ',', default_values_t = ["franka-like".to_string()])]
    presets: Vec<String>,
    /// Simulated time per case [s].
    #[arg(long, default_value_t = 60.0)]
    seconds: f64,
    /// Worker threads (default: the machine's cores). Each case runs on one thread.
    #[arg(long)]
    jobs: Option<usize>,
    /// Leave out the named corner cases.
    #[arg(long)]
    no_corner_cases: bool,
    /// The tangential structure the estimator is given: `object` (each object's own), `whole`
    /// (ground spring and friction for every object: a scene that does not say), or `select`
    /// (the whole one, and the estimator chooses from the data which of it the object needs;
    /// the tables say what it chose).
    #[arg(long, value_enum, default_value_t = StructureMode::Object)]
    structure: StructureMode,
    /// Print the report as JSON instead of tables.
    #[arg(long)]
    json: bool,
    /// Directory for benchmark.json and the error-against-parameters plot (SVG and PNG).
    #[arg(long)]
    out: Option<PathBuf>,
}

pub fn run_cmd(args: BenchmarkArgs) -> Result<()> {
    let config = config(&args)?;
    // Checked before the cases run (minutes), written atomically after.
    let dir = args.out.as_deref().map(rt::OutDir::prepare).transpose()?;
    let started = Instant::now();
    let quiet = args.json;
    let report = run(&config, &|done, total| {
        if !quiet && (done % 10 == 0 || done == total) {
            eprint!("\r{done}/{total} cases");
            if done == total {
                eprintln!();
            }
        }
    })?;
    let wall = started.elapsed().as_secs_f64();
    if let Some(dir) = &dir {
        dir.write_atomic(
            "benchmark.json",
            serde_json::to_string_pretty(&report)?.as_bytes(),
        )?;
        let panels = error_panels(&report);
        dir.write_atomic(
            "error_vs_parameters.svg",
            svg(&panels, 3, (1500, 900))?.as_bytes(),
        )?;
        dir.write_atomic("error_vs_parameters.png", &png(&panels, 3, (1500, 900))?)?;
    }
    if args.json {
        return super::print_json(&report);
    }
    print!("{}", cases_table(&report));
    print!("{}", summary_table(&report));
    print!("{}", targets_table(&report));
    println!(
        "{} cases, {:.0} s simulated each, in {wall:.0} s on {} threads{}",
        report.cases.len(),
        config.seconds,
        config.jobs,
        args.out
            .as_ref()
            .map_or(String::new(), |d| format!("; files in {}", d.display()))
    );
    Ok(())
}

fn config(args: &BenchmarkArgs) -> Result<BenchmarkConfig> {
    let mut presets = Vec::new();
    for name in &args.presets {
        if name == "all" {
            presets.extend(SensorPreset::ALL);
        } else if let Some(p) = SensorPreset::parse(name) {
            presets.push(p);
        } else {
            bail!(
                "unknown sensor preset {name:?}: expected franka-like, arm-wrench, wrist-ft, clean or all"
            );
        }
    }
    for m in &args.motions {
        if !sim::trajectory::NAMES.contains(&m.as_str()) {
            bail!(
                "unknown motion {m:?}: expected one of {}",
                sim::trajectory::NAMES.join(", ")
            );
        }
    }
    if args.objects == 0 && args.no_corner_cases {
        bail!("no objects: --objects 0 with --no-corner-cases leaves nothing to run");
    }
    Ok(BenchmarkConfig {
        objects: args.objects,
        corner_cases: !args.no_corner_cases,
        seed: args.seed,
        motions: args.motions.clone(),
        delays_ms: args.delays_ms.clone(),
        presets,
        seconds: args.seconds,
        jobs: args
            .jobs
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
            .max(1),
        structure: args.structure,
        ..BenchmarkConfig::default()
    })
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("never".into(), |v| format!("{v:.digits$}"))
}

fn cases_table(r: &BenchmarkReport) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{:<15} {:<6} {:>5} {:<11} {:>7} {:>7} {:>7} {:>7} {:>6} {:>7} {:>16}",
        "object",
        "motion",
        "delay",
        "preset",
        "after%",
        "first%",
        "render",
        "stable",
        "recon%",
        "param%",
        "rej/withh/conf"
    );
    for c in &r.cases {
        let f = &c.figures;
        let _ = writeln!(
            out,
            "{:<15} {:<6} {:>5} {:<11} {:>7} {:>7} {:>7} {:>7} {:>6} {:>7} {:>16}",
            r.objects[c.case.object].name,
            c.case.motion,
            c.case.delay_ms,
            c.case.preset,
            opt(f.error_after_stable_pct, 2),
            opt(f.error_from_first_contact_pct, 1),
            opt(f.time_to_first_render_s, 2),
            opt(f.time_to_stable_s, 2),
            opt(f.reconstruction_error_pct, 1),
            opt(f.worst_tangential_parameter_pct(), 0),
            format!("{}/{}/{}", f.gate_rejections, f.withheld, f.confirmed),
        );
        if let Some(chosen) = f.selected {
            let _ = writeln!(out, "{:<15} chose {}", "", chosen.describe());
        }
    }
    out
}

fn pct(p: &Percentiles, digits: usize) -> String {
    format!("{} / {}", opt(p.median, digits), opt(p.p90, digits))
}

fn summary_table(r: &BenchmarkReport) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "\nmedian / p90 over the objects ('never': the percentile falls on an object without the figure)"
    );
    let _ = writeln!(
        out,
        "{:<6} {:>5} {:<11} {:<6} {:>5} {:>6} {:>15} {:>15} {:>15} {:>13} {:>13} {:>13}",
        "motion",
        "delay",
        "preset",
        "group",
        "never",
        "unstab",
        "after stable %",
        "vs true %",
        "first contact %",
        "render s",
        "stable s",
        "worst param %"
    );
    for s in &r.summaries {
        let _ = writeln!(
            out,
            "{:<6} {:>5} {:<11} {:<6} {:>5} {:>6} {:>15} {:>15} {:>15} {:>13} {:>13} {:>13}",
            s.motion,
            s.delay_ms,
            s.preset,
            s.objects,
            s.never_rendered,
            s.never_stable,
            pct(&s.error_after_stable_pct, 2),
            pct(&s.error_after_stable_vs_true_pct, 2),
            pct(&s.error_from_first_contact_pct, 1),
            pct(&s.time_to_first_render_s, 2),
            pct(&s.time_to_stable_s, 2),
            pct(&s.worst_parameter_pct, 0),
        );
    }
    for s in &r.summaries {
        if let (Some((gs, n)), Some((fr, m))) = (s.ground_spring_right, s.friction_chosen) {
            let _ = writeln!(
                out,
                "structure chosen, {} {} ms {} {}: ground spring right for {gs} of {n}, friction for {fr} of {m}",
                s.motion, s.delay_ms, s.preset, s.objects
            );
        }
    }
    out
}

/// Issue 12's figures table (exp-1 motion, the class), against its targets.
fn targets_table(r: &BenchmarkReport) -> String {
    let mut out = String::new();
    let find = |motion: &str, delay: f64, preset: &str| -> Option<&Summary> {
        r.summaries.iter().find(|s| {
            s.motion == motion && s.delay_ms == delay && s.preset == preset && s.objects == "class"
        })
    };
    for preset in &r.config.presets {
        for &delay in &r.config.delays_ms {
            let Some(s) = find("exp1", delay, preset.name()) else {
                continue;
            };
            let _ = writeln!(
                out,
                "\nissue 12 figures: exp1 motion, {} class objects, {} ms, {}",
                s.error_after_stable_pct.n,
                delay,
                preset.name()
            );
            let mut row = |what: &str, target: &str, value: String| {
                let _ = writeln!(out, "  {what:<46} {target:>14}   {value}");
            };
            row("objects never rendered", "0", s.never_rendered.to_string());
            row(
                "time to stable, median / p90 [s]",
                "≤ 1.5 / ≤ 3",
                pct(&s.time_to_stable_s, 2),
            );
            row(
                "error after stable, median / p90 [%]",
                "≤ 3 / ≤ 6",
                pct(&s.error_after_stable_pct, 2),
            );
            row(
                "error from first contact, median / p90 [%]",
                "≤ 10 / ≤ 15",
                pct(&s.error_from_first_contact_pct, 1),
            );
            let poor: Vec<Option<f64>> = ["chirp", "steps", "slow"]
                .iter()
                .filter_map(|m| find(m, delay, preset.name()))
                .map(|s| s.time_to_first_render_s.max)
                .collect();
            if !poor.is_empty() {
                let worst = poor.iter().try_fold(0.0f64, |a, v| v.map(|v| a.max(v)));
                row(
                    "poor motions: time to first render, worst [s]",
                    "≤ 2",
                    opt(worst, 2),
                );
            }
        }
    }
    out
}

/// Error after stable and from first contact against the object's parameters: the exp-1
/// motion (or the first motion), the first delay and preset.
/// An object parameter plotted on a panel's horizontal axis.
type ObjectAxis = fn(&crate::benchmark::Object) -> f64;

fn error_panels(r: &BenchmarkReport) -> Vec<Panel> {
    let motion = if r.config.motions.iter().any(|m| m == "exp1") {
        "exp1".to_string()
    } else {
        r.config.motions.first().cloned().unwrap_or_default()
    };
    let delay = r.config.delays_ms.first().copied().unwrap_or(0.0);
    let preset = r.config.presets.first().map_or("", |p| p.name());
    let cases: Vec<_> = r
        .cases
        .iter()
        .filter(|c| c.case.motion == motion && c.case.delay_ms == delay && c.case.preset == preset)
        .collect();
    let axes: [(&str, bool, ObjectAxis); 6] = [
        ("mass m [kg]", true, |o| o.mass_kg),
        ("contact stiffness k2 [N/m]", true, |o| o.k_contact_n_per_m),
        ("contact mode [Hz]", true, |o| o.mode_hz()),
        ("static friction Fs [N]", false, |o| o.static_friction_n),
        ("friction coefficient Fs/(m g)", true, |o| {
            o.friction_coefficient().max(1e-3)
        }),
        ("ground spring k1 [N/m] (0 plotted at 10)", true, |o| {
            o.k_ground_n_per_m.max(10.0)
        }),
    ];
    axes.iter()
        .map(|&(label, log_x, x)| {
            let points = |f: &dyn Fn(&crate::benchmark::CaseFigures) -> Option<f64>| {
                cases
                    .iter()
                    .filter_map(|c| f(&c.figures).map(|y| (x(&r.objects[c.case.object]), y)))
                    .collect()
            };
            Panel {
                title: format!("{motion}, {delay} ms, {preset}"),
                x_label: label.into(),
                y_label: "RMS error [%]".into(),
                log_x,
                log_y: true,
                series: vec![
                    Line::scatter("after stable", points(&|f| f.error_after_stable_pct)),
                    Line::scatter(
                        "from first contact",
                        points(&|f| f.error_from_first_contact_pct),
                    ),
                ],
            }
        })
        .collect()
}
