//! rtd's learned denoiser: a U-Net of inception modules ([`model`]) that takes a noisy HDR
//! render plus its guide pass and returns a clean image, HDR input encoding ([`encode`]),
//! tiled inference ([`infer`]) with a fast CPU path ([`fast`]), and a non-learned guided filter
//! baseline ([`filter`]).

#![warn(missing_docs)]

pub mod column_winograd;
pub mod direct;
pub mod encode;
mod extreme_pool;
pub mod fast;
pub mod feature_map;
pub mod filter;
pub mod infer;
pub mod kernel_output;
pub mod model;
pub mod plane_encoder;
pub mod planes;
pub mod pooling;
mod same_conv;
mod tensor_ops;
mod upsample;
mod vector_math;
pub mod winograd;

pub use encode::DenoiseInput;
pub use infer::Denoiser;
pub use model::{DenoiserConfig, DenoiserNet};
pub use planes::INPUT_CHANNELS;

/// Errors from the denoiser: a model that cannot be loaded, or inputs that do not fit.
#[derive(Debug, thiserror::Error)]
pub enum DenoiseError {
    /// A model file could not be read.
    #[error("model: {path}: {source}")]
    Io {
        /// The file concerned (weights or config).
        path: std::path::PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The model's config or weights are corrupt or do not fit this rtd.
    #[error("model: {model}: {message}")]
    Model {
        /// The model's name (its path, or `builtin:…`).
        model: String,
        /// What is wrong with it.
        message: String,
    },
    /// An input layer's size differs from the colour image's.
    #[error("the {layer} image is {}x{} but the colour image is {}x{}", size.0, size.1, color.0, color.1)]
    SizeMismatch {
        /// The layer (guide, albedo or normal).
        layer: &'static str,
        /// Its width and height.
        size: (u32, u32),
        /// The colour image's width and height.
        color: (u32, u32),
    },
    /// An image's pixels do not fill its width × height.
    #[error("the {layer} image holds {pixels} pixels, not {}x{}", size.0, size.1)]
    PixelCount {
        /// The layer (colour, guide, variance, albedo or normal).
        layer: &'static str,
        /// Pixels it holds.
        pixels: usize,
        /// Its width and height.
        size: (u32, u32),
    },
    /// The AO or depth plane has another length than the colour image has pixels.
    #[error("AO/depth have {ao} and {depth} values, expected {expected}")]
    PlaneLength {
        /// AO values given.
        ao: usize,
        /// Depth values given.
        depth: usize,
        /// The colour image's pixel count.
        expected: usize,
    },
    /// The image is empty or larger than [`rtd_image::MAX_DIMENSION`] on a side.
    #[error("image size {width}x{height} is outside 1..={} per side", rtd_image::MAX_DIMENSION)]
    Size {
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
}

impl DenoiseError {
    /// A problem with the model `model`.
    pub fn model(model: &str, message: impl Into<String>) -> Self {
        DenoiseError::Model { model: model.to_string(), message: message.into() }
    }
}
