//! The pipeline itself: render, guide pass, denoise, in that order and in this one place.

use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use rtd_denoise::{DenoiseInput, Denoiser};
use rtd_guide::{GuidePass, GuideSettings};
use rtd_image::{HdrImage, ImageFormat, Layer, Layers, Progress, Tonemap};
use rtd_render::{Film, PathTracer, RenderSettings, RenderStats};

use crate::{PipelineError, SceneView};

/// How long the render stage runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// This many samples per pixel.
    Samples(u32),
    /// Whole 1-spp passes until this much wall time is spent (at least one pass).
    Time(Duration),
}

/// Seconds each stage took.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StageTimings {
    /// Loading the scene file.
    pub load_s: f64,
    /// Building the BVH.
    pub bvh_s: f64,
    /// Rendering.
    pub render_s: f64,
    /// The guide pass, when it ran.
    pub guide_s: Option<f64>,
    /// The denoiser (encoding, network, decoding), when it ran.
    pub denoise_s: Option<f64>,
}

impl StageTimings {
    /// Render + guide + denoise seconds: the pipeline's cost once the scene is loaded.
    pub fn pipeline_s(&self) -> f64 {
        self.render_s + self.guide_s.unwrap_or(0.0) + self.denoise_s.unwrap_or(0.0)
    }
}

/// The render → guide → denoise pipeline over one [`SceneView`], configured builder style:
/// `Pipeline::new(&view, settings).guide(g).denoise(&model).run(Budget::Samples(8), &Quiet)`.
pub struct Pipeline<'a> {
    view: &'a SceneView,
    render: RenderSettings,
    guide: Option<GuideSettings>,
    denoiser: Option<&'a Denoiser>,
}

/// What a run made.
pub struct PipelineRun {
    /// The accumulated film (beauty and first-hit AOVs).
    pub film: Film,
    /// The render's counters.
    pub stats: RenderStats,
    /// The guide pass, when it ran.
    pub guide: Option<GuidePass>,
    /// The denoised image, when a denoiser was given.
    pub denoised: Option<HdrImage>,
    /// Seconds per stage.
    pub timings: StageTimings,
    /// True if the progress observer cancelled the render early (the film holds whole passes).
    pub interrupted: bool,
}

/// The denoiser's input for `color` with every layer of rtd's own guide pass (guide RGB,
/// albedo, normal, AO, depth).
pub fn denoise_input<'a>(color: &'a HdrImage, pass: &'a GuidePass) -> DenoiseInput<'a> {
    DenoiseInput::new(color, &pass.guide).albedo_normal(&pass.albedo, &pass.normal).ao_depth(&pass.ao, &pass.depth)
}

impl<'a> Pipeline<'a> {
    /// A pipeline that renders `view` with `render` settings, with no guide pass or denoiser.
    pub fn new(view: &'a SceneView, render: RenderSettings) -> Self {
        Pipeline { view, render, guide: None, denoiser: None }
    }

    /// Adds the guide pass with these settings (their size must be the render's).
    pub fn guide(mut self, settings: GuideSettings) -> Self {
        self.guide = Some(settings);
        self
    }

    /// Adds the denoiser; the guide pass runs too, with default settings unless
    /// [`Pipeline::guide`] set others.
    pub fn denoise(mut self, denoiser: &'a Denoiser) -> Self {
        self.denoiser = Some(denoiser);
        self
    }

