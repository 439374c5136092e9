use std::path::{Path, PathBuf};

/// Errors from the benchmarks; each names the file concerned.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// A file or directory could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A file's content is wrong (a reference of the wrong size, an external result without
    /// colour).
    #[error("{path}: {message}")]
    Invalid {
        /// The file concerned.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// Image I/O failed.
    #[error(transparent)]
    Image(#[from] rtd_image::ImageError),
    /// A pipeline stage failed.
    #[error(transparent)]
    Pipeline(#[from] rtd_pipeline::PipelineError),
    /// Rendering failed.
    #[error(transparent)]
    Render(#[from] rtd_render::RenderError),
    /// The guide pass's settings are invalid.
    #[error(transparent)]
    Guide(#[from] rtd_guide::GuideError),
    /// The denoiser failed.
    #[error(transparent)]
    Denoise(#[from] rtd_denoise::DenoiseError),
    /// The dataset of a validation benchmark could not be read.
    #[error(transparent)]
    Dataset(#[from] rtd_train::TrainError),
}

impl BenchError {
    /// An I/O error on `path`.
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        BenchError::Io { path: path.to_path_buf(), source }
    }
    /// A content error on `path`.
    pub fn msg(path: &Path, message: impl Into<String>) -> Self {
        BenchError::Invalid { path: path.to_path_buf(), message: message.into() }
    }
}
