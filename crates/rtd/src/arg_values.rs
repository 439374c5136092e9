//! What the shared arguments mean as library values: the denoiser `--model`/`--ensemble`
//! name, and the scene view that `--camera`/`--look-from`/`--look-at` pick.

use rtd_denoise::Denoiser;
use rtd_pipeline::{CameraChoice, SceneView};
use rtd_scene::EnvironmentChoice;

use crate::args::{DenoiserArgs, ViewArgs};
use crate::output::warn_all;

impl DenoiserArgs {
    /// Loads the model named on the command line, or the built-in one, set to run its
    /// `--ensemble` passes.
    pub fn load(&self) -> anyhow::Result<Denoiser> {
        let model = match &self.model {
            Some(p) => Denoiser::load(p)?,
            None => Denoiser::builtin()?,
        };
        Ok(model.passes(self.ensemble as usize))
    }
}

impl ViewArgs {
    /// The camera these arguments ask for.
    pub fn camera_choice(&self) -> CameraChoice {
        match (self.look_from, self.look_at, &self.camera) {
            (Some(from), Some(at), _) => CameraChoice::LookAt { from, at, fov: self.fov },
            (_, _, Some(name)) => CameraChoice::Named(name.clone()),
            _ => CameraChoice::Default,
        }
    }

    /// Loads the scene with the chosen camera and `env`, printing its warnings, and returns it
    /// with the image size `--width`/`--height` and the camera's aspect ratio give.
    pub fn load(&self, env: Option<&EnvironmentChoice>) -> anyhow::Result<(SceneView, (u32, u32))> {
        let loaded = SceneView::load_scene(&self.scene, self.scene_choice.as_deref(), &self.camera_choice(), env)?;
        let (w, h, size_warning) = loaded.resolution(self.width, self.height);
        warn_all(&self.scene, loaded.warnings.iter().map(String::as_str).chain(size_warning.as_deref()));
        Ok((loaded, (w, h)))
    }
}
