//! Line plots with `plotters`, rendered in memory with an embedded font (DejaVu Sans, see
//! `assets/DejaVuSans-LICENSE.txt`), so no system font library is needed.

use plotters::coord::ranged1d::ValueFormatter;
use plotters::prelude::*;
use std::sync::Once;
use thiserror::Error;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

/// One named line.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// Legend label.
    pub name: String,
    /// `(x, y)` points; non-finite points are skipped (and so are non-positive ones on log axes).
    pub points: Vec<(f64, f64)>,
    /// Draw markers at the points as well as the line.
    pub markers: bool,
    /// Draw the line (false: markers only, a scatter plot).
    pub line: bool,
}

impl Series {
    /// Markers only.
    pub fn scatter(name: &str, points: Vec<(f64, f64)>) -> Series {
        Series {
            name: name.into(),
            points,
            markers: true,
            line: false,
        }
    }
}

/// One chart.
#[derive(Clone, Debug, PartialEq)]
pub struct Panel {
    /// Title above the chart.
    pub title: String,
    /// x-axis label.
    pub x_label: String,
    /// y-axis label.
    pub y_label: String,
    /// Logarithmic x axis.
    pub log_x: bool,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// The lines.
    pub series: Vec<Series>,
}

/// Plotting failed.
#[derive(Debug, Error)]
pub enum PlotError {
    /// The drawing backend failed.
    #[error("plot: {0}")]
    Draw(String),
    /// PNG encoding failed.
    #[error("png encoding: {0}")]
    Png(#[from] png::EncodingError),
}

fn draw_err<E: std::fmt::Debug>(e: E) -> PlotError {
    PlotError::Draw(format!("{e:?}"))
}

/// Renders panels on a grid of `columns` as an SVG document of `size` pixels.
pub fn svg(panels: &[Panel], columns: usize, size: (u32, u32)) -> Result<String, PlotError> {
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, size).into_drawing_area();
        draw(&root, panels, columns)?;
        root.present().map_err(draw_err)?;
    }
    Ok(out)
}

/// Renders panels as PNG bytes.
pub fn png(panels: &[Panel], columns: usize, size: (u32, u32)) -> Result<Vec<u8>, PlotError> {
    let mut rgb = vec![0u8; (size.0 * size.1 * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
        draw(&root, panels, columns)?;
        root.present().map_err(draw_err)?;
    }
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, size.0, size.1);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header()?;
        writer.write_image_data(&rgb)?;
    }
    Ok(bytes)
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    panels: &[Panel],
    columns: usize,
) -> Result<(), PlotError>
where
    DB::ErrorType: 'static,
{
    REGISTER.call_once(|| {
        // The embedded font is valid TTF; a failure would only cost the text, not the plot.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
    root.fill(&WHITE).map_err(draw_err)?;
    let columns = columns.max(1);
    let rows = panels.len().div_ceil(columns).max(1);
    let areas = root.split_evenly((rows, columns));
    for (panel, area) in panels.iter().zip(areas.iter()) {
        draw_panel(area, panel)?;
    }
    Ok(())
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    panel: &Panel,
) -> Result<(), PlotError>
where
    DB::ErrorType: 'static,
{
    let pts: Vec<(f64, f64)> = panel
        .series
        .iter()
        .flat_map(|s| s.points.iter().copied())
        .filter(|&(x, y)| panel.keeps(x, y))
        .collect();
    let (x0, x1) = axis_range(&mut pts.iter().map(|p| p.0), panel.log_x);
    let (y0, y1) = axis_range(&mut pts.iter().map(|p| p.1), panel.log_y);
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(&panel.title, ("sans-serif", 16))
        .margin(8)
        .x_label_area_size(36)
        .y_label_area_size(64);
    match (panel.log_x, panel.log_y) {
        (false, false) => draw_lines(
            builder
                .build_cartesian_2d(x0..x1, y0..y1)
                .map_err(draw_err)?,
            panel,
        ),
        (true, false) => draw_lines(
            builder
                .build_cartesian_2d((x0..x1).log_scale(), y0..y1)
                .map_err(draw_err)?,
            panel,
        ),
        (false, true) => draw_lines(
            builder
                .build_cartesian_2d(x0..x1, (y0..y1).log_scale())
                .map_err(draw_err)?,
            panel,
        ),
        (true, true) => draw_lines(
            builder
                .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
                .map_err(draw_err)?,
            panel,
        ),
    }
}

impl Panel {
    /// Whether a point can be drawn: finite, and positive on a log axis.
    fn keeps(&self, x: f64, y: f64) -> bool {
        x.is_finite() && y.is_finite() && (!self.log_x || x > 0.0) && (!self.log_y || y > 0.0)
    }
}

/// The span of an axis holding `vals`: 5 % padding on a linear axis, a factor 1.5 on a log
/// one, and a default span when there is nothing (or one value) to show.
fn axis_range(vals: &mut dyn Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let (lo, hi) = vals.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
        (l.min(v), h.max(v))
    });
    if !lo.is_finite() {
        return if log { (0.1, 10.0) } else { (0.0, 1.0) };
    }
    if log {
        (lo / 1.5, hi * 1.5)
    } else if hi > lo {
        let pad = 0.05 * (hi - lo);
        (lo - pad, hi + pad)
    } else {
        (lo - 1.0, hi + 1.0)
    }
}

