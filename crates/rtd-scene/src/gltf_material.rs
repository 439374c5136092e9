//! glTF materials and their textures: the metallic-roughness core, the KHR material extensions
//! rtd renders (emissive strength, transmission, IOR, specular, volume, clearcoat, sheen,
//! unlit), and texture slots with `texCoord` and `KHR_texture_transform`.

use std::collections::HashMap;

use glam::{Mat3, Vec2, Vec3, Vec4};
use gltf::image::Format;
use gltf::json::Value;
use rayon::prelude::*;

use crate::{AlphaMode, Clearcoat, Material, Scene, Sheen, Texture, TextureRef, UvTransform, Wrap};

/// Decodes each (texture, colour space) pair once.
pub(crate) struct TextureCache<'a> {
    document: &'a gltf::Document,
    images: &'a [gltf::image::Data],
    map: HashMap<(usize, bool), (u32, Texture)>,
    warned_texcoord: bool,
    /// Whether some texture reads `TEXCOORD_1` (then meshes keep their second set).
    uses_set1: bool,
}

impl<'a> TextureCache<'a> {
    /// An empty cache over a document's decoded images.
    pub(crate) fn new(document: &'a gltf::Document, images: &'a [gltf::image::Data]) -> Self {
        TextureCache { document, images, map: HashMap::new(), warned_texcoord: false, uses_set1: false }
    }

    /// Whether some texture reads `TEXCOORD_1` (then meshes keep their second set).
    pub(crate) fn uses_set1(&self) -> bool {
        self.uses_set1
    }

    fn get(&mut self, tex: gltf::Texture, srgb: bool) -> u32 {
        let next = self.map.len() as u32;
        let images = self.images;
        let entry = self.map.entry((tex.index(), srgb)).or_insert_with(|| (next, decode_texture(&tex, images, srgb)));
        entry.0
    }

    /// The decoded textures, in the order their indices were handed out.
    pub(crate) fn into_textures(self) -> Vec<Texture> {
        let mut v: Vec<(u32, Texture)> = self.map.into_values().collect();
        v.sort_by_key(|(i, _)| *i);
        v.into_iter().map(|(_, t)| t).collect()
    }

    /// A texture slot with its optional `KHR_texture_transform`.
    fn info(&mut self, info: Option<gltf::texture::Info>, srgb: bool, scene: &mut Scene) -> Option<TextureRef> {
        let info = info?;
        let mut tex_coord = info.tex_coord();
        let transform = info.texture_transform().map(|t| {
            if let Some(tc) = t.tex_coord() {
                tex_coord = tc;
            }
            UvTransform { offset: Vec2::from(t.offset()), rotation: t.rotation(), scale: Vec2::from(t.scale()) }
                .matrix()
        });
        let tex_coord = self.tex_coord(tex_coord, scene);
        Some(TextureRef { texture: self.get(info.texture(), srgb), transform, tex_coord })
    }

    /// A texture slot of an extension the gltf crate does not parse, from its JSON
    /// (`{"index", "texCoord", "extensions": {"KHR_texture_transform"}}`); a slot naming a
    /// missing texture is dropped with a warning.
    fn raw_info(&mut self, json: Option<&Value>, srgb: bool, scene: &mut Scene) -> Option<TextureRef> {
        let json = json?;
        let index = json.get("index").and_then(Value::as_u64).unwrap_or(u64::MAX);
        let Some(texture) = usize::try_from(index).ok().and_then(|i| self.document.textures().nth(i)) else {
            scene.warnings.push(format!("a material extension names texture {index}, which does not exist; ignored"));
            return None;
        };
        let ext = json.get("extensions").and_then(|e| e.get("KHR_texture_transform"));
        let (transform, set) = raw_transform(ext);
        let set = set.or(json.get("texCoord").and_then(Value::as_u64)).unwrap_or(0);
        let tex_coord = self.tex_coord(u32::try_from(set).unwrap_or(u32::MAX), scene);
        Some(TextureRef { texture: self.get(texture, srgb), transform, tex_coord })
    }

