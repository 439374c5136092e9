//! Training batches: every view of the dataset is encoded once per noisy sample count (with
//! the auto-exposure inference would use), then random crops are cut, flipped, transposed,
//! colour-permuted and stripped of optional guide layers, exactly as inference can see them
//! (down to colour alone, whose guide is the noisy colour itself).

use std::path::{Path, PathBuf};

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rtd_denoise::encode::{demod_albedo, demod_factor, encode_color_plane, encode_deviation_plane, Encoding};
use rtd_denoise::plane_encoder::{encode_planes, PlaneEncoder};
use rtd_denoise::planes::{OptionalInput, Plane};
use rtd_denoise::DenoiseInput;
use rtd_image::{HdrImage, Layer};

use crate::dataset::{view_path, Manifest, ViewRecord};
use crate::TrainError;

/// One view of a dataset, loaded from its EXR.
pub struct View {
    /// The manifest entry.
    pub record: ViewRecord,
    /// The view's EXR file (in the dataset directory), which errors about the view name.
    pub path: PathBuf,
    /// Width and height in pixels.
    pub size: (usize, usize),
    /// Noisy renders by sample count, in the manifest's order.
    pub noisy: Vec<(u32, HdrImage)>,
    /// Each noisy render's per-pixel variance, in the same order: None where the view's file
    /// has none (datasets made before the variance planes, and 1-spp renders).
    pub variance: Vec<Option<HdrImage>>,
    /// The high-spp reference render.
    pub reference: HdrImage,
    /// The guide RGB: albedo × AO.
    pub guide: HdrImage,
    /// Albedo layer of the guide pass.
    pub albedo: HdrImage,
    /// World-space normal layer of the guide pass.
    pub normal: HdrImage,
    /// Ambient occlusion, one value per pixel.
    pub ao: Vec<f32>,
    /// Camera distance, one value per pixel (0 where the ray escapes).
    pub depth: Vec<f32>,
}

impl View {
    /// The denoiser input for the noisy render at `spp`, with every guide layer; an error
    /// naming the view's file and the sample counts it has when it has no render at `spp`.
    pub fn input(&self, spp: u32) -> Result<DenoiseInput<'_>, TrainError> {
        let Some(k) = self.noisy.iter().position(|(s, _)| *s == spp) else {
            let stored: Vec<String> = self.noisy.iter().map(|(s, _)| s.to_string()).collect();
            let message = format!("has no noisy render at {spp} spp (it has {} spp)", stored.join(", "));
            return Err(TrainError::msg(&self.path, message));
        };
        let input = DenoiseInput::new(&self.noisy[k].1, &self.guide).albedo_normal(&self.albedo, &self.normal);
        Ok(input.ao_depth(&self.ao, &self.depth).variance(self.variance.get(k).and_then(Option::as_ref)))
    }
}

/// Loads the training or validation views of the dataset in `dir`.
pub fn load_views(dir: &Path, validation: bool) -> Result<Vec<View>, TrainError> {
    let manifest = Manifest::load(dir)?;
    let mut views = vec![];
    for record in manifest.views.iter().filter(|v| v.validation == validation) {
        let path = view_path(dir, record);
        let layers = rtd_image::read_exr(&path)?;
        let missing = |layer: Layer| TrainError::msg(&path, format!("missing layer {}", layer.prefix()));
        let image = |layer: Layer| layers.image(layer).ok_or_else(|| missing(layer));
        let plane = |layer: Layer| layers.plane(layer).map(<[f32]>::to_vec).ok_or_else(|| missing(layer));
        let (mut noisy, mut variance) = (vec![], vec![]);
        for spp in &manifest.noisy_spp {
            noisy.push((*spp, image(Layer::NoisyAt(*spp))?));
            variance.push(layers.image(Layer::VarianceAt(*spp)));
        }
        let reference = image(Layer::Reference)?;
        views.push(View {
            record: record.clone(),
            path: path.clone(),
            size: (reference.width as usize, reference.height as usize),
            noisy,
            variance,
            guide: image(Layer::Guide)?,
            albedo: image(Layer::Albedo)?,
            normal: image(Layer::Normal)?,
            ao: plane(Layer::Ao)?,
            depth: plane(Layer::Depth)?,
            reference,
        });
    }
    Ok(views)
}

