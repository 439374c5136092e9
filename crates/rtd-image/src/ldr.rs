use std::path::Path;
use std::sync::LazyLock;

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

/// [`srgb_to_linear`] of an 8-bit code `v / 255`, from a table made by that function (the same
/// bits, without a `powf` per texel).
#[inline]
pub fn srgb8_to_linear(v: u8) -> f32 {
    static TABLE: LazyLock<[f32; 256]> = LazyLock::new(|| std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0)));
    TABLE[v as usize]
}

/// [`srgb_to_linear`] of a 16-bit code `v / 65535`, from a table made by that function on first
/// use (256 KiB).
#[inline]
pub fn srgb16_to_linear(v: u16) -> f32 {
    static TABLE: LazyLock<Vec<f32>> =
        LazyLock::new(|| (0..=u16::MAX).map(|i| srgb_to_linear(i as f32 / 65535.0)).collect());
    TABLE[v as usize]
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
        ImageFormat::Exr | ImageFormat::Pfm | ImageFormat::Phm => {
            return Err(ImageError::invalid(path, "is a float format, not an 8-bit one"))
        }
    };
    let bytes: Vec<u8> = image.pixels.iter().flat_map(|&p| tonemap_to_srgb8(p, exposure, tonemap)).collect();
    let buf = image::RgbImage::from_raw(image.width, image.height, bytes)
        .ok_or_else(|| ImageError::invalid(path, "pixel buffer does not match image size"))?;
    let mut encoded = std::io::Cursor::new(Vec::new());
    buf.write_to(&mut encoded, format).map_err(|e| ImageError::decode(path, e))?;
    write_bytes_atomic(path, encoded.get_ref())
}

/// A decoded PNG or JPEG: 8 bits a channel, or more (16-bit PNG).
enum Decoded {
    Eight(image::RgbImage),
    Wide(image::Rgb32FImage),
}

/// Reads a PNG (8 or 16 bits a channel) or JPEG as sRGB-encoded and returns it as linear RGB in
/// [0,1].
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
    // Fenced as the other parsers are: the image is a stranger's. 16-bit files keep their
    // 16 bits (to_rgb32f divides by 65535); 8-bit ones are read as bytes.
    let decoded = crate::contain_panic(|| {
        reader.decode().map(|d| match d.color().bytes_per_pixel() / d.color().channel_count() {
            1 => Decoded::Eight(d.to_rgb8()),
            _ => Decoded::Wide(d.to_rgb32f()),
        })
    })
    .map_err(|e| ImageError::decode(path, e))?
    .map_err(|e| ImageError::decode(path, e))?;
    let (pixels, size): (Vec<Vec3>, (u32, u32)) = match &decoded {
        Decoded::Eight(img) => {
            let lin = srgb8_to_linear;
            (img.pixels().map(|p| Vec3::new(lin(p[0]), lin(p[1]), lin(p[2]))).collect(), img.dimensions())
        }
        Decoded::Wide(img) => {
            let lin = |v: f32| srgb_to_linear(v.clamp(0.0, 1.0));
            (img.pixels().map(|p| Vec3::new(lin(p[0]), lin(p[1]), lin(p[2]))).collect(), img.dimensions())
        }
    };
    // A file whose header and pixel data disagree on the size (found by fuzzing a JPEG).
    if size != (w, h) {
        return Err(ImageError::invalid(
            path,
            format!("header says {w}x{h} but the pixel data is {}x{}", size.0, size.1),
        ));
    }
    Ok(HdrImage::from_pixels(w, h, pixels))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_tables_give_the_functions_bits() {
        for v in 0..=255u8 {
            assert_eq!(srgb8_to_linear(v).to_bits(), srgb_to_linear(v as f32 / 255.0).to_bits(), "{v}");
        }
        for v in 0..=u16::MAX {
            assert_eq!(srgb16_to_linear(v).to_bits(), srgb_to_linear(v as f32 / 65535.0).to_bits(), "{v}");
        }
        assert_eq!((srgb8_to_linear(0), srgb8_to_linear(255)), (0.0, 1.0));
    }

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
    fn sixteen_bit_pngs_keep_their_precision() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("wide.png");
        // Two encoded values 1/65535 apart, which 8 bits would merge.
        let buf =
            image::ImageBuffer::<image::Rgb<u16>, Vec<u16>>::from_raw(2, 1, vec![30000, 30000, 30000, 30001, 0, 65535])
                .unwrap();
        buf.save(&path).unwrap();
        let back = read_ldr(&path).unwrap();
        assert_eq!(back.pixels[0].x, srgb_to_linear(30000.0 / 65535.0));
        assert_eq!(back.pixels[1].x, srgb_to_linear(30001.0 / 65535.0));
        assert_eq!((back.pixels[1].y, back.pixels[1].z), (0.0, 1.0));
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
