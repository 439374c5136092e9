//! `rtd bench speed`: render throughput (paths/s, rays/s), guide seconds per megapixel and
//! denoise seconds per megapixel, each the median of several runs with the min–max range, and
//! the render's rays/s as a share of raw closest-hit traversal on the same scene.

use std::time::Instant;

use rtd_denoise::Denoiser;
use rtd_image::{Progress, Quiet};
use rtd_pipeline::{denoise_input, Budget, Pipeline, PipelineRun, SceneView};
use rtd_render::RenderSettings;
use serde::{Deserialize, Serialize};

use crate::traversal::RawTraversal;
use crate::BenchError;

/// Camera rays in the raw traversal sets (the bounce set has one per camera hit).
pub const PROBE_RAYS: u32 = 1 << 16;
/// Seconds (at least) each raw traversal rate is measured for.
pub const PROBE_SECONDS: f64 = 1.0;
/// Timed warm calls of the denoiser, after one untimed, on the last run's render.
pub const WARM_DENOISE_RUNS: usize = 5;

/// Median and range of repeated measurements.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct Spread {
    /// Median.
    pub median: f64,
    /// Smallest.
    pub min: f64,
    /// Largest.
    pub max: f64,
}

impl Spread {
    /// Summarises `values` (at least one).
    pub fn of(mut values: Vec<f64>) -> Self {
        values.sort_by(|a, b| a.total_cmp(b));
        Spread { median: values[values.len() / 2], min: values[0], max: values[values.len() - 1] }
    }
}

/// The speed report of one scene at one size.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SpeedReport {
    /// Scene file.
    pub scene: String,
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Samples per pixel of each timed render.
    pub spp: u32,
    /// Runs per figure.
    pub runs: usize,
    /// Millions of camera paths per second.
    pub mpaths_per_s: Spread,
    /// Millions of rays per second.
    pub mrays_per_s: Spread,
    /// Guide pass seconds per megapixel.
    pub guide_s_per_mpixel: Spread,
    /// Denoiser seconds per megapixel, as the pipeline spent them after each render (cold:
    /// the first touch of its buffers included, as in a one-shot `rtd render --denoise`).
    pub denoise_s_per_mpixel: Spread,
    /// Denoiser seconds per megapixel of [`WARM_DENOISE_RUNS`] calls on the last run's render
    /// after one untimed call: the figure to compare with OIDN's, which is timed warm too (None:
    /// a cancelled run, or a report from before it was measured).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub denoise_warm_s_per_mpixel: Option<Spread>,
    /// The denoiser's self-ensemble passes.
    pub denoise_passes: usize,
    /// The network's multiply-accumulates per pixel and pass as a direct convolution computes
    /// them ([`rtd_denoise::DenoiserConfig::macs_per_pixel`]): the work a GFLOP/s figure counts.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub denoise_macs_per_pixel: Option<f64>,
    /// Raw closest-hit traversal of camera rays, millions of rays per second (one measurement;
    /// None when not measured: a cancelled run, or no rays).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub raw_camera_mrays_per_s: Option<f64>,
    /// Raw closest-hit traversal of one diffuse bounce from each camera hit (incoherent rays),
    /// millions of rays per second (one measurement; None when not measured: a cancelled run,
    /// or no camera ray hit anything).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub raw_bounce_mrays_per_s: Option<f64>,
}

/// Measures `runs` times each: an `spp` render of `view` at `width`×`height`, its guide pass
/// and the denoiser, each run through the pipeline with its own seed; then, unless cancelled,
/// raw traversal of camera rays and of one bounce from each camera hit (see
/// [`crate::traversal`]), once each for [`PROBE_SECONDS`].
pub fn run_speed(
    view: &SceneView,
    denoiser: &Denoiser,
    (width, height): (u32, u32),
    spp: u32,
    runs: usize,
    progress: &dyn Progress,
) -> Result<SpeedReport, BenchError> {
    let mp = (width as f64 * height as f64) / 1e6;
    let (mut paths, mut rays, mut guide_t, mut den_t) = (vec![], vec![], vec![], vec![]);
    let mut last = None;
    progress.start(runs as u64, "speed");
    for run in 0..runs.max(1) {
        let settings = RenderSettings::new(width, height).seed(run as u64);
        let r = Pipeline::new(view, settings).denoise(denoiser).run(Budget::Samples(spp), &Quiet)?;
        paths.push(r.stats.paths as f64 / r.stats.seconds / 1e6);
        rays.push(r.stats.rays as f64 / r.stats.seconds / 1e6);
        guide_t.push(r.timings.guide_s.unwrap_or(0.0) / mp);
        den_t.push(r.timings.denoise_s.unwrap_or(0.0) / mp);
        last = Some(r);
        progress.inc(1);
        if progress.cancelled() {
            break;
        }
    }
    // Warm denoiser calls and raw traversal after the renders, on the same pool and scene.
    let (warm, raw) = match last.filter(|_| !progress.cancelled()) {
        Some(r) => (
            warm_denoise_s(denoiser, &r, mp)?,
            RawTraversal::measure(&view.scene, &view.camera, (width, height), PROBE_RAYS, PROBE_SECONDS),
        ),
        None => (None, RawTraversal { camera: None, bounce: None }),
    };
    Ok(SpeedReport {
        scene: view.path.display().to_string(),
        width,
        height,
        spp,
        runs: paths.len(),
        mpaths_per_s: Spread::of(paths),
        mrays_per_s: Spread::of(rays),
        guide_s_per_mpixel: Spread::of(guide_t),
        denoise_s_per_mpixel: Spread::of(den_t),
        denoise_warm_s_per_mpixel: warm,
        denoise_passes: denoiser.ensemble_passes(),
        denoise_macs_per_pixel: Some(denoiser.config().macs_per_pixel()),
        raw_camera_mrays_per_s: raw.camera,
        raw_bounce_mrays_per_s: raw.bounce,
    })
}