    /// The set a texture reads, noting set 1's use; sets past 1 (which Blender and the other
    /// common exporters never write) read set 0, with one warning.
    fn tex_coord(&mut self, tex_coord: u32, scene: &mut Scene) -> u8 {
        match tex_coord {
            0 => 0,
            1 => {
                self.uses_set1 = true;
                1
            }
            _ => {
                if !self.warned_texcoord {
                    self.warned_texcoord = true;
                    scene.warnings.push(format!(
                        "a texture uses TEXCOORD_{tex_coord}; rtd reads sets 0 and 1, so it reads set 0"
                    ));
                }
                0
            }
        }
    }
}

/// Converts glTF image data to linear float RGBA, linearising sRGB colour channels.
fn decode_texture(tex: &gltf::Texture, images: &[gltf::image::Data], srgb: bool) -> Texture {
    let sampler = tex.sampler();
    let wrap = |w: gltf::texture::WrappingMode| match w {
        gltf::texture::WrappingMode::ClampToEdge => Wrap::Clamp,
        gltf::texture::WrappingMode::MirroredRepeat => Wrap::Mirror,
        gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
    };
    let nearest = matches!(sampler.mag_filter(), Some(gltf::texture::MagFilter::Nearest));
    let Some(data) = images.get(tex.source().index()) else {
        return Texture::constant(Vec4::ONE);
    };
    let (channels, sample) = match data.format {
        Format::R8 => (1, ChannelType::U8),
        Format::R8G8 => (2, ChannelType::U8),
        Format::R8G8B8 => (3, ChannelType::U8),
        Format::R8G8B8A8 => (4, ChannelType::U8),
        Format::R16 => (1, ChannelType::U16),
        Format::R16G16 => (2, ChannelType::U16),
        Format::R16G16B16 => (3, ChannelType::U16),
        Format::R16G16B16A16 => (4, ChannelType::U16),
        Format::R32G32B32FLOAT => (3, ChannelType::F32),
        Format::R32G32B32A32FLOAT => (4, ChannelType::F32),
    };
    let n = data.width as usize * data.height as usize;
    let (w, h, wrap_u, wrap_v) = (data.width, data.height, wrap(sampler.wrap_s()), wrap(sampler.wrap_t()));
    // 8-bit images stay 8-bit (decoded on each lookup to the same values), the rest as floats.
    let texture =
        match sample {
            ChannelType::U8 => rgba8_from(&data.pixels, n, channels)
                .map(|t| Texture::from_rgba8(w, h, t, srgb, wrap_u, wrap_v, nearest)),
            _ => texels_from(&data.pixels, n, channels, sample, srgb)
                .map(|t| Texture::new(w, h, t, wrap_u, wrap_v, nearest)),
        };
    texture.unwrap_or_else(|| Texture::constant(Vec4::ONE))
}

/// `n` 8-bit texels of `channels` channels as RGBA, as [`Texture::from_rgba8`] keeps them: one
/// channel is luminance, two are luminance + alpha, and a missing alpha is opaque. None if
/// `pixels` is too short.
fn rgba8_from(pixels: &[u8], n: usize, channels: usize) -> Option<Vec<[u8; 4]>> {
    let bytes = pixels.get(..n * channels)?;
    let texels = bytes
        .par_chunks_exact(channels)
        .map(|t| match *t {
            [l] => [l, l, l, 255],
            [l, a] => [l, l, l, a],
            [r, g, b] => [r, g, b, 255],
            [r, g, b, a, ..] => [r, g, b, a],
            [] => [255; 4],
        })
        .collect();
    Some(texels)
}

/// `n` texels of `channels` channels stored as `sample` in `pixels`, as linear RGBA: colour
/// channels sRGB-decoded when `srgb`, one channel taken as luminance and two as luminance +
/// alpha (as PNG decoders give them). Texels are converted in parallel, in order. None if
/// `pixels` is too short.
fn texels_from(pixels: &[u8], n: usize, channels: usize, sample: ChannelType, srgb: bool) -> Option<Vec<Vec4>> {
    let stride = channels * sample.bytes();
    let bytes = pixels.get(..n * stride)?;
    let texels = bytes
        .par_chunks_exact(stride)
        .map(|t| {
            let plain = |k: usize| sample.plain(&t[k * sample.bytes()..]);
            let c = |k: usize| if srgb { sample.srgb(&t[k * sample.bytes()..]) } else { plain(k) };
            match channels {
                1 => Vec4::new(c(0), c(0), c(0), 1.0),
                2 => Vec4::new(c(0), c(0), c(0), plain(1)),
                3 => Vec4::new(c(0), c(1), c(2), 1.0),
                _ => Vec4::new(c(0), c(1), c(2), plain(3)),
            }
        })
        .collect();
    Some(texels)
}

