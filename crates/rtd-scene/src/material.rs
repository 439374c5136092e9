//! glTF metallic-roughness materials: their factors and texture slots, and their evaluation at a
//! surface point into the clamped parameters the BSDF and the guide pass read.

use glam::{Vec3, Vec4, Vec4Swizzles};

use crate::layers::{Clearcoat, LayerParams, Sheen};
use crate::texture::FootprintFilter;
use crate::texture_ref::{TexCoords, TextureRef};
use crate::Texture;

/// The footprint filters of a material's base-colour and normal textures (see
/// [`Material::footprint`]), shared by lookups with the same footprint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MaterialFootprint {
    base: FootprintFilter,
    normal: FootprintFilter,
}

impl MaterialFootprint {
    /// Plain lookups: a footprint no wider than a texel.
    pub const POINT: MaterialFootprint =
        MaterialFootprint { base: FootprintFilter::POINT, normal: FootprintFilter::POINT };
}

/// How a material's alpha is used.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum AlphaMode {
    /// Alpha is ignored.
    #[default]
    Opaque,
    /// Cut-out: the surface is absent where alpha < cutoff (for camera and shadow rays alike).
    Mask(f32),
    /// Partial coverage: rays pass straight through with probability 1 − alpha.
    Blend,
}

/// A glTF metallic-roughness material with the extensions rtd supports.
/// Factors are stored already multiplied together (e.g. emissive × emissive strength).
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// Name from the file, for messages.
    pub name: String,
    /// Linear base colour and alpha factor.
    pub base_color: Vec4,
    /// Base colour texture (linearised from sRGB at load).
    pub base_color_texture: Option<TextureRef>,
    /// Metallic factor in [0,1].
    pub metallic: f32,
    /// Perceptual roughness factor in [0,1] (GGX alpha = roughness²).
    pub roughness: f32,
    /// Metallic (B) and roughness (G) texture.
    pub metallic_roughness_texture: Option<TextureRef>,
    /// Tangent-space normal map.
    pub normal_texture: Option<TextureRef>,
    /// Scale applied to the normal map's X and Y.
    pub normal_scale: f32,
    /// Emitted radiance: emissive factor × `KHR_materials_emissive_strength`.
    pub emissive: Vec3,
    /// Emissive texture (linearised from sRGB at load).
    pub emissive_texture: Option<TextureRef>,
    /// `KHR_materials_transmission` factor in [0,1].
    pub transmission: f32,
    /// Transmission texture (R channel).
    pub transmission_texture: Option<TextureRef>,
    /// Index of refraction (`KHR_materials_ior`, default 1.5).
    pub ior: f32,
    /// Absorption coefficient σ_a per world unit inside the closed mesh this material bounds
    /// (`KHR_materials_volume`: −ln(attenuationColor)/attenuationDistance); zero for none.
    /// Transmitted light is attenuated by exp(−σ_a·d) over the distance d it travels inside.
    pub absorption: Vec3,
    /// `KHR_materials_specular` specularFactor (default 1).
    pub specular: f32,
    /// Specular texture (A channel).
    pub specular_texture: Option<TextureRef>,
    /// `KHR_materials_specular` specularColorFactor (default white).
    pub specular_color: Vec3,
    /// Specular colour texture (RGB, linearised from sRGB at load), multiplied into
    /// [`Material::specular_color`].
    pub specular_color_texture: Option<TextureRef>,
    /// `KHR_materials_clearcoat`, if the material has a coat.
    pub clearcoat: Option<Clearcoat>,
    /// `KHR_materials_sheen`, if the material has a sheen.
    pub sheen: Option<Sheen>,
    /// Alpha handling.
    pub alpha_mode: AlphaMode,
    /// Whether back faces are rendered as front faces (and emit).
    pub double_sided: bool,
    /// `KHR_materials_unlit`: the surface shows its base colour as it is, to camera rays and
    /// through mirrors and clear glass, and neither receives nor casts light (it is not an
    /// emitter; diffuse and glossy bounces see it black).
    pub unlit: bool,
}

impl Default for Material {
    /// The glTF default material: white, fully rough, dielectric.
    fn default() -> Self {
        Material {
            name: "default".into(),
            base_color: Vec4::ONE,
            base_color_texture: None,
            metallic: 1.0,
            roughness: 1.0,
            metallic_roughness_texture: None,
            normal_texture: None,
            normal_scale: 1.0,
            emissive: Vec3::ZERO,
            emissive_texture: None,
            transmission: 0.0,
            transmission_texture: None,
            ior: 1.5,
            absorption: Vec3::ZERO,
            specular: 1.0,
            specular_texture: None,
            specular_color: Vec3::ONE,
            specular_color_texture: None,
            clearcoat: None,
            sheen: None,
            alpha_mode: AlphaMode::Opaque,
            double_sided: false,
            unlit: false,
        }
    }
}

