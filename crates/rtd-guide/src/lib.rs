//! rtd's guide pass: a cheap, noise-free picture of what the scene is made of.
//!
//! [`GuidePass::render`] rasterises the scene through the beauty's camera (same resolution, same
//! tent pixel filter) and shades each sample with the path tracer's own albedo and shading-normal
//! code (textures averaged over the sample's screen footprint, so detail finer than a pixel is
//! averaged as the path tracer's many samples average it), then adds ambient occlusion through
//! the BVH. Its layers are `albedo`, `normal` (world, after normal maps), `depth` (camera-space
//! distance), `ao`, and `guide` = albedo × AO, the "material render with AO" of the seed thesis.

#![warn(missing_docs)]

mod ao;
mod bins;
mod lanes;
mod projection;
pub mod raster;
mod sample_grid;
#[cfg(test)]
mod test_soup;

use std::time::Instant;

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use rtd_image::{HdrImage, Layer, Layers};
use rtd_render::surface::{shading_normal, NormalMap, Surface};
use rtd_render::{RenderError, RenderSettings, SceneBvh, Workers};
use rtd_scene::{Camera, MaterialFootprint, Projection, Scene};

/// Width in pixels of the screen footprint over which each sample averages its textures: about
/// the samples' spacing, so together they cover the pixel filter (0.5 fits the converged albedo
/// of training views better than 0.25, 0.375, 0.75 or 1).
pub const SAMPLE_FOOTPRINT: f32 = 0.5;

pub use ao::{ao_at, pattern, AoPoint, DEFAULT_AO_RAYS};

/// The default AO lattice step: every 4th pixel, or coarser for large images, keeping at least
/// about 135 lattice points across the short side (more than twice the 64 of a 256² guide).
/// The lattice then has the same density per image at every resolution above 540 px, and its
/// interpolation error stays below a 256² guide's (1080p at step 8: mean |AO − per-pixel AO|
/// 0.002–0.006 on the bundled scenes; 256² at step 4: 0.006–0.009).
pub fn default_ao_step(width: u32, height: u32) -> u32 {
    (width.min(height) / 135).max(4)
}

/// Options of the guide pass, builder style: `GuideSettings::new(w, h).ao_rays(64)`.
#[derive(Debug, Clone, PartialEq)]
pub struct GuideSettings {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Occlusion rays per AO evaluation.
    pub ao_rays: u32,
    /// AO radius in scene units; None: 10% of the scene's bounding-box diagonal.
    pub ao_radius: Option<f32>,
    /// AO is evaluated directly every `ao_step` pixels and interpolated in between.
    pub ao_step: u32,
    /// Worker threads (None: rayon's default).
    pub threads: Option<usize>,
}

impl GuideSettings {
    /// Defaults for a `width`×`height` guide: [`DEFAULT_AO_RAYS`] AO rays, radius 10% of the
    /// scene, evaluated on a lattice every [`default_ao_step`] pixels.
    pub fn new(width: u32, height: u32) -> Self {
        let ao_step = default_ao_step(width, height);
        GuideSettings { width, height, ao_rays: DEFAULT_AO_RAYS, ao_radius: None, ao_step, threads: None }
    }
    /// Sets the AO ray count.
    pub fn ao_rays(mut self, n: u32) -> Self {
        self.ao_rays = n.max(1);
        self
    }
    /// Sets the AO radius.
    pub fn ao_radius(mut self, r: Option<f32>) -> Self {
        self.ao_radius = r;
        self
    }
    /// Sets the sparse AO step (1 evaluates every pixel).
    pub fn ao_step(mut self, s: u32) -> Self {
        self.ao_step = s.max(1);
        self
    }
    /// Sets the thread count.
    pub fn threads(mut self, t: Option<usize>) -> Self {
        self.threads = t;
        self
    }

    /// Checks the settings, naming the first problem: the size and threads as a render's, then
    /// the AO ray count, radius and step.
    pub fn validate(&self) -> Result<(), GuideError> {
        RenderSettings::new(self.width, self.height).threads(self.threads).validate()?;
        if self.ao_rays == 0 || self.ao_rays > MAX_AO_RAYS {
            return Err(GuideError::AoRays(self.ao_rays));
        }
        if let Some(r) = self.ao_radius {
            if !(r > 0.0 && r.is_finite()) {
                return Err(GuideError::AoRadius(r));
            }
        }
        if self.ao_step == 0 {
            return Err(GuideError::AoStep);
        }
        Ok(())
    }
}

