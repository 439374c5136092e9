//! HDR input encoding: sanitising (NaN → 0, Inf and negatives clamped), auto-exposure from the
//! log-average luminance, and a log transfer for colour. The input planes are assembled from
//! these in [`crate::plane_encoder`].

use glam::Vec3;
use rayon::prelude::*;
use rtd_image::{luminance, HdrImage};

use crate::planes::INPUT_CHANNELS;
use crate::vector_math::{exp_m1, ln_1p, multiversioned};
use crate::DenoiseError;

/// Largest colour value accepted after exposure (ln(1 + 10⁹) ≈ 20.7 after the transfer); +Inf
/// and larger values are clamped to it. Bounding the exposed value rather than the raw one keeps
/// encoding independent of the image's units.
pub const MAX_EXPOSED: f32 = 1e9;

/// Exposures are kept within [1/`MAX_EXPOSURE`, `MAX_EXPOSURE`], which no image whose
/// log-average luminance lies between about 1e-19 and 1e19 reaches.
pub const MAX_EXPOSURE: f32 = 1e20;

/// Lit pixels darker than this fraction of the image's log-average luminance count at it in the
/// log-average, so that a few nearly black samples cannot drag the exposure up; a fraction
/// rather than a fixed level, so the exposure scales exactly with the image, and of a
/// geometric mean rather than the mean, so that one huge firefly cannot raise it.
const LOG_AVERAGE_FLOOR: f64 = 1e-6;

/// The value [`auto_exposure`] maps the log-average luminance to (middle grey).
pub const DEFAULT_KEY: f32 = 0.18;

/// Added to the albedo before demodulating, so black albedo divides by this, not by 0.
pub const DEMOD_EPS: f32 = 0.01;

/// How a model turns its inputs into planes (from [`crate::DenoiserConfig::encoding`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Encoding {
    /// Colour is divided by albedo + [`DEMOD_EPS`] where an albedo layer is given.
    pub demodulate: bool,
    /// The value auto-exposure maps the log-average luminance to before the log transfer
    /// ([`DEFAULT_KEY`] unless the model says otherwise).
    pub key: f32,
    /// How many planes of the layout the model reads: [`INPUT_CHANNELS`], or
    /// [`crate::planes::LEGACY_INPUT_CHANNELS`] for a model made before the variance planes.
    pub channels: usize,
}

impl Default for Encoding {
    /// No demodulation; the default key; every plane.
    fn default() -> Self {
        Encoding { demodulate: false, key: DEFAULT_KEY, channels: INPUT_CHANNELS }
    }
}

impl Encoding {
    /// The exposure of `color` under this encoding: [`auto_exposure`] scaled to the key.
    pub fn exposure(&self, color: &HdrImage) -> f32 {
        (auto_exposure(color) * (self.key / DEFAULT_KEY)).clamp(1.0 / MAX_EXPOSURE, MAX_EXPOSURE)
    }
}

/// What the denoiser is given. Colour and a guide are required; albedo + normal, AO + depth and
/// the colour's variance are optional (rtd's own renders have all of them).
#[derive(Clone, Copy)]
pub struct DenoiseInput<'a> {
    /// The noisy HDR colour.
    pub color: &'a HdrImage,
    /// The guide RGB: albedo × AO, the thesis's material render.
    pub guide: &'a HdrImage,
    /// Albedo and world-space normal.
    pub albedo_normal: Option<(&'a HdrImage, &'a HdrImage)>,
    /// Ambient occlusion and camera distance, one value per pixel.
    pub ao_depth: Option<(&'a [f32], &'a [f32])>,
    /// The variance of each pixel's colour estimate, per channel (the film's
    /// [`Layer::Variance`](rtd_image::Layer::Variance)).
    pub variance: Option<&'a HdrImage>,
}

