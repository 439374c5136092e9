//! The glTF and OBJ importers on hand-made files that exercise each supported feature.

mod common;

use std::path::Path;

use common::gltf::{b64, default_material, f32_bytes, quad_gltf, write_glb, write_gltf};
use glam::{Vec2, Vec3};
use rtd::render::SceneBvh;
use rtd::scene::{load_scene, AlphaMode, CameraError, Light, Projection};
use serde_json::json;

#[test]
fn node_hierarchy_transforms_and_glb_match_gltf() {
    let dir = tempfile::tempdir().unwrap();
    // Parent translates by (10,0,0) and scales by 2; child rotates 90° about Y.
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let nodes = json!([
        {"translation": [10.0, 0.0, 0.0], "scale": [2.0, 2.0, 2.0], "children": [1]},
        {"rotation": [0.0, s, 0.0, s], "mesh": 0}
    ]);
    let (doc, buf) = quad_gltf(nodes, default_material(), &[]);
    let a = load_scene(&write_gltf(dir.path(), "q.gltf", doc.clone(), &buf)).unwrap();
    let b = load_scene(&write_glb(dir.path(), "q.glb", doc, &buf)).unwrap();
    assert_eq!(a.triangles.len(), 2);
    assert_eq!(a.triangles, b.triangles, ".glb and .gltf differ");
    // Vertex (1,0,0) rotates to (0,0,-1), scales to (0,0,-2), translates to (10,0,-2).
    assert!((a.triangles[0].p[1] - Vec3::new(10.0, 0.0, -2.0)).length() < 1e-5, "{}", a.triangles[0].p[1]);
    // No normals in the file: flat normals from the winding, rotated to +X.
    assert!((a.triangles[0].n[0] - Vec3::X).length() < 1e-5, "{}", a.triangles[0].n[0]);
    assert!(a.warnings.iter().all(|w| !w.contains("skipped")));
}

#[test]
fn mirrored_nodes_keep_their_front_face() {
    let dir = tempfile::tempdir().unwrap();
    let (doc, buf) = quad_gltf(json!([{"scale": [1.0, 1.0, -1.0], "mesh": 0}]), default_material(), &[]);
    let s = load_scene(&write_gltf(dir.path(), "m.gltf", doc, &buf)).unwrap();
    // A z-mirror of a +Z-facing quad in the z=0 plane must face −Z... after mirroring the
    // normal direction flips, and the winding is swapped so the front stays consistent.
    let t = &s.triangles[0];
    assert!(t.front_normal().dot(t.n[0]) > 0.99);
}

#[test]
fn materials_and_extensions_follow_the_spec() {
    let dir = tempfile::tempdir().unwrap();
    let mats = json!([
        {"pbrMetallicRoughness": {"metallicFactor": 0.25, "roughnessFactor": 0.75},
         "emissiveFactor": [1.0, 0.5, 0.0],
         "extensions": {
            "KHR_materials_emissive_strength": {"emissiveStrength": 8.0},
            "KHR_materials_ior": {"ior": 1.33},
            "KHR_materials_transmission": {"transmissionFactor": 0.9},
            "KHR_materials_specular": {"specularFactor": 0.4},
            "KHR_materials_volume": {
                "thicknessFactor": 0.1, "attenuationDistance": 2.0, "attenuationColor": [0.5, 1.0, 0.25]
            }
         },
         "alphaMode": "MASK", "alphaCutoff": 0.3, "doubleSided": true},
        {"emissiveFactor": [1.0, 1.0, 1.0]},
        // Thin-walled (thickness 0, the default) and infinite-distance volumes absorb nothing.
        {"extensions": {"KHR_materials_volume": {"attenuationDistance": 2.0, "attenuationColor": [0.5, 0.5, 0.5]}}},
        {"extensions": {"KHR_materials_volume": {"thicknessFactor": 1.0, "attenuationColor": [0.5, 0.5, 0.5]}}}
    ]);
    let used = json!([
        "KHR_materials_emissive_strength",
        "KHR_materials_ior",
        "KHR_materials_transmission",
        "KHR_materials_specular",
        "KHR_materials_volume"
    ]);
    let (doc, buf) = quad_gltf(json!([{"mesh": 0}]), mats, &[("extensionsUsed", used)]);
    let s = load_scene(&write_gltf(dir.path(), "m.gltf", doc, &buf)).unwrap();
    let m = &s.materials[0];
    assert_eq!(m.emissive, Vec3::new(8.0, 4.0, 0.0));
    assert_eq!((m.ior, m.transmission, m.specular, m.metallic, m.roughness), (1.33, 0.9, 0.4, 0.25, 0.75));
    assert_eq!(m.alpha_mode, AlphaMode::Mask(0.3));
    assert!(m.double_sided);
    // Defaults: emissive strength 1, ior 1.5, transmission 0, specular 1.
    let d = &s.materials[1];
    assert_eq!((d.emissive, d.ior, d.transmission, d.specular), (Vec3::ONE, 1.5, 0.0, 1.0));
    // White light turns attenuationColor after attenuationDistance: σ = −ln(colour)/distance.
    let want = Vec3::new(0.5f32.ln(), 0.0, 0.25f32.ln()) / -2.0;
    assert!(m.absorption.abs_diff_eq(want, 1e-6), "{}", m.absorption);
    assert_eq!(
        (d.absorption, s.materials[2].absorption, s.materials[3].absorption),
        (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO)
    );
}

