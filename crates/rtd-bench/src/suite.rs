//! `rtd bench suite`: ETRT over several scenes plus the spp sweep (1–64 spp, raw against
//! denoised, error against time): the speed/accuracy trade curve, with a summary table.

use std::path::{Path, PathBuf};

use rtd_denoise::Denoiser;
use rtd_image::metrics::{metrics, Metrics};
use rtd_image::{HdrImage, Progress, Quiet};
use rtd_pipeline::{Budget, CameraChoice, Pipeline, SceneView};
use rtd_plot::{write_charts, Chart, Series};
use rtd_render::{RenderSettings, SPP_LADDER};
use serde::{Deserialize, Serialize};

use crate::etrt::{run_etrt, EtrtOptions, EtrtReport};
use crate::report_files::{write_etrt, write_text};
use crate::{BenchError, METRIC_BORDER};
use rtd_image::write_json;

/// One point of the sweep.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SweepPoint {
    /// Samples per pixel.
    pub spp: u32,
    /// Render seconds.
    pub render_s: f64,
    /// Render + guide + denoise seconds.
    pub pipeline_s: f64,
    /// The raw render's metrics.
    pub raw: Metrics,
    /// The denoised render's metrics.
    pub denoised: Metrics,
}

/// One scene's results.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SceneResult {
    /// The ETRT report.
    pub etrt: EtrtReport,
    /// The spp sweep.
    pub sweep: Vec<SweepPoint>,
}

/// Runs the pipeline at every count of [`SPP_LADDER`] on `view` and scores the raw and the
/// denoised image against `reference`.
pub fn spp_sweep(
    view: &SceneView,
    denoiser: &Denoiser,
    o: &EtrtOptions,
    reference: &HdrImage,
) -> Result<Vec<SweepPoint>, BenchError> {
    let pipeline = Pipeline::new(view, RenderSettings::new(o.width, o.height).seed(o.seed)).denoise(denoiser);
    let mut out = vec![];
    for spp in SPP_LADDER {
        let run = pipeline.run(Budget::Samples(spp), &Quiet)?;
        let beauty = run.film.beauty();
        let denoised = run.denoised.as_ref().unwrap_or(&beauty);
        out.push(SweepPoint {
            spp,
            render_s: run.timings.render_s,
            pipeline_s: run.timings.pipeline_s(),
            raw: metrics(&beauty, reference, METRIC_BORDER),
            denoised: metrics(denoised, reference, METRIC_BORDER),
        });
    }
    Ok(out)
}

/// Runs ETRT and the sweep on every scene, writing per-scene reports under `dir/<stem>/` and
/// `summary.md`, `summary.json`, `error-vs-time.png` and `sweep.png` in `dir`.
pub fn run_suite(
    scenes: &[PathBuf],
    denoiser: &Denoiser,
    o: &EtrtOptions,
    dir: &Path,
    progress: &dyn Progress,
) -> Result<Vec<SceneResult>, BenchError> {
    let mut results = vec![];
    for scene_path in scenes {
        if progress.cancelled() {
            break;
        }
        let view = SceneView::load(scene_path, &CameraChoice::Default, None)?;
        for w in &view.warnings {
            progress.note(&format!("{}: {w}", scene_path.display()));
        }
        let (report, images) = run_etrt(&view, denoiser, o, None, &dir.join("cache"), progress)?;
        write_etrt(&dir.join(view.name()), &report, &images)?;
        let sweep = spp_sweep(&view, denoiser, o, &images.reference)?;
        results.push(SceneResult { etrt: report, sweep });
        // Summaries are rewritten after every scene, so an interrupted suite keeps finished work.
        write_summary(dir, &results)?;
    }
    Ok(results)
}

fn write_summary(dir: &Path, results: &[SceneResult]) -> Result<(), BenchError> {
    write_json(&dir.join("summary.json"), &results)?;
    write_text(&dir.join("summary.md"), &summary_markdown(results))?;
    let reports: Vec<EtrtReport> = results.iter().map(|r| r.etrt.clone()).collect();
    crate::figures::error_plot(&dir.join("error-vs-time.png"), &reports)?;
    let mut chart = Chart::new("spp sweep 1-64: raw against denoised", "wall time (s)", "relMSE against the reference")
        .log(true, true);
    for r in results {
        let name = crate::figures::scene_name(&r.etrt.scene);
        chart
            .series
            .push(Series::line(format!("{name}: raw"), r.sweep.iter().map(|p| (p.render_s, p.raw.relmse)).collect()));
        chart.series.push(Series::line(
            format!("{name}: denoised"),
            r.sweep.iter().map(|p| (p.pipeline_s, p.denoised.relmse)).collect(),
        ));
    }
    write_charts(&dir.join("sweep.png"), &[chart])?;
    Ok(())
}

/// The summary table.
pub fn summary_markdown(results: &[SceneResult]) -> String {
    let mut s = String::from("| scene | noisy PSNR | rtd PSNR | ETRT PSNR (spp) | filter PSNR | no-guide PSNR | rtd relMSE | ETRT relMSE | speed-up | time saved |\n|---|---|---|---|---|---|---|---|---|---|\n");
    for r in results {
        let e = &r.etrt;
        let i = &e.images;
        let (np, dp, dr) = (i.noisy.metrics.psnr, i.denoised.metrics.psnr, i.denoised.metrics.relmse);
        let (ep, er, es) = (i.etrt.metrics.psnr, i.etrt.metrics.relmse, i.etrt.spp);
        let (fp, ap) = (i.filtered.metrics.psnr, i.ablation.metrics.psnr);
        s += &format!(
            "| {} | {np:.2} | {dp:.2} | {ep:.2} ({es}) | {fp:.2} | {ap:.2} | {dr:.4} | {er:.4} | {:.1}×{} | {:.1}% |\n",
            Path::new(&e.scene).file_name().and_then(|n| n.to_str()).unwrap_or("?"),
            e.speedup,
            if e.time_to_quality_extrapolated { " (extrap.)" } else { "" },
            e.pipeline_time_saved_percent
        );
    }
    s += "\nspp sweep, PSNR raw → denoised (dB):\n\n| scene |";
    for spp in SPP_LADDER {
        s += &format!(" {spp} |");
    }
    s += "\n|---|";
    s += &"---|".repeat(SPP_LADDER.len());
    s += "\n";
    for r in results {
        s += &format!("| {} |", Path::new(&r.etrt.scene).file_name().and_then(|n| n.to_str()).unwrap_or("?"));
        for p in &r.sweep {
            s += &format!(" {:.1} → {:.1} |", p.raw.psnr, p.denoised.psnr);
        }
        s += "\n";
    }
    s
}
