use std::borrow::Cow;
use std::path::Path;

use exr::prelude::{
    f16, AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer as ExrLayer, LayerAttributes, LineOrder,
    SmallVec, WritableImage,
};

use crate::layer::{join, Channels, Layer};
use crate::{write_bytes_atomic, HdrImage, ImageError};

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
    /// The channels stored as 16-bit half floats (as read from a file, or to be written so);
    /// the rest are 32-bit.
    pub half_channels: Vec<String>,
}

impl Layers {
    /// An empty set of channels for an image of the given size.
    pub fn new(width: u32, height: u32) -> Self {
        Layers { width, height, channels: Vec::new(), half_channels: Vec::new() }
    }

    /// Adds one channel; replaces an existing channel of the same name.
    pub fn push(&mut self, name: impl Into<String>, samples: Vec<f32>) {
        let name = name.into();
        assert_eq!(samples.len(), self.width as usize * self.height as usize, "channel {name} has the wrong size");
        self.channels.retain(|(n, _)| *n != name);
        self.half_channels.retain(|n| *n != name);
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
        let suffixes = channels.triple()?;
        let [r, g, b] = suffixes.map(|n| self.get(&join(&layer.prefix(), n)));
        Some(HdrImage::from_planes(self.width, self.height, r?, g?, b?))
    }

    /// Replaces the samples of the existing channel `name`, keeping its sample type (half or
    /// 32-bit); adds it as a 32-bit channel if absent.
    pub fn set_samples(&mut self, name: &str, samples: Vec<f32>) {
        assert_eq!(samples.len(), self.width as usize * self.height as usize, "channel {name} has the wrong size");
        match self.channels.iter_mut().find(|(n, _)| n == name) {
            Some((_, s)) => *s = samples,
            None => self.channels.push((name.to_string(), samples)),
        }
    }

    /// The samples of a one-value-per-pixel layer, if present.
    pub fn plane(&self, layer: Layer) -> Option<&[f32]> {
        layer.channel_names().first().and_then(|n| self.get(n))
    }
}

/// Writes `layers` as a one-part float EXR, atomically: 32-bit channels, and 16-bit ones for
/// those in [`Layers::half_channels`]. Non-finite samples are written as 0, and half samples
/// beyond half's range as its largest finite value, so NaN or Inf never reaches a file.
pub fn write_exr(path: &Path, layers: &Layers) -> Result<(), ImageError> {
    write_bytes_atomic(path, &encode_exr(path, layers)?)
}

/// [`write_exr`], taking the channels: 32-bit ones move into the encoder instead of being copied,
/// so a large image is not held twice while it is written (a 4K file of 17 channels: 564 MB less
/// at the peak).
pub fn write_exr_owned(path: &Path, layers: Layers) -> Result<(), ImageError> {
    let (size, half) = ((layers.width, layers.height), layers.half_channels);
    let channels = layers.channels.into_iter().map(|(name, s)| (name, Cow::Owned(s)));
    write_bytes_atomic(path, &encode_channels(path, size, &half, channels)?)
}

/// The bytes [`write_exr`] writes for `layers`: the same bytes for the same layers on any
/// machine, so an EXR made on one machine and written on another is the file the second would
/// have made. `path` names the file in errors.
pub fn encode_exr(path: &Path, layers: &Layers) -> Result<Vec<u8>, ImageError> {
    let channels = layers.channels.iter().map(|(name, s)| (name.clone(), Cow::Borrowed(s.as_slice())));
    encode_channels(path, (layers.width, layers.height), &layers.half_channels, channels)
}

