use std::path::Path;

use exr::prelude::{
    read_all_flat_layers_from_file, AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer as ExrLayer,
    LayerAttributes, LineOrder, SmallVec, WritableImage,
};

use crate::layer::{Channels, Layer};
use crate::{write_bytes_atomic, HdrImage, ImageError, MAX_DIMENSION};

/// Named float channels of one size: the content of a one-part EXR.
///
/// Channel names follow the interoperable convention: `R,G,B` for the beauty and
/// `layer.channel` for the rest (`albedo.R`, `normal.X`, `depth.Z`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Layers {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `(name, samples)` pairs, each with `width * height` samples, row-major from the top.
    pub channels: Vec<(String, Vec<f32>)>,
}

impl Layers {
    /// An empty set of channels for an image of the given size.
    pub fn new(width: u32, height: u32) -> Self {
        Layers { width, height, channels: Vec::new() }
    }

    /// Adds one channel; replaces an existing channel of the same name.
    pub fn push(&mut self, name: impl Into<String>, samples: Vec<f32>) {
        let name = name.into();
        assert_eq!(samples.len(), self.width as usize * self.height as usize, "channel {name} has the wrong size");
        self.channels.retain(|(n, _)| *n != name);
        self.channels.push((name, samples));
    }

    /// Adds an image layer (an RGB or XYZ [`Layer`]); replaces its channels if present.
    pub fn put_image(&mut self, layer: Layer, image: &HdrImage) {
        assert_eq!((image.width, image.height), (self.width, self.height), "layer size mismatch");
        let names = layer.channel_names();
        assert_eq!(names.len(), 3, "{layer:?} is not an image layer");
        for (c, name) in names.into_iter().enumerate() {
            self.push(name, image.channel(c));
        }
    }

    /// Adds a one-value-per-pixel layer (a [`Channels::Scalar`] [`Layer`]).
    pub fn put_plane(&mut self, layer: Layer, samples: Vec<f32>) {
        let mut names = layer.channel_names();
        assert_eq!(names.len(), 1, "{layer:?} is not a scalar layer");
        self.push(names.remove(0), samples);
    }

    /// The channel of that name, if present.
    pub fn get(&self, name: &str) -> Option<&[f32]> {
        self.channels.iter().find(|(n, _)| n == name).map(|(_, s)| s.as_slice())
    }

    /// The image stored in `layer`'s channels, if all three exist.
    pub fn image(&self, layer: Layer) -> Option<HdrImage> {
        self.image_as(layer, layer.channels())
    }

    /// The image under `layer`'s prefix with the channel naming `channels` (for files from
    /// other software, which may store normals as `normal.R/G/B`).
    pub fn image_as(&self, layer: Layer, channels: Channels) -> Option<HdrImage> {
        let suffixes = match channels {
            Channels::Rgb => ["R", "G", "B"],
            Channels::Xyz => ["X", "Y", "Z"],
            Channels::Scalar(_) => return None,
        };
        let prefix = layer.prefix();
        let full = |n: &str| if prefix.is_empty() { n.to_string() } else { format!("{prefix}.{n}") };
        let r = self.get(&full(suffixes[0]))?;
        let g = self.get(&full(suffixes[1]))?;
        let b = self.get(&full(suffixes[2]))?;
        Some(HdrImage::from_planes(self.width, self.height, r, g, b))
    }

    /// The samples of a one-value-per-pixel layer, if present.
    pub fn plane(&self, layer: Layer) -> Option<&[f32]> {
        layer.channel_names().first().and_then(|n| self.get(n))
    }
}

/// Writes `layers` as a one-part, 32-bit float EXR, atomically.
/// Non-finite samples are written as 0, so NaN or Inf never reaches a file.
pub fn write_exr(path: &Path, layers: &Layers) -> Result<(), ImageError> {
    if layers.channels.is_empty() || layers.width == 0 || layers.height == 0 {
        return Err(ImageError::invalid(path, "refusing to write an empty EXR"));
    }
    let size = (layers.width as usize, layers.height as usize);
    let channels: SmallVec<[AnyChannel<FlatSamples>; 4]> = layers
        .channels
        .iter()
        .map(|(name, s)| {
            let clean = s.iter().map(|&v| if v.is_finite() { v } else { 0.0 }).collect();
            AnyChannel::new(name.as_str(), FlatSamples::F32(clean))
        })
        .collect();
    // Blocks in increasing order: with the default (unspecified) order, blocks compressed in
    // parallel land in completion order and the same image gives different bytes.
    let encoding = Encoding { line_order: LineOrder::Increasing, ..Encoding::FAST_LOSSLESS };
    let layer = ExrLayer::new(size, LayerAttributes::default(), encoding, AnyChannels::sort(channels));
    let image = Image::from_layer(layer);
    // exr needs a seekable writer: encode to memory, then write the bytes atomically.
    let mut encoded = std::io::Cursor::new(Vec::new());
    image.write().to_buffered(&mut encoded).map_err(|e| ImageError::decode(path, e))?;
    write_bytes_atomic(path, encoded.get_ref())
}

