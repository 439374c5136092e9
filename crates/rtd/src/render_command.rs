//! `rtd render`: load, build, render progressively, write the image and the report.

use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use serde::Serialize;

use rtd_denoise::DenoiseInput;
use rtd_guide::{GuidePass, GuideSettings};
use rtd_image::{HdrImage, ImageFormat, Tonemap};
use rtd_render::{Film, PathTracer, RenderScene, RenderSettings, RenderStats};
use rtd_scene::{Camera, Environment, Scene};

use crate::args::{RenderArgs, TonemapArg, ViewArgs};
use crate::progress::{bar, interrupt_flag, BarObserver};

/// What `rtd render --report` writes.
#[derive(Debug, Clone, Serialize)]
pub struct RenderReport {
    /// Scene file.
    pub scene: String,
    /// Output file.
    pub output: String,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel reached.
    pub spp: u32,
    /// Seed.
    pub seed: u64,
    /// Maximum depth.
    pub max_depth: u32,
    /// Camera used.
    pub camera: String,
    /// Scene loading seconds.
    pub load_s: f64,
    /// BVH build seconds.
    pub bvh_s: f64,
    /// Rendering seconds.
    pub render_s: f64,
    /// Camera paths per second.
    pub paths_per_s: f64,
    /// Rays (closest-hit and shadow) per second.
    pub rays_per_s: f64,
    /// Mean rays per path.
    pub rays_per_path: f64,
    /// Samples dropped as NaN/Inf (counted as black).
    pub nonfinite_samples: u64,
    /// Triangles rendered.
    pub triangles: usize,
    /// Emissive triangles.
    pub emissive_triangles: usize,
    /// Lights in the light set (emissive triangles, punctual lights, environment).
    pub lights: usize,
    /// Triangles dropped at load (NaN or degenerate).
    pub skipped_triangles: usize,
    /// Load warnings.
    pub warnings: Vec<String>,
    /// True if Ctrl-C stopped the render early (the image holds the finished passes).
    pub interrupted: bool,
    /// Guide-pass seconds (with `--aov`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub guide_s: Option<f64>,
    /// Denoiser seconds (with --denoise).
    pub denoise_s: Option<f64>,
    /// The denoiser model used (with --denoise).
    pub denoise_model: Option<String>,
    /// The denoiser's self-ensemble passes (with --denoise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub denoise_passes: Option<usize>,
}

/// Fails early, before any rendering, if `path` cannot be written as an image.
pub fn check_output(path: &Path) -> anyhow::Result<ImageFormat> {
    let format = ImageFormat::from_path(path)?;
    let dir = existing_dir(path, "output")?;
    if path.is_dir() {
        bail!("{}: is a directory", path.display());
    }
    tempfile::Builder::new()
        .prefix(".rtd-check-")
        .tempfile_in(dir)
        .with_context(|| format!("{}: output directory is not writable", path.display()))?;
    Ok(format)
}

/// Loads a scene and applies the environment argument.
pub fn load_scene(path: &Path, env: Option<&str>) -> anyhow::Result<Scene> {
    if !path.exists() {
        bail!("{}: no such file", path.display());
    }
    let mut scene = rtd_scene::load_scene(path)?;
    if let Some(env) = env {
        scene.environment = Environment::parse(env)?;
    }
    Ok(scene)
}

/// Chooses the camera from `--look-from/--look-at/--fov` or `--camera`, warning if automatic.
pub fn choose_camera(scene: &Scene, args: &ViewArgs) -> anyhow::Result<(Camera, Option<String>)> {
    if let (Some(from), Some(at)) = (args.look_from, args.look_at) {
        if from == at {
            bail!("--look-from and --look-at are the same point");
        }
        return Ok((Camera::look_at(from, at, args.fov), None));
    }
    scene.select_camera(args.camera.as_deref()).map_err(|e| anyhow::anyhow!("{}: {e}", args.scene.display()))
}