/// Most AO rays per pixel the guide pass accepts.
pub const MAX_AO_RAYS: u32 = 4096;

/// Errors from the guide pass's settings.
#[derive(Debug, thiserror::Error)]
pub enum GuideError {
    /// The size or thread count is out of range, as for a render.
    #[error(transparent)]
    Settings(#[from] RenderError),
    /// The AO ray count is 0 or above [`MAX_AO_RAYS`].
    #[error("AO rays {0} are outside 1..={MAX_AO_RAYS}")]
    AoRays(u32),
    /// The AO radius is not a positive finite number.
    #[error("AO radius {0} must be a positive finite number")]
    AoRadius(f32),
    /// The sparse AO step is 0.
    #[error("the AO step must be at least 1")]
    AoStep,
}

/// One pixel's filtered guide values and its centre sample's surface point.
#[derive(Debug, Clone, Copy, Default)]
struct Shaded {
    albedo: Vec3,
    normal: Vec3,
    depth: f32,
    centre: Option<AoPoint>,
}

/// One band of rows of the layers that the rasteriser writes in place.
struct Band<'a> {
    albedo: &'a mut [Vec3],
    normal: &'a mut [Vec3],
    depth: &'a mut [f32],
    centre: &'a mut [Option<AoPoint>],
}

/// Camera-space distance of `p` as the path tracer's depth AOV defines it.
#[inline]
fn camera_depth(camera: &Camera, p: Vec3) -> f32 {
    match camera.projection {
        Projection::Perspective { .. } => (p - camera.position).length(),
        Projection::Orthographic { .. } => (p - camera.position).dot(camera.forward),
    }
}

/// The AO point of a centre sample, looking out of the side the camera sees.
#[inline]
fn ao_point(camera: &Camera, tri: u32, t: &rtd_scene::Triangle, b: Vec3, p: Vec3, ng: Vec3, depth: f32) -> AoPoint {
    let view = match camera.projection {
        Projection::Perspective { .. } => camera.position - p,
        Projection::Orthographic { .. } => -camera.forward,
    };
    let n = if ng.dot(view) < 0.0 { -ng } else { ng };
    AoPoint { p, p_error: Surface::error_bound(t, b), n, depth, triangle: tri }
}

/// True if the material's guide values vary over a triangle with its textures.
#[inline]
fn has_textures(m: &rtd_scene::Material) -> bool {
    m.base_color_texture.is_some() || m.normal_texture.is_some() || m.emissive_texture.is_some()
}

/// The texture filters of a sample's footprint on triangle `tri` with material `m`, from the
/// footprint's barycentric steps `steps` (along screen x and y).
#[inline]
fn texture_footprint(scene: &Scene, tri: u32, m: &rtd_scene::Material, steps: &[Vec3; 2]) -> MaterialFootprint {
    let [du, dv] = scene.tex_coord_steps(tri, steps);
    m.footprint(&scene.textures, du, dv)
}

/// Fast path for the common pixel: every sample on one triangle with flat normals and no normal
/// map. The normal is then constant over the pixel, so one evaluation is exact; so is the
/// albedo unless the material is textured, when each sample still looks its texture up
/// through the footprint filters of the pixel's first sample, as the general path does.
#[inline]
fn shade_one_triangle(
    scene: &Scene,
    camera: &Camera,
    px: &[Option<raster::SampleHit>],
    footprints: &raster::Footprints,
) -> Option<Shaded> {
    let first = px[0]?;
    if px.iter().any(|h| h.is_none_or(|h| h.triangle != first.triangle)) {
        return None;
    }
    let t = &scene.triangles[first.triangle as usize];
    let m = &scene.materials[t.material as usize];
    // Vertex colours vary across the triangle: the general path takes them per sample.
    if m.normal_texture.is_some() || t.n[0] != t.n[1] || t.n[1] != t.n[2] || !scene.vertex_colors.is_empty() {
        return None;
    }
    let ng = t.front_normal();
    let point = |b: Vec3| t.p[0] * b.x + t.p[1] * b.y + t.p[2] * b.z;
    let inv = 1.0 / px.len() as f32;
    let depth = |b: Vec3| camera_depth(camera, point(b));
    // Depth is not affine over a pixel seen at a grazing angle: average it per sample (summed as
    // the general path sums it where the albedo is too).
    let (albedo, depth) = if has_textures(m) {
        let f = if m.base_color_texture.is_some() {
            texture_footprint(scene, first.triangle, m, &footprints.bary_steps(&first, SAMPLE_FOOTPRINT))
        } else {
            MaterialFootprint::POINT
        };
        px.iter().flatten().fold((Vec3::ZERO, 0.0), |(albedo, d), h| {
            let b = h.bary;
            let uv = scene.tex_coords(first.triangle, b);
            (albedo + m.albedo_filtered(&scene.textures, uv, &f) * inv, d + depth(b) * inv)
        })
    } else {
        let d = px.iter().flatten().map(|h| depth(h.bary)).sum::<f32>() / px.len() as f32;
        (m.albedo(&scene.textures, Vec2::ZERO.into()), d)
    };
    let centre = px[raster::SAMPLES / 2]?.bary;
    let p_centre = point(centre);
    Some(Shaded {
        albedo,
        normal: shading_normal(t, first.bary, ng, None),
        depth,
        centre: Some(ao_point(camera, first.triangle, t, centre, p_centre, ng, camera_depth(camera, p_centre))),
    })
}

