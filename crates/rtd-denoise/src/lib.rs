//! rtd's learned denoiser: a U-Net of inception modules ([`model`]) that takes a noisy HDR
//! render plus its guide pass and returns a clean image, HDR input encoding ([`encode`]),
//! tiled inference ([`infer`]) with a fast CPU path ([`fast`]), and a non-learned guided filter
//! baseline ([`filter`]).

#![warn(missing_docs)]

pub mod encode;
pub mod fast;
pub mod filter;
pub mod infer;
pub mod model;
pub mod planes;

pub use encode::DenoiseInput;
pub use infer::Denoiser;
pub use model::{DenoiserConfig, DenoiserNet};
pub use planes::INPUT_CHANNELS;

/// Errors from the denoiser.
#[derive(Debug, thiserror::Error)]
pub enum DenoiseError {
    /// The model file is missing, corrupt, or does not fit this rtd.
    #[error("model: {0}")]
    Model(String),
    /// The inputs are inconsistent (sizes, missing layers).
    #[error("{0}")]
    Input(String),
}
