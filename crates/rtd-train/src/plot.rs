//! The training curves PNG: loss per step and validation PSNR per epoch against the noisy input.

use std::path::Path;

use rtd_plot::{write_charts, Chart, Series};

use crate::train::{EpochRecord, TrainState};
use crate::TrainError;

/// The charts of a run: the loss (smoothed over 20 steps), and validation PSNR per epoch if the
/// dataset had validation views (a run without them records 0 dB, which is not drawn).
pub fn training_charts(state: &TrainState) -> Vec<Chart> {
    let smoothed: Vec<(f64, f64)> = state
        .losses
        .chunks(20)
        .enumerate()
        .map(|(i, c)| ((i * 20 + c.len()) as f64, c.iter().map(|v| *v as f64).sum::<f64>() / c.len() as f64))
        .collect();
    let y_label = match state.options.display_loss {
        w if w > 0.0 => format!("L1 (log colour) + {w} x display MSE"),
        _ => "L1 (log colour)".into(),
    };
    let mut charts = vec![Chart {
        title: "training loss".into(),
        x_label: "step".into(),
        y_label,
        log_x: false,
        series: vec![Series::line("train (mean of 20 steps)", smoothed)],
    }];
    let h = &state.history;
    if h.iter().any(EpochRecord::has_validation) {
        charts.push(Chart {
            title: "validation at 8 spp".into(),
            x_label: "step".into(),
            y_label: "PSNR (dB)".into(),
            log_x: false,
            series: vec![
                Series::line("denoised", h.iter().map(|r| (r.step as f64, r.psnr)).collect()),
                Series::line("noisy input", h.iter().map(|r| (r.step as f64, r.noisy_psnr)).collect()),
            ],
        });
    }
    charts
}

/// Writes [`training_charts`] side by side into a PNG.
pub fn write_training_curves(path: &Path, state: &TrainState) -> Result<(), TrainError> {
    write_charts(path, &training_charts(state))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::TrainOptions;

    fn state(noisy_psnr: f64) -> TrainState {
        let record = EpochRecord {
            step: 20,
            train_loss: 0.1,
            psnr: if noisy_psnr > 0.0 { 30.0 } else { 0.0 },
            ssim: 0.0,
            relmse: 0.0,
            noisy_psnr,
            noisy_ssim: 0.0,
            noisy_relmse: 0.0,
            crops_per_s: 1.0,
            wall_s: 1.0,
        };
        TrainState { options: TrainOptions::default(), step: 20, history: vec![record], losses: vec![0.1; 20] }
    }

    #[test]
    fn the_validation_panel_is_drawn_only_when_there_were_validation_views() {
        let titles = |s: &TrainState| training_charts(s).into_iter().map(|c| c.title).collect::<Vec<_>>();
        assert_eq!(titles(&state(24.0)), ["training loss", "validation at 8 spp"]);
        assert_eq!(titles(&state(0.0)), ["training loss"]);
        let mut weighted = state(0.0);
        weighted.options = weighted.options.display_loss(100.0);
        assert_eq!(training_charts(&weighted)[0].y_label, "L1 (log colour) + 100 x display MSE");
    }
}
