//! Ray queries over the scene's triangles: an obvhs CWBVH with a watertight triangle test.
//!
//! obvhs reorders primitives; `slot_tri` maps a BVH slot back to the scene's triangle index.
//! The triangle test is Woop, Benthin & Wald's watertight algorithm (JCGT 2013), which never
//! lets a ray slip between two triangles sharing an edge. Alpha-masked triangles are tested
//! against their cut-out in the walk's triangle test, so cut-outs also let shadow rays through.
//!
//! Scale: obvhs culls every node whose interval ends before t = 1e-4 (an absolute epsilon), which
//! would drop geometry near the ray origin in small scenes. The BVH is therefore built on
//! vertices scaled by a power of two `k` that brings the scene's coordinates to about 1e4, and
//! rays enter traversal as (k·origin, unit direction, k·t). Power-of-two scaling is exact, so
//! the triangle test still runs on the original world-space vertices and t values.
//!
//! Leaving a surface: the watertight test's t carries a rounding error that grows with the
//! triangle's size, while a ray's offset origin clears the surface by an amount that grows with
//! the point's coordinates. On a large triangle the first can exceed the second, so a ray leaving
//! it could hit it again at t ≈ 0. Rays that leave a surface therefore name the triangle they
//! leave ([`SceneBvh::intersect_leaving`], [`SceneBvh::occluded_leaving`]) and skip it: a ray
//! starting on a flat triangle cannot meet it again. Camera rays pass [`NO_TRIANGLE`].

use std::time::Duration;

use glam::{UVec2, Vec2, Vec3, Vec3A}; // UVec2: named by obvhs::traverse!
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::cwbvh::{builder::build_cwbvh_from_tris, CwBvh};
use obvhs::ray::Ray as BvhRay;
use obvhs::triangle::Triangle as BvhTriangle;
use obvhs::BvhBuildParams;
use rtd_scene::{Aabb, AlphaMode, Scene};

use crate::prefetch::prefetch;

mod bundle;
pub use bundle::MAX_BUNDLE;

/// A triangle index that matches no triangle: rays that leave no surface.
pub const NO_TRIANGLE: u32 = u32::MAX;

/// The closest intersection found by [`SceneBvh::intersect`].
#[derive(Debug, Clone, Copy)]
pub struct Hit {
    /// Index into `Scene::triangles`.
    pub triangle: u32,
    /// Ray parameter of the hit.
    pub t: f32,
    /// Barycentric weights of vertices 0, 1, 2.
    pub bary: Vec3,
}

/// Per-ray constants of the watertight test.
#[derive(Clone, Copy, Default)]
struct RayShear {
    origin: Vec3A,
    kx: usize,
    ky: usize,
    kz: usize,
    s: Vec3,
}

impl RayShear {
    #[inline]
    fn new(origin: Vec3, dir: Vec3) -> Self {
        // Choose the dominant axis as z; swap x and y to keep the winding when it is negative.
        let a = dir.abs();
        let kz = if a.x > a.y {
            if a.x > a.z {
                0
            } else {
                2
            }
        } else if a.y > a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let s = Vec3::new(dir[kx] / dir[kz], dir[ky] / dir[kz], 1.0 / dir[kz]);
        RayShear { origin: origin.into(), kx, ky, kz, s }
    }