/// A view's encoded inputs and target at one sample count.
struct Encoded {
    w: usize,
    h: usize,
    planes: Vec<f32>,
    target: Vec<f32>,
    /// Per channel and pixel, what e^y − 1 of an encoded colour y is multiplied by to give
    /// linear radiance: demodulation factor ÷ exposure (3 × H × W).
    scale: Vec<f32>,
    /// The exposure the view was encoded with.
    exposure: f32,
    /// For a demodulating model: the colour and deviation planes (3 + 3) and the target
    /// without demodulation, used by crops whose albedo layer is dropped (inference demodulates
    /// only when albedo is given).
    plain: Option<(Vec<f32>, Vec<f32>)>,
    /// The guide planes (3 × H × W) of colour alone, where the noisy colour stands in for the
    /// guide as `rtd denoise` makes it stand in.
    colour_guide: Vec<f32>,
}

/// One training batch, channel-major: `n` crops of side `s`.
pub struct Batch {
    /// Network inputs, [n, C, s, s].
    pub inputs: Vec<f32>,
    /// Encoded reference colour, [n, 3, s, s].
    pub targets: Vec<f32>,
    /// Decode scales, [n, 3, s, s]: linear radiance = (e^y − 1) × scale for an encoded colour
    /// y of the same crop (see [`crate::loss::display_loss`]).
    pub scales: Vec<f32>,
}

/// Encodes the standard deviation of a variance image (not demodulated) into 3 × H × W, as
/// the deviation planes hold it.
fn encode_deviation(variance: &HdrImage, exposure: f32) -> Vec<f32> {
    let n = variance.pixels.len();
    let mut out = vec![0.0f32; 3 * n];
    for (k, plane) in out.chunks_mut(n).enumerate() {
        encode_deviation_plane(plane, variance, None, k, exposure);
    }
    out
}

/// Encodes the three channels of `img` (demodulated by `albedo` if given) into 3 × H × W.
fn encode_rgb(img: &HdrImage, albedo: Option<&HdrImage>, exposure: f32) -> Vec<f32> {
    let n = img.pixels.len();
    let mut out = vec![0.0f32; 3 * n];
    for (k, plane) in out.chunks_mut(n).enumerate() {
        encode_color_plane(plane, img, albedo, k, exposure);
    }
    out
}

/// The three guide planes of `colour` standing in for its own guide, encoded as inference
/// encodes them.
fn encode_colour_as_guide(colour: &HdrImage, exposure: f32, encoding: Encoding) -> Result<Vec<f32>, TrainError> {
    let n = colour.pixels.len();
    let input = DenoiseInput::new(colour, colour);
    let encoder = PlaneEncoder::new(&input, exposure, encoding)?;
    let mut out = vec![0.0f32; 3 * n];
    for (k, plane) in out.chunks_mut(n).enumerate() {
        encoder.encode(Plane::Guide(k).index(), 0..n, plane);
    }
    Ok(out)
}

/// Random crops for training.
pub struct CropSampler {
    encoded: Vec<Encoded>,
    /// Crop side in pixels.
    pub crop: usize,
    /// Probability that a crop loses its albedo+normal layers, and (independently) its
    /// AO+depth layers.
    pub drop_probability: f32,
    /// Probability that a crop loses its variance.
    pub variance_drop_probability: f32,
    /// Probability that a crop is colour alone: its guide is the noisy colour, and it has no
    /// albedo, normal, AO or depth.
    pub colour_only_probability: f32,
    /// Probability that a crop with albedo but without AO + depth takes its albedo as its
    /// guide RGB, as `rtd denoise` does for files from other software that have no guide (the
    /// rule of [`rtd_denoise::DenoiseInput::with_stand_in_guide`], here on encoded planes).
    pub albedo_guide_probability: f32,
    /// Input planes per crop: the model's width.
    channels: usize,
}