/// A 2×1 RGBA PNG written through rtd's own LDR writer: left texel opaque, right transparent.
fn png_data_uri(dir: &Path) -> String {
    let p = dir.join("t.png");
    let img = image_rgba(&[[128, 64, 255, 255], [10, 200, 30, 0]]);
    std::fs::write(&p, &img).unwrap();
    format!("data:image/png;base64,{}", b64(&img))
}

/// Encodes a 1-row RGBA PNG by hand (stored zlib block) so the test needs no image crate.
fn image_rgba(px: &[[u8; 4]]) -> Vec<u8> {
    fn crc(data: &[u8]) -> u32 {
        let mut c = 0xffff_ffffu32;
        for &b in data {
            c ^= b as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 { 0xedb8_8320 ^ (c >> 1) } else { c >> 1 };
            }
        }
        !c
    }
    fn adler(data: &[u8]) -> u32 {
        let (mut a, mut b) = (1u32, 0u32);
        for &d in data {
            a = (a + d as u32) % 65521;
            b = (b + a) % 65521;
        }
        b << 16 | a
    }
    let mut raw = vec![0u8];
    for p in px {
        raw.extend(p);
    }
    let mut z = vec![0x78, 0x01, 1];
    z.extend((raw.len() as u16).to_le_bytes());
    z.extend((!(raw.len() as u16)).to_le_bytes());
    z.extend(&raw);
    z.extend(adler(&raw).to_be_bytes());
    let chunk = |t: &[u8], d: &[u8]| {
        let mut c = (d.len() as u32).to_be_bytes().to_vec();
        let mut td = t.to_vec();
        td.extend(d);
        c.extend(&td);
        c.extend(crc(&td).to_be_bytes());
        c
    };
    let mut ihdr = (px.len() as u32).to_be_bytes().to_vec();
    ihdr.extend(1u32.to_be_bytes());
    ihdr.extend([8, 6, 0, 0, 0]);
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    out.extend(chunk(b"IHDR", &ihdr));
    out.extend(chunk(b"IDAT", &z));
    out.extend(chunk(b"IEND", &[]));
    out
}

