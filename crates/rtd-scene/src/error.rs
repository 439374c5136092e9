use std::path::{Path, PathBuf};

/// A scene that could not be loaded: the file and a one-line reason.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct SceneError {
    /// The file that failed to load.
    pub path: PathBuf,
    /// What is wrong with it, in one line.
    pub message: String,
}

impl SceneError {
    /// A new error for `path`.
    pub fn new(path: &Path, message: impl ToString) -> Self {
        let message = message.to_string().replace('\n', " ");
        SceneError { path: path.to_path_buf(), message }
    }
}
