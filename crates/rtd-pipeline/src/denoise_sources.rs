//! `rtd denoise` as a library call: a noisy image and its guide layers, from rtd or any other
//! renderer, read from files, checked, denoised and written.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Vec3;
use rtd_denoise::{DenoiseInput, Denoiser};
use rtd_image::{Channels, HdrImage, ImageFormat, Layer, Layers, Tonemap};
use serde::Serialize;

use crate::PipelineError;

/// The files a denoise reads: the noisy colour, and a guide (material colour × AO) or an albedo
/// with a normal, or all three. EXR inputs are read from their named layer (`guide.*`,
/// `albedo.*`, `normal.*`) if present, else from `R,G,B`; PNG and JPEG as sRGB (normals as
/// n·0.5 + 0.5).
#[derive(Clone, Debug, Default)]
pub struct DenoiseSources {
    /// Noisy colour.
    pub color: PathBuf,
    /// Guide RGB: material colour × AO.
    pub guide: Option<PathBuf>,
    /// Albedo.
    pub albedo: Option<PathBuf>,
    /// Normal (world or camera space).
    pub normal: Option<PathBuf>,
}

/// What a denoise did, as `rtd denoise --report` writes it.
#[derive(Debug, Clone, Serialize)]
pub struct DenoiseOutcome {
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

/// The refusal of inputs with neither a guide nor an albedo + normal pair.
const NO_GUIDE: PipelineError =
    PipelineError::Sources("a guide (material colour × AO) or an albedo with a normal is needed");

impl DenoiseSources {
    /// Checks, before any file is read, that the inputs make a usable set: a guide, or an albedo
    /// with a normal, or both.
    pub fn check(&self) -> Result<(), PipelineError> {
        match (&self.guide, &self.albedo, &self.normal) {
            (_, Some(_), None) | (_, None, Some(_)) => {
                Err(PipelineError::Sources("albedo and normal must be given together"))
            }
            (None, None, None) => Err(NO_GUIDE),
            _ => Ok(()),
        }
    }

    /// Reads the inputs, denoises them with `denoiser` and writes the result to `output`
    /// ([`Denoised::write`]).
    pub fn run(&self, denoiser: &Denoiser, output: &Path, exposure: f32) -> Result<DenoiseOutcome, PipelineError> {
        ImageFormat::from_path(output)?;
        let denoised = self.denoise(denoiser)?;
        denoised.write(output, exposure)?;
        Ok(denoised.outcome(&self.color, output))
    }

    /// Reads the inputs and denoises them with `denoiser`.
    pub fn denoise(&self, denoiser: &Denoiser) -> Result<Denoised, PipelineError> {
        self.check()?;
        let color = read_layer(&self.color, Layer::Beauty)?;
        let mut inputs = vec!["color".to_string()];
        let albedo_normal = match (&self.albedo, &self.normal) {
            (Some(a), Some(n)) => {
                let (ai, ni) = (read_layer(a, Layer::Albedo)?, read_layer(n, Layer::Normal)?);
                same_size(a, &ai, &color)?;
                same_size(n, &ni, &color)?;
                inputs.extend(["albedo".to_string(), "normal".to_string()]);
                Some((ai, ni))
            }
            _ => None,
        };
        let guide = match (&self.guide, &albedo_normal) {
            (Some(g), _) => {
                let gi = read_layer(g, Layer::Guide)?;
                same_size(g, &gi, &color)?;
                inputs.push("guide".into());
                gi
            }
            // Without a guide image, the albedo stands in for material colour × AO.
            (None, Some((a, _))) => a.clone(),
            (None, None) => return Err(NO_GUIDE),
        };
        let mut input = DenoiseInput::new(&color, &guide);
        if let Some((a, n)) = &albedo_normal {
            input = input.albedo_normal(a, n);
        }
        let t = Instant::now();
        let image = finite(denoiser.denoise(&input)?);
        let denoise_s = t.elapsed().as_secs_f64();
        let guide = self.guide.as_ref().map(|_| guide);
        Ok(Denoised {
            nonfinite_input_values: count_nonfinite(&color),
            image,
            color,
            guide,
            albedo_normal,
            inputs,
            denoise_s,
            model: denoiser.name().to_string(),
            passes: denoiser.ensemble_passes(),
        })
    }
}

/// A denoised image with the inputs it was made from.
pub struct Denoised {
    /// The denoised image.
    pub image: HdrImage,
    /// The noisy colour as read.
    pub color: HdrImage,
    /// The guide image, when one was given.
    pub guide: Option<HdrImage>,
    /// Albedo and normal, when given.
    pub albedo_normal: Option<(HdrImage, HdrImage)>,
    /// Which inputs were given.
    pub inputs: Vec<String>,
    /// Seconds in the denoiser.
    pub denoise_s: f64,
    /// The model's name.
    pub model: String,
    /// Self-ensemble passes.
    pub passes: usize,
    /// Colour input values that were NaN or infinite.
    pub nonfinite_input_values: usize,
}

impl Denoised {
    /// Writes the result to `path`, the format chosen by its extension. An EXR holds the
    /// denoised `R,G,B` and the inputs as layers (`noisy.*`, and `guide.*`, `albedo.*`,
    /// `normal.*` where given); a PNG or JPEG the denoised image, exposed by `exposure` stops
    /// and clamped.
    pub fn write(&self, path: &Path, exposure: f32) -> Result<(), PipelineError> {
        match ImageFormat::from_path(path)? {
            ImageFormat::Exr => {
                let mut layers = Layers::new(self.image.width, self.image.height);
                layers.put_image(Layer::Beauty, &self.image);
                layers.put_image(Layer::Noisy, &self.color);
                if let Some(g) = &self.guide {
                    layers.put_image(Layer::Guide, g);
                }
                if let Some((a, n)) = &self.albedo_normal {
                    layers.put_image(Layer::Albedo, a);
                    layers.put_image(Layer::Normal, n);
                }
                rtd_image::write_exr(path, &layers)?
            }
            ImageFormat::Png | ImageFormat::Jpeg => rtd_image::write_ldr(path, &self.image, exposure, Tonemap::Clamp)?,
        }
        Ok(())
    }

