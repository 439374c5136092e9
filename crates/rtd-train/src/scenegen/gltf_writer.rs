//! Writes a generated scene as glTF 2.0: one JSON file, one `.bin` buffer and PNG textures, all
//! side by side, so that `rtd render` loads exactly what the dataset was rendered from.

use std::path::Path;

use glam::{Mat3, Quat, Vec3};
use serde_json::{json, Value};

use super::mesh::Mesh;
use crate::TrainError;

/// A glTF metallic-roughness material with the extensions rtd reads.
#[derive(Clone, Debug)]
pub struct GenMaterial {
    /// Linear base colour.
    pub base_color: Vec3,
    /// Index into the scene's textures for the base colour, if any.
    pub texture: Option<usize>,
    /// glTF metallic factor.
    pub metallic: f32,
    /// glTF roughness factor.
    pub roughness: f32,
    /// KHR_materials_transmission factor.
    pub transmission: f32,
    /// KHR_materials_ior.
    pub ior: f32,
    /// Emitted radiance (linear, before strength).
    pub emissive: Vec3,
    /// KHR_materials_emissive_strength.
    pub emissive_strength: f32,
}

/// A scene's meshes in glTF form: the binary buffer and the JSON arrays that index it.
struct Geometry {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
    meshes: Vec<Value>,
    nodes: Vec<Value>,
}

impl GenMaterial {
    /// A plain diffuse material.
    pub fn diffuse(c: Vec3) -> Self {
        GenMaterial {
            base_color: c,
            texture: None,
            metallic: 0.0,
            roughness: 1.0,
            transmission: 0.0,
            ior: 1.5,
            emissive: Vec3::ZERO,
            emissive_strength: 1.0,
        }
    }
}

/// A perspective camera looking from `from` at `at`.
#[derive(Clone, Copy, Debug)]
pub struct GenCamera {
    /// Eye position.
    pub from: Vec3,
    /// Point looked at.
    pub at: Vec3,
    /// Vertical field of view in degrees.
    pub yfov_degrees: f32,
}

/// A generated scene before it is written.
#[derive(Default)]
pub struct GenScene {
    /// Meshes with their material indices.
    pub objects: Vec<(Mesh, usize)>,
    /// Materials, indexed by the objects' material indices.
    pub materials: Vec<GenMaterial>,
    /// Textures as sRGB images.
    pub textures: Vec<image::RgbImage>,
    /// Cameras (the dataset renders each as one view).
    pub cameras: Vec<GenCamera>,
    /// More placements of objects' meshes: (object index, translation), each a glTF node that
    /// instances the object's mesh.
    pub instances: Vec<(usize, Vec3)>,
}