/// A texture whose `texCoord` is 1 reads `TEXCOORD_1`; the others keep reading set 0.
#[test]
fn a_texture_reads_the_uv_set_its_tex_coord_names() {
    let dir = tempfile::tempdir().unwrap();
    let uri = png_data_uri(dir.path());
    let mats = json!([{
        "pbrMetallicRoughness": {
            "baseColorTexture": {"index": 0, "texCoord": 1},
            "metallicRoughnessTexture": {"index": 0}
        }
    }]);
    let extra = [
        ("images", json!([{"uri": uri}])),
        ("samplers", json!([{"magFilter": 9728, "minFilter": 9728}])),
        ("textures", json!([{"source": 0, "sampler": 0}])),
    ];
    let (mut doc, mut buf) = quad_gltf(json!([{"mesh": 0}]), mats, &extra);
    // Set 1 is set 0 mirrored in u: texture u = 1 − quad x.
    let offset = buf.len();
    buf.extend(f32_bytes(&[1.0, 1.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0]));
    doc["buffers"][0]["byteLength"] = json!(buf.len());
    doc["bufferViews"].as_array_mut().unwrap().push(json!({"buffer": 0, "byteOffset": offset, "byteLength": 32}));
    doc["accessors"]
        .as_array_mut()
        .unwrap()
        .push(json!({"bufferView": 3, "componentType": 5126, "count": 4, "type": "VEC2"}));
    doc["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_1"] = json!(3);
    let s = load_scene(&write_gltf(dir.path(), "t.gltf", doc, &buf)).unwrap();
    assert!(s.warnings.iter().all(|w| !w.contains("TEXCOORD")), "{:?}", s.warnings);
    let bvh = SceneBvh::build(&s);
    let surface = |x: f32| {
        let hit = bvh.intersect(&s, Vec3::new(x, 0.5, 1.0), Vec3::NEG_Z, f32::INFINITY).unwrap();
        rtd::render::surface::Surface::new(&s, &hit).params
    };
    // The left texel is opaque blue-violet (128, 64, 255), the right one green (10, 200, 30).
    // Quad x = 0.2 is texture u = 0.2 in set 0 and 0.8 in set 1.
    let (left, right) = (surface(0.2), surface(0.8));
    assert!(
        left.base_color.y > 0.5 && left.base_color.z < 0.05,
        "set 1 at x 0.2 is the green texel: {}",
        left.base_color
    );
    assert!(right.base_color.z > 0.9, "set 1 at x 0.8 is the violet texel: {}", right.base_color);
    // Metallic-roughness reads set 0: the left texel's roughness G = 64/255 at x 0.2.
    assert!((left.roughness - 64.0 / 255.0).abs() < 1e-6, "{}", left.roughness);
    assert!((right.roughness - 200.0 / 255.0).abs() < 1e-6, "{}", right.roughness);
}

/// `KHR_materials_clearcoat` and `KHR_materials_sheen` reach the surface: factors × textures
/// (sheen colour sRGB, roughnesses from G and A), and a missing texture index is a warning.
#[test]
fn clearcoat_and_sheen_reach_the_surface() {
    let dir = tempfile::tempdir().unwrap();
    let uri = png_data_uri(dir.path());
    let mats = json!([{
        "extensions": {
            "KHR_materials_clearcoat": {
                "clearcoatFactor": 0.5, "clearcoatTexture": {"index": 0},
                "clearcoatRoughnessFactor": 0.8, "clearcoatRoughnessTexture": {"index": 0},
                "clearcoatNormalTexture": {"index": 0}
            },
            "KHR_materials_sheen": {
                "sheenColorFactor": [1.0, 0.5, 0.25], "sheenColorTexture": {"index": 0},
                "sheenRoughnessFactor": 0.6, "sheenRoughnessTexture": {"index": 7}
            }
        }
    }]);
    let extra = [
        ("images", json!([{"uri": uri}])),
        ("samplers", json!([{"magFilter": 9728, "minFilter": 9728}])),
        ("textures", json!([{"source": 0, "sampler": 0}])),
        ("extensionsUsed", json!(["KHR_materials_clearcoat", "KHR_materials_sheen"])),
    ];
    let (doc, buf) = quad_gltf(json!([{"mesh": 0}]), mats, &extra);
    let s = load_scene(&write_gltf(dir.path(), "t.gltf", doc, &buf)).unwrap();
    assert!(s.warnings.iter().any(|w| w.contains("clearcoatNormalTexture")), "{:?}", s.warnings);
    assert!(s.warnings.iter().any(|w| w.contains("texture 7")), "{:?}", s.warnings);
    assert!(s.warnings.iter().all(|w| !w.contains("unsupported")), "{:?}", s.warnings);
    let bvh = SceneBvh::build(&s);
    let hit = bvh.intersect(&s, Vec3::new(0.2, 0.5, 1.0), Vec3::NEG_Z, f32::INFINITY).unwrap();
    let l = rtd::render::surface::Surface::new(&s, &hit).params.layers;
    // The left texel is sRGB (128, 64, 255), alpha 255.
    let raw = Vec3::new(128.0, 64.0, 255.0) / 255.0;
    let srgb = raw.map(rtd::image::srgb_to_linear);
    assert!((l.clearcoat - 0.5 * raw.x).abs() < 1e-6, "{}", l.clearcoat);
    assert!((l.clearcoat_roughness - 0.8 * raw.y).abs() < 1e-6, "{}", l.clearcoat_roughness);
    assert!(l.sheen_color.abs_diff_eq(Vec3::new(1.0, 0.5, 0.25) * srgb, 1e-5), "{}", l.sheen_color);
    // The sheen roughness texture names no texture: the factor alone.
    assert_eq!(l.sheen_roughness, 0.6);
}

