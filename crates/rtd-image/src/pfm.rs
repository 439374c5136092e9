//! PFM and PHM: the portable float map (32-bit, `PF`/`Pf`) and its half-float twin (`PH`/`Ph`),
//! the formats of `oidnDenoise`, pbrt and Mitsuba. A header of three whitespace-separated
//! tokens (kind, `width height`, scale) ends in one whitespace byte; the pixels follow bottom row
//! first, little-endian when the scale is negative. `Pf`/`Ph` hold one channel, read as grey.

use std::path::Path;

use exr::prelude::f16;
use glam::Vec3;

use crate::limits::check_image_size;
use crate::{write_bytes_atomic, HdrImage, ImageError};

/// What a PFM/PHM header says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PfmHeader {
    /// Channels per pixel: 3 (`PF`, `PH`) or 1 (`Pf`, `Ph`).
    pub channels: usize,
    /// Bytes per sample: 4 (PFM) or 2 (PHM).
    pub sample_bytes: usize,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Samples are little-endian (negative scale).
    pub little_endian: bool,
    /// Offset of the first pixel byte.
    pub data_offset: usize,
}

/// Longest header rtd reads: three tokens of a few digits each, with generous whitespace.
const MAX_HEADER: usize = 256;

/// Whether `bytes` start like a PFM or PHM file (the kind token and a whitespace byte).
pub(crate) fn is_pfm(bytes: &[u8]) -> bool {
    matches!(bytes, [b'P', b'F' | b'f' | b'H' | b'h', w, ..] if w.is_ascii_whitespace())
}

/// Parses the header of a PFM/PHM file and checks its size against the limits; `name` names the
/// file in errors.
pub fn read_pfm_header(name: &Path, bytes: &[u8]) -> Result<PfmHeader, ImageError> {
    let bad = |what: &str| ImageError::invalid(name, format!("not a PFM/PHM file: {what}"));
    let mut tokens: Vec<&[u8]> = Vec::with_capacity(4);
    let mut pos = 0;
    // Four tokens: kind, width, height, scale; each ends at whitespace.
    while tokens.len() < 4 {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        if pos >= bytes.len() || pos > MAX_HEADER || start == pos {
            return Err(bad("the header (kind, width, height, scale) is incomplete"));
        }
        tokens.push(&bytes[start..pos]);
    }
    // Exactly one whitespace byte separates the scale from the pixels.
    let data_offset = pos + 1;
    let (channels, sample_bytes) = match tokens[0] {
        b"PF" => (3, 4),
        b"Pf" => (1, 4),
        b"PH" => (3, 2),
        b"Ph" => (1, 2),
        _ => return Err(bad("the kind is not PF, Pf, PH or Ph")),
    };
    let number = |t: &[u8]| std::str::from_utf8(t).ok().map(str::to_string);
    let size = |t: &[u8]| number(t).and_then(|s| s.parse::<usize>().ok());
    let (width, height) = match (size(tokens[1]), size(tokens[2])) {
        (Some(w), Some(h)) => (w, h),
        _ => return Err(bad("the width and height are not whole numbers")),
    };
    check_image_size(name, width, height)?;
    let scale = number(tokens[3]).and_then(|s| s.parse::<f64>().ok());
    let little_endian = match scale {
        Some(s) if s.is_finite() && s != 0.0 => s < 0.0,
        _ => {
            let text = String::from_utf8_lossy(tokens[3]);
            return Err(ImageError::invalid(
                name,
                format!("PFM scale {text:?} is not a non-zero finite number (its sign gives the byte order)"),
            ));
        }
    };
    Ok(PfmHeader { channels, sample_bytes, width, height, little_endian, data_offset })
}

/// Reads a PFM or PHM file as linear RGB (one-channel files as grey). NaN and infinite samples
/// are kept for the caller to count and clean, as an EXR's are.
pub fn read_pfm(path: &Path) -> Result<HdrImage, ImageError> {
    if !path.exists() {
        return Err(ImageError::missing(path));
    }
    let bytes = std::fs::read(path).map_err(|e| ImageError::io(path, e))?;
    decode_pfm(path, &bytes)
}

