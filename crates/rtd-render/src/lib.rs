//! rtd's path tracer.
//!
//! [`RenderScene`] prepares a loaded scene (BVH, lights); [`PathTracer`] renders it through a
//! camera into a [`Film`], progressively and deterministically: sample *i* of pixel *p* depends
//! only on (seed, p, i, dimension), so 8 spp continued by 8 more equals 16 spp, byte for byte,
//! whatever the thread count.

#![warn(missing_docs)]

pub mod bsdf;
pub mod bvh;
pub mod energy;
mod film;
pub mod integrator;
pub mod light_tree;
pub mod lights;
pub mod microfacet;
mod prefetch;
mod render;
pub mod sampler;
pub mod sampling;
pub mod sheen;
pub mod surface;

pub use bsdf::{Bsdf, BsdfParams, BsdfSample};
pub use bvh::{SceneBvh, MAX_BUNDLE, NO_TRIANGLE};
pub use film::{Film, FilmMergeError, SAMPLE_QUANTUM};
pub use lights::{LightSelection, LightSet};
pub use prefetch::prefetch;
pub use render::{PathTracer, RenderScene, RenderSettings, RenderStats, Workers, MAX_DEPTH, MAX_SPP, SPP_LADDER};
pub use sampler::Sampler;

use rtd_image::{MAX_DIMENSION, MAX_PIXELS};

/// Errors from setting up or running a render; each says which setting is out of range.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// A side is 0 or above [`MAX_DIMENSION`].
    #[error("resolution {width}x{height} is outside 1..={MAX_DIMENSION} per side")]
    Resolution {
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
    },
    /// The image has more than [`MAX_PIXELS`] pixels.
    #[error(
        "resolution {width}x{height} exceeds {MAX_PIXELS} pixels (8192x8192); render tiles or lower the resolution"
    )]
    TooManyPixels {
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
    },
    /// The maximum depth is above [`MAX_DEPTH`].
    #[error("max depth {0} is above {MAX_DEPTH}")]
    MaxDepth(u32),
    /// The per-sample clamp is not a positive finite number.
    #[error("clamp {0} must be a positive finite number")]
    Clamp(f32),
    /// Zero worker threads were asked for.
    #[error("threads must be at least 1")]
    NoThreads,
    /// The worker pool could not be started.
    #[error("cannot start {threads} render threads: {source}")]
    ThreadPool {
        /// Threads asked for.
        threads: usize,
        /// What rayon said.
        source: rayon::ThreadPoolBuildError,
    },
    /// A film of another size was given to the path tracer.
    #[error("film size {}x{} does not match the render settings' {}x{}", film.0, film.1, settings.0, settings.1)]
    FilmSize {
        /// The film's width and height.
        film: (u32, u32),
        /// The settings' width and height.
        settings: (u32, u32),
    },
    /// The samples asked for, with those already in the film, fall outside 1..=[`MAX_SPP`].
    #[error("samples per pixel must be in 1..={MAX_SPP} in total (the film has {have}, {asked} more were asked for)")]
    Samples {
        /// Samples already in the film.
        have: u32,
        /// Samples asked for.
        asked: u32,
    },
}
