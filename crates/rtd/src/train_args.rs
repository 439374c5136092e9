//! `rtd datagen` and `rtd train` options.

use std::path::PathBuf;

use clap::{Args, ValueEnum};

/// `rtd datagen` options.
#[derive(Debug, Clone, Args)]
pub struct DatagenArgs {
    /// Output directory (scenes/, views/ and manifest.json). Rerun to resume.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Master seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Number of generated scenes.
    #[arg(long, default_value_t = 28, value_parser = clap::value_parser!(u64).range(1..=100_000))]
    pub scenes: u64,
    /// Views (cameras) per scene.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub views: u32,
    /// Image width and height of every view.
    #[arg(long, default_value_t = 96, value_parser = clap::value_parser!(u32).range(16..=4096))]
    pub size: u32,
    /// Reference samples per pixel (doubled where the reference stays noisy).
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(2..=1_048_576))]
    pub reference_spp: u32,
    /// Render only these scenes: `validation` makes just the held-out views (every 6th scene),
    /// enough to score a model in about a sixth of the time; `training` the rest. A view is the
    /// same bytes whichever split renders it.
    #[arg(long, value_enum, default_value_t = SplitArg::All)]
    pub split: SplitArg,
    /// Instead of generating: re-render the guide layers of the existing dataset's views in place
    /// with the current guide pass (noisy renders and references are kept). The dataset's own
    /// settings apply, so the generation options cannot be given with it.
    #[arg(long, conflicts_with_all = ["seed", "scenes", "views", "size", "reference_spp", "split", "database"])]
    pub refresh_guides: bool,
    /// Render on the queue instead: queue one task per scene in this database (sqlite://… or
    /// postgres://…) for `rtd worker` nodes, and gather their views into the output directory
    /// as they finish. The dataset is the same as without it. Rerun to resume.
    #[arg(long, value_name = "URL")]
    pub database: Option<String>,
    /// With --database: also render on this many workers in this process.
    #[arg(long, default_value_t = 0, requires = "database", value_parser = clap::value_parser!(u32).range(0..=64))]
    pub workers: u32,
    /// Hide the progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Which scenes `rtd datagen` renders.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum SplitArg {
    /// Every scene.
    All,
    /// Only the training scenes.
    Training,
    /// Only the held-out validation scenes.
    Validation,
}

/// `rtd train` options.
#[derive(Debug, Clone, Args)]
pub struct TrainArgs {
    /// Dataset directory made by `rtd datagen` (with --quick: where to make a tiny one).
    #[arg(long)]
    pub data: PathBuf,
    /// Output directory: checkpoints, state.json, curves.png, and model.bpk + model.json at the end.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Steps, batches, crops, learning rate and seed.
    #[command(flatten)]
    pub schedule: TrainScheduleArgs,
    /// The network: a model to fine-tune and the input encoding.
    #[command(flatten)]
    pub model: TrainModelArgs,
    /// The loss and the inputs it is computed on.
    #[command(flatten)]
    pub loss: TrainLossArgs,
    /// Score every epoch on the validation views of this dataset (made apart, e.g. by `rtd
    /// datagen --split validation`) instead of --data's own, which a `--split training` set
    /// lacks. Part of the run's options: --resume needs it again. Not with --quick, which
    /// scores its own tiny dataset.
    #[arg(long, conflicts_with = "quick")]
    pub validation_data: Option<PathBuf>,
    /// Another dataset whose training views are pooled with --data's (repeatable): sets
    /// generated apart, trained on together. Each is checked as --data is. Part of the run's
    /// options: --resume needs them again. Not with --quick.
    #[arg(long, value_name = "DIR", conflicts_with = "quick")]
    pub more_data: Vec<PathBuf>,
    /// Continue the run in --output after an interruption.
    #[arg(long)]
    pub resume: bool,
    /// Smoke run: make a tiny dataset in --data and train a few steps on it.
    #[arg(long)]
    pub quick: bool,
    /// Hide the progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// `rtd train`'s schedule: how many steps of how many crops of which size, at which rate.
#[derive(Debug, Clone, Args)]
pub struct TrainScheduleArgs {
    /// Optimiser steps.
    #[arg(long, default_value_t = 3000, value_parser = clap::value_parser!(u64).range(1..=10_000_000))]
    pub steps: u64,
    /// Crops per batch.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub batch: u32,
    /// Crop side in pixels (a multiple of the network's alignment, 2^(levels−1): 4 for the
    /// shipped U-Net; and at most the dataset's image size).
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(8..=1024))]
    pub crop: u32,
    /// Steps per epoch (validation + checkpoint after each).
    #[arg(long, default_value_t = 200, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    pub epoch_steps: u64,
    /// Seed for weights and batches.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Peak learning rate (warm-up then cosine decay).
    #[arg(long, default_value_t = 2e-3, value_parser = positive_rate)]
    pub lr: f64,
}

