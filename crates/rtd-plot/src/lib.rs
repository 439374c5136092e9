//! Line plots written as PNG (loss curves, error-versus-time curves), drawn with plotters and
//! the bundled DejaVu Sans font so that they look the same on every machine. Only training and
//! the benchmarks plot, so plotting (plotters and the 760 KB font) lives here rather than in
//! the image I/O crate every other crate builds on.

#![warn(missing_docs)]

use std::path::Path;
use std::sync::Once;

use plotters::prelude::*;

use rtd_image::ImageError;

static FONT: Once = Once::new();

fn register_font() {
    FONT.call_once(|| {
        let bytes: &'static [u8] = include_bytes!("../assets/DejaVuSans.ttf");
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, bytes);
    });
}

/// One named series of (x, y) points.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Points in drawing order.
    pub points: Vec<(f64, f64)>,
    /// Draw markers only (no line).
    pub markers_only: bool,
}

impl Series {
    /// A line series.
    pub fn line(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Series { label: label.into(), points, markers_only: false }
    }
    /// A marker-only series (single measured results).
    pub fn markers(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Series { label: label.into(), points, markers_only: true }
    }
}

/// A chart: title, axis labels, optional log-scale x, and its series.
#[derive(Clone, Debug)]
pub struct Chart {
    /// Title above the plot.
    pub title: String,
    /// X axis label.
    pub x_label: String,
    /// Y axis label.
    pub y_label: String,
    /// Log-scale x axis.
    pub log_x: bool,
    /// The data.
    pub series: Vec<Series>,
}

const COLOURS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(23, 190, 207),
];

/// Draws `charts` side by side into a PNG at `path` (written atomically).
pub fn write_charts(path: &Path, charts: &[Chart]) -> Result<(), ImageError> {
    register_font();
    let (w, h) = (640 * charts.len().max(1) as u32, 440u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        let err = |e: String| ImageError::invalid(path, format!("cannot draw plot: {e}"));
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let areas = root.split_evenly((1, charts.len().max(1)));
        for (chart, area) in charts.iter().zip(areas) {
            draw(chart, &area).map_err(err)?;
        }
        root.present().map_err(|e| err(e.to_string()))?;
    }
    let img = image::RgbImage::from_raw(w, h, buf).ok_or_else(|| ImageError::invalid(path, "plot buffer size"))?;
    rtd_image::write_atomic(path, |out| {
        img.write_to(out, image::ImageFormat::Png).map_err(|e| ImageError::invalid(path, e))
    })
}

fn draw(chart: &Chart, area: &DrawingArea<BitMapBackend, plotters::coord::Shift>) -> Result<(), String> {
    let pts = chart
        .series
        .iter()
        .flat_map(|s| s.points.iter())
        .filter(|(x, y)| x.is_finite() && y.is_finite() && (!chart.log_x || *x > 0.0));
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for (x, y) in pts {
        x0 = x0.min(*x);
        x1 = x1.max(*x);
        y0 = y0.min(*y);
        y1 = y1.max(*y);
    }
    if !x0.is_finite() {
        (x0, x1, y0, y1) = (1.0, 2.0, 0.0, 1.0);
    }
    if x1 <= x0 {
        x1 = x0 * 2.0 + 1.0;
    }
    let pad = ((y1 - y0) * 0.05).max(1e-9);
    let (y0, y1) = (y0 - pad, y1 + pad);
    let mut builder = ChartBuilder::on(area);
    builder.caption(&chart.title, ("sans-serif", 20)).margin(12).x_label_area_size(40).y_label_area_size(60);
    macro_rules! body {
        ($ctx:expr) => {{
            let mut ctx = $ctx;
            ctx.configure_mesh()
                .x_desc(chart.x_label.as_str())
                .y_desc(chart.y_label.as_str())
                .label_style(("sans-serif", 13))
                .draw()
                .map_err(|e| e.to_string())?;
            for (i, s) in chart.series.iter().enumerate() {
                let colour = COLOURS[i % COLOURS.len()];
                let data: Vec<(f64, f64)> = s
                    .points
                    .iter()
                    .copied()
                    .filter(|(x, y)| x.is_finite() && y.is_finite() && (!chart.log_x || *x > 0.0))
                    .collect();
                let anno = if s.markers_only {
                    ctx.draw_series(data.iter().map(|p| Circle::new(*p, 6, colour.filled())))
                        .map_err(|e| e.to_string())?
                } else {
                    ctx.draw_series(LineSeries::new(data.clone(), colour.stroke_width(2))).map_err(|e| e.to_string())?
                };
                anno.label(s.label.as_str())
                    .legend(move |(x, y)| Rectangle::new([(x, y - 4), (x + 16, y + 4)], colour.filled()));
            }
            ctx.configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 13))
                .draw()
                .map_err(|e| e.to_string())?;
        }};
    }
    if chart.log_x {
        body!(builder.build_cartesian_2d((x0..x1).log_scale(), y0..y1).map_err(|e| e.to_string())?);
    } else {
        body!(builder.build_cartesian_2d(x0..x1, y0..y1).map_err(|e| e.to_string())?);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn charts_render_to_png_with_lines_in_them() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.png");
        let chart = Chart {
            title: "loss".into(),
            x_label: "step".into(),
            y_label: "L1".into(),
            log_x: true,
            series: vec![
                Series::line("train", (1..50).map(|i| (i as f64, 1.0 / i as f64)).collect()),
                Series::markers("val", vec![(10.0, 0.2)]),
            ],
        };
        write_charts(&path, &[chart.clone(), chart]).unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (1280, 440));
        // The first series colour appears: the line was drawn.
        assert!(img.pixels().any(|p| p.0 == [31, 119, 180]));
    }
}
