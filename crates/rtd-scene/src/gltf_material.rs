//! glTF materials and their textures: the metallic-roughness core, the KHR material extensions
//! rtd renders (emissive strength, transmission, IOR, specular, volume, clearcoat, sheen,
//! unlit), and texture slots with `texCoord` and `KHR_texture_transform`.

use std::collections::HashMap;

use glam::{Mat3, Vec2, Vec3, Vec4};
use gltf::image::Format;
use gltf::json::Value;

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
    let px = &data.pixels;
    let u16_at = |i: usize| u16::from_le_bytes([px[2 * i], px[2 * i + 1]]) as f32 / 65535.0;
    let f32_at = |i: usize| f32::from_le_bytes([px[4 * i], px[4 * i + 1], px[4 * i + 2], px[4 * i + 3]]);
    let n = data.width as usize * data.height as usize;
    let (channels, fetch): (usize, Box<dyn Fn(usize) -> f32>) = match data.format {
        Format::R8 => (1, Box::new(|i| px[i] as f32 / 255.0)),
        Format::R8G8 => (2, Box::new(|i| px[i] as f32 / 255.0)),
        Format::R8G8B8 => (3, Box::new(|i| px[i] as f32 / 255.0)),
        Format::R8G8B8A8 => (4, Box::new(|i| px[i] as f32 / 255.0)),
        Format::R16 => (1, Box::new(u16_at)),
        Format::R16G16 => (2, Box::new(u16_at)),
        Format::R16G16B16 => (3, Box::new(u16_at)),
        Format::R16G16B16A16 => (4, Box::new(u16_at)),
        Format::R32G32B32FLOAT => (3, Box::new(f32_at)),
        Format::R32G32B32A32FLOAT => (4, Box::new(f32_at)),
    };
    let is_float = matches!(data.format, Format::R32G32B32FLOAT | Format::R32G32B32A32FLOAT);
    let lin = |x: f32| {
        if srgb && !is_float {
            rtd_image::srgb_to_linear(x)
        } else {
            x
        }
    };
    let texels = (0..n)
        .map(|i| {
            let c = |k: usize| fetch(i * channels + k);
            match channels {
                // One channel is luminance, two are luminance + alpha (as PNG decoders give them).
                1 => Vec4::new(lin(c(0)), lin(c(0)), lin(c(0)), 1.0),
                2 => Vec4::new(lin(c(0)), lin(c(0)), lin(c(0)), c(1)),
                3 => Vec4::new(lin(c(0)), lin(c(1)), lin(c(2)), 1.0),
                _ => Vec4::new(lin(c(0)), lin(c(1)), lin(c(2)), c(3)),
            }
        })
        .collect();
    Texture::new(data.width, data.height, texels, wrap(sampler.wrap_s()), wrap(sampler.wrap_t()), nearest)
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
