//! Every light in the scene as one closed set, and how a shading point picks one.
//!
//! [`LightSelection::Tree`] (the default) walks a light BVH ([`crate::light_tree`]) over the
//! lights with a position (emissive triangles, point and spot lights), by their power,
//! distance and orientation as seen from the point; the lights at infinity (the sun,
//! directional lights, the environment) are chosen by power against the tree's total.
//! [`LightSelection::Power`] picks every light in proportion to its power alone, wherever the
//! point is. Emissive triangles are sampled uniformly by area; point, spot and directional
//! lights are deltas; the environment is sampled uniformly (constant) or by a luminance × sinθ
//! piecewise-constant distribution over the equirectangular map.

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

use rtd_scene::{EnvMap, Environment, Light, Scene};

use crate::light_tree::{LightBounds, LightTree};
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

/// How a shading point picks the light it samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LightSelection {
    /// A light BVH by power, distance and orientation (lights at infinity by power).
    #[default]
    Tree,
    /// In proportion to power alone.
    Power,
}

/// The selection structure of a [`LightSet`].
#[derive(Debug, Clone)]
enum Selector {
    /// One distribution over all lights by power.
    Power(Distribution1D),
    /// The tree over the lights with a position, and a power distribution over those at
    /// infinity, chosen first with probability `p_infinite`.
    Tree {
        tree: LightTree,
        /// The bounded lights by power, the defensive share of the tree's choice.
        by_power: Distribution1D,
        /// Light index of each tree entry.
        bounded: Vec<u32>,
        /// Tree entry of each light (u32::MAX for lights at infinity).
        entry: Vec<u32>,
        /// Light index of each entry of `infinite_select`.
        infinite: Vec<u32>,
        infinite_select: Distribution1D,
        p_infinite: f32,
    },
}

/// The scene's lights and how a shading point selects among them.
#[derive(Debug, Clone)]
pub struct LightSet {
    lights: Vec<LightSource>,
    selector: Selector,
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
    /// Collects the lights of `scene` (including its environment unless black), selected by
    /// the light tree.
    pub fn new(scene: &Scene) -> Self {
        Self::with_selection(scene, LightSelection::Tree)
    }

