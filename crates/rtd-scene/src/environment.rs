use std::path::Path;

use glam::{Vec2, Vec3};
use rtd_image::HdrImage;

use crate::SceneError;

/// Light arriving from infinitely far away, seen by rays that leave the scene.
#[derive(Debug, Clone, PartialEq)]
pub enum Environment {
    /// The same radiance from every direction (black by default).
    Constant(Vec3),
    /// An equirectangular (latitude-longitude) HDR map.
    Map(EnvMap),
}

/// An equirectangular HDR map, turned about the up axis. +Y is up; unturned, the image's
/// centre column looks down −Z and u grows towards +X (the convention of Blender and most HDRI
/// sites). Radiance is interpolated bilinearly between texel centres.
#[derive(Debug, Clone, PartialEq)]
pub struct EnvMap {
    /// The map, non-negative and finite.
    pub image: HdrImage,
    /// Turn about +Y in radians, counter-clockwise seen from above (Blender's Z rotation in a
    /// world Mapping node, Z-up there being +Y here).
    pub rotation: f32,
}

impl Default for Environment {
    fn default() -> Self {
        Environment::Constant(Vec3::ZERO)
    }
}

/// `--env`, `--env-strength` and `--env-rotation` as given: what [`Environment::load`] builds.
#[derive(Debug, Clone, PartialEq)]
pub struct EnvironmentChoice {
    /// `R,G,B` (or one number) radiance, or the path of an `.exr`, `.hdr`, `.pfm` or `.phm` map.
    pub source: String,
    /// Radiance multiplier (≥ 0).
    pub strength: f32,
    /// Turn of a map about the up axis, in degrees.
    pub rotation_deg: f32,
}

impl EnvironmentChoice {
    /// `source` at strength 1, unturned.
    pub fn new(source: impl Into<String>) -> Self {
        EnvironmentChoice { source: source.into(), strength: 1.0, rotation_deg: 0.0 }
    }
    /// Sets the strength.
    pub fn strength(mut self, strength: f32) -> Self {
        self.strength = strength;
        self
    }
    /// Sets the turn about the up axis, in degrees.
    pub fn rotation_deg(mut self, degrees: f32) -> Self {
        self.rotation_deg = degrees;
        self
    }
}

impl Environment {
    /// Parses the `--env` argument at strength 1, unturned ([`Environment::load`]).
    pub fn parse(arg: &str) -> Result<Self, SceneError> {
        Self::load(&EnvironmentChoice::new(arg))
    }

    /// Builds the environment `choice` asks for: a constant colour, or a map read from an
    /// `.exr` (its beauty, under rtd's or another renderer's name), a Radiance `.hdr`, or a
    /// `.pfm`/`.phm`; scaled by the strength, a map turned by the rotation. NaN, infinite and
    /// negative texels become 0.
    pub fn load(choice: &EnvironmentChoice) -> Result<Self, SceneError> {
        let arg = choice.source.as_str();
        let (strength, degrees) = (choice.strength, choice.rotation_deg);
        if !(strength.is_finite() && strength >= 0.0) {
            return Err(SceneError::new(Path::new(arg), format!("--env-strength {strength} is not finite and ≥ 0")));
        }
        if !degrees.is_finite() {
            return Err(SceneError::new(Path::new(arg), "--env-rotation must be a finite number of degrees"));
        }
        let parts: Vec<&str> = arg.split(',').map(str::trim).collect();
        let nums: Option<Vec<f32>> = parts.iter().map(|p| p.parse::<f32>().ok()).collect();
        if let Some(n) = nums {
            let v = match n.as_slice() {
                [g] => Vec3::splat(*g),
                [r, g, b] => Vec3::new(*r, *g, *b),
                _ => return Err(SceneError::new(Path::new(arg), "--env takes R,G,B or a map's path")),
            };
            if !v.is_finite() || v.min_element() < 0.0 {
                return Err(SceneError::new(Path::new(arg), "environment colour must be finite and non-negative"));
            }
            return Ok(Environment::Constant(v * strength));
        }
        let path = Path::new(arg);
        let mut image = read_map(path)?;
        for p in &mut image.pixels {
            *p = if p.is_finite() { (p.max(Vec3::ZERO) * strength).min(Vec3::splat(f32::MAX)) } else { Vec3::ZERO };
        }
        Ok(Environment::Map(EnvMap { image, rotation: degrees.to_radians().rem_euclid(std::f32::consts::TAU) }))
    }

