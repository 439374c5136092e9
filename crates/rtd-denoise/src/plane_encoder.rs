//! The network's input planes, assembled from a [`DenoiseInput`] in the [`Plane`] layout: whole
//! images for training ([`encode_planes`]), or a tile's window at a time for inference
//! ([`PlaneEncoder`]), so a large image is never held as twenty full-size planes.

use rayon::prelude::*;
use rtd_image::HdrImage;

use crate::encode::{clean, demod_albedo, encode_values, DenoiseInput, Encoding, Estimate, PIXEL_CHUNK};
use crate::planes::{Plane, INPUT_CHANNELS};
use crate::DenoiseError;

/// The input planes of one image, encoded on demand at any pixels, with the whole-image values
/// (exposure, depth scale) found once. Every plane value is a function of its own pixel, so a
/// window encoded here equals the same pixels of [`encode_planes`], bit for bit.
pub struct PlaneEncoder<'a> {
    input: DenoiseInput<'a>,
    exposure: f32,
    /// 1 / the mean hit distance, when AO and depth are given.
    depth_scale: Option<f32>,
    /// The albedo colour is divided by, when the model demodulates and one is given.
    demod: Option<&'a HdrImage>,
    channels: usize,
}

impl<'a> PlaneEncoder<'a> {
    /// The encoder of `input` under `encoding`, at `exposure`; checks the layers' sizes.
    pub fn new(input: &DenoiseInput<'a>, exposure: f32, encoding: Encoding) -> Result<Self, DenoiseError> {
        input.size()?;
        // Depth relative to the mean hit distance, so the scene's scale does not matter.
        let depth_scale = input.ao_depth.map(|(_, d)| {
            let (sum, hits) =
                d.iter().filter(|v| v.is_finite() && **v > 0.0).fold((0.0f32, 0usize), |(s, n), v| (s + v, n + 1));
            if hits == 0 {
                1.0
            } else {
                hits as f32 / sum
            }
        });
        Ok(PlaneEncoder {
            input: *input,
            exposure,
            depth_scale,
            demod: demod_albedo(input, encoding.demodulate),
            channels: encoding.channels.min(INPUT_CHANNELS),
        })
    }

    /// How many planes the model reads.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Writes plane `c` at the pixels `index` (row-major indices into the image) into `dst`.
    /// Absent inputs give 0, and their flags 0.
    pub fn encode(&self, c: usize, index: impl Iterator<Item = usize>, dst: &mut [f32]) {
        let input = &self.input;
        let (e, demod) = (self.exposure, self.demod);
        // Channel k of an image, clamped to [lo, hi].
        fn gather(dst: &mut [f32], index: impl Iterator<Item = usize>, image: &HdrImage, k: usize, lo: f32, hi: f32) {
            dst.iter_mut().zip(index).for_each(|(v, i)| *v = clean(image.pixels[i].to_array()[k], lo, hi))
        }
        match (Plane::of(c), input.albedo_normal, input.ao_depth.zip(self.depth_scale)) {
            (Plane::Color(k), _, _) => encode_values(dst, index, input.color, demod, k, e, Estimate::Color),
            (Plane::Guide(k), _, _) => gather(dst, index, input.guide, k, 0.0, 1.0),
            (Plane::Albedo(k), Some((a, _)), _) => gather(dst, index, a, k, 0.0, 1.0),
            (Plane::Normal(k), Some((_, n)), _) => gather(dst, index, n, k, -1.0, 1.0),
            (Plane::Ao, _, Some(((ao, _), _))) => {
                dst.iter_mut().zip(index).for_each(|(v, i)| *v = clean(ao[i], 0.0, 1.0))
            }
            (Plane::Depth, _, Some(((_, d), s))) => {
                dst.iter_mut().zip(index).for_each(|(v, i)| *v = clean(d[i] * s, 0.0, 8.0))
            }
            (Plane::HasAlbedoNormal, Some(_), _) | (Plane::HasAoDepth, _, Some(_)) => dst.fill(1.0),
            (Plane::Deviation(k), _, _) => match input.variance {
                Some(v) => encode_values(dst, index, v, demod, k, e, Estimate::Deviation),
                None => dst.fill(0.0),
            },
            (Plane::HasVariance, _, _) if input.variance.is_some() => dst.fill(1.0),
            _ => dst.fill(0.0),
        }
    }
}