/// Encodes `width` × `height` channels, those named in `half` as 16-bit and the rest 32-bit, with
/// non-finite samples as 0 and half samples clamped to half's range. Owned 32-bit samples are
/// cleaned in place and moved, not copied.
fn encode_channels<'a>(
    path: &Path,
    (width, height): (u32, u32),
    half: &[String],
    channels: impl Iterator<Item = (String, Cow<'a, [f32]>)>,
) -> Result<Vec<u8>, ImageError> {
    let channels: SmallVec<[AnyChannel<FlatSamples>; 4]> = channels
        .map(|(name, s)| {
            let clean = |v: f32| if v.is_finite() { v } else { 0.0 };
            let samples = if half.contains(&name) {
                let max = f16::MAX.to_f32();
                FlatSamples::F16(s.iter().map(|&v| f16::from_f32(clean(v).clamp(-max, max))).collect())
            } else {
                let mut v = s.into_owned();
                v.iter_mut().for_each(|x| *x = clean(*x));
                FlatSamples::F32(v)
            };
            AnyChannel::new(name.as_str(), samples)
        })
        .collect();
    if channels.is_empty() || width == 0 || height == 0 {
        return Err(ImageError::invalid(path, "refusing to write an empty EXR"));
    }
    let size = (width as usize, height as usize);
    // Blocks in increasing order: with the default (unspecified) order, blocks compressed in
    // parallel land in completion order and the same image gives different bytes.
    let encoding = Encoding { line_order: LineOrder::Increasing, ..Encoding::FAST_LOSSLESS };
    let layer = ExrLayer::new(size, LayerAttributes::default(), encoding, AnyChannels::sort(channels));
    let image = Image::from_layer(layer);
    // exr needs a seekable writer: encode to memory, then write the bytes atomically.
    let mut encoded = std::io::Cursor::new(Vec::new());
    image.write().to_buffered(&mut encoded).map_err(|e| ImageError::decode(path, e))?;
    Ok(encoded.into_inner())
}

/// Reads every channel of every part of an EXR (flat, largest resolution level), as f32. A
/// channel is named `part.channel` when its part has a name (multi-part files such as Blender's,
/// whose parts are `ViewLayer.Combined`, `ViewLayer.Denoising Albedo`, …), else by its own name;
/// channel names that already carry the part's name keep it once. Every part must have the same
/// size. Sizes are checked from the headers before anything is decoded.
pub fn read_exr(path: &Path) -> Result<Layers, ImageError> {
    if !path.exists() {
        return Err(ImageError::missing(path));
    }
    check_exr_headers(path)?;
    // The exr crate panics on some malformed files (found by fuzzing): fenced. Its parallel
    // decoder runs blocks on a thread pool of its own, where a panic aborts the process
    // instead of unwinding to the fence, so the blocks are decoded on this thread.
    let read = || {
        use exr::prelude::{ReadChannels, ReadLayers};
        exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .all_layers()
            .all_attributes()
            .non_parallel()
            .from_file(path)
    };
    let image = crate::contain_panic(read)
        .map_err(|e| ImageError::decode(path, e))?
        .map_err(|e| ImageError::decode(path, e))?;
    let first = image.layer_data.first().ok_or_else(|| ImageError::decode(path, "no image part"))?;
    let (w, h) = (first.size.width(), first.size.height());
    let mut out = Layers::new(w as u32, h as u32);
    // The parts are taken apart as they are read: 32-bit samples move into the channels, so
    // the file is never held twice.
    for part in image.layer_data {
        if (part.size.width(), part.size.height()) != (w, h) {
            let name = part.attributes.layer_name.as_ref().map(|n| n.to_string()).unwrap_or_default();
            return Err(ImageError::invalid(
                path,
                format!("part {name:?} is {}x{}, another part is {w}x{h}", part.size.width(), part.size.height()),
            ));
        }
        let prefix = part.attributes.layer_name.as_ref().map(|n| n.to_string());
        for ch in part.channel_data.list {
            let own = ch.name.to_string();
            let name = match &prefix {
                Some(p) if !own.starts_with(&format!("{p}.")) => format!("{p}.{own}"),
                _ => own,
            };
            let half = matches!(ch.sample_data, FlatSamples::F16(_));
            let samples: Vec<f32> = match ch.sample_data {
                FlatSamples::F32(v) => v,
                other => other.values_as_f32().collect(),
            };
            if samples.len() != w * h {
                return Err(ImageError::invalid(
                    path,
                    format!("channel {name} is subsampled, which rtd does not read"),
                ));
            }
            if half {
                out.half_channels.push(name.clone());
            }
            out.channels.push((name, samples));
        }
    }
    Ok(out)
}

