//! `mmt work-precision`.

use crate::analysis::work_precision::{Point, problems, work_precision};
use crate::plot::{Panel, Series, png, svg};
use anyhow::{Context, Result};
use clap::Args;
use mmt::render::integrators::Method;
use std::path::PathBuf;
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
    let epoch = Instant::now();
    let mut clock = || epoch.elapsed().as_nanos() as u64;
    let report = work_precision(&mut clock, args.repeats);
    if let Some(path) = &args.plot {
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
        std::fs::write(path, bytes).with_context(|| format!("writing {}", path.display()))?;
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
