//! What an image's bytes say it is, and how large, from its header alone: how uploads are
//! checked before anything is decoded, so a small file that declares 100000x100000 pixels
//! (a decompression bomb) is refused without allocating its pixels.

use std::io::Cursor;
use std::path::Path;

use crate::limits::check_image_size;
use crate::{ImageError, ImageFormat, MAX_DIMENSION, MAX_PIXELS};

/// An image's format (from its magic bytes, not its name) and size (from its header).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageHeader {
    /// The format the bytes are in.
    pub format: ImageFormat,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

/// Refuses an EXR whose parts are empty or over [`MAX_DIMENSION`] a side, or over
/// [`MAX_PIXELS`] together, from its headers; returns the first part's size.
pub(crate) fn check_exr_parts(name: &Path, meta: &exr::meta::MetaData) -> Result<(usize, usize), ImageError> {
    let first = meta.headers.first().ok_or_else(|| ImageError::decode(name, "no image part"))?;
    let mut total = 0usize;
    for header in meta.headers.iter() {
        let (w, h) = (header.layer_size.width(), header.layer_size.height());
        if w == 0 || h == 0 || w > MAX_DIMENSION as usize || h > MAX_DIMENSION as usize {
            return Err(ImageError::invalid(name, format!("image size {w}x{h} is outside 1..={MAX_DIMENSION}")));
        }
        total = total.saturating_add(w * h);
    }
    if total > MAX_PIXELS {
        return Err(ImageError::invalid(name, format!("{total} pixels in all parts exceed {MAX_PIXELS}")));
    }
    Ok((first.layer_size.width(), first.layer_size.height()))
}

impl ImageFormat {
    /// The format `bytes` begin with: EXR, PNG, JPEG or PFM/PHM magic numbers, else `None`.
    pub fn sniff(bytes: &[u8]) -> Option<ImageFormat> {
        if bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
            Some(ImageFormat::Exr)
        } else if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
            Some(ImageFormat::Png)
        } else if bytes.starts_with(&[0xff, 0xd8, 0xff]) {
            Some(ImageFormat::Jpeg)
        } else if crate::pfm::is_pfm(bytes) {
            Some(if matches!(bytes[1], b'F' | b'f') { ImageFormat::Pfm } else { ImageFormat::Phm })
        } else {
            None
        }
    }

    /// The usual file extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            ImageFormat::Exr => "exr",
            ImageFormat::Png => "png",
            ImageFormat::Jpeg => "jpg",
            ImageFormat::Pfm => "pfm",
            ImageFormat::Phm => "phm",
        }
    }
}

/// Reads the format and size of the image in `bytes` from its header, and checks the size
/// against the limits ([`check_image_size`]; for EXR every part, and their total). Nothing is
/// decoded. `name` names the upload or file in errors.
pub fn read_image_header(name: &Path, bytes: &[u8]) -> Result<ImageHeader, ImageError> {
    let format = ImageFormat::sniff(bytes)
        .ok_or_else(|| ImageError::invalid(name, "is not an EXR, PNG, JPEG, PFM or PHM image (judged by its bytes)"))?;
    let (width, height) = match format {
        ImageFormat::Exr => {
            let meta = crate::contain_panic(|| exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false))
                .map_err(|e| ImageError::decode(name, e))?
                .map_err(|e| ImageError::decode(name, e))?;
            check_exr_parts(name, &meta)?
        }
        ImageFormat::Png | ImageFormat::Jpeg => {
            let reader = image::ImageReader::new(Cursor::new(bytes))
                .with_guessed_format()
                .map_err(|e| ImageError::io(name, e))?;
            let (w, h) = reader.into_dimensions().map_err(|e| ImageError::decode(name, e))?;
            (w as usize, h as usize)
        }
        ImageFormat::Pfm | ImageFormat::Phm => {
            let h = crate::pfm::read_pfm_header(name, bytes)?;
            (h.width, h.height)
        }
    };
    check_image_size(name, width, height)?;
    Ok(ImageHeader { format, width: width as u32, height: height as u32 })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A PNG (signature, IHDR, empty IDAT) declaring `w`x`h`, with no pixel data after it.
    fn png_header(w: u32, h: u32) -> Vec<u8> {
        let mut ihdr = b"IHDR".to_vec();
        ihdr.extend(w.to_be_bytes());
        ihdr.extend(h.to_be_bytes());
        ihdr.extend([8, 2, 0, 0, 0]);
        let crc = crc32(&ihdr);
        let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
        out.extend(13u32.to_be_bytes());
        out.extend(&ihdr);
        out.extend(crc.to_be_bytes());
        // An empty IDAT chunk: the header ends where pixel data would begin.
        out.extend(0u32.to_be_bytes());
        out.extend(b"IDAT");
        out.extend(crc32(b"IDAT").to_be_bytes());
        out
    }

    /// CRC-32 (IEEE), which the PNG chunk needs to be accepted.
    fn crc32(data: &[u8]) -> u32 {
        let mut c = !0u32;
        for &b in data {
            c ^= b as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 { 0xedb8_8320 ^ (c >> 1) } else { c >> 1 };
            }
        }
        !c
    }

    #[test]
    fn a_decompression_bomb_is_refused_from_its_header() {
        let err = read_image_header(Path::new("color"), &png_header(100_000, 100_000)).unwrap_err().to_string();
        assert!(err.starts_with("color: image size 100000x100000 is outside"), "{err}");
        let err = read_image_header(Path::new("color"), &png_header(16000, 16000)).unwrap_err().to_string();
        assert!(err.contains("exceeds"), "{err}");
        // The file reader holds to the same limit: a 16000×16000 PNG (each side allowed, 256
        // Mpx in all) used to be decoded, allocating 3 GB (found by fuzzing, as a JPEG).
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("bomb.png");
        std::fs::write(&file, png_header(16000, 16000)).unwrap();
        let err = crate::read_ldr(&file).unwrap_err().to_string();
        assert!(err.contains("exceeds"), "{err}");
        let ok = read_image_header(Path::new("color"), &png_header(640, 480)).unwrap();
        assert_eq!((ok.format, ok.width, ok.height), (ImageFormat::Png, 640, 480));
    }

    #[test]
    fn formats_are_judged_by_bytes() {
        assert_eq!(ImageFormat::sniff(b"\xff\xd8\xff\xe0rest"), Some(ImageFormat::Jpeg));
        assert_eq!(ImageFormat::sniff(b"<svg>"), None);
        assert_eq!(ImageFormat::sniff(b"PF\n1 1\n-1\n"), Some(ImageFormat::Pfm));
        assert_eq!(ImageFormat::sniff(b"Ph 1 1 -1 "), Some(ImageFormat::Phm));
        let h = read_image_header(Path::new("color"), b"PH\n640 480\n-1\n").unwrap();
        assert_eq!((h.format, h.width, h.height), (ImageFormat::Phm, 640, 480));
        assert!(read_image_header(Path::new("guide"), b"GIF89a....").is_err());
    }
}