/// How a decoded glTF image stores one channel.
#[derive(Clone, Copy, Debug)]
enum ChannelType {
    U8,
    U16,
    F32,
}

impl ChannelType {
    /// Bytes per channel.
    fn bytes(self) -> usize {
        match self {
            ChannelType::U8 => 1,
            ChannelType::U16 => 2,
            ChannelType::F32 => 4,
        }
    }

    /// The channel at the start of `b` as stored: integers normalised to [0, 1].
    #[inline]
    fn plain(self, b: &[u8]) -> f32 {
        match self {
            ChannelType::U8 => b[0] as f32 / 255.0,
            ChannelType::U16 => u16::from_le_bytes([b[0], b[1]]) as f32 / 65535.0,
            ChannelType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        }
    }

    /// The channel as an sRGB-encoded colour, linearised ([`rtd_image::srgb_to_linear`] of the
    /// normalised integer; float images are linear already).
    #[inline]
    fn srgb(self, b: &[u8]) -> f32 {
        match self {
            ChannelType::U8 => rtd_image::srgb8_to_linear(b[0]),
            ChannelType::U16 => rtd_image::srgb16_to_linear(u16::from_le_bytes([b[0], b[1]])),
            ChannelType::F32 => self.plain(b),
        }
    }
}

/// The rtd material of a glTF material.
pub(crate) fn convert_material(m: &gltf::Material, textures: &mut TextureCache, scene: &mut Scene) -> Material {
    let pbr = m.pbr_metallic_roughness();
    let strength = m.emissive_strength().unwrap_or(1.0);
    let normal_texture = m.normal_texture().map(|n| {
        // gltf 1.4 exposes no texture_transform() on normal textures; read the extension by hand.
        let (transform, set) = raw_transform(n.extension_value("KHR_texture_transform"));
        // The extension's texCoord, when given, overrides the slot's.
        let set = set.map_or(n.tex_coord(), |x| u32::try_from(x).unwrap_or(u32::MAX));
        let tex_coord = textures.tex_coord(set, scene);
        (TextureRef { texture: textures.get(n.texture(), false), transform, tex_coord }, n.scale())
    });
    let (transmission, transmission_texture) = match m.transmission() {
        Some(t) => (t.transmission_factor(), textures.info(t.transmission_texture(), false, scene)),
        None => (0.0, None),
    };
    let (specular, specular_texture, specular_color, specular_color_texture) = match m.specular() {
        Some(s) => (
            s.specular_factor(),
            textures.info(s.specular_texture(), false, scene),
            Vec3::from(s.specular_color_factor()),
            // The colour texture is sRGB-encoded, as the base colour is.
            textures.info(s.specular_color_texture(), true, scene),
        ),
        None => (1.0, None, Vec3::ONE, None),
    };
    Material {
        name: m.name().unwrap_or("unnamed").to_string(),
        base_color: Vec4::from(pbr.base_color_factor()),
        base_color_texture: textures.info(pbr.base_color_texture(), true, scene),
        metallic: pbr.metallic_factor(),
        roughness: pbr.roughness_factor(),
        metallic_roughness_texture: textures.info(pbr.metallic_roughness_texture(), false, scene),
        normal_scale: normal_texture.map(|n| n.1).unwrap_or(1.0),
        normal_texture: normal_texture.map(|n| n.0),
        emissive: Vec3::from(m.emissive_factor()) * strength,
        emissive_texture: textures.info(m.emissive_texture(), true, scene),
        transmission,
        transmission_texture,
        ior: m.ior().unwrap_or(1.5),
        absorption: m.volume().map_or(Vec3::ZERO, |v| {
            volume_absorption(v.thickness_factor(), v.attenuation_color(), v.attenuation_distance())
        }),
        specular,
        specular_texture,
        specular_color,
        specular_color_texture,
        clearcoat: clearcoat(m.extension_value("KHR_materials_clearcoat"), textures, scene),
        sheen: sheen(m.extension_value("KHR_materials_sheen"), textures, scene),
        alpha_mode: match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
            gltf::material::AlphaMode::Mask => AlphaMode::Mask(m.alpha_cutoff().unwrap_or(0.5)),
            gltf::material::AlphaMode::Blend => AlphaMode::Blend,
        },
        double_sided: m.double_sided(),
        unlit: m.unlit(),
    }
}

