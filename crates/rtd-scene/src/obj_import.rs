use std::path::Path;

use glam::{Vec2, Vec3, Vec4};

use crate::{Material, Scene, SceneError, Texture, TextureRef, Triangle, Wrap};

/// Loads an OBJ file and its MTL materials. OBJ has no cameras: callers supply one.
///
/// MTL mapping: `Kd`/`map_Kd` → base colour; `Ks` with `Ns` → a glossy dielectric layer
/// (GGX α = √(2/(Ns+2))); black `Kd` with non-zero `Ks` → a metal of colour `Ks`;
/// `Ke` → emission; `illum` 4/6/7/9, `d` < 1 or `Tr` > 0 → glass with IOR `Ni`.
pub fn load_obj(path: &Path) -> Result<Scene, SceneError> {
    let (models, mtl) = parse_obj(path)?;
    let mut scene = Scene::default();
    let dir = path.parent().unwrap_or(Path::new("."));
    match mtl {
        Ok(mats) => {
            for m in &mats {
                let mat = convert_material(m, dir, &mut scene);
                scene.materials.push(mat);
            }
        }
        Err(e) => scene.warnings.push(format!("materials not loaded ({e}); using the default material")),
    }
    let default_material = scene.materials.len() as u32;
    scene.materials.push(Material {
        metallic: 0.0,
        name: "obj-default".into(),
        base_color: Vec4::new(0.8, 0.8, 0.8, 1.0),
        ..Material::default()
    });

    for model in &models {
        let mesh = &model.mesh;
        let pos = |i: u32| {
            let i = i as usize * 3;
            Vec3::new(mesh.positions[i], mesh.positions[i + 1], mesh.positions[i + 2])
        };
        let nrm = |i: u32| {
            let i = i as usize * 3;
            if mesh.normals.len() >= i + 3 {
                Vec3::new(mesh.normals[i], mesh.normals[i + 1], mesh.normals[i + 2])
            } else {
                Vec3::ZERO
            }
        };
        // OBJ's v runs bottom-up; rtd's textures are stored top row first.
        let uv = |i: u32| {
            let i = i as usize * 2;
            if mesh.texcoords.len() >= i + 2 {
                Vec2::new(mesh.texcoords[i], 1.0 - mesh.texcoords[i + 1])
            } else {
                Vec2::ZERO
            }
        };
        let material = mesh.material_id.map(|m| m as u32).filter(|&m| m < default_material).unwrap_or(default_material);
        let nverts = (mesh.positions.len() / 3) as u32;
        for c in mesh.indices.chunks_exact(3) {
            let t = [c[0], c[1], c[2]];
            // tobj refuses such faces itself (FaceVertexOutOfBounds); this guard keeps a change
            // there from becoming an index panic here.
            if t.iter().any(|&i| i >= nverts) {
                return Err(SceneError::new(path, "a face names a vertex the file lacks"));
            }
            scene.push_triangle(Triangle { p: t.map(pos), n: t.map(nrm), uv: t.map(uv), material });
        }
    }
    scene.finish_load(path)?;
    Ok(scene)
}

/// An OBJ file's models and, separately, the outcome of loading its materials.
type ObjContents = (Vec<tobj::Model>, Result<Vec<tobj::Material>, tobj::LoadError>);

/// Parses the OBJ file and its MTL libraries (resolved next to it, as `tobj::load_obj` does).
/// Opening the file ourselves keeps the I/O error, so that a missing file reads `PATH: no such file`.
fn parse_obj(path: &Path) -> Result<ObjContents, SceneError> {
    let opts = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let file = std::fs::File::open(path).map_err(|e| SceneError::io(path, e))?;
    let mut reader = std::io::BufReader::new(file);
    // tobj panics on some malformed OBJ and MTL lines (found by fuzzing): fenced.
    rtd_image::contain_panic(|| {
        tobj::load_obj_buf(&mut reader, &opts, |mtl| {
            let full = match path.parent() {
                Some(parent) => parent.join(mtl),
                None => mtl.to_path_buf(),
            };
            tobj::load_mtl(full)
        })
    })
    .map_err(|e| SceneError::new(path, e))?
    .map_err(|source| SceneError::Obj { path: path.to_path_buf(), source })
}

