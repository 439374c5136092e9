//! Unidirectional path tracing with next-event estimation and multiple importance sampling.
//!
//! At each non-delta vertex one light is chosen in proportion to power and sampled (NEE), and
//! the BSDF is sampled to continue the path; both estimates of emitted light are combined by
//! the power heuristic. Delta lights and delta lobes take no MIS. Russian roulette starts after
//! three bounces with survival probability min(max β, 0.95).
//!
//! A path that refracts into a closed mesh whose material absorbs (`KHR_materials_volume`)
//! carries that absorption coefficient σ_a until it refracts out through the same material,
//! and each segment it travels inside is weighted by the Beer–Lambert transmittance
//! exp(−σ_a·d). Volumes do not nest: entering a second absorbing mesh replaces the first.

use glam::{Vec2, Vec3};
use rtd_scene::{AlphaMode, Material, Scene};

use crate::bsdf::{Bsdf, BsdfParams};
use crate::bvh::{SceneBvh, NO_TRIANGLE};
use crate::lights::LightSet;
use crate::sampler::Sampler;
use crate::sampling::{power_heuristic, Frame};
use crate::surface::Surface;

/// First-hit auxiliary values of one sample.
#[derive(Debug, Clone, Copy, Default)]
pub struct Aov {
    /// Base colour at the first hit (glass and mirrors: their own reflectance colour; emitters
    /// and an emitting environment: white).
    pub albedo: Vec3,
    /// World-space shading normal at the first hit.
    pub normal: Vec3,
    /// Camera-space distance to the first hit.
    pub depth: f32,
}

/// The result of tracing one camera path.
#[derive(Debug, Clone, Copy)]
pub struct PathResult {
    /// Radiance carried to the camera.
    pub radiance: Vec3,
    /// First-hit AOVs (zero if the camera ray escaped, but for a white albedo where the
    /// environment emits).
    pub aov: Aov,
    /// Rays traced (closest-hit and shadow).
    pub rays: u32,
}

/// Immutable inputs of the integrator.
pub struct Integrator<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Its BVH.
    pub bvh: &'a SceneBvh,
    /// Its lights.
    pub lights: &'a LightSet,
    /// Maximum number of bounces (1 = direct lighting only).
    pub max_depth: u32,
}

