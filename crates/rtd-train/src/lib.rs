//! Self-contained training for rtd's denoiser: the procedural scene generator
//! ([`scenegen`]), dataset rendering ([`dataset`]), batches ([`data`]), the training loop
//! ([`train`]) with its [`TrainOptions`] ([`options`]), the run's record ([`run_state`]) and
//! its curves ([`plot`]). The validation benchmark that scores a model on a dataset's held-out
//! views is `rtd_bench::validation`.

#![warn(missing_docs)]

pub mod data;
pub mod dataset;
pub mod loss;
pub mod options;
pub mod plot;
pub mod run_state;
pub mod scenegen;
pub mod train;

use std::path::{Path, PathBuf};

// The one progress trait, from the image crate; `crate::Progress` names it inside this crate.
use rtd_image::Progress;

pub use options::TrainOptions;

/// Errors from dataset generation and training; each names the file concerned.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// A file or directory could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A file's content is wrong.
    #[error("{path}: {message}")]
    Invalid {
        /// The file concerned.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// Training options that cannot work, or not on the dataset they were given (see
    /// [`TrainOptions::validate`]); nothing was loaded or written.
    #[error("{dataset}: {message}")]
    InvalidOptions {
        /// The dataset directory the options were checked against.
        dataset: PathBuf,
        /// Which option is wrong and why, in one line.
        message: String,
    },
    /// Image I/O failed.
    #[error(transparent)]
    Image(#[from] rtd_image::ImageError),
    /// A generated scene failed to load.
    #[error(transparent)]
    Scene(#[from] rtd_scene::SceneError),
    /// Rendering failed.
    #[error(transparent)]
    Render(#[from] rtd_render::RenderError),
    /// The guide pass's settings are invalid.
    #[error(transparent)]
    Guide(#[from] rtd_guide::GuideError),
    /// The denoiser failed.
    #[error(transparent)]
    Denoise(#[from] rtd_denoise::DenoiseError),
}

impl TrainError {
    /// An I/O error on `path`.
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        TrainError::Io { path: path.to_path_buf(), source }
    }
    /// A content error on `path`.
    pub fn msg(path: &Path, message: impl Into<String>) -> Self {
        TrainError::Invalid { path: path.to_path_buf(), message: message.into() }
    }
}