/// `specularColorTexture` is sRGB and multiplies into `specularColorFactor`.
#[test]
fn the_specular_colour_texture_tints_the_specular_colour() {
    let dir = tempfile::tempdir().unwrap();
    let uri = png_data_uri(dir.path());
    let mats = json!([{
        "extensions": {"KHR_materials_specular": {
            "specularColorFactor": [0.5, 1.0, 2.0],
            "specularColorTexture": {"index": 0}
        }}
    }]);
    let extra = [
        ("images", json!([{"uri": uri}])),
        ("samplers", json!([{"magFilter": 9728, "minFilter": 9728}])),
        ("textures", json!([{"source": 0, "sampler": 0}])),
        ("extensionsUsed", json!(["KHR_materials_specular"])),
    ];
    let (doc, buf) = quad_gltf(json!([{"mesh": 0}]), mats, &extra);
    let s = load_scene(&write_gltf(dir.path(), "t.gltf", doc, &buf)).unwrap();
    let bvh = SceneBvh::build(&s);
    let hit = bvh.intersect(&s, Vec3::new(0.8, 0.5, 1.0), Vec3::NEG_Z, f32::INFINITY).unwrap();
    let tint = rtd::render::surface::Surface::new(&s, &hit).params.specular_color;
    // The right texel is sRGB (10, 200, 30).
    let texel = Vec3::new(10.0, 200.0, 30.0).map(|c| rtd::image::srgb_to_linear(c / 255.0));
    let want = Vec3::new(0.5, 1.0, 2.0) * texel;
    assert!(tint.abs_diff_eq(want, 1e-5), "{tint} vs {want}");
}

#[test]
fn textures_are_linearised_transformed_and_cut_out() {
    let dir = tempfile::tempdir().unwrap();
    let uri = png_data_uri(dir.path());
    let mats = json!([{
        "pbrMetallicRoughness": {
            "baseColorTexture": {"index": 0, "extensions": {"KHR_texture_transform": {"offset": [0.5, 0.0], "scale": [0.5, 1.0]}}},
            "metallicRoughnessTexture": {"index": 0}
        },
        "alphaMode": "MASK"
    }]);
    let extra = [
        ("images", json!([{"uri": uri}])),
        ("samplers", json!([{"magFilter": 9728, "minFilter": 9728}])),
        ("textures", json!([{"source": 0, "sampler": 0}])),
        ("extensionsUsed", json!(["KHR_texture_transform"])),
    ];
    let (doc, buf) = quad_gltf(json!([{"mesh": 0}]), mats, &extra);
    let s = load_scene(&write_gltf(dir.path(), "t.gltf", doc, &buf)).unwrap();
    let m = &s.materials[0];
    assert_eq!(s.textures.len(), 2, "one sRGB and one linear decode of the same image");
    // uv (0.2, 0.5) → transform → (0.6, 0.5): the right texel (transparent, green).
    let p = m.evaluate(&s.textures, Vec2::new(0.2, 0.5).into());
    assert!((p.base_color - Vec3::new(0.003_035, 0.577_58, 0.012_983)).abs().max_element() < 1e-3, "{}", p.base_color);
    assert_eq!(p.alpha, 0.0);
    // Untransformed metallic-roughness at the left texel: G = 64/255 roughness, B = 1 metallic, linear.
    let p = m.evaluate(&s.textures, Vec2::new(0.2, 0.5).into());
    assert!((p.roughness - 64.0 / 255.0).abs() < 1e-6 && (p.metallic - 1.0).abs() < 1e-6, "{p:?}");
    // The cut-out lets rays through where the base colour texture's alpha is below 0.5:
    // texture u ≥ 0.5 is transparent, which the transform maps to quad u < 1.
    let bvh = SceneBvh::build(&s);
    assert!(bvh.intersect(&s, Vec3::new(0.5, 0.5, 1.0), Vec3::NEG_Z, f32::INFINITY).is_none());
    assert!(!bvh.occluded(&s, Vec3::new(0.5, 0.5, 1.0), Vec3::NEG_Z, 2.0));
}