/// Reads every channel of the first part of an EXR (flat, largest resolution level), as f32.
/// Channels of other layers in the same part keep their full `layer.channel` names.
pub fn read_exr(path: &Path) -> Result<Layers, ImageError> {
    if !path.exists() {
        return Err(ImageError::missing(path));
    }
    let image = read_all_flat_layers_from_file(path).map_err(|e| ImageError::decode(path, e))?;
    let layer = image.layer_data.first().ok_or_else(|| ImageError::decode(path, "no image part"))?;
    let (w, h) = (layer.size.width(), layer.size.height());
    if w == 0 || h == 0 || w > MAX_DIMENSION as usize || h > MAX_DIMENSION as usize {
        return Err(ImageError::invalid(path, format!("image size {w}x{h} is outside 1..={MAX_DIMENSION}")));
    }
    let prefix = layer.attributes.layer_name.as_ref().map(|n| n.to_string());
    let mut out = Layers::new(w as u32, h as u32);
    for ch in &layer.channel_data.list {
        let name = match &prefix {
            Some(p) => format!("{p}.{}", ch.name),
            None => ch.name.to_string(),
        };
        let samples: Vec<f32> = ch.sample_data.values_as_f32().collect();
        if samples.len() != w * h {
            return Err(ImageError::invalid(path, format!("channel {name} is subsampled, which rtd does not read")));
        }
        out.channels.push((name, samples));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn round_trip_named_channels() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.exr");
        let img = HdrImage::from_pixels(3, 2, (0..6).map(|i| Vec3::new(i as f32, 1e6, -0.5)).collect());
        let mut layers = Layers::new(3, 2);
        layers.put_image(Layer::Beauty, &img);
        layers.put_image(Layer::Normal, &img);
        layers.put_plane(Layer::Depth, vec![f32::NAN, 1.0, 2.0, 3.0, f32::INFINITY, 5.0]);
        write_exr(&path, &layers).unwrap();
        let back = read_exr(&path).unwrap();
        assert_eq!(back.image(Layer::Beauty).unwrap(), img);
        assert_eq!(back.image(Layer::Normal).unwrap(), img);
        assert_eq!(back.image_as(Layer::Normal, Channels::Rgb), None);
        assert_eq!(back.get("normal.X").unwrap(), img.channel(0));
        assert_eq!(back.plane(Layer::Depth).unwrap(), &[0.0, 1.0, 2.0, 3.0, 0.0, 5.0]);
    }

    #[test]
    fn the_same_image_gives_identical_bytes() {
        let dir = tempfile::tempdir().unwrap();
        // Many blocks, so that parallel compression could reorder them.
        let (w, h) = (96u32, 512u32);
        let img = HdrImage::from_pixels(
            w,
            h,
            (0..w * h).map(|i| Vec3::new((i % 97) as f32, (i * 31 % 1013) as f32 * 1e-3, 0.5)).collect(),
        );
        let mut layers = Layers::new(w, h);
        layers.put_image(Layer::Beauty, &img);
        let bytes: Vec<Vec<u8>> = (0..4)
            .map(|k| {
                let path = dir.path().join(format!("{k}.exr"));
                write_exr(&path, &layers).unwrap();
                std::fs::read(path).unwrap()
            })
            .collect();
        assert!(bytes.iter().all(|b| *b == bytes[0]));
    }

    #[test]
    fn corrupt_file_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.exr");
        std::fs::write(&path, b"not an exr at all").unwrap();
        let err = read_exr(&path).unwrap_err().to_string();
        assert!(err.contains("bad.exr"), "{err}");
        assert!(read_exr(&dir.path().join("missing.exr")).is_err());
    }
}
