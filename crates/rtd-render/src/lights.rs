//! Every light in the scene as one closed set, chosen in proportion to its power.
//!
//! Emissive triangles are sampled uniformly by area; point, spot and directional lights are
//! deltas; the environment is sampled uniformly (constant) or by a luminance × sinθ
//! piecewise-constant distribution over the equirectangular map.

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

use rtd_scene::{EnvMap, Environment, Light, Scene};

use crate::sampling::{sample_triangle, sample_uniform_sphere, Distribution1D};
use rtd_image::luminance;

/// One light of the closed set.
#[derive(Debug, Clone, Copy)]
pub enum LightSource {
    /// An emissive triangle (index into `Scene::triangles`).
    Triangle(u32),
    /// A punctual light from the scene.
    Punctual(Light),
    /// The environment.
    Environment,
}

/// A light sample as seen from a shading point.
#[derive(Debug, Clone, Copy)]
pub struct LightSample {
    /// Unit direction from the shading point towards the light.
    pub wi: Vec3,
    /// Incident radiance (or, for delta lights, irradiance-like intensity at the point).
    pub li: Vec3,
    /// Solid-angle pdf including the selection probability; for delta lights, the selection probability.
    pub pdf: f32,
    /// The sampled point on the light, or None for lights at infinity.
    pub point: Option<Vec3>,
    /// True for point, spot and directional lights.
    pub delta: bool,
}

/// Importance-sampling data for an environment map.
#[derive(Debug, Clone)]
struct EnvDistribution {
    rows: Vec<Distribution1D>,
    marginal: Distribution1D,
}

/// The scene's lights with a power-proportional selection distribution.
#[derive(Debug, Clone)]
pub struct LightSet {
    lights: Vec<LightSource>,
    select: Distribution1D,
    /// Light index of each triangle, or u32::MAX for non-emitters.
    tri_light: Vec<u32>,
    env_index: Option<u32>,
    env_dist: Option<EnvDistribution>,
}

/// Emitted radiance of triangle `tri` at barycentrics `b`.
#[inline]
pub fn triangle_emission(scene: &Scene, tri: u32, b: Vec3) -> Vec3 {
    let m = &scene.materials[scene.triangles[tri as usize].material as usize];
    let mut e = m.emissive;
    if let Some(tex) = &m.emissive_texture {
        e *= tex.sample(&scene.textures, scene.tex_coords(tri, b)).truncate();
    }
    e.max(Vec3::ZERO)
}

impl LightSet {
    /// Collects the lights of `scene` (including its environment unless black).
    pub fn new(scene: &Scene) -> Self {
        let bounds = scene.bounds();
        let scene_radius = if bounds.is_empty() { 1.0 } else { (bounds.diagonal().length() * 0.5).max(1e-6) };
        let mut lights = Vec::new();
        let mut power = Vec::new();
        let mut tri_light = vec![u32::MAX; scene.triangles.len()];
        for (i, t) in scene.triangles.iter().enumerate() {
            let m = &scene.materials[t.material as usize];
            if !m.is_emissive() {
                continue;
            }
            let mean = match &m.emissive_texture {
                Some(tex) => m.emissive * scene.textures[tex.texture as usize].mean().truncate(),
                None => m.emissive,
            };
            // Φ = π · L · A per emitting side.
            let sides = if m.double_sided { 2.0 } else { 1.0 };
            let p = luminance(mean) * t.area() * PI * sides;
            if p > 0.0 && p.is_finite() {
                tri_light[i] = lights.len() as u32;
                lights.push(LightSource::Triangle(i as u32));
                power.push(p);
            }
        }
        for l in &scene.lights {
            let p = match *l {
                Light::Point { intensity, .. } => 4.0 * PI * luminance(intensity),
                // The cone's solid angle with the edge counted at half strength.
                Light::Spot { intensity, cos_outer, smooth, .. } => {
                    2.0 * PI * luminance(intensity) * (1.0 - cos_outer - 0.5 * smooth)
                }
                Light::Directional { irradiance, .. } => PI * scene_radius * scene_radius * luminance(irradiance),
            };
            if p > 0.0 && p.is_finite() {
                lights.push(LightSource::Punctual(*l));
                power.push(p);
            }
        }
        let mut env_index = None;
        let mut env_dist = None;
        if !scene.environment.is_black() {
            let mean = match &scene.environment {
                Environment::Constant(c) => luminance(*c),
                Environment::Map(map) => {
                    let d = build_env_distribution(&map.image);
                    // Mean radiance over the sphere: ∫ L sinθ dθ dφ / 4π = integral · 2π² / 4π.
                    let m = d.marginal.integral * PI * 0.5;
                    env_dist = Some(d);
                    m
                }
            };
            let p = 4.0 * PI * PI * scene_radius * scene_radius * mean;
            if p > 0.0 && p.is_finite() {
                env_index = Some(lights.len() as u32);
                lights.push(LightSource::Environment);
                power.push(p);
            }
        }
        LightSet { select: Distribution1D::new(&power), lights, tri_light, env_index, env_dist }
    }

