//! `rtd datagen`: renders the training set. For every view of every generated scene it writes
//! one EXR holding the noisy beauty at several sample counts (independent seeds), the guide
//! pass and a high-spp reference, and records the view in `manifest.json`. Finished views are
//! kept, so an interrupted run resumes where it stopped.
//!
//! The views can also be rendered elsewhere, a scene at a time ([`render_shard`]), and added
//! to the dataset as they arrive ([`Manifest::add_shard`]): the dataset is then the same files
//! and the same manifest (but for its wall-clock `seconds`) as the one-machine run.

mod shard;
mod view_render;

use std::path::{Path, PathBuf};

use rtd_guide::{GuidePass, GuideSettings};
use rtd_render::{RenderScene, SPP_LADDER};
use serde::{Deserialize, Serialize};

pub use shard::{render_shard, SceneShard};
pub use view_render::{scene_name, view_file, write_scene, DatasetScene, RenderedView, ViewRender};

use crate::scenegen::Layout;
use crate::{Progress, TrainError};

/// Options for [`generate_dataset`]: start from [`DatasetOptions::default`] and change fields
/// with the chained setters below.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct DatasetOptions {
    /// Master seed: scenes, cameras and render seeds derive from it.
    pub seed: u64,
    /// Number of scenes.
    pub scenes: u64,
    /// Views (cameras) per scene.
    pub views_per_scene: usize,
    /// Image width and height.
    pub size: u32,
    /// Reference samples per pixel (at least); doubled once for views whose estimated
    /// reference noise stays above `reference_relmse`.
    pub reference_spp: u32,
    /// Target for the reference's estimated remaining relMSE.
    pub reference_relmse: f64,
    /// Every `validation_every`-th scene (by index) is held out for validation.
    pub validation_every: u64,
    /// Which scenes are rendered: all of them, or only the training or validation ones (each
    /// scene and its renders are the same whichever split makes it).
    #[serde(default)]
    pub split: Split,
}

/// A subset of a dataset's scenes.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, PartialEq, Eq)]
pub enum Split {
    /// Every scene.
    #[default]
    All,
    /// Only the scenes used for training.
    Training,
    /// Only the held-out scenes: enough to score a model, in about a sixth of the time.
    Validation,
}

impl Default for DatasetOptions {
    fn default() -> Self {
        DatasetOptions {
            seed: 1,
            scenes: 28,
            views_per_scene: 2,
            size: 96,
            reference_spp: 1024,
            reference_relmse: 1e-3,
            validation_every: 6,
            split: Split::All,
        }
    }
}

impl DatasetOptions {
    /// Sets the seed.
    pub fn seed(mut self, s: u64) -> Self {
        self.seed = s;
        self
    }
    /// Sets the number of scenes.
    pub fn scenes(mut self, n: u64) -> Self {
        self.scenes = n;
        self
    }
    /// Sets the image size.
    pub fn size(mut self, s: u32) -> Self {
        self.size = s;
        self
    }
    /// Sets the reference spp.
    pub fn reference_spp(mut self, s: u32) -> Self {
        self.reference_spp = s;
        self
    }
    /// Sets how often a scene is held out (every n-th).
    pub fn validation_every(mut self, n: u64) -> Self {
        self.validation_every = n.max(1);
        self
    }
    /// Sets the views per scene.
    pub fn views_per_scene(mut self, v: usize) -> Self {
        self.views_per_scene = v;
        self
    }
    /// Renders only the scenes of `split`.
    pub fn split(mut self, split: Split) -> Self {
        self.split = split;
        self
    }

    /// True when scene `index` is held out for validation.
    pub fn is_validation(&self, index: u64) -> bool {
        index % self.validation_every == self.validation_every - 1
    }

    /// The scene indices this dataset renders, in order.
    pub fn scene_indices(&self) -> impl Iterator<Item = u64> + '_ {
        (0..self.scenes).filter(move |&i| match self.split {
            Split::All => true,
            Split::Training => !self.is_validation(i),
            Split::Validation => self.is_validation(i),
        })
    }
}

/// One rendered view in the manifest.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ViewRecord {
    /// File name of the view's EXR, relative to the dataset directory.
    pub file: String,
    /// Scene index.
    pub scene: u64,
    /// Camera index within the scene.
    pub view: usize,
    /// The scene's layout.
    pub layout: Layout,
    /// True when held out for validation.
    pub validation: bool,
    /// Reference samples per pixel actually rendered.
    pub reference_spp: u32,
    /// Estimated relMSE remaining in the reference (from two independent halves).
    pub reference_relmse: f64,
    /// Seconds spent rendering this view.
    pub seconds: f64,
}