/// Decodes PFM/PHM `bytes`; `name` names the file in errors.
pub fn decode_pfm(name: &Path, bytes: &[u8]) -> Result<HdrImage, ImageError> {
    let h = read_pfm_header(name, bytes)?;
    let samples = h.width * h.height * h.channels;
    let need = samples * h.sample_bytes;
    let data = bytes.get(h.data_offset..).unwrap_or_default();
    if data.len() != need {
        return Err(ImageError::invalid(
            name,
            format!(
                "a {}x{} {}-channel file needs {need} bytes of pixels, it has {}",
                h.width,
                h.height,
                h.channels,
                data.len()
            ),
        ));
    }
    let sample = |i: usize| -> f32 {
        let b = &data[i * h.sample_bytes..(i + 1) * h.sample_bytes];
        match (h.sample_bytes, h.little_endian) {
            (4, true) => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            (4, false) => f32::from_be_bytes([b[0], b[1], b[2], b[3]]),
            (_, true) => f16::from_le_bytes([b[0], b[1]]).to_f32(),
            (_, false) => f16::from_be_bytes([b[0], b[1]]).to_f32(),
        }
    };
    let mut pixels = Vec::with_capacity(h.width * h.height);
    // Rows are stored bottom first; rtd's images are top first.
    for y in (0..h.height).rev() {
        for x in 0..h.width {
            let i = (y * h.width + x) * h.channels;
            pixels.push(match h.channels {
                3 => Vec3::new(sample(i), sample(i + 1), sample(i + 2)),
                _ => Vec3::splat(sample(i)),
            });
        }
    }
    Ok(HdrImage::from_pixels(h.width as u32, h.height as u32, pixels))
}

/// Encodes `image` as a little-endian three-channel PFM (`half`: PHM). Non-finite samples are
/// written as 0, and for PHM values beyond half's range as its largest finite value.
pub fn encode_pfm(image: &HdrImage, half: bool) -> Vec<u8> {
    let kind = if half { "PH" } else { "PF" };
    let mut out = format!("{kind}\n{} {}\n-1.0\n", image.width, image.height).into_bytes();
    let w = image.width as usize;
    for row in image.pixels.chunks(w.max(1)).rev() {
        for p in row {
            for v in p.to_array() {
                let v = if v.is_finite() { v } else { 0.0 };
                if half {
                    let max = f16::MAX.to_f32();
                    out.extend(f16::from_f32(v.clamp(-max, max)).to_le_bytes());
                } else {
                    out.extend(v.to_le_bytes());
                }
            }
        }
    }
    out
}

/// Writes `image` as PFM (`half`: PHM), atomically ([`encode_pfm`]).
pub fn write_pfm(path: &Path, image: &HdrImage, half: bool) -> Result<(), ImageError> {
    write_bytes_atomic(path, &encode_pfm(image, half))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image() -> HdrImage {
        HdrImage::from_pixels(3, 2, (0..6).map(|i| Vec3::new(i as f32, 0.5 * i as f32, -(i as f32))).collect())
    }

    #[test]
    fn pfm_and_phm_round_trip_top_row_first() {
        let img = image();
        assert_eq!(decode_pfm(Path::new("a.pfm"), &encode_pfm(&img, false)).unwrap(), img);
        // These values are exact in half precision.
        assert_eq!(decode_pfm(Path::new("a.phm"), &encode_pfm(&img, true)).unwrap(), img);
        // The first stored row is the image's bottom row.
        let bytes = encode_pfm(&img, false);
        let first = f32::from_le_bytes(bytes[b"PF\n3 2\n-1.0\n".len()..][..4].try_into().unwrap());
        assert_eq!(first, 3.0);
    }

    #[test]
    fn big_endian_grey_files_read_as_grey() {
        let mut bytes = b"Pf 2 1 1.0\n".to_vec();
        for v in [0.25f32, 2.0] {
            bytes.extend(v.to_be_bytes());
        }
        let img = decode_pfm(Path::new("g.pfm"), &bytes).unwrap();
        assert_eq!(img.pixels, [Vec3::splat(0.25), Vec3::splat(2.0)]);
    }

    #[test]
    fn bad_headers_and_sizes_are_named() {
        let err = |b: &[u8]| decode_pfm(Path::new("x.pfm"), b).unwrap_err().to_string();
        assert!(err(b"PF\n2 2\n0\n").contains("scale \"0\" is not a non-zero finite number"));
        assert!(err(b"PF\n2 2\nnan\n").contains("scale \"nan\""));
        assert!(err(b"PF\n2 2\n-1\n\0\0").contains("needs 48 bytes of pixels, it has 2"));
        assert!(err(b"PX\n2 2\n-1\n").contains("kind"));
        assert!(err(b"PF\n2").contains("incomplete"));
        assert!(err(b"PF\n100000 1\n-1\n").contains("outside"));
        assert!(err(b"PF\n-2 2\n-1\n").contains("whole numbers"));
        assert!(is_pfm(b"PF\n") && is_pfm(b"Ph ") && !is_pfm(b"PFX") && !is_pfm(b"P6\n"));
    }

    #[test]
    fn phm_output_never_holds_inf_or_nan() {
        let img = HdrImage::from_pixels(1, 1, vec![Vec3::new(1e9, f32::NAN, f32::NEG_INFINITY)]);
        let back = decode_pfm(Path::new("a.phm"), &encode_pfm(&img, true)).unwrap();
        assert_eq!(back.pixels[0], Vec3::new(65504.0, 0.0, 0.0));
    }
}
