//! The image loop: pixels in parallel, samples in order, progress and cancellation.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use rtd_image::{Progress, Quiet, MAX_DIMENSION, MAX_PIXELS};
use rtd_scene::{Camera, Scene};

use crate::bvh::SceneBvh;
use crate::film::{quantize, quantize3, quantize_square, Film};
use crate::integrator::Integrator;
use crate::lights::{LightSelection, LightSet};
use crate::sampler::Sampler;
use crate::sampling::sample_tent;
use crate::RenderError;

/// Largest accepted samples per pixel in one call.
pub const MAX_SPP: u32 = 1 << 24;
/// Largest accepted maximum path depth.
pub const MAX_DEPTH: u32 = 1024;
/// The sample counts rtd compares at: a dataset's noisy renders and the benchmarks' spp sweep.
pub const SPP_LADDER: [u32; 7] = [1, 2, 4, 8, 16, 32, 64];

/// A scene prepared for rendering: the scene plus its BVH and light set.
pub struct RenderScene {
    /// The scene.
    pub scene: Scene,
    /// Its acceleration structure.
    pub bvh: SceneBvh,
    /// Its lights.
    pub lights: LightSet,
    /// Seconds spent building the BVH.
    pub bvh_seconds: f64,
}

impl RenderScene {
    /// Builds the BVH and light set (lights selected by the light tree).
    pub fn new(scene: Scene) -> Self {
        Self::with_light_selection(scene, LightSelection::Tree)
    }

    /// Builds the BVH and light set, lights selected as `selection` says.
    pub fn with_light_selection(scene: Scene, selection: LightSelection) -> Self {
        let t = Instant::now();
        let bvh = SceneBvh::build(&scene);
        let bvh_seconds = t.elapsed().as_secs_f64();
        let lights = LightSet::with_selection(&scene, selection);
        RenderScene { scene, bvh, lights, bvh_seconds }
    }
}

/// Render options, built in the builder style: `RenderSettings::new(w, h).seed(3).max_depth(8)`.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderSettings {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Global seed; every random number derives from (seed, pixel, sample, dimension).
    pub seed: u64,
    /// Maximum bounces.
    pub max_depth: u32,
    /// Optional clamp of each sample's largest channel (off by default: it biases).
    pub clamp: Option<f32>,
    /// Worker threads (None: rayon's default).
    pub threads: Option<usize>,
}

impl RenderSettings {
    /// Defaults for a `width`×`height` image: seed 0, 12 bounces, no clamp.
    pub fn new(width: u32, height: u32) -> Self {
        RenderSettings { width, height, seed: 0, max_depth: 12, clamp: None, threads: None }
    }
    /// Sets the seed.
    pub fn seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }
    /// Sets the maximum depth.
    pub fn max_depth(mut self, d: u32) -> Self {
        self.max_depth = d;
        self
    }
    /// Sets the per-sample clamp.
    pub fn clamp(mut self, c: Option<f32>) -> Self {
        self.clamp = c;
        self
    }
    /// Sets the thread count.
    pub fn threads(mut self, t: Option<usize>) -> Self {
        self.threads = t;
        self
    }

    /// Checks the settings, naming the first problem.
    pub fn validate(&self) -> Result<(), RenderError> {
        let (width, height) = (self.width, self.height);
        if width == 0 || height == 0 || width > MAX_DIMENSION || height > MAX_DIMENSION {
            return Err(RenderError::Resolution { width, height });
        }
        if width as u64 * height as u64 > MAX_PIXELS as u64 {
            return Err(RenderError::TooManyPixels { width, height });
        }
        if self.max_depth > MAX_DEPTH {
            return Err(RenderError::MaxDepth(self.max_depth));
        }
        if let Some(c) = self.clamp {
            if !(c > 0.0 && c.is_finite()) {
                return Err(RenderError::Clamp(c));
            }
        }
        if self.threads == Some(0) {
            return Err(RenderError::NoThreads);
        }
        Ok(())
    }
}

