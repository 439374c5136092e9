//! Tiled, threaded inference with a trained [`DenoiserNet`]: load a model (file or the one
//! compiled into the binary), encode the inputs, run overlapping tiles, decode.

use std::path::Path;

use burn::module::Module;
use burn::store::ModuleRecord;
use burn::tensor::{Bytes, Device, Tensor, TensorData};
use glam::Vec3;
use rayon::prelude::*;
use rtd_image::HdrImage;

use crate::encode::{add_decoded_row, demod_albedo, demod_factor, DenoiseInput};
use crate::fast::{FastNet, Map, Scratch};
use crate::model::{DenoiserConfig, DenoiserNet};
use crate::plane_encoder::{PlaneEncoder, PlaneSource};
use crate::planes::{is_supported_width, LEGACY_INPUT_CHANNELS};
use crate::{DenoiseError, INPUT_CHANNELS};
use rtd_image::MAX_DIMENSION;

/// The shipped model's config and weights, compiled into the binary.
const BUILTIN_CONFIG: &str = include_str!("../../../models/rtd-denoiser.json");
const BUILTIN_WEIGHTS: &[u8] = include_bytes!("../../../models/rtd-denoiser.bpk");

/// How far past the image edges the edge pixels are repeated (rounded up to the network's
/// alignment, and at most the tile margin); the network's own zero padding lies beyond that.
/// Measured on the validation views (docs/denoiser.md): on 2026-12-06, 8 px scored as 16
/// did and none 0.01 dB less (stage 14, 50 views); at stage 9 every width from 0 to 48 px
/// scored within 0.01 dB. At 512², 8 px does 6% less work than 16.
pub const EDGE_PAD: usize = 8;

/// A trained denoiser ready to run.
pub struct Denoiser {
    net: DenoiserNet,
    fast: FastNet,
    use_burn: bool,
    config: DenoiserConfig,
    device: Device,
    name: String,
    tile: usize,
    /// Self-ensemble passes (1 to 8): see [`Denoiser::passes`].
    passes: usize,
    /// Feature buffers kept between calls (taken with `try_lock`; a concurrent call uses its own).
    scratch: std::sync::Mutex<Scratch>,
}

/// Most self-ensemble passes: one per symmetry of the square.
pub const MAX_PASSES: usize = 8;

/// One of the eight symmetries of the pixel grid that training's augmentation draws crops under
/// (a transpose, then mirrors of the transposed axes): pixel (x, y) of the transformed image is
/// pixel [`Dihedral::source`] of the original.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Dihedral {
    /// Swap x and y.
    pub transpose: bool,
    /// Mirror x (after the transpose).
    pub flip_x: bool,
    /// Mirror y (after the transpose).
    pub flip_y: bool,
}

impl Dihedral {
    /// The eight symmetries in the order self-ensemble passes use them: identity, transpose,
    /// half turn, anti-transpose, then the two mirrors and the two quarter turns.
    pub const ORDER: [Dihedral; MAX_PASSES] = {
        const fn d(transpose: bool, flip_x: bool, flip_y: bool) -> Dihedral {
            Dihedral { transpose, flip_x, flip_y }
        }
        [
            d(false, false, false),
            d(true, false, false),
            d(false, true, true),
            d(true, true, true),
            d(false, true, false),
            d(false, false, true),
            d(true, true, false),
            d(true, false, true),
        ]
    };

    /// Width and height of a `w`×`h` image after the transform.
    pub fn size(self, w: usize, h: usize) -> (usize, usize) {
        if self.transpose {
            (h, w)
        } else {
            (w, h)
        }
    }

    /// Index (y × w + x) in the original `w`×`h` image of pixel (x, y) of the transformed one.
    pub fn source(self, x: usize, y: usize, w: usize, h: usize) -> usize {
        let (tw, th) = self.size(w, h);
        // Flips act on the transformed axes, then the transpose maps back.
        let (x, y) = (if self.flip_x { tw - 1 - x } else { x }, if self.flip_y { th - 1 - y } else { y });
        let (u, v) = if self.transpose { (y, x) } else { (x, y) };
        v * w + u
    }
}