    /// Equirectangular coordinates in [0,1]² of a unit direction, for an unturned map.
    #[inline]
    pub fn dir_to_uv(d: Vec3) -> Vec2 {
        let u = 0.5 + d.x.atan2(-d.z) * (0.5 * std::f32::consts::FRAC_1_PI);
        // atan2 keeps full precision near the poles, where acos(y) does not.
        let v = (d.x * d.x + d.z * d.z).sqrt().atan2(d.y) * std::f32::consts::FRAC_1_PI;
        Vec2::new(u, v)
    }

    /// The unit direction of equirectangular coordinates `uv`, for an unturned map.
    #[inline]
    pub fn uv_to_dir(uv: Vec2) -> Vec3 {
        let phi = (uv.x - 0.5) * std::f32::consts::TAU;
        let theta = uv.y * std::f32::consts::PI;
        let (st, ct) = theta.sin_cos();
        let (sp, cp) = phi.sin_cos();
        Vec3::new(st * sp, ct, -st * cp)
    }

    /// Radiance arriving along direction `-d` (i.e. seen looking along unit `d`).
    #[inline]
    pub fn radiance(&self, d: Vec3) -> Vec3 {
        match self {
            Environment::Constant(c) => *c,
            Environment::Map(map) => map.radiance(d),
        }
    }

    /// True if no light comes from the environment.
    pub fn is_black(&self) -> bool {
        match self {
            Environment::Constant(c) => c.max_element() <= 0.0,
            Environment::Map(map) => map.image.pixels.iter().all(|p| p.max_element() <= 0.0),
        }
    }
}

impl EnvMap {
    /// An unturned map.
    pub fn new(image: HdrImage) -> Self {
        EnvMap { image, rotation: 0.0 }
    }

    /// The map's coordinates of world direction `d`: the direction turned back by the rotation.
    #[inline]
    pub fn uv(&self, d: Vec3) -> Vec2 {
        Environment::dir_to_uv(turn(d, -self.rotation))
    }

    /// The world direction of map coordinates `uv`.
    #[inline]
    pub fn dir(&self, uv: Vec2) -> Vec3 {
        turn(Environment::uv_to_dir(uv), self.rotation)
    }

    /// Bilinearly interpolated radiance seen looking along unit `d`: texel centres at
    /// ((x + ½)/w, (y + ½)/h), wrapping around in u and clamped at the poles.
    #[inline]
    pub fn radiance(&self, d: Vec3) -> Vec3 {
        let (w, h) = (self.image.width as i64, self.image.height as i64);
        let uv = self.uv(d);
        let (fx, fy) = (uv.x * w as f32 - 0.5, uv.y * h as f32 - 0.5);
        let (x0, y0) = (fx.floor(), fy.floor());
        let (tx, ty) = (fx - x0, fy - y0);
        let texel = |x: i64, y: i64| self.image.get(x.rem_euclid(w) as u32, y.clamp(0, h - 1) as u32);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let top = texel(x0, y0).lerp(texel(x0 + 1, y0), tx);
        let bottom = texel(x0, y0 + 1).lerp(texel(x0 + 1, y0 + 1), tx);
        top.lerp(bottom, ty)
    }
}

/// `d` turned by `angle` radians about +Y, counter-clockwise seen from above.
#[inline]
fn turn(d: Vec3, angle: f32) -> Vec3 {
    if angle == 0.0 {
        return d;
    }
    let (s, c) = angle.sin_cos();
    // Right-handed rotation about +Y: x' = c·x + s·z, z' = −s·x + c·z.
    Vec3::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z)
}