/// The dataset index written beside the views.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Manifest {
    /// The options that made it.
    pub options: DatasetOptions,
    /// Noisy spp levels stored per view (`noisyN.R/G/B`).
    pub noisy_spp: Vec<u32>,
    /// Finished views.
    pub views: Vec<ViewRecord>,
    /// Views rejected as black or empty, as "scene/view".
    pub rejected: Vec<String>,
}

impl Manifest {
    /// Reads `dir/manifest.json`.
    pub fn load(dir: &Path) -> Result<Manifest, TrainError> {
        let path = dir.join("manifest.json");
        let text = std::fs::read_to_string(&path).map_err(|e| TrainError::io(&path, e))?;
        serde_json::from_str(&text).map_err(|e| TrainError::msg(&path, format!("not a dataset manifest: {e}")))
    }

    /// Writes `dir/manifest.json` atomically, its views and rejections in (scene, view) order
    /// whatever order they were rendered in.
    fn save(&mut self, dir: &Path) -> Result<(), TrainError> {
        self.views.sort_by_key(|r| (r.scene, r.view));
        self.rejected.sort_by_key(|k| parse_view_key(k));
        let path = dir.join("manifest.json");
        let text = serde_json::to_vec_pretty(self).map_err(|e| TrainError::msg(&path, e.to_string()))?;
        Ok(rtd_image::write_bytes_atomic(&path, &text)?)
    }

    /// The manifest to continue in `dir`: the one there if `options` made it, or made it with
    /// fewer scenes (it is then extended: scene k is the same whatever the count), a new one if
    /// there is none; a dataset made with any other options is refused. A new one is saved at
    /// once, so `dir` is claimed for `options`.
    pub fn open(dir: &Path, options: &DatasetOptions) -> Result<Manifest, TrainError> {
        rtd_image::create_dir_durably(&dir.join("scenes")).map_err(|e| TrainError::io(dir, e))?;
        match Manifest::load(dir) {
            Ok(m) if m.options == *options => Ok(m),
            Ok(mut m) if m.options.scenes < options.scenes && m.options == options.clone().scenes(m.options.scenes) => {
                m.options.scenes = options.scenes;
                m.save(dir)?;
                Ok(m)
            }
            Ok(_) => Err(TrainError::msg(
                &dir.join("manifest.json"),
                "was made with other options (only --scenes may grow); use a new directory",
            )),
            Err(_) if dir.join("manifest.json").exists() => {
                Err(TrainError::msg(&dir.join("manifest.json"), "is not a dataset manifest; use a new directory"))
            }
            Err(_) => {
                let mut m = Manifest {
                    options: options.clone(),
                    noisy_spp: SPP_LADDER.to_vec(),
                    views: vec![],
                    rejected: vec![],
                };
                m.save(dir)?;
                Ok(m)
            }
        }
    }

    /// True when the manifest has view `view` of scene `scene`, or has rejected it.
    pub fn has_view(&self, scene: u64, view: usize) -> bool {
        let key = format!("{scene}/{view}");
        self.views.iter().any(|r| r.scene == scene && r.view == view) || self.rejected.contains(&key)
    }

    /// The scenes of the dataset with at least one view still to render, in order.
    pub fn scenes_to_render(&self) -> Vec<u64> {
        let views = self.options.views_per_scene;
        self.options.scene_indices().filter(|&s| (0..views).any(|v| !self.has_view(s, v))).collect()
    }

    /// The number of views the finished dataset will have, kept or rejected.
    pub fn views_in_total(&self) -> u64 {
        self.options.scene_indices().count() as u64 * self.options.views_per_scene as u64
    }

    /// The number of views already rendered, kept or rejected.
    pub fn views_done(&self) -> u64 {
        (self.views.len() + self.rejected.len()) as u64
    }