impl Denoiser {
    /// Builds a denoiser from a config (JSON) and burnpack weights; `name` is shown in reports.
    pub fn from_bytes(config_json: &str, weights: Vec<u8>, name: &str) -> Result<Self, DenoiseError> {
        let config = DenoiserConfig::from_json(config_json)
            .map_err(|e| DenoiseError::model(name, format!("bad model config: {e}")))?;
        if !is_supported_width(config.input_channels) {
            return Err(DenoiseError::model(
                name,
                format!(
                    "model expects {} input channels, this rtd provides {INPUT_CHANNELS} (or {LEGACY_INPUT_CHANNELS} for older models)",
                    config.input_channels
                ),
            ));
        }
        if let Some(problem) = config.shape_problem() {
            return Err(DenoiseError::model(name, problem));
        }
        let device = Device::flex();
        // burn's record reader is fenced as the other parsers are: a model file is a stranger's too.
        let record = rtd_image::contain_panic(|| ModuleRecord::from_bytes(Bytes::from_bytes_vec(weights)))
            .map_err(|e| DenoiseError::model(name, e))?
            .map_err(|e| DenoiseError::model(name, format!("corrupt weights: {e}")))?;
        let net = rtd_image::contain_panic(|| config.init(&device).try_load_record(record))
            .map_err(|e| DenoiseError::model(name, e))?
            .map_err(|e| DenoiseError::model(name, format!("weights do not match the config: {e}")))?;
        Ok(Self::from_net(net, config, device, name))
    }

    /// Loads `path` (burnpack weights) and its config `path` with extension `.json`.
    pub fn load(path: &Path) -> Result<Self, DenoiseError> {
        let weights = std::fs::read(path).map_err(|source| DenoiseError::Io { path: path.into(), source })?;
        let cfg_path = path.with_extension("json");
        let config =
            std::fs::read_to_string(&cfg_path).map_err(|source| DenoiseError::Io { path: cfg_path.clone(), source })?;
        Self::from_bytes(&config, weights, &path.display().to_string())
    }

    /// The model shipped in `models/` and compiled into the binary.
    pub fn builtin() -> Result<Self, DenoiseError> {
        Self::from_bytes(BUILTIN_CONFIG, BUILTIN_WEIGHTS.to_vec(), "builtin:rtd-denoiser")
    }

    /// A denoiser of `config`'s shape with untrained weights drawn from `seed`: what tests of
    /// the inference machinery and speed measurements of other shapes run.
    pub fn untrained(config: DenoiserConfig, seed: u64) -> Self {
        let device = Device::flex();
        let net = config.init_seeded(&device, seed);
        Self::from_net(net, config, device, &format!("untrained:{seed}"))
    }

    /// Wraps an already-built network (training's validation uses this).
    pub fn from_net(net: DenoiserNet, config: DenoiserConfig, device: Device, name: &str) -> Self {
        let fast = FastNet::from_net(&net);
        Denoiser {
            net,
            fast,
            use_burn: false,
            config,
            device,
            name: name.to_string(),
            tile: 768,
            passes: 1,
            scratch: Default::default(),
        }
    }

    /// Sets the tile size (rounded up to the network's alignment).
    pub fn tile(mut self, tile: usize) -> Self {
        let a = self.config.alignment();
        self.tile = tile.max(1).div_ceil(a) * a;
        self
    }

    /// Self-ensemble: runs the network on the image under the first `n` (1 to [`MAX_PASSES`])
    /// symmetries of [`Dihedral::ORDER`] and averages the decoded outputs. Each pass costs a
    /// whole run; 1 (the default) is the network alone. `rtd bench validation --ensemble` and
    /// `rtd bench speed --ensemble` measure the trade.
    pub fn passes(mut self, n: usize) -> Self {
        self.passes = n.clamp(1, MAX_PASSES);
        self
    }