/// Seconds per call, per `mp` megapixels, of [`WARM_DENOISE_RUNS`] denoiser calls on `run`'s
/// render and guide pass after one untimed call (None without a guide pass).
fn warm_denoise_s(denoiser: &Denoiser, run: &PipelineRun, mp: f64) -> Result<Option<Spread>, BenchError> {
    let Some(pass) = &run.guide else {
        return Ok(None);
    };
    let (beauty, variance) = (run.film.beauty(), run.film.variance());
    let input = denoise_input(&beauty, pass).variance(variance.as_ref());
    denoiser.denoise(&input)?;
    let mut seconds = vec![];
    for _ in 0..WARM_DENOISE_RUNS {
        let t = Instant::now();
        std::hint::black_box(denoiser.denoise(&input)?);
        seconds.push(t.elapsed().as_secs_f64() / mp);
    }
    Ok(Some(Spread::of(seconds)))
}

impl SpeedReport {
    /// The render's rays/s over raw traversal rays/s `raw`: how much of a render ray's time
    /// closest-hit traversal alone would take (an estimate from above: the render's shadow rays
    /// stop at their first hit and at the light).
    pub fn traversal_share(&self, raw: f64) -> f64 {
        self.mrays_per_s.median / raw
    }

    /// The warm denoiser's rate in GFLOP/s (two per multiply-accumulate of the network as a
    /// direct convolution computes it, so that kernels doing fewer, as Winograd's do, show as
    /// faster): median, and the range from the slowest call to the fastest.
    pub fn denoise_gflops(&self) -> Option<Spread> {
        let (warm, macs) = (self.denoise_warm_s_per_mpixel?, self.denoise_macs_per_pixel?);
        // s per Mpixel → GFLOP/s: 2 · MACs/px · passes · 10⁶ px ÷ s ÷ 10⁹.
        let rate = |s: f64| 2.0 * macs * self.denoise_passes as f64 / (s * 1e3);
        Some(Spread { median: rate(warm.median), min: rate(warm.max), max: rate(warm.min) })
    }

    /// One Markdown table row per figure, then a table of the raw traversal rates.
    pub fn markdown(&self) -> String {
        let row = |name: &str, s: &Spread| format!("| {name} | {:.3} | {:.3}–{:.3} |\n", s.median, s.min, s.max);
        let raw = |name: &str, raw: Option<f64>| match raw {
            Some(r) => format!("| {name} | {r:.3} | {:.2} |\n", self.traversal_share(r)),
            None => format!("| {name} | not measured | – |\n"),
        };
        let passes = format!("{} pass{}", self.denoise_passes, if self.denoise_passes == 1 { "" } else { "es" });
        let warm = match &self.denoise_warm_s_per_mpixel {
            Some(w) => row(&format!("denoise s / Mpixel, warm ({passes}, {WARM_DENOISE_RUNS} calls)"), w),
            None => format!("| denoise s / Mpixel, warm ({passes}) | not measured | – |\n"),
        };
        let gflops = match (self.denoise_gflops(), self.denoise_macs_per_pixel) {
            (Some(g), Some(macs)) => {
                row(&format!("denoise GFLOP/s, warm (2 × {:.1}k MAC/px as direct convolution)", macs / 1e3), &g)
            }
            _ => "| denoise GFLOP/s, warm | not measured | – |\n".to_string(),
        };
        format!(
            "Speed on {} at {}×{} ({} spp renders, {} runs):\n\n| figure | median | min–max |\n|---|---|---|\n{}{}{}{}{}{}\n\
             Raw closest-hit traversal on the same scene (one measurement each):\n\n\
             | rays | M rays/s | render rays/s ÷ raw |\n|---|---|---|\n{}{}",
            self.scene,
            self.width,
            self.height,
            self.spp,
            self.runs,
            row("render M paths/s", &self.mpaths_per_s),
            row("render M rays/s", &self.mrays_per_s),
            row("guide s / Mpixel", &self.guide_s_per_mpixel),
            row(&format!("denoise s / Mpixel, in the pipeline ({passes})"), &self.denoise_s_per_mpixel),
            warm,
            gflops,
            raw("camera rays", self.raw_camera_mrays_per_s),
            raw("diffuse bounces from the camera hits", self.raw_bounce_mrays_per_s),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_is_median_and_range() {
        let s = Spread::of(vec![3.0, 1.0, 2.0, 10.0, 4.0]);
        assert_eq!((s.median, s.min, s.max), (3.0, 1.0, 10.0));
    }
}