/// Default probability that a crop loses its albedo+normal (and, independently, AO+depth, and
/// the variance) layers, so the model also serves inputs from other software.
pub const DROP_PROBABILITY: f32 = 0.3;

/// Default probability that a crop is colour alone (see
/// [`CropSampler::colour_only_probability`]).
pub const COLOUR_ONLY_PROBABILITY: f32 = 0.1;

impl CropSampler {
    /// Encodes every view at every stored sample count (or only those in `spp_levels`) as
    /// `encoding` says (demodulating colour and target by the albedo if it demodulates). A view
    /// smaller than `crop` on either side is an error naming its file.
    pub fn new(
        views: &[View],
        crop: usize,
        encoding: Encoding,
        spp_levels: Option<&[u32]>,
    ) -> Result<Self, TrainError> {
        let demodulate = encoding.demodulate;
        let mut encoded = vec![];
        for v in views {
            if v.size.0 < crop || v.size.1 < crop {
                let (w, h) = v.size;
                return Err(TrainError::msg(&v.path, format!("is {w}x{h} px, smaller than the {crop} px crops")));
            }
            for (spp, _) in v.noisy.iter().filter(|(spp, _)| spp_levels.is_none_or(|l| l.contains(spp))) {
                let input = v.input(*spp)?;
                let e = encoding.exposure(input.color);
                let planes = encode_planes(&input, e, encoding)?;
                let albedo = demod_albedo(&input, demodulate);
                let target = encode_rgb(&v.reference, albedo, e);
                let plain = demodulate.then(|| {
                    let mut planes = encode_rgb(input.color, None, e);
                    planes.extend(input.variance.map_or_else(|| vec![0.0; planes.len()], |v| encode_deviation(v, e)));
                    (planes, encode_rgb(&v.reference, None, e))
                });
                let n = v.reference.pixels.len();
                let scale = (0..3 * n).map(|j| demod_factor(albedo, j % n, j / n) / e).collect();
                let colour_guide = encode_colour_as_guide(input.color, e, encoding)?;
                encoded.push(Encoded {
                    w: v.size.0,
                    h: v.size.1,
                    planes,
                    target,
                    scale,
                    exposure: e,
                    plain,
                    colour_guide,
                });
            }
        }
        let channels = encoding.channels;
        Ok(CropSampler {
            encoded,
            crop,
            drop_probability: DROP_PROBABILITY,
            variance_drop_probability: DROP_PROBABILITY,
            colour_only_probability: 0.0,
            albedo_guide_probability: 0.0,
            channels,
        })
    }

    /// Sets the probability that a crop is colour alone.
    pub fn colour_only_probability(mut self, p: f32) -> Self {
        self.colour_only_probability = p;
        self
    }

    /// Sets the probability that a crop with albedo but without AO + depth takes its albedo as
    /// its guide.
    pub fn albedo_guide_probability(mut self, p: f32) -> Self {
        self.albedo_guide_probability = p;
        self
    }

    /// Sets the probability that a crop loses each optional pair of guide layers.
    pub fn drop_probability(mut self, p: f32) -> Self {
        self.drop_probability = p;
        self
    }

    /// Sets the probability that a crop loses its variance.
    pub fn variance_drop_probability(mut self, p: f32) -> Self {
        self.variance_drop_probability = p;
        self
    }