    /// Runs the network through burn instead of the fast im2col + gemm path (for tests and
    /// benchmarks; both compute the same function).
    pub fn with_burn(mut self, on: bool) -> Self {
        self.use_burn = on;
        self
    }

    /// The model's name (path or `builtin:…`).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Self-ensemble passes per call (1: the network alone).
    pub fn ensemble_passes(&self) -> usize {
        self.passes
    }

    /// The model's config.
    pub fn config(&self) -> &DenoiserConfig {
        &self.config
    }

    /// Whether the model reads the colour's per-pixel variance (models made before the variance
    /// planes do not).
    pub fn reads_variance(&self) -> bool {
        self.config.input_channels > LEGACY_INPUT_CHANNELS
    }

    /// Tile overlap: the receptive radius rounded up to the alignment.
    pub fn margin(&self) -> usize {
        let a = self.config.alignment();
        self.config.receptive_radius().div_ceil(a) * a
    }

    /// Denoises one image.
    pub fn denoise(&self, input: &DenoiseInput) -> Result<HdrImage, DenoiseError> {
        let (w, h) = input.size()?;
        if w == 0 || h == 0 || w > MAX_DIMENSION || h > MAX_DIMENSION {
            return Err(DenoiseError::Size { width: w, height: h });
        }
        let encoding = self.config.encoding();
        let exposure = encoding.exposure(input.color);
        // Each tile's window is encoded as it is read: no whole-image input planes.
        let encoder = PlaneEncoder::new(input, exposure, encoding)?;
        let n = (w * h) as usize;
        // Mean over the passes of the decoded output (one pass: the decoded output itself).
        let mut sum = vec![0.0f32; 3 * n];
        for t in &Dihedral::ORDER[..self.passes] {
            let out = self.run_source_as(PlaneSource::Inputs(&encoder), w as usize, h as usize, *t);
            sum.par_chunks_mut(w as usize)
                .zip(out.par_chunks(w as usize))
                .for_each(|(s, o)| add_decoded_row(s, o, exposure));
        }
        let passes = self.passes as f32;
        // Multiply the albedo back in if the colour was demodulated.
        let demod = demod_albedo(input, encoding.demodulate);
        let channel = |k: usize, i: usize| (sum[k * n + i] / passes * demod_factor(demod, i, k)).min(f32::MAX);
        let pixels = (0..n).into_par_iter().map(|i| Vec3::new(channel(0, i), channel(1, i), channel(2, i))).collect();
        Ok(HdrImage::from_pixels(w, h, pixels))
    }

    /// Replicated pixels beyond each image edge: [`EDGE_PAD`] rounded up to the alignment,
    /// at most the margin.
    pub fn edge_pad(&self) -> usize {
        let a = self.config.alignment();
        EDGE_PAD.div_ceil(a).min(self.margin().div_ceil(a)) * a
    }

    /// Runs the network over encoded input planes (C × H × W), tile by tile, and returns the
    /// encoded output planes (3 × H × W).
    ///
    /// The function computed is the network applied to the image extended by
    /// [`Denoiser::edge_pad`] repeated edge pixels on each side (and to a multiple of the
    /// alignment). Each tile reads its neighbours' pixels out to the receptive radius, clipped to
    /// that extended image, and its windows keep the extended image's alignment, so tiled and
    /// untiled runs compute the same values.
    pub fn run_planes(&self, planes: &[f32], w: usize, h: usize) -> Vec<f32> {
        self.run_planes_as(planes, w, h, Dihedral::ORDER[0])
    }

    /// [`Denoiser::run_planes`] on the image transformed by `t` (read in place, not copied),
    /// with the output mapped back to the original's pixels.
    pub fn run_planes_as(&self, planes: &[f32], w: usize, h: usize, t: Dihedral) -> Vec<f32> {
        self.run_source_as(PlaneSource::Planes(planes), w, h, t)
    }