/// Shades one pixel's samples with the renderer's surface code (through
/// [`shade_one_triangle`] when it applies): albedo, shading normal and depth averaged over all
/// the pixel's samples (a sample that sees nothing adds `miss_albedo` and zero normal and
/// depth), and the centre sample's AO point.
fn shade_pixel(
    scene: &Scene,
    camera: &Camera,
    miss_albedo: Vec3,
    px: &[Option<raster::SampleHit>],
    footprints: &raster::Footprints,
) -> Shaded {
    let n = raster::SAMPLES;
    let inv = 1.0 / n as f32;
    if let Some(fast) = shade_one_triangle(scene, camera, px, footprints) {
        return fast;
    }
    let mut out = Shaded::default();
    // Texture filters of the footprint, computed at a pixel's first sample on each textured
    // triangle and shared by its other samples there (they lie within a pixel, where the
    // perspective derivatives barely change).
    let mut filters: Option<(u32, MaterialFootprint)> = None;
    for (s, hit) in px.iter().enumerate() {
        let Some(hit) = hit else {
            out.albedo += miss_albedo * inv;
            continue;
        };
        let t = &scene.triangles[hit.triangle as usize];
        let b = hit.bary;
        let m = &scene.materials[t.material as usize];
        let p = t.p[0] * b.x + t.p[1] * b.y + t.p[2] * b.z;
        // The geometric normal per sample (not a table over every triangle: a dense mesh
        // has far more triangles than the image has samples).
        let ng = t.front_normal();
        let d = camera_depth(camera, p);
        // Textures are averaged over the sample's footprint, so that 9 samples see a
        // texture finer than a pixel as the path tracer's many samples converge to it.
        let f = if m.base_color_texture.is_some() || m.normal_texture.is_some() {
            match filters {
                Some((tri, f)) if tri == hit.triangle => f,
                _ => {
                    let f = texture_footprint(scene, hit.triangle, m, &footprints.bary_steps(hit, SAMPLE_FOOTPRINT));
                    filters = Some((hit.triangle, f));
                    f
                }
            }
        } else {
            MaterialFootprint::POINT
        };
        let uv = scene.tex_coords(hit.triangle, b);
        let mut albedo = m.albedo_filtered(&scene.textures, uv, &f);
        // COLOR_0 tints the base colour; emitters stay white in the albedo.
        if !m.is_emissive() {
            albedo *= scene.vertex_color(hit.triangle, b);
        }
        let tangent = m.tangent_normal_filtered(&scene.textures, uv, &f);
        out.albedo += albedo * inv;
        let normal_map = tangent.map(|value| NormalMap {
            value,
            uv: scene.uv_set(hit.triangle, m.normal_tex_coord()),
            tangents: scene.tangents(hit.triangle),
        });
        out.normal += shading_normal(t, b, ng, normal_map) * inv;
        out.depth += d * inv;
        if s == n / 2 {
            out.centre = Some(ao_point(camera, hit.triangle, t, b, p, ng, d));
        }
    }
    out
}

/// The guide layers of one view.
#[derive(Debug, Clone, PartialEq)]
pub struct GuidePass {
    /// Base colour × texture (tent-filtered); white where an emitter or an emitting environment
    /// is seen.
    pub albedo: HdrImage,
    /// World-space shading normal (tent-filtered, not renormalised at edges).
    pub normal: HdrImage,
    /// Camera-space distance (0 where nothing is hit).
    pub depth: Vec<f32>,
    /// Ambient occlusion in 0..=1 (1 where nothing is hit).
    pub ao: Vec<f32>,
    /// albedo × AO.
    pub guide: HdrImage,
    /// Seconds the pass took (excluding scene loading and BVH build).
    pub seconds: f64,
}

