//! Scene import for rtd.
//!
//! glTF 2.0 (`.gltf`, `.glb`) and OBJ/MTL files are flattened into a [`Scene`]: world-space
//! triangles with per-vertex shading attributes, glTF metallic-roughness [`Material`]s,
//! [`Texture`]s read as linear float, [`Camera`]s, punctual [`Light`]s and an [`Environment`].
//! Bad input gives a [`SceneError`] naming the file and the problem (a missing file reads
//! `PATH: no such file`; a corrupt glTF accessor names its mesh and accessor); recoverable
//! problems (skipped degenerate triangles, a missing camera) become [`Scene::warnings`].
#![warn(missing_docs)]

mod aabb;
mod camera;
mod camera_choice;
mod environment;
mod error;
mod gltf_accessors;
mod gltf_import;
mod gltf_material;
mod layers;
mod light;
mod material;
mod obj_import;
mod scene;
mod texture;
mod texture_ref;

pub use aabb::Aabb;
pub use camera::{Camera, Projection};
pub use camera_choice::CameraError;
pub use environment::{EnvMap, Environment, EnvironmentChoice};
pub use error::{AccessorProblem, SceneError};
pub use gltf_import::{load_gltf, load_gltf_scene, SUPPORTED_GLTF_EXTENSIONS};
pub use layers::{Clearcoat, LayerParams, Sheen};
pub use light::{Light, LUMENS_PER_WATT};
pub use material::{AlphaMode, Material, MaterialFootprint, SurfaceParams};
pub use obj_import::load_obj;
pub use scene::{Scene, Triangle, TriangleExtras};
pub use texture::{FootprintFilter, Texture, Wrap};
pub use texture_ref::{TexCoords, TextureRef, UvTransform};

use std::path::Path;

/// Loads a scene, choosing the importer by extension (`.gltf`, `.glb`, `.obj`, in any case).
/// A missing file is a [`SceneError::Io`] whose message is `PATH: no such file`; an unknown
/// extension is a [`SceneError::UnknownFormat`].
pub fn load_scene(path: &Path) -> Result<Scene, SceneError> {
    load_scene_named(path, None)
}

/// [`load_scene`] of one of a glTF file's scenes, by name or index ([`load_gltf_scene`]); an
/// OBJ file holds one scene and takes no choice.
pub fn load_scene_named(path: &Path, scene: Option<&str>) -> Result<Scene, SceneError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("gltf") | Some("glb") => load_gltf_scene(path, scene),
        Some("obj") if scene.is_some() => {
            Err(SceneError::new(path, "an OBJ file holds one scene; --scene is for glTF"))
        }
        Some("obj") => load_obj(path),
        _ => Err(SceneError::UnknownFormat { path: path.to_path_buf() }),
    }
}
