//! The film: per-pixel running sums of the beauty, its square (for the per-pixel variance the
//! denoiser reads) and the first-hit AOVs.
//!
//! Every sample is snapped to a multiple of [`SAMPLE_QUANTUM`] before it is added to an `f64`
//! sum. Sums of such values are exact while they stay below 2^29, so they do not depend on the
//! order of addition: N samples followed by M more give the same bytes as N+M in one go, and a
//! render split into sample ranges on several machines and merged ([`Film::merge`]) gives the same
//! bytes as the whole render on one.

use glam::{DVec3, Vec3};
use rtd_image::{HdrImage, Layer, Layers};
use serde::{Deserialize, Serialize};

/// The grid samples are snapped to before accumulation: 2^-24, about 6e-8, far below what a
/// 32-bit float output shows of any visible pixel value.
pub const SAMPLE_QUANTUM: f64 = 1.0 / (1u64 << 24) as f64;

/// A sample value on the [`SAMPLE_QUANTUM`] grid (round to nearest), so that sums are exact.
#[inline]
pub(crate) fn quantize(v: f64) -> f64 {
    (v / SAMPLE_QUANTUM).round() * SAMPLE_QUANTUM
}

/// [`quantize`] per component.
#[inline]
pub(crate) fn quantize3(v: Vec3) -> DVec3 {
    let d = v.as_dvec3();
    DVec3::new(quantize(d.x), quantize(d.y), quantize(d.z))
}

/// The square of a snapped sample, snapped again, so that sums of squares are exact as well.
#[inline]
pub(crate) fn quantize_square(q: DVec3) -> DVec3 {
    let s = q * q;
    DVec3::new(quantize(s.x), quantize(s.y), quantize(s.z))
}

/// Accumulated samples for one image: samples `first_sample..spp` of every pixel.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Film {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// One past the index of the last sample taken per pixel (the samples so far, for a film
    /// that started at sample 0).
    pub spp: u32,
    /// The first sample index this film holds: 0 unless it is one range of a split render.
    pub first_sample: u32,
    pub(crate) beauty: Vec<DVec3>,
    /// Sums of the squared samples (each square snapped to the grid again, so these sums are
    /// exact too): with `beauty` they give each pixel's sample variance.
    pub(crate) beauty_sq: Vec<DVec3>,
    pub(crate) albedo: Vec<DVec3>,
    pub(crate) normal: Vec<DVec3>,
    pub(crate) depth: Vec<f64>,
    /// Samples whose radiance was NaN or infinite; they were counted as black.
    pub nonfinite_samples: u64,
}

impl Film {
    /// An empty film.
    pub fn new(width: u32, height: u32) -> Self {
        Film::starting_at(width, height, 0)
    }

    /// An empty film whose next sample index is `first_sample`: one range of a render split
    /// by sample index, to be [`Film::merge`]d with the ranges before it.
    pub fn starting_at(width: u32, height: u32, first_sample: u32) -> Self {
        let n = width as usize * height as usize;
        Film {
            width,
            height,
            spp: first_sample,
            first_sample,
            beauty: vec![DVec3::ZERO; n],
            beauty_sq: vec![DVec3::ZERO; n],
            albedo: vec![DVec3::ZERO; n],
            normal: vec![DVec3::ZERO; n],
            depth: vec![0.0; n],
            nonfinite_samples: 0,
        }
    }

    /// Samples per pixel this film holds.
    pub fn samples(&self) -> u32 {
        self.spp - self.first_sample
    }

    /// True if the film's buffers have its size and its sample range is in order: what a film
    /// read back from storage must satisfy before it is used.
    pub fn is_consistent(&self) -> bool {
        let n = self.width as usize * self.height as usize;
        self.first_sample <= self.spp
            && [self.beauty.len(), self.beauty_sq.len(), self.albedo.len(), self.normal.len(), self.depth.len()]
                .iter()
                .all(|&l| l == n)
    }

