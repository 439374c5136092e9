use std::path::PathBuf;

/// Errors from any stage of the pipeline; each names the file or setting concerned.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// The scene could not be loaded.
    #[error(transparent)]
    Scene(#[from] rtd_scene::SceneError),
    /// The render or guide settings are invalid.
    #[error(transparent)]
    Render(#[from] rtd_render::RenderError),
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
    /// The render was cancelled before its first pass finished, so there is no image.
    #[error("interrupted before the first pass finished; nothing written")]
    NothingRendered,
}