/// A material evaluated at one surface point: all factors × textures, clamped to valid ranges.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceParams {
    /// Linear base colour.
    pub base_color: Vec3,
    /// Coverage in [0,1].
    pub alpha: f32,
    /// Metallic in [0,1].
    pub metallic: f32,
    /// Perceptual roughness in [0,1].
    pub roughness: f32,
    /// Emitted radiance.
    pub emission: Vec3,
    /// Transmission in [0,1].
    pub transmission: f32,
    /// Index of refraction, at least 1.
    pub ior: f32,
    /// Specular weight in [0,1].
    pub specular: f32,
    /// Specular tint (F0 multiplier).
    pub specular_color: Vec3,
    /// Tangent-space normal from the normal map (scaled, unnormalised), if any.
    pub tangent_normal: Option<Vec3>,
    /// The clear coat and sheen over the base.
    pub layers: LayerParams,
}

impl SurfaceParams {
    /// The albedo the path tracer's AOV records at this point: white where it emits, else its
    /// base colour (as [`Material::albedo`]).
    #[inline]
    pub fn aov_albedo(&self) -> Vec3 {
        if self.emission != Vec3::ZERO {
            Vec3::ONE
        } else {
            self.base_color
        }
    }
}

impl Material {
    /// True if the material emits light anywhere.
    pub fn is_emissive(&self) -> bool {
        self.emissive.max_element() > 0.0
    }

    /// Coverage alpha at `uv` (base colour alpha × texture alpha).
    #[inline]
    pub fn alpha(&self, textures: &[Texture], uv: TexCoords) -> f32 {
        let mut a = self.base_color.w;
        if let Some(t) = &self.base_color_texture {
            a *= t.sample(textures, uv).w;
        }
        a
    }

    /// Base colour × texture at `uv` (RGB and alpha, unclamped).
    #[inline]
    fn base_rgba(&self, textures: &[Texture], uv: TexCoords) -> Vec4 {
        match &self.base_color_texture {
            Some(t) => self.base_color * t.sample(textures, uv),
            None => self.base_color,
        }
    }

    /// True if the surface emits at `uv` (emissive factor × emissive texture has a positive channel).
    #[inline]
    pub fn emits_at(&self, textures: &[Texture], uv: TexCoords) -> bool {
        self.is_emissive()
            && self
                .emissive_texture
                .as_ref()
                .is_none_or(|t| (self.emissive * t.sample(textures, uv).xyz()).max_element() > 0.0)
    }

    /// The albedo that the AOVs and the guide pass record: base colour × texture in [0,1], or
    /// white where the surface emits (the rule of [`SurfaceParams::aov_albedo`]). A light's
    /// radiance is not reflected light, so a denoiser that divides colour by albedo must leave it
    /// as it is; with its base colour (often black) it would be divided by ~0 and its edges would
    /// bleed into the surfaces around it.
    #[inline]
    pub fn albedo(&self, textures: &[Texture], uv: TexCoords) -> Vec3 {
        self.albedo_filtered(textures, uv, &MaterialFootprint::POINT)
    }

    /// The UV set the normal map reads, which is also the set its tangent frame follows.
    pub fn normal_tex_coord(&self) -> u8 {
        self.normal_texture.as_ref().map_or(0, |t| t.tex_coord)
    }

    /// Tangent-space normal from the normal map (scaled, unnormalised), if the material has one.
    #[inline]
    pub fn tangent_normal(&self, textures: &[Texture], uv: TexCoords) -> Option<Vec3> {
        self.normal_texture.as_ref().map(|t| self.decode_normal(t.sample(textures, uv)))
    }

    /// Normal-map texel → scaled tangent-space normal.
    #[inline]
    fn decode_normal(&self, texel: Vec4) -> Vec3 {
        let s = texel.xyz() * 2.0 - Vec3::ONE;
        Vec3::new(s.x * self.normal_scale, s.y * self.normal_scale, s.z)
    }

    /// The filters for a footprint spanned by UV steps `du`, `dv`, for
    /// [`Material::albedo_filtered`] and [`Material::tangent_normal_filtered`].
    #[inline]
    pub fn footprint(&self, textures: &[Texture], du: TexCoords, dv: TexCoords) -> MaterialFootprint {
        let filter =
            |t: &Option<TextureRef>| t.map_or(FootprintFilter::POINT, |t| t.footprint_filter(textures, du, dv));
        MaterialFootprint { base: filter(&self.base_color_texture), normal: filter(&self.normal_texture) }
    }

