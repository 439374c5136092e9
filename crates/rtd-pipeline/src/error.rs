use std::path::PathBuf;

/// Errors from any stage of the pipeline; each names the file or setting concerned.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// The scene could not be loaded.
    #[error(transparent)]
    Scene(#[from] rtd_scene::SceneError),
    /// The render settings are invalid.
    #[error(transparent)]
    Render(#[from] rtd_render::RenderError),
    /// The guide pass's settings are invalid.
    #[error(transparent)]
    Guide(#[from] rtd_guide::GuideError),
    /// The denoiser failed or its inputs are inconsistent.
    #[error(transparent)]
    Denoise(#[from] rtd_denoise::DenoiseError),
    /// An image could not be read or written.
    #[error(transparent)]
    Image(#[from] rtd_image::ImageError),
    /// The camera asked for does not exist.
    #[error("{path}: {source}")]
    Camera {
        /// The scene file.
        path: PathBuf,
        /// Which camera was missing, and which exist.
        source: rtd_scene::CameraError,
    },
    /// A look-at camera was asked for with its position equal to its target.
    #[error("{path}: --look-from and --look-at are the same point")]
    LookAtItself {
        /// The scene file.
        path: PathBuf,
    },
    /// An input file lacks the layer the pipeline needs.
    #[error("{path}: {message}")]
    Input {
        /// The input file.
        path: PathBuf,
        /// What is missing or wrong.
        message: String,
    },
    /// The guide pass was set to another size than the render.
    #[error("the guide pass is {}x{} but the render is {}x{}", guide.0, guide.1, render.0, render.1)]
    GuideSize {
        /// The guide settings' width and height.
        guide: (u32, u32),
        /// The render settings' width and height.
        render: (u32, u32),
    },
    /// A look-at camera was asked for with a field of view outside (0, 180) degrees or a
    /// position or target that is not finite.
    #[error("{path}: a look-at camera needs finite points and a field of view in (0, 180) degrees, not {fov}")]
    LookAtInvalid {
        /// The scene file.
        path: PathBuf,
        /// The field of view asked for, in degrees.
        fov: f32,
    },
    /// The denoise inputs do not make a usable set (albedo without normal, or no guide at all).
    #[error("{0}")]
    Sources(&'static str),
    /// The render was cancelled before its first pass finished, so there is no image.
    #[error("interrupted before the first pass finished; nothing written")]
    NothingRendered,
}