/// The absorption coefficient σ_a per world unit of a `KHR_materials_volume`: white light
/// turns `color` after `distance` (Beer–Lambert, σ_a = −ln(color)/distance). A thin-walled
/// volume (thickness 0), an infinite distance, or a white colour absorbs nothing.
fn volume_absorption(thickness: f32, color: [f32; 3], distance: f32) -> Vec3 {
    if !(thickness > 0.0 && distance > 0.0 && distance.is_finite()) {
        return Vec3::ZERO;
    }
    // A colour of 0 would be an infinite coefficient: clamp to a tiny transmittance instead.
    Vec3::from(color).map(|c| if c.is_finite() { -c.clamp(1e-6, 1.0).ln() / distance } else { 0.0 })
}

/// `KHR_materials_clearcoat` from its JSON; none when absent or of zero weight.
fn clearcoat(json: Option<&Value>, textures: &mut TextureCache, scene: &mut Scene) -> Option<Clearcoat> {
    let json = json?;
    let coat = Clearcoat {
        factor: number(json, "clearcoatFactor", 0.0),
        texture: textures.raw_info(json.get("clearcoatTexture"), false, scene),
        roughness: number(json, "clearcoatRoughnessFactor", 0.0),
        roughness_texture: textures.raw_info(json.get("clearcoatRoughnessTexture"), false, scene),
    };
    if json.get("clearcoatNormalTexture").is_some() {
        scene.warnings.push("clearcoatNormalTexture is not read: the coat follows the base's normal".into());
    }
    (coat.factor > 0.0).then_some(coat)
}

/// `KHR_materials_sheen` from its JSON; none when absent or black.
fn sheen(json: Option<&Value>, textures: &mut TextureCache, scene: &mut Scene) -> Option<Sheen> {
    let json = json?;
    let color = json.get("sheenColorFactor").and_then(Value::as_array);
    let channel = |i: usize| color.and_then(|c| c.get(i)).and_then(Value::as_f64).unwrap_or(0.0) as f32;
    let sheen = Sheen {
        color: Vec3::new(channel(0), channel(1), channel(2)),
        // The colour texture is sRGB-encoded, as the base colour is.
        color_texture: textures.raw_info(json.get("sheenColorTexture"), true, scene),
        roughness: number(json, "sheenRoughnessFactor", 0.0),
        roughness_texture: textures.raw_info(json.get("sheenRoughnessTexture"), false, scene),
    };
    (sheen.color.max_element() > 0.0).then_some(sheen)
}

/// A number field of extension JSON, or `default`.
fn number(json: &Value, key: &str, default: f32) -> f32 {
    json.get(key).and_then(Value::as_f64).map_or(default, |x| x as f32)
}