    /// What `rtd denoise --report` writes for this result, read from `color` and written to
    /// `output`.
    pub fn outcome(&self, color: &Path, output: &Path) -> DenoiseOutcome {
        DenoiseOutcome {
            color: color.display().to_string(),
            output: output.display().to_string(),
            width: self.image.width,
            height: self.image.height,
            denoise_s: self.denoise_s,
            denoise_model: self.model.clone(),
            denoise_passes: self.passes,
            inputs: self.inputs.clone(),
            nonfinite_input_values: self.nonfinite_input_values,
        }
    }
}

impl DenoiseOutcome {
    /// The one-line summary `rtd denoise` prints.
    pub fn summary(&self) -> String {
        let nonfinite = match self.nonfinite_input_values {
            0 => String::new(),
            n => format!(" ({n} NaN/Inf input values zeroed or clamped)"),
        };
        format!(
            "denoised {}x{} in {:.3} s with {}{nonfinite}",
            self.width, self.height, self.denoise_s, self.denoise_model
        )
    }
}

/// Reads the image of `layer` from `path`: from an EXR (one part or several) that layer under
/// rtd's or another renderer's name ([`Layers::find_image`]), else the beauty; from PNG/JPEG the
/// sRGB-decoded RGB, with 8-bit normals decoded from n·0.5 + 0.5.
fn read_layer(path: &Path, layer: Layer) -> Result<HdrImage, PipelineError> {
    let vector = layer.channels() == Channels::Xyz;
    let img = match ImageFormat::from_path(path)? {
        ImageFormat::Exr => {
            let layers = rtd_image::read_exr(path)?;
            let found = layers.find_image(layer).or_else(|| layers.find_image(Layer::Beauty));
            found.ok_or_else(|| PipelineError::Input {
                path: path.to_path_buf(),
                message: missing_layer(layer, &layers),
            })?
        }
        ImageFormat::Png | ImageFormat::Jpeg => {
            let img = rtd_image::read_ldr(path)?;
            if vector {
                // 8-bit normal maps store n·0.5 + 0.5 (before sRGB decoding, which read_ldr undid).
                let e = |x: f32| rtd_image::linear_to_srgb(x) * 2.0 - 1.0;
                let px = img.pixels.iter().map(|p| Vec3::new(e(p.x), e(p.y), e(p.z))).collect();
                HdrImage::from_pixels(img.width, img.height, px)
            } else {
                img
            }
        }
    };
    Ok(img)
}

/// What a file without the layer rtd looked for says: the names it tried and the layers found.
fn missing_layer(layer: Layer, layers: &Layers) -> String {
    let mut tried: Vec<String> =
        Some(layer.prefix()).filter(|p| !p.is_empty()).map(|p| format!("`{p}.*`")).into_iter().collect();
    tried.extend(layer.studio_names().iter().map(|n| format!("`*.{n}.*`")));
    tried.push("R,G,B".into());
    let found: Vec<String> =
        layers.prefixes().into_iter().map(|p| if p.is_empty() { "(bare channels)".into() } else { p }).collect();
    format!("no {} channels (layers found: {})", tried.join(", "), found.join(", "))
}

fn same_size(path: &Path, img: &HdrImage, color: &HdrImage) -> Result<(), PipelineError> {
    if (img.width, img.height) != (color.width, color.height) {
        return Err(PipelineError::Input {
            path: path.to_path_buf(),
            message: format!(
                "image is {}x{} but the colour image is {}x{}",
                img.width, img.height, color.width, color.height
            ),
        });
    }
    Ok(())
}

/// Counts NaN/Inf values in an image.
fn count_nonfinite(img: &HdrImage) -> usize {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unusable_set_of_inputs_is_refused_before_any_file_is_read() {
        let with = |guide: bool, albedo: bool, normal: bool| DenoiseSources {
            color: "missing.exr".into(),
            guide: guide.then(|| "g.exr".into()),
            albedo: albedo.then(|| "a.exr".into()),
            normal: normal.then(|| "n.exr".into()),
        };
        assert!(with(true, false, false).check().is_ok());
        assert!(with(false, true, true).check().is_ok());
        assert!(with(true, true, true).check().is_ok());
        for (g, a, n) in [(false, false, false), (false, true, false), (true, false, true)] {
            assert!(matches!(with(g, a, n).check(), Err(PipelineError::Sources(_))), "{g} {a} {n}");
        }
    }
}
