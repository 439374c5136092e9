//! The training curves PNG: loss per step and validation PSNR per epoch against the noisy input.

use std::path::Path;

use rtd_plot::{write_charts, Chart, Series};

use crate::run_state::TrainState;
use crate::TrainError;

/// The charts of a run: the loss (smoothed over 20 steps), and validation PSNR per validated
/// epoch, denoised and noisy, if the dataset had validation views.
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
    let mut charts =
        vec![Chart::new("training loss", "optimiser step", y_label)
            .with(Series::line("train (mean of 20 steps)", smoothed))];
    let validated: Vec<_> = state.history.iter().filter_map(|r| Some((r.step as f64, r.validation?))).collect();
    if !validated.is_empty() {
        charts.push(
            Chart::new(format!("validation at {} spp", state.options.validation_spp), "optimiser step", "PSNR (dB)")
                .with(Series::line("denoised", validated.iter().map(|(step, v)| (*step, v.psnr)).collect()))
                .with(Series::line("noisy input", validated.iter().map(|(step, v)| (*step, v.noisy_psnr)).collect())),
        );
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
    use crate::run_state::{EpochRecord, ValidationScores};
    use crate::TrainOptions;

    /// A run of two epochs; `validated` says whether they were scored on validation views.
    fn state(validated: bool) -> TrainState {
        let scores = |psnr: f64| ValidationScores {
            psnr,
            ssim: 0.9,
            relmse: 0.01,
            noisy_psnr: 24.0,
            noisy_ssim: 0.5,
            noisy_relmse: 0.2,
        };
        let record = |step: u64, psnr: f64| EpochRecord {
            step,
            train_loss: 0.1,
            validation: validated.then(|| scores(psnr)),
            crops_per_s: 1.0,
            wall_s: 1.0,
        };
        let history = vec![record(20, 30.0), record(40, 31.0)];
        TrainState { options: TrainOptions::default(), step: 40, history, losses: vec![0.1; 40] }
    }

    #[test]
    fn the_validation_panel_is_drawn_only_when_there_were_validation_views() {
        let titles = |s: &TrainState| training_charts(s).into_iter().map(|c| c.title).collect::<Vec<_>>();
        assert_eq!(titles(&state(true)), ["training loss", "validation at 8 spp"]);
        assert_eq!(titles(&state(false)), ["training loss"]);
        // The panel draws each validated epoch's scores, denoised and noisy.
        let panel = training_charts(&state(true)).remove(1);
        let points: Vec<Vec<(f64, f64)>> = panel.series.iter().map(|s| s.points.clone()).collect();
        assert_eq!(points, [vec![(20.0, 30.0), (40.0, 31.0)], vec![(20.0, 24.0), (40.0, 24.0)]]);
        let mut weighted = state(false);
        weighted.options = weighted.options.display_loss(100.0);
        assert_eq!(training_charts(&weighted)[0].y_label, "L1 (log colour) + 100 x display MSE");
    }
}