    /// Appends `next`, the range that starts where this film ends. The sums are exact, so
    /// merging the ranges of a split render in any grouping gives the one-machine film's bytes.
    pub fn merge(&mut self, next: &Film) -> Result<(), FilmMergeError> {
        if (next.width, next.height) != (self.width, self.height) {
            return Err(FilmMergeError::Size { have: (self.width, self.height), next: (next.width, next.height) });
        }
        if next.first_sample != self.spp || !next.is_consistent() {
            return Err(FilmMergeError::Range { have: self.spp, next: next.first_sample });
        }
        let add3 = |a: &mut [DVec3], b: &[DVec3]| a.iter_mut().zip(b).for_each(|(a, b)| *a += *b);
        add3(&mut self.beauty, &next.beauty);
        add3(&mut self.beauty_sq, &next.beauty_sq);
        add3(&mut self.albedo, &next.albedo);
        add3(&mut self.normal, &next.normal);
        self.depth.iter_mut().zip(&next.depth).for_each(|(a, b)| *a += *b);
        self.spp = next.spp;
        self.nonfinite_samples += next.nonfinite_samples;
        Ok(())
    }

    fn mean_image(&self, f: impl Fn(usize) -> Vec3) -> HdrImage {
        let n = self.width as usize * self.height as usize;
        HdrImage::from_pixels(self.width, self.height, (0..n).map(f).collect())
    }

    /// The beauty image (mean radiance per pixel).
    pub fn beauty(&self) -> HdrImage {
        let inv = self.inverse_samples();
        self.mean_image(|i| (self.beauty[i] * inv).as_vec3())
    }

    /// The variance of each pixel's mean, per channel: the sample variance
    /// (Σx² − (Σx)²/N)/(N − 1) divided by N, the noise a denoiser should expect in
    /// [`Film::beauty`]. None below 2 samples, where it is unknown.
    pub fn variance(&self) -> Option<HdrImage> {
        let n = self.samples();
        if n < 2 {
            return None;
        }
        let n = n as f64;
        Some(self.mean_image(|i| {
            let (sum, sq) = (self.beauty[i], self.beauty_sq[i]);
            // Rounding can leave a tiny negative difference for a constant pixel.
            let spread = (sq - sum * sum / n).max(DVec3::ZERO);
            (spread / ((n - 1.0) * n)).as_vec3()
        }))
    }

    /// Mean first-hit albedo.
    pub fn albedo(&self) -> HdrImage {
        let inv = self.inverse_samples();
        self.mean_image(|i| (self.albedo[i] * inv).as_vec3())
    }

    /// Mean first-hit world-space shading normal (not renormalised at edges).
    pub fn normal(&self) -> HdrImage {
        let inv = self.inverse_samples();
        self.mean_image(|i| (self.normal[i] * inv).as_vec3())
    }

    /// Mean camera-space distance to the first hit (0 where rays escaped).
    pub fn depth(&self) -> Vec<f32> {
        let inv = self.inverse_samples();
        self.depth.iter().map(|d| (d * inv) as f32).collect()
    }

    /// 1 / samples held (1 for an empty film, whose sums are all zero).
    fn inverse_samples(&self) -> f64 {
        1.0 / self.samples().max(1) as f64
    }

    /// The EXR channels: `R,G,B`, `albedo.R/G/B`, `normal.X/Y/Z`, `depth.Z`, and from 2
    /// samples on `variance.R/G/B` ([`Film::variance`]).
    pub fn layers(&self) -> Layers {
        let mut l = Layers::new(self.width, self.height);
        self.put_beauty(&mut l);
        self.put_first_hits(&mut l);
        l
    }

    /// [`Film::layers`], consuming the film: the beauty sums (half the film) are freed once the
    /// beauty and variance layers are made, before the first-hit layers are.
    pub fn into_layers(mut self) -> Layers {
        let mut l = Layers::new(self.width, self.height);
        self.put_beauty(&mut l);
        (self.beauty, self.beauty_sq) = (Vec::new(), Vec::new());
        self.put_first_hits(&mut l);
        l
    }

