//! Doing one claimed task: the same library calls as `rtd denoise` and `rtd render --denoise`
//! make, on the job's files written to a private temporary folder, so that a job's result has
//! the bytes the command line gives for the same inputs.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use rtd_denoise::Denoiser;
use rtd_image::{Progress, Tonemap};
use rtd_pipeline::{CameraChoice, DenoiseSources, Pipeline, PipelineRun, SceneView};
use rtd_render::{Film, RenderSettings};
use rtd_train::dataset::{render_shard, DatasetOptions};

use crate::jobs::{Input, RenderParams};
use crate::queue::{Claim, TaskKind, TaskOutput};
use crate::ServiceError;

/// A task's live progress and its stop flag, shared between the work and the lease renewal.
#[derive(Default)]
pub struct TaskProgress {
    len: AtomicU64,
    done: AtomicU64,
    fraction_bits: AtomicU64,
    stop: AtomicBool,
}

impl TaskProgress {
    /// The fraction done, 0 to 1.
    pub fn fraction(&self) -> f64 {
        f64::from_bits(self.fraction_bits.load(Ordering::Relaxed))
    }
    /// Asks the work to stop after the pass in flight.
    pub fn stop(&self) {
        self.stop.store(true, Ordering::Relaxed);
    }
    /// True once [`TaskProgress::stop`] was called.
    pub fn stopped(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }
    fn set_fraction(&self, f: f64) {
        self.fraction_bits.store(f.clamp(0.0, 1.0).to_bits(), Ordering::Relaxed);
    }
}

impl Progress for TaskProgress {
    fn start(&self, len: u64, what: &str) {
        self.len.store(len.max(1), Ordering::Relaxed);
        self.done.store(0, Ordering::Relaxed);
        // The stages after a render are short: show them as the last tenth.
        match what {
            "guide" => self.set_fraction(0.9),
            "denoise" => self.set_fraction(0.95),
            _ => {}
        }
    }
    fn inc(&self, n: u64) {
        let done = self.done.fetch_add(n, Ordering::Relaxed) + n;
        let len = self.len.load(Ordering::Relaxed).max(1);
        self.set_fraction((done as f64 / len as f64).min(1.0) * 0.9);
    }
    fn cancelled(&self) -> bool {
        self.stopped()
    }
}

/// Everything a task needs from the database, fetched before the work starts.
pub struct TaskInputs {
    /// The job's uploaded files.
    pub files: Vec<Input>,
    /// The job's settings as stored (JSON): [`RenderParams`] for a render, the
    /// [`DatasetOptions`] for a dataset.
    pub params: String,
    /// The finished ranges' films, in order (the finishing task only).
    pub films: Vec<Vec<u8>>,
}

/// Does `claim`'s work. Errors are for the user: they name the upload's field, not the
/// server's temporary folder.
pub fn execute(
    claim: &Claim,
    inputs: &TaskInputs,
    denoiser: &Denoiser,
    threads: Option<usize>,
    progress: &TaskProgress,
) -> Result<TaskOutput, ServiceError> {
    // The folder's own errors name a server path: logged, and the user told only what failed.
    let no_room = |e: std::io::Error| {
        tracing::error!(error = %e, "cannot write a job's files");
        ServiceError::Job("the render node could not store the job's files".into())
    };
    let dir = tempfile::tempdir().map_err(no_room)?;
    let mut paths = Vec::new();
    for f in &inputs.files {
        let path = dir.path().join(format!("{}.{}", f.name, f.format));
        std::fs::write(&path, &f.data).map_err(no_room)?;
        paths.push((f.name.clone(), path));
    }
    let find = |name: &str| paths.iter().find(|(n, _)| n == name).map(|(_, p)| p.clone());
    let result = match claim.kind {
        TaskKind::Denoise => denoise(dir.path(), &find, denoiser),
        TaskKind::RenderRange => {
            let (view, settings) = render_view(&find, &render_params(inputs)?, threads)?;
            let film = Pipeline::new(&view, settings).render_range(claim.first_sample, claim.samples, progress)?;
            if film.samples() != claim.samples {
                return Err(ServiceError::Job("the render was stopped".into()));
            }
            postcard::to_stdvec(&film).map(TaskOutput::Film).map_err(|e| ServiceError::Corrupt(e.to_string()))
        }
        TaskKind::RenderFinish => {
            let params = render_params(inputs)?;
            let (view, settings) = render_view(&find, &params, threads)?;
            let film = merge_films(&inputs.films, params.spp)?;
            let run = Pipeline::new(&view, settings).denoise(denoiser).finish(film, progress)?;
            render_result(dir.path(), &run)
        }
        TaskKind::DatasetScene => {
            let options: DatasetOptions = serde_json::from_str(&inputs.params)
                .map_err(|e| ServiceError::Corrupt(format!("dataset options: {e}")))?;
            let shard = render_shard(dir.path(), &options, claim.scene, progress)
                .map_err(|e| ServiceError::Job(e.to_string()))?
                .ok_or_else(|| ServiceError::Job("the render was stopped".into()))?;
            postcard::to_stdvec(&shard).map(TaskOutput::Shard).map_err(|e| ServiceError::Corrupt(e.to_string()))
        }
    };
    result.map_err(|e| hide_folder(e, dir.path()))
}