/// Writes the film as EXR (all layers, plus the guide pass's if given) or as a tonemapped
/// 8-bit image.
pub fn write_film(
    path: &Path,
    film: &Film,
    guide: Option<&GuidePass>,
    denoised: Option<&HdrImage>,
    exposure: f32,
    tonemap: TonemapArg,
) -> anyhow::Result<()> {
    match ImageFormat::from_path(path)? {
        ImageFormat::Exr => {
            let mut layers = film.layers();
            if let Some(g) = guide {
                g.add_to(&mut layers);
            }
            if let Some(d) = denoised {
                layers.push_rgb("noisy", &film.beauty());
                layers.push_rgb("", d);
            }
            rtd_image::write_exr(path, &layers)?
        }
        _ => {
            let t = match tonemap {
                TonemapArg::Clamp => Tonemap::Clamp,
                TonemapArg::Aces => Tonemap::Aces,
            };
            rtd_image::write_ldr(path, denoised.unwrap_or(&film.beauty()), exposure, t)?
        }
    }
    Ok(())
}

/// A loaded, prepared scene and the chosen camera, with warnings already printed.
pub struct PreparedView {
    /// Scene, BVH and lights.
    pub scene: RenderScene,
    /// The camera.
    pub camera: Camera,
    /// Seconds spent loading the file.
    pub load_s: f64,
}

/// Loads the scene of `view`, prints its warnings, picks the camera and builds the BVH.
pub fn prepare_view(view: &ViewArgs, env: Option<&str>) -> anyhow::Result<PreparedView> {
    let t_load = Instant::now();
    let scene = load_scene(&view.scene, env)?;
    let load_s = t_load.elapsed().as_secs_f64();
    for w in &scene.warnings {
        eprintln!("rtd: warning: {}: {w}", view.scene.display());
    }
    let (camera, cam_warning) = choose_camera(&scene, view)?;
    if let Some(w) = cam_warning {
        eprintln!("rtd: warning: {}: {w}", view.scene.display());
    }
    if scene.triangles.is_empty() {
        eprintln!("rtd: warning: {}: scene has no triangles", view.scene.display());
    }
    Ok(PreparedView { scene: RenderScene::new(scene), camera, load_s })
}

/// Runs `rtd render` and returns its report.
pub fn render(args: &RenderArgs) -> anyhow::Result<RenderReport> {
    let view = &args.view;
    check_output(&args.output)?;
    if let Some(r) = &args.report {
        check_report_path(r)?;
    }
    // Load the model first: a bad model should fail before minutes of rendering.
    let model = if args.denoise { Some(crate::denoise_command::load_model(&args.denoiser())?) } else { None };
    let PreparedView { scene: prepared, camera, load_s } = prepare_view(view, args.env.as_deref())?;
    if prepared.lights.is_empty() {
        eprintln!("rtd: warning: {}: scene has no lights and no --env; the image will be black", view.scene.display());
    }
    let settings = RenderSettings::new(view.width, view.height)
        .seed(args.seed)
        .max_depth(args.max_depth)
        .clamp(args.clamp)
        .threads(view.threads.map(|t| t as usize));
    let tracer = PathTracer::new(&prepared, camera.clone(), settings)?;
    let mut film = tracer.film();
    let interrupted = interrupt_flag();
    let stats = match args.time {
        Some(secs) => {
            let observer = TimedObserver::new(secs, view.quiet, interrupted.clone());
            let s = tracer.render_for(&mut film, Duration::from_secs_f64(secs), &observer)?;
            observer.bar.finish_and_clear();
            s
        }
        None => {
            let spp = args.spp.unwrap_or(16);
            let observer = BarObserver {
                bar: bar(spp as u64 * view.height as u64, "render", view.quiet),
                interrupted: interrupted.clone(),
            };
            let s = tracer.render_observed(&mut film, spp, &observer)?;
            observer.bar.finish_and_clear();
            s
        }
    };
    let was_interrupted = interrupted.load(std::sync::atomic::Ordering::SeqCst);
    if film.spp == 0 {
        bail!("interrupted before the first pass finished; nothing written");
    }
    let guide = if args.aov || args.denoise {
        let settings = GuideSettings::new(view.width, view.height).threads(view.threads.map(|t| t as usize));
        Some(GuidePass::render(&prepared.scene, &prepared.bvh, &camera, &settings)?)
    } else {
        None
    };
    let mut denoise_s = None;
    let denoised = match (&model, &guide) {
        (Some(model), Some(g)) => {
            let t = Instant::now();
            let beauty = film.beauty();
            let input = DenoiseInput::with_guide_pass(&beauty, g);
            let out = model.denoise(&input)?;
            denoise_s = Some(t.elapsed().as_secs_f64());
            Some(out)
        }
        _ => None,
    };
    write_film(&args.output, &film, guide.as_ref(), denoised.as_ref(), args.exposure, args.tonemap)?;
    let mut report = make_report(args, &prepared, &camera, load_s, &stats, &film, was_interrupted);
    report.guide_s = guide.as_ref().map(|g| g.seconds);
    report.denoise_s = denoise_s;
    report.denoise_model = model.as_ref().map(|m| m.name().to_string());
    report.denoise_passes = model.as_ref().map(|m| m.ensemble_passes());
    crate::print_line(&format!(
        "rendered {} spp at {}x{} in {:.2} s: {:.3} M paths/s, {:.3} M rays/s ({:.1} rays/path), {} non-finite samples{}{}",
        report.spp,
        view.width,
        view.height,
        report.render_s,
        report.paths_per_s / 1e6,
        report.rays_per_s / 1e6,
        report.rays_per_path,
        report.nonfinite_samples,
        guide.as_ref().map(|g| format!(", guide pass {:.3} s", g.seconds)).unwrap_or_default()
            + &denoise_s.map(|d| format!(", denoised in {d:.3} s")).unwrap_or_default(),
        if was_interrupted { " (interrupted: image holds the finished passes)" } else { "" }
    ))?;
    if let Some(path) = &args.report {
        write_json(path, &report)?;
    }
    Ok(report)
}

