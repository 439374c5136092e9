//! Tiled, threaded inference with a trained [`DenoiserNet`]: load a model (file or the one
//! compiled into the binary), encode the inputs, run overlapping tiles, decode.

use std::path::Path;

use burn::module::Module;
use burn::store::ModuleRecord;
use burn::tensor::{Bytes, Device, Tensor, TensorData};
use glam::Vec3;
use rtd_image::HdrImage;

use crate::encode::{auto_exposure, decode_color, encode_planes, DenoiseInput};
use crate::fast::{FastNet, Map};
use crate::model::{DenoiserConfig, DenoiserNet};
use crate::{DenoiseError, INPUT_CHANNELS};

/// The shipped model's config and weights, compiled into the binary.
const BUILTIN_CONFIG: &str = include_str!("../../../models/rtd-denoiser.json");
const BUILTIN_WEIGHTS: &[u8] = include_bytes!("../../../models/rtd-denoiser.bpk");

/// Largest accepted image side.
pub const MAX_SIDE: u32 = 16384;

/// A trained denoiser ready to run.
pub struct Denoiser {
    net: DenoiserNet,
    fast: FastNet,
    use_burn: bool,
    config: DenoiserConfig,
    device: Device,
    name: String,
    tile: usize,
}

impl Denoiser {
    /// Builds a denoiser from a config (JSON) and burnpack weights; `name` is shown in reports.
    pub fn from_bytes(config_json: &str, weights: Vec<u8>, name: &str) -> Result<Self, DenoiseError> {
        let config: DenoiserConfig = serde_json::from_str(config_json)
            .map_err(|e| DenoiseError::Model(format!("{name}: bad model config: {e}")))?;
        if config.input_channels != INPUT_CHANNELS {
            return Err(DenoiseError::Model(format!(
                "{name}: model expects {} input channels, this rtd provides {INPUT_CHANNELS}",
                config.input_channels
            )));
        }
        if config.channels.is_empty()
            || config.channels.len() > 5
            || config.channels.iter().any(|c| *c == 0 || *c > 512)
        {
            return Err(DenoiseError::Model(format!("{name}: implausible channel list {:?}", config.channels)));
        }
        let device = Device::flex();
        let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(weights))
            .map_err(|e| DenoiseError::Model(format!("{name}: corrupt weights: {e}")))?;
        let net = config
            .init(&device)
            .try_load_record(record)
            .map_err(|e| DenoiseError::Model(format!("{name}: weights do not match the config: {e}")))?;
        Ok(Self::from_net(net, config, device, name))
    }

    /// Loads `path` (burnpack weights) and its config `path` with extension `.json`.
    pub fn load(path: &Path) -> Result<Self, DenoiseError> {
        let weights = std::fs::read(path).map_err(|e| DenoiseError::Model(format!("{}: {e}", path.display())))?;
        let cfg_path = path.with_extension("json");
        let config = std::fs::read_to_string(&cfg_path).map_err(|e| {
            DenoiseError::Model(format!(
                "{}: cannot read the model's config {}: {e}",
                path.display(),
                cfg_path.display()
            ))
        })?;
        Self::from_bytes(&config, weights, &path.display().to_string())
    }

    /// The model shipped in `models/` and compiled into the binary.
    pub fn builtin() -> Result<Self, DenoiseError> {
        Self::from_bytes(BUILTIN_CONFIG, BUILTIN_WEIGHTS.to_vec(), "builtin:rtd-denoiser")
    }

    /// Wraps an already-built network (training's validation uses this).
    pub fn from_net(net: DenoiserNet, config: DenoiserConfig, device: Device, name: &str) -> Self {
        let fast = FastNet::from_net(&net);
        Denoiser { net, fast, use_burn: false, config, device, name: name.to_string(), tile: 512 }
    }

    /// Sets the tile size (rounded up to the network's alignment).
    pub fn tile(mut self, tile: usize) -> Self {
        let a = self.config.alignment();
        self.tile = tile.max(1).div_ceil(a) * a;
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

    /// The model's config.
    pub fn config(&self) -> &DenoiserConfig {
        &self.config
    }

    /// Tile overlap: the receptive radius rounded up to the alignment.
    pub fn margin(&self) -> usize {
        let a = self.config.alignment();
        self.config.receptive_radius().div_ceil(a) * a
    }

    /// Denoises one image.
    pub fn denoise(&self, input: &DenoiseInput) -> Result<HdrImage, DenoiseError> {
        let (w, h) = input.size()?;
        if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
            return Err(DenoiseError::Input(format!("image size {w}x{h} is outside 1..={MAX_SIDE} per side")));
        }
        let exposure = auto_exposure(input.color);
        let planes = encode_planes(input, exposure)?;
        let out = self.run_planes(&planes, w as usize, h as usize);
        let n = (w * h) as usize;
        let pixels = (0..n)
            .map(|i| {
                Vec3::new(
                    decode_color(out[i], exposure),
                    decode_color(out[n + i], exposure),
                    decode_color(out[2 * n + i], exposure),
                )
            })
            .collect();
        Ok(HdrImage::from_pixels(w, h, pixels))
    }

    /// Runs the network over encoded input planes (C × H × W), tile by tile, and returns the
    /// encoded output planes (3 × H × W). Pixels outside the image repeat the nearest edge pixel.
    pub fn run_planes(&self, planes: &[f32], w: usize, h: usize) -> Vec<f32> {
        let a = self.config.alignment();
        let m = self.margin();
        let (wp, hp) = (w.div_ceil(a) * a, h.div_ceil(a) * a);
        let mut out = vec![0.0f32; 3 * w * h];
        let mut ty = 0;
        while ty < hp {
            let th = self.tile.min(hp - ty);
            let mut tx = 0;
            while tx < wp {
                let tw = self.tile.min(wp - tx);
                let tile =
                    self.run_tile(planes, w, h, tx as i64 - m as i64, ty as i64 - m as i64, tw + 2 * m, th + 2 * m);
                // Keep the tile's interior.
                let (iw, ih) = (tw + 2 * m, th + 2 * m);
                for c in 0..3 {
                    for y in ty..(ty + th).min(h) {
                        for x in tx..(tx + tw).min(w) {
                            out[c * w * h + y * w + x] = tile[c * iw * ih + (y - ty + m) * iw + (x - tx + m)];
                        }
                    }
                }
                tx += tw;
            }
            ty += th;
        }
        out
    }

    /// One tile of `tw`×`th` pixels whose top-left is (x0, y0) in image coordinates.
    #[allow(clippy::too_many_arguments)]
    fn run_tile(&self, planes: &[f32], w: usize, h: usize, x0: i64, y0: i64, tw: usize, th: usize) -> Vec<f32> {
        let mut data = vec![0.0f32; INPUT_CHANNELS * tw * th];
        for c in 0..INPUT_CHANNELS {
            for y in 0..th {
                let sy = (y0 + y as i64).clamp(0, h as i64 - 1) as usize;
                for x in 0..tw {
                    let sx = (x0 + x as i64).clamp(0, w as i64 - 1) as usize;
                    data[c * tw * th + y * tw + x] = planes[c * w * h + sy * w + sx];
                }
            }
        }
        if self.use_burn {
            let input = Tensor::<4>::from_data(TensorData::new(data, [1, INPUT_CHANNELS, th, tw]), &self.device);
            let y = self.net.forward(input); // [1, 3, th, tw]
            return y.into_data().try_into_vec::<f32>().expect("the network outputs f32");
        }
        // Channel-major to HWC for the fast path, and back.
        let n = tw * th;
        let mut hwc = vec![0.0f32; n * INPUT_CHANNELS];
        for c in 0..INPUT_CHANNELS {
            for p in 0..n {
                hwc[p * INPUT_CHANNELS + c] = data[c * n + p];
            }
        }
        let y = self.fast.forward(&Map { w: tw, h: th, c: INPUT_CHANNELS, data: hwc });
        let mut out = vec![0.0f32; 3 * n];
        for p in 0..n {
            for c in 0..3 {
                out[c * n + p] = y.data[p * 3 + c];
            }
        }
        out
    }
}
