//! Ambient occlusion through the BVH: a fixed, stratified, cosine-weighted pattern of occlusion
//! rays, evaluated on a sparse lattice and upsampled with surface-aware weights.
//!
//! AO(p) = (1/π) ∫ V(p, ω, R) cosθ dω, the cosine-weighted fraction of the hemisphere around the
//! camera-facing geometric normal that is free of geometry within radius R. The same direction
//! pattern is used everywhere, so the result is deterministic and spatially smooth (no per-pixel
//! noise). Pixels where surfaces meet (a neighbour on another surface within the AO radius), whose
//! cell spans a steep change of AO, or with no neighbour on their surface are retried on a lattice
//! of half the step, evaluated only around them, and what is still left is evaluated directly.

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
    /// The scene triangle the point lies on, which its rays leave and do not test
    /// ([`rtd_render::NO_TRIANGLE`]: none).
    pub triangle: u32,
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
    // Every pattern direction leaves the surface on the normal's side, so all rays share one
    // offset origin.
    let o = offset_origin(pt.p, pt.p_error, pt.n, pt.n);
    let mut open = 0u32;
    for d in dirs {
        let w = frame.to_world(*d);
        if !bvh.occluded_leaving(scene, o, w, radius, pt.triangle) {
            open += 1;
        }
    }
    open as f32 / dirs.len() as f32
}

/// A lattice of AO evaluation points every `step` pixels (clamped to the image), over which
/// the pixels between are interpolated.
struct Lattice {
    w: usize,
    h: usize,
    step: usize,
    gw: usize,
}

impl Lattice {
    fn new(w: usize, h: usize, step: usize) -> Self {
        Lattice { w, h, step, gw: w.div_ceil(step) + 1 }
    }
    /// Number of lattice points.
    fn len(&self) -> usize {
        self.gw * (self.h.div_ceil(self.step) + 1)
    }
    /// The pixel a lattice point sits on.
    fn pixel(&self, g: usize) -> usize {
        let (gx, gy) = (g % self.gw, g / self.gw);
        (gy * self.step).min(self.h - 1) * self.w + (gx * self.step).min(self.w - 1)
    }
    /// The four lattice points around pixel `i`, with their bilinear weights.
    fn corners(&self, i: usize) -> [(usize, f32); 4] {
        let (x, y) = (i % self.w, i / self.w);
        let (gx, gy) = (x / self.step, y / self.step);
        let s = self.step as f32;
        let (fx, fy) = ((x - gx * self.step) as f32 / s, (y - gy * self.step) as f32 / s);
        let g = gy * self.gw + gx;
        [
            (g, (1.0 - fx) * (1.0 - fy)),
            (g + 1, fx * (1.0 - fy)),
            (g + self.gw, (1.0 - fx) * fy),
            (g + self.gw + 1, fx * fy),
        ]
    }
}

/// Same surface: normals agree and `q` lies close to `pt`'s tangent plane (which holds along
/// receding planes, unlike a depth comparison).
#[inline]
fn same_surface(q: &AoPoint, pt: &AoPoint) -> bool {
    let d = q.p - pt.p;
    q.n.dot(pt.n) > 0.95 && d.dot(pt.n).abs() <= TANGENT_SLACK * d.length() + 1e-6 * pt.depth
}

/// AO at `pt` interpolated from the lattice points around it, or None where that is not safe:
/// a corner on another surface within the AO radius means the surfaces meet or nearly meet
/// there (a crease or contact, where AO changes steeply), and corners whose AO spreads more
/// than [`REFINE_SPREAD`] mean a steep change across the cell. (At a silhouette the other
/// surface lies far behind and does not affect this one's AO.)
fn interpolate(
    lattice: &Lattice,
    values: &[Option<(AoPoint, f32)>],
    i: usize,
    pt: &AoPoint,
    radius: f32,
) -> Option<f32> {
    let (mut sum, mut wsum) = (0.0, 0.0);
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for (g, bw) in lattice.corners(i) {
        let Some((q, ao)) = values[g] else { continue };
        if !same_surface(&q, pt) {
            if (q.p - pt.p).length() < radius {
                return None;
            }
            continue;
        }
        // Bilinear weights over the corners on this pixel's surface.
        let bw = bw.max(1e-3);
        sum += bw * ao;
        wsum += bw;
        lo = lo.min(ao);
        hi = hi.max(ao);
    }
    (wsum > 0.0 && hi - lo <= REFINE_SPREAD).then(|| sum / wsum)
}

/// Computes AO for a `width`×`height` image of optional points. AO is evaluated directly on a
/// lattice every `step` pixels and interpolated between lattice points on the pixel's surface.
/// Pixels where that is not safe go to a lattice of half the step, evaluated only where such
/// pixels need it, and so on; what is left at step 1 is evaluated directly.
#[allow(clippy::too_many_arguments)]
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
    let eval = |pt: &AoPoint| ao_at(scene, bvh, pt, dirs, radius);
    // AO per pixel; NaN: not known yet (1 where no surface is seen).
    let mut ao: Vec<f32> =
        (0..w * h).into_par_iter().map(|i| if point(i).is_some() { f32::NAN } else { 1.0 }).collect();
    // Directly evaluated pixels (NaN: not yet), so that finer lattices reuse coarser points.
    let mut exact = vec![f32::NAN; w * h];
    let mut level = step.max(1) as usize;
    let mut first = true;
    while level > 1 {
        let lattice = Lattice::new(w, h, level);
        // The first lattice is evaluated everywhere; finer ones only around pixels still unknown.
        let needed = if first {
            vec![true; lattice.len()]
        } else {
            let pending: Vec<usize> = (0..w * h).into_par_iter().filter(|&i| ao[i].is_nan()).collect();
            if pending.is_empty() {
                break;
            }
            let mut needed = vec![false; lattice.len()];
            for &i in &pending {
                for (g, _) in lattice.corners(i) {
                    needed[g] = true;
                }
            }
            needed
        };
        let values: Vec<Option<(AoPoint, f32)>> = needed
            .par_iter()
            .enumerate()
            .map(|(g, &need)| {
                let px = lattice.pixel(g);
                let pt = point(px).filter(|_| need)?;
                Some((pt, if exact[px].is_nan() { eval(&pt) } else { exact[px] }))
            })
            .collect();
        for (g, v) in values.iter().enumerate() {
            if let Some((_, a)) = v {
                exact[lattice.pixel(g)] = *a;
            }
        }
        ao.par_iter_mut().enumerate().filter(|(_, a)| a.is_nan()).for_each(|(i, a)| {
            if let Some(v) = point(i).and_then(|pt| interpolate(&lattice, &values, i, &pt, radius)) {
                *a = v;
            }
        });
        level /= 2;
        first = false;
    }
    // What is left is evaluated directly.
    ao.par_iter_mut().enumerate().filter(|(_, a)| a.is_nan()).for_each(|(i, a)| {
        *a = if exact[i].is_nan() { point(i).map_or(1.0, |pt| eval(&pt)) } else { exact[i] };
    });
    ao
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