    /// A path tracer with the pipeline's settings, to continue a run's film (equal-time
    /// comparisons render on from where the pipeline stopped).
    pub fn tracer(&self) -> Result<PathTracer<'a>, PipelineError> {
        Ok(PathTracer::new(&self.view.scene, self.view.camera.clone(), self.render.clone())?)
    }

    /// The guide settings a run uses, if it runs the guide pass.
    fn guide_settings(&self) -> Option<GuideSettings> {
        let default = || GuideSettings::new(self.render.width, self.render.height).threads(self.render.threads);
        self.guide.clone().or_else(|| self.denoiser.map(|_| default()))
    }

    /// Checks the render's and the guide pass's settings before any work.
    pub fn validate(&self) -> Result<(), PipelineError> {
        self.render.validate()?;
        if let Some(g) = self.guide_settings() {
            g.validate()?;
            if (g.width, g.height) != (self.render.width, self.render.height) {
                return Err(PipelineError::GuideSize {
                    guide: (g.width, g.height),
                    render: (self.render.width, self.render.height),
                });
            }
        }
        Ok(())
    }

    /// Runs every configured stage. `progress` sees a "render" phase (image rows, or
    /// milliseconds of a time budget), then one-unit "guide" and "denoise" phases, and can
    /// cancel the render between passes; the guide pass and
    /// the denoiser then still run on the passes finished, so an interrupted render keeps an
    /// image. Fails with [`PipelineError::NothingRendered`] if no pass finished.
    pub fn run(&self, budget: Budget, progress: &dyn Progress) -> Result<PipelineRun, PipelineError> {
        self.validate()?;
        let tracer = self.tracer()?;
        let mut film = tracer.film();
        let stats = match budget {
            Budget::Samples(spp) => {
                progress.start(spp as u64 * self.render.height as u64, "render");
                tracer.render_observed(&mut film, spp, progress)?
            }
            Budget::Time(limit) => {
                progress.start(limit.as_millis() as u64, "render");
                tracer.render_for(&mut film, limit, &Elapsed::new(progress))?
            }
        };
        if film.spp == 0 {
            return Err(PipelineError::NothingRendered);
        }
        // Stopped early: fewer passes than asked for, or a time budget the observer cut short.
        let interrupted = match budget {
            Budget::Samples(spp) => stats.spp < spp,
            Budget::Time(_) => progress.cancelled(),
        };
        self.finish_film(film, stats, interrupted, progress)
    }

    /// Renders samples `first..first + count` of every pixel into a film of their own: one
    /// range of a render split over machines, to be merged in order ([`Film::merge`]) and
    /// finished with [`Pipeline::finish`]. Cancelling stops it between passes (check
    /// [`Film::samples`]).
    pub fn render_range(&self, first: u32, count: u32, progress: &dyn Progress) -> Result<Film, PipelineError> {
        self.validate()?;
        let tracer = self.tracer()?;
        let mut film = Film::starting_at(self.render.width, self.render.height, first);
        progress.start(count as u64 * self.render.height as u64, "render");
        tracer.render_observed(&mut film, count, progress)?;
        Ok(film)
    }

    /// Runs the guide pass and the denoiser, as configured, on `film`: a whole render made
    /// elsewhere, such as merged sample ranges. Gives what [`Pipeline::run`] gives for the same
    /// samples (its render counters hold only the film's spp and non-finite samples).
    pub fn finish(&self, film: Film, progress: &dyn Progress) -> Result<PipelineRun, PipelineError> {
        self.validate()?;
        if film.first_sample != 0 || film.samples() == 0 {
            return Err(PipelineError::NothingRendered);
        }
        if (film.width, film.height) != (self.render.width, self.render.height) {
            return Err(rtd_render::RenderError::FilmSize {
                film: (film.width, film.height),
                settings: (self.render.width, self.render.height),
            }
            .into());
        }
        let stats = RenderStats { spp: film.spp, nonfinite_samples: film.nonfinite_samples, ..RenderStats::default() };
        self.finish_film(film, stats, false, progress)
    }

    /// The stages after the render: guide pass and denoiser.
    fn finish_film(
        &self,
        film: Film,
        stats: RenderStats,
        interrupted: bool,
        progress: &dyn Progress,
    ) -> Result<PipelineRun, PipelineError> {
        let mut timings = StageTimings {
            load_s: self.view.load_s,
            bvh_s: self.view.scene.bvh_seconds,
            render_s: stats.seconds,
            ..StageTimings::default()
        };
        let scene = &self.view.scene;
        let guide = match self.guide_settings() {
            Some(settings) => {
                progress.start(1, "guide");
                let pass = GuidePass::render(&scene.scene, &scene.bvh, &self.view.camera, &settings)?;
                progress.inc(1);
                Some(pass)
            }
            None => None,
        };
        timings.guide_s = guide.as_ref().map(|g| g.seconds);
        let denoised = match (self.denoiser, &guide) {
            (Some(denoiser), Some(pass)) => {
                progress.start(1, "denoise");
                let (beauty, variance) = (film.beauty(), film.variance());
                let t = Instant::now();
                let out = denoiser.denoise(&denoise_input(&beauty, pass).variance(variance.as_ref()))?;
                timings.denoise_s = Some(t.elapsed().as_secs_f64());
                progress.inc(1);
                Some(out)
            }
            _ => None,
        };
        Ok(PipelineRun { film, stats, guide, denoised, timings, interrupted })
    }
}

