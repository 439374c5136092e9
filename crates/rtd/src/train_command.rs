//! `rtd datagen` and `rtd train`: thin wrappers over `rtd_train`.

use std::path::Path;

use rtd_denoise::DenoiserConfig;
use rtd_train::dataset::{generate_dataset, refresh_guides, DatasetOptions, Split};
use rtd_train::train::{EpochRecord, TrainState};
use rtd_train::TrainOptions;

use crate::exit::Interrupted;
use crate::progress::TaskBar;
use crate::train_args::{DatagenArgs, SplitArg, TrainArgs};
use rtd_image::Progress;

/// Runs `rtd datagen`.
pub fn datagen(args: &DatagenArgs) -> anyhow::Result<()> {
    if args.refresh_guides {
        let bar = TaskBar::new(args.quiet);
        let n = refresh_guides(&args.output, &bar)?;
        bar.finish();
        if bar.cancelled() {
            let kept = format!("{n} views refreshed; rerun the same command to refresh them all");
            return Err(Interrupted(kept).into());
        }
        eprintln!("{}: guide layers of {n} views re-rendered", args.output.display());
        return Ok(());
    }
    let options = DatasetOptions::default()
        .seed(args.seed)
        .scenes(args.scenes)
        .views_per_scene(args.views as usize)
        .size(args.size)
        .reference_spp(args.reference_spp)
        .split(match args.split {
            SplitArg::All => Split::All,
            SplitArg::Training => Split::Training,
            SplitArg::Validation => Split::Validation,
        });
    if let Some(url) = &args.database {
        return crate::service_command::datagen_on_queue(args, url, &options);
    }
    let bar = TaskBar::new(args.quiet);
    let manifest = generate_dataset(&args.output, &options, &bar)?;
    bar.finish();
    let secs: f64 = manifest.views.iter().map(|v| v.seconds).sum();
    let worst = manifest.views.iter().map(|v| v.reference_relmse).fold(0.0, f64::max);
    let mean = manifest.views.iter().map(|v| v.reference_relmse).sum::<f64>() / manifest.views.len().max(1) as f64;
    eprintln!(
        "{}: {} views ({} validation), {} rejected, {:.0} s of rendering; reference relMSE mean {:.2e}, worst {:.2e}",
        args.output.display(),
        manifest.views.len(),
        manifest.views.iter().filter(|v| v.validation).count(),
        manifest.rejected.len(),
        secs,
        mean,
        worst
    );
    if bar.cancelled() {
        return Err(Interrupted("finished views are kept; rerun the same command to resume".into()).into());
    }
    Ok(())
}

/// Runs `rtd train` and returns the final state: the options from `args` (`--quick` first makes
/// its tiny dataset and shrinks the run), the library's training (which writes the curves),
/// then a summary.
/// The library checks the options against the dataset before it writes anything.
pub fn train(args: &TrainArgs) -> anyhow::Result<TrainState> {
    crate::heap::keep_freed_blocks();
    let bar = TaskBar::new(args.quiet);
    let mut options = train_options(args)?;
    if args.quick {
        let schedule = &args.schedule;
        options = options.batch(4, 32).steps(schedule.steps.min(48)).epoch_steps(schedule.epoch_steps.min(16));
        // What needs no dataset is checked before the tiny one is made.
        options.validate_alone(&args.data)?;
        // A tiny dataset (one training and one validation scene at 32², 64-spp references).
        let data =
            DatasetOptions::default().scenes(2).views_per_scene(1).size(32).reference_spp(64).validation_every(2);
        generate_dataset(&args.data, &data, &bar)?;
    }
    let state = rtd_train::train::train(&args.data, &args.output, &options, args.resume, &bar)?;
    bar.finish();
    if state.step < options.steps {
        let kept = format!("at step {}: the checkpoint is kept; rerun with --resume to continue", state.step);
        return Err(Interrupted(kept).into());
    }
    if let Some(last) = state.history.last() {
        eprintln!("{}", summary(state.step, last, &args.output));
    }
    Ok(state)
}

/// The library's options for `args`: the network is `--init`'s (its config read from the model
/// file) or the shipped U-Net's shape with `--channels` and `--bottleneck-blocks` applied, with
/// `--demodulate` and `--exposure-key` applied.
fn train_options(args: &TrainArgs) -> anyhow::Result<TrainOptions> {
    let (schedule, model, loss) = (&args.schedule, &args.model, &args.loss);
    // A model made before the variance planes is widened to read them (its stem starts with
    // zero weights there), so every model trained now reads every plane this rtd provides.
    let config = match &model.init {
        Some(path) => {
            rtd_denoise::Denoiser::load(path)?.config().clone().with_input_channels(rtd_denoise::INPUT_CHANNELS)
        }
        None => {
            let mut config = DenoiserConfig::unet();
            if !model.channels.is_empty() {
                config.channels = model.channels.iter().map(|&c| c as usize).collect();
            }
            if let Some(blocks) = model.bottleneck_blocks {
                config.bottleneck_blocks = blocks as usize;
            }
            config
        }
    };
    let config = if model.demodulate { config.with_demodulate(Some(true)) } else { config };
    let config = if model.kernel_output { config.with_kernel_output(Some(true)) } else { config };
    let config = if model.bilinear_blend { config.with_bilinear_blend(Some(true)) } else { config };
    let config = match model.kernel_size {
        Some(k) => config.with_kernel_size(Some(k as usize)),
        None => config,
    };
    anyhow::ensure!(
        !config.blends_bilinearly() || config.predicts_kernels(),
        "--bilinear-blend: the network predicts colour directly, so it has no kernel levels to blend (add --kernel-output)"
    );
    let config = match model.exposure_key {
        Some(k) => config.with_exposure_key(Some(k)),
        None => config,
    };
    Ok(TrainOptions::default()
        .config(config)
        .learning_rate(schedule.lr)
        .init(model.init.clone())
        .display_loss(loss.display_loss)
        .spp_levels((!loss.spp_levels.is_empty()).then(|| loss.spp_levels.clone()))
        .guide_drop(loss.guide_drop)
        .variance_drop(loss.variance_drop)
        .colour_only(loss.colour_only)
        .albedo_guide(loss.albedo_guide)
        .validation_data(args.validation_data.clone())
        .more_data(args.more_data.clone())
        .seed(schedule.seed)
        .steps(schedule.steps)
        .batch(schedule.batch as usize, schedule.crop as usize)
        .epoch_steps(schedule.epoch_steps))
}

/// The line printed after a finished run of `steps` steps whose last epoch is `last`.
fn summary(steps: u64, last: &EpochRecord, output: &Path) -> String {
    let validation = match &last.validation {
        Some(v) => format!("validation PSNR {:.2} dB vs noisy {:.2} dB", v.psnr, v.noisy_psnr),
        None => "no validation views in the dataset".to_string(),
    };
    format!(
        "trained {steps} steps in {:.0} s ({:.1} crops/s): {validation}; model in {}",
        last.wall_s,
        last.crops_per_s,
        output.join("model.bpk").display()
    )
}