impl Integrator<'_> {
    /// Traces one path from `origin` along unit `dir`.
    pub fn trace(&self, origin: Vec3, dir: Vec3, sampler: &mut Sampler) -> PathResult {
        self.trace_clipped(origin, dir, 0.0, sampler)
    }

    /// [`Integrator::trace`] with the first ray seeing nothing nearer than `t_near` (the
    /// camera's near clip).
    pub fn trace_clipped(&self, origin: Vec3, dir: Vec3, t_near: f32, sampler: &mut Sampler) -> PathResult {
        let (scene, bvh) = (self.scene, self.bvh);
        let mut radiance = Vec3::ZERO;
        let mut beta = Vec3::ONE;
        let mut aov = Aov::default();
        let mut rays = 0u32;
        let (mut o, mut d) = (origin, dir);
        let mut prev = PrevVertex { specular: true, pdf: 0.0, p: origin, n: Vec3::ZERO };
        // The triangle the ray leaves (none for the camera ray).
        let mut leaving = NO_TRIANGLE;
        // Absorption coefficient of the medium the path is travelling in (zero: none).
        let mut medium = Vec3::ZERO;
        let mut depth = 0u32;
        loop {
            rays += 1;
            let t_min = if depth == 0 { t_near } else { 0.0 };
            let Some(hit) = bvh.intersect_within(scene, o, d, t_min, f32::INFINITY, leaving) else {
                // A camera ray that escapes sees the environment: a light, white in the albedo
                // AOV as emitters are (see `Material::albedo`), unless the environment is black.
                if depth == 0 && self.lights.has_environment() {
                    aov.albedo = Vec3::ONE;
                }
                radiance += self.escaped(beta, d, &prev);
                break;
            };
            if medium != Vec3::ZERO {
                beta *= transmittance(medium, hit.t);
            }
            let s = Surface::new(scene, &hit);
            let wo = -d;
            let material = &scene.materials[scene.triangles[hit.triangle as usize].material as usize];
            if depth == 0 {
                aov = Aov { albedo: s.params.aov_albedo(), normal: s.ns, depth: (s.p - origin).length() };
            }
            radiance += self.emitted(beta, &s, material, wo, &prev);
            // KHR_materials_unlit: the base colour as it is, seen directly or through delta
            // bounces; it scatters nothing, so it neither receives nor casts light.
            if material.unlit {
                if prev.specular {
                    radiance += beta * s.params.base_color;
                }
                break;
            }
            if depth >= self.max_depth {
                break;
            }
            let frame = Frame::from_normal(s.ns);
            let wo_l = frame.to_local(wo);
            let bsdf = Bsdf::new(bsdf_params(&s, material), wo_l);
            let at = ShadingPoint { surface: &s, frame: &frame, bsdf: &bsdf, wo, wo_l };
            let (direct, shadow_rays) = self.next_event(beta, &at, medium, sampler);
            radiance += direct;
            rays += shadow_rays;

            // Continue the path by sampling the BSDF.
            let u_lobe = sampler.get_1d();
            let u_dir: Vec2 = sampler.get_2d();
            let u_rr = sampler.get_1d();
            let Some(bs) = bsdf.sample(wo_l, u_lobe, u_dir) else {
                break;
            };
            let wi = frame.to_world(bs.wi).normalize_or_zero();
            if wi == Vec3::ZERO || !same_side_agrees(wo, wi, s.ng, wo_l, bs.wi) {
                break;
            }
            // Refracting through an absorbing material enters or leaves its medium.
            if material.absorption != Vec3::ZERO && wo.dot(s.ng) * wi.dot(s.ng) < 0.0 {
                medium = if wi.dot(s.ng) < 0.0 { material.absorption } else { Vec3::ZERO };
            }
            beta *= bs.weight;
            prev = PrevVertex { specular: bs.delta, pdf: bs.pdf, p: s.p, n: s.ng };
            leaving = s.triangle;
            o = s.spawn_origin(wi);
            d = wi;
            depth += 1;
            // Russian roulette after three bounces, survival min(max β, 0.95).
            if depth > 3 {
                let q = beta.max_element().min(0.95);
                if !(u_rr < q) {
                    break;
                }
                beta /= q;
            }
            if beta == Vec3::ZERO || !beta.is_finite() {
                break;
            }
        }
        PathResult { radiance, aov, rays }
    }

    /// Radiance, times the path throughput `beta`, that a ray escaping along `d` brings back
    /// from the environment, MIS-weighted against light sampling at the previous vertex.
    #[inline(always)]
    fn escaped(&self, beta: Vec3, d: Vec3, prev: &PrevVertex) -> Vec3 {
        let le = self.scene.environment.radiance(d);
        if le == Vec3::ZERO {
            return Vec3::ZERO;
        }
        let w = if prev.specular {
            1.0
        } else {
            power_heuristic(prev.pdf, self.lights.environment_pdf(&self.scene.environment, d))
        };
        beta * le * w
    }

    /// Emitted radiance toward `wo`, times the path throughput `beta`, at a surface the path
    /// hits (front side only unless double-sided): unweighted after the camera or a delta
    /// bounce, else MIS-weighted against light sampling at the previous vertex.
    #[inline(always)]
    fn emitted(&self, beta: Vec3, s: &Surface, material: &Material, wo: Vec3, prev: &PrevVertex) -> Vec3 {
        if s.params.emission == Vec3::ZERO || !(material.double_sided || wo.dot(s.ng) > 0.0) {
            return Vec3::ZERO;
        }
        let w = if prev.specular {
            1.0
        } else {
            // Area-to-solid-angle pdf of having sampled this point by light sampling.
            let area = self.scene.triangles[s.triangle as usize].area();
            let dist2 = (s.p - prev.p).length_squared();
            let pmf = self.lights.triangle_pmf(prev.p, prev.n, s.triangle);
            let pdf_light = pmf * dist2 / (wo.dot(s.ng).abs() * area);
            power_heuristic(prev.pdf, pdf_light)
        };
        beta * s.params.emission * w
    }

    /// Next-event estimation at `at`: one light chosen and sampled, its unoccluded contribution
    /// weighted by the power heuristic against BSDF sampling (delta lights unweighted), and a
    /// light point's attenuated by the medium the path is in (a ray to infinity leaves it).
    /// Returns the radiance, times the path throughput `beta`, and the shadow rays traced.
    /// Draws its three numbers whether or not the BSDF can use them, so the sample stream does
    /// not depend on the material.
    #[inline(always)]
    fn next_event(&self, beta: Vec3, at: &ShadingPoint, medium: Vec3, sampler: &mut Sampler) -> (Vec3, u32) {
        let ShadingPoint { surface: s, frame, bsdf, wo, wo_l } = *at;
        let (scene, bvh) = (self.scene, self.bvh);
        let u_select = sampler.get_1d();
        let u_light = sampler.get_2d();
        if !bsdf.has_non_delta() {
            return (Vec3::ZERO, 0);
        }
        let Some(ls) = self.lights.sample(scene, s.p, s.ng, u_select, u_light) else {
            return (Vec3::ZERO, 0);
        };
        let wi_l = frame.to_local(ls.wi);
        if !(ls.pdf > 0.0 && ls.li != Vec3::ZERO && same_side_agrees(wo, ls.wi, s.ng, wo_l, wi_l)) {
            return (Vec3::ZERO, 0);
        }
        let (f, bsdf_pdf) = bsdf.eval(wo_l, wi_l);
        let f = f * wi_l.z.abs();
        if f == Vec3::ZERO {
            return (Vec3::ZERO, 0);
        }
        let from = s.spawn_origin(ls.wi);
        let (blocked, absorbed) = match ls.point {
            // Stop the shadow ray just short of the light point.
            Some(q) => {
                let (dir, dist) = (q - from).normalize_and_length();
                let blocked = bvh.occluded_leaving(scene, from, dir, dist * (1.0 - 1e-4), s.triangle);
                (blocked, transmittance(medium, dist))
            }
            // An unblocked ray to infinity leaves any (open) medium at once.
            None => (bvh.occluded_leaving(scene, from, ls.wi, f32::INFINITY, s.triangle), Vec3::ONE),
        };
        if blocked {
            return (Vec3::ZERO, 1);
        }
        let w = if ls.delta { 1.0 } else { power_heuristic(ls.pdf, bsdf_pdf) };
        (beta * absorbed * f * ls.li * (w / ls.pdf), 1)
    }
}