    /// Watertight ray/triangle test: (t, barycentrics) or None.
    ///
    /// The sign tests combine their comparisons with `|` and `&`, not `||` and `&&`: on a
    /// ray that misses, which edge fails is unpredictable, and one branch on the combined test
    /// mispredicts less than one per comparison.
    #[inline(always)]
    fn intersect(&self, v: &[Vec3A; 3], tmin: f32, tmax: f32) -> Option<(f32, Vec3)> {
        let (kx, ky, kz, s) = (self.kx, self.ky, self.kz, self.s);
        let a = v[0] - self.origin;
        let b = v[1] - self.origin;
        let c = v[2] - self.origin;
        // Shear and scale the vertices into ray space.
        let (ax, ay) = (a[kx] - s.x * a[kz], a[ky] - s.y * a[kz]);
        let (bx, by) = (b[kx] - s.x * b[kz], b[ky] - s.y * b[kz]);
        let (cx, cy) = (c[kx] - s.x * c[kz], c[ky] - s.y * c[kz]);
        // Scaled barycentrics as 2D edge functions; redo in f64 when one is exactly zero.
        let mut u = cx * by - cy * bx;
        let mut vv = ax * cy - ay * cx;
        let mut w = bx * ay - by * ax;
        if (u == 0.0) | (vv == 0.0) | (w == 0.0) {
            u = (cx as f64 * by as f64 - cy as f64 * bx as f64) as f32;
            vv = (ax as f64 * cy as f64 - ay as f64 * cx as f64) as f32;
            w = (bx as f64 * ay as f64 - by as f64 * ax as f64) as f32;
        }
        if ((u < 0.0) | (vv < 0.0) | (w < 0.0)) & ((u > 0.0) | (vv > 0.0) | (w > 0.0)) {
            return None;
        }
        let det = u + vv + w;
        if det == 0.0 {
            return None;
        }
        let tt = u * (s.z * a[kz]) + vv * (s.z * b[kz]) + w * (s.z * c[kz]);
        let inv = 1.0 / det;
        let t = tt * inv;
        if !((t > tmin) & (t < tmax)) {
            return None;
        }
        Some((t, Vec3::new(u * inv, vv * inv, w * inv)))
    }
}

/// The scene's triangles in a compressed wide BVH, ready for closest-hit and occlusion queries.
pub struct SceneBvh {
    bvh: CwBvh,
    /// Power-of-two scale from world space to BVH space.
    k: f32,
    /// Vertices in BVH slot order.
    verts: Vec<[Vec3A; 3]>,
    /// Scene triangle index of each slot.
    slot_tri: Vec<u32>,
    /// Alpha cut-out data per slot: (cutoff, material) for masked triangles; empty when the
    /// scene has none, as `uvs` is.
    mask: Vec<Option<(f32, u32)>>,
    uvs: Vec<[Vec2; 3]>,
    /// The scene's bounding box ([`Scene::bounds`]), kept from the build.
    bounds: Aabb,
}

impl SceneBvh {
    /// Builds the BVH over all scene triangles (an empty scene gives a BVH that never hits).
    pub fn build(scene: &Scene) -> Self {
        if scene.triangles.is_empty() {
            return SceneBvh {
                bvh: CwBvh::default(),
                k: 1.0,
                verts: vec![],
                slot_tri: vec![],
                mask: vec![],
                uvs: vec![],
                bounds: Aabb::EMPTY,
            };
        }
        let bounds = scene.bounds();
        let max_abs = bounds.min.abs().max(bounds.max.abs()).max_element().max(f32::MIN_POSITIVE);
        let k = (2f32).powi((1e4f32 / max_abs).log2().round().clamp(-100.0, 100.0) as i32);
        let scaled: Vec<BvhTriangle> = scene
            .triangles
            .iter()
            .map(|t| BvhTriangle {
                v0: Vec3A::from(t.p[0]) * k,
                v1: Vec3A::from(t.p[1]) * k,
                v2: Vec3A::from(t.p[2]) * k,
            })
            .collect();
        let bvh = build_cwbvh_from_tris(&scaled, BvhBuildParams::medium_build(), &mut Duration::default());
        drop(scaled);
        let slot_tri: Vec<u32> = bvh.primitive_indices.clone();
        let verts = slot_tri.iter().map(|&i| scene.triangles[i as usize].p.map(Vec3A::from)).collect();
        // Cut-out data only where some material masks: most scenes keep no per-slot copy.
        let masked = |i: u32| {
            let m = scene.triangles[i as usize].material;
            match scene.materials[m as usize].alpha_mode {
                AlphaMode::Mask(cut) => Some((cut, m)),
                _ => None,
            }
        };
        let any_masked = scene.materials.iter().any(|m| matches!(m.alpha_mode, AlphaMode::Mask(_)));
        let (mask, uvs) = if any_masked {
            (
                slot_tri.iter().map(|&i| masked(i)).collect(),
                slot_tri.iter().map(|&i| scene.triangles[i as usize].uv).collect(),
            )
        } else {
            (vec![], vec![])
        };
        SceneBvh { bvh, k, verts, slot_tri, mask, uvs, bounds }
    }

