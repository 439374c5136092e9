//! `rtd denoise`: the learned denoiser on images from any renderer.

use std::path::Path;
use std::time::Instant;

use anyhow::{anyhow, bail, Context};
use glam::Vec3;
use serde::Serialize;

use rtd_denoise::{DenoiseInput, Denoiser, MAX_SIDE};
use rtd_image::{HdrImage, ImageFormat, Layers, Tonemap};

use crate::args::{DenoiseArgs, DenoiserArgs};
use crate::render_command::{check_output, check_report_path, write_json};

/// What `rtd denoise --report` writes.
#[derive(Debug, Clone, Serialize)]
pub struct DenoiseReport {
    /// Colour input.
    pub color: String,
    /// Output file.
    pub output: String,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Seconds spent in the denoiser (encoding, network, decoding).
    pub denoise_s: f64,
    /// The model used (path or builtin:…).
    pub denoise_model: String,
    /// Self-ensemble passes (1: the network alone).
    pub denoise_passes: usize,
    /// Which inputs were given.
    pub inputs: Vec<String>,
    /// Input colour values that were NaN or infinite (set to 0 or clamped).
    pub nonfinite_input_values: usize,
}

/// Loads the model named on the command line, or the built-in one, set to run its
/// `--ensemble` passes.
pub fn load_model(args: &DenoiserArgs) -> anyhow::Result<Denoiser> {
    let model = match &args.model {
        Some(p) => Denoiser::load(p)?,
        None => Denoiser::builtin()?,
    };
    Ok(model.passes(args.ensemble as usize))
}

/// Reads an image layer: from an EXR the `prefix.*` layer if present, else `R,G,B` (or
/// `X,Y,Z` for vectors); from PNG/JPEG the sRGB-decoded RGB.
fn read_layer(path: &Path, prefix: &str, vector: bool) -> anyhow::Result<HdrImage> {
    if !path.exists() {
        bail!("{}: no such file", path.display());
    }
    match ImageFormat::from_path(path)? {
        ImageFormat::Exr => {
            let layers: Layers = rtd_image::read_exr(path)?;
            let found = if vector { layers.xyz(prefix).or_else(|| layers.rgb(prefix)) } else { layers.rgb(prefix) };
            found
                .or_else(|| layers.rgb(""))
                .or_else(|| if vector { layers.xyz("") } else { None })
                .ok_or_else(|| anyhow!("{}: no `{prefix}.*` or R,G,B channels", path.display()))
        }
        _ => {
            let img = rtd_image::read_ldr(path)?;
            if vector {
                // 8-bit normal maps store n·0.5 + 0.5 (before sRGB decoding, which read_ldr undid).
                let px = img.pixels.iter().map(|p| {
                    let e = |x: f32| rtd_image::linear_to_srgb(x) * 2.0 - 1.0;
                    Vec3::new(e(p.x), e(p.y), e(p.z))
                });
                Ok(HdrImage::from_pixels(img.width, img.height, px.collect()))
            } else {
                Ok(img)
            }
        }
    }
}

fn check_size(path: &Path, img: &HdrImage) -> anyhow::Result<()> {
    if img.width > MAX_SIDE || img.height > MAX_SIDE {
        bail!("{}: {}x{} exceeds {MAX_SIDE} pixels on a side", path.display(), img.width, img.height);
    }
    Ok(())
}

fn same_size(path: &Path, img: &HdrImage, color: &HdrImage) -> anyhow::Result<()> {
    if (img.width, img.height) != (color.width, color.height) {
        bail!(
            "{}: image is {}x{} but the colour image is {}x{}",
            path.display(),
            img.width,
            img.height,
            color.width,
            color.height
        );
    }
    Ok(())
}

/// Counts NaN/Inf values in an image.
pub fn count_nonfinite(img: &HdrImage) -> usize {
    img.pixels.iter().map(|p| p.to_array().iter().filter(|v| !v.is_finite()).count()).sum()
}

/// Replaces NaN/Inf in an output (the denoiser never makes them; this is the last guard).
fn finite(img: HdrImage) -> HdrImage {
    let px = img
        .pixels
        .iter()
        .map(|p| Vec3::from_array(p.to_array().map(|v| if v.is_finite() { v } else { 0.0 })))
        .collect();
    HdrImage::from_pixels(img.width, img.height, px)
}

/// Runs `rtd denoise` and returns its report.
pub fn denoise(args: &DenoiseArgs) -> anyhow::Result<DenoiseReport> {
    check_output(&args.output)?;
    if let Some(r) = &args.report {
        check_report_path(r)?;
    }
    if args.guide.is_none() && args.albedo.is_none() {
        bail!("rtd denoise needs --guide (material colour × AO) or --albedo with --normal");
    }
    let model = load_model(&args.denoiser)?;
    let color = read_layer(&args.color, "", false)?;
    check_size(&args.color, &color)?;
    let mut inputs = vec!["color".to_string()];
    let albedo_normal = match (&args.albedo, &args.normal) {
        (Some(a), Some(n)) => {
            let (ai, ni) = (read_layer(a, "albedo", false)?, read_layer(n, "normal", true)?);
            same_size(a, &ai, &color)?;
            same_size(n, &ni, &color)?;
            inputs.extend(["albedo".to_string(), "normal".to_string()]);
            Some((ai, ni))
        }
        _ => None,
    };
    let guide = match &args.guide {
        Some(g) => {
            let gi = read_layer(g, "guide", false)?;
            same_size(g, &gi, &color)?;
            inputs.push("guide".into());
            gi
        }
        // Without a guide image, the albedo stands in for material colour × AO.
        None => albedo_normal.as_ref().map(|(a, _)| a.clone()).context("no guide")?,
    };
    let mut input = DenoiseInput::new(&color, &guide);
    if let Some((a, n)) = &albedo_normal {
        input = input.albedo_normal(a, n);
    }
    let t = Instant::now();
    let out = finite(model.denoise(&input)?);
    let denoise_s = t.elapsed().as_secs_f64();
    match ImageFormat::from_path(&args.output)? {
        ImageFormat::Exr => {
            let mut layers = Layers::new(out.width, out.height);
            layers.push_rgb("", &out);
            rtd_image::write_exr(&args.output, &layers)?
        }
        _ => rtd_image::write_ldr(&args.output, &out, args.exposure, Tonemap::Clamp)?,
    }
    let report = DenoiseReport {
        color: args.color.display().to_string(),
        output: args.output.display().to_string(),
        width: out.width,
        height: out.height,
        denoise_s,
        denoise_model: model.name().to_string(),
        denoise_passes: model.ensemble_passes(),
        inputs,
        nonfinite_input_values: count_nonfinite(&color),
    };
    crate::print_line(&format!(
        "denoised {}x{} in {:.3} s with {}{}",
        out.width,
        out.height,
        denoise_s,
        report.denoise_model,
        if report.nonfinite_input_values > 0 {
            format!(" ({} NaN/Inf input values zeroed or clamped)", report.nonfinite_input_values)
        } else {
            String::new()
        }
    ))?;
    if let Some(path) = &args.report {
        write_json(path, &report)?;
    }
    Ok(report)
}
