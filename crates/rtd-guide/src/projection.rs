//! Scene triangles on the screen: camera space, the near-plane clip, the projection, and the
//! screen triangles the rasteriser draws (with their perspective-correct barycentrics).

use glam::{Vec3, Vec3A};
use rtd_scene::{Camera, Projection};

use crate::sample_grid::{covers_a_sample, sample_fractions, sample_reach, SAMPLES_1D};

/// A projected, clipped triangle.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ScreenTri {
    /// Screen x, y in pixels and the depth key (1/z for perspective, −z for orthographic).
    pub(crate) v: [Vec3; 3],
    /// 1/z per vertex for perspective-correct interpolation (1 for orthographic).
    pub(crate) w: [f32; 3],
    /// Barycentrics of each vertex in the original triangle.
    pub(crate) b: [Vec3A; 3],
    /// Twice the signed screen area ([`signed_area`] of `v`).
    pub(crate) area: f64,
    /// The scene triangle it is (a piece of).
    pub(crate) triangle: u32,
    /// The scene triangle's material (kept here: reading it from the triangle is a cache miss
    /// per triangle on a mesh of millions).
    pub(crate) material: u32,
}

/// Camera-space coordinates (x right, y up, z forward) of a world point.
#[inline]
pub(crate) fn to_camera(cam: &Camera, p: Vec3) -> Vec3 {
    let d = p - cam.position;
    Vec3::new(d.dot(cam.right), d.dot(cam.up), d.dot(cam.forward))
}

/// A camera-space triangle clipped against the near plane: up to 4 (position, barycentrics)
/// vertices, `len` of them used.
#[derive(Clone, Copy)]
pub(crate) struct Clipped {
    pub(crate) v: [(Vec3, Vec3); 4],
    pub(crate) len: usize,
}

/// Clips a camera-space triangle against z ≥ near (Sutherland–Hodgman), carrying barycentrics.
pub(crate) fn clip_near(tri: &[(Vec3, Vec3); 3], near: f32) -> Clipped {
    let mut out = Clipped { v: [(Vec3::ZERO, Vec3::ZERO); 4], len: 0 };
    let mut push = |v: (Vec3, Vec3)| {
        out.v[out.len] = v;
        out.len += 1;
    };
    for i in 0..3 {
        let (a, ba) = tri[i];
        let (b, bb) = tri[(i + 1) % 3];
        let (ina, inb) = (a.z >= near, b.z >= near);
        if ina {
            push((a, ba));
        }
        if ina != inb {
            let t = (near - a.z) / (b.z - a.z);
            push((a.lerp(b, t), ba.lerp(bb, t)));
        }
    }
    out
}

/// Twice the signed screen area of a triangle, in f64 (clipped vertices can project far off
/// screen).
#[inline(always)]
pub(crate) fn signed_area(v: &[Vec3; 3]) -> f64 {
    let [a, b, c] = v.map(|p| (p.x as f64, p.y as f64));
    (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0)
}

/// Whether the rasteriser draws a triangle of this [`signed_area`]: not a degenerate or
/// non-finite one. The one test both dropping a triangle early and drawing it use.
#[inline(always)]
pub(crate) fn drawable(area: f64) -> bool {
    (area != 0.0) & area.is_finite()
}

/// How world-space triangles reach the screen: the camera, the image size, the projection's
/// scales and the near clip.
pub(crate) struct Projector<'a> {
    /// The camera.
    pub(crate) cam: &'a Camera,
    /// Image width in pixels.
    pub(crate) width: u32,
    /// Image height in pixels.
    pub(crate) height: u32,
    /// Camera-space x to normalised device coordinates (before the perspective divide).
    pub(crate) sx: f32,
    /// Camera-space y to normalised device coordinates (before the perspective divide).
    pub(crate) sy: f32,
    /// Perspective (else orthographic).
    pub(crate) persp: bool,
    /// The near clip: camera-space z below it is cut away.
    pub(crate) near: f32,
    /// Where in its pixel each sample lies along x and along y.
    pub(crate) fractions: [f32; SAMPLES_1D],
    /// How far a sample lies from its pixel's centre at most ([`sample_reach`]).
    pub(crate) reach: f32,
}

impl<'a> Projector<'a> {
    /// The projection of `cam` onto a `width`×`height` image, clipping perspective views at
    /// `near` (orthographic ones at the camera's own near clip).
    pub(crate) fn new(cam: &'a Camera, (width, height): (u32, u32), near: f32) -> Self {
        let aspect = width as f32 / height as f32;
        let (sx, sy, persp) = match cam.projection {
            Projection::Perspective { yfov } => {
                let t = (yfov * 0.5).tan();
                (1.0 / (t * aspect), 1.0 / t, true)
            }
            Projection::Orthographic { ymag } => (1.0 / (ymag * aspect), 1.0 / ymag, false),
        };
        // Orthographic rays start on the camera plane, so both projections clip (at z = 0 there,
        // or the camera's own near clip).
        let near = if persp { near } else { cam.znear };
        Projector { cam, width, height, sx, sy, persp, near, fractions: sample_fractions(), reach: sample_reach() }
    }

