use glam::{Mat4, Vec2, Vec3};

use crate::Aabb;

/// A camera's projection. The image aspect ratio always comes from the render resolution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Projection {
    /// Pinhole camera with a vertical field of view in radians.
    Perspective {
        /// Vertical field of view, radians.
        yfov: f32,
    },
    /// Parallel projection; `ymag` is half the view height in world units.
    Orthographic {
        /// Half the view height.
        ymag: f32,
    },
}

/// A camera: position and orientation in world space plus a projection.
/// It looks down its local −Z with +Y up, as glTF defines.
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    /// Name from the file, or a description.
    pub name: String,
    /// Eye position.
    pub position: Vec3,
    /// Unit right vector (local +X).
    pub right: Vec3,
    /// Unit up vector (local +Y).
    pub up: Vec3,
    /// Unit view direction (local −Z).
    pub forward: Vec3,
    /// How view directions map to the film: perspective or orthographic.
    pub projection: Projection,
    /// The width ÷ height the file's camera was made for (glTF `aspectRatio`, or `xmag/ymag`),
    /// which the image size follows unless both sides are given; None when the file says none.
    pub aspect_ratio: Option<f32>,
    /// The near clip distance along the view axis (glTF `znear`): what lies nearer the eye is
    /// not seen. 0: no clip.
    pub znear: f32,
}

impl Camera {
    /// A camera from a world transform (scale and shear are removed by re-orthonormalising).
    pub fn from_matrix(name: impl Into<String>, m: Mat4, projection: Projection) -> Self {
        let position = m.w_axis.truncate();
        let forward = (-m.z_axis.truncate()).normalize_or(Vec3::NEG_Z);
        let up_hint = m.y_axis.truncate();
        Self::oriented(name, position, forward, up_hint, projection)
    }

    /// The same camera made for images of `aspect` = width ÷ height (ignored unless positive and
    /// finite).
    pub fn with_aspect_ratio(mut self, aspect: Option<f32>) -> Self {
        self.aspect_ratio = aspect.filter(|a| *a > 0.0 && a.is_finite());
        self
    }

    /// The same camera with a near clip at `znear` along the view axis (ignored unless positive
    /// and finite).
    pub fn with_znear(mut self, znear: f32) -> Self {
        self.znear = if znear > 0.0 && znear.is_finite() { znear } else { 0.0 };
        self
    }

    /// How far along the primary ray direction `dir` (unit, from [`Camera::ray`]) the near clip
    /// plane lies: primary rays start there.
    #[inline]
    pub fn clip_distance(&self, dir: Vec3) -> f32 {
        match self.projection {
            // The plane z = znear in camera space, met at t·cos θ = znear.
            Projection::Perspective { .. } => self.znear / dir.dot(self.forward).max(1e-6),
            Projection::Orthographic { .. } => self.znear,
        }
    }

    /// A perspective camera at `from` looking at `at`, with +Y as the up hint.
    pub fn look_at(from: Vec3, at: Vec3, yfov_degrees: f32) -> Self {
        let forward = (at - from).normalize_or(Vec3::NEG_Z);
        let projection = Projection::Perspective { yfov: yfov_degrees.to_radians() };
        Self::oriented("look-at", from, forward, Vec3::Y, projection)
    }

    fn oriented(name: impl Into<String>, position: Vec3, forward: Vec3, up_hint: Vec3, projection: Projection) -> Self {
        // Gram–Schmidt: right ⟂ forward, then up ⟂ both; fall back to another hint if parallel.
        let mut right = forward.cross(up_hint);
        if right.length_squared() < 1e-12 {
            right = forward.cross(if forward.y.abs() < 0.9 { Vec3::Y } else { Vec3::Z });
        }
        let right = right.normalize();
        let up = right.cross(forward).normalize();
        Camera { name: name.into(), position, right, up, forward, projection, aspect_ratio: None, znear: 0.0 }
    }