    /// Collects the lights of `scene`, selected as `selection` says.
    pub fn with_selection(scene: &Scene, selection: LightSelection) -> Self {
        let bounds = scene.bounds();
        let scene_radius = if bounds.is_empty() { 1.0 } else { (bounds.diagonal().length() * 0.5).max(1e-6) };
        let mut lights = Vec::new();
        let mut power = Vec::new();
        // Bounds of each light with a position, for the tree (None: a light at infinity).
        let mut bounds: Vec<Option<LightBounds>> = Vec::new();
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
                bounds.push(Some(LightBounds::triangle(t.p, t.front_normal(), p, m.double_sided)));
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
                bounds.push(match *l {
                    Light::Point { position, .. } => Some(LightBounds::point(position, Vec3::Z, -1.0, p)),
                    Light::Spot { position, direction, cos_outer, .. } => {
                        Some(LightBounds::point(position, direction, cos_outer, p))
                    }
                    Light::Directional { .. } => None,
                });
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
                bounds.push(None);
            }
        }
        let selector = match selection {
            LightSelection::Power => Selector::Power(Distribution1D::new(&power)),
            LightSelection::Tree => tree_selector(&power, &bounds),
        };
        LightSet { selector, lights, tri_light, env_index, env_dist }
    }

    /// The probability that a point at `p` with normal `n` selects light `i`.
    #[inline]
    fn pmf(&self, p: Vec3, n: Vec3, i: u32) -> f32 {
        match &self.selector {
            Selector::Power(d) => d.pmf(i as usize),
            Selector::Tree { tree, by_power, entry, infinite, infinite_select, p_infinite, .. } => {
                match entry[i as usize] {
                    u32::MAX => {
                        let k = infinite.iter().position(|&j| j == i).unwrap_or(0);
                        p_infinite * infinite_select.pmf(k)
                    }
                    e => {
                        let mixed = (1.0 - DEFENSIVE) * tree.pmf(p, n, e) + DEFENSIVE * by_power.pmf(e as usize);
                        (1.0 - p_infinite) * mixed
                    }
                }
            }
        }
    }

    /// Picks a light for a point at `p` with normal `n` with `u` in [0, 1): (light, probability).
    #[inline]
    fn select(&self, p: Vec3, n: Vec3, u: f32) -> Option<(usize, f32)> {
        match &self.selector {
            Selector::Power(d) => {
                let (i, pmf, _) = d.sample_discrete(u);
                Some((i, pmf))
            }
            Selector::Tree { tree, by_power, bounded, infinite, infinite_select, p_infinite, .. } => {
                if u < *p_infinite {
                    let (k, pmf, _) = infinite_select.sample_discrete((u / p_infinite).min(ONE_MINUS_EPSILON));
                    return Some((infinite[k] as usize, p_infinite * pmf));
                }
                let u = ((u - p_infinite) / (1.0 - p_infinite)).min(ONE_MINUS_EPSILON);
                // Either strategy may pick a light: the probability is their mixture (the
                // tree's share known from its walk, or walked for the light power picked).
                let (e, tree_pmf) = if u < DEFENSIVE {
                    let e = by_power.sample_discrete((u / DEFENSIVE).min(ONE_MINUS_EPSILON)).0 as u32;
                    (e, tree.pmf(p, n, e))
                } else {
                    tree.sample(p, n, ((u - DEFENSIVE) / (1.0 - DEFENSIVE)).min(ONE_MINUS_EPSILON))?
                };
                let mixed = (1.0 - DEFENSIVE) * tree_pmf + DEFENSIVE * by_power.pmf(e as usize);
                Some((bounded[e as usize] as usize, (1.0 - p_infinite) * mixed))
            }
        }
    }

    /// Number of lights.
    pub fn len(&self) -> usize {
        self.lights.len()
    }

    /// True if the scene has no light at all.
    pub fn is_empty(&self) -> bool {
        self.lights.is_empty()
    }

    /// Selection probability, at a point `p` with normal `n` (the one [`LightSet::sample`] was
    /// given there), of the light on triangle `tri` (0 if it is not a light).
    #[inline]
    pub fn triangle_pmf(&self, p: Vec3, n: Vec3, tri: u32) -> f32 {
        match self.tri_light.get(tri as usize) {
            Some(&i) if i != u32::MAX => self.pmf(p, n, i),
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
        // Lights at infinity are selected independently of the point.
        let sel = self.pmf(Vec3::ZERO, Vec3::ZERO, i);
        match (env, &self.env_dist) {
            (Environment::Map(map), Some(d)) => sel * env_map_pdf(d, map, dir),
            _ => sel / (4.0 * PI),
        }
    }

    /// Samples a light and a point on it as seen from `p`, a point with normal `n` (zero for
    /// none), which the light tree weighs lights by.
    pub fn sample(&self, scene: &Scene, p: Vec3, n: Vec3, u_select: f32, u: Vec2) -> Option<LightSample> {
        if self.lights.is_empty() {
            return None;
        }
        let (i, sel) = self.select(p, n, u_select)?;
        if !(sel > 0.0) {
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

/// The largest f32 below 1.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// The share of the bounded lights' selection made by power alone beside the tree (defensive
/// importance sampling): the tree's importance is a heuristic that can rate a light far below
/// what it gives a point, and this keeps every light's probability at least this share of its
/// power's, which bounds the noise such a light can add.
const DEFENSIVE: f32 = 0.1;

/// The tree selector over lights of `power`, with `bounds` for those with a position.
fn tree_selector(power: &[f32], bounds: &[Option<LightBounds>]) -> Selector {
    let (mut bounded, mut entry, mut infinite) = (vec![], vec![u32::MAX; power.len()], vec![]);
    let mut tree_bounds = vec![];
    for (i, b) in bounds.iter().enumerate() {
        match b {
            Some(b) => {
                entry[i] = bounded.len() as u32;
                bounded.push(i as u32);
                tree_bounds.push(*b);
            }
            None => infinite.push(i as u32),
        }
    }
    let infinite_power: Vec<f32> = infinite.iter().map(|&i| power[i as usize]).collect();
    let (p_inf, p_tree) = (infinite_power.iter().sum::<f32>(), tree_bounds.iter().map(|b| b.phi).sum::<f32>());
    // The lights at infinity against the tree's total, by power.
    let p_infinite = match (infinite.is_empty(), tree_bounds.is_empty()) {
        (true, _) => 0.0,
        (false, true) => 1.0,
        (false, false) => p_inf / (p_inf + p_tree),
    };
    Selector::Tree {
        by_power: Distribution1D::new(&tree_bounds.iter().map(|b| b.phi).collect::<Vec<_>>()),
        tree: LightTree::new(&tree_bounds),
        bounded,
        entry,
        infinite,
        infinite_select: Distribution1D::new(&infinite_power),
        p_infinite,
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
