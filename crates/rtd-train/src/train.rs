//! `rtd train`: Adam on random crops with a warm-up + cosine learning-rate schedule, the losses
//! of [`crate::loss`], validation (PSNR, SSIM, relMSE against the noisy input) on held-out
//! scenes every epoch, and resumable checkpoints.

use std::path::{Path, PathBuf};
use std::time::Instant;

use burn::module::Module;
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::store::ModuleRecord;
use burn::tensor::{Device, Tensor, TensorData};
use rtd_denoise::{Denoiser, DenoiserConfig, DenoiserNet};
use rtd_image::metrics;

use crate::data::{load_views, Batch, CropSampler, View};
use crate::dataset::Manifest;
use crate::loss::{display_loss, training_loss};
use crate::run_state::RunFiles;
pub use crate::run_state::{EpochRecord, TrainState, ValidationScores};
use crate::{Progress, TrainError, TrainOptions};

/// What the step loop advances: the network, its optimiser and the run's state.
struct Run {
    net: DenoiserNet,
    optim: ModuleOptimizer,
    state: TrainState,
}

fn save_record(path: &Path, bytes: &[u8]) -> Result<(), TrainError> {
    Ok(rtd_image::write_bytes_atomic(path, bytes)?)
}

/// Mean scores of `denoiser` on the validation `views` at `spp`, beside the noisy input's.
pub fn validation_scores(denoiser: &Denoiser, views: &[View], spp: u32) -> Result<ValidationScores, TrainError> {
    let mut sums = [[0.0f64; 3]; 2];
    for v in views {
        let input = v.input(spp)?;
        let out = denoiser.denoise(&input)?;
        for (k, img) in [&out, input.color].into_iter().enumerate() {
            let m = metrics::metrics(img, &v.reference, 0);
            sums[k][0] += m.psnr;
            sums[k][1] += m.ssim;
            sums[k][2] += m.relmse;
        }
    }
    let n = views.len().max(1) as f64;
    let [denoised, noisy] = sums.map(|s| s.map(|x| x / n));
    Ok(ValidationScores {
        psnr: denoised[0],
        ssim: denoised[1],
        relmse: denoised[2],
        noisy_psnr: noisy[0],
        noisy_ssim: noisy[1],
        noisy_relmse: noisy[2],
    })
}

/// A copy of the network on the plain (non-autodiff) CPU device, for inference.
fn inference_copy(net: &DenoiserNet, config: &DenoiserConfig) -> Result<Denoiser, TrainError> {
    let device = Device::flex();
    let inference = config.init(&device).load_record(net.clone().into_record());
    Ok(Denoiser::from_net(inference, config.clone(), device, "training"))
}

/// Random weights, or those of `options.init` after checking that its config describes the
/// network being trained.
fn initial_net(options: &TrainOptions, device: &Device) -> Result<DenoiserNet, TrainError> {
    let Some(path) = &options.init else {
        return Ok(options.config.init_seeded(device, options.seed));
    };
    let cfg_path = path.with_extension("json");
    let text = std::fs::read_to_string(&cfg_path).map_err(|e| TrainError::io(&cfg_path, e))?;
    let config = DenoiserConfig::from_json(&text)
        .map_err(|e| TrainError::msg(&cfg_path, format!("not a usable model config: {e}")))?;
    // Demodulation and the exposure key change what the input planes mean, not the weights'
    // shapes, so a model without them may seed one with them; a model reading fewer input
    // planes seeds one reading more, whose stem starts with zero weights for the new ones.
    let narrower = config.input_channels < options.config.input_channels;
    if config.input_channels > options.config.input_channels {
        return Err(TrainError::msg(&cfg_path, "reads more input planes than the network being trained"));
    }
    // A direct-prediction model seeds a kernel-predicting one: its heads, of the run's kernel
    // size, start random.
    let adds_kernels = options.config.predicts_kernels() && !config.predicts_kernels();
    // The blend's upsampling has no weights either.
    let config = config
        .with_demodulate(options.config.demodulate)
        .with_exposure_key(options.config.exposure_key)
        .with_bilinear_blend(options.config.bilinear_blend);
    let target = config.clone().with_input_channels(options.config.input_channels);
    let target = if adds_kernels {
        target.with_kernel_output(options.config.kernel_output).with_kernel_size(options.config.kernel_size)
    } else {
        target
    };
    if target != options.config {
        return Err(TrainError::msg(&cfg_path, "describes another network than the one being trained"));
    }
    let record = load_fenced(path, || ModuleRecord::load(path))?;
    let net = config.init(device).try_load_record(record).map_err(|e| TrainError::msg(path, e.to_string()))?;
    let net = if narrower { net.widen_input(options.config.input_channels) } else { net };
    Ok(if adds_kernels { net.with_kernel_output(&options.config, device, options.seed) } else { net })
}