/// Where the tiled denoiser reads its input planes from.
#[derive(Clone, Copy)]
pub enum PlaneSource<'a> {
    /// Planes encoded beforehand, C × H × W in channel-major order.
    Planes(&'a [f32]),
    /// The inputs themselves, each window encoded as it is read.
    Inputs(&'a PlaneEncoder<'a>),
}

impl PlaneSource<'_> {
    /// Writes plane `c` at the pixels `index` of the `n`-pixel image into `dst`.
    pub fn fill(&self, c: usize, index: &[usize], n: usize, dst: &mut [f32]) {
        match self {
            PlaneSource::Planes(planes) => {
                let plane = &planes[c * n..][..n];
                dst.iter_mut().zip(index).for_each(|(d, i)| *d = plane[*i]);
            }
            PlaneSource::Inputs(encoder) => encoder.encode(c, index.iter().copied(), dst),
        }
    }
}

/// The network's input planes of the whole image, `encoding.channels` × H × W in channel-major
/// order (the first planes of the [`Plane`] layout). With `encoding.demodulate` and an albedo
/// layer, the colour and deviation planes hold colour (deviation) ÷ (albedo + DEMOD_EPS).
pub fn encode_planes(input: &DenoiseInput, exposure: f32, encoding: Encoding) -> Result<Vec<f32>, DenoiseError> {
    let (w, h) = input.size()?;
    let encoder = PlaneEncoder::new(input, exposure, encoding)?;
    let n = (w * h) as usize;
    let mut planes = vec![0.0f32; encoder.channels() * n];
    // Tasks of one plane's pixel chunk each.
    planes.par_chunks_mut(n).enumerate().for_each(|(c, plane)| {
        plane.par_chunks_mut(PIXEL_CHUNK).enumerate().for_each(|(j, chunk)| {
            let i0 = j * PIXEL_CHUNK;
            encoder.encode(c, i0..i0 + chunk.len(), chunk);
        })
    });
    Ok(planes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encode::encode_color;
    use glam::Vec3;

    #[test]
    fn demodulation_divides_colour_by_albedo_only_when_asked_and_given() {
        let color = HdrImage::from_pixels(2, 1, vec![Vec3::new(0.5, 1.0, 2.0), Vec3::splat(3.0)]);
        let albedo = HdrImage::from_pixels(2, 1, vec![Vec3::new(0.24, 0.49, 0.0), Vec3::splat(2.0)]);
        let normal = HdrImage::from_pixels(2, 1, vec![Vec3::Z; 2]);
        let with = DenoiseInput::new(&color, &color).albedo_normal(&albedo, &normal);
        let demod = encode_planes(&with, 0.7, Encoding { demodulate: true, ..Encoding::default() }).unwrap();
        let plain = encode_planes(&with, 0.7, Encoding::default()).unwrap();
        // Albedo + ε: 0.25, 0.5, 0.01; albedo above 1 is clamped to 1 first.
        let expected = [0.5 / 0.25, 3.0 / 1.01, 1.0 / 0.5, 3.0 / 1.01, 2.0 / 0.01, 3.0 / 1.01];
        for (v, x) in demod[..6].iter().zip(expected) {
            assert!((v - encode_color(x, 0.7)).abs() < 1e-5, "{v} vs {x}");
        }
        assert_eq!(demod[6..], plain[6..], "only the colour planes change");
        assert_ne!(demod[..6], plain[..6]);
        // Without an albedo layer there is nothing to divide by.
        let without = DenoiseInput::new(&color, &color);
        let demod = Encoding { demodulate: true, ..Encoding::default() };
        assert_eq!(
            encode_planes(&without, 0.7, demod).unwrap(),
            encode_planes(&without, 0.7, Encoding::default()).unwrap()
        );
    }

    #[test]
    fn ao_and_depth_fill_their_planes_and_flag_only_when_given() {
        let color = HdrImage::from_pixels(2, 1, vec![Vec3::splat(0.5), Vec3::splat(3.0)]);
        let (ao, depth) = ([0.25, 1.0], [2.0, 6.0]);
        let plane = |planes: &[f32], c: usize| planes[2 * c..2 * c + 2].to_vec();
        let with = encode_planes(&DenoiseInput::new(&color, &color).ao_depth(&ao, &depth), 1.0, Encoding::default());
        let without = encode_planes(&DenoiseInput::new(&color, &color), 1.0, Encoding::default());
        let (with, without) = (with.unwrap(), without.unwrap());
        let (ao, depth, flag) = (Plane::Ao.index(), Plane::Depth.index(), Plane::HasAoDepth.index());
        // Depth relative to the mean hit distance (4).
        assert_eq!(plane(&with, depth), [0.5, 1.5]);
        assert_eq!((plane(&with, ao), plane(&with, flag)), (vec![0.25, 1.0], vec![1.0, 1.0]));
        for c in [ao, depth, flag] {
            assert_eq!(plane(&without, c), [0.0, 0.0], "plane {c}");
        }
        for c in (0..INPUT_CHANNELS).filter(|c| ![ao, depth, flag].contains(c)) {
            assert_eq!(plane(&with, c), plane(&without, c), "plane {c}");
        }
    }

    /// Every plane encoded at scattered pixels (as a tile's window reads them) equals the same
    /// pixels of the whole-image planes, bit for bit, with every input given, hostile values
    /// among them, and with the optional inputs left out.
    #[test]
    fn windows_encode_as_the_whole_image_does() {
        let (w, h) = (7u32, 5u32);
        let n = (w * h) as usize;
        let v = |i: usize, k: usize| ((i * 7 + k * 13) % 17) as f32 / 4.0 - 0.5;
        let image = |f: &dyn Fn(usize, usize) -> f32| {
            HdrImage::from_pixels(w, h, (0..n).map(|i| Vec3::new(f(i, 0), f(i, 1), f(i, 2))).collect())
        };
        let mut color = image(&|i, k| v(i, k) * 3.0);
        color.pixels[3] = Vec3::new(f32::NAN, f32::INFINITY, -2.0);
        let (albedo, normal, variance) = (image(&|i, k| v(i, k + 1)), image(&|i, k| v(i, k + 2)), image(&v));
        let ao: Vec<f32> = (0..n).map(|i| v(i, 4)).collect();
        let depth: Vec<f32> = (0..n).map(|i| if i == 9 { f32::NAN } else { v(i, 5) * 9.0 }).collect();
        let full = DenoiseInput::new(&color, &albedo)
            .albedo_normal(&albedo, &normal)
            .ao_depth(&ao, &depth)
            .variance(Some(&variance));
        let index: Vec<usize> = (0..n).map(|i| i * 11 % n).collect();
        for input in [full, DenoiseInput::new(&color, &albedo)] {
            let legacy = Encoding { channels: crate::planes::LEGACY_INPUT_CHANNELS, ..Encoding::default() };
            for encoding in [Encoding { demodulate: true, ..Encoding::default() }, Encoding::default(), legacy] {
                let planes = encode_planes(&input, 0.8, encoding).unwrap();
                let encoder = PlaneEncoder::new(&input, 0.8, encoding).unwrap();
                assert_eq!(planes.len(), encoder.channels() * n);
                for c in 0..encoder.channels() {
                    let mut window = vec![f32::NAN; n];
                    PlaneSource::Inputs(&encoder).fill(c, &index, n, &mut window);
                    let expected: Vec<u32> = index.iter().map(|i| planes[c * n + i].to_bits()).collect();
                    assert_eq!(window.iter().map(|x| x.to_bits()).collect::<Vec<_>>(), expected, "plane {c}");
                }
            }
        }
    }
}
