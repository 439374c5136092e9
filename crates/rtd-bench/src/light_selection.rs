//! `rtd bench lights`: the light tree against power-proportional light selection at equal
//! time. Each strategy renders the scene for the same wall time; both are scored against one
//! reference (rendered with the tree, whose expectation is the same image), so the figure is
//! the noise each leaves, and the spp it reached.

use std::time::Duration;

use rtd_image::metrics::{metrics, Metrics};
use rtd_image::Quiet;
use rtd_render::{LightSelection, PathTracer, RenderScene, RenderSettings};
use rtd_scene::{Camera, Scene};
use serde::{Deserialize, Serialize};

use crate::{BenchError, METRIC_BORDER};

/// One strategy's equal-time result.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SelectionResult {
    /// `tree` or `power`.
    pub selection: String,
    /// Samples per pixel reached in the time.
    pub spp: u32,
    /// Seconds rendered.
    pub seconds: f64,
    /// Scores against the reference.
    pub metrics: Metrics,
}

/// The comparison on one scene.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct LightSelectionReport {
    /// Emissive triangles and punctual lights in the scene.
    pub lights: usize,
    /// Image width and height.
    pub size: (u32, u32),
    /// Reference samples per pixel.
    pub reference_spp: u32,
    /// Seconds each strategy rendered for.
    pub seconds: f64,
    /// The results, tree first.
    pub results: Vec<SelectionResult>,
}

impl LightSelectionReport {
    /// relMSE of power selection over the tree's: how much more noise power selection leaves.
    pub fn noise_ratio(&self) -> f64 {
        self.results[1].metrics.relmse / self.results[0].metrics.relmse
    }

    /// The report as a Markdown table.
    pub fn markdown(&self) -> String {
        let mut md = format!(
            "{} lights, {}x{}, {:.1} s each, reference {} spp (tree)\n\n| selection | spp reached | relMSE | PSNR (dB) |\n|---|---|---|---|\n",
            self.lights, self.size.0, self.size.1, self.seconds, self.reference_spp
        );
        for r in &self.results {
            md += &format!("| {} | {} | {:.5} | {:.2} |\n", r.selection, r.spp, r.metrics.relmse, r.metrics.psnr);
        }
        md + &format!("\nPower selection leaves {:.2}× the tree's relMSE at equal time.\n", self.noise_ratio())
    }
}

/// Renders `scene` through `camera` at `size` for `seconds` with each strategy and scores both
/// against a `reference_spp` render.
pub fn compare_light_selection(
    scene: &Scene,
    camera: &Camera,
    size: (u32, u32),
    seconds: f64,
    reference_spp: u32,
) -> Result<LightSelectionReport, BenchError> {
    let settings = |seed| RenderSettings::new(size.0, size.1).seed(seed);
    let tree = RenderScene::with_light_selection(scene.clone(), LightSelection::Tree);
    let reference = {
        let tracer = PathTracer::new(&tree, camera.clone(), settings(1000))?;
        let mut film = tracer.film();
        tracer.render(&mut film, reference_spp)?;
        film.beauty()
    };
    let mut results = vec![];
    for (name, selection) in [("tree", LightSelection::Tree), ("power", LightSelection::Power)] {
        let prepared = RenderScene::with_light_selection(scene.clone(), selection);
        let tracer = PathTracer::new(&prepared, camera.clone(), settings(1))?;
        let mut film = tracer.film();
        let stats = tracer.render_for(&mut film, Duration::from_secs_f64(seconds), &Quiet)?;
        results.push(SelectionResult {
            selection: name.into(),
            spp: stats.spp,
            seconds: stats.seconds,
            metrics: metrics(&film.beauty(), &reference, METRIC_BORDER),
        });
    }
    let lights = scene.emissive_triangle_count() + scene.lights.len();
    Ok(LightSelectionReport { lights, size, reference_spp, seconds, results })
}
