//! Radiance `.hdr` (RGBE) images, the format most HDRI libraries ship environment maps in.

use std::path::Path;

use glam::Vec3;

use crate::{HdrImage, ImageError};

/// Reads a Radiance `.hdr` file as linear RGB, its size checked from the header before any
/// pixel is decoded, the decoder fenced as every parser of a stranger's file is.
pub fn read_rgbe(path: &Path) -> Result<HdrImage, ImageError> {
    if !path.exists() {
        return Err(ImageError::missing(path));
    }
    let open = || -> Result<image::ImageReader<std::io::BufReader<std::fs::File>>, ImageError> {
        let mut reader = image::ImageReader::open(path).map_err(|e| ImageError::io(path, e))?;
        reader.set_format(image::ImageFormat::Hdr);
        Ok(reader)
    };
    let (w, h) = open()?.into_dimensions().map_err(|e| ImageError::decode(path, e))?;
    crate::check_image_size(path, w as usize, h as usize)?;
    let reader = open()?;
    let decoded = crate::contain_panic(|| reader.decode().map(|d| d.to_rgb32f()))
        .map_err(|e| ImageError::decode(path, e))?
        .map_err(|e| ImageError::decode(path, e))?;
    if decoded.dimensions() != (w, h) {
        let (dw, dh) = decoded.dimensions();
        return Err(ImageError::invalid(path, format!("header says {w}x{h} but the pixel data is {dw}x{dh}")));
    }
    let pixels = decoded.pixels().map(|p| Vec3::new(p[0], p[1], p[2])).collect();
    Ok(HdrImage::from_pixels(w, h, pixels))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_hdr_file_reads_back_its_values() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sky.hdr");
        // Powers of two are exact in RGBE's shared-exponent encoding.
        let px = [[1.0f32, 0.5, 0.25], [8.0, 4.0, 2.0], [0.0, 0.0, 0.0]];
        let img = image::Rgb32FImage::from_fn(3, 1, |x, _| image::Rgb(px[x as usize]));
        image::DynamicImage::ImageRgb32F(img).save(&path).unwrap();
        let back = read_rgbe(&path).unwrap();
        assert_eq!(back.pixels, px.map(Vec3::from_array));
        std::fs::write(&path, b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 2\n\x02").unwrap();
        assert!(read_rgbe(&path).unwrap_err().to_string().starts_with(&path.display().to_string()));
    }
}
