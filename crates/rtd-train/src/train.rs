//! `rtd train`: Adam on random crops with a warm-up + cosine learning-rate schedule, L1 loss on
//! log-encoded HDR colour (optionally plus L1 on its image gradients and a squared error on the
//! display transform the PSNR measures), validation (PSNR, SSIM, relMSE against the noisy input) on held-out
//! scenes every epoch, and resumable checkpoints.

use std::path::{Path, PathBuf};
use std::time::Instant;

use burn::module::Module;
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::store::ModuleRecord;
use burn::tensor::{Device, Tensor, TensorData};
use rtd_denoise::{grow, Denoiser, DenoiserConfig, DenoiserNet, INPUT_CHANNELS};
use rtd_image::metrics;
use serde::{Deserialize, Serialize};

use crate::data::{load_views, CropSampler, View, DROP_PROBABILITY};
use crate::dataset::Manifest;
use crate::{Progress, TrainError};

/// Training options, builder style.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct TrainOptions {
    /// The network to train.
    pub config: DenoiserConfig,
    /// Seed for weights and batches.
    pub seed: u64,
    /// Optimiser steps in all.
    pub steps: u64,
    /// Crops per batch.
    pub batch: usize,
    /// Crop side in pixels.
    pub crop: usize,
    /// Peak learning rate.
    pub learning_rate: f64,
    /// Steps per epoch (validation and checkpoint after each).
    pub epoch_steps: u64,
    /// Validation sample count.
    pub validation_spp: u32,
    /// Start from these weights (a `model.bpk` whose `.json` config equals `config`) instead
    /// of random ones: fine-tuning. The optimiser and schedule start afresh.
    #[serde(default)]
    pub init: Option<PathBuf>,
    /// Weight of the gradient term of [`training_loss`] (0: plain L1).
    #[serde(default)]
    pub gradient_loss: f32,
    /// Weight of [`display_loss`], the squared error on the display transform the PSNR is
    /// measured on (0: off).
    #[serde(default)]
    pub display_loss: f32,
    /// Grow the `init` network by a coarser level before training (then `config` is the grown
    /// config; see [`rtd_denoise::grow`]).
    #[serde(default)]
    pub grow: Option<GrowLevel>,
    /// Train only on the noisy renders at these sample counts (`None`: every stored count).
    #[serde(default)]
    pub spp_levels: Option<Vec<u32>>,
    /// Probability that a crop loses its albedo+normal layers, and (independently) its AO+depth
    /// layers, so the model also serves inputs with the guide RGB alone.
    #[serde(default = "default_guide_drop")]
    pub guide_drop: f32,
}

fn default_guide_drop() -> f32 {
    DROP_PROBABILITY
}

/// A coarser level to add to a trained network: its channels and bottleneck blocks.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct GrowLevel {
    /// Channels of the new level.
    pub channels: usize,
    /// Inception blocks at the new level (the new bottleneck).
    pub blocks: usize,
}

impl GrowLevel {
    /// `config` grown by this level ([`grow::grown_config`]).
    pub fn grown(&self, config: &DenoiserConfig) -> DenoiserConfig {
        grow::grown_config(config, self.channels, self.blocks)
    }
}

impl Default for TrainOptions {
    fn default() -> Self {
        TrainOptions {
            config: DenoiserConfig::unet(),
            seed: 1,
            steps: 3000,
            batch: 8,
            crop: 64,
            learning_rate: 2e-3,
            epoch_steps: 200,
            validation_spp: 8,
            init: None,
            gradient_loss: 0.0,
            display_loss: 0.0,
            grow: None,
            spp_levels: None,
            guide_drop: DROP_PROBABILITY,
        }
    }
}

