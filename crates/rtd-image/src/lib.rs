//! Image buffers and image file I/O for rtd.
//!
//! - [`HdrImage`]: a linear RGB float image, the currency of the renderer and denoiser.
//! - [`Layers`]: named float channels of one size, written to a one-part EXR and read from
//!   EXRs of one part or many (`R,G,B`, `albedo.R`, `normal.X`, `depth.Z`, ...).
//! - [`Layer`]: the EXR layer vocabulary every writer and reader shares.
//! - LDR output (PNG/JPEG, 8-bit sRGB) with exposure and a [`Tonemap`]; PNG input of 8 or 16
//!   bits.
//! - Radiance `.hdr` input ([`read_rgbe`]) for environment maps.
//! - PFM/PHM in and out ([`read_pfm`], [`write_pfm`]), the format of `oidnDenoise`.
//! - Every write is atomic and durable: a temporary file in the target directory, `fsync`,
//!   then a rename.
//! - [`Progress`]: the one observer trait long library calls report to.
//! - [`MAX_DIMENSION`] and [`MAX_PIXELS`]: the size limits on any image side and area.

#![warn(missing_docs)]

mod atomic;
mod error;
mod exr_io;
mod format;
mod hdr;
mod layer;
mod layer_lookup;
mod ldr;
mod limits;
pub mod metrics;
mod parser_guard;
mod pfm;
mod progress;
mod rgbe;
mod sniff;

pub use atomic::{create_dir_durably, parent_dir, remove_orphans_once, write_atomic, write_bytes_atomic, write_json};
pub use error::ImageError;
pub use exr_io::{encode_exr, read_exr, write_exr, write_exr_owned, Layers};
pub use format::ImageFormat;
pub use hdr::{luminance, HdrImage};
pub use layer::{Channels, Layer};
pub use ldr::{
    linear_to_srgb, read_ldr, srgb16_to_linear, srgb8_to_linear, srgb_to_linear, tonemap_to_srgb8, write_ldr, Tonemap,
};
pub use limits::{check_image_size, MAX_DIMENSION, MAX_PIXELS};
pub use parser_guard::{contain_panic, contained_panics};
pub use pfm::{decode_pfm, encode_pfm, read_pfm, read_pfm_header, write_pfm, PfmHeader};
pub use progress::{Progress, Quiet};
pub use rgbe::read_rgbe;
pub use sniff::{read_image_header, ImageHeader};