    /// [`Material::albedo`] averaged over a UV footprint around `uv` whose filters
    /// [`Material::footprint`] worked out, as a pixel sees a texture finer than itself: the guide
    /// pass's anti-aliased lookup.
    #[inline]
    pub fn albedo_filtered(&self, textures: &[Texture], uv: TexCoords, footprint: &MaterialFootprint) -> Vec3 {
        if self.emits_at(textures, uv) {
            return Vec3::ONE;
        }
        match &self.base_color_texture {
            Some(t) => clamp_color((self.base_color * t.sample_filtered(textures, &footprint.base, uv)).xyz()),
            None => clamp_color(self.base_color.xyz()),
        }
    }

    /// [`Material::tangent_normal`] from the normal map averaged over a UV footprint around `uv`
    /// whose filters [`Material::footprint`] worked out.
    #[inline]
    pub fn tangent_normal_filtered(
        &self,
        textures: &[Texture],
        uv: TexCoords,
        footprint: &MaterialFootprint,
    ) -> Option<Vec3> {
        self.normal_texture.as_ref().map(|t| self.decode_normal(t.sample_filtered(textures, &footprint.normal, uv)))
    }

    /// Evaluates every factor and texture at `uv`.
    pub fn evaluate(&self, textures: &[Texture], uv: TexCoords) -> SurfaceParams {
        let base = self.base_rgba(textures, uv);
        let (mut metallic, mut roughness) = (self.metallic, self.roughness);
        if let Some(t) = &self.metallic_roughness_texture {
            let s = t.sample(textures, uv);
            roughness *= s.y;
            metallic *= s.z;
        }
        let mut emission = self.emissive;
        if let Some(t) = &self.emissive_texture {
            emission *= t.sample(textures, uv).xyz();
        }
        let mut transmission = self.transmission;
        if let Some(t) = &self.transmission_texture {
            transmission *= t.sample(textures, uv).x;
        }
        let mut specular = self.specular;
        if let Some(t) = &self.specular_texture {
            specular *= t.sample(textures, uv).w;
        }
        let mut specular_color = self.specular_color;
        if let Some(t) = &self.specular_color_texture {
            specular_color *= t.sample(textures, uv).xyz();
        }
        let tangent_normal = self.tangent_normal(textures, uv);
        let sat = |x: f32| {
            if x.is_finite() {
                x.clamp(0.0, 1.0)
            } else {
                0.0
            }
        };
        let pos = |v: Vec3| v.map(|x| if x.is_finite() { x.max(0.0) } else { 0.0 });
        SurfaceParams {
            base_color: clamp_color(base.xyz()),
            alpha: sat(base.w),
            metallic: sat(metallic),
            roughness: sat(roughness),
            emission: pos(emission),
            transmission: sat(transmission),
            ior: if self.ior.is_finite() { self.ior.max(1.0) } else { 1.5 },
            specular: sat(specular),
            specular_color: pos(specular_color),
            tangent_normal,
            layers: LayerParams::evaluate(self.clearcoat.as_ref(), self.sheen.as_ref(), textures, uv),
        }
    }
}

/// Maps each channel into [0,1], with NaN as 0.
#[inline]
fn clamp_color(v: Vec3) -> Vec3 {
    v.map(|x| if x.is_finite() { x.clamp(0.0, 1.0) } else { 0.0 })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;

    #[test]
    fn emitters_record_white_albedo() {
        let mut m = Material { base_color: Vec4::new(0.2, 0.4, 0.6, 1.0), ..Material::default() };
        assert_eq!(m.albedo(&[], Vec2::ZERO.into()), Vec3::new(0.2, 0.4, 0.6));
        m.emissive = Vec3::new(0.0, 3.0, 0.0);
        assert!(m.emits_at(&[], Vec2::ZERO.into()));
        assert_eq!(m.albedo(&[], Vec2::ZERO.into()), Vec3::ONE);
    }

    #[test]
    fn evaluate_multiplies_factors_and_clamps() {
        let textures = vec![Texture::constant(Vec4::new(1.0, 0.5, 0.25, 1.0))];
        let m = Material {
            roughness: 0.8,
            metallic: 1.0,
            metallic_roughness_texture: Some(TextureRef::plain(0)),
            base_color: Vec4::new(2.0, 0.5, f32::NAN, 1.0),
            ior: 0.5,
            ..Material::default()
        };
        let s = m.evaluate(&textures, Vec2::ZERO.into());
        assert_eq!(s.roughness, 0.4);
        assert_eq!(s.metallic, 0.25);
        assert_eq!(s.base_color, Vec3::new(1.0, 0.5, 0.0));
        assert_eq!(s.ior, 1.0);
    }
}
