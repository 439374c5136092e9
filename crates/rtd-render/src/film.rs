//! The film: per-pixel running sums of the beauty and the first-hit AOVs.
//!
//! Sums are accumulated per pixel in sample order, so N samples followed by M more give the
//! same bytes as N+M samples in one go.

use glam::{DVec3, Vec3};
use rtd_image::{HdrImage, Layer, Layers};

/// Accumulated samples for one image.
#[derive(Debug, Clone)]
pub struct Film {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Samples taken per pixel so far.
    pub spp: u32,
    pub(crate) beauty: Vec<DVec3>,
    pub(crate) albedo: Vec<Vec3>,
    pub(crate) normal: Vec<Vec3>,
    pub(crate) depth: Vec<f32>,
    /// Samples whose radiance was NaN or infinite; they were counted as black.
    pub nonfinite_samples: u64,
}

impl Film {
    /// An empty film.
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Film {
            width,
            height,
            spp: 0,
            beauty: vec![DVec3::ZERO; n],
            albedo: vec![Vec3::ZERO; n],
            normal: vec![Vec3::ZERO; n],
            depth: vec![0.0; n],
            nonfinite_samples: 0,
        }
    }

    fn mean_image(&self, f: impl Fn(usize) -> Vec3) -> HdrImage {
        let n = self.width as usize * self.height as usize;
        HdrImage::from_pixels(self.width, self.height, (0..n).map(f).collect())
    }

    /// The beauty image (mean radiance per pixel).
    pub fn beauty(&self) -> HdrImage {
        let inv = 1.0 / self.spp.max(1) as f64;
        self.mean_image(|i| (self.beauty[i] * inv).as_vec3())
    }

    /// Mean first-hit albedo.
    pub fn albedo(&self) -> HdrImage {
        let inv = 1.0 / self.spp.max(1) as f32;
        self.mean_image(|i| self.albedo[i] * inv)
    }

    /// Mean first-hit world-space shading normal (not renormalised at edges).
    pub fn normal(&self) -> HdrImage {
        let inv = 1.0 / self.spp.max(1) as f32;
        self.mean_image(|i| self.normal[i] * inv)
    }

    /// Mean camera-space distance to the first hit (0 where rays escaped).
    pub fn depth(&self) -> Vec<f32> {
        let inv = 1.0 / self.spp.max(1) as f32;
        self.depth.iter().map(|d| d * inv).collect()
    }

    /// The EXR channels: `R,G,B`, `albedo.R/G/B`, `normal.X/Y/Z`, `depth.Z`.
    pub fn layers(&self) -> Layers {
        let mut l = Layers::new(self.width, self.height);
        l.put_image(Layer::Beauty, &self.beauty());
        l.put_image(Layer::Albedo, &self.albedo());
        l.put_image(Layer::Normal, &self.normal());
        l.put_plane(Layer::Depth, self.depth());
        l
    }
}