impl TrainOptions {
    /// Sets the step count.
    pub fn steps(mut self, n: u64) -> Self {
        self.steps = n;
        self
    }
    /// Sets the seed.
    pub fn seed(mut self, s: u64) -> Self {
        self.seed = s;
        self
    }
    /// Sets the network config.
    pub fn config(mut self, c: DenoiserConfig) -> Self {
        self.config = c;
        self
    }
    /// Sets batch size and crop side.
    pub fn batch(mut self, batch: usize, crop: usize) -> Self {
        self.batch = batch;
        self.crop = crop;
        self
    }
    /// Sets the peak learning rate.
    pub fn learning_rate(mut self, lr: f64) -> Self {
        self.learning_rate = lr;
        self
    }
    /// Starts from a trained model's weights (fine-tuning).
    pub fn init(mut self, model: Option<PathBuf>) -> Self {
        self.init = model;
        self
    }
    /// Grows the `init` network by a coarser level before training; `config` must then be
    /// the grown config ([`rtd_denoise::grow::grown_config`]).
    pub fn grow(mut self, level: Option<GrowLevel>) -> Self {
        self.grow = level;
        self
    }
    /// Sets the weight of the gradient term of the loss (see [`training_loss`]).
    pub fn gradient_loss(mut self, w: f32) -> Self {
        self.gradient_loss = w.max(0.0);
        self
    }
    /// Sets the weight of [`display_loss`] in the loss (0: off).
    pub fn display_loss(mut self, w: f32) -> Self {
        self.display_loss = w.max(0.0);
        self
    }
    /// Trains only on the noisy renders at these sample counts (`None`: all of them).
    pub fn spp_levels(mut self, levels: Option<Vec<u32>>) -> Self {
        self.spp_levels = levels;
        self
    }
    /// Sets the probability that a crop loses each optional pair of guide layers (clamped to
    /// [0, 1]).
    pub fn guide_drop(mut self, p: f32) -> Self {
        self.guide_drop = p.clamp(0.0, 1.0);
        self
    }
    /// Sets steps per epoch.
    pub fn epoch_steps(mut self, n: u64) -> Self {
        self.epoch_steps = n;
        self
    }

    /// Learning rate at `step`: linear warm-up over 5% of the steps, then cosine decay to 1%.
    pub fn learning_rate_at(&self, step: u64) -> f64 {
        let warm = (self.steps / 20).max(1);
        if step < warm {
            return self.learning_rate * (step + 1) as f64 / warm as f64;
        }
        let t = (step - warm) as f64 / (self.steps - warm).max(1) as f64;
        self.learning_rate * (0.01 + 0.99 * 0.5 * (1.0 + (std::f64::consts::PI * t).cos()))
    }
}

/// Validation numbers after one epoch (means over the validation views).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct EpochRecord {
    /// Steps done.
    pub step: u64,
    /// Mean training loss over the epoch.
    pub train_loss: f64,
    /// Denoised PSNR (dB).
    pub psnr: f64,
    /// Denoised SSIM.
    pub ssim: f64,
    /// Denoised relMSE.
    pub relmse: f64,
    /// Noisy-input PSNR, the baseline.
    pub noisy_psnr: f64,
    /// Noisy-input SSIM.
    pub noisy_ssim: f64,
    /// Noisy-input relMSE.
    pub noisy_relmse: f64,
    /// Training throughput over the epoch, crops per second.
    pub crops_per_s: f64,
    /// Wall seconds of training so far (all sessions).
    pub wall_s: f64,
}

impl EpochRecord {
    /// Whether the epoch was validated: a dataset without validation views records 0 dB for
    /// the noisy input too, which no real image scores.
    pub fn has_validation(&self) -> bool {
        self.noisy_psnr > 0.0
    }
}

/// The resumable training state (`state.json` beside the checkpoint).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TrainState {
    /// The options of the run.
    pub options: TrainOptions,
    /// Steps done.
    pub step: u64,
    /// One record per finished epoch.
    pub history: Vec<EpochRecord>,
    /// Per-step training losses.
    pub losses: Vec<f32>,
}

/// Files of a training run in `out`.
struct RunFiles {
    state: PathBuf,
    weights: PathBuf,
    optimizer: PathBuf,
}

impl RunFiles {
    fn new(out: &Path) -> Self {
        RunFiles {
            state: out.join("state.json"),
            weights: out.join("checkpoint.bpk"),
            optimizer: out.join("optimizer.bpk"),
        }
    }
}

fn save_record(path: &Path, bytes: &[u8]) -> Result<(), TrainError> {
    rtd_image::write_atomic(path, |w| {
        std::io::Write::write_all(w, bytes).map_err(|e| rtd_image::ImageError::io(path, e))
    })?;
    Ok(())
}