    /// Screen x, y in pixels and the depth key of a camera-space point, and its 1/z weight.
    #[inline(always)]
    pub(crate) fn to_screen(&self, c: Vec3) -> (Vec3, f32) {
        let (nx, ny) =
            if self.persp { (c.x * self.sx / c.z, c.y * self.sy / c.z) } else { (c.x * self.sx, c.y * self.sy) };
        let key = if self.persp { 1.0 / c.z } else { -c.z };
        (Vec3::new((nx + 1.0) * 0.5 * self.width as f32, (1.0 - ny) * 0.5 * self.height as f32, key), self.weight(key))
    }

    /// The perspective-correct interpolation weight of a vertex with depth key `key`: 1/z,
    /// which under perspective is the key itself, and 1 under orthographic projection.
    #[inline(always)]
    pub(crate) fn weight(&self, key: f32) -> f32 {
        if self.persp {
            key
        } else {
            1.0
        }
    }

    /// Scene triangle `i`'s screen triangles: none, one, or two (a clipped quad,
    /// fan-triangulated). Alpha-blended triangles are drawn as opaque, like the path tracer's
    /// first-hit AOVs. With `drop_uncovering`, those that cover no sample are left out.
    pub(crate) fn project(&self, i: usize, t: &rtd_scene::Triangle, drop_uncovering: bool) -> [Option<ScreenTri>; 2] {
        let c = t.p.map(|p| to_camera(self.cam, p));
        let base = [(c[0], Vec3::X), (c[1], Vec3::Y), (c[2], Vec3::Z)];
        if c.iter().all(|v| v.z < self.near) {
            return [None; 2];
        }
        let poly = if c.iter().all(|v| v.z >= self.near) {
            Clipped { v: [base[0], base[1], base[2], base[2]], len: 3 }
        } else {
            clip_near(&base, self.near)
        };
        let proj = poly.v.map(|(c, b)| {
            let (s, w) = self.to_screen(c);
            (s, w, b)
        });
        std::array::from_fn(|k| {
            let k = k + 1;
            if k + 1 >= poly.len {
                return None;
            }
            let tri = [proj[0], proj[k], proj[k + 1]];
            let v = tri.map(|x| x.0);
            if !v.iter().all(|p| p.is_finite()) {
                return None;
            }
            let area = signed_area(&v);
            if drop_uncovering && !self.draws_a_sample(&v, area) {
                return None;
            }
            Some(ScreenTri::new(v, tri.map(|x| x.1), tri.map(|x| x.2.into()), area, (i as u32, t.material)))
        })
    }

    /// Whether a finite screen triangle with vertices `v` (of [`signed_area`] `area`) can draw
    /// a sample: its bounding box holds one, and it is not degenerate. The one test both the
    /// triangle pass and [`Projector::project`] apply.
    #[inline(always)]
    pub(crate) fn draws_a_sample(&self, v: &[Vec3; 3], area: f64) -> bool {
        covers_a_sample(v, self.width, self.height, &self.fractions) & drawable(area)
    }
}

impl ScreenTri {
    /// The screen triangle with vertices `v` (of [`signed_area`] `area`), weights `w` and
    /// original barycentrics `b`, of scene triangle and material `(triangle, material)`.
    #[inline(always)]
    pub(crate) fn new(v: [Vec3; 3], w: [f32; 3], b: [Vec3A; 3], area: f64, (triangle, material): (u32, u32)) -> Self {
        ScreenTri { v, w, b, area, triangle, material }
    }

    /// Screen gradients of the screen-space barycentrics: ∂e0/∂x, ∂e0/∂y, ∂e1/∂x, ∂e1/∂y.
    /// Computed when asked (only textured samples ask), not when the triangle is built: a dense
    /// mesh builds hundreds of thousands of screen triangles and four f64 divisions each.
    #[inline]
    pub(crate) fn grad(&self) -> [f32; 4] {
        // e0 = area(p, b, c) / area(a, b, c) and e1 = area(p, c, a) / area(a, b, c) are affine in
        // screen (x, y); their gradients (in f64: clipped vertices can be far off).
        let [a, b, c] = self.v.map(|p| (p.x as f64, p.y as f64));
        let area = self.area;
        [(b.1 - c.1) / area, (c.0 - b.0) / area, (c.1 - a.1) / area, (a.0 - c.0) / area].map(|g| g as f32)
    }

    /// Perspective-correct barycentrics in the original triangle at screen-space barycentrics
    /// (e0, e1, 1 − e0 − e1).
    #[inline]
    pub(crate) fn bary(&self, e0: f32, e1: f32) -> Vec3 {
        let (w0, w1, w2) = (e0 * self.w[0], e1 * self.w[1], (1.0 - e0 - e1) * self.w[2]);
        // In SIMD lanes (Vec3A): one vector division instead of three, with the same results.
        let b = &self.b;
        ((b[0] * w0 + b[1] * w1 + b[2] * w2) / (w0 + w1 + w2)).into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn near_clipping_keeps_barycentrics() {
        let poly = [
            (Vec3::new(0.0, 0.0, -1.0), Vec3::X),
            (Vec3::new(0.0, 1.0, 1.0), Vec3::Y),
            (Vec3::new(1.0, 0.0, 1.0), Vec3::Z),
        ];
        let out = clip_near(&poly, 0.0);
        assert_eq!(out.len, 4);
        for &(p, b) in &out.v[..out.len] {
            assert!(p.z >= -1e-6);
            let back = poly[0].0 * b.x + poly[1].0 * b.y + poly[2].0 * b.z;
            assert!((back - p).length() < 1e-6, "barycentrics must reproduce the clipped point");
        }
    }
}
