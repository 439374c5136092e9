//! `rtd denoise` as a library call: a noisy image and its guide layers, from rtd or any other
//! renderer, read from files, checked, denoised and written.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Vec3;
use rtd_denoise::{DenoiseInput, Denoiser};
use rtd_image::{Channels, HdrImage, ImageFormat, Layer, Layers, Tonemap};
use serde::Serialize;

use crate::PipelineError;

/// The files a denoise reads: the noisy colour, and optionally a guide (material colour × AO),
/// an albedo, and a normal (which needs the albedo). EXR inputs are read from their named layer
/// (rtd's `guide.*`, `albedo.*`, `normal.*`, other renderers' pass names, or a prefix set with
/// [`DenoiseSources::layer`]), else from `R,G,B`; PFM/PHM as linear; PNG and JPEG as sRGB
/// (normals as n·0.5 + 0.5).
///
/// The inputs set the mode, as OIDN's do: colour with albedo and normal (and a guide, from rtd),
/// colour with albedo, or colour alone. An EXR colour file from `rtd render` also carries the
/// colour's per-pixel variance (`variance.*`), which the denoiser reads when its model does. Without a guide the albedo stands in for material
/// colour × AO, and without an albedo the noisy colour itself (the thesis's §6.4 ablation).
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
    /// Layer prefixes the caller named for some inputs (`--layer-color`, …), by layer.
    pub layer_names: Vec<(Layer, String)>,
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
    /// Guide layers the colour's EXR holds that were not given as inputs, and so not read
    /// (`guide`, `albedo`, `normal`): an `rtd render --aov` file named as the colour alone is
    /// denoised from its colour only, as OIDN's modes go, which can cost dB.
    pub unread_layers: Vec<String>,
    /// Input colour values that were NaN or infinite (set to 0 or clamped).
    pub nonfinite_input_values: usize,
}

impl DenoiseSources {
    /// Sources with the noisy colour only; add the rest with the setters.
    pub fn new(color: impl Into<PathBuf>) -> Self {
        DenoiseSources { color: color.into(), ..Default::default() }
    }
    /// Sets the guide image.
    pub fn guide(mut self, path: Option<PathBuf>) -> Self {
        self.guide = path;
        self
    }
    /// Sets the albedo image.
    pub fn albedo(mut self, path: Option<PathBuf>) -> Self {
        self.albedo = path;
        self
    }
    /// Sets the normal image.
    pub fn normal(mut self, path: Option<PathBuf>) -> Self {
        self.normal = path;
        self
    }
    /// Reads `layer` from the EXR channels under `prefix` (its whole name or last dotted part).
    pub fn layer(mut self, layer: Layer, prefix: Option<String>) -> Self {
        self.layer_names.retain(|(l, _)| *l != layer);
        if let Some(p) = prefix {
            self.layer_names.push((layer, p));
        }
        self
    }

    /// Checks, before any file is read, that the inputs make a usable set: a normal needs an
    /// albedo; every other combination is a mode.
    pub fn check(&self) -> Result<(), PipelineError> {
        match (&self.albedo, &self.normal) {
            (None, Some(_)) => Err(PipelineError::Sources("a normal image needs an albedo image too")),
            _ => Ok(()),
        }
    }

    /// Reads the inputs, denoises them with `denoiser` and writes the result to `output`
    /// ([`Denoised::write`]).
    pub fn run(&self, denoiser: &Denoiser, output: &Path, exposure: f32) -> Result<DenoiseOutcome, PipelineError> {
        ImageFormat::from_path(output)?;
        let denoised = self.denoise(denoiser)?;
        let outcome = denoised.outcome(&self.color, output);
        denoised.write_into(output, exposure)?;
        Ok(outcome)
    }

