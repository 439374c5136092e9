//! [`TrainOptions`]: what a training run does (network, schedule, loss, crops), with the
//! setters that build it and the checks against a dataset that [`crate::train::train`] runs
//! before it writes anything.

use std::path::{Path, PathBuf};

use rtd_denoise::DenoiserConfig;
use serde::{Deserialize, Serialize};

use crate::data::{COLOUR_ONLY_PROBABILITY, DROP_PROBABILITY};
use crate::dataset::Manifest;
use crate::TrainError;

/// What a training run does: the network, the schedule, the loss and the crops. Start from
/// [`TrainOptions::default`] and change fields with the chained setters below, e.g.
/// `TrainOptions::default().steps(500).batch(4, 32)`; [`TrainOptions::validate`] checks the
/// result against a dataset, [`TrainOptions::validate_validation_data`] against a separate
/// validation dataset, and [`train`] calls both before it writes anything.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct TrainOptions {
    /// The network to train (saved as `model.json` at the end).
    pub config: DenoiserConfig,
    /// Seed for the initial weights and for every batch's crops and augmentations.
    pub seed: u64,
    /// Optimiser steps in all (at least 1).
    pub steps: u64,
    /// Crops per batch (at least 1).
    pub batch: usize,
    /// Crop side in pixels: a positive multiple of the network's alignment, at most the
    /// dataset's view sides.
    pub crop: usize,
    /// Peak learning rate of the warm-up + cosine schedule ([`TrainOptions::learning_rate_at`]).
    pub learning_rate: f64,
    /// Steps per epoch (at least 1): validation and a checkpoint follow each epoch.
    pub epoch_steps: u64,
    /// Noisy sample count the validation views are denoised at every epoch.
    pub validation_spp: u32,
    /// Start from these weights (a `model.bpk` whose `.json` config equals `config`) instead
    /// of random ones: fine-tuning. The optimiser and schedule start afresh.
    #[serde(default)]
    pub init: Option<PathBuf>,
    /// Weight of [`display_loss`](crate::loss::display_loss), the squared error on the display
    /// transform the PSNR is measured on, added to the L1
    /// [`training_loss`](crate::loss::training_loss) (0: off).
    #[serde(default)]
    pub display_loss: f32,
    /// Train only on the noisy renders at these sample counts (`None`: every stored count).
    #[serde(default)]
    pub spp_levels: Option<Vec<u32>>,
    /// Probability that a crop loses its albedo+normal layers, and (independently) its AO+depth
    /// layers, so the model also serves inputs with the guide RGB alone.
    #[serde(default = "default_guide_drop")]
    pub guide_drop: f32,
    /// Probability that a crop loses its per-pixel variance (independently of the guide
    /// layers), so the model also serves files from other software, which have none. Runs
    /// made before the variance planes had none to lose: their state files read 1.
    #[serde(default = "never_shown")]
    pub variance_drop: f32,
    /// Probability that a crop is colour alone: the noisy colour stands in for its guide, and
    /// it has no albedo, normal, AO or depth, as `rtd denoise` sees a file with no passes. Runs
    /// made before this case existed had none: their state files read 0.
    #[serde(default)]
    pub colour_only: f32,
    /// Probability that a crop with albedo but without AO + depth takes its albedo as its guide
    /// RGB, as `rtd denoise` does for files from other software (Blender, Nuke) that have no
    /// guide. Runs made before this case existed had none: their state files read 0.
    #[serde(default)]
    pub albedo_guide: f32,
    /// Score every epoch on the validation views of this dataset instead of the training
    /// dataset's own: a held-out split made apart (`rtd datagen --split validation`), for a
    /// training set made with `--split training`, which has none.
    #[serde(default)]
    pub validation_data: Option<PathBuf>,
    /// More datasets whose training views are pooled with the training dataset's, each checked
    /// as that one is: sets generated apart (other seeds, other sessions) trained on together.
    #[serde(default)]
    pub more_data: Vec<PathBuf>,
}

fn never_shown() -> f32 {
    1.0
}

fn default_guide_drop() -> f32 {
    DROP_PROBABILITY
}

