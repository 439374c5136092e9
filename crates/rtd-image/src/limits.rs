//! The size limits on every image rtd reads, renders, denoises or writes, and their one check.

use std::path::Path;

use crate::ImageError;

/// Largest width or height rtd accepts for any image it reads, renders, denoises or writes.
/// Every size check in rtd uses this one constant.
pub const MAX_DIMENSION: u32 = 16384;

/// Largest image area rtd renders or decodes (64 Mpx, 8192²). A render's film keeps 52 bytes
/// per pixel (f64 beauty, f32 AOVs), so this bounds it near 3.5 GB on the 24 GiB machines rtd
/// targets; a decoded EXR is checked against it from its headers, before any pixel is read.
pub const MAX_PIXELS: usize = 1 << 26;

/// Refuses a size outside 1..=[`MAX_DIMENSION`] a side or above [`MAX_PIXELS`] in all; `name`
/// names the file in the error.
pub fn check_image_size(name: &Path, width: usize, height: usize) -> Result<(), ImageError> {
    if width == 0 || height == 0 || width > MAX_DIMENSION as usize || height > MAX_DIMENSION as usize {
        return Err(ImageError::invalid(
            name,
            format!("image size {width}x{height} is outside 1..={MAX_DIMENSION} a side"),
        ));
    }
    if width.saturating_mul(height) > MAX_PIXELS {
        return Err(ImageError::invalid(name, format!("image size {width}x{height} exceeds {MAX_PIXELS} pixels")));
    }
    Ok(())
}