/// Where a path scatters: the surface point, its shading frame and BSDF, and the direction
/// toward the previous vertex in world (`wo`) and local (`wo_l`) space.
#[derive(Clone, Copy)]
struct ShadingPoint<'a> {
    /// The surface point.
    surface: &'a Surface,
    /// Its shading frame.
    frame: &'a Frame,
    /// Its BSDF, for `wo_l`.
    bsdf: &'a Bsdf,
    /// Toward the previous vertex, world space.
    wo: Vec3,
    /// The same in the shading frame.
    wo_l: Vec3,
}

/// What a path keeps of its previous scattering vertex, for the MIS weight of emitters that
/// BSDF sampling hits.
struct PrevVertex {
    /// The direction came from a delta lobe (or the camera): no MIS.
    specular: bool,
    /// Solid-angle pdf with which the BSDF sampled the direction.
    pdf: f32,
    /// The vertex's position.
    p: Vec3,
    /// The normal light selection weighed the lights by there.
    n: Vec3,
}

/// The BSDF parameters of a surface point of `material` (alpha blending as opacity).
#[inline]
fn bsdf_params(s: &Surface, material: &Material) -> BsdfParams {
    BsdfParams {
        base_color: s.params.base_color,
        metallic: s.params.metallic,
        roughness: s.params.roughness,
        transmission: s.params.transmission,
        ior: s.params.ior,
        specular: s.params.specular,
        specular_color: s.params.specular_color,
        opacity: if material.alpha_mode == AlphaMode::Blend { s.params.alpha } else { 1.0 },
        layers: s.params.layers,
    }
}

/// Beer–Lambert transmittance exp(−σ_a·d) over distance `d` in a medium of absorption `sigma`.
#[inline]
fn transmittance(sigma: Vec3, d: f32) -> Vec3 {
    if sigma == Vec3::ZERO {
        Vec3::ONE
    } else {
        (-sigma * d).exp()
    }
}

/// Rejects directions whose reflection/transmission status differs between the shading frame
/// and the true surface (interpolated normals would otherwise leak light through geometry).
#[inline]
fn same_side_agrees(wo: Vec3, wi: Vec3, ng: Vec3, wo_l: Vec3, wi_l: Vec3) -> bool {
    ((wo.dot(ng) * wi.dot(ng)) > 0.0) == ((wo_l.z * wi_l.z) > 0.0)
}
