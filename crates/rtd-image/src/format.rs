use std::path::Path;

use crate::ImageError;

/// An image file format, chosen from a file's extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageFormat {
    /// OpenEXR, linear float channels.
    Exr,
    /// PNG, 8-bit sRGB.
    Png,
    /// JPEG, 8-bit sRGB.
    Jpeg,
    /// PFM, linear 32-bit float RGB (or grey), the format of `oidnDenoise`, pbrt and Mitsuba.
    Pfm,
    /// PHM, PFM's half-float twin.
    Phm,
}

impl ImageFormat {
    /// The format named by `path`'s extension (case-insensitive), or an error naming the file.
    pub fn from_path(path: &Path) -> Result<Self, ImageError> {
        let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
        match ext.as_deref() {
            Some("exr") => Ok(ImageFormat::Exr),
            Some("png") => Ok(ImageFormat::Png),
            Some("jpg") | Some("jpeg") => Ok(ImageFormat::Jpeg),
            Some("pfm") => Ok(ImageFormat::Pfm),
            Some("phm") => Ok(ImageFormat::Phm),
            _ => Err(ImageError::UnknownFormat { path: path.to_path_buf() }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extensions() {
        assert_eq!(ImageFormat::from_path(Path::new("a/b.EXR")).unwrap(), ImageFormat::Exr);
        assert_eq!(ImageFormat::from_path(Path::new("b.jpeg")).unwrap(), ImageFormat::Jpeg);
        assert_eq!(ImageFormat::from_path(Path::new("b.PFM")).unwrap(), ImageFormat::Pfm);
        assert_eq!(ImageFormat::from_path(Path::new("b.phm")).unwrap(), ImageFormat::Phm);
        assert!(ImageFormat::from_path(Path::new("b.tiff")).is_err());
        assert!(ImageFormat::from_path(Path::new("noext")).is_err());
    }
}
