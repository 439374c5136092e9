//! `rtd datagen`: renders the training set. For every view of every generated scene it writes
//! one EXR holding the noisy beauty at several sample counts (independent seeds), the guide
//! pass and a high-spp reference, and records the view in `manifest.json`. Finished views are
//! kept, so an interrupted run resumes where it stopped.

use std::path::{Path, PathBuf};
use std::time::Instant;

use rtd_guide::{GuidePass, GuideSettings};
use rtd_image::{luminance, HdrImage, Layer, Layers};
use rtd_render::{PathTracer, RenderScene, RenderSettings, SPP_LADDER};
use serde::{Deserialize, Serialize};

use crate::scenegen::{generate_scene, Layout, SceneGenOptions};
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

    fn save(&self, dir: &Path) -> Result<(), TrainError> {
        let path = dir.join("manifest.json");
        let text = serde_json::to_vec_pretty(self).map_err(|e| TrainError::msg(&path, e.to_string()))?;
        Ok(rtd_image::write_bytes_atomic(&path, &text)?)
    }
}

/// A seed for one render of one view: distinct for every (scene, view, purpose).
fn render_seed(master: u64, scene: u64, view: usize, purpose: u64) -> u64 {
    let mut z = master
        ^ scene.wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (view as u64).wrapping_mul(0xD1B5_4A32_D192_ED03)
        ^ purpose.wrapping_mul(0x8CB9_2BA7_2F3D_8DD7);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z ^ (z >> 31)
}

/// Renders `spp` samples with `seed` and returns the beauty.
fn beauty(rs: &RenderScene, cam: &rtd_scene::Camera, size: u32, seed: u64, spp: u32) -> Result<HdrImage, TrainError> {
    let tracer = PathTracer::new(rs, cam.clone(), RenderSettings::new(size, size).seed(seed))?;
    let mut film = tracer.film();
    tracer.render(&mut film, spp)?;
    Ok(film.beauty())
}

/// Why a view is unusable, if it is: black (almost no light) or empty (mostly sky or one flat colour).
fn reject_reason(preview: &HdrImage, guide: &GuidePass) -> Option<&'static str> {
    let mean = luminance(preview.mean());
    if !(mean > 1e-3) {
        return Some("black");
    }
    let hit = guide.depth.iter().filter(|d| **d > 0.0).count() as f32 / guide.depth.len() as f32;
    let albedo_mean = guide.albedo.mean();
    let spread = guide.albedo.pixels.iter().map(|a| (*a - albedo_mean).abs().max_element()).sum::<f32>()
        / guide.depth.len() as f32;
    if hit < 0.5 || spread < 0.02 {
        return Some("empty");
    }
    None
}

/// Generates (or resumes) the dataset in `dir`. Returns the manifest.
pub fn generate_dataset(dir: &Path, options: &DatasetOptions, progress: &dyn Progress) -> Result<Manifest, TrainError> {
    std::fs::create_dir_all(dir.join("scenes")).map_err(|e| TrainError::io(dir, e))?;
    let mut manifest = open_manifest(dir, options)?;
    let total = options.scene_indices().count() as u64 * options.views_per_scene as u64;
    progress.start(total, "datagen");
    progress.inc((manifest.views.len() + manifest.rejected.len()) as u64);
    for scene_index in options.scene_indices() {
        if !render_scene(dir, options, scene_index, &mut manifest, progress)? {
            break;
        }
    }
    Ok(manifest)
}

/// The manifest to continue in `dir`: the one there if `options` made it, or made it with fewer
/// scenes (it is then extended: scene k is the same whatever the count), a new one if there is
/// none; a dataset made with any other options is refused.
fn open_manifest(dir: &Path, options: &DatasetOptions) -> Result<Manifest, TrainError> {
    match Manifest::load(dir) {
        Ok(m) if m.options == *options => Ok(m),
        Ok(mut m) if m.options.scenes < options.scenes && m.options == options.clone().scenes(m.options.scenes) => {
            m.options.scenes = options.scenes;
            Ok(m)
        }
        Ok(_) => Err(TrainError::msg(
            &dir.join("manifest.json"),
            "was made with other options (only --scenes may grow); use a new directory",
        )),
        Err(_) => {
            Ok(Manifest { options: options.clone(), noisy_spp: SPP_LADDER.to_vec(), views: vec![], rejected: vec![] })
        }
    }
}

/// True when `manifest` has view `view` of scene `scene`, or has rejected it.
fn view_done(manifest: &Manifest, scene: u64, view: usize) -> bool {
    let key = format!("{scene}/{view}");
    manifest.views.iter().any(|r| r.scene == scene && r.view == view) || manifest.rejected.contains(&key)
}