/// Counters from a render call.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RenderStats {
    /// Camera paths traced.
    pub paths: u64,
    /// Rays traced (closest-hit plus shadow).
    pub rays: u64,
    /// Samples dropped as NaN/Inf.
    pub nonfinite_samples: u64,
    /// Wall time.
    pub seconds: f64,
    /// Samples per pixel added by this call.
    pub spp: u32,
}

/// Renders a [`RenderScene`] through a camera.
pub struct PathTracer<'a> {
    scene: &'a RenderScene,
    camera: Camera,
    settings: RenderSettings,
    pool: Workers,
}

/// The threads a render runs on: a dedicated rayon pool of a fixed size, or rayon's global pool.
pub struct Workers(Option<rayon::ThreadPool>);

impl Workers {
    /// A pool of `threads` workers (None: the global pool).
    pub fn new(threads: Option<usize>) -> Result<Self, RenderError> {
        match threads {
            Some(n) => rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map(|p| Workers(Some(p)))
                .map_err(|source| RenderError::ThreadPool { threads: n, source }),
            None => Ok(Workers(None)),
        }
    }

    /// Runs `f` on these workers.
    pub fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        match &self.0 {
            Some(pool) => pool.install(f),
            None => f(),
        }
    }
}

impl RenderStats {
    /// Adds one finished pass's counters.
    fn add_pass(&mut self, pass: &RenderStats) {
        self.paths += pass.paths;
        self.rays += pass.rays;
        self.nonfinite_samples += pass.nonfinite_samples;
        self.spp += pass.spp;
    }
}

impl<'a> PathTracer<'a> {
    /// A path tracer; fails on invalid settings.
    pub fn new(scene: &'a RenderScene, camera: Camera, settings: RenderSettings) -> Result<Self, RenderError> {
        settings.validate()?;
        let pool = Workers::new(settings.threads)?;
        Ok(PathTracer { scene, camera, settings, pool })
    }

    /// The settings in use.
    pub fn settings(&self) -> &RenderSettings {
        &self.settings
    }

    /// A new empty film of the right size.
    pub fn film(&self) -> Film {
        Film::new(self.settings.width, self.settings.height)
    }

    /// Adds `samples` samples per pixel to `film`, one pass of 1 spp at a time.
    pub fn render(&self, film: &mut Film, samples: u32) -> Result<RenderStats, RenderError> {
        self.render_observed(film, samples, &Quiet)
    }

    /// As [`PathTracer::render`], reporting each finished image row to `progress`; stops early
    /// (keeping whole passes) if it is cancelled.
    pub fn render_observed(
        &self,
        film: &mut Film,
        samples: u32,
        observer: &dyn Progress,
    ) -> Result<RenderStats, RenderError> {
        self.check_film(film, samples)?;
        let start = Instant::now();
        let mut stats = RenderStats::default();
        for _ in 0..samples {
            if observer.cancelled() {
                break;
            }
            stats.add_pass(&self.pass(film, observer));
        }
        stats.seconds = start.elapsed().as_secs_f64();
        Ok(stats)
    }

    /// Renders whole 1-spp passes until `budget` would be exceeded (at least one pass), as
    /// equal-time comparisons and `--time` need. The next pass is predicted from the slowest so far.
    pub fn render_for(
        &self,
        film: &mut Film,
        budget: Duration,
        observer: &dyn Progress,
    ) -> Result<RenderStats, RenderError> {
        self.check_film(film, 1)?;
        let start = Instant::now();
        let mut stats = RenderStats::default();
        let mut slowest = 0.0f64;
        loop {
            let elapsed = start.elapsed().as_secs_f64();
            if stats.spp > 0 && (elapsed + slowest > budget.as_secs_f64() || observer.cancelled()) {
                break;
            }
            if film.spp == MAX_SPP {
                break;
            }
            let t = Instant::now();
            let pass = self.pass(film, observer);
            slowest = slowest.max(t.elapsed().as_secs_f64());
            stats.add_pass(&pass);
        }
        stats.seconds = start.elapsed().as_secs_f64();
        Ok(stats)
    }