fn f32_bytes(out: &mut Vec<u8>, v: &[f32]) {
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

fn min_max(v: &[Vec3]) -> (Value, Value) {
    let lo = v.iter().fold(Vec3::splat(f32::INFINITY), |a, b| a.min(*b));
    let hi = v.iter().fold(Vec3::splat(f32::NEG_INFINITY), |a, b| a.max(*b));
    (json!([lo.x, lo.y, lo.z]), json!([hi.x, hi.y, hi.z]))
}

impl GenScene {
    /// Writes `dir/name.gltf`, `dir/name.bin` and `dir/name_texN.png`.
    pub fn write(&self, dir: &Path, name: &str) -> Result<(), TrainError> {
        rtd_image::create_dir_durably(dir).map_err(|e| TrainError::io(dir, e))?;
        let Geometry { bin, views, accessors, meshes, mut nodes } = self.geometry();
        for (object, offset) in &self.instances {
            nodes.push(json!({"mesh": object, "translation": offset.to_array()}));
        }
        let cameras = self.cameras_json(&mut nodes);
        let materials = self.materials_json();
        let images = self.write_textures(dir, name)?;
        let textures: Vec<Value> = (0..images.len()).map(|i| json!({"source": i, "sampler": 0})).collect();
        let bin_name = format!("{name}.bin");
        let doc = json!({
            "asset": {"version": "2.0", "generator": "rtd datagen"},
            "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_materials_transmission", "KHR_materials_ior"],
            "scene": 0,
            "scenes": [{"nodes": (0..nodes.len()).collect::<Vec<_>>()}],
            "nodes": nodes, "meshes": meshes, "cameras": cameras, "materials": materials,
            "textures": textures, "images": images,
            "samplers": [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}],
            "accessors": accessors, "bufferViews": views,
            "buffers": [{"uri": bin_name, "byteLength": bin.len()}],
        });
        rtd_image::write_bytes_atomic(&dir.join(&bin_name), &bin)?;
        let text = serde_json::to_vec_pretty(&doc).map_err(|e| TrainError::msg(dir, e.to_string()))?;
        Ok(rtd_image::write_bytes_atomic(&dir.join(format!("{name}.gltf")), &text)?)
    }

    /// The meshes as one binary buffer with its views and accessors, one node per mesh.
    fn geometry(&self) -> Geometry {
        let mut bin = Vec::new();
        let (mut views, mut accessors, mut meshes, mut nodes) = (vec![], vec![], vec![], vec![]);
        for (mesh, material) in &self.objects {
            let mesh = &mesh.without_degenerate_triangles();
            let mut attr = json!({});
            for (key, data, ty, count) in [
                (
                    "POSITION",
                    mesh.positions.iter().flat_map(|p| p.to_array()).collect::<Vec<_>>(),
                    "VEC3",
                    mesh.positions.len(),
                ),
                ("NORMAL", mesh.normals.iter().flat_map(|p| p.to_array()).collect(), "VEC3", mesh.normals.len()),
                ("TEXCOORD_0", mesh.uvs.iter().flat_map(|p| p.to_array()).collect(), "VEC2", mesh.uvs.len()),
            ] {
                let offset = bin.len();
                f32_bytes(&mut bin, &data);
                views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": data.len() * 4, "target": 34962}));
                let mut acc = json!({"bufferView": views.len() - 1, "componentType": 5126, "count": count, "type": ty});
                if key == "POSITION" {
                    let (lo, hi) = min_max(&mesh.positions);
                    acc["min"] = lo;
                    acc["max"] = hi;
                }
                accessors.push(acc);
                attr[key] = json!(accessors.len() - 1);
            }
            let offset = bin.len();
            for i in &mesh.indices {
                bin.extend_from_slice(&i.to_le_bytes());
            }
            views.push(
                json!({"buffer": 0, "byteOffset": offset, "byteLength": mesh.indices.len() * 4, "target": 34963}),
            );
            accessors.push(json!({"bufferView": views.len() - 1, "componentType": 5125, "count": mesh.indices.len(), "type": "SCALAR"}));
            meshes.push(
                json!({"primitives": [{"attributes": attr, "indices": accessors.len() - 1, "material": material}]}),
            );
            nodes.push(json!({"mesh": meshes.len() - 1}));
        }
        Geometry { bin, views, accessors, meshes, nodes }
    }

    /// The cameras, each with its node appended to `nodes`.
    fn cameras_json(&self, nodes: &mut Vec<Value>) -> Vec<Value> {
        let mut cameras = vec![];
        for (i, cam) in self.cameras.iter().enumerate() {
            // Camera frame: glTF cameras look down their local -Z with +Y up.
            let back = (cam.from - cam.at).normalize();
            let right = Vec3::Y.cross(back).try_normalize().unwrap_or(Vec3::X);
            let up = back.cross(right);
            let q = Quat::from_mat3(&Mat3::from_cols(right, up, back)).normalize();
            cameras.push(json!({"type": "perspective", "name": format!("view{i}"),
                "perspective": {"yfov": cam.yfov_degrees.to_radians(), "znear": 0.01, "aspectRatio": 1.0}}));
            nodes.push(json!({"name": format!("view{i}"), "camera": i,
                "translation": cam.from.to_array(), "rotation": q.to_array()}));
        }
        cameras
    }

    /// The materials as glTF metallic-roughness materials with their extensions.
    fn materials_json(&self) -> Vec<Value> {
        self.materials
            .iter()
            .map(|m| {
                let mut pbr = json!({"baseColorFactor": [m.base_color.x, m.base_color.y, m.base_color.z, 1.0],
                "metallicFactor": m.metallic, "roughnessFactor": m.roughness});
                if let Some(t) = m.texture {
                    pbr["baseColorTexture"] = json!({"index": t});
                }
                let mut mat = json!({"pbrMetallicRoughness": pbr, "extensions": {}});
                if m.emissive != Vec3::ZERO {
                    mat["emissiveFactor"] = json!(m.emissive.to_array());
                    mat["extensions"]["KHR_materials_emissive_strength"] =
                        json!({"emissiveStrength": m.emissive_strength});
                }
                if m.transmission > 0.0 {
                    mat["extensions"]["KHR_materials_transmission"] = json!({"transmissionFactor": m.transmission});
                    mat["extensions"]["KHR_materials_ior"] = json!({"ior": m.ior});
                }
                mat
            })
            .collect()
    }

    /// Writes the textures as PNG files beside the scene and returns their image entries.
    fn write_textures(&self, dir: &Path, name: &str) -> Result<Vec<Value>, TrainError> {
        let mut images = vec![];
        for (i, tex) in self.textures.iter().enumerate() {
            let file = format!("{name}_tex{i}.png");
            let path = dir.join(&file);
            rtd_image::write_atomic(&path, |w| {
                tex.write_to(w, image::ImageFormat::Png).map_err(|e| rtd_image::ImageError::invalid(&path, e))
            })
            .map_err(TrainError::from)?;
            images.push(json!({"uri": file}));
        }
        Ok(images)
    }
}