impl GuidePass {
    /// Renders the guide layers of `scene` through `camera`; `bvh` must be
    /// `SceneBvh::build(scene)` (its rays give the AO, and its bounds the near plane).
    pub fn render(
        scene: &Scene,
        bvh: &SceneBvh,
        camera: &Camera,
        settings: &GuideSettings,
    ) -> Result<Self, GuideError> {
        settings.validate()?;
        let workers = Workers::new(settings.threads)?;
        Ok(workers.install(|| Self::render_inner(scene, bvh, camera, settings)))
    }

    fn render_inner(scene: &Scene, bvh: &SceneBvh, camera: &Camera, settings: &GuideSettings) -> Self {
        let start = Instant::now();
        let (w, h) = (settings.width, settings.height);
        // A sample that sees nothing sees the environment: white albedo if it emits, like an
        // emitter's (and like the path tracer's albedo AOV).
        let miss_albedo = if scene.environment.is_black() { Vec3::ZERO } else { Vec3::ONE };
        // The layers are written in place, a band of rows at a time.
        let pixels = w as usize * h as usize;
        let (mut albedo, mut normal) = (vec![Vec3::ZERO; pixels], vec![Vec3::ZERO; pixels]);
        let mut depth = vec![0.0f32; pixels];
        // Filled in parallel: 48 bytes a pixel, too much to page in on one thread.
        let mut centre: Vec<Option<AoPoint>> = (0..pixels).into_par_iter().map(|_| None).collect();
        let rows = w as usize * raster::TILE as usize;
        let bands: Vec<Band> = albedo
            .chunks_mut(rows)
            .zip(normal.chunks_mut(rows))
            .zip(depth.chunks_mut(rows))
            .zip(centre.chunks_mut(rows))
            .map(|(((albedo, normal), depth), centre)| Band { albedo, normal, depth, centre })
            .collect();
        let bounds = bvh.scene_bounds();
        raster::rasterize(scene, &bounds, camera, w, h, bands, |band, i, px, footprints| {
            let s = shade_pixel(scene, camera, miss_albedo, px, footprints);
            (band.albedo[i], band.normal[i], band.depth[i], band.centre[i]) = (s.albedo, s.normal, s.depth, s.centre);
        });
        let radius =
            settings.ao_radius.unwrap_or(if bounds.is_empty() { 1.0 } else { 0.1 * bounds.diagonal().length() });
        let dirs = pattern(settings.ao_rays);
        let ao = ao::ao_image(scene, bvh, |i| centre[i], (w, h), &dirs, radius, settings.ao_step);
        let albedo = HdrImage::from_pixels(w, h, albedo);
        let normal = HdrImage::from_pixels(w, h, normal);
        let guide = HdrImage::from_pixels(w, h, albedo.pixels.par_iter().zip(&ao).map(|(a, o)| *a * *o).collect());
        GuidePass { albedo, normal, depth, ao, guide, seconds: start.elapsed().as_secs_f64() }
    }

    /// The EXR channels: `guide.R/G/B`, `albedo.R/G/B`, `normal.X/Y/Z`, `depth.Z`, `ao.Y`.
    pub fn layers(&self) -> Layers {
        let mut l = Layers::new(self.albedo.width, self.albedo.height);
        self.add_to(&mut l);
        l
    }

    /// Adds (or replaces) this pass's channels in `layers`, which must be the same size.
    pub fn add_to(&self, layers: &mut Layers) {
        layers.put_image(Layer::Guide, &self.guide);
        layers.put_image(Layer::Albedo, &self.albedo);
        layers.put_image(Layer::Normal, &self.normal);
        layers.put_plane(Layer::Depth, self.depth.clone());
        layers.put_plane(Layer::Ao, self.ao.clone());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ao_lattice_step_grows_with_the_short_side() {
        assert_eq!(default_ao_step(1, 1), 4);
        assert_eq!(default_ao_step(256, 256), 4);
        assert_eq!(default_ao_step(1920, 1080), 8);
        assert_eq!(default_ao_step(1080, 1920), 8);
        assert_eq!(default_ao_step(3840, 2160), 16);
        // The lattice keeps at least 135 points across the short side.
        for side in [540, 1000, 2160, 16384] {
            assert!(side / default_ao_step(side, side) >= 135, "{side}");
        }
    }
}
