//! References from material slots to textures: which texture, through which UV set and
//! `KHR_texture_transform`, and the texture coordinates a lookup reads.

use glam::{Mat3, Vec2, Vec3, Vec4};

use crate::texture::FootprintFilter;
use crate::Texture;

/// `KHR_texture_transform`: uv' = T(offset) · R(rotation) · S(scale) · uv.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UvTransform {
    /// Translation added after rotation and scale.
    pub offset: Vec2,
    /// Rotation in radians (counter-clockwise in UV space, as the extension defines it).
    pub rotation: f32,
    /// Per-axis scale applied first.
    pub scale: Vec2,
}

impl UvTransform {
    /// The transform as a 3×3 matrix acting on (u, v, 1).
    pub fn matrix(&self) -> Mat3 {
        let (s, c) = self.rotation.sin_cos();
        let t = Mat3::from_cols(Vec3::X, Vec3::Y, self.offset.extend(1.0));
        // The extension's rotation matrix, as written in its specification (column-major).
        let r = Mat3::from_cols(Vec3::new(c, -s, 0.0), Vec3::new(s, c, 0.0), Vec3::Z);
        let sc = Mat3::from_diagonal(self.scale.extend(1.0));
        t * r * sc
    }
}

/// The texture coordinates of one surface point (or one footprint step): set 0 (`TEXCOORD_0`)
/// and set 1 (`TEXCOORD_1`, a copy of set 0 where the mesh has no second set).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TexCoords(pub [Vec2; 2]);

impl TexCoords {
    /// The same coordinates in both sets.
    #[inline]
    pub fn uniform(uv: Vec2) -> Self {
        TexCoords([uv, uv])
    }

    /// Set `set` (0 or 1; higher sets are not kept and read set 0).
    #[inline]
    pub fn set(&self, set: u8) -> Vec2 {
        self.0[if set == 1 { 1 } else { 0 }]
    }
}

impl From<Vec2> for TexCoords {
    fn from(uv: Vec2) -> Self {
        TexCoords::uniform(uv)
    }
}

/// A reference from a material slot to a texture.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TextureRef {
    /// Index into [`crate::Scene::textures`].
    pub texture: u32,
    /// Optional UV transform (`KHR_texture_transform`), stored as a matrix.
    pub transform: Option<Mat3>,
    /// The set of texture coordinates it reads (`texCoord`, after `KHR_texture_transform`'s
    /// override): 0 or 1.
    pub tex_coord: u8,
}

impl TextureRef {
    /// A reference to `texture` through set 0 with no transform.
    pub fn plain(texture: u32) -> Self {
        TextureRef { texture, transform: None, tex_coord: 0 }
    }

    /// Samples the texture at `uv` (its own set of it) after the UV transform.
    #[inline]
    pub fn sample(&self, textures: &[Texture], uv: TexCoords) -> Vec4 {
        let uv = uv.set(self.tex_coord);
        let uv = match self.transform {
            Some(m) => (m * uv.extend(1.0)).truncate(),
            None => uv,
        };
        textures[self.texture as usize].sample(uv)
    }

    /// The filter of the footprint spanned by UV steps `du`, `dv` (before the UV transform): see
    /// [`Texture::sample_footprint`].
    #[inline]
    pub fn footprint_filter(&self, textures: &[Texture], du: TexCoords, dv: TexCoords) -> FootprintFilter {
        let (du, dv) = (du.set(self.tex_coord), dv.set(self.tex_coord));
        let (du, dv) = match self.transform {
            Some(m) => ((m * du.extend(0.0)).truncate(), (m * dv.extend(0.0)).truncate()),
            None => (du, dv),
        };
        textures[self.texture as usize].footprint_filter(du, dv)
    }

    /// The texture at `uv` (before the UV transform) through `filter`.
    #[inline]
    pub fn sample_filtered(&self, textures: &[Texture], filter: &FootprintFilter, uv: TexCoords) -> Vec4 {
        let uv = uv.set(self.tex_coord);
        let uv = match self.transform {
            Some(m) => (m * uv.extend(1.0)).truncate(),
            None => uv,
        };
        textures[self.texture as usize].sample_filtered(filter, uv)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texture_transform_matches_spec_example() {
        // Rotation by 90°: the spec's matrix maps (1,0) to (cos, -sin) = (0,-1).
        let t =
            UvTransform { offset: Vec2::new(0.5, 0.0), rotation: std::f32::consts::FRAC_PI_2, scale: Vec2::splat(2.0) };
        let p = t.matrix() * Vec3::new(1.0, 0.0, 1.0);
        assert!((p - Vec3::new(0.5, -2.0, 1.0)).length() < 1e-6, "{p}");
    }
}
