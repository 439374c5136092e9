//! `rtd bench etrt`: the seed thesis's equal-time ray-trace comparison. The rtd pipeline
//! (render at low spp, guide pass, denoiser) is timed; the same render then continues for the
//! wall time the guide and denoiser took (ETRT), and on until its error matches the denoised
//! image's (time-to-quality, extrapolated from the error-versus-time curve when that would
//! take too long). Every image is scored against a reference with the same metric code.

use std::path::Path;
use std::time::Duration;

use rtd_denoise::filter::GuidedFilter;
use rtd_denoise::{DenoiseInput, Denoiser};
use rtd_image::metrics::{metrics, Metrics};
use rtd_image::{HdrImage, Quiet};
use rtd_pipeline::{denoise_input, Budget, Pipeline, SceneView};
use rtd_render::{PathTracer, RenderSettings};
use serde::{Deserialize, Serialize};

use crate::reference::{reference, ReferenceOptions};
use crate::{BenchError, METRIC_BORDER};
use rtd_image::Progress;

/// What an equal-time comparison measures: the pipeline's sample count, the image size, the
/// seeds and the reference.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct EtrtOptions {
    /// Samples per pixel of the denoised pipeline.
    pub spp: u32,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Seed of the measured render (the reference uses independent seeds).
    pub seed: u64,
    /// How a rendered reference is made (when none is given).
    pub reference: ReferenceOptions,
    /// Longest plain rendering for time-to-quality, as a multiple of the pipeline's time;
    /// beyond it the time is extrapolated.
    pub max_plain_factor: f64,
}

impl Default for EtrtOptions {
    fn default() -> Self {
        EtrtOptions {
            spp: 8,
            width: 256,
            height: 256,
            seed: 0,
            reference: ReferenceOptions::default(),
            max_plain_factor: 16.0,
        }
    }
}

/// One scored image.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Scored {
    /// What it is, as the tables label it.
    pub name: String,
    /// Samples per pixel behind it.
    pub spp: u32,
    /// Wall seconds to make it (render + guide + denoise where they apply).
    pub seconds: f64,
    /// Its metrics against the reference.
    pub metrics: Metrics,
}

/// The ETRT report.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct EtrtReport {
    /// Scene file.
    pub scene: String,
    /// What was measured: sample counts, size, seeds, reference.
    pub options: EtrtOptions,
    /// Reference spp and where it came from.
    pub reference: String,
    /// The reference's samples per pixel (None if it was loaded from a file).
    pub reference_spp: Option<u32>,
    /// Estimated relMSE left in the reference (from two independent halves; None if loaded).
    pub reference_relmse: Option<f64>,
    /// Render seconds of the pipeline.
    pub render_s: f64,
    /// Guide pass seconds.
    pub guide_s: f64,
    /// Denoiser seconds.
    pub denoise_s: f64,
    /// The denoiser model.
    pub denoise_model: String,
    /// The denoiser's self-ensemble passes.
    pub denoise_passes: usize,
    /// The scored images.
    pub images: EtrtScores,
    /// Plain path tracing's error over time: (seconds, spp, relMSE, PSNR).
    pub curve: Vec<(f64, u32, f64, f64)>,
    /// Seconds plain path tracing needs to reach the denoised image's relMSE.
    pub time_to_quality_s: f64,
    /// True when `time_to_quality_s` was extrapolated from the curve (MSE ∝ 1/time).
    pub time_to_quality_extrapolated: bool,
    /// time_to_quality_s / pipeline seconds.
    pub speedup: f64,
    /// 100 · (1 − pipeline / time_to_quality).
    pub pipeline_time_saved_percent: f64,
}

impl EtrtReport {
    /// The pipeline's total seconds.
    pub fn pipeline_s(&self) -> f64 {
        self.render_s + self.guide_s + self.denoise_s
    }
}

/// The images an equal-time comparison scores.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct EtrtScores {
    /// The pipeline's noisy render.
    pub noisy: Scored,
    /// rtd: the noisy render denoised with every guide layer.
    pub denoised: Scored,
    /// Plain path tracing given the pipeline's wall time.
    pub etrt: Scored,
    /// The thesis's ablation: the denoiser given the noisy render as its guide.
    pub ablation: Scored,
    /// The non-learned guided filter on the same inputs.
    pub filtered: Scored,
}