/// Generates scene `scene_index` (writing its glTF) and renders the views of it that `manifest`
/// lacks, recording each view or its rejection in `manifest`, saved after every view. Returns
/// false when `progress` was cancelled.
fn render_scene(
    dir: &Path,
    options: &DatasetOptions,
    scene_index: u64,
    manifest: &mut Manifest,
    progress: &dyn Progress,
) -> Result<bool, TrainError> {
    if (0..options.views_per_scene).all(|v| view_done(manifest, scene_index, v)) {
        return Ok(true);
    }
    let scene_options = SceneGenOptions { views: options.views_per_scene, texture_size: 256 };
    let (gen, layout) = generate_scene(options.seed, scene_index, &scene_options);
    let name = format!("scene{scene_index:04}");
    gen.write(&dir.join("scenes"), &name)?;
    let scene = rtd_scene::load_scene(&dir.join("scenes").join(format!("{name}.gltf")))?;
    let rs = RenderScene::new(scene);
    for view in 0..options.views_per_scene {
        if view_done(manifest, scene_index, view) {
            continue;
        }
        if progress.cancelled() {
            return Ok(false);
        }
        let start = Instant::now();
        match render_view(&rs, options, scene_index, view)? {
            ViewRender::Rejected(why) => {
                manifest.rejected.push(format!("{scene_index}/{view}"));
                progress.note(&format!("scene {scene_index} view {view} rejected: {why}"));
            }
            ViewRender::Kept { layers, reference_spp, reference_relmse } => {
                let file = format!("views/{name}_v{view}.exr");
                std::fs::create_dir_all(dir.join("views")).map_err(|e| TrainError::io(dir, e))?;
                rtd_image::write_exr(&dir.join(&file), &layers)?;
                manifest.views.push(ViewRecord {
                    file,
                    scene: scene_index,
                    view,
                    layout,
                    validation: options.is_validation(scene_index),
                    reference_spp,
                    reference_relmse,
                    seconds: start.elapsed().as_secs_f64(),
                });
            }
        }
        manifest.save(dir)?;
        progress.inc(1);
    }
    Ok(true)
}

/// One view's renders, or why the view is not kept.
enum ViewRender {
    /// The noisy renders, guide layers and reference, with the reference's samples per pixel
    /// and its estimated remaining relMSE.
    Kept { layers: Layers, reference_spp: u32, reference_relmse: f64 },
    /// Its preview came out black or empty ([`reject_reason`]).
    Rejected(&'static str),
}

/// Renders camera `view` of scene `scene_index` (loaded as `rs`): the guide pass and a 4-spp
/// preview that may reject the view, then the noisy renders at every [`SPP_LADDER`] and the
/// reference.
fn render_view(
    rs: &RenderScene,
    options: &DatasetOptions,
    scene_index: u64,
    view: usize,
) -> Result<ViewRender, TrainError> {
    let size = options.size;
    let cam = rs.scene.cameras[view].clone();
    let guide = GuidePass::render(&rs.scene, &rs.bvh, &cam, &GuideSettings::new(size, size))?;
    let preview = beauty(rs, &cam, size, render_seed(options.seed, scene_index, view, 99), 4)?;
    if let Some(why) = reject_reason(&preview, &guide) {
        return Ok(ViewRender::Rejected(why));
    }
    let mut layers = Layers::new(size, size);
    for (k, spp) in SPP_LADDER.iter().enumerate() {
        let img = beauty(rs, &cam, size, render_seed(options.seed, scene_index, view, k as u64), *spp)?;
        layers.put_image(Layer::NoisyAt(*spp), &img);
    }
    guide.add_to(&mut layers);
    let (reference, rounds, reference_relmse) = render_reference(rs, &cam, options, scene_index, view)?;
    layers.put_image(Layer::Reference, &reference);
    Ok(ViewRender::Kept { layers, reference_spp: options.reference_spp * rounds, reference_relmse })
}

/// A view's reference from independent half renders of `options.reference_spp / 2` samples,
/// whose difference estimates the noise left in their mean: one pair, and a second where the
/// first leaves more relMSE than `options.reference_relmse`. Returns the mean of all halves,
/// the number of pairs and the estimated relMSE.
fn render_reference(
    rs: &RenderScene,
    cam: &rtd_scene::Camera,
    options: &DatasetOptions,
    scene_index: u64,
    view: usize,
) -> Result<(HdrImage, u32, f64), TrainError> {
    let mut halves: Vec<HdrImage> = vec![];
    let mut round = 0u64;
    loop {
        for h in 0..2 {
            let seed = render_seed(options.seed, scene_index, view, 100 + round * 2 + h);
            halves.push(beauty(rs, cam, options.size, seed, options.reference_spp / 2)?);
        }
        let (a, b) = mean_of_halves(&halves);
        let (both, noise) = rtd_image::metrics::mean_of_halves_with_noise(&a, &b);
        round += 1;
        if noise <= options.reference_relmse || round >= 2 {
            return Ok((both, round as u32, noise));
        }
    }
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
        let path = dir.join("scenes").join(format!("scene{:04}.gltf", group[0].scene));
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

/// The mean of the even-numbered and of the odd-numbered half renders.
fn mean_of_halves(halves: &[HdrImage]) -> (HdrImage, HdrImage) {
    let pick = |parity: usize| {
        let imgs: Vec<&HdrImage> = halves.iter().skip(parity).step_by(2).collect();
        let n = imgs.len() as f32;
        let mut out = imgs[0].clone();
        for (i, p) in out.pixels.iter_mut().enumerate() {
            *p = imgs.iter().map(|im| im.pixels[i]).sum::<glam::Vec3>() / n;
        }
        out
    };
    (pick(0), pick(1))
}

/// The path of a view's EXR.
pub fn view_path(dir: &Path, record: &ViewRecord) -> PathBuf {
    dir.join(&record.file)
}
