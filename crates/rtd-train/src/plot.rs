//! The training curves PNG: loss per step and validation PSNR per epoch against the noisy input.

use std::path::Path;

use rtd_image::plot::{write_charts, Chart, Series};

use crate::train::TrainState;
use crate::TrainError;

/// Writes loss (smoothed over 20 steps) and validation PSNR curves.
pub fn write_training_curves(path: &Path, state: &TrainState) -> Result<(), TrainError> {
    let smoothed: Vec<(f64, f64)> = state
        .losses
        .chunks(20)
        .enumerate()
        .map(|(i, c)| ((i * 20 + c.len()) as f64, c.iter().map(|v| *v as f64).sum::<f64>() / c.len() as f64))
        .collect();
    let loss = Chart {
        title: "training loss".into(),
        x_label: "step".into(),
        y_label: "L1 (log colour)".into(),
        log_x: false,
        series: vec![Series::line("train (mean of 20 steps)", smoothed)],
    };
    let h = &state.history;
    let psnr = Chart {
        title: "validation at 8 spp".into(),
        x_label: "step".into(),
        y_label: "PSNR (dB)".into(),
        log_x: false,
        series: vec![
            Series::line("denoised", h.iter().map(|r| (r.step as f64, r.psnr)).collect()),
            Series::line("noisy input", h.iter().map(|r| (r.step as f64, r.noisy_psnr)).collect()),
        ],
    };
    write_charts(path, &[loss, psnr])?;
    Ok(())
}
