//! Scene builders shared by the integration tests.
#![allow(dead_code)]

use glam::{Vec2, Vec3};
use rtd::render::{Film, PathTracer, RenderScene, RenderSettings};
use rtd::scene::{Camera, Environment, Material, Scene, Triangle};

pub mod bomb;
pub mod cli;
pub mod gltf;

/// A material with the given base colour, roughness, metallic and transmission.
pub fn material(color: Vec3, roughness: f32, metallic: f32, transmission: f32) -> Material {
    Material { base_color: color.extend(1.0), roughness, metallic, transmission, ..Material::default() }
}

/// Adds a triangle with flat normals.
pub fn tri(scene: &mut Scene, p: [Vec3; 3], material: u32) {
    let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
    scene.push_triangle(Triangle { p, n: [n; 3], uv: [Vec2::ZERO, Vec2::X, Vec2::ONE], material });
}

/// Adds a quad a-b-c-d (counter-clockwise seen from its front).
pub fn quad(scene: &mut Scene, a: Vec3, b: Vec3, c: Vec3, d: Vec3, material: u32) {
    tri(scene, [a, b, c], material);
    tri(scene, [a, c, d], material);
}

/// Adds a UV sphere with smooth normals facing outwards.
pub fn sphere(scene: &mut Scene, center: Vec3, r: f32, material: u32, nu: u32, nv: u32) {
    let pt = |i: u32, j: u32| {
        let th = std::f32::consts::PI * j as f32 / nv as f32;
        let ph = std::f32::consts::TAU * i as f32 / nu as f32;
        Vec3::new(th.sin() * ph.cos(), th.cos(), -th.sin() * ph.sin())
    };
    for j in 0..nv {
        for i in 0..nu {
            let (a, b, c, d) = (pt(i, j), pt(i, j + 1), pt(i + 1, j + 1), pt(i + 1, j));
            for t in [[a, b, c], [a, c, d]] {
                scene.push_triangle(Triangle { p: t.map(|n| center + n * r), n: t, uv: [Vec2::ZERO; 3], material });
            }
        }
    }
}

/// The bundled Cornell box.
pub fn cornell() -> Scene {
    rtd::scene::load_scene(&repo_path("scenes/cornell-box.gltf")).expect("bundled Cornell box loads")
}

/// A path relative to the repository root.
pub fn repo_path(p: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// Renders `spp` samples of `scene` through `camera`.
pub fn render(scene: Scene, camera: Camera, settings: RenderSettings, spp: u32) -> Film {
    let prepared = RenderScene::new(scene);
    let tracer = PathTracer::new(&prepared, camera, settings).unwrap();
    let mut film = tracer.film();
    tracer.render(&mut film, spp).unwrap();
    film
}

/// A scene with only a constant environment.
pub fn furnace(env: f32) -> Scene {
    Scene { environment: Environment::Constant(Vec3::splat(env)), ..Scene::default() }
}

/// Mean of a set of pixels' luminance-free RGB average.
pub fn mean(pixels: &[Vec3]) -> f64 {
    pixels.iter().map(|p| (p.x + p.y + p.z) as f64 / 3.0).sum::<f64>() / pixels.len().max(1) as f64
}

/// One part of a multi-part EXR: its name and its (channel, samples) pairs.
pub type ExrPart<'a> = (&'a str, Vec<(&'a str, Vec<f32>)>);

/// Writes a multi-part EXR as Blender 5 writes its render passes: one part per pass, each named
/// `ViewLayer.<pass>`, with its own channels (`R,G,B[,A]` or `X,Y,Z`).
pub fn write_multipart_exr(path: &std::path::Path, size: (usize, usize), parts: &[ExrPart]) {
    write_multipart_exr_as(path, size, parts, false)
}

/// [`write_multipart_exr`] with every channel stored as 16-bit half floats when `half` (as
/// Blender writes by default).
pub fn write_multipart_exr_as(path: &std::path::Path, (w, h): (usize, usize), parts: &[ExrPart], half: bool) {
    use exr::prelude::*;
    let samples = |s: &Vec<f32>| match half {
        true => FlatSamples::F16(s.iter().map(|&v| f16::from_f32(v)).collect()),
        false => FlatSamples::F32(s.clone()),
    };
    let layers: Vec<Layer<AnyChannels<FlatSamples>>> = parts
        .iter()
        .map(|(name, channels)| {
            let list: SmallVec<[AnyChannel<FlatSamples>; 4]> =
                channels.iter().map(|(n, s)| AnyChannel::new(*n, samples(s))).collect();
            Layer::new((w, h), LayerAttributes::named(*name), Encoding::FAST_LOSSLESS, AnyChannels::sort(list))
        })
        .collect();
    let image = Image::from_layers(ImageAttributes::new(IntegerBounds::from_dimensions((w, h))), layers);
    image.write().to_file(path).expect("write a multi-part EXR");
}

/// Every file under `dir`, by relative path.
pub fn files_under(dir: &std::path::Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    fn walk(root: &std::path::Path, dir: &std::path::Path, out: &mut std::collections::BTreeMap<String, Vec<u8>>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(root, &p, out);
            } else {
                out.insert(p.strip_prefix(root).unwrap().display().to_string(), std::fs::read(&p).unwrap());
            }
        }
    }
    let mut out = std::collections::BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

/// Every file of an `rtd datagen` dataset, with the manifest's wall-clock `seconds` zeroed:
/// what two runs of the same options must agree on.
pub fn dataset_files(dir: &std::path::Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    let mut out = files_under(dir);
    let mut manifest: serde_json::Value = serde_json::from_slice(&out["manifest.json"]).unwrap();
    for v in manifest["views"].as_array_mut().unwrap() {
        v["seconds"] = 0.0.into();
    }
    out.insert("manifest.json".into(), serde_json::to_vec_pretty(&manifest).unwrap());
    out
}

/// The bundled Cornell box's glTF JSON with its buffer URIs made absolute, so an edited copy
/// can be written anywhere.
pub fn cornell_json() -> serde_json::Value {
    let mut doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(repo_path("scenes/cornell-box.gltf")).unwrap()).unwrap();
    for b in doc["buffers"].as_array_mut().unwrap() {
        if let Some(uri) = b["uri"].as_str().filter(|u| !u.starts_with("data:")) {
            b["uri"] = repo_path("scenes").join(uri).display().to_string().into();
        }
    }
    doc
}
