use std::path::Path;

use glam::{Vec2, Vec3};
use rtd_image::HdrImage;

use crate::SceneError;

/// Light arriving from infinitely far away, seen by rays that leave the scene.
#[derive(Debug, Clone, PartialEq)]
pub enum Environment {
    /// The same radiance from every direction (black by default).
    Constant(Vec3),
    /// An equirectangular (latitude-longitude) HDR map. +Y is up; the image's centre column
    /// looks down −Z and u grows towards +X (the convention of Blender and most HDRI sites).
    Map(HdrImage),
}

impl Default for Environment {
    fn default() -> Self {
        Environment::Constant(Vec3::ZERO)
    }
}

impl Environment {
    /// Parses the `--env` argument: `R,G,B` (or one number for grey) or a path to an `.exr` map.
    pub fn parse(arg: &str) -> Result<Self, SceneError> {
        let parts: Vec<&str> = arg.split(',').map(str::trim).collect();
        let nums: Option<Vec<f32>> = parts.iter().map(|p| p.parse::<f32>().ok()).collect();
        if let Some(n) = nums {
            let v = match n.as_slice() {
                [g] => Vec3::splat(*g),
                [r, g, b] => Vec3::new(*r, *g, *b),
                _ => return Err(SceneError::new(Path::new(arg), "--env takes R,G,B or an .exr path")),
            };
            if !v.is_finite() || v.min_element() < 0.0 {
                return Err(SceneError::new(Path::new(arg), "environment colour must be finite and non-negative"));
            }
            return Ok(Environment::Constant(v));
        }
        let path = Path::new(arg);
        let image_error = |source| SceneError::Image { path: path.to_path_buf(), source };
        let layers = rtd_image::read_exr(path).map_err(image_error)?;
        let mut img =
            layers.image(rtd_image::Layer::Beauty).ok_or_else(|| SceneError::new(path, "EXR has no R,G,B channels"))?;
        for p in &mut img.pixels {
            *p = if p.is_finite() { p.max(Vec3::ZERO) } else { Vec3::ZERO };
        }
        Ok(Environment::Map(img))
    }

    /// Equirectangular coordinates in [0,1]² of a unit direction.
    #[inline]
    pub fn dir_to_uv(d: Vec3) -> Vec2 {
        let u = 0.5 + d.x.atan2(-d.z) * (0.5 * std::f32::consts::FRAC_1_PI);
        // atan2 keeps full precision near the poles, where acos(y) does not.
        let v = (d.x * d.x + d.z * d.z).sqrt().atan2(d.y) * std::f32::consts::FRAC_1_PI;
        Vec2::new(u, v)
    }

    /// The unit direction of equirectangular coordinates `uv`.
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
            Environment::Map(img) => {
                let uv = Self::dir_to_uv(d);
                let x = ((uv.x * img.width as f32) as i64).rem_euclid(img.width as i64) as u32;
                let y = ((uv.y * img.height as f32) as u32).min(img.height - 1);
                img.get(x, y)
            }
        }
    }

    /// True if no light comes from the environment.
    pub fn is_black(&self) -> bool {
        match self {
            Environment::Constant(c) => c.max_element() <= 0.0,
            Environment::Map(img) => img.pixels.iter().all(|p| p.max_element() <= 0.0),
        }
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
    fn parse_constant() {
        assert_eq!(Environment::parse("1,0.5,0").unwrap(), Environment::Constant(Vec3::new(1.0, 0.5, 0.0)));
        assert_eq!(Environment::parse("2").unwrap(), Environment::Constant(Vec3::splat(2.0)));
        assert!(Environment::parse("1,-1,0").is_err());
        let e = Environment::parse("missing.exr").unwrap_err();
        assert!(matches!(e, SceneError::Image { .. }), "{e:?}");
        assert_eq!(e.to_string(), "missing.exr: no such file", "the path is named once");
    }
}
