//! The files of a run's `--out DIR`: `report.json`, `series.csv`, and plots as SVG and PNG.
//! Built in memory; the caller writes them.

use metrics::spectrum::spectrum;
use metrics::{ExperimentReport, Series, Window};
use mmt::vec3;

use crate::plot::{Panel, PlotError, Series as Line, png, svg};

/// The files of a run: `report.json` (deterministic: no wall-clock figure), `series.csv`, and
/// `force`, `error` and `spectrum` plots, each as SVG and PNG.
pub fn files(r: &ExperimentReport, s: &Series) -> Result<Vec<(String, Vec<u8>)>, PlotError> {
    let json = serde_json::to_string_pretty(r).map_err(|e| PlotError::Draw(e.to_string()))?;
    let mut out = vec![
        ("report.json".to_string(), json.into_bytes()),
        ("series.csv".to_string(), s.to_csv().into_bytes()),
    ];
    out.extend(plots(s, &r.error_over_time)?);
    Ok(out)
}

/// The `force`, `error` and `spectrum` plots of a series and its error over time, each as SVG
/// and PNG.
pub fn plots(s: &Series, error_over_time: &[Window]) -> Result<Vec<(String, Vec<u8>)>, PlotError> {
    let mut out = Vec::new();
    for (name, panels, columns, size) in [
        ("force", force_panels(s), 1, (1400, 800)),
        ("error", error_panels(error_over_time), 1, (1000, 450)),
        ("spectrum", spectrum_panels(s), 1, (1000, 550)),
    ] {
        out.push((
            format!("{name}.svg"),
            svg(&panels, columns, size)?.into_bytes(),
        ));
        out.push((format!("{name}.png"), png(&panels, columns, size)?));
    }
    Ok(out)
}

/// At most this many points per plotted line (the CSV keeps every sample).
const PLOT_POINTS: usize = 6000;

fn decimated(s: &Series, f: impl Fn(usize) -> Option<f64>) -> Vec<(f64, f64)> {
    let step = s.len().div_ceil(PLOT_POINTS).max(1);
    (0..s.len())
        .step_by(step)
        .filter_map(|i| f(i).map(|v| (i as f64 * s.dt_s(), v)))
        .collect()
}

fn force_panels(s: &Series) -> Vec<Panel> {
    let along = |v: [f64; 3]| vec3::dot(v, s.axis);
    let normal = |v: [f64; 3]| vec3::dot(v, s.normal);
    let mut panels = vec![Panel {
        title: "force along the tangential axis (rendered shifted back by the delay)".into(),
        x_label: "command time [s]".into(),
        y_label: "force on tool [N]".into(),
        log_x: false,
        log_y: false,
        series: vec![
            line("measured", decimated(s, |i| s.measured[i].map(along))),
            line("rendered", decimated(s, |i| Some(along(s.rendered[i])))),
        ],
    }];
    panels.push(Panel {
        title: "force along the surface normal".into(),
        x_label: "command time [s]".into(),
        y_label: "force on tool [N]".into(),
        log_x: false,
        log_y: false,
        series: vec![
            line("measured", decimated(s, |i| s.measured[i].map(normal))),
            line("rendered", decimated(s, |i| Some(normal(s.rendered[i])))),
        ],
    });
    // The shadow node's line, when a run had one (the networked app has none: its series
    // repeats the operator's).
    if s.rendered_remote != s.rendered {
        for (panel, axis) in panels.iter_mut().zip([s.axis, s.normal]) {
            panel.series.push(line(
                "rendered, remote-only contact",
                decimated(s, |i| Some(vec3::dot(s.rendered_remote[i], axis))),
            ));
        }
    }
    panels
}

fn error_panels(error_over_time: &[Window]) -> Vec<Panel> {
    vec![Panel {
        title: "RMS error over run time (1 s windows)".into(),
        x_label: "time [s]".into(),
        y_label: "RMS error / RMS measured [%]".into(),
        log_x: false,
        log_y: true,
        series: vec![Line {
            name: "error".into(),
            points: error_over_time
                .iter()
                .filter_map(|w| w.rms_error_pct.map(|e| (w.t_s + 0.5, e)))
                .collect(),
            markers: true,
            line: true,
        }],
    }]
}

fn spectrum_panels(s: &Series) -> Vec<Panel> {
    let after = s.whole_model_start().unwrap_or(0);
    let along = |v: [f64; 3]| vec3::dot(v, s.axis);
    let measured: Vec<f64> = (after..s.len())
        .map(|i| s.measured[i].map_or(0.0, along))
        .collect();
    let error: Vec<f64> = (after..s.len())
        .map(|i| s.measured[i].map_or(0.0, |m| along(s.rendered[i]) - along(m)))
        .collect();
    let n = measured.len().max(1) as f64;
    let amplitude = |x: &[f64]| -> Vec<(f64, f64)> {
        spectrum(x, s.dt_s())
            .into_iter()
            .filter(|(f, _)| *f > 0.0 && *f <= 10.0)
            .map(|(f, c)| (f, 2.0 * c.norm() / n))
            .collect()
    };
    vec![Panel {
        title: "spectrum of the tangential force and of its rendering error (after stable)".into(),
        x_label: "frequency [Hz]".into(),
        y_label: "amplitude [N]".into(),
        log_x: true,
        log_y: true,
        series: vec![
            line("measured", amplitude(&measured)),
            line("error", amplitude(&error)),
        ],
    }]
}

fn line(name: &str, points: Vec<(f64, f64)>) -> Line {
    Line {
        name: name.into(),
        points,
        markers: false,
        line: true,
    }
}