    /// Bytes held on the heap: nodes, slot order, vertices and cut-out data.
    pub fn heap_bytes(&self) -> usize {
        use std::mem::size_of_val;
        size_of_val(self.bvh.nodes.as_slice())
            + size_of_val(self.bvh.primitive_indices.as_slice())
            + self.bvh.exact_node_aabbs.as_ref().map_or(0, |a| size_of_val(a.as_slice()))
            + size_of_val(self.verts.as_slice())
            + size_of_val(self.slot_tri.as_slice())
            + size_of_val(self.mask.as_slice())
            + size_of_val(self.uvs.as_slice())
    }

    /// The bounding box of the scene it was built over, exactly [`Scene::bounds`] (kept from the
    /// build: a dense mesh has hundreds of megabytes of triangles to go over again).
    pub fn scene_bounds(&self) -> Aabb {
        self.bounds
    }

    /// Number of triangles in the BVH.
    pub fn len(&self) -> usize {
        self.slot_tri.len()
    }

    /// True if there are no triangles.
    pub fn is_empty(&self) -> bool {
        self.slot_tri.is_empty()
    }

    /// True if a masked triangle's cut-out removes the surface at barycentrics `b`.
    #[inline]
    fn cut_away(&self, slot: usize, b: Vec3, scene: &Scene) -> bool {
        match self.mask.get(slot).copied().flatten() {
            None => false,
            Some((cutoff, m)) => {
                let uv = self.uvs[slot];
                let p = uv[0] * b.x + uv[1] * b.y + uv[2] * b.z;
                let uv = scene.tex_coords_from(self.slot_tri[slot], p, b);
                scene.materials[m as usize].alpha(&scene.textures, uv) < cutoff
            }
        }
    }