impl PipelineRun {
    /// The image a user sees: the denoised one if there is one, else the render.
    pub fn image(&self) -> HdrImage {
        self.denoised.clone().unwrap_or_else(|| self.film.beauty())
    }

    /// Writes the run to `path`, the format chosen by its extension. An EXR holds
    /// [`PipelineRun::exr_layers`]; a PFM or PHM holds [`PipelineRun::image`] as linear floats; a
    /// PNG or JPEG holds it exposed by `exposure` stops and tonemapped.
    pub fn write(&self, path: &Path, exposure: f32, tonemap: Tonemap) -> Result<(), PipelineError> {
        match ImageFormat::from_path(path)? {
            ImageFormat::Exr => rtd_image::write_exr_owned(path, self.exr_layers())?,
            format @ (ImageFormat::Pfm | ImageFormat::Phm) => {
                rtd_image::write_pfm(path, &self.image(), format == ImageFormat::Phm)?
            }
            ImageFormat::Png | ImageFormat::Jpeg => rtd_image::write_ldr(path, &self.image(), exposure, tonemap)?,
        }
        Ok(())
    }

    /// [`PipelineRun::write`], consuming the run: an EXR's layers are made from the film as it is
    /// freed, and the guide pass and the denoised image are freed before the file is encoded
    /// (`rtd render --spp 4 --denoise` at 3840×2160: 3.10 GiB at the peak before, 1.83 GiB after).
    pub fn write_into(self, path: &Path, exposure: f32, tonemap: Tonemap) -> Result<(), PipelineError> {
        if ImageFormat::from_path(path)? != ImageFormat::Exr {
            return self.write(path, exposure, tonemap);
        }
        let PipelineRun { film, guide, denoised, .. } = self;
        let layers = with_stages(film.into_layers(), guide.as_ref(), denoised.as_ref());
        drop((guide, denoised));
        Ok(rtd_image::write_exr_owned(path, layers)?)
    }

    /// The channels an EXR of the run holds: the film's layers (beauty, its variance, albedo,
    /// normal, depth), the guide pass's (guide, albedo, normal, depth, AO) and, when denoised,
    /// the denoised beauty with the noisy one as `noisy`.
    pub fn exr_layers(&self) -> Layers {
        with_stages(self.film.layers(), self.guide.as_ref(), self.denoised.as_ref())
    }
}

/// The film's `layers` with the guide pass's layers (in place of the film's albedo, normal and
/// depth) and, when denoised, the denoised beauty, the film's moved to `noisy`.
fn with_stages(mut layers: Layers, guide: Option<&GuidePass>, denoised: Option<&HdrImage>) -> Layers {
    if let Some(g) = guide {
        g.add_to(&mut layers);
    }
    if let Some(d) = denoised {
        if let Some(noisy) = layers.image(Layer::Beauty) {
            layers.put_image(Layer::Noisy, &noisy);
        }
        layers.put_image(Layer::Beauty, d);
    }
    layers
}

/// Turns a time-budgeted render's row reports into milliseconds elapsed, so a bar started
/// with the budget in milliseconds tracks time against it.
struct Elapsed<'p> {
    inner: &'p dyn Progress,
    start: Instant,
    reported_ms: AtomicU64,
}

impl<'p> Elapsed<'p> {
    fn new(inner: &'p dyn Progress) -> Self {
        Elapsed { inner, start: Instant::now(), reported_ms: AtomicU64::new(0) }
    }
}

impl Progress for Elapsed<'_> {
    fn inc(&self, _rows: u64) {
        let now = self.start.elapsed().as_millis() as u64;
        let before = self.reported_ms.fetch_max(now, Ordering::Relaxed);
        if now > before {
            self.inner.inc(now - before);
        }
    }
    fn note(&self, line: &str) {
        self.inner.note(line);
    }
    fn cancelled(&self) -> bool {
        self.inner.cancelled()
    }
}