    /// Number of lights.
    pub fn len(&self) -> usize {
        self.lights.len()
    }

    /// True if the scene has no light at all.
    pub fn is_empty(&self) -> bool {
        self.lights.is_empty()
    }

    /// Selection probability of the light on triangle `tri` (0 if it is not a light).
    #[inline]
    pub fn triangle_pmf(&self, tri: u32) -> f32 {
        match self.tri_light.get(tri as usize) {
            Some(&i) if i != u32::MAX => self.select.pmf(i as usize),
            _ => 0.0,
        }
    }

    /// True if the environment emits (it is then one of the lights).
    pub fn has_environment(&self) -> bool {
        self.env_index.is_some()
    }

    /// Solid-angle pdf (with selection) that light sampling picks direction `dir` towards the environment.
    #[inline]
    pub fn environment_pdf(&self, env: &Environment, dir: Vec3) -> f32 {
        let Some(i) = self.env_index else { return 0.0 };
        let sel = self.select.pmf(i as usize);
        match (env, &self.env_dist) {
            (Environment::Map(map), Some(d)) => sel * env_map_pdf(d, map, dir),
            _ => sel / (4.0 * PI),
        }
    }

    /// Samples a light and a point on it as seen from `p`.
    pub fn sample(&self, scene: &Scene, p: Vec3, u_select: f32, u: Vec2) -> Option<LightSample> {
        if self.lights.is_empty() {
            return None;
        }
        let (i, sel, _) = self.select.sample_discrete(u_select);
        if sel <= 0.0 {
            return None;
        }
        match self.lights[i] {
            LightSource::Triangle(tri) => {
                let t = &scene.triangles[tri as usize];
                let b = sample_triangle(u);
                let q = t.p[0] * b.x + t.p[1] * b.y + t.p[2] * b.z;
                let area = t.area();
                let n = t.front_normal();
                let d = q - p;
                let dist2 = d.length_squared();
                if !(dist2 > 0.0) {
                    return None;
                }
                let wi = d / dist2.sqrt();
                let cos_l = -wi.dot(n);
                let m = &scene.materials[t.material as usize];
                if cos_l == 0.0 || (cos_l < 0.0 && !m.double_sided) {
                    return None;
                }
                // Area to solid angle: pdf_ω = d² / (|cos_l| · A).
                let pdf = sel * dist2 / (cos_l.abs() * area);
                Some(LightSample { wi, li: triangle_emission(scene, tri, b), pdf, point: Some(q), delta: false })
            }
            LightSource::Punctual(l) => Some(sample_punctual(&l, p, sel)),
            LightSource::Environment => {
                let (wi, pdf_dir) = match (&scene.environment, &self.env_dist) {
                    (Environment::Map(map), Some(d)) => sample_env_map(d, map, u)?,
                    _ => (sample_uniform_sphere(u), 1.0 / (4.0 * PI)),
                };
                let li = scene.environment.radiance(wi);
                Some(LightSample { wi, li, pdf: sel * pdf_dir, point: None, delta: false })
            }
        }
    }
}

/// Samples a delta light from `p`.
fn sample_punctual(l: &Light, p: Vec3, sel: f32) -> LightSample {
    match *l {
        Light::Point { position, intensity } => {
            let d = position - p;
            let dist2 = d.length_squared().max(f32::MIN_POSITIVE);
            LightSample { wi: d / dist2.sqrt(), li: intensity / dist2, pdf: sel, point: Some(position), delta: true }
        }
        Light::Spot { position, direction, intensity, .. } => {
            let d = position - p;
            let dist2 = d.length_squared().max(f32::MIN_POSITIVE);
            let wi = d / dist2.sqrt();
            let a = l.cone_falloff(direction.dot(-wi));
            LightSample { wi, li: intensity * a / dist2, pdf: sel, point: Some(position), delta: true }
        }
        Light::Directional { direction, irradiance } => {
            LightSample { wi: -direction, li: irradiance, pdf: sel, point: None, delta: true }
        }
    }
}

