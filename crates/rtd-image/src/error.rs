use std::path::PathBuf;

/// Errors from reading or writing images. Each names the file and the problem.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The file could not be opened, created, written or renamed.
    #[error("{path}: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying I/O error.
        source: std::io::Error,
    },
    /// The file exists but could not be decoded as an image.
    #[error("{path}: cannot decode image: {message}")]
    Decode {
        /// The file concerned.
        path: PathBuf,
        /// What the decoder said.
        message: String,
    },
    /// The file's extension names no format rtd can write or read.
    #[error("{path}: unknown image format (use .exr, .png, .jpg, .jpeg, .pfm or .phm)")]
    UnknownFormat {
        /// The file concerned.
        path: PathBuf,
    },
    /// The image is too large, empty, or has inconsistent channel sizes.
    #[error("{path}: {message}")]
    Invalid {
        /// The file concerned.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
}

impl ImageError {
    /// An I/O failure on `path`.
    pub fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        ImageError::Io { path: path.to_path_buf(), source }
    }
    /// `path` does not exist.
    pub fn missing(path: &std::path::Path) -> Self {
        ImageError::io(path, std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"))
    }
    /// `path` could not be decoded.
    pub fn decode(path: &std::path::Path, message: impl ToString) -> Self {
        ImageError::Decode { path: path.to_path_buf(), message: message.to_string() }
    }
    /// `path` holds something invalid.
    pub fn invalid(path: &std::path::Path, message: impl ToString) -> Self {
        ImageError::Invalid { path: path.to_path_buf(), message: message.to_string() }
    }
}
