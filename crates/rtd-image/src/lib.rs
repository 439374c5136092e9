//! Image buffers and image file I/O for rtd.
//!
//! - [`HdrImage`]: a linear RGB float image, the currency of the renderer and denoiser.
//! - [`Layers`]: named float channels of one size, written to and read from a one-part EXR
//!   (`R,G,B`, `albedo.R`, `normal.X`, `depth.Z`, ...).
//! - LDR output (PNG/JPEG, 8-bit sRGB) with exposure and a [`Tonemap`].
//! - Every write is atomic: a temporary file in the target directory, then a rename.

mod atomic;
mod error;
mod exr_io;
mod format;
mod hdr;
mod ldr;

pub use atomic::{parent_dir, write_atomic};
pub use error::ImageError;
pub use exr_io::{read_exr, write_exr, Layers};
pub use format::ImageFormat;
pub use hdr::HdrImage;
pub mod metrics;
pub mod plot;
pub use ldr::{linear_to_srgb, read_ldr, srgb_to_linear, tonemap_to_srgb8, write_ldr, Tonemap};

/// Largest width or height rtd accepts for any image it reads or writes.
pub const MAX_DIMENSION: u32 = 16384;
