use std::path::Path;

use glam::Vec3;

use crate::{write_bytes_atomic, HdrImage, ImageError, ImageFormat};

/// How linear radiance is mapped into [0,1] before sRGB encoding.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Tonemap {
    /// Clamp to [0,1]: the fixed tonemap that metrics use.
    #[default]
    Clamp,
    /// The ACES filmic curve (Narkowicz's fit), which rolls highlights off smoothly.
    Aces,
}

/// sRGB opto-electronic transfer: linear [0,1] to encoded [0,1].
#[inline]
pub fn linear_to_srgb(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// Inverse sRGB transfer: encoded [0,1] to linear [0,1].
#[inline]
pub fn srgb_to_linear(x: f32) -> f32 {
    if x <= 0.040_45 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

/// ACES filmic approximation (Narkowicz 2015) applied per channel.
#[inline]
fn aces(x: f32) -> f32 {
    let (a, b, c, d, e) = (2.51, 0.03, 2.43, 0.59, 0.14);
    (x * (a * x + b)) / (x * (c * x + d) + e)
}

/// Maps a linear pixel to 8-bit sRGB: multiply by 2^exposure, tonemap, encode.
/// Non-finite values map to black.
pub fn tonemap_to_srgb8(v: Vec3, exposure: f32, tonemap: Tonemap) -> [u8; 3] {
    let scale = exposure.exp2();
    let mut out = [0u8; 3];
    for c in 0..3 {
        let x = v[c] * scale;
        let x = if x.is_finite() { x.max(0.0) } else { 0.0 };
        let t = match tonemap {
            Tonemap::Clamp => x,
            Tonemap::Aces => aces(x),
        };
        out[c] = (linear_to_srgb(t) * 255.0 + 0.5) as u8;
    }
    out
}

/// Writes an 8-bit sRGB PNG or JPEG (chosen by `path`'s extension), atomically.
pub fn write_ldr(path: &Path, image: &HdrImage, exposure: f32, tonemap: Tonemap) -> Result<(), ImageError> {
    let format = match ImageFormat::from_path(path)? {
        ImageFormat::Png => image::ImageFormat::Png,
        ImageFormat::Jpeg => image::ImageFormat::Jpeg,
        ImageFormat::Exr => return Err(ImageError::invalid(path, "EXR is not an 8-bit format; use write_exr")),
    };
    let bytes: Vec<u8> = image.pixels.iter().flat_map(|&p| tonemap_to_srgb8(p, exposure, tonemap)).collect();
    let buf = image::RgbImage::from_raw(image.width, image.height, bytes)
        .ok_or_else(|| ImageError::invalid(path, "pixel buffer does not match image size"))?;
    let mut encoded = std::io::Cursor::new(Vec::new());
    buf.write_to(&mut encoded, format).map_err(|e| ImageError::decode(path, e))?;
    write_bytes_atomic(path, encoded.get_ref())
}

/// Reads a PNG or JPEG as sRGB-encoded LDR and returns it as linear RGB in [0,1].
pub fn read_ldr(path: &Path) -> Result<HdrImage, ImageError> {
    if !path.exists() {
        return Err(ImageError::missing(path));
    }
    let reader = image::ImageReader::open(path).map_err(|e| ImageError::io(path, e))?;
    let reader = reader.with_guessed_format().map_err(|e| ImageError::io(path, e))?;
    let (w, h) = reader.into_dimensions().map_err(|e| ImageError::decode(path, e))?;
    // Both sides and the pixel count, from the header, before anything is decoded.
    crate::check_image_size(path, w as usize, h as usize)?;
    let reader = image::ImageReader::open(path)
        .map_err(|e| ImageError::io(path, e))?
        .with_guessed_format()
        .map_err(|e| ImageError::io(path, e))?;
    // Fenced as the other parsers are: the image is a stranger's.
    let decoded = crate::contain_panic(|| reader.decode().map(|d| d.to_rgb8()))
        .map_err(|e| ImageError::decode(path, e))?
        .map_err(|e| ImageError::decode(path, e))?;
    let pixels = decoded
        .pixels()
        .map(|p| {
            Vec3::new(
                srgb_to_linear(p[0] as f32 / 255.0),
                srgb_to_linear(p[1] as f32 / 255.0),
                srgb_to_linear(p[2] as f32 / 255.0),
            )
        })
        .collect();
    // A file whose header and pixel data disagree on the size (found by fuzzing a JPEG).
    if (decoded.width(), decoded.height()) != (w, h) {
        return Err(ImageError::invalid(
            path,
            format!("header says {w}x{h} but the pixel data is {}x{}", decoded.width(), decoded.height()),
        ));
    }
    Ok(HdrImage::from_pixels(w, h, pixels))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trip() {
        for i in 0..=255 {
            let e = i as f32 / 255.0;
            assert!((linear_to_srgb(srgb_to_linear(e)) - e).abs() < 1e-5);
        }
    }

    #[test]
    fn tonemap_handles_extremes() {
        assert_eq!(tonemap_to_srgb8(Vec3::new(f32::NAN, f32::INFINITY, -1.0), 0.0, Tonemap::Clamp), [0, 0, 0]);
        assert_eq!(tonemap_to_srgb8(Vec3::splat(1e6), 0.0, Tonemap::Clamp), [255, 255, 255]);
        assert_eq!(tonemap_to_srgb8(Vec3::splat(1e6), 0.0, Tonemap::Aces), [255, 255, 255]);
        assert_eq!(tonemap_to_srgb8(Vec3::splat(0.5), 1.0, Tonemap::Clamp), [255, 255, 255]);
    }

    #[test]
    fn png_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.png");
        let img = HdrImage::from_pixels(2, 1, vec![Vec3::new(0.0, 0.5, 1.0), Vec3::splat(0.25)]);
        write_ldr(&path, &img, 0.0, Tonemap::Clamp).unwrap();
        let back = read_ldr(&path).unwrap();
        for (a, b) in img.pixels.iter().zip(&back.pixels) {
            assert!((*a - *b).abs().max_element() < 0.01, "{a} vs {b}");
        }
    }
}
