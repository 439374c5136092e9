//! `rtd datagen` and `rtd train`: thin wrappers over `rtd_train`.

use rtd_denoise::DenoiserConfig;
use rtd_train::dataset::{generate_dataset, refresh_guides, DatasetOptions, Split};
use rtd_train::train::{GrowLevel, TrainOptions, TrainState};

use crate::args::{DatagenArgs, SplitArg, TrainArgs, VariantArg};
use crate::progress::TaskBar;

/// Runs `rtd datagen`.
pub fn datagen(args: &DatagenArgs) -> anyhow::Result<()> {
    if args.refresh_guides {
        let bar = TaskBar::new(args.quiet);
        let n = refresh_guides(&args.output, &bar)?;
        bar.finish();
        if bar_cancelled(&bar) {
            anyhow::bail!("interrupted after {n} views: rerun the same command to refresh them all");
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
    if bar_cancelled(&bar) {
        anyhow::bail!("interrupted: finished views are kept; rerun the same command to resume");
    }
    Ok(())
}

fn bar_cancelled(bar: &TaskBar) -> bool {
    rtd_image::Progress::cancelled(bar)
}

/// Runs `rtd train` and returns the final state.
pub fn train(args: &TrainArgs) -> anyhow::Result<TrainState> {
    let bar = TaskBar::new(args.quiet);
    let config = match (&args.init, args.variant) {
        (Some(model), _) => rtd_denoise::Denoiser::load(model)?.config().clone(),
        (None, VariantArg::Unet) => DenoiserConfig::unet(),
        (None, VariantArg::SingleScale) => DenoiserConfig::single_scale(),
    };
    let config = if args.demodulate { config.with_demodulate(Some(true)) } else { config };
    let config = if args.no_depth { config.with_depth(Some(false)) } else { config };
    let config = match args.exposure_key {
        Some(k) => config.with_exposure_key(Some(k)),
        None => config,
    };
    let grow = args.grow.map(|c| GrowLevel { channels: c as usize, blocks: args.grow_blocks as usize });
    let config = grow.map_or(config.clone(), |g| g.grown(&config));
    let mut options = TrainOptions::default()
        .config(config)
        .learning_rate(args.lr)
        .init(args.init.clone())
        .grow(grow)
        .gradient_loss(args.gradient_loss)
        .display_loss(args.display_loss)
        .spp_levels((!args.spp_levels.is_empty()).then(|| args.spp_levels.clone()))
        .guide_drop(args.guide_drop)
        .seed(args.seed)
        .steps(args.steps)
        .batch(args.batch as usize, args.crop as usize)
        .epoch_steps(args.epoch_steps);
    if args.quick {
        // A tiny dataset (one training and one validation scene at 32², 64-spp references).
        let data =
            DatasetOptions::default().scenes(2).views_per_scene(1).size(32).reference_spp(64).validation_every(2);
        generate_dataset(&args.data, &data, &bar)?;
        options = options.batch(4, 32).steps(args.steps.min(48)).epoch_steps(args.epoch_steps.min(16));
    }
    let crop = options.crop as u32;
    if crop % 4 != 0 {
        anyhow::bail!("--crop {crop} must be a multiple of 4");
    }
    let state = rtd_train::train::train(&args.data, &args.output, &options, args.resume, &bar)?;
    bar.finish();
    rtd_train::plot::write_training_curves(&args.output.join("curves.png"), &state)?;
    if state.step < options.steps {
        anyhow::bail!("interrupted at step {}: the checkpoint is kept; rerun with --resume to continue", state.step);
    }
    if let Some(last) = state.history.last() {
        let validation = match last.has_validation() {
            true => format!("validation PSNR {:.2} dB vs noisy {:.2} dB", last.psnr, last.noisy_psnr),
            false => "no validation views in the dataset".to_string(),
        };
        eprintln!(
            "trained {} steps in {:.0} s ({:.1} crops/s): {validation}; model in {}",
            state.step,
            last.wall_s,
            last.crops_per_s,
            args.output.join("model.bpk").display()
        );
    }
    Ok(state)
}
