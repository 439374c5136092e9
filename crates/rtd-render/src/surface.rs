//! The local geometry and material at a ray hit, and robust spawning of new rays from it.

use glam::{Vec2, Vec3};
use rtd_scene::{Scene, SurfaceParams, TexCoords};

use crate::bvh::Hit;

/// γ(n) = n·ε/(1 − n·ε), the floating-point error bound factor (pbrt §6.8).
const GAMMA7: f32 = 7.0 * (f32::EPSILON * 0.5) / (1.0 - 7.0 * (f32::EPSILON * 0.5));

/// A surface point found by a ray.
#[derive(Debug, Clone, Copy)]
pub struct Surface {
    /// Hit position, from barycentrics (not from o + t·d, which loses precision far away).
    pub p: Vec3,
    /// Conservative absolute error bound of `p` per axis.
    pub p_error: Vec3,
    /// Unit geometric normal on the front side.
    pub ng: Vec3,
    /// Unit shading normal (interpolated, normal-mapped), on the same side as `ng`.
    pub ns: Vec3,
    /// Texture coordinates (both sets).
    pub uv: TexCoords,
    /// Scene triangle index.
    pub triangle: u32,
    /// The material evaluated here.
    pub params: SurfaceParams,
}

impl Surface {
    /// Builds the surface record for a hit.
    pub fn new(scene: &Scene, hit: &Hit) -> Self {
        let t = &scene.triangles[hit.triangle as usize];
        let b = hit.bary;
        let p = t.p[0] * b.x + t.p[1] * b.y + t.p[2] * b.z;
        let p_error = Self::error_bound(t, b);
        let ng = t.front_normal();
        let uv = scene.tex_coords(hit.triangle, b);
        let material = &scene.materials[t.material as usize];
        let mut params = material.evaluate(&scene.textures, uv);
        params.base_color *= scene.vertex_color(hit.triangle, b);
        let normal_map = params.tangent_normal.map(|value| NormalMap {
            value,
            uv: scene.uv_set(hit.triangle, material.normal_tex_coord()),
            tangents: scene.tangents(hit.triangle),
        });
        let ns = shading_normal(t, b, ng, normal_map);
        Surface { p, p_error, ng, ns, uv, triangle: hit.triangle, params }
    }

    /// The point's rounding-error bound for a hit at barycentrics `b` of triangle `t`.
    #[inline]
    pub fn error_bound(t: &rtd_scene::Triangle, b: Vec3) -> Vec3 {
        ((t.p[0] * b.x).abs() + (t.p[1] * b.y).abs() + (t.p[2] * b.z).abs()) * GAMMA7
    }

    /// A ray origin offset off the surface towards direction `w`, far enough to escape the
    /// hit point's rounding error and no further (pbrt-v4's OffsetRayOrigin).
    #[inline]
    pub fn spawn_origin(&self, w: Vec3) -> Vec3 {
        offset_origin(self.p, self.p_error, self.ng, w)
    }
}

/// A normal-map sample at a surface point.
#[derive(Debug, Clone, Copy)]
pub struct NormalMap {
    /// The tangent-space normal read from the map.
    pub value: Vec3,
    /// The triangle's texture coordinates in the set the map reads; a tangent frame derived
    /// from the UV parameterisation (no `TANGENT` in the file) follows this set.
    pub uv: [Vec2; 3],
    /// The triangle's tangents from the file ([`rtd_scene::Scene::tangents`]); all zero for
    /// none.
    pub tangents: [glam::Vec4; 3],
}

/// The unit shading normal at barycentrics `b`: interpolated vertex normals, perturbed by the
/// normal map `normal_map` if any, on the side of the front normal `ng`.
#[inline]
pub fn shading_normal(t: &rtd_scene::Triangle, b: Vec3, ng: Vec3, normal_map: Option<NormalMap>) -> Vec3 {
    let mut ns = (t.n[0] * b.x + t.n[1] * b.y + t.n[2] * b.z).normalize_or(ng);
    if let Some(map) = normal_map {
        ns = apply_normal_map(t, b, ns, map).unwrap_or(ns);
    }
    if ns.dot(ng) < 0.0 {
        -ns
    } else {
        ns
    }
}