impl EtrtScores {
    /// Every scored image, in table order.
    pub fn all(&self) -> [&Scored; 5] {
        [&self.noisy, &self.denoised, &self.etrt, &self.ablation, &self.filtered]
    }
}

/// The images a run produced, for figures.
pub struct EtrtImages {
    /// Noisy pipeline input.
    pub noisy: HdrImage,
    /// Denoised.
    pub denoised: HdrImage,
    /// Equal-time plain render.
    pub etrt: HdrImage,
    /// Reference.
    pub reference: HdrImage,
}

/// Runs the whole comparison on `view` against `given_reference`, or a rendered one cached in
/// `cache_dir`.
pub fn run_etrt(
    view: &SceneView,
    denoiser: &Denoiser,
    options: &EtrtOptions,
    given_reference: Option<&Path>,
    cache_dir: &Path,
    progress: &dyn Progress,
) -> Result<(EtrtReport, EtrtImages), BenchError> {
    let o = options;
    progress.start(6, "etrt");
    let size = (o.width, o.height, o.seed);
    let reference = reference(view, size, &o.reference, given_reference, cache_dir, progress)?;
    progress.inc(1);
    // The rtd pipeline, timed stage by stage.
    let pipeline = Pipeline::new(view, RenderSettings::new(o.width, o.height).seed(o.seed)).denoise(denoiser);
    let run = pipeline.run(Budget::Samples(o.spp), &Quiet)?;
    let (Some(guide), Some(denoised)) = (run.guide, run.denoised) else {
        return Err(BenchError::msg(&view.path, "the pipeline ran without its guide pass or denoiser"));
    };
    let (render_s, guide_s, denoise_s) = (run.timings.render_s, guide.seconds, run.timings.denoise_s.unwrap_or(0.0));
    let pipeline_s = render_s + guide_s + denoise_s;
    let mut film = run.film;
    let noisy = film.beauty();
    progress.inc(1);
    // ETRT: the same render continues for the guide + denoise time.
    let tracer = pipeline.tracer()?;
    let extra = tracer.render_for(&mut film, Duration::from_secs_f64(guide_s + denoise_s), &Quiet)?;
    let etrt = film.beauty();
    progress.inc(1);
    // Equal-sample baselines.
    let ablation = denoiser.denoise(&DenoiseInput::new(&noisy, &noisy))?;
    let filtered = GuidedFilter::default().filter(&denoise_input(&noisy, &guide))?;
    progress.inc(1);
    let score = |name: &str, spp: u32, seconds: f64, img: &HdrImage| Scored {
        name: name.into(),
        spp,
        seconds,
        metrics: metrics(img, &reference.image, METRIC_BORDER),
    };
    let images = EtrtScores {
        noisy: score("noisy", o.spp, render_s, &noisy),
        denoised: score("rtd denoised", o.spp, pipeline_s, &denoised),
        etrt: score("ETRT (equal time)", film.spp, render_s + extra.seconds, &etrt),
        ablation: score("ablation: noisy as guide", o.spp, pipeline_s, &ablation),
        filtered: score("guided filter", o.spp, render_s + guide_s, &filtered),
    };
    let mut curve = vec![
        (render_s, o.spp, images.noisy.metrics.relmse, images.noisy.metrics.psnr),
        (render_s + extra.seconds, film.spp, images.etrt.metrics.relmse, images.etrt.metrics.psnr),
    ];
    let plain = PlainRender { tracer: &tracer, reference: &reference.image, start_s: render_s + extra.seconds };
    let reached = plain.time_to_quality(
        &mut film,
        &mut curve,
        images.denoised.metrics.relmse,
        pipeline_s * o.max_plain_factor,
        progress,
    )?;
    progress.inc(1);
    let (time_to_quality_s, extrapolated) = reached;
    let report = EtrtReport {
        scene: view.path.display().to_string(),
        options: o.clone(),
        reference: reference.description,
        reference_spp: reference.spp,
        reference_relmse: reference.relmse,
        render_s,
        guide_s,
        denoise_s,
        denoise_model: denoiser.name().to_string(),
        denoise_passes: denoiser.ensemble_passes(),
        images,
        curve,
        time_to_quality_s,
        time_to_quality_extrapolated: extrapolated,
        speedup: time_to_quality_s / pipeline_s,
        pipeline_time_saved_percent: 100.0 * (1.0 - pipeline_s / time_to_quality_s),
    };
    progress.inc(1);
    Ok((report, EtrtImages { noisy, denoised, etrt, reference: reference.image }))
}