#[test]
fn cameras_and_lights() {
    let dir = tempfile::tempdir().unwrap();
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let nodes = json!([
        {"mesh": 0, "children": [1, 2, 3, 4]},
        {"name": "persp", "camera": 0, "translation": [0.0, 0.0, 5.0]},
        {"name": "ortho", "camera": 1, "rotation": [0.0, s, 0.0, s]},
        {"translation": [1.0, 2.0, 3.0], "extensions": {"KHR_lights_punctual": {"light": 0}}},
        {"rotation": [-s, 0.0, 0.0, s], "extensions": {"KHR_lights_punctual": {"light": 1}}}
    ]);
    let extra = [
        (
            "cameras",
            json!([
                {"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.1}},
                {"type": "orthographic", "orthographic": {"xmag": 2.0, "ymag": 1.5, "znear": 0.1, "zfar": 10.0}}
            ]),
        ),
        (
            "extensions",
            json!({"KHR_lights_punctual": {"lights": [
                {"type": "point", "color": [1.0, 0.5, 0.5], "intensity": 6830.0},
                {"type": "directional", "intensity": 2049.0}
            ]}}),
        ),
        ("extensionsUsed", json!(["KHR_lights_punctual"])),
    ];
    let (doc, buf) = quad_gltf(nodes, default_material(), &extra);
    let sc = load_scene(&write_gltf(dir.path(), "c.gltf", doc, &buf)).unwrap();
    assert_eq!(sc.cameras.len(), 2);
    let (cam, _) = sc.select_camera(None).unwrap();
    assert_eq!(cam.name, "persp", "default is the first perspective camera");
    let (cam, warn) = sc.select_camera(Some("ortho")).unwrap();
    assert!(warn.is_none());
    assert_eq!(cam.projection, Projection::Orthographic { ymag: 1.5 });
    assert_eq!(cam.aspect_ratio, Some(2.0 / 1.5), "an orthographic camera's aspect is xmag / ymag");
    assert_eq!(cam.znear, 0.1);
    assert!((cam.forward - Vec3::NEG_X).length() < 1e-5, "{}", cam.forward);
    let (cam, _) = sc.select_camera(Some("0")).unwrap();
    assert_eq!(cam.projection, Projection::Perspective { yfov: 0.5 });
    assert_eq!(cam.aspect_ratio, None, "no aspectRatio in the file");
    assert_eq!(cam.znear, 0.1, "znear is the near clip");
    let e = sc.select_camera(Some("nope")).unwrap_err();
    assert_eq!(e, CameraError::NoSuchName { name: "nope".into(), available: vec!["persp".into(), "ortho".into()] });
    assert_eq!(e.to_string(), "no camera named 'nope' (cameras: persp, ortho)");
    let e = sc.select_camera(Some("7")).unwrap_err();
    assert_eq!(e, CameraError::IndexOutOfRange { index: 7, count: 2 });
    assert_eq!(e.to_string(), "camera index 7 out of range (scene has 2 cameras)");
    // Photometric glTF intensities become radiometric ones at 683 lm/W: 6830 cd is 10 W/sr and
    // 2049 lux is 3 W/m².
    assert!(sc
        .lights
        .contains(&Light::Point { position: Vec3::new(1.0, 2.0, 3.0), intensity: Vec3::new(10.0, 5.0, 5.0) }));
    let sun = sc.lights.iter().find_map(|l| match l {
        Light::Directional { irradiance, .. } => Some(*irradiance),
        _ => None,
    });
    assert_eq!(sun, Some(Vec3::splat(3.0)));
    // A −90° rotation about X turns the light's −Z into −Y: straight down.
    let down = sc.lights.iter().find_map(|l| match l {
        Light::Directional { direction, .. } => Some(*direction),
        _ => None,
    });
    assert!((down.unwrap() - Vec3::NEG_Y).length() < 1e-5);
}

#[test]
fn no_camera_gives_an_automatic_one_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let (doc, buf) = quad_gltf(json!([{"mesh": 0}]), default_material(), &[]);
    let s = load_scene(&write_gltf(dir.path(), "n.gltf", doc, &buf)).unwrap();
    let (cam, warn) = s.select_camera(None).unwrap();
    assert!(warn.unwrap().contains("automatic"));
    // The automatic camera sees the quad's centre.
    let p = cam.project(Vec3::new(0.5, 0.5, 0.0), 64, 64).unwrap().0;
    assert!((p - Vec2::splat(32.0)).length() < 1.0, "{p}");
}

