//! Ambient occlusion through the BVH: a fixed, stratified, cosine-weighted pattern of occlusion
//! rays, evaluated on a sparse grid and upsampled with depth- and normal-aware weights.
//!
//! AO(p) = (1/π) ∫ V(p, ω, R) cosθ dω, the cosine-weighted fraction of the hemisphere around the
//! camera-facing geometric normal that is free of geometry within radius R. The same direction
//! pattern is used everywhere, so the result is deterministic and spatially smooth (no per-pixel
//! noise). Pixels where surfaces meet (a neighbour on another surface within the AO radius), whose
//! cell spans a steep change of AO, or with no neighbour on their surface are evaluated directly.

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use rtd_render::sampling::{sample_cosine_hemisphere, Frame};
use rtd_render::surface::offset_origin;
use rtd_render::SceneBvh;
use rtd_scene::Scene;

/// A sparse cell whose AO values spread more than this is evaluated per pixel.
const REFINE_SPREAD: f32 = 0.15;

/// How far (as a fraction of their separation) a neighbour may leave a point's tangent plane and
/// still count as the same surface: |d|/2r for a sphere of radius r seen across d, so 0.15
/// keeps curved surfaces down to r ≈ 3 grid steps together while perpendicular surfaces (≈ 1)
/// and silhouettes stay apart.
const TANGENT_SLACK: f32 = 0.15;

/// A surface point where AO is wanted.
#[derive(Debug, Clone, Copy)]
pub struct AoPoint {
    /// Position.
    pub p: Vec3,
    /// Rounding-error bound of `p`.
    pub p_error: Vec3,
    /// Unit geometric normal facing the camera.
    pub n: Vec3,
    /// Camera-space distance, for the upsampling weights.
    pub depth: f32,
}

/// The fixed direction pattern: `n` cosine-weighted directions from a Hammersley set (+z up).
/// Its first point (·, 0) would map to the rim of the concentric disk, a direction in the
/// tangent plane whose hit or miss at a crease is decided by rounding in the BVH's box tests;
/// it is lifted to the middle of its stratum instead.
pub fn pattern(n: u32) -> Vec<Vec3> {
    let first = 0.5 / n.max(1).next_power_of_two() as f64;
    (0..n)
        .map(|i| {
            let v = if i == 0 { first } else { i.reverse_bits() as f64 / 4294967296.0 };
            sample_cosine_hemisphere(Vec2::new((i as f32 + 0.5) / n as f32, v as f32))
        })
        .collect()
}

/// AO at one point: the fraction of pattern directions unoccluded within `radius`.
pub fn ao_at(scene: &Scene, bvh: &SceneBvh, pt: &AoPoint, dirs: &[Vec3], radius: f32) -> f32 {
    let frame = Frame::from_normal(pt.n);
    let mut open = 0u32;
    for d in dirs {
        let w = frame.to_world(*d);
        let o = offset_origin(pt.p, pt.p_error, pt.n, w);
        if !bvh.occluded(scene, o, w, radius) {
            open += 1;
        }
    }
    open as f32 / dirs.len() as f32
}

/// Computes AO for a `width`×`height` image of optional points, evaluating directly on every
/// `step`-th pixel and interpolating between those where the surfaces agree.
pub fn ao_image(
    scene: &Scene,
    bvh: &SceneBvh,
    point: impl Fn(usize) -> Option<AoPoint> + Sync,
    width: u32,
    height: u32,
    dirs: &[Vec3],
    radius: f32,
    step: u32,
) -> Vec<f32> {
    let (w, h) = (width as usize, height as usize);
    let step = step.max(1) as usize;
    let (gw, gh) = (w.div_ceil(step) + 1, h.div_ceil(step) + 1);
    // Sparse grid: pixel (gx·step, gy·step), clamped to the image.
    let grid_px = |gx: usize, gy: usize| ((gx * step).min(w - 1), (gy * step).min(h - 1));
    let grid: Vec<Option<(AoPoint, f32)>> = (0..gw * gh)
        .into_par_iter()
        .map(|g| {
            let (x, y) = grid_px(g % gw, g / gw);
            point(y * w + x).map(|pt| (pt, ao_at(scene, bvh, &pt, dirs, radius)))
        })
        .collect();
    // Same surface: normals agree and the neighbour lies close to this point's tangent plane
    // (which holds along receding planes, unlike a depth comparison).
    let same = |q: &AoPoint, pt: &AoPoint| {
        let d = q.p - pt.p;
        q.n.dot(pt.n) > 0.95 && d.dot(pt.n).abs() <= TANGENT_SLACK * d.length() + 1e-6 * pt.depth
    };
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let Some(pt) = point(i) else { return 1.0 };
            let (x, y) = (i % w, i / w);
            let (gx, gy) = (x / step, y / step);
            let (fx, fy) = ((x - gx * step) as f32 / step as f32, (y - gy * step) as f32 / step as f32);
            // Bilinear over the four surrounding grid points that lie on this pixel's surface.
            let mut sum = 0.0;
            let mut wsum = 0.0;
            let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
            // A corner on another surface within the AO radius means the surfaces meet or nearly
            // meet here (a crease or contact), where AO changes steeply.
            let mut touching = false;
            for (dx, dy, bw) in
                [(0, 0, (1.0 - fx) * (1.0 - fy)), (1, 0, fx * (1.0 - fy)), (0, 1, (1.0 - fx) * fy), (1, 1, fx * fy)]
            {
                if let Some((q, ao)) = grid[(gy + dy) * gw + gx + dx] {
                    if !same(&q, &pt) {
                        touching |= (q.p - pt.p).length() < radius;
                    } else {
                        let bw = bw.max(1e-3);
                        sum += bw * ao;
                        wsum += bw;
                        lo = lo.min(ao);
                        hi = hi.max(ao);
                    }
                }
            }
            // Interpolate from the corners on this surface where AO varies gently. Where surfaces
            // meet, or AO changes steeply across the cell, evaluate this pixel directly. (At a
            // silhouette the other surface lies far behind and does not affect this one's AO.)
            if !touching && wsum > 0.0 && hi - lo <= REFINE_SPREAD {
                return sum / wsum;
            }
            ao_at(scene, bvh, &pt, dirs, radius)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pattern_directions_leave_the_surface_and_are_cosine_distributed() {
        for n in [1, 2, 7, 24, 64, 4096] {
            let dirs = pattern(n);
            assert_eq!(dirs.len(), n as usize);
            // No direction lies in the tangent plane.
            assert!(dirs.iter().all(|d| d.z > 1e-3 && (d.length() - 1.0).abs() < 1e-5), "n = {n}");
        }
        // E[cosθ] under cosine weighting is 2/3.
        let dirs = pattern(4096);
        let mean = dirs.iter().map(|d| d.z as f64).sum::<f64>() / dirs.len() as f64;
        assert!((mean - 2.0 / 3.0).abs() < 1e-3, "{mean}");
    }
}