    /// A batch of `n` crops for step `step` (a pure function of seed and step, so a resumed run
    /// sees the same batches).
    pub fn batch(&self, seed: u64, step: u64, n: usize) -> Batch {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ step.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let s = self.crop;
        let (mut xs, mut ys) = (Vec::with_capacity(n * self.channels * s * s), Vec::with_capacity(n * 3 * s * s));
        let mut scales = Vec::with_capacity(n * 3 * s * s);
        for _ in 0..n {
            let e = &self.encoded[rng.random_range(0..self.encoded.len())];
            let (x0, y0) = (rng.random_range(0..=e.w - s), rng.random_range(0..=e.h - s));
            let (flip_x, flip_y, transpose) = (rng.random::<bool>(), rng.random::<bool>(), rng.random::<bool>());
            let mut perm = [0usize, 1, 2];
            perm.shuffle(&mut rng);
            let drop_an = rng.random::<f32>() < self.drop_probability;
            let drop_ad = rng.random::<f32>() < self.drop_probability;
            // (No draw at probability 0, so such a run sees the batches it saw before.)
            let colour_only = self.colour_only_probability > 0.0 && rng.random::<f32>() < self.colour_only_probability;
            let (drop_an, drop_ad) = (drop_an || colour_only, drop_ad || colour_only);
            let drop_var = rng.random::<f32>() < self.variance_drop_probability;
            let black = rng.random::<f32>() < 0.02;
            // (Drawn last, and not at probability 0, so older runs see the batches they saw.)
            let albedo_guide = self.albedo_guide_probability > 0.0
                && rng.random::<f32>() < self.albedo_guide_probability
                && drop_ad
                && !drop_an;
            // Source pixel of crop pixel (x, y) after the flips and transpose.
            let src = |x: usize, y: usize| {
                let (mut u, mut v) = if transpose { (y, x) } else { (x, y) };
                if flip_x {
                    u = s - 1 - u;
                }
                if flip_y {
                    v = s - 1 - v;
                }
                (y0 + v) * e.w + x0 + u
            };
            let n_px = e.w * e.h;
            for c in 0..self.channels {
                let p = Plane::of(c);
                // Colour-carrying planes share one channel permutation.
                let source = p.colour_channel().map_or(p, |k| p.with_colour_channel(perm[k]));
                let noise = matches!(p, Plane::Color(_) | Plane::Deviation(_));
                let dropped = match p.optional() {
                    Some(OptionalInput::AlbedoNormal) => drop_an,
                    Some(OptionalInput::AoDepth) => drop_ad,
                    Some(OptionalInput::Variance) => drop_var,
                    None => false,
                };
                let zero = (black && noise) || dropped;
                // Without albedo, colour and deviation are not demodulated.
                let plane = match (&e.plain, source, drop_an) {
                    (_, Plane::Guide(k), _) if colour_only => &e.colour_guide[k * n_px..][..n_px],
                    (_, Plane::Guide(k), _) if albedo_guide => &e.planes[Plane::Albedo(k).index() * n_px..][..n_px],
                    (Some((plain, _)), Plane::Color(k), true) => &plain[k * n_px..][..n_px],
                    (Some((plain, _)), Plane::Deviation(k), true) => &plain[(3 + k) * n_px..][..n_px],
                    _ => &e.planes[source.index() * n_px..][..n_px],
                };
                for y in 0..s {
                    for x in 0..s {
                        xs.push(if zero { 0.0 } else { plane[src(x, y)] });
                    }
                }
            }
            let target = match &e.plain {
                Some((_, target)) if drop_an => target,
                _ => &e.target,
            };
            for &channel in &perm {
                for y in 0..s {
                    for x in 0..s {
                        let i = channel * n_px + src(x, y);
                        ys.push(if black { 0.0 } else { target[i] });
                        // A crop without albedo is not demodulated, so it decodes by exposure alone.
                        scales.push(if e.plain.is_some() && drop_an { 1.0 / e.exposure } else { e.scale[i] });
                    }
                }
            }
        }
        Batch { inputs: xs, targets: ys, scales }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn toy_view() -> View {
        let (w, h) = (8u32, 8u32);
        let img = |f: &dyn Fn(u32, u32) -> Vec3| {
            HdrImage::from_pixels(
                w,
                h,
                (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| f(x, y)).collect(),
            )
        };
        let color = img(&|x, y| Vec3::new(x as f32, y as f32, 1.0) * 0.1);
        View {
            record: ViewRecord {
                file: String::new(),
                scene: 0,
                view: 0,
                layout: crate::scenegen::Layout::ClosedRoom,
                validation: false,
                reference_spp: 1,
                reference_relmse: 0.0,
                seconds: 0.0,
            },
            path: PathBuf::from("toy.exr"),
            size: (8, 8),
            noisy: vec![(1, color.clone())],
            variance: vec![None],
            reference: color.clone(),
            guide: img(&|x, _| Vec3::new(0.2, 0.4, 0.6) * (x % 2) as f32),
            albedo: img(&|_, _| Vec3::new(0.2, 0.4, 0.6)),
            normal: img(&|_, _| Vec3::Z),
            ao: vec![1.0; 64],
            depth: vec![2.0; 64],
        }
    }

    impl CropSampler {
        fn clone_with_variance_drop(&self, p: f32) -> CropSampler {
            let encoded = self
                .encoded
                .iter()
                .map(|e| Encoded {
                    w: e.w,
                    h: e.h,
                    planes: e.planes.clone(),
                    target: e.target.clone(),
                    scale: e.scale.clone(),
                    exposure: e.exposure,
                    plain: e.plain.clone(),
                    colour_guide: e.colour_guide.clone(),
                })
                .collect();
            CropSampler {
                encoded,
                crop: self.crop,
                drop_probability: self.drop_probability,
                variance_drop_probability: p,
                colour_only_probability: self.colour_only_probability,
                albedo_guide_probability: self.albedo_guide_probability,
                channels: self.channels,
            }
        }
    }

    #[test]
    fn batches_are_reproducible_and_augmentations_keep_input_and_target_aligned() {
        for demodulate in [false, true] {
            let sampler =
                CropSampler::new(&[toy_view()], 8, Encoding { demodulate, ..Encoding::default() }, None).unwrap();
            let (b1, b2) = (sampler.batch(3, 17, 4), sampler.batch(3, 17, 4));
            let (x1, y1) = (b1.inputs.clone(), b1.targets.clone());
            assert_eq!((&b1.inputs, &b1.targets, &b1.scales), (&b2.inputs, &b2.targets, &b2.scales));
            assert_ne!(x1, sampler.batch(3, 18, 4).inputs);
            // Here target == noisy colour, so whatever the flip/transpose/permutation and
            // whether the albedo (and with it demodulation) is dropped, the first three input
            // channels of every crop equal its target.
            let px = 64;
            for b in 0..4 {
                let xin = &x1[b * sampler.channels * px..][..3 * px];
                let yt = &y1[b * 3 * px..][..3 * px];
                assert_eq!(xin, yt);
            }
            // Each target decodes, with its scale, to the reference's linear colour (the toy's
            // reference is its noisy colour, whose channels lie in [0, 1.4]).
            let toy = toy_view();
            for (y, sc) in b1.targets.iter().zip(&b1.scales) {
                let linear = y.exp_m1() * sc;
                let close = |v: f32| (v - linear).abs() < 1e-4;
                assert!(toy.reference.pixels.iter().any(|p| close(p.x) || close(p.y) || close(p.z)), "{linear}");
            }
        }
        // Demodulation divides by albedo + eps: the toy's blue albedo 0.6 scales colour by 1/0.61.
        let sampler = |demodulate| {
            CropSampler::new(&[toy_view()], 8, Encoding { demodulate, ..Encoding::default() }, None).unwrap()
        };
        let (plain, demod) = (sampler(false), sampler(true));
        assert_ne!(plain.encoded[0].planes[..192], demod.encoded[0].planes[..192]);
        assert_eq!(plain.encoded[0].planes[192..], demod.encoded[0].planes[192..]);
    }

    #[test]
    fn spp_levels_choose_the_sources_and_the_drop_probability_is_obeyed() {
        let mut view = toy_view();
        view.noisy.push((8, view.noisy[0].1.clone()));
        let views = [view];
        let sampler = |levels: Option<&[u32]>| CropSampler::new(&views, 8, Encoding::default(), levels).unwrap();
        assert_eq!(sampler(None).encoded.len(), 2);
        assert_eq!(sampler(Some(&[8, 16])).encoded.len(), 1);
        assert_eq!(sampler(Some(&[16])).encoded.len(), 0);
        // The flag planes of the albedo + normal and the AO + depth pairs: 1 where given, 0
        // where the crop dropped them.
        let (an, ad) = (Plane::HasAlbedoNormal.index(), Plane::HasAoDepth.index());
        let flags = |p: f32| {
            let x = sampler(None).drop_probability(p).batch(5, 0, 64).inputs;
            let px = 64;
            let c = rtd_denoise::INPUT_CHANNELS;
            (0..64).map(|b| (x[(b * c + an) * px], x[(b * c + ad) * px])).collect::<Vec<_>>()
        };
        assert!(flags(0.0).iter().all(|&f| f == (1.0, 1.0)));
        assert!(flags(1.0).iter().all(|&f| f == (0.0, 0.0)));
        let half = flags(0.5);
        assert!(half.contains(&(1.0, 1.0)) && half.contains(&(0.0, 0.0)) && half.contains(&(1.0, 0.0)));
    }

    #[test]
    fn deviation_planes_follow_the_colour_through_every_augmentation() {
        // A variance equal to colour², so the deviation is the colour itself: whatever the
        // crop's flips, permutation, demodulation or dropped albedo, its deviation planes must
        // equal its colour planes, unless the variance was dropped (then 0, flag 0).
        let mut view = toy_view();
        let color = view.noisy[0].1.clone();
        let squared = HdrImage::from_pixels(8, 8, color.pixels.iter().map(|p| *p * *p).collect());
        view.noisy = vec![(8, color)];
        view.variance = vec![Some(squared)];
        let px = 64;
        let (c, dev, flag) = (rtd_denoise::INPUT_CHANNELS, Plane::Deviation(0).index(), Plane::HasVariance.index());
        for demodulate in [false, true] {
            let encoding = Encoding { demodulate, ..Encoding::default() };
            let sampler = CropSampler::new(std::slice::from_ref(&view), 8, encoding, None).unwrap();
            let (mut shown, mut hidden) = (0, 0);
            for p in [0.0, 0.5, 1.0] {
                let x = sampler.clone_with_variance_drop(p).batch(9, 1, 32).inputs;
                for b in 0..32 {
                    let crop = &x[b * c * px..][..c * px];
                    if crop[flag * px] == 1.0 {
                        assert_eq!(crop[..3 * px], crop[dev * px..][..3 * px], "demodulate {demodulate}");
                        shown += 1;
                    } else {
                        assert!(crop[dev * px..][..4 * px].iter().all(|v| *v == 0.0));
                        hidden += 1;
                    }
                }
            }
            assert!(shown >= 40 && hidden >= 40, "{shown} crops with the variance, {hidden} without");
        }
        // A legacy-width model's crops carry the first 16 planes only.
        let legacy = Encoding { channels: rtd_denoise::planes::LEGACY_INPUT_CHANNELS, ..Encoding::default() };
        let sampler = CropSampler::new(std::slice::from_ref(&view), 8, legacy, None).unwrap();
        assert_eq!(sampler.batch(9, 1, 2).inputs.len(), 2 * 16 * px);
    }

    #[test]
    fn colour_only_crops_are_colour_alone_as_inference_sees_it() {
        // Colour above 1 in places, so the guide's clamp to [0, 1] is exercised.
        let mut view = toy_view();
        let bright = HdrImage::from_pixels(8, 8, view.noisy[0].1.pixels.iter().map(|p| *p * 3.0).collect());
        view.noisy = vec![(8, bright.clone())];
        let (px, c) = (64, rtd_denoise::INPUT_CHANNELS);
        let dropped =
            [Plane::Albedo(0), Plane::Normal(0), Plane::Ao, Plane::Depth, Plane::HasAlbedoNormal, Plane::HasAoDepth];
        for demodulate in [false, true] {
            let encoding = Encoding { demodulate, ..Encoding::default() };
            let e = encoding.exposure(&bright);
            let sampler = CropSampler::new(std::slice::from_ref(&view), 8, encoding, None).unwrap();
            let x = sampler.colour_only_probability(1.0).batch(3, 2, 16).inputs;
            for b in 0..16 {
                let crop = &x[b * c * px..][..c * px];
                for p in dropped {
                    let n = if matches!(p, Plane::Albedo(_) | Plane::Normal(_)) { 3 } else { 1 };
                    assert!(crop[p.index() * px..][..n * px].iter().all(|v| *v == 0.0), "{p:?} shown");
                }
                // The colour is not demodulated (no albedo), and the guide is that colour,
                // linear and clamped to [0, 1], channel by channel and pixel by pixel through
                // the flips and the channel permutation.
                for k in 0..3 {
                    for i in 0..px {
                        let linear = (crop[Plane::Color(k).index() * px + i].exp() - 1.0) / e;
                        let guide = crop[Plane::Guide(k).index() * px + i];
                        assert!(
                            (guide - linear.min(1.0)).abs() < 1e-4,
                            "demodulate {demodulate}: {guide} against {linear}"
                        );
                    }
                }
            }
            // Some guide pixels reach the clamp and some do not, so the check saw both sides of it.
            let guides: Vec<f32> =
                x.chunks(c * px).flat_map(|crop| crop[Plane::Guide(0).index() * px..][..3 * px].to_vec()).collect();
            assert!(guides.contains(&1.0) && guides.iter().any(|v| *v > 0.0 && *v < 1.0));
        }
    }

    #[test]
    fn crops_from_other_software_take_their_albedo_as_guide() {
        // The toy's guide is its albedo on odd columns and black on even ones, so a crop whose
        // guide equals its albedo took the stand-in, and one whose guide does not kept its own.
        let sampler = CropSampler::new(&[toy_view()], 8, Encoding::default(), None).unwrap();
        let (px, c) = (64, rtd_denoise::INPUT_CHANNELS);
        let (an, ad) = (Plane::HasAlbedoNormal.index(), Plane::HasAoDepth.index());
        let (guide, albedo) = (Plane::Guide(0).index(), Plane::Albedo(0).index());
        let count = |p: f32| {
            let x = sampler.clone_with_variance_drop(0.3).drop_probability(0.5).albedo_guide_probability(p);
            let x = x.batch(11, 4, 64).inputs;
            let (mut stand_in, mut own) = (0, 0);
            for crop in x.chunks(c * px) {
                let same = crop[guide * px..][..3 * px] == crop[albedo * px..][..3 * px];
                // Only a crop with albedo and without AO + depth may take the stand-in.
                let eligible = crop[an * px] == 1.0 && crop[ad * px] == 0.0;
                assert!(eligible || !same, "a crop with AO or without albedo took the albedo as guide");
                if eligible {
                    if same {
                        stand_in += 1
                    } else {
                        own += 1
                    }
                }
            }
            (stand_in, own)
        };
        let (never, _) = count(0.0);
        let (always, kept) = count(1.0);
        assert_eq!((never, kept), (0, 0));
        assert!(always >= 8, "{always} eligible crops");
    }

    #[test]
    fn a_missing_sample_count_or_an_oversized_crop_is_an_error_naming_the_view() {
        let mut view = toy_view();
        view.noisy.push((8, view.noisy[0].1.clone()));
        assert!(view.input(8).is_ok());
        let e = view.input(3).err().expect("no render at 3 spp").to_string();
        assert_eq!(e, "toy.exr: has no noisy render at 3 spp (it has 1, 8 spp)");
        let e = CropSampler::new(&[view], 16, Encoding::default(), None).err().expect("16 px crops of 8 px views");
        assert_eq!(e.to_string(), "toy.exr: is 8x8 px, smaller than the 16 px crops");
    }
}