/// Mean metrics of `net` on the validation views at `spp`: (denoised, noisy).
pub fn validate(
    denoiser: &Denoiser,
    views: &[View],
    spp: u32,
) -> Result<(metrics::Metrics, metrics::Metrics), TrainError> {
    let mut sums = [[0.0f64; 3]; 2];
    for v in views {
        let input = v.input(spp);
        let out = denoiser.denoise(&input)?;
        for (k, img) in [&out, input.color].into_iter().enumerate() {
            let m = metrics::metrics(img, &v.reference, 0);
            sums[k][0] += m.psnr;
            sums[k][1] += m.ssim;
            sums[k][2] += m.relmse;
        }
    }
    let n = views.len().max(1) as f64;
    let mk = |s: [f64; 3]| metrics::Metrics {
        psnr: s[0] / n,
        ssim: s[1] / n,
        relmse: s[2] / n,
        smape: f64::NAN,
        snr_db: f64::NAN,
    };
    Ok((mk(sums[0]), mk(sums[1])))
}

/// The training loss of output and target batches `[B, 3, H, W]` of log-encoded colour: mean
/// |out − target|, plus `gradient_weight` × the mean |∂(out − target)| over horizontal and
/// vertical neighbour differences. The gradient term is zero only where the output's edges and
/// texture have the reference's position and contrast, so it penalises blurred edges more than
/// plain L1 does.
pub fn training_loss(out: Tensor<4>, target: Tensor<4>, gradient_weight: f32) -> Tensor<1> {
    let diff = out - target;
    let l1 = diff.clone().abs().mean();
    let [b, c, h, w] = diff.dims();
    if gradient_weight == 0.0 || h < 2 || w < 2 {
        return l1;
    }
    // Neighbour differences of the error along x and y.
    let dx = diff.clone().slice([0..b, 0..c, 0..h, 1..w]) - diff.clone().slice([0..b, 0..c, 0..h, 0..w - 1]);
    let dy = diff.clone().slice([0..b, 0..c, 1..h, 0..w]) - diff.slice([0..b, 0..c, 0..h - 1, 0..w]);
    l1 + (dx.abs().mean() + dy.abs().mean()).mul_scalar(gradient_weight)
}

/// Encoded colour that decodes beyond this is clipped by the display transform anyway; the
/// clamp keeps e^y finite for wild outputs.
const DISPLAY_MAX_ENCODED: f32 = 30.0;

/// The mean squared error of output and target batches `[B, 3, H, W]` of encoded colour on the
/// display transform that [`rtd_image::metrics::psnr`] compares: each is decoded to linear
/// radiance, (e^y − 1) × `scale` (demodulation factor ÷ exposure, per pixel), clamped to
/// [0, 1] and sRGB-encoded. Minimising it maximises the validation PSNR; pixels brighter than
/// 1 add nothing, so it is meant beside [`training_loss`], not instead of it.
pub fn display_loss(out: Tensor<4>, target: Tensor<4>, scale: Tensor<4>) -> Tensor<1> {
    let display = |y: Tensor<4>| {
        // Linear radiance in [0, 1].
        let x = y.clamp(0.0, DISPLAY_MAX_ENCODED).exp().sub_scalar(1.0) * scale.clone();
        let x = x.clamp(0.0, 1.0);
        // The sRGB transfer: 12.92 x up to 0.0031308, 1.055 x^(1/2.4) − 0.055 above (the power
        // taken of x ≥ 0.0031308 only, so its derivative stays finite).
        let dark = x.clone().lower_equal_elem(0.003_130_8);
        let curve = x.clone().clamp_min(0.003_130_8).powf_scalar(1.0 / 2.4).mul_scalar(1.055).sub_scalar(0.055);
        curve.mask_where(dark, x.mul_scalar(12.92))
    };
    let diff = display(out) - display(target);
    (diff.clone() * diff).mean()
}

/// A copy of the network on the plain (non-autodiff) CPU device, for inference.
fn inference_copy(net: &DenoiserNet, config: &DenoiserConfig) -> Result<Denoiser, TrainError> {
    let device = Device::flex();
    let inference = config.init(&device).load_record(net.clone().into_record());
    Ok(Denoiser::from_net(inference, config.clone(), device, "training"))
}