/// Draws the mesh and the panel's lines (with markers where asked) on `chart`, and the legend
/// when there is more than one line.
fn draw_lines<'a, DB, X, Y>(
    mut chart: ChartContext<'a, DB, Cartesian2d<X, Y>>,
    panel: &Panel,
) -> Result<(), PlotError>
where
    DB: DrawingBackend + 'a,
    DB::ErrorType: 'static,
    X: Ranged<ValueType = f64> + ValueFormatter<f64>,
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    chart
        .configure_mesh()
        .x_desc(panel.x_label.as_str())
        .y_desc(panel.y_label.as_str())
        .label_style(("sans-serif", 12))
        .x_label_formatter(&tick)
        .y_label_formatter(&tick)
        .draw()
        .map_err(draw_err)?;
    for (i, s) in panel.series.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        let line: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|&(x, y)| panel.keeps(x, y))
            .collect();
        if s.line {
            chart
                .draw_series(LineSeries::new(line.clone(), color.stroke_width(2)))
                .map_err(draw_err)?
                .label(s.name.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                });
        }
        if s.markers {
            let markers = chart
                .draw_series(line.iter().map(|&p| Circle::new(p, 3, color.filled())))
                .map_err(draw_err)?;
            if !s.line {
                markers
                    .label(s.name.as_str())
                    .legend(move |(x, y)| Circle::new((x + 9, y), 3, color.filled()));
            }
        }
    }
    if panel.series.len() > 1 {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(("sans-serif", 11))
            .draw()
            .map_err(draw_err)?;
    }
    Ok(())
}

/// An axis tick as a short number: three significant digits, exponent form outside
/// [1e-3, 1e4), with the rounding noise of log-scale tick positions removed.
fn tick(v: &f64) -> String {
    let v = *v;
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if (1e-3..1e4).contains(&a) {
        let digits = (2 - a.log10().floor() as i32).max(0) as usize;
        let s = format!("{v:.digits$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        let s = format!("{v:.2e}");
        let (mantissa, exp) = s.split_once('e').unwrap_or((&s, "0"));
        let mantissa = if mantissa.contains('.') {
            mantissa.trim_end_matches('0').trim_end_matches('.')
        } else {
            mantissa
        };
        format!("{mantissa}e{exp}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_short() {
        assert_eq!(tick(&9.999_999_999_999_999e-5), "1e-4");
        assert_eq!(tick(&1e-6), "1e-6");
        assert_eq!(tick(&0.001), "0.001");
        assert_eq!(tick(&0.0099999999), "0.01");
        assert_eq!(tick(&0.25), "0.25");
        assert_eq!(tick(&12.5), "12.5");
        assert_eq!(tick(&-3.0), "-3");
        assert_eq!(tick(&2500.0), "2500");
        assert_eq!(tick(&1.5e5), "1.5e5");
        assert_eq!(tick(&0.0), "0");
    }

    fn panel(log: bool) -> Panel {
        Panel {
            title: "t".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            log_x: log,
            log_y: log,
            series: vec![
                Series {
                    name: "a".into(),
                    points: vec![(1.0, 2.0), (2.0, 3.0), (f64::NAN, 1.0), (0.0, 5.0)],
                    markers: true,
                    line: true,
                },
                Series {
                    name: "b".into(),
                    points: vec![],
                    markers: false,
                    line: true,
                },
                Series::scatter("c", vec![(1.5, 2.5)]),
            ],
        }
    }

    #[test]
    fn renders_svg_and_png_without_system_fonts() {
        let s = svg(&[panel(false), panel(true)], 2, (800, 400)).unwrap();
        assert!(s.starts_with("<svg") && s.contains("<text"));
        let p = png(&[panel(true)], 1, (300, 200)).unwrap();
        assert_eq!(&p[1..4], b"PNG");
    }
}