    /// Reads the inputs and denoises them with `denoiser`.
    pub fn denoise(&self, denoiser: &Denoiser) -> Result<Denoised, PipelineError> {
        self.check()?;
        let mut files = InputFiles::default();
        let color = files.read(&self.color, Layer::Beauty, self.named(Layer::Beauty))?;
        let mut inputs = vec!["color".to_string()];
        let mut other = |path: &Option<PathBuf>, layer: Layer, name: &str| -> Result<Option<HdrImage>, PipelineError> {
            let Some(p) = path else { return Ok(None) };
            let img = files.read(p, layer, self.named(layer))?.image;
            same_size(p, &img, &color.image)?;
            inputs.push(name.to_string());
            Ok(Some(img))
        };
        let albedo = other(&self.albedo, Layer::Albedo, "albedo")?;
        let normal = other(&self.normal, Layer::Normal, "normal")?;
        let guide = other(&self.guide, Layer::Guide, "guide")?;
        let unread_layers = files.exr.get(&self.color).map(|layers| self.unread_layers(layers)).unwrap_or_default();
        // The colour's EXR file, taken whole (not copied): the output is made from it.
        let color_file = color.names.and_then(|names| Some((files.exr.remove(&self.color)?, names)));
        drop(files);
        // rtd's own renders carry the colour's per-pixel variance beside it.
        let variance = color_file.as_ref().and_then(|(layers, _)| layers.image(Layer::Variance));
        let variance = variance.filter(|v| (v.width, v.height) == (color.image.width, color.image.height));
        if variance.is_some() && denoiser.reads_variance() {
            inputs.push("variance".to_string());
        }
        // Without a guide image, the albedo stands in for material colour × AO, and without an
        // albedo the noisy colour itself.
        let input = DenoiseInput::with_stand_in_guide(&color.image, guide.as_ref(), albedo.as_ref(), normal.as_ref())
            .variance(variance.as_ref());
        let t = Instant::now();
        let image = finite(denoiser.denoise(&input)?);
        let denoise_s = t.elapsed().as_secs_f64();
        drop(variance);
        Ok(Denoised {
            nonfinite_input_values: count_nonfinite(&color.image),
            image,
            color: color.image,
            color_file,
            color_half: color.half,
            guide,
            albedo_normal: albedo.zip(normal),
            inputs,
            unread_layers,
            denoise_s,
            model: denoiser.name().to_string(),
            passes: denoiser.ensemble_passes(),
        })
    }

    /// The guide layers in the colour's EXR `layers` that were not given as inputs and could
    /// be: a normal only beside an albedo (given, or unread in the same file), which it needs.
    fn unread_layers(&self, layers: &Layers) -> Vec<String> {
        let has = |layer| layers.find_channels(layer, None).is_some();
        let albedo = self.albedo.is_some() || has(Layer::Albedo);
        [(Layer::Guide, &self.guide, true), (Layer::Albedo, &self.albedo, true), (Layer::Normal, &self.normal, albedo)]
            .into_iter()
            .filter(|(layer, given, usable)| given.is_none() && *usable && has(*layer))
            .map(|(layer, _, _)| layer.prefix())
            .collect()
    }

    /// The prefix the caller named for `layer`, if any.
    fn named(&self, layer: Layer) -> Option<&str> {
        self.layer_names.iter().find(|(l, _)| *l == layer).map(|(_, p)| p.as_str())
    }
}

/// One input as read: its image, and for an EXR the three channels it came from.
struct Source {
    image: HdrImage,
    names: Option<[String; 3]>,
    half: bool,
}

/// The EXR files a denoise has read, each read once however many inputs it holds.
#[derive(Default)]
struct InputFiles {
    exr: HashMap<PathBuf, Layers>,
}

impl InputFiles {
    /// Reads the image of `layer` from `path`: from an EXR that layer under rtd's or another
    /// renderer's name, or under `prefix` when the caller named one ([`Layers::find_channels`]),
    /// else its bare `R,G,B`; PFM/PHM as linear RGB; PNG/JPEG sRGB-decoded, with 8- or 16-bit
    /// normals decoded from n·0.5 + 0.5. An EXR's channels stay in [`InputFiles::exr`].
    fn read(&mut self, path: &Path, layer: Layer, prefix: Option<&str>) -> Result<Source, PipelineError> {
        let vector = layer.channels() == Channels::Xyz;
        let format = ImageFormat::from_path(path)?;
        let source = match format {
            ImageFormat::Exr => {
                if !self.exr.contains_key(path) {
                    self.exr.insert(path.to_path_buf(), rtd_image::read_exr(path)?);
                }
                let layers = &self.exr[path];
                // Without a named prefix, a file of bare R,G,B holds any layer (another renderer's
                // albedo or normal saved on its own).
                let bare = ["R", "G", "B"].map(String::from);
                let fallback = (prefix.is_none() && bare.iter().all(|c| layers.get(c).is_some())).then_some(bare);
                let names = layers.find_channels(layer, prefix).or(fallback);
                let names = names.ok_or_else(|| PipelineError::Input {
                    path: path.to_path_buf(),
                    message: missing_layer(layer, prefix, layers),
                })?;
                let half = names.iter().all(|n| layers.half_channels.contains(n));
                let image = layers.image_in(&names);
                Source { image, names: Some(names), half }
            }
            ImageFormat::Pfm | ImageFormat::Phm => {
                Source { image: rtd_image::read_pfm(path)?, names: None, half: format == ImageFormat::Phm }
            }
            ImageFormat::Png | ImageFormat::Jpeg => {
                let img = rtd_image::read_ldr(path)?;
                let image = if vector {
                    // Normal maps store n·0.5 + 0.5 (before sRGB decoding, which read_ldr undid).
                    let e = |x: f32| rtd_image::linear_to_srgb(x) * 2.0 - 1.0;
                    let px = img.pixels.iter().map(|p| Vec3::new(e(p.x), e(p.y), e(p.z))).collect();
                    HdrImage::from_pixels(img.width, img.height, px)
                } else {
                    img
                };
                Source { image, names: None, half: false }
            }
        };
        Ok(source)
    }
}

