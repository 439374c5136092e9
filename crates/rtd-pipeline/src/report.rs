//! [`RenderReport`]: what a render did, as `rtd render --report` writes it.

use std::path::Path;

use rtd_denoise::Denoiser;
use rtd_render::RenderSettings;
use serde::Serialize;

use crate::{PipelineRun, SceneView};

/// What a pipeline run did: sizes, sample counts, per-stage seconds, throughput and the scene's
/// counts. Built once from the view, the settings and the run.
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
    /// True if the render was stopped early (the image holds the finished passes).
    pub interrupted: bool,
    /// Guide-pass seconds, when the guide pass ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub guide_s: Option<f64>,
    /// Denoiser seconds, when denoised.
    pub denoise_s: Option<f64>,
    /// The denoiser model used, when denoised.
    pub denoise_model: Option<String>,
    /// The denoiser's self-ensemble passes, when denoised.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub denoise_passes: Option<usize>,
}

impl RenderReport {
    /// The report of `run`, made by rendering `view` with `settings` (and `denoiser`, if it
    /// denoised) into `output`.
    pub fn new(
        view: &SceneView,
        settings: &RenderSettings,
        denoiser: Option<&Denoiser>,
        run: &PipelineRun,
        output: &Path,
    ) -> Self {
        let scene = &view.scene.scene;
        let stats = &run.stats;
        let secs = stats.seconds.max(1e-9);
        let denoiser = denoiser.filter(|_| run.denoised.is_some());
        RenderReport {
            scene: view.path.display().to_string(),
            output: output.display().to_string(),
            width: settings.width,
            height: settings.height,
            spp: run.film.spp,
            seed: settings.seed,
            max_depth: settings.max_depth,
            camera: view.camera.name.clone(),
            load_s: run.timings.load_s,
            bvh_s: run.timings.bvh_s,
            render_s: run.timings.render_s,
            paths_per_s: stats.paths as f64 / secs,
            rays_per_s: stats.rays as f64 / secs,
            rays_per_path: stats.rays as f64 / stats.paths.max(1) as f64,
            nonfinite_samples: run.film.nonfinite_samples,
            triangles: scene.triangles.len(),
            emissive_triangles: scene.emissive_triangle_count(),
            lights: view.scene.lights.len(),
            skipped_triangles: scene.skipped_degenerate + scene.skipped_nonfinite,
            warnings: scene.warnings.clone(),
            interrupted: run.interrupted,
            guide_s: run.timings.guide_s,
            denoise_s: run.timings.denoise_s,
            denoise_model: denoiser.map(|d| d.name().to_string()),
            denoise_passes: denoiser.map(|d| d.ensemble_passes()),
        }
    }

    /// The one-line summary `rtd render` prints.
    pub fn summary(&self) -> String {
        format!(
            "rendered {} spp at {}x{} in {:.2} s: {:.3} M paths/s, {:.3} M rays/s ({:.1} rays/path), {} non-finite samples{}{}{}",
            self.spp,
            self.width,
            self.height,
            self.render_s,
            self.paths_per_s / 1e6,
            self.rays_per_s / 1e6,
            self.rays_per_path,
            self.nonfinite_samples,
            self.guide_s.map(|g| format!(", guide pass {g:.3} s")).unwrap_or_default(),
            self.denoise_s.map(|d| format!(", denoised in {d:.3} s")).unwrap_or_default(),
            if self.interrupted { " (interrupted: image holds the finished passes)" } else { "" }
        )
    }
}
