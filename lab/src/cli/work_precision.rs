//! `mmt work-precision`.

use crate::analysis::work_precision::{Point, problems, work_precision};
use crate::plot::{Panel, Series, png, svg};
use anyhow::{Result, anyhow, bail};
use clap::Args;
use mmt::render::integrators::Method;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Error against run time per integrator and step size.
#[derive(Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct WorkPrecisionArgs {
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// Write the diagram (one panel per problem) to this file: SVG, or PNG if it ends in .png.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Timed repeats per point (the median is reported).
    #[arg(long, default_value_t = 5)]
    repeats: usize,
}

pub fn run(args: WorkPrecisionArgs) -> Result<()> {
    // The plot's directory is checked before the timed runs, and the file written atomically.
    let plot = args.plot.as_deref().map(plot_target).transpose()?;
    let epoch = Instant::now();
    let mut clock = || epoch.elapsed().as_nanos() as u64;
    let report = work_precision(&mut clock, args.repeats);
    if let (Some((dir, name)), Some(path)) = (&plot, &args.plot) {
        let panels: Vec<Panel> = problems()
            .iter()
            .map(|p| Panel {
                title: p.name.to_string(),
                x_label: "cost per simulated second [ms]".into(),
                y_label: "RMS relative force error".into(),
                log_x: true,
                log_y: true,
                series: Method::ALL
                    .iter()
                    .map(|m| Series {
                        name: m.name().into(),
                        points: report
                            .points
                            .iter()
                            .filter(|pt| pt.problem == p.name && pt.method == m.name())
                            .filter_map(|pt: &Point| {
                                Some((pt.ns_per_step / pt.step_s * 1e-6, pt.rms_rel_error?))
                            })
                            .collect(),
                        markers: true,
                        line: true,
                    })
                    .collect(),
            })
            .collect();
        let bytes = if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("png"))
        {
            png(&panels, 3, (1500, 900))?
        } else {
            svg(&panels, 3, (1500, 900))?.into_bytes()
        };
        dir.write_atomic(name, &bytes)?;
    }
    if args.json {
        return super::print_json(&report);
    }
    println!(
        "{:<14} {:<15} {:>9} {:>13} {:>10}",
        "problem", "method", "step", "rms rel err", "ns/step"
    );
    for p in &report.points {
        let err = p
            .rms_rel_error
            .map_or("unstable".to_string(), |e| format!("{e:.3e}"));
        println!(
            "{:<14} {:<15} {:>9} {:>13} {:>10.1}",
            p.problem,
            p.method,
            format!("1/{:.0}", 1.0 / p.step_s),
            err,
            p.ns_per_step
        );
    }
    Ok(())
}

/// The directory (checked) and file name of `--plot FILE`.
fn plot_target(path: &Path) -> Result<(rt::OutDir, String)> {
    let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
        bail!(
            "--plot {}: expected a file name (e.g. work_precision.svg)",
            path.display()
        );
    };
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    // `OutError` names `--out`; the flag here is `--plot`.
    let dir = rt::OutDir::prepare(parent).map_err(|e| match e {
        rt::OutError::NotADirectory(p) => {
            anyhow!(
                "--plot {}: {} exists and is not a directory",
                path.display(),
                p.display()
            )
        }
        rt::OutError::Io {
            path: p,
            what,
            source,
        } => anyhow::Error::new(source).context(format!("--plot {}: cannot {what}", p.display())),
    })?;
    Ok((dir, name.to_string()))
}