/// Reads an environment map by its extension: `.exr`, `.hdr`, `.pfm` or `.phm`.
fn read_map(path: &Path) -> Result<HdrImage, SceneError> {
    let image_error = |source| SceneError::Image { path: path.to_path_buf(), source };
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("exr") => {
            let layers = rtd_image::read_exr(path).map_err(image_error)?;
            layers
                .find_image(rtd_image::Layer::Beauty)
                .ok_or_else(|| SceneError::new(path, "EXR has no colour layer (R,G,B or a Combined pass)"))
        }
        Some("hdr") => rtd_image::read_rgbe(path).map_err(image_error),
        Some("pfm") | Some("phm") => rtd_image::read_pfm(path).map_err(image_error),
        _ => Err(SceneError::new(path, "an environment map must be .exr, .hdr, .pfm or .phm")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uv_direction_round_trip() {
        for &d in &[Vec3::X, Vec3::NEG_Z, Vec3::new(0.3, 0.5, 0.8).normalize(), Vec3::new(-0.6, -0.7, 0.2).normalize()]
        {
            let back = Environment::uv_to_dir(Environment::dir_to_uv(d));
            assert!((back - d).length() < 1e-5, "{d} -> {back}");
        }
        assert!((Environment::dir_to_uv(Vec3::NEG_Z) - Vec2::new(0.5, 0.5)).length() < 1e-6);
    }

    #[test]
    fn a_turned_map_shows_at_the_turned_direction_and_interpolates_between_texels() {
        let mut image = HdrImage::new(8, 4);
        for (i, p) in image.pixels.iter_mut().enumerate() {
            *p = Vec3::splat((i * 7 % 11) as f32);
        }
        let flat = EnvMap::new(image.clone());
        let turned = EnvMap { image, rotation: 0.7 };
        for &d in &[Vec3::X, Vec3::new(0.3, 0.5, 0.8).normalize(), Vec3::new(-0.6, -0.7, 0.2).normalize()] {
            let moved = turn(d, 0.7);
            assert!((turned.radiance(moved) - flat.radiance(d)).abs().max_element() < 1e-4);
            assert!((turned.dir(turned.uv(moved)) - moved).length() < 1e-5);
        }
        // Counter-clockwise seen from above: −Z (the map's centre) turns towards −X.
        assert!((turn(Vec3::NEG_Z, std::f32::consts::FRAC_PI_2) - Vec3::NEG_X).length() < 1e-6);
        // At a texel centre the texel itself; halfway between two centres, their mean.
        let centre = |x: f32, y: f32| Environment::uv_to_dir(Vec2::new(x / 8.0, y / 4.0));
        assert!((flat.radiance(centre(2.5, 1.5)) - flat.image.get(2, 1)).abs().max_element() < 1e-3);
        let mid = (flat.image.get(2, 1) + flat.image.get(3, 1)) * 0.5;
        assert!((flat.radiance(centre(3.0, 1.5)) - mid).abs().max_element() < 1e-3);
        // Across the seam u = 0: the last and first columns blend.
        let seam = (flat.image.get(7, 1) + flat.image.get(0, 1)) * 0.5;
        assert!((flat.radiance(centre(0.0, 1.5)) - seam).abs().max_element() < 1e-3);
    }

    #[test]
    fn strength_scales_and_bad_settings_are_refused() {
        let c = Environment::load(&EnvironmentChoice::new("1,0.5,0").strength(2.0)).unwrap();
        assert_eq!(c, Environment::Constant(Vec3::new(2.0, 1.0, 0.0)));
        for bad in [EnvironmentChoice::new("1").strength(-1.0), EnvironmentChoice::new("1").rotation_deg(f32::NAN)] {
            assert!(Environment::load(&bad).is_err());
        }
        let e = Environment::parse("sky.tiff").unwrap_err().to_string();
        assert_eq!(e, "sky.tiff: an environment map must be .exr, .hdr, .pfm or .phm");
    }

    #[test]
    fn parse_constant() {
        assert_eq!(Environment::parse("1,0.5,0").unwrap(), Environment::Constant(Vec3::new(1.0, 0.5, 0.0)));
        assert_eq!(Environment::parse("2").unwrap(), Environment::Constant(Vec3::splat(2.0)));
        assert!(Environment::parse("1,-1,0").is_err());
        let e = Environment::parse("missing.exr").unwrap_err();
        assert!(matches!(e, SceneError::Image { .. }), "{e:?}");
        assert_eq!(e.to_string(), "missing.exr: no such file", "the path is named once");
    }
}
