//! The reference image a benchmark scores against: loaded from a file, or rendered as two
//! independent halves whose sample count doubles until their difference says the mean is
//! converged (or a cap is reached), and cached under a key of everything it depends on.

use std::path::Path;

use rtd_image::{HdrImage, Layer, Layers, Progress};
use rtd_pipeline::SceneView;
use rtd_render::{Film, PathTracer, RenderSettings};
use serde::{Deserialize, Serialize};

use crate::BenchError;

/// How a rendered reference is made: where its sample count starts, the estimated relMSE it
/// renders down to, and the most samples it may take.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceOptions {
    /// Samples per pixel of the first round (split between the two halves).
    pub spp: u32,
    /// The estimated remaining relMSE at which doubling stops.
    pub relmse: f64,
    /// The most samples per pixel; doubling stops before exceeding it.
    pub max_spp: u32,
}

impl Default for ReferenceOptions {
    fn default() -> Self {
        ReferenceOptions { spp: 1024, relmse: 1e-3, max_spp: 16384 }
    }
}

impl ReferenceOptions {
    /// Sets the first round's samples per pixel.
    pub fn spp(mut self, spp: u32) -> Self {
        self.spp = spp;
        self
    }

    /// Sets the estimated relMSE at which doubling stops.
    pub fn relmse(mut self, relmse: f64) -> Self {
        self.relmse = relmse;
        self
    }

    /// Sets the most samples per pixel.
    pub fn max_spp(mut self, max_spp: u32) -> Self {
        self.max_spp = max_spp;
        self
    }
}

/// A reference image, where it came from, and its estimated remaining relMSE.
pub struct Reference {
    /// The image.
    pub image: HdrImage,
    /// Its samples per pixel (None if loaded from a file).
    pub spp: Option<u32>,
    /// Its spp and file, for the report.
    pub description: String,
    /// Estimated relMSE left in it (from two independent halves; None if loaded).
    pub relmse: Option<f64>,
}

/// Loads `given` (which must be `width` × `height`) or renders a reference of `view` with
/// [`render_reference`], cached in `cache_dir` under a key of the scene's bytes, the size, the
/// seed, `options` and the rtd version. `seed` is the measured render's; the halves' seeds differ
/// from it.
pub fn reference(
    view: &SceneView,
    (width, height, seed): (u32, u32, u64),
    options: &ReferenceOptions,
    given: Option<&Path>,
    cache_dir: &Path,
    progress: &dyn Progress,
) -> Result<Reference, BenchError> {
    if let Some(p) = given {
        let image =
            rtd_image::read_exr(p)?.image(Layer::Beauty).ok_or_else(|| BenchError::msg(p, "no R,G,B channels"))?;
        if (image.width, image.height) != (width, height) {
            return Err(BenchError::msg(
                p,
                format!("reference is {}x{}, the benchmark renders {width}x{height}", image.width, image.height),
            ));
        }
        let description = format!("loaded from {}", p.display());
        return Ok(Reference { image, spp: None, description, relmse: None });
    }
    let bytes = std::fs::read(&view.path).map_err(|e| BenchError::io(&view.path, e))?;
    // FNV-1a over everything the reference depends on.
    let mut key = 0xcbf2_9ce4_8422_2325u64;
    let o = options;
    let version = env!("CARGO_PKG_VERSION");
    let settings = format!("{width}x{height}x{seed}x{}x{:e}x{}x{version}", o.spp, o.relmse, o.max_spp);
    for b in bytes.iter().chain(settings.as_bytes()) {
        key = (key ^ *b as u64).wrapping_mul(0x100_0000_01b3);
    }
    let path = cache_dir.join(format!("reference-{key:016x}.exr"));
    if let Ok(l) = rtd_image::read_exr(&path) {
        // A cached file of another size or without its sample count (damaged, or written by
        // hand) is rendered again.
        let sized = |i: &HdrImage| (i.width, i.height) == (width, height);
        let spp = l.plane(Layer::SampleCount).and_then(|s| s.first().copied()).filter(|s| *s >= 1.0);
        if let (Some(image), Some(noise), Some(spp)) =
            (l.image(Layer::Beauty).filter(sized), l.plane(Layer::NoiseEstimate), spp)
        {
            return Ok(Reference::rendered(
                image,
                spp as u32,
                noise[0] as f64,
                options,
                format!("cached {}", path.display()),
            ));
        }
    }
    let (image, spp, noise) = render_reference(view, (width, height, seed), options, progress)?;
    std::fs::create_dir_all(cache_dir).map_err(|e| BenchError::io(cache_dir, e))?;
    let mut layers = Layers::new(width, height);
    layers.put_image(Layer::Beauty, &image);
    let pixels = (width * height) as usize;
    layers.put_plane(Layer::NoiseEstimate, vec![noise as f32; pixels]);
    layers.put_plane(Layer::SampleCount, vec![spp as f32; pixels]);
    rtd_image::write_exr(&path, &layers)?;
    Ok(Reference::rendered(image, spp, noise, options, format!("rendered and cached {}", path.display())))
}

impl Reference {
    /// A rendered reference of `spp` samples with estimated relMSE `noise`, described with its
    /// spp, whether the cap stopped it short of `options.relmse`, and `origin`.
    fn rendered(image: HdrImage, spp: u32, noise: f64, options: &ReferenceOptions, origin: String) -> Self {
        let short = if noise > options.relmse {
            format!(" (stopped by the {} spp cap, short of the {:.0e} relMSE target)", options.max_spp, options.relmse)
        } else {
            String::new()
        };
        let description = format!("{spp} spp{short}, {origin}");
        Reference { image, spp: Some(spp), description, relmse: Some(noise) }
    }
}

/// Renders two independent halves of `options.spp` samples between them, then doubles both
/// while their estimated remaining relMSE is above `options.relmse` and twice the samples stay
/// within `options.max_spp`. Returns their mean, its samples per pixel and that estimate. Each
/// doubling continues the same two films, so a reference of N spp is the same image however
/// many rounds reached it.
pub fn render_reference(
    view: &SceneView,
    (width, height, seed): (u32, u32, u64),
    options: &ReferenceOptions,
    progress: &dyn Progress,
) -> Result<(HdrImage, u32, f64), BenchError> {
    let tracer = |half_seed: u64| {
        PathTracer::new(&view.scene, view.camera.clone(), RenderSettings::new(width, height).seed(half_seed))
    };
    let halves = [tracer(seed ^ 0xA5A5_0001)?, tracer(seed ^ 0x5A5A_0002)?];
    let mut films: Vec<Film> = halves.iter().map(PathTracer::film).collect();
    let mut half_spp = (options.spp / 2).max(1);
    loop {
        progress.note(&format!("rendering a {} spp reference (cached afterwards)", 2 * half_spp));
        for (film, tracer) in films.iter_mut().zip(&halves) {
            tracer.render(film, half_spp - film.spp)?;
        }
        // The halves' difference estimates the mean's remaining relMSE.
        let (mean, noise) = rtd_image::metrics::mean_of_halves_with_noise(&films[0].beauty(), &films[1].beauty());
        let spp = 2 * half_spp;
        if noise <= options.relmse || 2 * spp > options.max_spp {
            return Ok((mean, spp, noise));
        }
        half_spp *= 2;
    }
}