/// Trains (or, with `resume`, continues training) on the dataset in `data` (and those of
/// [`TrainOptions::more_data`], each checked as `data` is), writing
/// checkpoints, `state.json` and `curves.png` after every epoch (the curves again when it
/// stops), and finally `model.bpk` + `model.json` into `out`. The options
/// are checked first ([`TrainOptions::validate`], and
/// [`TrainOptions::validate_validation_data`] when they name a validation dataset), before
/// `out` is created.
pub fn train(
    data: &Path,
    out: &Path,
    options: &TrainOptions,
    resume: bool,
    progress: &dyn Progress,
) -> Result<TrainState, TrainError> {
    for dir in training_sets(data, options) {
        options.validate(dir, &Manifest::load(dir)?)?;
    }
    if let Some(dir) = &options.validation_data {
        options.validate_validation_data(dir, &Manifest::load(dir)?)?;
    }
    rtd_image::create_dir_durably(out).map_err(|e| TrainError::io(out, e))?;
    let files = RunFiles::new(out);
    let device = Device::flex().autodiff();
    let run = start_or_resume(&files, options, resume, &device)?;
    let (sampler, val_views) = load_data(data, options)?;
    let run = run_steps(run, &sampler, &val_views, &files, options, &device, progress)?;
    // The last epoch's curves are on disk already unless steps followed it (a stop mid-epoch).
    if run.state.history.last().map(|h| h.step) != Some(run.state.step) {
        crate::plot::write_training_curves(&files.curves(), &run.state)?;
    }
    if run.state.step >= options.steps {
        save_model(out, &run.net, &options.config)?;
    }
    Ok(run.state)
}

/// A fresh run (initial weights, a new optimiser, no history), or with `resume` the one whose
/// checkpoint is in `files`, which must have been started with the same options.
fn start_or_resume(files: &RunFiles, options: &TrainOptions, resume: bool, device: &Device) -> Result<Run, TrainError> {
    if !files.state.exists() {
        let state = TrainState { options: options.clone(), step: 0, history: vec![], losses: vec![] };
        return Ok(Run { net: initial_net(options, device)?, optim: AdamConfig::new().init(), state });
    }
    if !resume {
        return Err(TrainError::msg(
            &files.state,
            "a training run is already here; pass --resume to continue it or choose a new directory",
        ));
    }
    let text = std::fs::read_to_string(&files.state).map_err(|e| TrainError::io(&files.state, e))?;
    if let Some(why) = removed_option(&text) {
        return Err(TrainError::msg(&files.state, why));
    }
    let state: TrainState = serde_json::from_str(&text).map_err(|e| TrainError::msg(&files.state, e.to_string()))?;
    if state.options != *options {
        let differing = differing_options(&state.options, options).join(", ");
        let message = format!("was written with other training options (they differ in: {differing})");
        return Err(TrainError::msg(&files.state, message));
    }
    let (weights, optimizer) = (files.weights(state.step), files.optimizer(state.step));
    let record = load_fenced(&weights, || ModuleRecord::load(&weights))?;
    let net =
        options.config.init(device).try_load_record(record).map_err(|e| TrainError::msg(&weights, e.to_string()))?;
    let optim_record = load_fenced(&optimizer, || burn::optim::OptimizerRecord::load(&optimizer))?;
    let optim = AdamConfig::new().init().load_record(optim_record);
    // A run killed between naming a checkpoint and removing the older ones left those behind.
    files.remove_all_but(state.step);
    Ok(Run { net, optim, state })
}

/// The names of the options (as `state.json` writes them) in which `a` and `b` differ.
fn differing_options(a: &TrainOptions, b: &TrainOptions) -> Vec<String> {
    let (a, b) = (serde_json::to_value(a).unwrap_or_default(), serde_json::to_value(b).unwrap_or_default());
    let (Some(a), Some(b)) = (a.as_object(), b.as_object()) else { return vec![] };
    a.keys().chain(b.keys().filter(|k| !a.contains_key(*k))).filter(|k| a.get(*k) != b.get(*k)).cloned().collect()
}

/// A record read from `path` by burn's reader, fenced as every parser of a file is (a damaged
/// checkpoint must give an error naming it, not a panic).
fn load_fenced<T, E: std::fmt::Display>(path: &Path, load: impl FnOnce() -> Result<T, E>) -> Result<T, TrainError> {
    rtd_image::contain_panic(load)
        .map_err(|e| TrainError::msg(path, e))?
        .map_err(|e| TrainError::msg(path, e.to_string()))
}