/// Offsets `p` along ±`n` by the error bound projected on the normal, then rounds away from `p`.
#[inline]
pub fn offset_origin(p: Vec3, p_error: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    let d = n.abs().dot(p_error);
    let mut offset = n * d;
    if w.dot(n) < 0.0 {
        offset = -offset;
    }
    let mut po = p + offset;
    for i in 0..3 {
        if offset[i] > 0.0 {
            po[i] = po[i].next_up();
        } else if offset[i] < 0.0 {
            po[i] = po[i].next_down();
        }
    }
    po
}

/// Perturbs the shading normal by a tangent-space normal map sample.
fn apply_normal_map(t: &rtd_scene::Triangle, b: Vec3, ns: Vec3, map: NormalMap) -> Option<Vec3> {
    let (tn, uv, tg) = (map.value, map.uv, map.tangents);
    let tangent4 = tg[0] * b.x + tg[1] * b.y + tg[2] * b.z;
    let (tangent, sign) = if tangent4.truncate().length_squared() > 0.0 {
        (tangent4.truncate(), if tg[0].w < 0.0 { -1.0 } else { 1.0 })
    } else {
        // No tangents in the file: derive dp/du from the UV parameterisation.
        let dp1 = t.p[1] - t.p[0];
        let dp2 = t.p[2] - t.p[0];
        let duv1 = uv[1] - uv[0];
        let duv2 = uv[2] - uv[0];
        let det = duv1.x * duv2.y - duv1.y * duv2.x;
        if det.abs() < 1e-12 {
            return None;
        }
        let dpdu = (dp1 * duv2.y - dp2 * duv1.y) / det;
        let dpdv = (dp2 * duv1.x - dp1 * duv2.x) / det;
        // glTF's V runs down the image, so the bitangent is −dp/dv in its convention.
        let sign = if ns.cross(dpdu).dot(-dpdv) < 0.0 { -1.0 } else { 1.0 };
        (dpdu, sign)
    };
    let tangent = (tangent - ns * ns.dot(tangent)).normalize_or_zero();
    if tangent == Vec3::ZERO {
        return None;
    }
    let bitangent = ns.cross(tangent) * sign;
    let n = (tangent * tn.x + bitangent * tn.y + ns * tn.z).normalize_or_zero();
    (n != Vec3::ZERO && n.is_finite()).then_some(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_derived_tangent_frame_follows_the_normal_maps_uv_set() {
        // A triangle in z = 0 whose set 0 has u along +x; set 1 is rotated so u runs along +y.
        let t = rtd_scene::Triangle {
            p: [Vec3::ZERO, Vec3::X, Vec3::Y],
            n: [Vec3::Z; 3],
            uv: [Vec2::ZERO, Vec2::X, Vec2::Y],
            material: 0,
        };
        let set1 = [Vec2::ZERO, Vec2::Y, Vec2::X];
        // A map value tilted towards +u must tilt the normal towards that set's dp/du.
        let value = Vec3::new(1.0, 0.0, 1.0).normalize();
        let b = Vec3::splat(1.0 / 3.0);
        let tangents = [glam::Vec4::ZERO; 3];
        let n0 = shading_normal(&t, b, Vec3::Z, Some(NormalMap { value, uv: t.uv, tangents }));
        let n1 = shading_normal(&t, b, Vec3::Z, Some(NormalMap { value, uv: set1, tangents }));
        assert!(n0.abs_diff_eq(value, 1e-5), "{n0}");
        assert!(n1.abs_diff_eq(Vec3::new(0.0, value.x, value.z), 1e-5), "{n1}");
    }

    #[test]
    fn offset_escapes_rounding_at_any_scale() {
        for &s in &[1e-3f32, 1.0, 1e3, 1e5] {
            let p = Vec3::new(0.3, 0.7, 0.1) * s + Vec3::splat(s);
            let err = p.abs() * GAMMA7;
            let n = Vec3::new(0.0, 0.0, 1.0);
            let up = offset_origin(p, err, n, n);
            let down = offset_origin(p, err, n, -n);
            assert!(up.z > p.z && down.z < p.z);
            // The offset is a few ulps, not a scene-sized jump.
            assert!((up.z - p.z) < p.z.abs() * 1e-5);
        }
    }
}
