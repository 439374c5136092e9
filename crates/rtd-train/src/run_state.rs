//! A training run's record and files: the per-epoch history and resumable state that
//! `state.json` holds, and where a run keeps its checkpoints.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::TrainOptions;

/// Validation means of one epoch over the dataset's validation views: the denoised output's
/// scores and, as the baseline, the noisy input's, all against the references.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct ValidationScores {
    /// Denoised PSNR (dB).
    pub psnr: f64,
    /// Denoised SSIM.
    pub ssim: f64,
    /// Denoised relMSE.
    pub relmse: f64,
    /// Noisy-input PSNR (dB).
    pub noisy_psnr: f64,
    /// Noisy-input SSIM.
    pub noisy_ssim: f64,
    /// Noisy-input relMSE.
    pub noisy_relmse: f64,
}

/// One finished epoch of a run, as `state.json` records it.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(from = "EpochWire")]
pub struct EpochRecord {
    /// Steps done at the end of the epoch.
    pub step: u64,
    /// Mean training loss over the epoch.
    pub train_loss: f64,
    /// The validation scores, or `None` when the dataset has no validation views.
    pub validation: Option<ValidationScores>,
    /// Training throughput over the epoch, crops per second.
    pub crops_per_s: f64,
    /// Wall seconds of training so far (all sessions).
    pub wall_s: f64,
}

/// An [`EpochRecord`] as `state.json` holds it: as written now (`validation` an object or
/// null), or as written before `validation` existed, with the six scores flat in the record
/// and 0 dB for the noisy input when the dataset had no validation views (no real image scores
/// that), so that older runs still resume.
#[derive(Deserialize)]
struct EpochWire {
    step: u64,
    train_loss: f64,
    #[serde(default)]
    validation: Option<ValidationScores>,
    #[serde(default)]
    psnr: f64,
    #[serde(default)]
    ssim: f64,
    #[serde(default)]
    relmse: f64,
    #[serde(default)]
    noisy_psnr: f64,
    #[serde(default)]
    noisy_ssim: f64,
    #[serde(default)]
    noisy_relmse: f64,
    crops_per_s: f64,
    wall_s: f64,
}

impl From<EpochWire> for EpochRecord {
    fn from(w: EpochWire) -> Self {
        let flat = ValidationScores {
            psnr: w.psnr,
            ssim: w.ssim,
            relmse: w.relmse,
            noisy_psnr: w.noisy_psnr,
            noisy_ssim: w.noisy_ssim,
            noisy_relmse: w.noisy_relmse,
        };
        let validation = w.validation.or((w.noisy_psnr > 0.0).then_some(flat));
        EpochRecord { step: w.step, train_loss: w.train_loss, validation, crops_per_s: w.crops_per_s, wall_s: w.wall_s }
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

/// Files of a training run in `out`: `state.json`, and the checkpoint it names,
/// `checkpoints/STEP/{weights,optimizer}.bpk`. A checkpoint is written whole before
/// `state.json` names it, and older ones are removed after, so a kill at any moment leaves
/// `state.json` naming a complete checkpoint of its own step.
pub(crate) struct RunFiles {
    out: PathBuf,
    pub(crate) state: PathBuf,
}

impl RunFiles {
    pub(crate) fn new(out: &Path) -> Self {
        RunFiles { out: out.to_path_buf(), state: out.join("state.json") }
    }

    /// The training curves, `curves.png`.
    pub(crate) fn curves(&self) -> PathBuf {
        self.out.join("curves.png")
    }

    pub(crate) fn checkpoints(&self) -> PathBuf {
        self.out.join("checkpoints")
    }

    /// The folder of the checkpoint after `step` steps.
    pub(crate) fn checkpoint(&self, step: u64) -> PathBuf {
        self.checkpoints().join(format!("{step:08}"))
    }

    /// The weights after `step` steps (or a run's from before checkpoint folders, which kept
    /// one `checkpoint.bpk`).
    pub(crate) fn weights(&self, step: u64) -> PathBuf {
        self.in_checkpoint_or_legacy(step, "weights.bpk", "checkpoint.bpk")
    }

    /// The optimiser state after `step` steps (or a legacy run's `optimizer.bpk`).
    pub(crate) fn optimizer(&self, step: u64) -> PathBuf {
        self.in_checkpoint_or_legacy(step, "optimizer.bpk", "optimizer.bpk")
    }

    /// File `name` of the checkpoint after `step` steps, or the legacy file `legacy` in the
    /// run's folder when only that exists.
    fn in_checkpoint_or_legacy(&self, step: u64, name: &str, legacy: &str) -> PathBuf {
        let (path, legacy) = (self.checkpoint(step).join(name), self.out.join(legacy));
        if !path.exists() && legacy.exists() {
            return legacy;
        }
        path
    }

    /// Removes every checkpoint but the one after `step` steps, and a legacy one, once the
    /// folder of `step` is whole (best effort: a leftover only takes room).
    pub(crate) fn remove_all_but(&self, step: u64) {
        let keep = self.checkpoint(step);
        if !keep.join("weights.bpk").exists() || !keep.join("optimizer.bpk").exists() {
            // The run's checkpoint is a legacy one (or missing): nothing else may go.
            return;
        }
        if let Ok(entries) = std::fs::read_dir(self.checkpoints()) {
            for e in entries.flatten() {
                if e.path() != keep {
                    let _ = std::fs::remove_dir_all(e.path());
                }
            }
        }
        for legacy in ["checkpoint.bpk", "optimizer.bpk"] {
            let _ = std::fs::remove_file(self.out.join(legacy));
        }
    }
}