/// Random weights, or those of `options.init` after checking its config matches (grown by
/// `options.grow` if set).
fn initial_net(options: &TrainOptions, device: &Device) -> Result<DenoiserNet, TrainError> {
    let Some(path) = &options.init else {
        return Ok(options.config.init(device));
    };
    let cfg_path = path.with_extension("json");
    let text = std::fs::read_to_string(&cfg_path).map_err(|e| TrainError::io(&cfg_path, e))?;
    let config: DenoiserConfig =
        serde_json::from_str(&text).map_err(|e| TrainError::msg(&cfg_path, format!("not a model config: {e}")))?;
    // Demodulation, leaving depth out and the exposure key change what the input planes mean,
    // not the weights' shapes, so a model without them may seed one with them.
    let config = config
        .with_demodulate(options.config.demodulate)
        .with_depth(options.config.depth)
        .with_exposure_key(options.config.exposure_key);
    if options.grow.map_or(config.clone(), |g| g.grown(&config)) != options.config {
        return Err(TrainError::msg(&cfg_path, "describes another network than the one being trained"));
    }
    let record = ModuleRecord::load(path).map_err(|e| TrainError::msg(path, e.to_string()))?;
    let net = config.init(device).try_load_record(record).map_err(|e| TrainError::msg(path, e.to_string()))?;
    Ok(match options.grow {
        Some(g) => grow::add_level(net, &config, g.channels, g.blocks, device).0,
        None => net,
    })
}