/// Why a `state.json` cannot be resumed by this rtd, if it was written by an older one with a
/// training option since removed (`--gradient-loss`, `--grow`, or a `--no-depth` network):
/// reading it as if the option were off would continue a different run.
fn removed_option(state_json: &str) -> Option<String> {
    let value: serde_json::Value = serde_json::from_str(state_json).ok()?;
    let options = value.get("options")?;
    let set = |field: &str| options.get(field).is_some_and(|v| !v.is_null() && v.as_f64() != Some(0.0));
    for (field, flag) in [("gradient_loss", "--gradient-loss"), ("grow", "--grow")] {
        if set(field) {
            return Some(format!("was written with `rtd train {flag}`, which this rtd no longer supports"));
        }
    }
    let config = options.get("config")?.to_string();
    DenoiserConfig::from_json(&config).err().map(|e| format!("its network was {e}"))
}

/// The datasets whose training views are trained on: `data`, then [`TrainOptions::more_data`].
fn training_sets<'a>(data: &'a Path, options: &'a TrainOptions) -> impl Iterator<Item = &'a Path> {
    std::iter::once(data).chain(options.more_data.iter().map(PathBuf::as_path))
}

/// The crop sampler over the training views of [`training_sets`], and the validation views.
fn load_data(data: &Path, options: &TrainOptions) -> Result<(CropSampler, Vec<View>), TrainError> {
    let mut train_views = vec![];
    for dir in training_sets(data, options) {
        train_views.extend(load_views(dir, false)?);
    }
    let val_views = load_views(options.validation_data.as_deref().unwrap_or(data), true)?;
    let sampler =
        CropSampler::new(&train_views, options.crop, options.config.encoding(), options.spp_levels.as_deref())?
            .drop_probability(options.guide_drop)
            .variance_drop_probability(options.variance_drop)
            .colour_only_probability(options.colour_only)
            .albedo_guide_probability(options.albedo_guide);
    Ok((sampler, val_views))
}

/// Runs optimiser steps from `run.state.step` until `options.steps` or until `progress` is
/// cancelled, validating on `val_views` and checkpointing into `files` after every epoch.
fn run_steps(
    mut run: Run,
    sampler: &CropSampler,
    val_views: &[View],
    files: &RunFiles,
    options: &TrainOptions,
    device: &Device,
    progress: &dyn Progress,
) -> Result<Run, TrainError> {
    progress.start(options.steps, "train");
    progress.inc(run.state.step);
    let prior_wall = run.state.history.last().map(|h| h.wall_s).unwrap_or(0.0);
    let session = Instant::now();
    let mut epoch_start = Instant::now();
    let mut epoch_losses = vec![];
    while run.state.step < options.steps {
        if progress.cancelled() {
            break;
        }
        let batch = sampler.batch(options.seed, run.state.step, options.batch);
        let (loss, grads) = loss_and_gradients(&run.net, batch, options, device);
        run.net = run.optim.step(options.learning_rate_at(run.state.step), run.net, grads);
        run.state.losses.push(loss);
        epoch_losses.push(loss as f64);
        run.state.step += 1;
        progress.inc(1);
        if run.state.step.is_multiple_of(options.epoch_steps) || run.state.step == options.steps {
            let crops_per_s = (epoch_losses.len() * options.batch) as f64 / epoch_start.elapsed().as_secs_f64();
            let record = EpochRecord {
                step: run.state.step,
                train_loss: epoch_losses.iter().sum::<f64>() / epoch_losses.len().max(1) as f64,
                validation: epoch_validation(&run.net, &options.config, val_views, options.validation_spp)?,
                crops_per_s,
                wall_s: prior_wall + session.elapsed().as_secs_f64(),
            };
            progress.note(&epoch_line(&record));
            run.state.history.push(record);
            checkpoint(files, &run.net, &run.optim, &run.state)?;
            // The curves so far, so a long run can be watched (and one killed keeps them). The
            // checkpoint is safe, so a curve that cannot be written is reported, not fatal.
            if let Err(e) = crate::plot::write_training_curves(&files.curves(), &run.state) {
                progress.note(&format!("warning: {e}"));
            }
            epoch_losses.clear();
            epoch_start = Instant::now();
        }
    }
    Ok(run)
}