/// Refuses, from the headers alone, an EXR whose parts are empty, wider or taller than
/// [`MAX_DIMENSION`], or larger than [`MAX_PIXELS`] together.
fn check_exr_headers(path: &Path) -> Result<(), ImageError> {
    let meta = crate::contain_panic(|| exr::meta::MetaData::read_from_file(path, false))
        .map_err(|e| ImageError::decode(path, e))?
        .map_err(|e| ImageError::decode(path, e))?;
    crate::sniff::check_exr_parts(path, &meta).map(|_| ())
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

    /// Writing channels taken (moved into the encoder) and writing them borrowed (copied) give
    /// the same file, non-finite samples and half channels beyond half's range included; and
    /// reading moves 32-bit samples out with their bits, half ones widened.
    #[test]
    fn owned_and_borrowed_channels_write_the_same_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let mut layers = Layers::new(3, 2);
        layers.push("R", vec![1.5, f32::NAN, -0.0, f32::INFINITY, 1e-40, -3.0]);
        layers.push("half.Y", vec![1e6, -1e6, f32::NEG_INFINITY, 0.333, 65504.0, 2.0]);
        layers.half_channels.push("half.Y".into());
        let (borrowed, owned) = (dir.path().join("b.exr"), dir.path().join("o.exr"));
        write_exr(&borrowed, &layers).unwrap();
        write_exr_owned(&owned, layers.clone()).unwrap();
        assert_eq!(std::fs::read(&borrowed).unwrap(), std::fs::read(&owned).unwrap());
        let back = read_exr(&owned).unwrap();
        let bits = |s: &[f32]| s.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(back.get("R").unwrap()), bits(&[1.5, 0.0, -0.0, 0.0, 1e-40, -3.0]));
        assert_eq!(back.get("half.Y").unwrap(), &[65504.0, -65504.0, 0.0, f16::from_f32(0.333).to_f32(), 65504.0, 2.0]);
        assert_eq!(back.half_channels, ["half.Y"]);
        let empty = write_exr_owned(&dir.path().join("e.exr"), Layers::new(3, 2)).unwrap_err().to_string();
        assert!(empty.contains("refusing to write an empty EXR"), "{empty}");
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
    fn a_header_declaring_a_huge_image_is_refused_before_decoding() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bomb.exr");
        let mut layers = Layers::new(4, 4);
        layers.put_image(Layer::Beauty, &HdrImage::new(4, 4));
        write_exr(&path, &layers).unwrap();
        // Patch the data window (box2i: xMin, yMin, xMax, yMax) to 100000 × 100000 pixels.
        let mut bytes = std::fs::read(&path).unwrap();
        let key = b"dataWindow\0box2i\0";
        let at = bytes.windows(key.len()).position(|w| w == key).unwrap() + key.len() + 4;
        for (k, v) in [0i32, 0, 99_999, 99_999].iter().enumerate() {
            bytes[at + 4 * k..at + 4 * k + 4].copy_from_slice(&v.to_le_bytes());
        }
        std::fs::write(&path, &bytes).unwrap();
        let err = read_exr(&path).unwrap_err().to_string();
        assert!(err.contains("bomb.exr") && err.contains("100000x100000"), "{err}");
    }

    #[test]
    fn every_part_of_a_multipart_file_is_read_under_its_name() {
        use exr::prelude::{Image, ImageAttributes, IntegerBounds, WritableImage};
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("parts.exr");
        let part = |name: &str, channels: &[(&str, f32)]| {
            let list: SmallVec<[AnyChannel<FlatSamples>; 4]> =
                channels.iter().map(|(n, v)| AnyChannel::new(*n, FlatSamples::F32(vec![*v; 6]))).collect();
            ExrLayer::new((3, 2), LayerAttributes::named(name), Encoding::FAST_LOSSLESS, AnyChannels::sort(list))
        };
        let parts = vec![
            part("ViewLayer.Combined", &[("R", 1.0), ("G", 2.0), ("B", 3.0), ("A", 1.0)]),
            part("ViewLayer.Denoising Normal", &[("X", 0.0), ("Y", 0.0), ("Z", 1.0)]),
        ];
        Image::from_layers(ImageAttributes::new(IntegerBounds::from_dimensions((3, 2))), parts)
            .write()
            .to_file(&path)
            .unwrap();
        let back = read_exr(&path).unwrap();
        assert_eq!(back.get("ViewLayer.Combined.G").unwrap(), &[2.0; 6]);
        assert_eq!(back.prefixes(), ["ViewLayer.Combined", "ViewLayer.Denoising Normal"]);
        assert_eq!(back.find_image(Layer::Beauty).unwrap().pixels[0], Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(back.find_image(Layer::Normal).unwrap().pixels[5], Vec3::Z);
        assert_eq!(back.find_image(Layer::Albedo), None);
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
