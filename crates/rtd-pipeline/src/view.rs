//! A scene loaded and prepared for rendering through one camera.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Vec3;
use rtd_render::RenderScene;
use rtd_scene::{Camera, Environment, EnvironmentChoice};

use crate::PipelineError;

/// Which camera renders the scene.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum CameraChoice {
    /// The file's first perspective camera, else its first camera, else an automatic camera
    /// framing the scene's bounds (with a warning).
    #[default]
    Default,
    /// A camera of the file by name or index.
    Named(String),
    /// A camera at `from` looking at `at` with this vertical field of view in degrees.
    LookAt {
        /// Camera position.
        from: Vec3,
        /// Point looked at.
        at: Vec3,
        /// Vertical field of view in degrees.
        fov: f32,
    },
}

/// Image width when neither side is given.
pub const DEFAULT_WIDTH: u32 = 512;

/// A loaded scene with its BVH, light set and chosen camera.
pub struct SceneView {
    /// The scene file.
    pub path: PathBuf,
    /// Scene, BVH and lights.
    pub scene: RenderScene,
    /// The camera.
    pub camera: Camera,
    /// Seconds spent loading the file.
    pub load_s: f64,
    /// What the user should be told: load warnings, an automatic camera, an empty scene.
    pub warnings: Vec<String>,
}

impl SceneView {
    /// Loads `path`, replaces its environment with `environment` if given (`R,G,B` radiance or
    /// an equirectangular map, with its strength and turn), picks the camera and builds the BVH
    /// and light set.
    pub fn load(
        path: &Path,
        camera: &CameraChoice,
        environment: Option<&EnvironmentChoice>,
    ) -> Result<Self, PipelineError> {
        Self::load_scene(path, None, camera, environment)
    }

    /// [`SceneView::load`] of the glTF file's scene named or numbered `scene` (None: its
    /// default scene).
    pub fn load_scene(
        path: &Path,
        scene: Option<&str>,
        camera: &CameraChoice,
        environment: Option<&EnvironmentChoice>,
    ) -> Result<Self, PipelineError> {
        let t = Instant::now();
        let mut scene = rtd_scene::load_scene_named(path, scene)?;
        if let Some(env) = environment {
            scene.environment = Environment::load(env)?;
        }
        let load_s = t.elapsed().as_secs_f64();
        let camera_error = |source| PipelineError::Camera { path: path.to_path_buf(), source };
        let (camera, camera_warning) = match camera {
            CameraChoice::LookAt { from, at, fov } => {
                if !(from.is_finite() && at.is_finite() && *fov > 0.0 && *fov < 180.0) {
                    return Err(PipelineError::LookAtInvalid { path: path.to_path_buf(), fov: *fov });
                }
                if from == at {
                    return Err(PipelineError::LookAtItself { path: path.to_path_buf() });
                }
                (Camera::look_at(*from, *at, *fov), None)
            }
            CameraChoice::Named(name) => scene.select_camera(Some(name)).map_err(camera_error)?,
            CameraChoice::Default => scene.select_camera(None).map_err(camera_error)?,
        };
        let mut warnings = scene.warnings.clone();
        warnings.extend(camera_warning);
        if scene.triangles.is_empty() {
            warnings.push("scene has no triangles".into());
        }
        warnings.extend(scene.precision_warning());
        let scene = RenderScene::new(scene);
        Ok(SceneView { path: path.to_path_buf(), scene, camera, load_s, warnings })
    }

    /// The warning a render (not a guide pass) of this view deserves: no light at all.
    pub fn lighting_warning(&self) -> Option<&'static str> {
        self.scene.lights.is_empty().then_some("scene has no lights and no environment; the image will be black")
    }

    /// The image size for `width` and `height` as given (either may be absent): both given are
    /// used as they are, with a warning if the camera was made for another aspect ratio; one
    /// given sets the other from the camera's aspect ratio (square without one); none gives
    /// [`DEFAULT_WIDTH`] wide. Returns (width, height, warning).
    pub fn resolution(&self, width: Option<u32>, height: Option<u32>) -> (u32, u32, Option<String>) {
        let aspect = self.camera.aspect_ratio;
        let a = aspect.unwrap_or(1.0) as f64;
        let side = |x: f64| (x.round() as u32).clamp(1, rtd_image::MAX_DIMENSION);
        match (width, height) {
            (Some(w), Some(h)) => {
                let warning = aspect.filter(|r| ((w as f64 / h as f64) / *r as f64 - 1.0).abs() > 0.01).map(|r| {
                    format!(
                        "camera '{}' was made for aspect ratio {r:.3} but the image is {w}x{h}; its field of view is kept vertically",
                        self.camera.name
                    )
                });
                (w, h, warning)
            }
            (Some(w), None) => (w, side(w as f64 / a), None),
            (None, Some(h)) => (side(h as f64 * a), h, None),
            (None, None) => (DEFAULT_WIDTH, side(DEFAULT_WIDTH as f64 / a), None),
        }
    }

    /// The scene file's stem, for naming reports and figures.
    pub fn name(&self) -> String {
        self.path.file_stem().and_then(|s| s.to_str()).unwrap_or("scene").to_string()
    }
}