    /// The traversal ray in BVH space, or None for unusable input.
    #[inline]
    fn bvh_ray(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<BvhRay> {
        if self.is_empty() || !origin.is_finite() || !dir.is_finite() || dir == Vec3::ZERO || tmax.is_nan() {
            return None;
        }
        let o = origin * self.k;
        let tmin = if tmin.is_finite() { tmin.max(0.0) } else { 0.0 };
        o.is_finite().then(|| BvhRay::new(o.into(), dir.into(), tmin * self.k, tmax * self.k))
    }

    /// The traversal's test of BVH slot `slot` against ray `r` (scaled by `k`; `inv_k` = 1/k,
    /// hoisted out of the traversal by the caller): its scaled hit distance within the ray's
    /// current interval and its barycentrics, or None for a miss, a cut-out, or the triangle
    /// `from` the ray leaves.
    #[inline(always)]
    fn slot_hit(
        &self,
        scene: &Scene,
        shear: &RayShear,
        r: &BvhRay,
        slot: usize,
        from: u32,
        inv_k: f32,
    ) -> Option<(f32, Vec3)> {
        self.slot_hit_within(scene, shear, r.tmin * inv_k, r.tmax * inv_k, slot, from).map(|(t, b)| (t * self.k, b))
    }

    /// [`SceneBvh::slot_hit`] in world space: the hit distance and barycentrics of slot `slot`
    /// in (tmin, tmax), or None for a miss, a cut-out, or the triangle `from` the ray leaves.
    #[inline(always)]
    fn slot_hit_within(
        &self,
        scene: &Scene,
        shear: &RayShear,
        tmin: f32,
        tmax: f32,
        slot: usize,
        from: u32,
    ) -> Option<(f32, Vec3)> {
        if self.slot_tri[slot] == from {
            return None;
        }
        match shear.intersect(&self.verts[slot], tmin, tmax) {
            Some((t, b)) if !self.cut_away(slot, b, scene) => Some((t, b)),
            _ => None,
        }
    }

    /// The closest hit along `origin + t·dir` for t in (0, tmax), or None.
    /// `dir` should be unit length (t is then a distance); non-finite input never hits.
    #[inline]
    pub fn intersect(&self, scene: &Scene, origin: Vec3, dir: Vec3, tmax: f32) -> Option<Hit> {
        self.intersect_leaving(scene, origin, dir, tmax, NO_TRIANGLE)
    }

    /// [`SceneBvh::intersect`] for a ray that leaves scene triangle `from` (`origin` is a point
    /// on it, offset off it), which is not tested: a ray starting on a flat triangle cannot meet
    /// it again, but rounding in the triangle test can report such a hit at t ≈ 1e-7 when
    /// the triangle is large next to the offset.
    #[inline]
    pub fn intersect_leaving(&self, scene: &Scene, origin: Vec3, dir: Vec3, tmax: f32, from: u32) -> Option<Hit> {
        self.intersect_within(scene, origin, dir, 0.0, tmax, from)
    }

    /// [`SceneBvh::intersect_leaving`] for t in (`tmin`, `tmax`): a camera ray clipped at the
    /// near plane starts at the eye, and ignores what lies before `tmin`.
    #[inline]
    pub fn intersect_within(
        &self,
        scene: &Scene,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
        from: u32,
    ) -> Option<Hit> {
        let ray = self.bvh_ray(origin, dir, tmin, tmax)?;
        let shear = RayShear::new(origin, dir);
        let inv_k = 1.0 / self.k;
        let (mut best, mut bary) = (None, Vec3::ZERO);
        let mut traverse_ray = ray;
        let mut state = self.bvh.new_traversal(ray.direction);
        let mut node;
        obvhs::traverse!(self.bvh, node, state, self.node_hits(node, &traverse_ray, state.oct_inv4), {
            let slot = state.primitive_id as usize;
            match self.slot_hit(scene, &shear, &traverse_ray, slot, from, inv_k) {
                Some((t, b)) if t < traverse_ray.tmax => {
                    best = Some(slot);
                    bary = b;
                    traverse_ray.tmax = t;
                    // The shading that follows reads the scene's copy of the nearest triangle
                    // (normals, texture coordinates, material): start its load now.
                    if let Some(tri) = scene.triangles.get(self.slot_tri[slot] as usize) {
                        prefetch(tri);
                    }
                }
                _ => {}
            }
        });
        best.map(|slot| Hit { triangle: self.slot_tri[slot], t: traverse_ray.tmax * inv_k, bary })
    }

    /// True if anything blocks `origin + t·dir` for t in (0, tmax); `dir` should be unit length.
    #[inline]
    pub fn occluded(&self, scene: &Scene, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        self.occluded_leaving(scene, origin, dir, tmax, NO_TRIANGLE)
    }

    /// [`SceneBvh::occluded`] for a ray that leaves scene triangle `from`, which is not tested
    /// (see [`SceneBvh::intersect_leaving`]).
    #[inline]
    pub fn occluded_leaving(&self, scene: &Scene, origin: Vec3, dir: Vec3, tmax: f32, from: u32) -> bool {
        let Some(ray) = self.bvh_ray(origin, dir, 0.0, tmax) else { return false };
        let shear = RayShear::new(origin, dir);
        let inv_k = 1.0 / self.k;
        let mut blocked = false;
        let mut state = self.bvh.new_traversal(ray.direction);
        let mut node;
        'walk: {
            obvhs::traverse!(self.bvh, node, state, self.node_hits(node, &ray, state.oct_inv4), {
                if self.slot_hit(scene, &shear, &ray, state.primitive_id as usize, from, inv_k).is_some() {
                    blocked = true;
                    break 'walk;
                }
            });
        }
        blocked
    }

