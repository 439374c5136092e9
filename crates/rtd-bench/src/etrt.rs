//! `rtd bench etrt`: the seed thesis's equal-time ray-trace comparison. The rtd pipeline
//! (render at low spp, guide pass, denoiser) is timed; the same render then continues for the
//! wall time the guide and denoiser took (ETRT), and on until its error matches the denoised
//! image's (time-to-quality, extrapolated from the error-versus-time curve when that would
//! take too long). Every image is scored against a reference with the same metric code.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use rtd_denoise::filter::GuidedFilter;
use rtd_denoise::{DenoiseInput, Denoiser};
use rtd_guide::{GuidePass, GuideSettings};
use rtd_image::metrics::{metrics, Metrics};
use rtd_image::{HdrImage, Layers};
use rtd_render::{PathTracer, RenderScene, RenderSettings, Silent};
use rtd_scene::Camera;
use serde::{Deserialize, Serialize};

use crate::{BenchError, Progress};

/// Border excluded from every metric.
pub const CROP: u32 = 8;

/// Options, builder style.
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
    /// Reference spp when rendering one.
    pub reference_spp: u32,
    /// Longest plain rendering for time-to-quality, as a multiple of the pipeline's time;
    /// beyond it the time is extrapolated.
    pub max_plain_factor: f64,
}

impl Default for EtrtOptions {
    fn default() -> Self {
        EtrtOptions { spp: 8, width: 256, height: 256, seed: 0, reference_spp: 1024, max_plain_factor: 16.0 }
    }
}

