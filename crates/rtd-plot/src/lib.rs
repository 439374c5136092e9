//! Line plots written as PNG (loss curves, error-versus-time curves, cost curves), drawn with
//! plotters and the bundled DejaVu Sans font so that they look the same on every machine, and
//! text labels on images (the panels of a side-by-side strip). Only training and the
//! benchmarks plot, so plotting (plotters and the 760 KB font) lives here rather than in the
//! image I/O crate every other crate builds on.
//!
//! Axes carry a few round-valued ticks ([`ticks`]) labelled compactly ([`tick_label`]), log
//! axes at 1-2-5 steps or whole decades, and the legend sits in a strip below the plot, where
//! it can cover no data.

#![warn(missing_docs)]

use std::path::Path;
use std::sync::Once;

use plotters::prelude::*;

use rtd_image::ImageError;

mod axis;

pub use axis::{tick_label, ticks};

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

/// A chart: title, axis labels (with units), log or linear axes, and its series.
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
    /// Log-scale y axis.
    pub log_y: bool,
    /// The data.
    pub series: Vec<Series>,
}

impl Chart {
    /// A chart with linear axes and no series yet.
    pub fn new(title: impl Into<String>, x_label: impl Into<String>, y_label: impl Into<String>) -> Self {
        Chart {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            log_x: false,
            log_y: false,
            series: vec![],
        }
    }
    /// Sets log-scale axes.
    pub fn log(mut self, x: bool, y: bool) -> Self {
        self.log_x = x;
        self.log_y = y;
        self
    }
    /// Adds a series.
    pub fn with(mut self, series: Series) -> Self {
        self.series.push(series);
        self
    }
}

/// Series colours, in order.
pub const COLOURS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(23, 190, 207),
];

/// Width and height of one chart's plot, without its legend strip.
const CHART: (u32, u32) = (640, 440);
/// Height of one legend row.
const LEGEND_ROW: u32 = 20;

/// Most charts side by side in one row of a picture; more go on further rows.
pub const MAX_COLUMNS: usize = 3;

/// Draws `charts` side by side (in rows of at most [`MAX_COLUMNS`]) into a PNG at `path`
/// (written atomically).
pub fn write_charts(path: &Path, charts: &[Chart]) -> Result<(), ImageError> {
    register_font();
    let legend_rows = charts.iter().map(|c| c.series.len()).max().unwrap_or(0) as u32;
    let columns = charts.len().clamp(1, MAX_COLUMNS);
    let rows = charts.len().div_ceil(columns).max(1);
    let cell = CHART.1 + legend_rows * LEGEND_ROW + 8;
    let (w, h) = (CHART.0 * columns as u32, cell * rows as u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        let err = |e: String| ImageError::invalid(path, format!("cannot draw plot: {e}"));
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let areas = root.split_evenly((rows, columns));
        for (chart, area) in charts.iter().zip(areas) {
            let (plot, legend) = area.split_vertically(CHART.1);
            draw(chart, &plot).map_err(err)?;
            draw_legend(chart, &legend).map_err(err)?;
        }
        root.present().map_err(|e| err(e.to_string()))?;
    }
    let img = image::RgbImage::from_raw(w, h, buf).ok_or_else(|| ImageError::invalid(path, "plot buffer size"))?;
    rtd_image::write_atomic(path, |out| {
        img.write_to(out, image::ImageFormat::Png).map_err(|e| ImageError::invalid(path, e))
    })
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

/// The value drawn for `v` on an axis: itself, or its log10 on a log axis (None where a log
/// axis cannot show it).
fn to_axis(v: f64, log: bool) -> Option<f64> {
    match log {
        true if v > 0.0 && v.is_finite() => Some(v.log10()),
        false if v.is_finite() => Some(v),
        _ => None,
    }
}

/// The extent of the values on one axis (in axis units), padded, or a unit range for none.
fn extent(values: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let span = hi - lo;
    // A flat series still gets a visible range: ±5% of its value, or ±0.5 around 0.
    let pad = if span > 0.0 {
        span * 0.05
    } else if log {
        0.1
    } else {
        (lo.abs() * 0.05).max(0.5)
    };
    (lo - pad, hi + pad)
}

fn draw(chart: &Chart, area: &Area) -> Result<(), String> {
    let data: Vec<Vec<(f64, f64)>> = chart
        .series
        .iter()
        .map(|s| {
            s.points.iter().filter_map(|(x, y)| Some((to_axis(*x, chart.log_x)?, to_axis(*y, chart.log_y)?))).collect()
        })
        .collect();
    let (x0, x1) = extent(data.iter().flatten().map(|p| p.0), chart.log_x);
    let (y0, y1) = extent(data.iter().flatten().map(|p| p.1), chart.log_y);
    let (xt, yt) = (ticks(x0, x1, chart.log_x), ticks(y0, y1, chart.log_y));
    let mut builder = ChartBuilder::on(area);
    builder.caption(&chart.title, ("sans-serif", 20)).margin(14).x_label_area_size(44).y_label_area_size(70);
    let x_axis = axis::TickedAxis::new(x0, x1, xt);
    let y_axis = axis::TickedAxis::new(y0, y1, yt);
    let mut ctx = builder.build_cartesian_2d(x_axis, y_axis).map_err(|e| e.to_string())?;
    let (log_x, log_y) = (chart.log_x, chart.log_y);
    let fx = move |v: &f64| tick_label(if log_x { 10f64.powf(*v) } else { *v });
    let fy = move |v: &f64| tick_label(if log_y { 10f64.powf(*v) } else { *v });
    ctx.configure_mesh()
        .x_desc(chart.x_label.as_str())
        .y_desc(chart.y_label.as_str())
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .x_label_formatter(&fx)
        .y_label_formatter(&fy)
        .bold_line_style(RGBColor(215, 215, 215))
        .light_line_style(TRANSPARENT)
        .draw()
        .map_err(|e| e.to_string())?;
    for (i, (s, points)) in chart.series.iter().zip(data).enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        if s.markers_only {
            ctx.draw_series(points.iter().map(|p| Circle::new(*p, 6, colour.filled()))).map_err(|e| e.to_string())?;
        } else if points.len() == 1 {
            // A line of one point (a run's first validated epoch) would draw nothing: a dot.
            ctx.draw_series(points.iter().map(|p| Circle::new(*p, 3, colour.filled()))).map_err(|e| e.to_string())?;
        } else {
            ctx.draw_series(LineSeries::new(points, colour.stroke_width(2))).map_err(|e| e.to_string())?;
        }
    }
    Ok(())
}