    /// A perspective camera that frames `bounds` from the front, slightly above.
    pub fn framing(bounds: &Aabb) -> Self {
        let center = bounds.center();
        let radius = (bounds.diagonal().length() * 0.5).max(1e-6);
        let yfov = 40f32.to_radians();
        let dist = radius / (yfov * 0.5).sin() * 1.05;
        let from = center + Vec3::new(0.0, 0.35, 1.0).normalize() * dist;
        let mut cam = Self::look_at(from, center, 40.0);
        cam.name = "automatic".into();
        cam
    }

    /// The primary ray through film position `film` (pixels, origin top-left, may be fractional)
    /// on a `width`×`height` image: returns (origin, unit direction).
    #[inline]
    pub fn ray(&self, film: Vec2, width: u32, height: u32) -> (Vec3, Vec3) {
        let aspect = width as f32 / height as f32;
        // NDC in [-1,1], +y up.
        let nx = 2.0 * film.x / width as f32 - 1.0;
        let ny = 1.0 - 2.0 * film.y / height as f32;
        match self.projection {
            Projection::Perspective { yfov } => {
                let t = (yfov * 0.5).tan();
                let d = self.forward + self.right * (nx * t * aspect) + self.up * (ny * t);
                (self.position, d.normalize())
            }
            Projection::Orthographic { ymag } => {
                let o = self.position + self.right * (nx * ymag * aspect) + self.up * (ny * ymag);
                (o, self.forward)
            }
        }
    }

    /// Projects a world point to film coordinates (pixels) and its camera-space distance.
    /// Returns `None` for points behind a perspective camera.
    pub fn project(&self, p: Vec3, width: u32, height: u32) -> Option<(Vec2, f32)> {
        let aspect = width as f32 / height as f32;
        let d = p - self.position;
        let (x, y, z) = (d.dot(self.right), d.dot(self.up), d.dot(self.forward));
        let (nx, ny, dist) = match self.projection {
            Projection::Perspective { yfov } => {
                if z <= 0.0 {
                    return None;
                }
                let t = (yfov * 0.5).tan();
                (x / (z * t * aspect), y / (z * t), d.length())
            }
            Projection::Orthographic { ymag } => (x / (ymag * aspect), y / ymag, z),
        };
        Some((Vec2::new((nx + 1.0) * 0.5 * width as f32, (1.0 - ny) * 0.5 * height as f32), dist))
    }

    /// This camera with position, near clip and orthographic extent transformed by a uniform
    /// scale and offset.
    pub fn scaled(&self, scale: f32, offset: Vec3) -> Self {
        let mut c = self.clone();
        c.position = c.position * scale + offset;
        c.znear *= scale;
        if let Projection::Orthographic { ymag } = c.projection {
            c.projection = Projection::Orthographic { ymag: ymag * scale };
        }
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_ray_looks_forward_and_projects_back() {
        let cam = Camera::look_at(Vec3::new(1.0, 2.0, 3.0), Vec3::new(1.0, 2.0, -7.0), 60.0);
        let (o, d) = cam.ray(Vec2::new(50.0, 25.0), 100, 50);
        assert_eq!(o, Vec3::new(1.0, 2.0, 3.0));
        assert!((d - Vec3::NEG_Z).length() < 1e-6);
        let (film, dist) = cam.project(o + cam.ray(Vec2::new(10.0, 40.0), 100, 50).1 * 5.0, 100, 50).unwrap();
        assert!((film - Vec2::new(10.0, 40.0)).length() < 1e-3, "{film}");
        assert!((dist - 5.0).abs() < 1e-5);
    }

    #[test]
    fn orthographic_rays_are_parallel() {
        let mut cam = Camera::look_at(Vec3::ZERO, Vec3::NEG_Z, 45.0);
        cam.projection = Projection::Orthographic { ymag: 2.0 };
        let (o, d) = cam.ray(Vec2::new(0.0, 0.0), 20, 10);
        assert_eq!(d, Vec3::NEG_Z);
        assert!((o - Vec3::new(-4.0, 2.0, 0.0)).length() < 1e-6);
    }
}