/// A render job's settings.
fn render_params(inputs: &TaskInputs) -> Result<RenderParams, ServiceError> {
    serde_json::from_str(&inputs.params).map_err(|e| ServiceError::Corrupt(format!("job parameters: {e}")))
}

/// The denoise job: `rtd denoise` on the uploaded files.
fn denoise(
    dir: &Path,
    find: &dyn Fn(&str) -> Option<PathBuf>,
    denoiser: &Denoiser,
) -> Result<TaskOutput, ServiceError> {
    let color = find("color").ok_or_else(|| ServiceError::Corrupt("a denoise job without colour".into()))?;
    let sources = DenoiseSources::new(color).guide(find("guide")).albedo(find("albedo")).normal(find("normal"));
    let denoised = sources.denoise(denoiser)?;
    let (exr, png, input) = (dir.join("result.exr"), dir.join("result.png"), dir.join("input.png"));
    denoised.write(&png, 0.0)?;
    rtd_image::write_ldr(&input, &denoised.color, 0.0, Tonemap::Clamp).map_err(rtd_pipeline::PipelineError::from)?;
    // What the job page shows beside the result: the time, the model, the inputs read, and
    // guide layers the colour's file holds that were not uploaded as their inputs.
    let mut timings = serde_json::json!({
        "denoise_s": denoised.denoise_s,
        "model": denoised.model,
        "inputs": denoised.inputs.join(", "),
    });
    if !denoised.unread_layers.is_empty() {
        timings["unread_layers"] = denoised.unread_layers.join(", ").into();
    }
    let timings = timings.to_string();
    let size = (denoised.image.width, denoised.image.height);
    // Last, consuming the result: the EXR is made in the colour file's own channels.
    denoised.write_into(&exr, 0.0)?;
    Ok(TaskOutput::Result { exr: read(&exr)?, png: read(&png)?, input_png: read(&input)?, timings, size })
}

/// The render job's scene, camera and settings: what `rtd render` would use for them.
fn render_view(
    find: &dyn Fn(&str) -> Option<PathBuf>,
    params: &RenderParams,
    threads: Option<usize>,
) -> Result<(SceneView, RenderSettings), ServiceError> {
    let scene = find("scene").ok_or_else(|| ServiceError::Corrupt("a render job without a scene".into()))?;
    let camera = params.camera.clone().map(CameraChoice::Named).unwrap_or_default();
    let view = SceneView::load(&scene, &camera, None)?;
    let (w, h, _) = view.resolution(params.width, params.height);
    let settings = RenderSettings::new(w, h).threads(threads);
    settings.validate().map_err(rtd_pipeline::PipelineError::from)?;
    Ok((view, settings))
}

/// The ranges' films merged in order; the whole must hold samples 0..spp.
fn merge_films(encoded: &[Vec<u8>], spp: u32) -> Result<Film, ServiceError> {
    let mut films = encoded.iter().map(|b| {
        let f: Film = postcard::from_bytes(b).map_err(|e| ServiceError::Corrupt(format!("a range's film: {e}")))?;
        if f.is_consistent() {
            Ok(f)
        } else {
            Err(ServiceError::Corrupt("a range's film has the wrong buffer sizes".into()))
        }
    });
    let mut film = films.next().ok_or_else(|| ServiceError::Corrupt("a render with no ranges".into()))??;
    for next in films {
        film.merge(&next?).map_err(|e| ServiceError::Corrupt(e.to_string()))?;
    }
    if film.first_sample != 0 || film.spp != spp {
        return Err(ServiceError::Corrupt(format!(
            "the ranges hold samples {}..{}, not 0..{spp}",
            film.first_sample, film.spp
        )));
    }
    Ok(film)
}

/// The render job's result files: what `rtd render --denoise -o result.exr|png` writes.
fn render_result(dir: &Path, run: &PipelineRun) -> Result<TaskOutput, ServiceError> {
    let (exr, png, input) = (dir.join("result.exr"), dir.join("result.png"), dir.join("input.png"));
    run.write(&exr, 0.0, Tonemap::Clamp)?;
    run.write(&png, 0.0, Tonemap::Clamp)?;
    rtd_image::write_ldr(&input, &run.film.beauty(), 0.0, Tonemap::Clamp).map_err(rtd_pipeline::PipelineError::from)?;
    let t = &run.timings;
    let timings = serde_json::json!({
        "spp": run.film.spp,
        "load_s": t.load_s,
        "bvh_s": t.bvh_s,
        "guide_s": t.guide_s,
        "denoise_s": t.denoise_s,
    })
    .to_string();
    Ok(TaskOutput::Result {
        exr: read(&exr)?,
        png: read(&png)?,
        input_png: read(&input)?,
        timings,
        size: (run.film.width, run.film.height),
    })
}

fn read(path: &Path) -> Result<Vec<u8>, ServiceError> {
    std::fs::read(path).map_err(|e| ServiceError::io("cannot read a result back", e))
}

/// `e` with the work folder's path taken out of its message, so the user sees `scene.gltf: …`.
fn hide_folder(e: ServiceError, dir: &Path) -> ServiceError {
    let text = e.to_string();
    let prefix = format!("{}/", dir.display());
    if text.contains(&prefix) {
        ServiceError::Job(text.replace(&prefix, ""))
    } else {
        e
    }
}
