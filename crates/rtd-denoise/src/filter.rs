//! The non-learned baseline: an edge-avoiding à-trous wavelet filter (Dammertz et al. 2010)
//! guided by the same guide pass the network sees. It filters the log-encoded colour with a
//! 5×5 B3-spline kernel dilated 2^i at iteration i, each tap weighted by how alike the
//! two pixels' colour, guide RGB and (when present) normal are.

use glam::Vec3;
use rayon::prelude::*;
use rtd_image::HdrImage;
use serde::{Deserialize, Serialize};

use crate::encode::{auto_exposure, decode_color, encode_color, DenoiseInput};
use crate::DenoiseError;

/// Parameters of the guided à-trous filter. [`GuidedFilter::default`] holds the tuned values;
/// the chained setters below change one at a time.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GuidedFilter {
    /// À-trous iterations (kernel footprint 4·2^n + 1 pixels).
    pub iterations: u32,
    /// Colour edge-stopping scale, in log-encoded units (halved every iteration).
    pub sigma_color: f32,
    /// Guide RGB edge-stopping scale.
    pub sigma_guide: f32,
    /// Normal edge-stopping scale (1 − cos between normals).
    pub sigma_normal: f32,
}

impl Default for GuidedFilter {
    /// The parameters `rtd bench validation`'s grid search picked on the training views of the
    /// shipped dataset at 8 spp (models/README.md).
    fn default() -> Self {
        GuidedFilter { iterations: 5, sigma_color: 4.0, sigma_guide: 0.05, sigma_normal: 0.1 }
    }
}

impl GuidedFilter {
    /// Sets the iteration count.
    pub fn iterations(mut self, n: u32) -> Self {
        self.iterations = n;
        self
    }
    /// Sets the colour scale.
    pub fn sigma_color(mut self, s: f32) -> Self {
        self.sigma_color = s;
        self
    }
    /// Sets the guide scale.
    pub fn sigma_guide(mut self, s: f32) -> Self {
        self.sigma_guide = s;
        self
    }

    /// Filters `input.color` guided by the rest of `input`.
    pub fn filter(&self, input: &DenoiseInput) -> Result<HdrImage, DenoiseError> {
        let (w, h) = input.size()?;
        let (w, h) = (w as usize, h as usize);
        let e = auto_exposure(input.color);
        let mut col: Vec<Vec3> = input
            .color
            .pixels
            .iter()
            .map(|c| Vec3::new(encode_color(c.x, e), encode_color(c.y, e), encode_color(c.z, e)))
            .collect();
        let guide: Vec<Vec3> = input.guide.pixels.iter().map(|g| g.clamp(Vec3::ZERO, Vec3::ONE)).collect();
        let normal: Option<Vec<Vec3>> =
            input.albedo_normal.map(|(_, n)| n.pixels.iter().map(|v| v.normalize_or_zero()).collect());
        const B3: [f32; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];
        for it in 0..self.iterations {
            let step = 1i64 << it;
            let sc = self.sigma_color * 0.5f32.powi(it as i32);
            let prev = col.clone();
            col.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
                for (x, out) in row.iter_mut().enumerate() {
                    let i = y * w + x;
                    let (c0, g0) = (prev[i], guide[i]);
                    let n0 = normal.as_ref().map(|n| n[i]);
                    let (mut sum, mut wsum) = (Vec3::ZERO, 0.0f32);
                    for (dy, ky) in B3.iter().enumerate() {
                        let sy = y as i64 + (dy as i64 - 2) * step;
                        if sy < 0 || sy >= h as i64 {
                            continue;
                        }
                        for (dx, kx) in B3.iter().enumerate() {
                            let sx = x as i64 + (dx as i64 - 2) * step;
                            if sx < 0 || sx >= w as i64 {
                                continue;
                            }
                            let j = sy as usize * w + sx as usize;
                            // Edge-stopping weight: Gaussian in colour, guide and normal distance.
                            let dc = (prev[j] - c0).length_squared() / (sc * sc);
                            let dg = (guide[j] - g0).length_squared() / (self.sigma_guide * self.sigma_guide);
                            let dn = match (n0, &normal) {
                                (Some(n0), Some(n)) => (1.0 - n0.dot(n[j])).max(0.0) / self.sigma_normal,
                                _ => 0.0,
                            };
                            let wt = kx * ky * (-(dc + dg + dn)).exp();
                            sum += prev[j] * wt;
                            wsum += wt;
                        }
                    }
                    *out = if wsum > 0.0 { sum / wsum } else { c0 };
                }
            });
        }
        let pixels =
            col.iter().map(|c| Vec3::new(decode_color(c.x, e), decode_color(c.y, e), decode_color(c.z, e))).collect();
        Ok(HdrImage::from_pixels(w as u32, h as u32, pixels))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_constant_image_is_unchanged_and_guide_edges_are_kept() {
        let c = HdrImage::from_pixels(16, 16, vec![Vec3::splat(0.7); 256]);
        let out = GuidedFilter::default().filter(&DenoiseInput::new(&c, &c)).unwrap();
        assert!(out.pixels.iter().all(|p| (*p - Vec3::splat(0.7)).abs().max_element() < 1e-5));
        // Left half dark, right half bright, with a guide edge at the same place: the step stays.
        let px: Vec<Vec3> = (0..256).map(|i| if i % 16 < 8 { Vec3::splat(0.1) } else { Vec3::splat(0.9) }).collect();
        let img = HdrImage::from_pixels(16, 16, px);
        let out = GuidedFilter::default().filter(&DenoiseInput::new(&img, &img)).unwrap();
        assert!(
            (out.get(7, 8).x - 0.1).abs() < 0.01 && (out.get(8, 8).x - 0.9).abs() < 0.01,
            "{:?}",
            (out.get(7, 8), out.get(8, 8))
        );
    }
}