fn parse_vec3(s: Option<&String>) -> Option<Vec3> {
    let v: Vec<f32> = s?.split_whitespace().filter_map(|x| x.parse().ok()).collect();
    match v.as_slice() {
        [g] => Some(Vec3::splat(*g)),
        [r, g, b, ..] => Some(Vec3::new(*r, *g, *b)),
        _ => None,
    }
}

fn convert_material(m: &tobj::Material, dir: &Path, scene: &mut Scene) -> Material {
    let kd = m.diffuse.map(Vec3::from).unwrap_or(Vec3::splat(0.8));
    let ks = m.specular.map(Vec3::from).unwrap_or(Vec3::ZERO);
    let ns = m.shininess.unwrap_or(0.0).max(0.0);
    let ke = m.emissive.map(Vec3::from).unwrap_or(Vec3::ZERO);
    let tr = m.unknown_param.get("Tr").and_then(|s| s.trim().parse::<f32>().ok()).unwrap_or(0.0);
    let d = m.dissolve.unwrap_or(1.0);
    let illum = m.illumination_model.unwrap_or(2);
    // Blinn-Phong exponent to GGX: α = √(2/(Ns+2)), perceptual roughness = √α.
    let roughness = if ns > 0.0 { (2.0 / (ns + 2.0)).sqrt().sqrt() } else { 1.0 };
    let is_glass = matches!(illum, 4 | 6 | 7 | 9) || d < 1.0 || tr > 0.0;
    let is_metal = !is_glass && kd.max_element() <= 0.0 && ks.max_element() > 0.0;
    let ks_max = ks.max_element();
    let mut mat = Material { name: m.name.clone(), metallic: 0.0, roughness, emissive: ke, ..Material::default() };
    if is_glass {
        let tf = parse_vec3(m.unknown_param.get("Tf")).unwrap_or(Vec3::ONE);
        mat.base_color = tf.min(Vec3::ONE).extend(1.0);
        mat.transmission = 1.0;
        mat.ior = m.optical_density.filter(|&n| n >= 1.0).unwrap_or(1.5);
        mat.roughness = if ns > 0.0 { roughness } else { 0.0 };
    } else if is_metal {
        mat.base_color = ks.min(Vec3::ONE).extend(1.0);
        mat.metallic = 1.0;
    } else {
        mat.base_color = kd.min(Vec3::ONE).extend(1.0);
        mat.specular = ks_max.min(1.0);
        mat.specular_color = if ks_max > 0.0 { ks / ks_max } else { Vec3::ONE };
        if ks_max <= 0.0 {
            mat.roughness = 1.0;
        }
    }
    if let Some(tex) = &m.diffuse_texture {
        let file = dir.join(tex.replace('\\', "/"));
        match load_texture(&file) {
            Ok(t) => {
                scene.textures.push(t);
                mat.base_color_texture = Some(TextureRef::plain(scene.textures.len() as u32 - 1));
            }
            Err(e) => scene.warnings.push(format!("material {}: texture not loaded: {e}", m.name)),
        }
    }
    mat
}

/// Decodes the image at `path` as a texture, under rtd's image size limits (checked from the
/// header, before decoding) and the parser fence; errors name the file.
fn load_texture(path: &Path) -> Result<Texture, String> {
    let named = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let open = || image::ImageReader::open(path)?.with_guessed_format();
    let (w, h) = open().map_err(|e| named(&e))?.into_dimensions().map_err(|e| named(&e))?;
    rtd_image::check_image_size(path, w as usize, h as usize).map_err(|e| e.to_string())?;
    let decoded = rtd_image::contain_panic(|| open().map_err(|e| named(&e))?.decode().map_err(|e| named(&e)))
        .map_err(|e| named(&e))??;
    let img = decoded.to_rgba8();
    if img.dimensions() != (w, h) {
        let (dw, dh) = img.dimensions();
        return Err(named(&format!("header says {w}x{h} but the pixel data is {dw}x{dh}")));
    }
    let (width, height) = img.dimensions();
    let texels = img.pixels().map(|p| p.0).collect();
    Ok(Texture::from_rgba8(width, height, texels, true, Wrap::Repeat, Wrap::Repeat, false))
}