/// Row and column distributions over an equirect map, weighted by luminance × sinθ. A texel's
/// weight is the largest luminance of it and its 8 neighbours (wrapping in u, clamped at the
/// poles), so every direction bilinear lookup lights has a non-zero pdf.
fn build_env_distribution(img: &rtd_image::HdrImage) -> EnvDistribution {
    let (w, h) = (img.width as usize, img.height as usize);
    let lum: Vec<f32> = img.pixels.iter().map(|&p| luminance(p)).collect();
    let rows: Vec<Distribution1D> = (0..h)
        .map(|y| {
            let sin_theta = (PI * (y as f32 + 0.5) / h as f32).sin();
            let near = |x: usize| {
                let mut m = 0.0f32;
                for yy in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                    for xx in [(x + w - 1) % w, x, (x + 1) % w] {
                        m = m.max(lum[yy * w + xx]);
                    }
                }
                m
            };
            let weights: Vec<f32> = (0..w).map(|x| near(x) * sin_theta).collect();
            Distribution1D::new(&weights)
        })
        .collect();
    let marginal = Distribution1D::new(&rows.iter().map(|r| r.integral).collect::<Vec<_>>());
    EnvDistribution { rows, marginal }
}

/// Samples a direction from the map distribution: (direction, solid-angle pdf).
fn sample_env_map(d: &EnvDistribution, map: &EnvMap, u: Vec2) -> Option<(Vec3, f32)> {
    if d.marginal.integral <= 0.0 {
        return None;
    }
    let (v, pdf_v, row) = d.marginal.sample_continuous(u.y);
    let (uu, pdf_u, _) = d.rows[row].sample_continuous(u.x);
    let dir = map.dir(Vec2::new(uu, v));
    let sin_theta = (v * PI).sin();
    if sin_theta <= 0.0 {
        return None;
    }
    // Jacobian of the equirect mapping: dω = 2π² sinθ du dv.
    Some((dir, pdf_u * pdf_v / (2.0 * PI * PI * sin_theta)))
}

/// Solid-angle pdf of [`sample_env_map`] for direction `dir`.
fn env_map_pdf(d: &EnvDistribution, map: &EnvMap, dir: Vec3) -> f32 {
    if d.marginal.integral <= 0.0 {
        return 0.0;
    }
    let (w, h) = (map.image.width, map.image.height);
    let uv = map.uv(dir);
    let x = ((uv.x * w as f32) as i64).rem_euclid(w as i64) as usize;
    let y = ((uv.y * h as f32) as usize).min(h as usize - 1);
    let sin_theta = (uv.y * PI).sin();
    if sin_theta <= 0.0 {
        return 0.0;
    }
    let row = &d.rows[y];
    if row.integral <= 0.0 {
        return 0.0;
    }
    let pdf_v = d.marginal.func[y] / d.marginal.integral;
    let pdf_u = row.func[x] / row.integral;
    pdf_u * pdf_v / (2.0 * PI * PI * sin_theta)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtd_image::HdrImage;

    #[test]
    fn env_map_pdf_matches_sampling_and_integrates_to_one() {
        let mut img = HdrImage::new(16, 8);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            *p = Vec3::splat(1.0 + (i % 7) as f32 * 3.0);
        }
        let d = build_env_distribution(&img);
        let map = EnvMap { image: img, rotation: 1.3 };
        let mut sum_inv = 0.0f64;
        let n = 20000;
        for i in 0..n {
            let mut s = crate::Sampler::new(1, 0, i);
            let (dir, pdf) = sample_env_map(&d, &map, s.get_2d()).unwrap();
            let uv = map.uv(dir) * Vec2::new(16.0, 8.0);
            let near_edge = |x: f32| (x - x.round()).abs() < 1e-3;
            if !near_edge(uv.x) && !near_edge(uv.y) {
                let p2 = env_map_pdf(&d, &map, dir);
                assert!((pdf - p2).abs() <= 1e-3 * pdf, "{pdf} vs {p2} at {uv}");
            }
            sum_inv += 1.0 / pdf as f64;
        }
        // E[1/pdf] = total solid angle 4π.
        let est = sum_inv / n as f64;
        assert!((est - 4.0 * std::f64::consts::PI).abs() < 0.05 * 4.0 * std::f64::consts::PI, "{est}");
    }
}