impl Default for TrainOptions {
    /// The shipped U-Net, 3000 steps of 8 crops of 64² at a peak rate of 0.002, epochs of 200
    /// steps validated at 8 spp, seed 1, plain L1 on every stored sample count.
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
            display_loss: 0.0,
            spp_levels: None,
            guide_drop: DROP_PROBABILITY,
            variance_drop: DROP_PROBABILITY,
            colour_only: COLOUR_ONLY_PROBABILITY,
            albedo_guide: 0.0,
            validation_data: None,
            more_data: vec![],
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
    /// Sets the weight of [`display_loss`](crate::loss::display_loss) in the loss (0: off;
    /// negative weights become 0).
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
    /// Sets the probability that a crop is colour alone (clamped to [0, 1]).
    pub fn colour_only(mut self, p: f32) -> Self {
        self.colour_only = p.clamp(0.0, 1.0);
        self
    }
    /// Sets the probability that a crop with albedo but without AO + depth takes its albedo as
    /// its guide (clamped to [0, 1]).
    pub fn albedo_guide(mut self, p: f32) -> Self {
        self.albedo_guide = p.clamp(0.0, 1.0);
        self
    }
    /// Sets the probability that a crop loses its variance (clamped to [0, 1]).
    pub fn variance_drop(mut self, p: f32) -> Self {
        self.variance_drop = p.clamp(0.0, 1.0);
        self
    }
    /// Scores every epoch on the validation views of the dataset in `dir` (`None`: the
    /// training dataset's own).
    pub fn validation_data(mut self, dir: Option<PathBuf>) -> Self {
        self.validation_data = dir;
        self
    }
    /// Pools the training views of the datasets in `dirs` with the training dataset's.
    pub fn more_data(mut self, dirs: Vec<PathBuf>) -> Self {
        self.more_data = dirs;
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

    /// Checks that these options can train on the dataset in `data`, whose manifest is
    /// `manifest`, before any view is loaded or any file written: a network of a plausible
    /// shape ([`DenoiserConfig::shape_problem`]); at least one step, epoch step and crop per
    /// batch; a finite learning rate above 0; a finite display-loss weight of at least 0;
    /// guide- and variance-drop probabilities in [0, 1]; a crop side that is a positive
    /// multiple of the network's alignment and at most the dataset's view sides; training
    /// sample counts the dataset stores, and the validation one unless
    /// [`TrainOptions::validation_data`] names another dataset (which
    /// [`TrainOptions::validate_validation_data`] checks); and training views. The error is
    /// [`TrainError::InvalidOptions`], naming `data`.
    pub fn validate(&self, data: &Path, manifest: &Manifest) -> Result<(), TrainError> {
        let problem = self.problem_alone().or_else(|| self.problem_on(manifest));
        match problem {
            Some(message) => Err(TrainError::InvalidOptions { dataset: data.to_path_buf(), message }),
            None => Ok(()),
        }
    }

    /// The checks of [`TrainOptions::validate`] that need no dataset (everything but the crop's
    /// fit to the views, the stored sample counts and the training views; nor the validation
    /// dataset), for a caller that is about to make the dataset in `data` (`rtd train
    /// --quick`).
    pub fn validate_alone(&self, data: &Path) -> Result<(), TrainError> {
        match self.problem_alone() {
            Some(message) => Err(TrainError::InvalidOptions { dataset: data.to_path_buf(), message }),
            None => Ok(()),
        }
    }

    /// What makes these options unusable on any dataset, if anything.
    fn problem_alone(&self) -> Option<String> {
        if let Some(problem) = self.config.shape_problem() {
            return Some(format!("the network's shape: {problem}"));
        }
        let counts =
            [("step count", self.steps), ("epoch length", self.epoch_steps), ("batch size", self.batch as u64)];
        if let Some((what, _)) = counts.iter().find(|(_, n)| *n == 0) {
            return Some(format!("the {what} is 0; it must be at least 1"));
        }
        if !(self.learning_rate.is_finite() && self.learning_rate > 0.0) {
            return Some(format!("the learning rate {} is not a finite number above 0", self.learning_rate));
        }
        if !(self.display_loss.is_finite() && self.display_loss >= 0.0) {
            return Some(format!("the display loss weight {} is not a finite number of at least 0", self.display_loss));
        }
        if !(0.0..=1.0).contains(&self.guide_drop) {
            return Some(format!("the guide drop probability {} is not in [0, 1]", self.guide_drop));
        }
        if !(0.0..=1.0).contains(&self.variance_drop) {
            return Some(format!("the variance drop probability {} is not in [0, 1]", self.variance_drop));
        }
        if !(0.0..=1.0).contains(&self.colour_only) {
            return Some(format!("the colour-only probability {} is not in [0, 1]", self.colour_only));
        }
        if !(0.0..=1.0).contains(&self.albedo_guide) {
            return Some(format!("the albedo-as-guide probability {} is not in [0, 1]", self.albedo_guide));
        }
        let (crop, align) = (self.crop, self.config.alignment());
        if crop == 0 || crop % align != 0 {
            return Some(format!(
                "the crop side {crop} px is not a positive multiple of {align}, the network's alignment"
            ));
        }
        None
    }

    /// What makes these options unusable on the dataset of `manifest`, if anything, beyond
    /// [`TrainOptions::problem_alone`].
    fn problem_on(&self, manifest: &Manifest) -> Option<String> {
        let (crop, side) = (self.crop, manifest.options.size as usize);
        if crop > side {
            return Some(format!("the crop side {crop} px is larger than the dataset's {side}x{side} px views"));
        }
        let stored = &manifest.noisy_spp;
        if let Some(levels) = &self.spp_levels {
            let missing: Vec<u32> = levels.iter().copied().filter(|l| !stored.contains(l)).collect();
            if levels.is_empty() {
                return Some("the list of sample counts to train on is empty".into());
            }
            if !missing.is_empty() {
                return Some(format!(
                    "the dataset has no noisy renders at the sample counts {missing:?} (it stores {stored:?})"
                ));
            }
        }
        if self.validation_data.is_none() {
            if let Some(problem) = self.validation_problem(manifest) {
                return Some(problem);
            }
        }
        if !manifest.views.iter().any(|v| !v.validation) {
            return Some("the dataset has no training views".into());
        }
        None
    }

    /// Checks that the dataset `dir` given as [`TrainOptions::validation_data`], whose
    /// manifest is `manifest`, can score the run: it has validation views, with noisy renders
    /// at the validation sample count. The error names `dir`.
    pub fn validate_validation_data(&self, dir: &Path, manifest: &Manifest) -> Result<(), TrainError> {
        let problem = match manifest.views.iter().any(|v| v.validation) {
            false => Some("the validation dataset has no validation views".to_string()),
            true => self.validation_problem(manifest),
        };
        match problem {
            Some(message) => Err(TrainError::InvalidOptions { dataset: dir.to_path_buf(), message }),
            None => Ok(()),
        }
    }

    /// Why the validation views of the dataset of `manifest` cannot be scored at the
    /// validation sample count, if they cannot.
    fn validation_problem(&self, manifest: &Manifest) -> Option<String> {
        let stored = &manifest.noisy_spp;
        (!stored.contains(&self.validation_spp)).then(|| {
            format!(
                "the dataset has no noisy renders at the validation sample count {} (it stores {stored:?})",
                self.validation_spp
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A manifest of two `size`² views, one for training and one for validation, at every
    /// stored sample count.
    fn manifest(size: u32) -> Manifest {
        let view = |validation| crate::dataset::ViewRecord {
            file: String::new(),
            scene: 0,
            view: 0,
            layout: crate::scenegen::Layout::ClosedRoom,
            validation,
            reference_spp: 16,
            reference_relmse: 0.0,
            seconds: 0.0,
        };
        Manifest {
            options: crate::dataset::DatasetOptions::default().size(size),
            noisy_spp: rtd_render::SPP_LADDER.to_vec(),
            views: vec![view(false), view(true)],
            rejected: vec![],
        }
    }

    /// The error message of validating `options` against `manifest`, checked to be an
    /// [`TrainError::InvalidOptions`] naming the dataset.
    fn refusal(options: &TrainOptions, manifest: &Manifest) -> String {
        match options.validate(Path::new("tiny-data"), manifest) {
            Err(e @ TrainError::InvalidOptions { .. }) => {
                let text = e.to_string();
                assert!(text.starts_with("tiny-data: ") && !text.contains('\n'), "{text}");
                text
            }
            other => panic!("expected InvalidOptions, got {other:?}"),
        }
    }

    #[test]
    fn options_are_checked_against_the_dataset() {
        let m = manifest(24);
        // Crops up to the views' side, in steps of the network's alignment (4 for the U-Net).
        for crop in [4, 16, 24] {
            assert!(TrainOptions::default().batch(2, crop).validate(Path::new("d"), &m).is_ok(), "{crop}");
        }
        let e = refusal(&TrainOptions::default().batch(2, 32), &m);
        assert!(e.contains("crop side 32 px is larger than the dataset's 24x24 px views"), "{e}");
        let e = refusal(&TrainOptions::default().batch(2, 18), &m);
        assert!(e.contains("crop side 18 px is not a positive multiple of 4"), "{e}");
        assert!(refusal(&TrainOptions::default().batch(2, 0), &m).contains("crop side 0 px"));
        // A two-level network aligns to 2, so 18 is fine for it.
        let two = TrainOptions::default().config(DenoiserConfig::new(vec![8, 8])).batch(2, 18);
        assert!(two.validate(Path::new("d"), &m).is_ok());
        let none = TrainOptions::default().config(DenoiserConfig::new(vec![])).batch(2, 16);
        assert!(refusal(&none, &m).contains("implausible channel list []"));
        use rtd_denoise::model::{MAX_BOTTLENECK_BLOCKS, MAX_LEVELS, MAX_LEVEL_CHANNELS};
        let over = MAX_LEVEL_CHANNELS + 1;
        let wide = TrainOptions::default().config(DenoiserConfig::new(vec![8, over])).batch(2, 16);
        assert!(refusal(&wide, &m).contains(&format!("implausible channel list [8, {over}]")));
        let deep = TrainOptions::default().config(DenoiserConfig::new(vec![8; MAX_LEVELS + 1])).batch(2, 16);
        assert!(refusal(&deep, &m).contains(&format!("1 to {MAX_LEVELS} levels")));
        let (many, most) = (MAX_BOTTLENECK_BLOCKS + 1, MAX_BOTTLENECK_BLOCKS);
        let blocks = TrainOptions::default().config(DenoiserConfig::new(vec![8]).with_bottleneck_blocks(many));
        let expected = format!("implausible bottleneck of {many} blocks (at most {most})");
        assert!(refusal(&blocks.batch(2, 16), &m).contains(&expected));
        let prong = TrainOptions::default().config(DenoiserConfig::new(vec![8]).with_prong(4)).batch(2, 16);
        assert!(refusal(&prong, &m).contains("implausible prong 4"));
        // Without a dataset: the shape is checked, the crop's fit to the views is not.
        let e = prong.validate_alone(Path::new("d")).unwrap_err().to_string();
        assert!(e.starts_with("d: the network's shape: implausible prong 4"), "{e}");
        assert!(TrainOptions::default().batch(2, 32).validate_alone(Path::new("d")).is_ok());
        // Counts, rates, weights and probabilities.
        let ok = TrainOptions::default().batch(2, 16);
        assert!(refusal(&ok.clone().batch(0, 16), &m).contains("batch size is 0"));
        assert!(refusal(&ok.clone().steps(0), &m).contains("step count is 0"));
        assert!(refusal(&ok.clone().epoch_steps(0), &m).contains("epoch length is 0"));
        for lr in [0.0, -1e-3, f64::NAN, f64::INFINITY] {
            assert!(refusal(&ok.clone().learning_rate(lr), &m).contains("learning rate"), "{lr}");
        }
        for w in [-1.0, f32::NAN, f32::INFINITY] {
            let o = TrainOptions { display_loss: w, ..ok.clone() };
            assert!(refusal(&o, &m).contains("display loss weight"), "{w}");
        }
        for p in [-0.1, 1.5, f32::NAN] {
            let o = TrainOptions { guide_drop: p, ..ok.clone() };
            assert!(refusal(&o, &m).contains("guide drop probability"), "{p}");
        }
        assert!(TrainOptions { guide_drop: 1.0, ..ok.clone() }.validate(Path::new("d"), &m).is_ok());
        // Sample counts the dataset lacks, for training or for validation.
        let e = refusal(&ok.clone().spp_levels(Some(vec![3, 8])), &m);
        assert!(e.contains("sample counts [3]") && e.contains("[1, 2, 4, 8, 16, 32, 64]"), "{e}");
        assert!(refusal(&ok.clone().spp_levels(Some(vec![])), &m).contains("empty"));
        let e = refusal(&TrainOptions { validation_spp: 5, ..ok.clone() }, &m);
        assert!(e.contains("validation sample count 5"), "{e}");
        // A dataset of validation views alone has nothing to train on.
        let mut held_out = manifest(24);
        held_out.views.retain(|v| v.validation);
        assert!(refusal(&ok, &held_out).contains("no training views"));
        // With a separate validation dataset, the validation sample count is that dataset's
        // business: the training set need not store it, the validation set must, and it must
        // have validation views.
        let elsewhere = TrainOptions { validation_spp: 5, ..ok.clone() }.validation_data(Some("v".into()));
        assert!(elsewhere.validate(Path::new("d"), &m).is_ok());
        let e = elsewhere.validate_validation_data(Path::new("v"), &m).unwrap_err().to_string();
        assert!(e.starts_with("v: ") && e.contains("validation sample count 5"), "{e}");
        let mut training_only = manifest(24);
        training_only.views.retain(|v| !v.validation);
        let e = ok.validate_validation_data(Path::new("v"), &training_only).unwrap_err().to_string();
        assert_eq!(e, "v: the validation dataset has no validation views");
        assert!(ok.validate_validation_data(Path::new("v"), &m).is_ok());
    }
}