    /// The children of `node` that `ray` reaches (obvhs's hit mask: inner nodes in the top 8
    /// bits, leaf triangles in the low 24), with the reached triangles' vertices prefetched:
    /// their tests follow at once, and their loads then overlap instead of waiting in turn.
    #[inline(always)]
    fn node_hits(&self, node: &CwBvhNode, ray: &BvhRay, oct_inv4: u32) -> u32 {
        let hits = node.intersect_ray(ray, oct_inv4);
        for bit in bits(hits & 0x00ff_ffff) {
            if let Some(v) = self.verts.get(node.primitive_base_idx as usize + bit) {
                prefetch(v);
            }
        }
        hits
    }
}

/// Iterates the set bits of `m`, lowest first.
#[inline]
fn bits(mut m: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (m != 0).then(|| {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            i
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtd_scene::Triangle;

    /// A triangle facing +z with material 0.
    pub(super) fn tri(p: [Vec3; 3]) -> Triangle {
        Triangle { p, n: [Vec3::Z; 3], uv: [Vec2::ZERO; 3], material: 0 }
    }

    #[test]
    fn the_kept_bounds_are_the_scenes() {
        let mut s = quad_scene();
        s.push_triangle(tri([Vec3::new(-3.0, 0.5, 2.0), Vec3::new(0.25, -7.0, 1.0), Vec3::new(1.0, 1.0, -4.5)]));
        let bounds = SceneBvh::build(&s).scene_bounds();
        assert_eq!((bounds.min, bounds.max), (Vec3::new(-3.0, -7.0, -4.5), Vec3::new(1.0, 1.0, 2.0)));
        assert_eq!(bounds, s.bounds());
        assert!(SceneBvh::build(&Scene::default()).scene_bounds().is_empty());
    }

    fn quad_scene() -> Scene {
        // Two triangles sharing the diagonal of the unit square in the z=0 plane.
        let mut s = Scene::default();
        s.push_triangle(tri([Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0)]));
        s.push_triangle(tri([Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Y]));
        s.materials.push(Default::default());
        s
    }

    #[test]
    fn shared_edge_is_watertight() {
        let s = quad_scene();
        let bvh = SceneBvh::build(&s);
        // Rays exactly through the shared interior diagonal must hit. (The two ends lie on the
        // mesh's outer boundary and its bounding box face, where a hit is not required.)
        for i in 1..100 {
            let x = i as f32 / 100.0;
            let h = bvh.intersect(&s, Vec3::new(x, x, 1.0), Vec3::new(0.0, 0.0, -1.0), f32::INFINITY);
            assert!(h.is_some(), "leak at {x}");
            let h = h.unwrap();
            assert!((h.t - 1.0).abs() < 1e-6);
            assert!((h.bary.element_sum() - 1.0).abs() < 1e-5);
        }
        assert!(bvh.intersect(&s, Vec3::new(1.5, 0.5, 1.0), Vec3::NEG_Z, f32::INFINITY).is_none());
    }

    #[test]
    fn barycentrics_and_occlusion() {
        let s = quad_scene();
        let bvh = SceneBvh::build(&s);
        let h = bvh.intersect(&s, Vec3::new(0.75, 0.25, 2.0), Vec3::NEG_Z, f32::INFINITY).unwrap();
        assert_eq!(h.triangle, 0);
        assert!((h.t - 2.0).abs() < 1e-6);
        let p = s.triangles[0].p[0] * h.bary.x + s.triangles[0].p[1] * h.bary.y + s.triangles[0].p[2] * h.bary.z;
        assert!((p - Vec3::new(0.75, 0.25, 0.0)).length() < 1e-6);
        assert!(bvh.occluded(&s, Vec3::new(0.5, 0.2, 1.0), Vec3::NEG_Z, 2.0));
        assert!(!bvh.occluded(&s, Vec3::new(0.5, 0.2, 1.0), Vec3::NEG_Z, 0.5));
        assert!(!bvh.occluded(&s, Vec3::new(0.5, 0.2, 1.0), Vec3::new(f32::NAN, 0.0, 0.0), 2.0));
    }

    /// Rays leaving a surface from its offset origin never hit that surface. Tested against the
    /// triangle they leave, rounding in the watertight test reported hits at t ≈ 1e-7 for about
    /// 1.5% of the rays leaving this long, thin shelf top (two triangles of the textured
    /// interior), which darkened its ambient occlusion.
    #[test]
    fn rays_leaving_a_surface_do_not_hit_it() {
        use crate::sampling::{sample_cosine_hemisphere, Frame};
        use crate::surface::{offset_origin, Surface};
        let mut s = Scene::default();
        let (a, b, c, d) = (
            Vec3::new(-0.4, 0.695, 0.1),
            Vec3::new(1.0, 0.695, 0.1),
            Vec3::new(1.0, 0.745, 0.1),
            Vec3::new(-0.4, 0.745, 0.1),
        );
        s.push_triangle(tri([a, b, c]));
        s.push_triangle(tri([a, c, d]));
        // A floor below and a ceiling out of the rays' reach, as in the room: the shelf's
        // quantised BVH box then reaches above the shelf and the rays' triangle tests run. (Alone,
        // the shelf's box is flat and obvhs culls it for rays that leave it at once.)
        let (down, up) = (Vec3::new(0.0, 0.0, -0.1), Vec3::Z);
        s.push_triangle(tri([a + down, b + down, c + down]));
        s.push_triangle(tri([a + up, b + up, c + up]));
        s.materials.push(Default::default());
        let bvh = SceneBvh::build(&s);
        let mut state = 12345u64;
        let mut next = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut hits = 0;
        for _ in 0..2000 {
            let which = (next() * 2.0) as usize % 2;
            let t = &s.triangles[which];
            let (u, v) = (next(), next());
            let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
            let bary = Vec3::new(1.0 - u - v, u, v);
            let p = t.p[0] * bary.x + t.p[1] * bary.y + t.p[2] * bary.z;
            let o = offset_origin(p, Surface::error_bound(t, bary), Vec3::Z, Vec3::Z);
            let frame = Frame::from_normal(Vec3::Z);
            for _ in 0..16 {
                let w = frame.to_world(sample_cosine_hemisphere(Vec2::new(next(), next())));
                hits += bvh.occluded_leaving(&s, o, w, 0.5, which as u32) as u32;
            }
        }
        assert_eq!(hits, 0, "rays hit the surface they leave");
    }

    /// obvhs culls nodes closer than t = 1e-4; after rescaling, a tiny scene keeps its near hits.
    #[test]
    fn tiny_scenes_keep_nearby_geometry() {
        let mut s = Scene::default();
        let e = 1e-6;
        s.push_triangle(tri([Vec3::ZERO, Vec3::X * e, Vec3::Y * e]));
        s.materials.push(Default::default());
        let bvh = SceneBvh::build(&s);
        let h = bvh.intersect(&s, Vec3::new(0.2 * e, 0.2 * e, 0.5 * e), Vec3::NEG_Z, f32::INFINITY);
        assert!((h.expect("near hit culled").t - 0.5 * e).abs() < 1e-12);
        assert!(bvh.occluded(&s, Vec3::new(0.2 * e, 0.2 * e, 0.5 * e), Vec3::NEG_Z, 1.0));
    }
}