/// One scored image.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Scored {
    /// What it is.
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
    /// Options.
    pub options: EtrtOptions,
    /// Reference spp and where it came from.
    pub reference: String,
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
    /// noisy, rtd denoised, ETRT, ablation (noisy as guide), guided filter.
    pub images: Vec<Scored>,
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

    /// The scored image by name.
    pub fn image(&self, name: &str) -> Option<&Scored> {
        self.images.iter().find(|s| s.name == name)
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

pub(crate) fn render_spp(
    rs: &RenderScene,
    cam: &rtd_scene::Camera,
    o: &EtrtOptions,
    seed: u64,
    spp: u32,
) -> Result<HdrImage, BenchError> {
    let tracer = PathTracer::new(rs, cam.clone(), RenderSettings::new(o.width, o.height).seed(seed))?;
    let mut film = tracer.film();
    tracer.render(&mut film, spp)?;
    Ok(film.beauty())
}

/// Loads `given` or renders a reference (two independent halves, cached in `cache_dir` under a key
/// of scene bytes, size, spp and rtd version). Returns (image, description, noise estimate).
pub fn reference(
    rs: &RenderScene,
    cam: &rtd_scene::Camera,
    scene: &Path,
    o: &EtrtOptions,
    given: Option<&Path>,
    cache_dir: &Path,
    progress: &dyn Progress,
) -> Result<(HdrImage, String, Option<f64>), BenchError> {
    if let Some(p) = given {
        let l = rtd_image::read_exr(p)?;
        let img = l.rgb("").ok_or_else(|| BenchError::msg(p, "no R,G,B channels"))?;
        if (img.width, img.height) != (o.width, o.height) {
            return Err(BenchError::msg(
                p,
                format!("reference is {}x{}, the benchmark renders {}x{}", img.width, img.height, o.width, o.height),
            ));
        }
        return Ok((img, format!("loaded from {}", p.display()), None));
    }
    let bytes = std::fs::read(scene).map_err(|e| BenchError::io(scene, e))?;
    // FNV-1a over everything the reference depends on.
    let mut key = 0xcbf2_9ce4_8422_2325u64;
    for b in bytes
        .iter()
        .chain(format!("{}x{}x{}x{}", o.width, o.height, o.reference_spp, env!("CARGO_PKG_VERSION")).as_bytes())
    {
        key = (key ^ *b as u64).wrapping_mul(0x100_0000_01b3);
    }
    let path = cache_dir.join(format!("reference-{key:016x}.exr"));
    if let Ok(l) = rtd_image::read_exr(&path) {
        if let (Some(img), Some(noise)) = (l.rgb(""), l.get("noise.Y")) {
            return Ok((img, format!("{} spp, cached {}", o.reference_spp, path.display()), Some(noise[0] as f64)));
        }
    }
    progress.note(&format!("rendering a {} spp reference (cached afterwards)", o.reference_spp));
    let a = render_spp(rs, cam, o, o.seed ^ 0xA5A5_0001, o.reference_spp / 2)?;
    let b = render_spp(rs, cam, o, o.seed ^ 0x5A5A_0002, o.reference_spp / 2)?;
    let (img, noise_relmse) = rtd_image::metrics::mean_of_halves_with_noise(&a, &b);
    std::fs::create_dir_all(cache_dir).map_err(|e| BenchError::io(cache_dir, e))?;
    let mut layers = Layers::new(o.width, o.height);
    layers.push_rgb("", &img);
    layers.push("noise.Y", vec![noise_relmse as f32; (o.width * o.height) as usize]);
    rtd_image::write_exr(&path, &layers)?;
    Ok((img, format!("{} spp, rendered and cached {}", o.reference_spp, path.display()), Some(noise_relmse)))
}

/// Loads `scene_path`, builds its BVH and picks its first camera.
pub fn load_with_camera(scene_path: &Path) -> Result<(RenderScene, Camera), BenchError> {
    let scene = rtd_scene::load_scene(scene_path)?;
    let (cam, _) = scene.select_camera(None).map_err(|e| BenchError::msg(scene_path, e))?;
    Ok((RenderScene::new(scene), cam))
}

/// Runs the whole comparison on `scene` (its first camera).
pub fn run_etrt(
    scene_path: &Path,
    denoiser: &Denoiser,
    options: &EtrtOptions,
    given_reference: Option<&Path>,
    cache_dir: &Path,
    progress: &dyn Progress,
) -> Result<(EtrtReport, EtrtImages), BenchError> {
    let (rs, cam) = load_with_camera(scene_path)?;
    run_etrt_on(scene_path, &rs, &cam, denoiser, options, given_reference, cache_dir, progress)
}

/// [`run_etrt`] on an already loaded scene (`scene_path` names it and keys the reference cache).
#[allow(clippy::too_many_arguments)]
pub fn run_etrt_on(
    scene_path: &Path,
    rs: &RenderScene,
    cam: &Camera,
    denoiser: &Denoiser,
    options: &EtrtOptions,
    given_reference: Option<&Path>,
    cache_dir: &Path,
    progress: &dyn Progress,
) -> Result<(EtrtReport, EtrtImages), BenchError> {
    let o = options;
    progress.start(6, "etrt");
    let (reference, reference_desc, reference_relmse) =
        reference(rs, cam, scene_path, o, given_reference, cache_dir, progress)?;
    progress.inc(1);
    // The rtd pipeline, timed part by part.
    let tracer = PathTracer::new(rs, cam.clone(), RenderSettings::new(o.width, o.height).seed(o.seed))?;
    let mut film = tracer.film();
    let t = Instant::now();
    tracer.render(&mut film, o.spp)?;
    let render_s = t.elapsed().as_secs_f64();
    let noisy = film.beauty();
    let guide = GuidePass::render(&rs.scene, &rs.bvh, cam, &GuideSettings::new(o.width, o.height))?;
    let t = Instant::now();
    let input = DenoiseInput::with_guide_pass(&noisy, &guide);
    let denoised = denoiser.denoise(&input)?;
    let denoise_s = t.elapsed().as_secs_f64();
    let pipeline_s = render_s + guide.seconds + denoise_s;
    progress.inc(1);
    // ETRT: the same render continues for the guide + denoise time.
    let extra = tracer.render_for(&mut film, Duration::from_secs_f64(guide.seconds + denoise_s), &Silent)?;
    let etrt = film.beauty();
    progress.inc(1);
    // Equal-sample baselines.
    let ablation = denoiser.denoise(&DenoiseInput::new(&noisy, &noisy))?;
    let filtered = GuidedFilter::default().filter(&input)?;
    progress.inc(1);
    let score = |name: &str, spp: u32, seconds: f64, img: &HdrImage| Scored {
        name: name.into(),
        spp,
        seconds,
        metrics: metrics(img, &reference, CROP),
    };
    let images = vec![
        score("noisy", o.spp, render_s, &noisy),
        score("rtd denoised", o.spp, pipeline_s, &denoised),
        score("ETRT (equal time)", film.spp, render_s + extra.seconds, &etrt),
        score("ablation: noisy as guide", o.spp, pipeline_s, &ablation),
        score("guided filter", o.spp, render_s + guide.seconds, &filtered),
    ];
    // Time-to-quality: keep rendering, doubling the spp, until plain matches the denoised relMSE.
    let target = images[1].metrics.relmse;
    let mut curve = vec![
        (render_s, o.spp, images[0].metrics.relmse, images[0].metrics.psnr),
        (render_s + extra.seconds, film.spp, images[2].metrics.relmse, images[2].metrics.psnr),
    ];
    let mut plain_s = render_s + extra.seconds;
    let mut reached = None;
    while plain_s < pipeline_s * o.max_plain_factor && !progress.cancelled() {
        if images[2].metrics.relmse <= target && reached.is_none() {
            reached = Some(plain_s);
            break;
        }
        let more = film.spp.max(1);
        let stats = tracer.render(&mut film, more)?;
        plain_s += stats.seconds;
        let m = metrics(&film.beauty(), &reference, CROP);
        curve.push((plain_s, film.spp, m.relmse, m.psnr));
        if m.relmse <= target {
            // Interpolate in log-log between the last two points.
            let (t0, e0) = (curve[curve.len() - 2].0, curve[curve.len() - 2].2);
            let f = ((e0 / target).ln() / (e0 / m.relmse).ln()).clamp(0.0, 1.0);
            reached = Some((t0.ln() + f * (plain_s.ln() - t0.ln())).exp());
            break;
        }
    }
    progress.inc(1);
    let (time_to_quality_s, extrapolated) = match reached {
        Some(t) => (t, false),
        None => {
            // MSE ∝ 1/time for an unbiased estimator: fit the constant on the last point.
            let (t1, _, e1, _) = *curve.last().expect("curve has points");
            (t1 * e1 / target.max(1e-12), true)
        }
    };
    let report = EtrtReport {
        scene: scene_path.display().to_string(),
        options: o.clone(),
        reference: reference_desc,
        reference_relmse,
        render_s,
        guide_s: guide.seconds,
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
    Ok((report, EtrtImages { noisy, denoised, etrt, reference }))
}

/// Writes `report.json`, `report.md`, `side-by-side.png` and `error-vs-time.png` into `dir`.
pub fn write_etrt(dir: &Path, report: &EtrtReport, images: &EtrtImages) -> Result<Vec<PathBuf>, BenchError> {
    std::fs::create_dir_all(dir).map_err(|e| BenchError::io(dir, e))?;
    let json = dir.join("report.json");
    let text = serde_json::to_vec_pretty(report).map_err(|e| BenchError::msg(&json, e.to_string()))?;
    write_text(&json, &text)?;
    let md = dir.join("report.md");
    write_text(&md, report.markdown().as_bytes())?;
    let side = dir.join("side-by-side.png");
    crate::figures::side_by_side(&side, images)?;
    let plot = dir.join("error-vs-time.png");
    crate::figures::error_plot(&plot, std::slice::from_ref(report))?;
    Ok(vec![json, md, side, plot])
}

/// Writes bytes atomically.
pub fn write_text(path: &Path, bytes: &[u8]) -> Result<(), BenchError> {
    rtd_image::write_atomic(path, |w| {
        std::io::Write::write_all(w, bytes).map_err(|e| rtd_image::ImageError::io(path, e))
    })?;
    Ok(())
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
        for i in &self.images {
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