    /// Adds the beauty and, from 2 samples on, its variance.
    fn put_beauty(&self, l: &mut Layers) {
        l.put_image(Layer::Beauty, &self.beauty());
        if let Some(v) = self.variance() {
            l.put_image(Layer::Variance, &v);
        }
    }

    /// Adds the first hits' albedo, normal and depth.
    fn put_first_hits(&self, l: &mut Layers) {
        l.put_image(Layer::Albedo, &self.albedo());
        l.put_image(Layer::Normal, &self.normal());
        l.put_plane(Layer::Depth, self.depth());
    }
}

/// Why two films cannot be merged.
#[derive(Debug, thiserror::Error)]
pub enum FilmMergeError {
    /// The films are of different sizes.
    #[error("film sizes differ: {}x{} and {}x{}", have.0, have.1, next.0, next.1)]
    Size {
        /// This film's size.
        have: (u32, u32),
        /// The other film's size.
        next: (u32, u32),
    },
    /// The next film does not start at the sample where this one ends (or is malformed).
    #[error("the next sample range starts at sample {next}, not at {have} where this film ends")]
    Range {
        /// Where this film ends.
        have: u32,
        /// Where the next one starts.
        next: u32,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Values far apart in magnitude, whose plain f64 sums depend on the grouping.
    const WIDE: [f64; 4] = [3.0e7, 1.0e-7 + 0.3, 0.1, -3.0e7 + 0.7];

    #[test]
    fn variance_of_the_mean_is_the_sample_variance_over_n() {
        let mut film = Film::new(1, 1);
        assert_eq!(film.variance(), None, "unknown without samples");
        // Samples 1, 2, 3, 4 in red, a constant 5 in green, 0 in blue: sample variance 5/3,
        // so the variance of the mean is 5/12.
        for v in [1.0, 2.0, 3.0, 4.0] {
            let q = quantize3(Vec3::new(v, 5.0, 0.0));
            film.beauty[0] += q;
            film.beauty_sq[0] += quantize_square(q);
            film.spp += 1;
            if film.spp == 1 {
                assert_eq!(film.variance(), None, "unknown from one sample");
            }
        }
        let v = film.variance().unwrap().pixels[0];
        assert!((v.x - 5.0 / 12.0).abs() < 1e-6 && v.y == 0.0 && v.z == 0.0, "{v}");
        assert!(film.layers().image(Layer::Variance).is_some());
    }

    /// A film taken apart for its layers gives the layers it gives when borrowed, variance
    /// included.
    #[test]
    fn consumed_films_give_the_same_layers() {
        let mut film = Film::new(3, 2);
        for (i, v) in [0.5, 2.0, 7.0].into_iter().enumerate() {
            for p in 0..6 {
                let q = quantize3(Vec3::new(v, p as f32, 1.0 + i as f32));
                film.beauty[p] += q;
                film.beauty_sq[p] += quantize_square(q);
                film.albedo[p] += DVec3::splat(0.25 * p as f64);
                film.normal[p] += DVec3::Z;
                film.depth[p] += 1.5 + i as f64;
            }
            film.spp += 1;
        }
        let borrowed = film.layers();
        assert!(borrowed.get("variance.R").is_some());
        assert_eq!(film.into_layers(), borrowed);
    }

    #[test]
    fn quantised_sums_do_not_depend_on_grouping() {
        let plain = [WIDE[0] + (WIDE[1] + WIDE[2]), (WIDE[0] + WIDE[1]) + WIDE[2]];
        assert_ne!(plain[0], plain[1], "the example must show plain sums are not associative");
        let q = WIDE.map(quantize);
        assert_eq!(q[0] + (q[1] + q[2]) + q[3], ((q[0] + q[1]) + q[2]) + q[3]);
        assert_eq!((q[0] + q[1]) + (q[2] + q[3]), ((q[0] + q[1]) + q[2]) + q[3]);
        assert!((quantize(0.3) - 0.3).abs() <= SAMPLE_QUANTUM / 2.0);
    }
}