/// What a file without the layer rtd looked for says: the names it tried and the layers found.
fn missing_layer(layer: Layer, prefix: Option<&str>, layers: &Layers) -> String {
    let what = match layer {
        Layer::Beauty => "colour".to_string(),
        other => other.prefix(),
    };
    let tried = match prefix {
        Some(p) => format!("the layer named {p:?}"),
        None => {
            let mut names: Vec<String> = Some(layer.prefix()).filter(|p| !p.is_empty()).into_iter().collect();
            names.extend(layer.studio_names().iter().map(|n| n.to_string()));
            if layer == Layer::Beauty {
                "bare R,G,B and passes named ".to_string() + &names.join(", ")
            } else {
                format!("passes named {}, and bare R,G,B", names.join(", "))
            }
        }
    };
    let found: Vec<String> =
        layers.prefixes().into_iter().map(|p| if p.is_empty() { "(bare channels)".into() } else { p }).collect();
    format!("no {what} layer (looked for {tried}; layers found: {})", found.join(", "))
}

/// A denoised image with the inputs it was made from.
pub struct Denoised {
    /// The denoised image.
    pub image: HdrImage,
    /// The noisy colour as read.
    pub color: HdrImage,
    /// The colour's EXR file, when it was one: every channel, and the three the colour came
    /// from (which the denoised image replaces on output).
    pub color_file: Option<(Layers, [String; 3])>,
    /// The colour was stored as half floats (EXR or PHM): outputs are too.
    pub color_half: bool,
    /// The guide image, when one was given.
    pub guide: Option<HdrImage>,
    /// Albedo and normal, when given.
    pub albedo_normal: Option<(HdrImage, HdrImage)>,
    /// Which inputs were given.
    pub inputs: Vec<String>,
    /// Guide layers in the colour's file that were not given as inputs (see
    /// [`DenoiseOutcome::unread_layers`]).
    pub unread_layers: Vec<String>,
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
    /// Writes the result to `path`, the format chosen by its extension.
    ///
    /// - **EXR**, colour read from an EXR: every channel of that file, with the denoised image
    ///   in place of the noisy colour's three channels (alpha and other passes kept, half
    ///   channels stay half), plus rtd's `guide.*`, `albedo.*`, `normal.*` for inputs from other
    ///   files that the output lacks.
    /// - **EXR**, colour from another format: the denoised `R,G,B` and the inputs as layers
    ///   (`noisy.*`, and `guide.*`, `albedo.*`, `normal.*` where given); half when the colour
    ///   was (PHM).
    /// - **PFM/PHM**: the denoised image, 32- or 16-bit.
    /// - **PNG/JPEG**: the denoised image, exposed by `exposure` stops and clamped.
    pub fn write(&self, path: &Path, exposure: f32) -> Result<(), PipelineError> {
        match ImageFormat::from_path(path)? {
            ImageFormat::Exr => rtd_image::write_exr_owned(path, self.exr_layers())?,
            format @ (ImageFormat::Pfm | ImageFormat::Phm) => {
                rtd_image::write_pfm(path, &self.image, format == ImageFormat::Phm)?
            }
            ImageFormat::Png | ImageFormat::Jpeg => rtd_image::write_ldr(path, &self.image, exposure, Tonemap::Clamp)?,
        }
        Ok(())
    }

    /// [`Denoised::write`], consuming the result: an EXR output is made in the colour file's own
    /// channels, which move into the file written instead of being copied.
    pub fn write_into(mut self, path: &Path, exposure: f32) -> Result<(), PipelineError> {
        match ImageFormat::from_path(path)? {
            ImageFormat::Exr => {
                let file = self.color_file.take();
                let layers = self.layers_with(file);
                drop(self);
                rtd_image::write_exr_owned(path, layers)?
            }
            _ => self.write(path, exposure)?,
        }
        Ok(())
    }