/// The loss of `net` on `batch` (of `options.batch` crops of side `options.crop`) and its
/// gradients: [`training_loss`], plus `options.display_loss` × [`display_loss`] when that
/// weight is not 0.
fn loss_and_gradients(
    net: &DenoiserNet,
    batch: Batch,
    options: &TrainOptions,
    device: &Device,
) -> (f32, GradientsParams) {
    let (b, s) = (options.batch, options.crop);
    let c = options.config.input_channels;
    let x = Tensor::<4>::from_data(TensorData::new(batch.inputs, [b, c, s, s]), device);
    let y = Tensor::<4>::from_data(TensorData::new(batch.targets, [b, 3, s, s]), device);
    let out = net.forward(x);
    let mut loss = training_loss(out.clone(), y.clone());
    if options.display_loss > 0.0 {
        let scale = Tensor::<4>::from_data(TensorData::new(batch.scales, [b, 3, s, s]), device);
        loss = loss + display_loss(out, y, scale).mul_scalar(options.display_loss);
    }
    let value = loss.clone().into_data().try_into_vec::<f32>().map(|v| v[0]).unwrap_or(f32::NAN);
    (value, GradientsParams::from_grads(loss.backward(), net))
}

/// The scores of `net` on the validation `views` at `spp`, or `None` when there are none.
fn epoch_validation(
    net: &DenoiserNet,
    config: &DenoiserConfig,
    views: &[View],
    spp: u32,
) -> Result<Option<ValidationScores>, TrainError> {
    if views.is_empty() {
        return Ok(None);
    }
    Ok(Some(validation_scores(&inference_copy(net, config)?, views, spp)?))
}

/// The progress line of a finished epoch.
fn epoch_line(r: &EpochRecord) -> String {
    let validation = match &r.validation {
        Some(v) => format!(
            "val PSNR {:.2} dB (noisy {:.2})  SSIM {:.3} ({:.3})  relMSE {:.4} ({:.4})",
            v.psnr, v.noisy_psnr, v.ssim, v.noisy_ssim, v.relmse, v.noisy_relmse
        ),
        None => "no validation views".to_string(),
    };
    format!("step {:>6}  loss {:.4}  {validation}  {:.1} crops/s", r.step, r.train_loss, r.crops_per_s)
}

/// Writes the checkpoint after `state.step` steps (weights and optimiser state, each
/// atomically, into their own folder), then `state.json` naming it, then removes the older
/// checkpoints: `state.json` always names a whole checkpoint of its own step.
fn checkpoint(
    files: &RunFiles,
    net: &DenoiserNet,
    optim: &ModuleOptimizer,
    state: &TrainState,
) -> Result<(), TrainError> {
    let dir = files.checkpoint(state.step);
    // Durably: `state.json` will name this folder, so its entry must reach the disk first.
    rtd_image::create_dir_durably(&dir).map_err(|e| TrainError::io(&dir, e))?;
    let (weights_path, optimizer_path) = (dir.join("weights.bpk"), dir.join("optimizer.bpk"));
    let weights = net.clone().into_record().into_bytes().map_err(|e| TrainError::msg(&weights_path, e.to_string()))?;
    save_record(&weights_path, &weights)?;
    // burn lays the optimiser's tensors out in its hash map's order, which changes from run to
    // run; read back, they come in name order, so a second encoding is the same bytes every run.
    let opt_err = |e: burn::store::RecordError| TrainError::msg(&optimizer_path, e.to_string());
    let opt = burn::optim::OptimizerRecord::from_bytes(optim.to_record().into_bytes().map_err(opt_err)?)
        .and_then(|r| r.into_bytes())
        .map_err(opt_err)?;
    save_record(&optimizer_path, &opt)?;
    let text = serde_json::to_vec(state).map_err(|e| TrainError::msg(&files.state, e.to_string()))?;
    save_record(&files.state, &text)?;
    files.remove_all_but(state.step);
    Ok(())
}

