use std::path::{Path, PathBuf};

use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};

use crate::gltf_accessors::{check_buffer_views, check_indices, check_primitive, MeshSite};
use crate::gltf_material::{convert_material, TextureCache};
use crate::light::LUMENS_PER_WATT;
use crate::{Camera, Light, Material, Projection, Scene, SceneError, Triangle, TriangleExtras};

/// glTF extensions rtd implements; a file that *requires* any other is rejected by name.
pub const SUPPORTED_GLTF_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_materials_specular",
    "KHR_texture_transform",
    "KHR_materials_unlit",
    "KHR_materials_volume",
    "KHR_materials_clearcoat",
    "KHR_materials_sheen",
];

/// Loads a `.gltf` (external or embedded buffers) or `.glb` file into a flat [`Scene`].
///
/// A missing file reads `PATH: no such file` ([`SceneError::Io`]). A structurally corrupt file is
/// refused: a buffer view past the end of its buffer ([`SceneError::BufferView`]), or an accessor
/// of a triangle mesh whose data runs past its buffer view, whose type rtd cannot read, or whose
/// indices name missing vertices ([`SceneError::Accessor`], naming the mesh and accessor).
/// Points and lines primitives are skipped with a warning.
pub fn load_gltf(path: &Path) -> Result<Scene, SceneError> {
    load_gltf_scene(path, None)
}

/// [`load_gltf`] of the file's scene named or numbered `choice` (its `name`, or its index), or
/// its default scene (else the first) when `choice` is None. A file with several scenes loaded
/// without a choice says so in a warning; an unknown choice is an error listing the scenes.
pub fn load_gltf_scene(path: &Path, choice: Option<&str>) -> Result<Scene, SceneError> {
    let GltfFile { document, buffers, images } = read_gltf(path)?;
    let mut scene = Scene::default();
    for ext in document.extensions_used().filter(|e| !SUPPORTED_GLTF_EXTENSIONS.contains(e)) {
        scene.warnings.push(format!("ignoring unsupported optional extension {ext}"));
    }
    let mut textures = TextureCache::new(&document, &images);
    for m in document.materials() {
        let mat = convert_material(&m, &mut textures, &mut scene);
        scene.materials.push(mat);
    }
    let default_material = scene.materials.len() as u32;
    scene.materials.push(Material::default());

    let gscene = pick_scene(path, &document, choice, &mut scene)?;
    let read_set1 = textures.uses_set1();
    let skipped_primitives = match gscene {
        Some(gscene) => {
            let mut nodes = NodeVisitor { path, buffers: &buffers, default_material, read_set1, skipped_primitives: 0 };
            nodes.visit(&gscene, &mut scene)?;
            nodes.skipped_primitives
        }
        None => 0,
    };
    scene.textures = textures.into_textures();
    if skipped_primitives > 0 {
        scene
            .warnings
            .push(format!("skipped {skipped_primitives} primitives that are not triangles or have no positions"));
    }
    scene.finish_load(path)?;
    Ok(scene)
}

/// A parsed and validated glTF document with its buffers and images loaded.
struct GltfFile {
    document: gltf::Document,
    buffers: Vec<gltf::buffer::Data>,
    images: Vec<gltf::image::Data>,
}

/// Reads, parses and validates a glTF file and loads its buffers and images.
fn read_gltf(path: &Path) -> Result<GltfFile, SceneError> {
    let bytes = std::fs::read(path).map_err(|e| SceneError::io(path, e))?;
    // The gltf crate panics on some malformed files (found by fuzzing): fenced.
    rtd_image::contain_panic(|| parse_gltf(path, &bytes)).map_err(|e| SceneError::new(path, e))?
}