/// Trains (or, with `resume`, continues training) on the dataset in `data`, writing
/// checkpoints, `state.json`, and finally `model.bpk` + `model.json` into `out`.
pub fn train(
    data: &Path,
    out: &Path,
    options: &TrainOptions,
    resume: bool,
    progress: &dyn Progress,
) -> Result<TrainState, TrainError> {
    if let Some(levels) = &options.spp_levels {
        // Checked against the manifest before any view is loaded or any file written.
        let stored = Manifest::load(data)?.noisy_spp;
        let missing: Vec<u32> = levels.iter().copied().filter(|l| !stored.contains(l)).collect();
        if !missing.is_empty() {
            return Err(TrainError::msg(
                &data.join("manifest.json"),
                format!("has no noisy renders at the sample counts {missing:?} (it stores {stored:?})"),
            ));
        }
    }
    std::fs::create_dir_all(out).map_err(|e| TrainError::io(out, e))?;
    let files = RunFiles::new(out);
    let device = Device::flex().autodiff();
    device.seed(options.seed);
    let (mut net, mut optim, mut state) = if files.state.exists() {
        if !resume {
            return Err(TrainError::msg(
                &files.state,
                "a training run is already here; pass --resume to continue it or choose a new directory",
            ));
        }
        let text = std::fs::read_to_string(&files.state).map_err(|e| TrainError::io(&files.state, e))?;
        let state: TrainState =
            serde_json::from_str(&text).map_err(|e| TrainError::msg(&files.state, e.to_string()))?;
        if state.options != *options {
            return Err(TrainError::msg(&files.state, "was written with other training options"));
        }
        let record = ModuleRecord::load(&files.weights).map_err(|e| TrainError::msg(&files.weights, e.to_string()))?;
        let net = options
            .config
            .init(&device)
            .try_load_record(record)
            .map_err(|e| TrainError::msg(&files.weights, e.to_string()))?;
        let optim_record = burn::optim::OptimizerRecord::load(&files.optimizer)
            .map_err(|e| TrainError::msg(&files.optimizer, e.to_string()))?;
        let optim = AdamConfig::new().init().load_record(optim_record);
        (net, optim, state)
    } else {
        (
            initial_net(options, &device)?,
            AdamConfig::new().init(),
            TrainState { options: options.clone(), step: 0, history: vec![], losses: vec![] },
        )
    };
    let train_views = load_views(data, false)?;
    let val_views = load_views(data, true)?;
    if train_views.is_empty() {
        return Err(TrainError::msg(&data.join("manifest.json"), "has no training views"));
    }
    let sampler =
        CropSampler::new(&train_views, options.crop, options.config.encoding(), options.spp_levels.as_deref())?
            .drop_probability(options.guide_drop);
    progress.start(options.steps, "train");
    progress.inc(state.step);
    let mut epoch_start = Instant::now();
    let mut epoch_losses = vec![];
    let prior_wall = state.history.last().map(|h| h.wall_s).unwrap_or(0.0);
    let session = Instant::now();
    let (b, s) = (options.batch, options.crop);
    while state.step < options.steps {
        if progress.cancelled() {
            break;
        }
        let batch = sampler.batch(options.seed, state.step, b);
        let x = Tensor::<4>::from_data(TensorData::new(batch.inputs, [b, INPUT_CHANNELS, s, s]), &device);
        let y = Tensor::<4>::from_data(TensorData::new(batch.targets, [b, 3, s, s]), &device);
        let out = net.forward(x);
        let mut loss = training_loss(out.clone(), y.clone(), options.gradient_loss);
        if options.display_loss > 0.0 {
            let scale = Tensor::<4>::from_data(TensorData::new(batch.scales, [b, 3, s, s]), &device);
            loss = loss + display_loss(out, y, scale).mul_scalar(options.display_loss);
        }
        let loss_value = loss.clone().into_data().try_into_vec::<f32>().map(|v| v[0]).unwrap_or(f32::NAN);
        let grads = GradientsParams::from_grads(loss.backward(), &net);
        net = optim.step(options.learning_rate_at(state.step), net, grads);
        state.losses.push(loss_value);
        epoch_losses.push(loss_value as f64);
        state.step += 1;
        progress.inc(1);
        if state.step % options.epoch_steps == 0 || state.step == options.steps {
            let crops_per_s = (epoch_losses.len() * b) as f64 / epoch_start.elapsed().as_secs_f64();
            let (den, noisy) = validate(&inference_copy(&net, &options.config)?, &val_views, options.validation_spp)?;
            let rec = EpochRecord {
                step: state.step,
                train_loss: epoch_losses.iter().sum::<f64>() / epoch_losses.len().max(1) as f64,
                psnr: den.psnr,
                ssim: den.ssim,
                relmse: den.relmse,
                noisy_psnr: noisy.psnr,
                noisy_ssim: noisy.ssim,
                noisy_relmse: noisy.relmse,
                crops_per_s,
                wall_s: prior_wall + session.elapsed().as_secs_f64(),
            };
            progress.note(&format!(
                "step {:>6}  loss {:.4}  val PSNR {:.2} dB (noisy {:.2})  SSIM {:.3} ({:.3})  relMSE {:.4} ({:.4})  {:.1} crops/s",
                rec.step, rec.train_loss, rec.psnr, rec.noisy_psnr, rec.ssim, rec.noisy_ssim, rec.relmse, rec.noisy_relmse, rec.crops_per_s
            ));
            state.history.push(rec);
            checkpoint(&files, &net, &optim, &state)?;
            epoch_losses.clear();
            epoch_start = Instant::now();
        }
    }
    if state.step >= options.steps {
        let bytes = net
            .valid()
            .into_record()
            .into_bytes()
            .map_err(|e| TrainError::msg(&out.join("model.bpk"), e.to_string()))?;
        save_record(&out.join("model.bpk"), &bytes)?;
        let cfg = serde_json::to_vec_pretty(&options.config).map_err(|e| TrainError::msg(out, e.to_string()))?;
        save_record(&out.join("model.json"), &cfg)?;
    }
    Ok(state)
}