#[test]
fn points_and_lines_are_skipped_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let (mut doc, buf) = quad_gltf(json!([{"mesh": 0}]), default_material(), &[]);
    doc["meshes"][0]["primitives"][0]["mode"] = json!(0);
    let s = load_scene(&write_gltf(dir.path(), "points.gltf", doc, &buf)).unwrap();
    assert!(s.triangles.is_empty());
    assert!(s.warnings.iter().any(|w| w.contains("skipped 1 primitives")), "{:?}", s.warnings);
}

#[test]
fn obj_with_mtl_maps_materials() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("m.mtl"),
        "newmtl glass\nKd 0 0 0\nNi 1.33\nillum 7\n\
         newmtl metal\nKd 0 0 0\nKs 0.9 0.6 0.3\nNs 200\n\
         newmtl lamp\nKd 0.5 0.5 0.5\nKe 4 4 2\n\
         newmtl plastic\nKd 0.8 0.1 0.1\nKs 0.5 0.5 0.5\nNs 1000\n",
    )
    .unwrap();
    std::fs::write(
        dir.path().join("m.obj"),
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\n\
         usemtl glass\nf 1/1 2/2 3/3\nusemtl metal\nf 1 3 4\nusemtl lamp\nf 1 2 4\nusemtl plastic\nf 2 3 4\n\
         f 1 1 2\n",
    )
    .unwrap();
    let s = load_scene(&dir.path().join("m.obj")).unwrap();
    assert_eq!(s.triangles.len(), 4);
    assert_eq!((s.skipped_nonfinite, s.skipped_degenerate), (0, 1));
    assert!(s.warnings.iter().any(|w| w.contains("degenerate")), "{:?}", s.warnings);
    let by_name = |n: &str| s.materials.iter().find(|m| m.name == n).unwrap();
    let g = by_name("glass");
    assert_eq!((g.transmission, g.ior, g.roughness), (1.0, 1.33, 0.0));
    let m = by_name("metal");
    assert_eq!((m.metallic, m.base_color.truncate()), (1.0, Vec3::new(0.9, 0.6, 0.3)));
    assert!((m.roughness - (2.0f32 / 202.0).sqrt().sqrt()).abs() < 1e-6);
    assert_eq!(by_name("lamp").emissive, Vec3::new(4.0, 4.0, 2.0));
    let p = by_name("plastic");
    assert_eq!((p.metallic, p.specular), (0.0, 0.5));
    // OBJ's v runs upwards; rtd flips it so that textures read top row first.
    assert_eq!(s.triangles[0].uv[2], Vec2::new(1.0, 0.0));
    // A missing MTL is a warning, not an error.
    std::fs::write(dir.path().join("n.obj"), "mtllib gone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let s = load_scene(&dir.path().join("n.obj")).unwrap();
    assert_eq!(s.triangles.len(), 1);
}

#[test]
fn bundled_scenes_load_without_warnings() {
    for name in ["cornell-box", "glass-and-metals", "textured-interior", "small-lights"] {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes").join(format!("{name}.gltf"));
        let s = load_scene(&p).unwrap();
        assert!(s.warnings.is_empty(), "{name}: {:?}", s.warnings);
        assert!(!s.cameras.is_empty() && s.emissive_triangle_count() > 0, "{name}");
    }
}