impl<'a> DenoiseInput<'a> {
    /// Colour plus the guide RGB only (renders from other software).
    pub fn new(color: &'a HdrImage, guide: &'a HdrImage) -> Self {
        DenoiseInput { color, guide, albedo_normal: None, ao_depth: None, variance: None }
    }
    /// The layers a file holds, as `rtd denoise` reads them: the guide RGB if given, else the
    /// albedo stands in for it, else the noisy colour itself; albedo and normal where both are
    /// given. Files from other software (Blender, Nuke, OIDN's inputs) have no guide.
    pub fn with_stand_in_guide(
        color: &'a HdrImage,
        guide: Option<&'a HdrImage>,
        albedo: Option<&'a HdrImage>,
        normal: Option<&'a HdrImage>,
    ) -> Self {
        let input = DenoiseInput::new(color, guide.or(albedo).unwrap_or(color));
        match (albedo, normal) {
            (Some(a), Some(n)) => input.albedo_normal(a, n),
            _ => input,
        }
    }
    /// Adds albedo and normal.
    pub fn albedo_normal(mut self, albedo: &'a HdrImage, normal: &'a HdrImage) -> Self {
        self.albedo_normal = Some((albedo, normal));
        self
    }
    /// Adds AO and depth.
    pub fn ao_depth(mut self, ao: &'a [f32], depth: &'a [f32]) -> Self {
        self.ao_depth = Some((ao, depth));
        self
    }
    /// Adds the colour's per-pixel variance (None leaves it out).
    pub fn variance(mut self, variance: Option<&'a HdrImage>) -> Self {
        self.variance = variance;
        self
    }

    /// Image width and height, after checking every layer has them.
    pub fn size(&self) -> Result<(u32, u32), DenoiseError> {
        let (w, h) = (self.color.width, self.color.height);
        let n = w as usize * h as usize;
        let mut images = vec![("colour", self.color), ("guide", self.guide)];
        if let Some(v) = self.variance {
            images.push(("variance", v));
        }
        if let Some((a, nrm)) = self.albedo_normal {
            images.extend([("albedo", a), ("normal", nrm)]);
        }
        for (name, image) in images {
            let size = (image.width, image.height);
            if size != (w, h) {
                return Err(DenoiseError::SizeMismatch { layer: name, size, color: (w, h) });
            }
            // Images are built through their constructors, but their fields are public.
            if image.pixels.len() != n {
                return Err(DenoiseError::PixelCount { layer: name, pixels: image.pixels.len(), size });
            }
        }
        if let Some((ao, d)) = self.ao_depth {
            if ao.len() != n || d.len() != n {
                return Err(DenoiseError::PlaneLength { ao: ao.len(), depth: d.len(), expected: n });
            }
        }
        Ok((w, h))
    }
}

/// x clamped to [lo, hi], with NaN as 0.
pub(crate) fn clean(x: f32, lo: f32, hi: f32) -> f32 {
    if x.is_nan() {
        0.0
    } else {
        x.clamp(lo, hi)
    }
}

/// Pixels per task where a per-pixel pass over an image is split between threads.
pub(crate) const PIXEL_CHUNK: usize = 16384;

/// Auto-exposure: the scale that maps the log-average luminance of the lit pixels to 0.18
/// (1 for an all-black image). Scaling the image by k scales the exposure by 1/k: black pixels
/// are left out, lit ones count at no less than a fixed fraction of their plain log-average,
/// and non-finite ones are left out as broken.
pub fn auto_exposure(color: &HdrImage) -> f32 {
    // Luminance of a pixel for the statistics: None where black or not finite. Sums run over
    // fixed chunks added in order, so the result does not depend on the thread count.
    let lum = |p: &Vec3| {
        let l = luminance(Vec3::new(p.x.max(0.0), p.y.max(0.0), p.z.max(0.0))) as f64;
        (l > 0.0 && l.is_finite()).then_some(l)
    };
    let sum_chunks = |f: &(dyn Fn(f64) -> f64 + Sync)| -> (f64, usize) {
        let partial: Vec<(f64, usize)> = color
            .pixels
            .par_chunks(PIXEL_CHUNK)
            .map(|chunk| chunk.iter().filter_map(lum).fold((0.0, 0), |(s, n), l| (s + f(l), n + 1)))
            .collect();
        partial.iter().fold((0.0, 0), |(s, n), (ps, pn)| (s + ps, n + pn))
    };
    let (log_sum, n) = sum_chunks(&|l| l.ln());
    if n == 0 {
        return 1.0;
    }
    let floor = LOG_AVERAGE_FLOOR * (log_sum / n as f64).exp();
    // Geometric mean of luminance over lit pixels, each at least the floor.
    let (log_sum, _) = sum_chunks(&|l| l.max(floor).ln());
    let log_avg = (log_sum / n as f64).exp();
    ((DEFAULT_KEY as f64 / log_avg) as f32).clamp(1.0 / MAX_EXPOSURE, MAX_EXPOSURE)
}