/// Writes weights, optimiser state and `state.json`, each atomically, state last.
fn checkpoint(
    files: &RunFiles,
    net: &DenoiserNet,
    optim: &ModuleOptimizer,
    state: &TrainState,
) -> Result<(), TrainError> {
    let weights = net.clone().into_record().into_bytes().map_err(|e| TrainError::msg(&files.weights, e.to_string()))?;
    save_record(&files.weights, &weights)?;
    let opt = optim.to_record().into_bytes().map_err(|e| TrainError::msg(&files.optimizer, e.to_string()))?;
    save_record(&files.optimizer, &opt)?;
    let text = serde_json::to_vec(state).map_err(|e| TrainError::msg(&files.state, e.to_string()))?;
    save_record(&files.state, &text)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three channels of two equal rows.
    fn image(row: &[f32]) -> Tensor<4> {
        let data: Vec<f32> = (0..6).flat_map(|_| row.iter().copied()).collect();
        Tensor::<4>::from_data(TensorData::new(data, [1, 3, 2, row.len()]), &Device::flex())
    }

    fn value(t: Tensor<1>) -> f32 {
        t.into_data().try_into_vec::<f32>().unwrap()[0]
    }

    #[test]
    fn gradient_loss_penalises_a_blurred_edge_and_not_an_offset() {
        // A step edge 0 → 1 across 4 pixels, a blurred copy, and a copy offset by a constant.
        let edge = image(&[0.0, 0.0, 1.0, 1.0]);
        let blurred = image(&[0.0, 0.25, 0.75, 1.0]);
        let offset = image(&[0.25, 0.25, 1.25, 1.25]);
        // Plain L1: 0.125 for the blurred copy, 0.25 for the offset one.
        let l1 = |a: &Tensor<4>, b: &Tensor<4>| value(training_loss(a.clone(), b.clone(), 0.0));
        assert!((l1(&blurred, &edge) - 0.125).abs() < 1e-6);
        assert!((l1(&offset, &edge) - 0.25).abs() < 1e-6);
        // The gradient term: the blur's error (0, 0.25, −0.25, 0) differs along x by
        // (0.25, −0.5, 0.25), mean 1/3; the offset's error is constant; the rows are equal, so
        // nothing along y.
        let g = |a: &Tensor<4>, b: &Tensor<4>| value(training_loss(a.clone(), b.clone(), 1.0)) - l1(a, b);
        assert!((g(&blurred, &edge) - 1.0 / 3.0).abs() < 1e-6, "{}", g(&blurred, &edge));
        assert!(g(&offset, &edge).abs() < 1e-6);
        assert_eq!(value(training_loss(edge.clone(), edge, 2.0)), 0.0);
    }

    #[test]
    fn display_loss_is_the_squared_error_psnr_measures_with_finite_gradients() {
        // Encoded values from black through the sRGB toe and mid-tones to far past white, with
        // per-pixel scales as demodulation and exposure make them.
        let n = 8;
        let out: Vec<f32> = (0..3 * n).map(|i| [0.0, 1e-4, 0.004, 0.3, 1.2, 2.5, 9.0, 80.0][i % n]).collect();
        let target: Vec<f32> = (0..3 * n).map(|i| [0.0, 0.002, 0.01, 0.1, 1.0, 3.0, 12.0, 0.5][i % n]).collect();
        let scale: Vec<f32> = (0..3 * n).map(|i| [0.05, 0.3, 1.0, 0.7][i % 4]).collect();
        // The same on the host, with the metric's own transfer.
        let display = |y: f32, s: f32| rtd_image::linear_to_srgb(y.min(DISPLAY_MAX_ENCODED).exp_m1() * s);
        let expected =
            (0..3 * n).map(|i| (display(out[i], scale[i]) - display(target[i], scale[i])).powi(2)).sum::<f32>()
                / (3 * n) as f32;
        assert!(expected > 1e-3, "the example compares unequal images");
        let device = Device::flex().autodiff();
        let tensor = |v: &[f32]| Tensor::<4>::from_data(TensorData::new(v.to_vec(), [1, 3, 1, n]), &device);
        let out_t = tensor(&out).require_grad();
        let loss = display_loss(out_t.clone(), tensor(&target), tensor(&scale));
        let got = loss.clone().into_data().try_into_vec::<f32>().unwrap()[0];
        assert!((got - expected).abs() < 1e-5 * expected.max(1.0), "{got} vs {expected}");
        // Gradients are finite everywhere (the black pixel and the 80 far past white included),
        // zero where the output is clipped to white, and push a too-dark output up.
        let grad = out_t.grad(&loss.backward()).unwrap().into_data().try_into_vec::<f32>().unwrap();
        assert!(grad.iter().all(|g| g.is_finite()), "{grad:?}");
        assert_eq!(grad[7], 0.0, "80 encoded decodes far past white: the clamp leaves no gradient");
        assert!(grad[2] < 0.0, "0.004 is darker than its 0.01 target: the loss falls as it rises");
        // Equal images: zero loss.
        assert_eq!(value(display_loss(tensor(&target), tensor(&target), tensor(&scale))), 0.0);
    }
}