    /// The channels an EXR output holds ([`Denoised::write`]).
    pub fn exr_layers(&self) -> Layers {
        self.layers_with(self.color_file.clone())
    }

    /// The channels an EXR output holds, made in `file` (the colour's EXR file and the names of
    /// the colour's channels in it) when there is one.
    fn layers_with(&self, file: Option<(Layers, [String; 3])>) -> Layers {
        let mut layers = match file {
            Some((mut layers, names)) => {
                for (c, name) in names.iter().enumerate() {
                    layers.set_samples(name, self.image.channel(c));
                }
                layers
            }
            None => {
                let mut layers = Layers::new(self.image.width, self.image.height);
                layers.put_image(Layer::Beauty, &self.image);
                layers.put_image(Layer::Noisy, &self.color);
                if self.color_half {
                    layers.half_channels =
                        [Layer::Beauty, Layer::Noisy].iter().flat_map(|l| l.channel_names()).collect();
                }
                layers
            }
        };
        let mut add = |layer: Layer, image: &HdrImage| {
            if layers.find_channels(layer, None).is_none() {
                layers.put_image(layer, image);
            }
        };
        if let Some(g) = &self.guide {
            add(Layer::Guide, g);
        }
        if let Some((a, n)) = &self.albedo_normal {
            add(Layer::Albedo, a);
            add(Layer::Normal, n);
        }
        layers
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
            unread_layers: self.unread_layers.clone(),
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
        let unread = match self.unread_layers.as_slice() {
            [] => String::new(),
            names => format!(
                "; {} also holds {} layers, not read: name it as --{} too to use them",
                self.color,
                names.join(", "),
                names.join(", --")
            ),
        };
        format!(
            "denoised {}x{} in {:.3} s with {} from {}{nonfinite}{unread}",
            self.width,
            self.height,
            self.denoise_s,
            self.denoise_model,
            self.inputs.join(", ")
        )
    }
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
fn finite(mut img: HdrImage) -> HdrImage {
    for p in &mut img.pixels {
        *p = Vec3::from_array(p.to_array().map(|v| if v.is_finite() { v } else { 0.0 }));
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_normal_without_an_albedo_is_refused_before_any_file_is_read() {
        let with = |guide: bool, albedo: bool, normal: bool| {
            DenoiseSources::new("missing.exr")
                .guide(guide.then(|| "g.exr".into()))
                .albedo(albedo.then(|| "a.exr".into()))
                .normal(normal.then(|| "n.exr".into()))
        };
        for (g, a, n) in
            [(true, false, false), (false, true, true), (true, true, true), (false, false, false), (false, true, false)]
        {
            assert!(with(g, a, n).check().is_ok(), "{g} {a} {n}");
        }
        for (g, a, n) in [(false, false, true), (true, false, true)] {
            assert!(matches!(with(g, a, n).check(), Err(PipelineError::Sources(_))), "{g} {a} {n}");
        }
    }

    /// A 2×2 layer set holding these of rtd's guide layers beside the colour.
    fn layers(with: &[Layer]) -> Layers {
        let mut l = Layers::new(2, 2);
        l.put_image(Layer::Beauty, &HdrImage::new(2, 2));
        with.iter().for_each(|&layer| l.put_image(layer, &HdrImage::new(2, 2)));
        l
    }

    #[test]
    fn unread_layers_are_the_ones_that_could_be_read() {
        let colour_alone = DenoiseSources::new("r.exr");
        let (guide, albedo, normal) = (Layer::Guide, Layer::Albedo, Layer::Normal);
        assert_eq!(colour_alone.unread_layers(&layers(&[guide, albedo, normal])), ["guide", "albedo", "normal"]);
        assert_eq!(colour_alone.unread_layers(&layers(&[])), Vec::<String>::new());
        // A normal needs an albedo: without one in the file or given, it is not offered.
        assert_eq!(colour_alone.unread_layers(&layers(&[guide, normal])), ["guide"]);
        let with_albedo = DenoiseSources::new("r.exr").albedo(Some("a.exr".into()));
        assert_eq!(with_albedo.unread_layers(&layers(&[guide, normal])), ["guide", "normal"]);
        let all = with_albedo.guide(Some("r.exr".into())).normal(Some("r.exr".into()));
        assert_eq!(all.unread_layers(&layers(&[guide, albedo, normal])), Vec::<String>::new());
    }
}