/// `rtd train`'s network: the shipped U-Net's shape (or another) from random weights, or a model
/// to fine-tune, with the input encoding it is trained for.
#[derive(Debug, Clone, Args)]
pub struct TrainModelArgs {
    /// Fine-tune: start from this model's weights (.bpk with its .json beside it); the network
    /// is the one its config describes.
    #[arg(long)]
    pub init: Option<PathBuf>,
    /// From random weights: channels at each resolution level, full resolution first
    /// (comma-separated; default: the shipped 24,48,64). Not with --init, whose model sets them.
    #[arg(long, value_delimiter = ',', conflicts_with = "init",
          value_parser = clap::value_parser!(u32).range(1..=rtd_denoise::model::MAX_LEVEL_CHANNELS as i64))]
    pub channels: Vec<u32>,
    /// From random weights: inception blocks at the coarsest level (default: the shipped 2).
    /// Not with --init, whose model sets them.
    #[arg(long, conflicts_with = "init",
          value_parser = clap::value_parser!(u32).range(0..=rtd_denoise::model::MAX_BOTTLENECK_BLOCKS as i64))]
    pub bottleneck_blocks: Option<u32>,
    /// Divide colour by the albedo before the network and multiply it back after (saved in the
    /// model's config; with --init, the initial model may lack it).
    #[arg(long)]
    pub demodulate: bool,
    /// Predict per-pixel kernels that average the noisy colour at each level, blended coarse
    /// to fine (multi-scale kernel prediction), instead of the colour itself (saved in the
    /// model's config; with --init, a direct-prediction model gets new, random heads).
    #[arg(long)]
    pub kernel_output: bool,
    /// Blend the kernel levels through bilinear upsampling of each coarser level's correction
    /// instead of nearest, whose blocks show where the correction is large (saved in the
    /// model's config; for a kernel-predicting network, from --kernel-output or --init)
    #[arg(long)]
    pub bilinear_blend: bool,
    /// The side of the predicted kernels at every level, odd (saved in the model's config;
    /// default 5; not with --init, whose model sets it)
    #[arg(long, conflicts_with = "init", requires = "kernel_output",
          value_parser = clap::value_parser!(u32).range(3..=rtd_denoise::kernel_output::MAX_KERNEL_SIZE as i64))]
    pub kernel_size: Option<u32>,
    /// Exposure the log-average luminance is mapped to before the log transfer (saved in the
    /// model's config; default 0.18, or the --init model's): larger keys give dark regions more
    /// of the transfer's range and of the loss
    #[arg(long, value_parser = parse_key)]
    pub exposure_key: Option<f32>,
}

/// `rtd train`'s loss and the inputs its crops carry.
#[derive(Debug, Clone, Args)]
pub struct TrainLossArgs {
    /// Weight of an extra squared-error term on the display transform the validation PSNR is
    /// measured on (linear colour clamped to [0, 1], sRGB-encoded; 0: off).
    #[arg(long, default_value_t = 0.0, value_parser = non_negative_weight)]
    pub display_loss: f32,
    /// Train only on the noisy renders at these sample counts (comma-separated, e.g. 4,8,16;
    /// default: every count the dataset has).
    #[arg(long, value_delimiter = ',', value_parser = clap::value_parser!(u32).range(1..))]
    pub spp_levels: Vec<u32>,
    /// Probability that a training crop loses its albedo + normal layers, and independently its
    /// AO + depth layers, so the model also serves colour + guide RGB alone.
    #[arg(long, default_value_t = rtd_train::data::DROP_PROBABILITY, value_parser = probability)]
    pub guide_drop: f32,
    /// Probability that a training crop loses its per-pixel variance, so the model also serves
    /// files from other software, which have none (1: never show it).
    #[arg(long, default_value_t = rtd_train::data::DROP_PROBABILITY, value_parser = probability)]
    pub variance_drop: f32,
    /// Probability that a training crop is colour alone: the noisy colour stands in for its
    /// guide and it has no albedo, normal, AO or depth, as `rtd denoise` sees a file without
    /// passes
    #[arg(long, default_value_t = rtd_train::data::COLOUR_ONLY_PROBABILITY, value_parser = probability)]
    pub colour_only: f32,
    /// Probability that a training crop with albedo but without AO + depth takes its albedo as
    /// its guide RGB, as `rtd denoise` does for files from other software (Blender, Nuke) that
    /// have no guide
    #[arg(long, default_value_t = 0.0, value_parser = probability)]
    pub albedo_guide: f32,
}

/// A loss weight in [0, 100].
fn non_negative_weight(s: &str) -> Result<f32, String> {
    f32_within(s, 0.0, 100.0)
}

/// A probability in [0, 1].
fn probability(s: &str) -> Result<f32, String> {
    f32_within(s, 0.0, 1.0)
}

/// A learning rate in (0, 1].
fn positive_rate(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("{e}"))?;
    if v > 0.0 && v <= 1.0 {
        Ok(v)
    } else {
        Err(format!("{v} is not in (0, 1]"))
    }
}

/// An exposure key in [0.001, 1000].
fn parse_key(s: &str) -> Result<f32, String> {
    let v: f32 = s.parse().map_err(|e| format!("{e}"))?;
    if (1e-3..=1e3).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{v} is not in [0.001, 1000]"))
    }
}

/// A number in [lo, hi].
fn f32_within(s: &str, lo: f32, hi: f32) -> Result<f32, String> {
    let v: f32 = s.parse().map_err(|e| format!("{e}"))?;
    if (lo..=hi).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{v} is not in [{lo}, {hi}]"))
    }
}