    /// [`Denoiser::run_planes_as`] on planes from `source`.
    fn run_source_as(&self, source: PlaneSource, w: usize, h: usize, t: Dihedral) -> Vec<f32> {
        let (ow, oh) = (w, h);
        let (w, h) = t.size(w, h);
        let a = self.config.alignment();
        let (m, p) = (self.margin() as i64, self.edge_pad() as i64);
        let (wp, hp) = (w.div_ceil(a) * a, h.div_ceil(a) * a);
        let mut out = vec![0.0f32; 3 * w * h];
        let mut own = Scratch::default();
        let mut kept = self.scratch.try_lock();
        let scratch = match kept.as_deref_mut() {
            Ok(s) => s,
            Err(_) => &mut own,
        };
        for ty in (0..hp).step_by(self.tile) {
            let th = self.tile.min(hp - ty);
            for tx in (0..wp).step_by(self.tile) {
                let tw = self.tile.min(wp - tx);
                // The tile plus its margin, clipped to the extended image.
                let (x0, y0) = ((tx as i64 - m).max(-p), (ty as i64 - m).max(-p));
                let (x1, y1) = (((tx + tw) as i64 + m).min(wp as i64 + p), ((ty + th) as i64 + m).min(hp as i64 + p));
                let (iw, ih) = ((x1 - x0) as usize, (y1 - y0) as usize);
                let tile = self.run_tile(source, (ow, oh), t, (x0, y0, iw, ih), scratch);
                // Keep the tile's interior, each pixel where it came from (a plane per task).
                let (ox, oy) = ((tx as i64 - x0) as usize, (ty as i64 - y0) as usize);
                out.par_chunks_mut(w * h).enumerate().for_each(|(c, plane)| {
                    for y in ty..(ty + th).min(h) {
                        let src = &tile.data[c * iw * ih + (y - ty + oy) * iw + ox..][..(tx + tw).min(w) - tx];
                        for (i, v) in src.iter().enumerate() {
                            plane[t.source(tx + i, y, ow, oh)] = *v;
                        }
                    }
                });
                scratch.recycle(tile);
            }
        }
        out
    }

    /// One window `(x0, y0, tw, th)`: `tw`×`th` pixels whose top-left is (x0, y0) in the coordinates of the
    /// `size` image transformed by `t` (pixels outside it repeat the nearest edge pixel).
    /// Returns 3 × th × tw encoded colour, in a map the caller gives back to `scratch`.
    fn run_tile(
        &self,
        source: PlaneSource,
        size: (usize, usize),
        t: Dihedral,
        (x0, y0, tw, th): (i64, i64, usize, usize),
        scratch: &mut Scratch,
    ) -> Map {
        let (ow, oh) = size;
        let (w, h) = t.size(ow, oh);
        let src = |x: usize, y: usize| {
            let sx = (x0 + x as i64).clamp(0, w as i64 - 1) as usize;
            let sy = (y0 + y as i64).clamp(0, h as i64 - 1) as usize;
            t.source(sx, sy, ow, oh)
        };
        // Where each window pixel comes from, found once for all planes.
        let mut index = vec![0usize; tw * th];
        index.par_chunks_mut(tw).enumerate().for_each(|(y, row)| {
            for (x, i) in row.iter_mut().enumerate() {
                *i = src(x, y);
            }
        });
        // The window's input planes (C × th × tw), which both paths read.
        let c = self.config.input_channels;
        let mut x = scratch.map(tw, th, c);
        x.data.par_chunks_mut(tw).enumerate().for_each(|(row, dst)| {
            let (plane, y) = (row / th, row % th);
            source.fill(plane, &index[y * tw..][..tw], w * h, dst);
        });
        if self.use_burn {
            let input = Tensor::<4>::from_data(TensorData::new(x.data, [1, c, th, tw]), &self.device);
            let y = self.net.forward(input); // [1, 3, th, tw]
            let data = y.into_data().try_into_vec::<f32>().expect("the network outputs f32");
            return Map { w: tw, h: th, c: 3, data };
        }
        let y = self.fast.forward(&x, scratch);
        scratch.recycle(x);
        y
    }
}