/// Writes the trained network as `model.bpk` (weights) + `model.json` (`config`) into `out`.
fn save_model(out: &Path, net: &DenoiserNet, config: &DenoiserConfig) -> Result<(), TrainError> {
    let weights = out.join("model.bpk");
    let bytes = net.valid().into_record().into_bytes().map_err(|e| TrainError::msg(&weights, e.to_string()))?;
    save_record(&weights, &bytes)?;
    let cfg = serde_json::to_vec_pretty(config).map_err(|e| TrainError::msg(out, e.to_string()))?;
    save_record(&out.join("model.json"), &cfg)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `state.json` files written before `validation` was an object keep their flat scores,
    /// so older runs resume; a noisy PSNR of 0 dB there meant no validation views.
    #[test]
    fn epoch_records_of_older_runs_still_read() {
        let old = r#"{"step":200,"train_loss":0.05,"psnr":30.5,"ssim":0.9,"relmse":0.01,"noisy_psnr":24.0,
            "noisy_ssim":0.5,"noisy_relmse":0.2,"crops_per_s":15.0,"wall_s":60.0}"#;
        let r: EpochRecord = serde_json::from_str(old).unwrap();
        let scores = ValidationScores {
            psnr: 30.5,
            ssim: 0.9,
            relmse: 0.01,
            noisy_psnr: 24.0,
            noisy_ssim: 0.5,
            noisy_relmse: 0.2,
        };
        assert_eq!(r.validation, Some(scores));
        assert_eq!((r.step, r.train_loss, r.crops_per_s, r.wall_s), (200, 0.05, 15.0, 60.0));
        let unvalidated = r#"{"step":20,"train_loss":0.1,"psnr":0.0,"ssim":0.0,"relmse":0.0,"noisy_psnr":0.0,
            "noisy_ssim":0.0,"noisy_relmse":0.0,"crops_per_s":1.0,"wall_s":1.0}"#;
        assert_eq!(serde_json::from_str::<EpochRecord>(unvalidated).unwrap().validation, None);
        // Records written now nest the scores (or write null), and read back as they were.
        let unscored = EpochRecord { validation: None, ..r.clone() };
        let (text, unscored_text) = (serde_json::to_string(&r).unwrap(), serde_json::to_string(&unscored).unwrap());
        assert!(text.contains(r#""validation":{"psnr":30.5,"#), "{text}");
        assert!(unscored_text.contains(r#""validation":null"#) && !unscored_text.contains("psnr"), "{unscored_text}");
        assert_eq!(serde_json::from_str::<EpochRecord>(&text).unwrap(), r);
        assert_eq!(serde_json::from_str::<EpochRecord>(&unscored_text).unwrap(), unscored);
    }

    /// A whole `state.json` as rtd wrote it before the architecture clean-up, with the fields
    /// of the removed options at their "off" values: it reads, equals today's defaults, and
    /// resumes; with a removed option in use it is refused.
    #[test]
    fn older_run_states_resume_unless_they_used_a_removed_option() {
        let state = |gradient_loss: &str, grow: &str, depth: &str| {
            format!(
                r#"{{"options":{{"config":{{"channels":[24,48,64],"level_blocks":null,"demodulate":null,
                "depth":{depth},"exposure_key":null,"bottleneck_blocks":2,"prong":5,"input_channels":16}},
                "seed":1,"steps":3000,"batch":8,"crop":64,"learning_rate":0.002,"epoch_steps":200,
                "validation_spp":8,"init":null,"gradient_loss":{gradient_loss},"display_loss":0.0,"grow":{grow},
                "spp_levels":null,"guide_drop":0.3}},"step":200,"history":[{{"step":200,"train_loss":0.05,
                "psnr":30.5,"ssim":0.9,"relmse":0.01,"noisy_psnr":24.0,"noisy_ssim":0.5,"noisy_relmse":0.2,
                "crops_per_s":15.0,"wall_s":60.0}}],"losses":[0.05]}}"#
            )
        };
        let old = state("0.0", "null", "null");
        let parsed: TrainState = serde_json::from_str(&old).unwrap();
        // Made before the variance planes: 16 input planes, and no variance to show; and before
        // the colour-only crops, so none of those.
        let before_variance = TrainOptions::default()
            .config(DenoiserConfig::unet().with_input_channels(rtd_denoise::planes::LEGACY_INPUT_CHANNELS))
            .variance_drop(1.0)
            .colour_only(0.0);
        assert_eq!(parsed.options, before_variance);
        assert_eq!(parsed.history[0].validation.map(|v| v.noisy_psnr), Some(24.0));
        assert_eq!(removed_option(&old), None);
        let e = removed_option(&state("0.5", "null", "null")).unwrap();
        assert!(e.contains("--gradient-loss"), "{e}");
        let e = removed_option(&state("0.0", r#"{"channels":64,"blocks":2}"#, "null")).unwrap();
        assert!(e.contains("--grow"), "{e}");
        let e = removed_option(&state("0.0", "null", "false")).unwrap();
        assert!(e.contains("--no-depth"), "{e}");
        // A state written now has none of those fields.
        let now = TrainState { options: TrainOptions::default(), step: 0, history: vec![], losses: vec![] };
        assert_eq!(removed_option(&serde_json::to_string(&now).unwrap()), None);
    }
}