/// KHR_materials_unlit is read (no "unsupported extension" warning), and required files load.
#[test]
fn unlit_materials_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = common::cornell_json();
    doc["materials"][0]["extensions"] = serde_json::json!({"KHR_materials_unlit": {}});
    doc["extensionsUsed"] = serde_json::json!(["KHR_materials_unlit"]);
    doc["extensionsRequired"] = serde_json::json!(["KHR_materials_unlit"]);
    let path = dir.path().join("unlit.gltf");
    std::fs::write(&path, serde_json::to_string(&doc).unwrap()).unwrap();
    let scene = rtd::scene::load_scene(&path).unwrap();
    assert!(scene.materials[0].unlit && !scene.materials[1].unlit);
    assert!(scene.warnings.iter().all(|w| !w.contains("unlit")), "{:?}", scene.warnings);
}

/// COLOR_0 (float RGB, or normalised u8 RGBA whose alpha is not read) multiplies the base
/// colour, in the path tracer and in the guide pass's albedo alike: a white unlit quad with
/// uniform vertex colour c renders as c exactly, and its guide albedo is c.
#[test]
fn vertex_colours_multiply_the_base_colour() {
    let dir = tempfile::tempdir().unwrap();
    let want = Vec3::new(0.2, 0.4, 0.6);
    let unlit =
        json!([{"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1]}, "extensions": {"KHR_materials_unlit": {}}}]);
    let node = json!([{"mesh": 0}, {"camera": 0, "translation": [0.5, 0.5, 2.0]}]);
    let cameras = json!([{"type": "perspective", "perspective": {"yfov": 0.2, "znear": 0.01}}]);
    let float: Vec<u8> = f32_bytes(&[0.2, 0.4, 0.6].repeat(4));
    // Normalised u8 RGBA: 51/255 = 0.2, 102/255 = 0.4, 153/255 = 0.6, alpha ignored.
    let bytes: Vec<u8> = [51u8, 102, 153, 7].repeat(4);
    for (name, data, ty, component) in [("float", float, "VEC3", 5126), ("u8", bytes, "VEC4", 5121)] {
        let (mut doc, mut buf) = quad_gltf(node.clone(), unlit.clone(), &[("cameras", cameras.clone())]);
        doc["scenes"][0]["nodes"] = json!([0, 1]);
        let offset = buf.len();
        buf.extend(&data);
        doc["buffers"][0]["byteLength"] = json!(buf.len());
        doc["bufferViews"]
            .as_array_mut()
            .unwrap()
            .push(json!({"buffer": 0, "byteOffset": offset, "byteLength": data.len()}));
        let mut accessor = json!({"bufferView": 3, "componentType": component, "count": 4, "type": ty});
        if component != 5126 {
            accessor["normalized"] = json!(true);
        }
        doc["accessors"].as_array_mut().unwrap().push(accessor);
        doc["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = json!(3);
        doc["extensionsUsed"] = json!(["KHR_materials_unlit"]);
        let path = write_gltf(dir.path(), &format!("{name}.gltf"), doc, &buf);
        let scene = load_scene(&path).unwrap();
        assert_eq!(scene.vertex_colors.len(), scene.triangles.len(), "{name}");
        let c = scene.vertex_color(0, Vec3::splat(1.0 / 3.0));
        assert!((c - want).abs().max_element() < 1e-6, "{name}: {c}");
        let camera = scene.cameras[0].clone();
        let bvh = SceneBvh::build(&scene);
        let guide =
            rtd::guide::GuidePass::render(&scene, &bvh, &camera, &rtd::guide::GuideSettings::new(6, 6)).unwrap();
        let prepared = rtd::render::RenderScene::new(scene);
        let tracer = rtd::render::PathTracer::new(&prepared, camera, rtd::render::RenderSettings::new(6, 6)).unwrap();
        let mut film = tracer.film();
        tracer.render(&mut film, 2).unwrap();
        for (p, a) in film.beauty().pixels.iter().zip(&guide.albedo.pixels) {
            assert!((*p - want).abs().max_element() < 1e-5, "{name}: pixel {p}");
            assert!((*a - want).abs().max_element() < 1e-5, "{name}: guide albedo {a}");
        }
    }
}