/// Fails early if the report's directory does not exist.
pub fn check_report_path(path: &Path) -> anyhow::Result<()> {
    existing_dir(path, "report").map(|_| ())
}

/// The directory `path` will be written in, or an error naming it if it does not exist.
fn existing_dir<'p>(path: &'p Path, what: &str) -> anyhow::Result<&'p Path> {
    let dir = rtd_image::parent_dir(path);
    if !dir.is_dir() {
        bail!("{}: {what} directory {} does not exist", path.display(), dir.display());
    }
    Ok(dir)
}

/// Writes any serialisable report as pretty JSON, atomically.
pub fn write_json<T: Serialize>(path: &Path, value: &T) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(value)?;
    rtd_image::write_atomic(path, |w| {
        std::io::Write::write_all(w, text.as_bytes())
            .map_err(|e| rtd_image::ImageError::Io { path: path.to_path_buf(), source: e })
    })?;
    Ok(())
}

fn make_report(
    args: &RenderArgs,
    prepared: &RenderScene,
    camera: &Camera,
    load_s: f64,
    stats: &RenderStats,
    film: &Film,
    interrupted: bool,
) -> RenderReport {
    let scene = &prepared.scene;
    let secs = stats.seconds.max(1e-9);
    RenderReport {
        scene: args.view.scene.display().to_string(),
        output: args.output.display().to_string(),
        width: args.view.width,
        height: args.view.height,
        spp: film.spp,
        seed: args.seed,
        max_depth: args.max_depth,
        camera: camera.name.clone(),
        load_s,
        bvh_s: prepared.bvh_seconds,
        render_s: stats.seconds,
        paths_per_s: stats.paths as f64 / secs,
        rays_per_s: stats.rays as f64 / secs,
        rays_per_path: stats.rays as f64 / stats.paths.max(1) as f64,
        nonfinite_samples: film.nonfinite_samples,
        triangles: scene.triangles.len(),
        emissive_triangles: scene.emissive_triangle_count(),
        lights: prepared.lights.len(),
        skipped_triangles: scene.skipped_degenerate + scene.skipped_nonfinite,
        warnings: scene.warnings.clone(),
        interrupted,
        guide_s: None,
        denoise_s: None,
        denoise_model: None,
        denoise_passes: None,
    }
}

/// Progress for `--time`: the bar tracks elapsed time against the budget.
struct TimedObserver {
    bar: indicatif::ProgressBar,
    start: Instant,
    interrupted: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

impl TimedObserver {
    fn new(secs: f64, quiet: bool, interrupted: std::sync::Arc<std::sync::atomic::AtomicBool>) -> Self {
        TimedObserver { bar: bar((secs * 1000.0) as u64, "render", quiet), start: Instant::now(), interrupted }
    }
}

impl rtd_render::RenderObserver for TimedObserver {
    fn rows_done(&self, _rows: u64) {
        self.bar.set_position(self.start.elapsed().as_millis() as u64);
    }
    fn cancelled(&self) -> bool {
        self.interrupted.load(std::sync::atomic::Ordering::SeqCst)
    }
}