/// [`read_gltf`]'s parsing of `bytes`, read from `path`.
fn parse_gltf(path: &Path, bytes: &[u8]) -> Result<GltfFile, SceneError> {
    let gltf_err = |stage: &'static str| move |source| SceneError::Gltf { path: path.to_path_buf(), stage, source };
    // Check required extensions before validation so the error can name the extension.
    let raw = gltf::Gltf::from_slice_without_validation(bytes).map_err(gltf_err("malformed glTF"))?;
    if let Some(ext) = raw.document.extensions_required().find(|e| !SUPPORTED_GLTF_EXTENSIONS.contains(e)) {
        return Err(SceneError::UnsupportedGltfExtension {
            path: path.to_path_buf(),
            extension: ext.to_string(),
            supported: SUPPORTED_GLTF_EXTENSIONS,
        });
    }
    let gltf::Gltf { document, blob } = gltf::Gltf::from_slice(bytes).map_err(gltf_err("invalid glTF"))?;
    check_buffer_views(&document, path)?;
    let base = path.parent();
    let buffers = gltf::import_buffers(&document, base, blob).map_err(gltf_err("cannot load buffers"))?;
    // Image by image (as `gltf::import_images` does), so that an error names the image.
    let images = document
        .images()
        .map(|image| {
            let data = gltf::image::Data::from_source(image.source(), base, &buffers).map_err(|source| {
                SceneError::GltfImage { path: path.to_path_buf(), image: image_label(&image), source }
            })?;
            // rtd's own pixel limit, before the texture is widened to f32 with mips (about 21 bytes
            // a texel): the decoder's 512 MiB bound alone lets an 11585² texture through.
            let name = PathBuf::from(format!("image {}", image_label(&image)));
            rtd_image::check_image_size(&name, data.width as usize, data.height as usize)
                .map_err(|e| SceneError::new(path, e))?;
            Ok(data)
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(GltfFile { document, buffers, images })
}

/// An image's index and where it comes from: `2 ("wood.png")`, `0 ("name", buffer view 3)`, or
/// `1 (embedded data)` for a `data:` URI.
fn image_label(image: &gltf::Image) -> String {
    let source = match image.source() {
        gltf::image::Source::Uri { uri, .. } if uri.starts_with("data:") => "embedded data".to_string(),
        gltf::image::Source::Uri { uri, .. } => format!("{uri:?}"),
        gltf::image::Source::View { view, .. } => format!("buffer view {}", view.index()),
    };
    match image.name() {
        Some(name) => format!("{} ({name:?}, {source})", image.index()),
        None => format!("{} ({source})", image.index()),
    }
}

/// The scene `choice` names (by name, then by index), else the default one, else the first.
fn pick_scene<'a>(
    path: &Path,
    document: &'a gltf::Document,
    choice: Option<&str>,
    scene: &mut Scene,
) -> Result<Option<gltf::Scene<'a>>, SceneError> {
    let label = |s: &gltf::Scene| format!("{} {:?}", s.index(), s.name().unwrap_or(""));
    let Some(wanted) = choice else {
        let picked = document.default_scene().or_else(|| document.scenes().next());
        if let (Some(p), n @ 2..) = (&picked, document.scenes().len()) {
            scene.warnings.push(format!("the file has {n} scenes; rendering scene {} (choose with --scene)", label(p)));
        }
        return Ok(picked);
    };
    let by_name = document.scenes().find(|s| s.name() == Some(wanted));
    let by_index = || wanted.parse::<usize>().ok().and_then(|i| document.scenes().nth(i));
    match by_name.or_else(by_index) {
        Some(s) => Ok(Some(s)),
        None => {
            let all: Vec<String> = document.scenes().map(|s| label(&s)).collect();
            let have = if all.is_empty() { "none".to_string() } else { all.join(", ") };
            Err(SceneError::new(path, format!("no scene {wanted:?} (scenes: {have})")))
        }
    }
}

/// Walks a glTF scene's node tree, adding meshes, cameras and lights in world space.
struct NodeVisitor<'a> {
    path: &'a Path,
    buffers: &'a [gltf::buffer::Data],
    default_material: u32,
    /// Whether to read `TEXCOORD_1` (some texture reads it).
    read_set1: bool,
    /// Primitives skipped because they are points or lines or have no positions.
    skipped_primitives: usize,
}