    /// Adds view `rendered` of scene `scene` (whose layout is `layout`) to the dataset in
    /// `dir`: writes its EXR, records it (or its rejection) and saves the manifest. A view the
    /// manifest already has is left as it is. Returns true when the view was added.
    pub fn record(
        &mut self,
        dir: &Path,
        scene: u64,
        layout: Layout,
        rendered: &RenderedView,
        progress: &dyn Progress,
    ) -> Result<bool, TrainError> {
        if self.has_view(scene, rendered.view) {
            return Ok(false);
        }
        match &rendered.render {
            ViewRender::Rejected { why } => {
                self.rejected.push(format!("{scene}/{}", rendered.view));
                progress.note(&format!("scene {scene} view {} rejected: {why}", rendered.view));
            }
            ViewRender::Kept { exr, reference_spp, reference_relmse } => {
                let file = view_file(scene, rendered.view);
                rtd_image::create_dir_durably(&dir.join("views")).map_err(|e| TrainError::io(dir, e))?;
                rtd_image::write_bytes_atomic(&dir.join(&file), exr)?;
                self.views.push(ViewRecord {
                    file,
                    scene,
                    view: rendered.view,
                    layout,
                    validation: self.options.is_validation(scene),
                    reference_spp: *reference_spp,
                    reference_relmse: *reference_relmse,
                    seconds: rendered.seconds,
                });
            }
        }
        self.save(dir)?;
        Ok(true)
    }
}

/// `(scene, view)` of a rejection's "scene/view" key (unparsable keys sort last).
fn parse_view_key(key: &str) -> (u64, u64) {
    let mut parts = key.split('/').map(|p| p.parse::<u64>().unwrap_or(u64::MAX));
    (parts.next().unwrap_or(u64::MAX), parts.next().unwrap_or(u64::MAX))
}

/// Generates (or resumes) the dataset in `dir`. Returns the manifest.
pub fn generate_dataset(dir: &Path, options: &DatasetOptions, progress: &dyn Progress) -> Result<Manifest, TrainError> {
    let mut manifest = Manifest::open(dir, options)?;
    progress.start(manifest.views_in_total(), "datagen");
    progress.inc(manifest.views_done());
    for scene_index in manifest.scenes_to_render() {
        let scene = DatasetScene::write_and_load(&dir.join("scenes"), options, scene_index)?;
        for view in 0..options.views_per_scene {
            if manifest.has_view(scene_index, view) {
                continue;
            }
            if progress.cancelled() {
                return Ok(manifest);
            }
            let rendered = scene.render_view(options, view)?;
            manifest.record(dir, scene_index, scene.layout, &rendered, progress)?;
            progress.inc(1);
        }
    }
    Ok(manifest)
}

/// Re-renders the guide layers (`guide`, `albedo`, `normal`, `depth`, `ao`) of every view of
/// the dataset in `dir` with the current guide pass, in place, and leaves the noisy renders and
/// references as they are: for when the guide pass changes but the path tracer does not. Each
/// view is rewritten whole (temporary file, then rename), so an interruption keeps every view
/// either old or new; rerunning redoes them all. Returns the number of views rewritten.
pub fn refresh_guides(dir: &Path, progress: &dyn Progress) -> Result<usize, TrainError> {
    let manifest = Manifest::load(dir)?;
    progress.start(manifest.views.len() as u64, "guides");
    let mut done = 0;
    let mut by_scene: Vec<&ViewRecord> = manifest.views.iter().collect();
    by_scene.sort_by_key(|v| (v.scene, v.view));
    for group in by_scene.chunk_by(|a, b| a.scene == b.scene) {
        let path = dir.join("scenes").join(format!("{}.gltf", scene_name(group[0].scene)));
        let rs = RenderScene::new(rtd_scene::load_scene(&path)?);
        for record in group {
            if progress.cancelled() {
                return Ok(done);
            }
            let file = view_path(dir, record);
            let mut layers = rtd_image::read_exr(&file)?;
            let cam =
                rs.scene.cameras.get(record.view).cloned().ok_or_else(|| {
                    TrainError::msg(&path, format!("has no camera {} for {}", record.view, record.file))
                })?;
            let guide = GuidePass::render(&rs.scene, &rs.bvh, &cam, &GuideSettings::new(layers.width, layers.height))?;
            guide.add_to(&mut layers);
            rtd_image::write_exr(&file, &layers)?;
            done += 1;
            progress.inc(1);
        }
    }
    Ok(done)
}

/// The path of a view's EXR.
pub fn view_path(dir: &Path, record: &ViewRecord) -> PathBuf {
    dir.join(&record.file)
}
