//! Pictures for the benchmark reports: a side-by-side strip (noisy | denoised | ETRT |
//! reference), each panel named with its spp and PSNR, with zoomed crops of the region where
//! the denoised image errs most, and the error-versus-time plot of plain path tracing with the
//! denoised result marked.

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

/// Height of the label row above each panel, in pixels.
const LABEL_ROW: u32 = 44;

/// The two label lines of each panel: what it is, and its samples and PSNR.
pub fn panel_labels(report: &EtrtReport) -> [[String; 2]; 4] {
    let s = &report.images;
    let scored = |name: &str, spp: String, psnr: f64| [name.to_string(), format!("{spp}, {psnr:.2} dB")];
    [
        scored("noisy", format!("{} spp", s.noisy.spp), s.noisy.metrics.psnr),
        scored("rtd: render + guide + denoise", format!("{} spp", s.denoised.spp), s.denoised.metrics.psnr),
        scored("equal time, plain path tracing", format!("{} spp", s.etrt.spp), s.etrt.metrics.psnr),
        ["reference".to_string(), reference_label(report)],
    ]
}

/// The reference's samples, or the file it was loaded from (the name only).
fn reference_label(report: &EtrtReport) -> String {
    match report.reference_spp {
        Some(spp) => format!("{spp} spp"),
        None => {
            let file = report.reference.strip_prefix("loaded from ").unwrap_or(&report.reference);
            Path::new(file).file_name().map_or(file.to_string(), |n| n.to_string_lossy().into_owned())
        }
    }
}

/// Writes the strip: the four images on top, each under its label ([`panel_labels`]), and ×4
/// zooms of the worst window below.
pub fn side_by_side(path: &Path, images: &EtrtImages, report: &EtrtReport) -> Result<(), BenchError> {
    let panels = [&images.noisy, &images.denoised, &images.etrt, &images.reference];
    let (w, h) = (images.reference.width, images.reference.height);
    let win = WINDOW.min(w).min(h);
    let (cx, cy) = worst_window(&images.denoised, &images.reference);
    let zoom = (w / win).max(1);
    let gap = 4;
    // Panels at least wide enough for their labels.
    let (pw, top) = (w.max(230), LABEL_ROW);
    let (tw, th) = (4 * pw + 3 * gap, top + h + gap + win * zoom);
    let mut out = image::RgbImage::from_pixel(tw, th, image::Rgb([255, 255, 255]));
    for (k, img) in panels.iter().enumerate() {
        let x0 = k as u32 * (pw + gap);
        for y in 0..h {
            for x in 0..w {
                out.put_pixel(x0 + x, top + y, image::Rgb(tonemap_to_srgb8(img.get(x, y), 0.0, Tonemap::Clamp)));
            }
        }
        // Mark the zoomed window on the full image.
        for i in 0..win {
            for (px, py) in [(cx + i, cy), (cx + i, cy + win - 1), (cx, cy + i), (cx + win - 1, cy + i)] {
                out.put_pixel(x0 + px, top + py, image::Rgb([255, 0, 0]));
            }
        }
        for y in 0..win * zoom {
            for x in 0..(win * zoom).min(w) {
                let v = img.get(cx + x / zoom, cy + y / zoom);
                out.put_pixel(x0 + x, top + h + gap + y, image::Rgb(tonemap_to_srgb8(v, 0.0, Tonemap::Clamp)));
            }
        }
    }
    for (k, [name, detail]) in panel_labels(report).iter().enumerate() {
        let x0 = (k as u32 * (pw + gap)) as i32 + 2;
        let draw = |out: &mut image::RgbImage, y: i32, text: &str| {
            rtd_plot::draw_text(out, x0, y, text, 15.0).map_err(|e| rtd_image::ImageError::invalid(path, e))
        };
        draw(&mut out, 3, name)?;
        draw(&mut out, 22, detail)?;
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
    let mut chart = Chart::new("error against time", "wall time (s)", "relMSE against the reference").log(true, true);
    for r in reports {
        let name = scene_name(&r.scene);
        chart
            .series
            .push(Series::line(format!("{name}: plain path tracing"), r.curve.iter().map(|c| (c.0, c.2)).collect()));
        let d = &r.images.denoised;
        chart.series.push(Series::markers(
            format!("{name}: rtd, {} spp + guide + denoise", d.spp),
            vec![(d.seconds, d.metrics.relmse)],
        ));
    }
    write_charts(path, &[chart])?;
    Ok(())
}