impl NodeVisitor<'_> {
    /// Visits the scene's nodes depth-first in file order (the order cameras are numbered in).
    fn visit(&mut self, gscene: &gltf::Scene, scene: &mut Scene) -> Result<(), SceneError> {
        let mut stack: Vec<(gltf::Node, Mat4)> = gscene.nodes().map(|n| (n, Mat4::IDENTITY)).collect();
        stack.reverse();
        // glTF nodes form trees: a node reached twice is in a cycle (which would never end) or
        // under two parents (which doubles the work at each such level).
        let mut seen = std::collections::HashSet::new();
        while let Some((node, parent)) = stack.pop() {
            if !seen.insert(node.index()) {
                let message =
                    format!("node {} has two parents or lies in a cycle: glTF nodes must form trees", node.index());
                return Err(SceneError::new(self.path, message));
            }
            let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
            // As NaN vertices are: nothing under such a node has a right place.
            if !world.is_finite() {
                let name = node.name().map(|n| format!(" ({n:?})")).unwrap_or_default();
                let message =
                    format!("node {}{name} has a non-finite transform (NaN, or past f32's range)", node.index());
                return Err(SceneError::new(self.path, message));
            }
            if let Some(mesh) = node.mesh() {
                let site = MeshSite { path: self.path, index: mesh.index(), name: mesh.name() };
                for prim in mesh.primitives() {
                    if !self.add_primitive(&prim, site, world, scene)? {
                        self.skipped_primitives += 1;
                    }
                }
            }
            if let Some(cam) = node.camera() {
                scene.cameras.push(convert_camera(&cam, &node, world, scene.cameras.len()));
            }
            if let Some(light) = node.light() {
                scene.lights.push(convert_light(&light, world));
            }
            // Push children in reverse so that they pop in file order (depth-first, node order).
            let children: Vec<gltf::Node> = node.children().collect();
            for child in children.into_iter().rev() {
                stack.push((child, world));
            }
        }
        Ok(())
    }

    /// Adds one primitive's triangles in world space. Returns `Ok(false)` for a primitive skipped
    /// as unusual (points or lines, or no positions), and an error for a corrupt one.
    fn add_primitive(
        &self,
        prim: &gltf::Primitive,
        site: MeshSite,
        world: Mat4,
        scene: &mut Scene,
    ) -> Result<bool, SceneError> {
        use gltf::mesh::Mode;
        if !matches!(prim.mode(), Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
            return Ok(false);
        }
        check_primitive(prim, site)?;
        let reader = prim.reader(|b| self.buffers.get(b.index()).map(|d| d.0.as_slice()));
        let Some(positions) = reader.read_positions() else {
            return Ok(false);
        };
        let positions: Vec<Vec3> = positions.map(|p| world.transform_point3(Vec3::from(p))).collect();
        let m3 = Mat3::from_mat4(world);
        let normal_matrix = m3.inverse().transpose();
        let normals: Option<Vec<Vec3>> =
            reader.read_normals().map(|n| n.map(|n| (normal_matrix * Vec3::from(n)).normalize_or_zero()).collect());
        let tangents: Option<Vec<Vec4>> = reader
            .read_tangents()
            .map(|t| t.map(|t| (m3 * Vec3::new(t[0], t[1], t[2])).normalize_or_zero().extend(t[3])).collect());
        let uvs: Option<Vec<Vec2>> = reader.read_tex_coords(0).map(|t| t.into_f32().map(Vec2::from).collect());
        let uv1: Option<Vec<Vec2>> = match self.read_set1 {
            true => reader.read_tex_coords(1).map(|t| t.into_f32().map(Vec2::from).collect()),
            false => None,
        };
        // COLOR_0 multiplies the base colour (its alpha is not read).
        let colors: Option<Vec<Vec3>> = reader.read_colors(0).map(|c| c.into_rgb_f32().map(Vec3::from).collect());
        let indices: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
            None => (0..positions.len() as u32).collect(),
        };
        check_indices(prim, &indices, positions.len(), site)?;
        // A mirroring transform flips winding; swap two vertices so front faces stay front.
        let mirrored = m3.determinant() < 0.0;
        let material = prim.material().index().map(|i| i as u32).unwrap_or(self.default_material);
        for mut t in triangles(prim.mode(), &indices) {
            if mirrored {
                t.swap(1, 2);
            }
            let triangle = Triangle {
                p: t.map(|i| positions[i as usize]),
                n: t.map(|i| attribute(&normals, i, Vec3::ZERO)),
                uv: t.map(|i| attribute(&uvs, i, Vec2::ZERO)),
                material,
            };
            let extras = TriangleExtras {
                colors: colors.as_ref().map(|_| t.map(|i| attribute(&colors, i, Vec3::ONE))),
                uv1: uv1.as_ref().map(|_| t.map(|i| attribute(&uv1, i, Vec2::ZERO))),
                tangents: tangents.as_ref().map(|_| t.map(|i| attribute(&tangents, i, Vec4::ZERO))),
            };
            scene.push_triangle_with(triangle, extras);
        }
        Ok(true)
    }
}

