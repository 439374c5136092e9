//! Pictures for the benchmark reports: a side-by-side strip (noisy | denoised | ETRT |
//! reference) with zoomed crops of the region where the denoised image errs most, and the
//! error-versus-time plot of plain path tracing with the denoised result marked.

use std::path::Path;

use glam::Vec3;
use rtd_image::{tonemap_to_srgb8, HdrImage, Tonemap};
use rtd_plot::{write_charts, Chart, Series};

use crate::etrt::{EtrtImages, EtrtReport};
use crate::BenchError;

/// Side of the square crop window, in image pixels.
const WINDOW: u32 = 32;

/// The top-left corner of the `WINDOW`² region where `test` differs most from `reference`
/// (summed squared tonemapped error), searched on a stride of WINDOW/2.
pub fn worst_window(test: &HdrImage, reference: &HdrImage) -> (u32, u32) {
    let win = WINDOW.min(reference.width).min(reference.height);
    let stride = (win / 2).max(1);
    let err = |x: u32, y: u32| {
        let a = Vec3::from_array(tonemap_to_srgb8(test.get(x, y), 0.0, Tonemap::Clamp).map(|v| v as f32));
        let b = Vec3::from_array(tonemap_to_srgb8(reference.get(x, y), 0.0, Tonemap::Clamp).map(|v| v as f32));
        (a - b).length_squared()
    };
    let mut best = (f32::NEG_INFINITY, (0, 0));
    let mut y = 0;
    while y + win <= reference.height {
        let mut x = 0;
        while x + win <= reference.width {
            let e: f32 = (y..y + win).flat_map(|j| (x..x + win).map(move |i| (i, j))).map(|(i, j)| err(i, j)).sum();
            if e > best.0 {
                best = (e, (x, y));
            }
            x += stride;
        }
        y += stride;
    }
    best.1
}

/// Writes the strip: the four images on top, ×4 zooms of the worst window below.
pub fn side_by_side(path: &Path, images: &EtrtImages) -> Result<(), BenchError> {
    let panels = [&images.noisy, &images.denoised, &images.etrt, &images.reference];
    let (w, h) = (images.reference.width, images.reference.height);
    let win = WINDOW.min(w).min(h);
    let (cx, cy) = worst_window(&images.denoised, &images.reference);
    let zoom = (w / win).max(1);
    let gap = 4;
    let (tw, th) = (4 * w + 3 * gap, h + gap + win * zoom);
    let mut out = image::RgbImage::from_pixel(tw, th, image::Rgb([255, 255, 255]));
    for (k, img) in panels.iter().enumerate() {
        let x0 = k as u32 * (w + gap);
        for y in 0..h {
            for x in 0..w {
                out.put_pixel(x0 + x, y, image::Rgb(tonemap_to_srgb8(img.get(x, y), 0.0, Tonemap::Clamp)));
            }
        }
        // Mark the zoomed window on the full image.
        for i in 0..win {
            for (px, py) in [(cx + i, cy), (cx + i, cy + win - 1), (cx, cy + i), (cx + win - 1, cy + i)] {
                out.put_pixel(x0 + px, py, image::Rgb([255, 0, 0]));
            }
        }
        for y in 0..win * zoom {
            for x in 0..(win * zoom).min(w) {
                let v = img.get(cx + x / zoom, cy + y / zoom);
                out.put_pixel(x0 + x, h + gap + y, image::Rgb(tonemap_to_srgb8(v, 0.0, Tonemap::Clamp)));
            }
        }
    }
    rtd_image::write_atomic(path, |w| {
        out.write_to(w, image::ImageFormat::Png).map_err(|e| rtd_image::ImageError::invalid(path, e))
    })?;
    Ok(())
}

/// A report's scene file by its stem, for legends.
pub fn scene_name(scene: &str) -> String {
    Path::new(scene).file_stem().and_then(|s| s.to_str()).unwrap_or("scene").to_string()
}

/// relMSE against time for plain path tracing, one line per report, with each denoised result
/// as a marker.
pub fn error_plot(path: &Path, reports: &[EtrtReport]) -> Result<(), BenchError> {
    let mut series = vec![];
    for r in reports {
        let name = scene_name(&r.scene);
        series.push(Series::line(format!("{name}: plain"), r.curve.iter().map(|c| (c.0, c.2.log10())).collect()));
        let d = &r.images.denoised;
        series.push(Series::markers(
            format!("{name}: rtd {} spp + denoise", d.spp),
            vec![(d.seconds, d.metrics.relmse.log10())],
        ));
    }
    let chart = Chart {
        title: "error against time".into(),
        x_label: "seconds (log)".into(),
        y_label: "log10 relMSE".into(),
        log_x: true,
        series,
    };
    write_charts(path, &[chart])?;
    Ok(())
}