/// The largest raw value that stays within [`MAX_EXPOSED`] at `exposure` (finite).
#[inline]
fn max_raw(exposure: f32) -> f32 {
    (MAX_EXPOSED / exposure).min(f32::MAX)
}

/// The colour transfer: y = ln(1 + x · exposure), x sanitised and x · exposure at most
/// [`MAX_EXPOSED`].
pub fn encode_color(x: f32, exposure: f32) -> f32 {
    transfer(clean(x, 0.0, max_raw(exposure)), exposure)
}

/// ln(1 + x · exposure) of an already sanitised x.
#[inline(always)]
fn transfer(x: f32, exposure: f32) -> f32 {
    ln_1p(x * exposure)
}

multiversioned! {
    /// [`transfer`] in place over a row of sanitised values.
    fn transfer_row(dst: &mut [f32], exposure: f32) {
        dst.iter_mut().for_each(|v| *v = transfer(*v, exposure));
    }
}

multiversioned! {
    /// sum += [`decode_color`] of `encoded`, elementwise: one pass's output added to the mean.
    pub(crate) fn add_decoded_row(sum: &mut [f32], encoded: &[f32], exposure: f32) {
        sum.iter_mut().zip(encoded).for_each(|(s, &y)| *s += decode_color(y, exposure));
    }
}

/// The inverse transfer: x = (e^y − 1) / exposure, for y ≥ 0.
/// Branch-free (a polynomial exponential and selects), so loops of it vectorise.
#[inline(always)]
pub fn decode_color(y: f32, exposure: f32) -> f32 {
    let y = if y.is_nan() { 0.0 } else { y.min(80.0) };
    (exp_m1(y) / exposure).min(f32::MAX)
}

/// The per-channel factor colour is divided by before encoding (and the output multiplied by
/// after decoding): albedo + [`DEMOD_EPS`], or 1 where the model does not demodulate or no
/// albedo is given.
pub fn demod_factor(albedo: Option<&HdrImage>, i: usize, k: usize) -> f32 {
    albedo.map_or(1.0, |a| albedo_factor(a.pixels[i][k]))
}

/// The demodulation factor of one albedo value: the value clamped to [0, 1], plus
/// [`DEMOD_EPS`].
#[inline]
fn albedo_factor(albedo: f32) -> f32 {
    clean(albedo, 0.0, 1.0) + DEMOD_EPS
}

/// The albedo colour is demodulated by: the input's albedo when `demodulate` is set.
pub fn demod_albedo<'a>(input: &DenoiseInput<'a>, demodulate: bool) -> Option<&'a HdrImage> {
    input.albedo_normal.filter(|_| demodulate).map(|(a, _)| a)
}

/// Writes channel `k` of `color`, divided by `albedo` + [`DEMOD_EPS`] if given, encoded, into
/// `plane` (one value per pixel).
pub fn encode_color_plane(plane: &mut [f32], color: &HdrImage, albedo: Option<&HdrImage>, k: usize, exposure: f32) {
    encode_plane(plane, color, albedo, k, exposure, Estimate::Color);
}

/// Writes channel `k` of the colour's standard deviation, √variance, divided by `albedo` +
/// [`DEMOD_EPS`] if given (as the colour is) and through the colour's transfer, into `plane`.
pub fn encode_deviation_plane(
    plane: &mut [f32],
    variance: &HdrImage,
    albedo: Option<&HdrImage>,
    k: usize,
    exposure: f32,
) {
    encode_plane(plane, variance, albedo, k, exposure, Estimate::Deviation);
}