/// A camera node's camera; unnamed cameras take the node's name, else `camera{number}`.
fn convert_camera(cam: &gltf::Camera, node: &gltf::Node, world: Mat4, number: usize) -> Camera {
    let name = cam.name().or(node.name()).map(str::to_string).unwrap_or_else(|| format!("camera{number}"));
    let (projection, aspect, znear) = match cam.projection() {
        gltf::camera::Projection::Perspective(p) => {
            (Projection::Perspective { yfov: p.yfov() }, p.aspect_ratio(), p.znear())
        }
        gltf::camera::Projection::Orthographic(o) => {
            (Projection::Orthographic { ymag: o.ymag().abs() }, Some(o.xmag().abs() / o.ymag().abs()), o.znear())
        }
    };
    // znear is along the camera's own axis; the node's scale, which the camera drops, would
    // scale it too (glTF cameras carry no scale in practice).
    Camera::from_matrix(name, world, projection).with_aspect_ratio(aspect).with_znear(znear)
}

fn convert_light(light: &gltf::khr_lights_punctual::Light, world: Mat4) -> Light {
    // Photometric (cd, lux) to radiometric (W/sr, W/m²).
    let color = Vec3::from(light.color()) * (light.intensity() / LUMENS_PER_WATT);
    let position = world.w_axis.truncate();
    let direction = world.transform_vector3(Vec3::NEG_Z).normalize_or(Vec3::NEG_Z);
    match light.kind() {
        gltf::khr_lights_punctual::Kind::Directional => Light::Directional { direction, irradiance: color },
        gltf::khr_lights_punctual::Kind::Point => Light::Point { position, intensity: color },
        gltf::khr_lights_punctual::Kind::Spot { inner_cone_angle, outer_cone_angle } => {
            Light::spot(position, direction, color, inner_cone_angle, outer_cone_angle)
        }
    }
}

/// The vertex triples of a triangle list, strip or fan; none for points and lines.
fn triangles(mode: gltf::mesh::Mode, indices: &[u32]) -> Vec<[u32; 3]> {
    use gltf::mesh::Mode;
    match mode {
        Mode::Triangles => indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        // Strips alternate winding; fans share the first vertex.
        Mode::TriangleStrip => (2..indices.len())
            .map(|i| {
                if i % 2 == 0 {
                    [indices[i - 2], indices[i - 1], indices[i]]
                } else {
                    [indices[i - 1], indices[i - 2], indices[i]]
                }
            })
            .collect(),
        Mode::TriangleFan => (2..indices.len()).map(|i| [indices[0], indices[i - 1], indices[i]]).collect(),
        _ => Vec::new(),
    }
}

/// Vertex `i` of an optional attribute array, or `default` where the primitive has none.
fn attribute<T: Copy>(values: &Option<Vec<T>>, i: u32, default: T) -> T {
    values.as_ref().and_then(|v| v.get(i as usize).copied()).unwrap_or(default)
}
