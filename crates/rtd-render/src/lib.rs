//! rtd's path tracer.
//!
//! [`RenderScene`] prepares a loaded scene (BVH, lights); [`PathTracer`] renders it through a
//! camera into a [`Film`], progressively and deterministically: sample *i* of pixel *p* depends
//! only on (seed, p, i, dimension), so 8 spp continued by 8 more equals 16 spp, byte for byte,
//! whatever the thread count.

pub mod bsdf;
pub mod bvh;
mod film;
pub mod integrator;
pub mod lights;
pub mod microfacet;
mod render;
pub mod sampler;
pub mod sampling;
pub mod surface;

pub use bsdf::{Bsdf, BsdfParams, BsdfSample};
pub use bvh::{SceneBvh, MAX_BUNDLE, NO_TRIANGLE};
pub use film::Film;
pub use lights::LightSet;
pub use render::{
    PathTracer, RenderObserver, RenderScene, RenderSettings, RenderStats, Silent, Workers, MAX_PIXELS, MAX_RESOLUTION,
    MAX_SPP,
};
pub use sampler::Sampler;

/// Errors from setting up or running a render.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// A setting is out of range; the message names it.
    #[error("{0}")]
    InvalidSettings(String),
}