    fn check_film(&self, film: &Film, samples: u32) -> Result<(), RenderError> {
        if (film.width, film.height) != (self.settings.width, self.settings.height) {
            return Err(RenderError::FilmSize {
                film: (film.width, film.height),
                settings: (self.settings.width, self.settings.height),
            });
        }
        if samples == 0 || samples > MAX_SPP || film.spp as u64 + samples as u64 > MAX_SPP as u64 {
            return Err(RenderError::Samples { have: film.spp, asked: samples });
        }
        Ok(())
    }

    /// One sample per pixel over the whole image.
    fn pass(&self, film: &mut Film, observer: &dyn Progress) -> RenderStats {
        self.pool.install(|| self.pass_inner(film, observer))
    }

    fn pass_inner(&self, film: &mut Film, observer: &dyn Progress) -> RenderStats {
        let (w, h) = (self.settings.width, self.settings.height);
        let index = film.spp;
        let rays = AtomicU64::new(0);
        let nonfinite = AtomicU64::new(0);
        let integrator = Integrator {
            scene: &self.scene.scene,
            bvh: &self.scene.bvh,
            lights: &self.scene.lights,
            max_depth: self.settings.max_depth,
        };
        let wu = w as usize;
        film.beauty
            .par_chunks_mut(wu)
            .zip(film.beauty_sq.par_chunks_mut(wu))
            .zip(film.albedo.par_chunks_mut(wu))
            .zip(film.normal.par_chunks_mut(wu))
            .zip(film.depth.par_chunks_mut(wu))
            .enumerate()
            .for_each(|(y, ((((beauty, beauty_sq), albedo), normal), depth))| {
                let mut row_rays = 0u64;
                let mut row_bad = 0u64;
                for x in 0..wu {
                    let pixel = y as u64 * w as u64 + x as u64;
                    let mut sampler = Sampler::new(self.settings.seed, pixel, index);
                    // Importance-sample the tent pixel filter: every sample has weight 1.
                    let u = sampler.get_2d();
                    let film_pos = Vec2::new(x as f32 + 0.5 + sample_tent(u.x), y as f32 + 0.5 + sample_tent(u.y));
                    let (o, d) = self.camera.ray(film_pos, w, h);
                    // The near clip: the camera ray sees nothing before its plane.
                    let r = integrator.trace_clipped(o, d, self.camera.clip_distance(d), &mut sampler);
                    row_rays += r.rays as u64;
                    let mut l = r.radiance;
                    if !l.is_finite() {
                        row_bad += 1;
                        l = Vec3::ZERO;
                    }
                    if let Some(c) = self.settings.clamp {
                        let m = l.max_element();
                        if m > c {
                            l *= c / m;
                        }
                    }
                    // Quantised sums are exact, hence independent of how samples are grouped.
                    let q = quantize3(l);
                    beauty[x] += q;
                    beauty_sq[x] += quantize_square(q);
                    if r.aov.albedo.is_finite() && r.aov.normal.is_finite() && r.aov.depth.is_finite() {
                        albedo[x] += quantize3(r.aov.albedo);
                        normal[x] += quantize3(r.aov.normal);
                        depth[x] += quantize(r.aov.depth as f64);
                    }
                }
                rays.fetch_add(row_rays, Ordering::Relaxed);
                nonfinite.fetch_add(row_bad, Ordering::Relaxed);
                observer.inc(1);
            });
        film.spp += 1;
        let bad = nonfinite.into_inner();
        film.nonfinite_samples += bad;
        RenderStats {
            paths: w as u64 * h as u64,
            rays: rays.into_inner(),
            nonfinite_samples: bad,
            seconds: 0.0,
            spp: 1,
        }
    }
}