/// The legend below a chart: one row per series, a swatch in its colour and its label.
fn draw_legend(chart: &Chart, area: &Area) -> Result<(), String> {
    let font = ("sans-serif", 14).into_font().color(&BLACK);
    let e = |e: DrawingAreaErrorKind<_>| e.to_string();
    for (i, s) in chart.series.iter().enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        let y = (i as u32 * LEGEND_ROW) as i32 + 4;
        if s.markers_only {
            area.draw(&Circle::new((92, y + 8), 6, colour.filled())).map_err(e)?;
        } else {
            area.draw(&Rectangle::new([(80, y + 6), (104, y + 10)], colour.filled())).map_err(e)?;
        }
        area.draw(&Text::new(s.label.clone(), (114, y), font.clone())).map_err(e)?;
    }
    Ok(())
}

/// Writes `text` onto `img` with its top-left corner at (`x`, `y`), `size` px high, in the
/// bundled font: labels of image panels.
pub fn draw_text(img: &mut image::RgbImage, x: i32, y: i32, text: &str, size: f64) -> Result<(), String> {
    register_font();
    let (w, h) = img.dimensions();
    let root = BitMapBackend::with_buffer(img.as_mut(), (w, h)).into_drawing_area();
    let font = ("sans-serif", size).into_font().color(&BLACK);
    root.draw(&Text::new(text.to_string(), (x, y), font)).map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn charts_render_to_png_with_lines_and_a_legend_below_the_plot() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.png");
        let chart = Chart::new("loss", "step", "L1")
            .log(true, true)
            .with(Series::line("train", (1..50).map(|i| (i as f64, 1.0 / i as f64)).collect()))
            .with(Series::markers("val", vec![(10.0, 0.2)]));
        write_charts(&path, &[chart.clone(), chart]).unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (1280, CHART.1 + 2 * LEGEND_ROW + 8));
        let blue = |p: &image::Rgb<u8>| p.0 == [31, 119, 180];
        // The line is drawn in the plot, and the legend swatch below it.
        assert!(img.enumerate_pixels().any(|(_, y, p)| y < CHART.1 && blue(p)));
        assert!(img.enumerate_pixels().any(|(_, y, p)| y >= CHART.1 && blue(p)));
    }

    #[test]
    fn a_line_of_one_point_is_drawn_as_a_dot() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.png");
        let chart = Chart::new("validation", "step", "PSNR (dB)").with(Series::line("denoised", vec![(500.0, 24.3)]));
        write_charts(&path, &[chart]).unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        let blue = |p: &image::Rgb<u8>| p.0 == [31, 119, 180];
        assert!(img.enumerate_pixels().any(|(_, y, p)| y < CHART.1 && blue(p)), "the point is not drawn");
    }

    #[test]
    fn text_is_drawn_where_asked() {
        let mut img = image::RgbImage::from_pixel(120, 30, image::Rgb([255, 255, 255]));
        draw_text(&mut img, 4, 4, "noisy 8 spp", 16.0).unwrap();
        let dark = |x0: u32, x1: u32| {
            (x0..x1).flat_map(|x| (0..30).map(move |y| (x, y))).any(|(x, y)| img.get_pixel(x, y).0[0] < 128)
        };
        assert!(dark(0, 60), "no text drawn");
        assert!(!dark(110, 120), "text ran past its end");
    }
}
