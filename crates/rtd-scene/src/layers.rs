//! The optional layers over a glTF material's base: a clear coat (`KHR_materials_clearcoat`)
//! and a sheen (`KHR_materials_sheen`), as the file gives them; the BSDF that renders them is
//! rtd-render's.

use glam::Vec3;

use crate::texture_ref::{TexCoords, TextureRef};
use crate::Texture;

/// `KHR_materials_clearcoat`: a colourless dielectric coat (IOR 1.5) over the whole material.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Clearcoat {
    /// clearcoatFactor in [0,1]: the coat's weight.
    pub factor: f32,
    /// clearcoatTexture (R channel), multiplied into `factor`.
    pub texture: Option<TextureRef>,
    /// clearcoatRoughnessFactor: the coat's perceptual roughness.
    pub roughness: f32,
    /// clearcoatRoughnessTexture (G channel), multiplied into `roughness`.
    pub roughness_texture: Option<TextureRef>,
}

/// `KHR_materials_sheen`: a retro-reflective fibre layer (cloth, velvet) over the base.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sheen {
    /// sheenColorFactor: the sheen's colour (linear).
    pub color: Vec3,
    /// sheenColorTexture (RGB, linearised from sRGB at load), multiplied into `color`.
    pub color_texture: Option<TextureRef>,
    /// sheenRoughnessFactor: the fibres' perceptual roughness.
    pub roughness: f32,
    /// sheenRoughnessTexture (A channel), multiplied into `roughness`.
    pub roughness_texture: Option<TextureRef>,
}

/// The layers evaluated at one surface point.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LayerParams {
    /// Clear-coat weight in [0,1] (0: no coat).
    pub clearcoat: f32,
    /// Clear-coat perceptual roughness in [0,1].
    pub clearcoat_roughness: f32,
    /// Sheen colour, each channel in [0,1] (black: no sheen).
    pub sheen_color: Vec3,
    /// Sheen perceptual roughness in [0,1].
    pub sheen_roughness: f32,
}

impl LayerParams {
    /// Evaluates the material's layers, if any, at `uv`; factors × textures, clamped to [0,1]
    /// with NaN as 0.
    pub fn evaluate(
        clearcoat: Option<&Clearcoat>,
        sheen: Option<&Sheen>,
        textures: &[Texture],
        uv: TexCoords,
    ) -> LayerParams {
        let channel = |t: &Option<TextureRef>, k: usize| t.as_ref().map_or(1.0, |t| t.sample(textures, uv)[k]);
        let mut out = LayerParams::default();
        if let Some(c) = clearcoat {
            out.clearcoat = unit(c.factor * channel(&c.texture, 0));
            out.clearcoat_roughness = unit(c.roughness * channel(&c.roughness_texture, 1));
        }
        if let Some(s) = sheen {
            let tint = s.color_texture.as_ref().map_or(Vec3::ONE, |t| t.sample(textures, uv).truncate());
            out.sheen_color = (s.color * tint).map(unit);
            out.sheen_roughness = unit(s.roughness * channel(&s.roughness_texture, 3));
        }
        out
    }
}

/// Clamps to [0,1], with NaN as 0.
#[inline]
fn unit(x: f32) -> f32 {
    if x.is_finite() {
        x.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layers_clamp_factors_and_read_nothing_when_absent() {
        let none = LayerParams::evaluate(None, None, &[], glam::Vec2::ZERO.into());
        assert_eq!(none, LayerParams::default());
        let c = Clearcoat { factor: 2.0, texture: None, roughness: f32::NAN, roughness_texture: None };
        let s =
            Sheen { color: Vec3::new(0.5, -1.0, 3.0), color_texture: None, roughness: 0.3, roughness_texture: None };
        let p = LayerParams::evaluate(Some(&c), Some(&s), &[], glam::Vec2::ZERO.into());
        assert_eq!((p.clearcoat, p.clearcoat_roughness, p.sheen_roughness), (1.0, 0.0, 0.3));
        assert_eq!(p.sheen_color, Vec3::new(0.5, 0.0, 1.0));
    }
}