/// Plain path tracing continued until it matches a target error: time-to-quality.
struct PlainRender<'t> {
    tracer: &'t PathTracer<'t>,
    reference: &'t HdrImage,
    /// Seconds of plain rendering already in the film.
    start_s: f64,
}

impl PlainRender<'_> {
    /// Keeps rendering `film`, doubling its spp, until its relMSE reaches `target` or `limit_s`
    /// seconds are spent, appending (seconds, spp, relMSE, PSNR) points to `curve` (whose last
    /// point is the film's state now). Returns the seconds needed and whether they were
    /// extrapolated (MSE ∝ 1/time) rather than measured.
    fn time_to_quality(
        &self,
        film: &mut rtd_render::Film,
        curve: &mut Vec<(f64, u32, f64, f64)>,
        target: f64,
        limit_s: f64,
        progress: &dyn Progress,
    ) -> Result<(f64, bool), BenchError> {
        let mut plain_s = self.start_s;
        if curve.last().is_some_and(|c| c.2 <= target) {
            return Ok((plain_s, false));
        }
        while plain_s < limit_s && !progress.cancelled() {
            let stats = self.tracer.render(film, film.spp.max(1))?;
            plain_s += stats.seconds;
            let m = metrics(&film.beauty(), self.reference, METRIC_BORDER);
            curve.push((plain_s, film.spp, m.relmse, m.psnr));
            if m.relmse <= target {
                // Interpolate in log-log between the last two points.
                let (t0, e0) = (curve[curve.len() - 2].0, curve[curve.len() - 2].2);
                let f = ((e0 / target).ln() / (e0 / m.relmse).ln()).clamp(0.0, 1.0);
                return Ok(((t0.ln() + f * (plain_s.ln() - t0.ln())).exp(), false));
            }
        }
        // MSE ∝ 1/time for an unbiased estimator: fit the constant on the last point.
        let (t1, e1) = curve.last().map_or((plain_s, target), |c| (c.0, c.2));
        Ok((t1 * e1 / target.max(1e-12), true))
    }
}

impl EtrtReport {
    /// The report as a Markdown table.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "## ETRT: {}\n\n{}×{}, reference {}{}. Pipeline: render {:.3} s + guide {:.3} s + denoise {:.3} s = {:.3} s ({}).\n\n",
            self.scene,
            self.options.width,
            self.options.height,
            self.reference,
            self.reference_relmse.map(|r| format!(" (estimated remaining relMSE {r:.2e})")).unwrap_or_default(),
            self.render_s,
            self.guide_s,
            self.denoise_s,
            self.pipeline_s(),
            self.denoise_model
        );
        s += "| image | spp | seconds | PSNR (dB) | SSIM | relMSE | SMAPE | SNR (dB) |\n|---|---|---|---|---|---|---|---|\n";
        for i in self.images.all() {
            let m = &i.metrics;
            s += &format!(
                "| {} | {} | {:.3} | {:.2} | {:.4} | {:.4} | {:.4} | {:.2} |\n",
                i.name, i.spp, i.seconds, m.psnr, m.ssim, m.relmse, m.smape, m.snr_db
            );
        }
        s += &format!(
            "\nPlain path tracing needs {:.2} s{} to reach the denoised relMSE: **{:.1}× speed-up, {:.1}% of pipeline time saved**.\n",
            self.time_to_quality_s,
            if self.time_to_quality_extrapolated { " (extrapolated from the error-vs-time curve, MSE ∝ 1/t)" } else { " (measured)" },
            self.speedup,
            self.pipeline_time_saved_percent
        );
        s
    }
}
