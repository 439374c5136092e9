//! `rtd bench suite`: ETRT over several scenes plus the spp sweep (1–64 spp, raw against
//! denoised, error against time): the speed/accuracy trade curve, with a summary table.

use std::path::{Path, PathBuf};
use std::time::Instant;

use rtd_denoise::{DenoiseInput, Denoiser};
use rtd_guide::{GuidePass, GuideSettings};
use rtd_image::metrics::{metrics, Metrics};
use rtd_image::plot::{write_charts, Chart, Series};
use rtd_render::{PathTracer, RenderScene, RenderSettings};
use serde::{Deserialize, Serialize};

use crate::etrt::{load_with_camera, run_etrt_on, write_etrt, write_text, EtrtOptions, EtrtReport, CROP};
use crate::{BenchError, Progress};

/// The sweep's sample counts.
pub const SWEEP_SPP: [u32; 7] = [1, 2, 4, 8, 16, 32, 64];

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

/// Renders the sweep for one scene against `reference`.
pub fn spp_sweep(
    rs: &RenderScene,
    cam: &rtd_scene::Camera,
    denoiser: &Denoiser,
    o: &EtrtOptions,
    reference: &rtd_image::HdrImage,
) -> Result<Vec<SweepPoint>, BenchError> {
    let guide = GuidePass::render(&rs.scene, &rs.bvh, cam, &GuideSettings::new(o.width, o.height))?;
    let mut out = vec![];
    for spp in SWEEP_SPP {
        let tracer = PathTracer::new(rs, cam.clone(), RenderSettings::new(o.width, o.height).seed(o.seed))?;
        let mut film = tracer.film();
        let stats = tracer.render(&mut film, spp)?;
        let noisy = film.beauty();
        let t = Instant::now();
        let input = DenoiseInput::with_guide_pass(&noisy, &guide);
        let denoised = denoiser.denoise(&input)?;
        let denoise_s = t.elapsed().as_secs_f64();
        out.push(SweepPoint {
            spp,
            render_s: stats.seconds,
            pipeline_s: stats.seconds + guide.seconds + denoise_s,
            raw: metrics(&noisy, reference, CROP),
            denoised: metrics(&denoised, reference, CROP),
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
        let stem = scene_path.file_stem().and_then(|s| s.to_str()).unwrap_or("scene").to_string();
        let sub = dir.join(&stem);
        let cache = dir.join("cache");
        let (rs, cam) = load_with_camera(scene_path)?;
        let (report, images) = run_etrt_on(scene_path, &rs, &cam, denoiser, o, None, &cache, progress)?;
        write_etrt(&sub, &report, &images)?;
        let sweep = spp_sweep(&rs, &cam, denoiser, o, &images.reference)?;
        results.push(SceneResult { etrt: report, sweep });
        // Summaries are rewritten after every scene, so an interrupted suite keeps finished work.
        write_summary(dir, &results)?;
    }
    Ok(results)
}

fn write_summary(dir: &Path, results: &[SceneResult]) -> Result<(), BenchError> {
    let json = dir.join("summary.json");
    let text = serde_json::to_vec_pretty(results).map_err(|e| BenchError::msg(&json, e.to_string()))?;
    write_text(&json, &text)?;
    write_text(&dir.join("summary.md"), summary_markdown(results).as_bytes())?;
    let reports: Vec<EtrtReport> = results.iter().map(|r| r.etrt.clone()).collect();
    crate::figures::error_plot(&dir.join("error-vs-time.png"), &reports)?;
    let mut series = vec![];
    for r in results {
        let name = Path::new(&r.etrt.scene).file_stem().and_then(|s| s.to_str()).unwrap_or("scene").to_string();
        series.push(Series::line(
            format!("{name}: raw"),
            r.sweep.iter().map(|p| (p.render_s, p.raw.relmse.log10())).collect(),
        ));
        series.push(Series::line(
            format!("{name}: denoised"),
            r.sweep.iter().map(|p| (p.pipeline_s, p.denoised.relmse.log10())).collect(),
        ));
    }
    let chart = Chart {
        title: "spp sweep 1-64: raw vs denoised".into(),
        x_label: "seconds (log)".into(),
        y_label: "log10 relMSE".into(),
        log_x: true,
        series,
    };
    write_charts(&dir.join("sweep.png"), &[chart])?;
    Ok(())
}

/// The summary table.
pub fn summary_markdown(results: &[SceneResult]) -> String {
    let mut s = String::from("| scene | noisy PSNR | rtd PSNR | ETRT PSNR (spp) | filter PSNR | no-guide PSNR | rtd relMSE | ETRT relMSE | speed-up | time saved |\n|---|---|---|---|---|---|---|---|---|---|\n");
    for r in results {
        let e = &r.etrt;
        let g =
            |n: &str| e.image(n).map(|i| (i.metrics.psnr, i.metrics.relmse, i.spp)).unwrap_or((f64::NAN, f64::NAN, 0));
        let (np, _, _) = g("noisy");
        let (dp, dr, _) = g("rtd denoised");
        let (ep, er, es) = g("ETRT (equal time)");
        let (fp, _, _) = g("guided filter");
        let (ap, _, _) = g("ablation: noisy as guide");
        s += &format!(
            "| {} | {np:.2} | {dp:.2} | {ep:.2} ({es}) | {fp:.2} | {ap:.2} | {dr:.4} | {er:.4} | {:.1}×{} | {:.1}% |\n",
            Path::new(&e.scene).file_name().and_then(|n| n.to_str()).unwrap_or("?"),
            e.speedup,
            if e.time_to_quality_extrapolated { " (extrap.)" } else { "" },
            e.pipeline_time_saved_percent
        );
    }
    s += "\nspp sweep, PSNR raw → denoised (dB):\n\n| scene |";
    for spp in SWEEP_SPP {
        s += &format!(" {spp} |");
    }
    s += "\n|---|";
    s += &"---|".repeat(SWEEP_SPP.len());
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