/// A `KHR_texture_transform` from its JSON: the UV matrix, and the texCoord it overrides with.
fn raw_transform(ext: Option<&Value>) -> (Option<Mat3>, Option<u64>) {
    let Some(v) = ext else {
        return (None, None);
    };
    let pair = |k: &str, d: f32| {
        let a = v.get(k).and_then(Value::as_array);
        let f = |i: usize| a.and_then(|a| a.get(i)).and_then(Value::as_f64).map_or(d, |x| x as f32);
        Vec2::new(f(0), f(1))
    };
    let rotation = v.get("rotation").and_then(Value::as_f64).unwrap_or(0.0) as f32;
    let matrix = UvTransform { offset: pair("offset", 0.0), rotation, scale: pair("scale", 1.0) }.matrix();
    (Some(matrix), v.get("texCoord").and_then(Value::as_u64))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtd_image::srgb_to_linear;

    /// Every storage and channel count against the per-channel formulas: integers normalised,
    /// colour channels through `srgb_to_linear` (bit for bit) when sRGB, alpha never.
    #[test]
    fn texels_match_the_channel_formulas_for_every_format() {
        let bytes: Vec<u8> = (0..=255u8).chain((0..=255u8).rev()).collect();
        for (sample, scale) in [(ChannelType::U8, 255.0f32), (ChannelType::U16, 65535.0)] {
            let value = |b: &[u8]| match sample {
                ChannelType::U8 => b[0] as f32,
                _ => u16::from_le_bytes([b[0], b[1]]) as f32,
            } / scale;
            for channels in 1..=4 {
                for srgb in [false, true] {
                    let stride = channels * sample.bytes();
                    let n = bytes.len() / stride;
                    let texels = texels_from(&bytes, n, channels, sample, srgb).expect("long enough");
                    assert_eq!(texels.len(), n);
                    for (i, t) in texels.iter().enumerate() {
                        let ch = |k: usize| value(&bytes[i * stride + k * sample.bytes()..]);
                        let col = |k: usize| if srgb { srgb_to_linear(ch(k)) } else { ch(k) };
                        let want = match channels {
                            1 => Vec4::new(col(0), col(0), col(0), 1.0),
                            2 => Vec4::new(col(0), col(0), col(0), ch(1)),
                            3 => Vec4::new(col(0), col(1), col(2), 1.0),
                            _ => Vec4::new(col(0), col(1), col(2), ch(3)),
                        };
                        assert_eq!(t.to_array().map(f32::to_bits), want.to_array().map(f32::to_bits), "{sample:?} {i}");
                    }
                }
            }
        }
        // Float images are linear whatever the slot says.
        let floats: Vec<u8> = [0.25f32, 2.0, -1.0, 0.5].iter().flat_map(|x| x.to_le_bytes()).collect();
        assert_eq!(texels_from(&floats, 1, 4, ChannelType::F32, true), Some(vec![Vec4::new(0.25, 2.0, -1.0, 0.5)]));
        // Too few bytes for the size: no texels rather than a panic.
        assert_eq!(texels_from(&bytes[..5], 2, 3, ChannelType::U8, true), None);
        assert_eq!(rgba8_from(&bytes[..5], 2, 3), None);
    }

    /// An 8-bit image kept as bytes samples exactly as its texels decoded to floats do: plain,
    /// nearest and footprint-filtered lookups (which read the mip levels), every wrap mode.
    #[test]
    fn eight_bit_textures_sample_as_their_decoded_floats() {
        let (w, h) = (13u32, 8u32);
        let n = (w * h) as usize;
        let bytes: Vec<u8> = (0..n * 4).map(|i| (i * 97 % 256) as u8).collect();
        for channels in 1..=4 {
            for srgb in [false, true] {
                for (wrap, nearest) in [(Wrap::Repeat, false), (Wrap::Clamp, false), (Wrap::Mirror, true)] {
                    let floats = texels_from(&bytes, n, channels, ChannelType::U8, srgb).unwrap();
                    let a = Texture::new(w, h, floats, wrap, wrap, nearest);
                    let b =
                        Texture::from_rgba8(w, h, rgba8_from(&bytes, n, channels).unwrap(), srgb, wrap, wrap, nearest);
                    assert_eq!(b.heap_bytes() + 12 * n, a.heap_bytes());
                    assert_eq!(a.mean(), b.mean());
                    for k in 0..400 {
                        let uv =
                            Vec2::new((k as f32 * 0.618).fract() * 3.0 - 1.0, (k as f32 * 0.377).fract() * 3.0 - 1.0);
                        let (du, dv) = (Vec2::new(0.02 * (k % 7) as f32, 0.0), Vec2::new(0.0, 0.03 * (k % 5) as f32));
                        assert_eq!(a.sample(uv), b.sample(uv), "{channels} {srgb} {uv}");
                        assert_eq!(a.sample_footprint(uv, du, dv), b.sample_footprint(uv, du, dv), "{channels} {uv}");
                    }
                }
            }
        }
    }
}