/// What a plane encoded through the colour's transfer holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Estimate {
    /// The noisy colour, from its image.
    Color,
    /// The colour's standard deviation, from its variance image.
    Deviation,
}

/// plane[i] = the encoded `what` of channel k at pixel i, threaded over pixel chunks.
fn encode_plane(
    plane: &mut [f32],
    image: &HdrImage,
    albedo: Option<&HdrImage>,
    k: usize,
    exposure: f32,
    what: Estimate,
) {
    plane.par_chunks_mut(PIXEL_CHUNK).enumerate().for_each(|(c, chunk)| {
        let i0 = c * PIXEL_CHUNK;
        encode_values(chunk, i0..i0 + chunk.len(), image, albedo, k, exposure, what);
    });
}

/// dst[j] = transfer(value of channel k at image pixel index[j] ÷ demodulation factor there),
/// the value being the colour or the standard deviation of a variance (`what`), sanitised and
/// clamped so that the exposed value is at most [`MAX_EXPOSED`]: the colour and deviation
/// planes at any pixels, whole planes or a tile's window ([`crate::plane_encoder::PlaneEncoder`]). The demodulation
/// factor is at least DEMOD_EPS, so the quotient is finite, and is not clamped again, so
/// demodulated HDR keeps its range.
pub(crate) fn encode_values(
    dst: &mut [f32],
    index: impl Iterator<Item = usize>,
    image: &HdrImage,
    albedo: Option<&HdrImage>,
    k: usize,
    exposure: f32,
    what: Estimate,
) {
    let max = max_raw(exposure);
    match what {
        Estimate::Color => gather_divided(dst, index, image, albedo, k, |x| clean(x, 0.0, max)),
        Estimate::Deviation => {
            gather_divided(dst, index, image, albedo, k, |x| clean(x, 0.0, f32::MAX).sqrt().min(max))
        }
    }
    // The transfer in a loop of its own, with no branches, so it vectorises.
    transfer_row(dst, exposure);
}

