//! Rendering one dataset view: the guide pass, a preview that may reject the view, the noisy
//! renders at every [`SPP_LADDER`] count (with their per-pixel variance from 2 spp on) and
//! the reference. Every render's seed derives from
//! (master seed, scene, view, purpose), so a view is the same bytes on any machine.

use std::path::Path;
use std::time::Instant;

use rtd_guide::{GuidePass, GuideSettings};
use rtd_image::{luminance, HdrImage, Layer, Layers};
use rtd_render::{Film, PathTracer, RenderScene, RenderSettings, SPP_LADDER};
use serde::{Deserialize, Serialize};

use super::DatasetOptions;
use crate::scenegen::{generate_scene, Layout, SceneGenOptions};
use crate::TrainError;

/// One view's renders, or why the view is not kept.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub enum ViewRender {
    /// Kept: the view's EXR (noisy renders, guide layers and reference) as the bytes of its
    /// file, the reference's samples per pixel and its estimated remaining relMSE.
    Kept {
        /// The EXR file's bytes.
        exr: Vec<u8>,
        /// Reference samples per pixel actually rendered.
        reference_spp: u32,
        /// Estimated relMSE left in the reference.
        reference_relmse: f64,
    },
    /// Rejected: its preview came out black or empty.
    Rejected {
        /// `black` or `empty`.
        why: String,
    },
}

/// A rendered view of a scene, wherever it was rendered.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RenderedView {
    /// Camera index within the scene.
    pub view: usize,
    /// Seconds spent rendering it.
    pub seconds: f64,
    /// What came out.
    pub render: ViewRender,
}

/// The file name of scene `index`'s glTF (without extension) and of its views.
pub fn scene_name(index: u64) -> String {
    format!("scene{index:04}")
}

/// Writes generated scene `index` of `options` as glTF (with its buffer and textures) into
/// `scene_dir` and returns its layout. The files are the same bytes every time.
pub fn write_scene(scene_dir: &Path, options: &DatasetOptions, index: u64) -> Result<Layout, TrainError> {
    let scene_options = SceneGenOptions { views: options.views_per_scene, texture_size: 256 };
    let (gen, layout) = generate_scene(options.seed, index, &scene_options);
    gen.write(scene_dir, &scene_name(index))?;
    Ok(layout)
}

/// One generated scene, written and loaded, ready to render its views.
pub struct DatasetScene {
    /// Scene index.
    pub index: u64,
    /// Its layout.
    pub layout: Layout,
    rs: RenderScene,
}

impl DatasetScene {
    /// Writes scene `index` into `scene_dir` ([`write_scene`]) and loads it back, so that it
    /// renders exactly as the files a dataset keeps.
    pub fn write_and_load(scene_dir: &Path, options: &DatasetOptions, index: u64) -> Result<Self, TrainError> {
        let layout = write_scene(scene_dir, options, index)?;
        let scene = rtd_scene::load_scene(&scene_dir.join(format!("{}.gltf", scene_name(index))))?;
        Ok(DatasetScene { index, layout, rs: RenderScene::new(scene) })
    }

    /// Renders camera `view`: the guide pass and a 4-spp preview that may reject the view,
    /// then the noisy renders at every [`SPP_LADDER`] count and the reference.
    pub fn render_view(&self, options: &DatasetOptions, view: usize) -> Result<RenderedView, TrainError> {
        let start = Instant::now();
        let (rs, size, index) = (&self.rs, options.size, self.index);
        let cam = rs
            .scene
            .cameras
            .get(view)
            .cloned()
            .ok_or_else(|| TrainError::msg(Path::new(&scene_name(index)), format!("has no camera {view}")))?;
        let guide = GuidePass::render(&rs.scene, &rs.bvh, &cam, &GuideSettings::new(size, size))?;
        let preview = beauty(rs, &cam, size, render_seed(options.seed, index, view, 99), 4)?;
        if let Some(why) = reject_reason(&preview, &guide) {
            let render = ViewRender::Rejected { why: why.into() };
            return Ok(RenderedView { view, seconds: start.elapsed().as_secs_f64(), render });
        }
        let mut layers = Layers::new(size, size);
        for (k, spp) in SPP_LADDER.iter().enumerate() {
            let film = render_film(rs, &cam, size, render_seed(options.seed, index, view, k as u64), *spp)?;
            layers.put_image(Layer::NoisyAt(*spp), &film.beauty());
            if let Some(variance) = film.variance() {
                layers.put_image(Layer::VarianceAt(*spp), &variance);
            }
        }
        guide.add_to(&mut layers);
        let (reference, rounds, reference_relmse) = render_reference(rs, &cam, options, index, view)?;
        layers.put_image(Layer::Reference, &reference);
        let exr = rtd_image::encode_exr(Path::new(&view_file(index, view)), &layers)?;
        let render = ViewRender::Kept { exr, reference_spp: options.reference_spp * rounds, reference_relmse };
        Ok(RenderedView { view, seconds: start.elapsed().as_secs_f64(), render })
    }
}

/// A view's EXR, relative to the dataset directory.
pub fn view_file(scene: u64, view: usize) -> String {
    format!("views/{}_v{view}.exr", scene_name(scene))
}

/// A seed for one render of one view: distinct for every (scene, view, purpose).
fn render_seed(master: u64, scene: u64, view: usize, purpose: u64) -> u64 {
    // SplitMix64's finaliser over the xor of the inputs times odd constants.
    let mut z = master
        ^ scene.wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (view as u64).wrapping_mul(0xD1B5_4A32_D192_ED03)
        ^ purpose.wrapping_mul(0x8CB9_2BA7_2F3D_8DD7);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z ^ (z >> 31)
}

/// Renders `spp` samples with `seed`.
fn render_film(rs: &RenderScene, cam: &rtd_scene::Camera, size: u32, seed: u64, spp: u32) -> Result<Film, TrainError> {
    let tracer = PathTracer::new(rs, cam.clone(), RenderSettings::new(size, size).seed(seed))?;
    let mut film = tracer.film();
    tracer.render(&mut film, spp)?;
    Ok(film)
}

/// Renders `spp` samples with `seed` and returns the beauty.
fn beauty(rs: &RenderScene, cam: &rtd_scene::Camera, size: u32, seed: u64, spp: u32) -> Result<HdrImage, TrainError> {
    Ok(render_film(rs, cam, size, seed, spp)?.beauty())
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