/// dst[j] = value(channel k at image pixel index[j]) ÷ the albedo's demodulation factor there,
/// the albedo's presence chosen outside the loop.
fn gather_divided(
    dst: &mut [f32],
    index: impl Iterator<Item = usize>,
    image: &HdrImage,
    albedo: Option<&HdrImage>,
    k: usize,
    value: impl Fn(f32) -> f32,
) {
    let channel = |p: &Vec3| p.to_array()[k];
    match albedo {
        Some(a) => {
            for (v, i) in dst.iter_mut().zip(index) {
                *v = value(channel(&image.pixels[i])) / albedo_factor(channel(&a.pixels[i]));
            }
        }
        None => dst.iter_mut().zip(index).for_each(|(v, i)| *v = value(channel(&image.pixels[i]))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transfer_round_trips_and_sanitises() {
        for x in [0.0f32, 1e-6, 0.18, 1.0, 37.0, 1e6] {
            let y = encode_color(x, 0.5);
            assert!((decode_color(y, 0.5) - x).abs() <= 1e-5 * x.max(1.0), "{x}");
        }
        assert_eq!(encode_color(f32::NAN, 1.0), 0.0);
        assert_eq!(encode_color(-5.0, 1.0), 0.0);
        assert!(encode_color(f32::INFINITY, 1.0).is_finite());
        assert!(decode_color(f32::INFINITY, 1.0).is_finite());
    }

    #[test]
    fn exposure_maps_the_log_average_to_middle_grey() {
        let img = HdrImage::from_pixels(2, 1, vec![Vec3::splat(0.5), Vec3::splat(2.0)]);
        assert!((auto_exposure(&img) - 0.18).abs() < 1e-6);
        let scaled = HdrImage::from_pixels(2, 1, vec![Vec3::splat(5e5), Vec3::splat(2e6)]);
        assert!((auto_exposure(&scaled) * 1e6 - 0.18).abs() < 1e-6);
        assert_eq!(auto_exposure(&HdrImage::new(3, 3)), 1.0);
        // A model's key scales it: the log-average goes to the key instead.
        let key = Encoding { key: 1.44, ..Encoding::default() };
        assert!((key.exposure(&img) - 1.44).abs() < 1e-5);
    }

    /// The exposure scales as 1/k when the image does, from 1e-15 to 1e15, with nearly black
    /// and non-finite pixels in it; a nearly black pixel counts at the floor, not below it, and
    /// a firefly at f32::MAX counts as its own luminance and moves nothing else.
    #[test]
    fn exposure_scales_exactly_with_the_image_and_ignores_broken_pixels() {
        let mut pixels: Vec<Vec3> = (0..64).map(|i| Vec3::splat(0.05 + 0.02 * i as f32)).collect();
        pixels[3] = Vec3::splat(1e-12);
        pixels[9] = Vec3::ZERO;
        let base = auto_exposure(&HdrImage::from_pixels(8, 8, pixels.clone()));
        for k in [1e-15f32, 1e-9, 1e-4, 0.3, 7.0, 1e4, 1e9, 1e15] {
            let img = HdrImage::from_pixels(8, 8, pixels.iter().map(|p| *p * k).collect());
            let ratio = auto_exposure(&img) * k / base;
            assert!((ratio - 1.0).abs() < 1e-5, "k = {k}: exposure × k is {ratio} of the unscaled one");
        }
        // The nearly black pixel counts at 1e-6 of the plain log-average, the black one not at
        // all; so does a firefly at f32::MAX, at its own luminance.
        let expected = |pixels: &[Vec3]| {
            let lums: Vec<f64> = pixels.iter().map(|p| luminance(*p) as f64).filter(|l| *l > 0.0).collect();
            let n = lums.len() as f64;
            let floor = 1e-6 * (lums.iter().map(|l| l.ln()).sum::<f64>() / n).exp();
            0.18 / (lums.iter().map(|l| l.max(floor).ln()).sum::<f64>() / n).exp()
        };
        assert!((base as f64 - expected(&pixels)).abs() < 1e-6 * base as f64);
        let mut firefly = pixels.clone();
        firefly[20] = Vec3::splat(f32::MAX);
        let e = auto_exposure(&HdrImage::from_pixels(8, 8, firefly.clone())) as f64;
        assert!((e - expected(&firefly)).abs() < 1e-5 * e, "{e} against {}", expected(&firefly));
        assert!(e > 0.05 * base as f64, "one firefly moved the exposure from {base} to {e}");
        // NaN, +Inf and negative pixels change nothing.
        let mut broken = pixels.clone();
        broken.extend([Vec3::new(f32::NAN, 0.0, 0.0), Vec3::splat(f32::INFINITY), Vec3::splat(-3.0)]);
        broken.push(Vec3::ZERO);
        assert_eq!(auto_exposure(&HdrImage::from_pixels(17, 4, broken)), base);
    }

    /// Encoding is bounded in exposed units: the same exposed value encodes the same at any
    /// exposure, and +Inf encodes as [`MAX_EXPOSED`] does.
    #[test]
    fn the_bound_on_input_is_on_the_exposed_value() {
        for e in [1e-20f32, 1e-6, 1.0, 1e6, 1e20] {
            let big = encode_color(f32::INFINITY, e);
            assert!((big - MAX_EXPOSED.ln_1p()).abs() < 1e-5, "exposure {e}: {big}");
            assert!((encode_color(2.0 / e, e) - 2f32.ln_1p()).abs() < 1e-5, "exposure {e}");
        }
    }

    #[test]
    fn mismatched_sizes_are_named() {
        let (a, b) = (HdrImage::new(4, 4), HdrImage::new(4, 5));
        let e = DenoiseInput::new(&a, &b).size().unwrap_err().to_string();
        assert!(e.contains("guide") && e.contains("4x5"), "{e}");
        // An image whose pixels do not fill its size is refused, not read out of bounds.
        let mut short = HdrImage::new(4, 4);
        short.pixels.pop();
        let e = DenoiseInput::new(&a, &a).albedo_normal(&a, &short).size().unwrap_err().to_string();
        assert_eq!(e, "the normal image holds 15 pixels, not 4x4");
    }
}
