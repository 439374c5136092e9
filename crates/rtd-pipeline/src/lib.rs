//! rtd's pipeline as one library call, the one the command line, the benchmarks and the
//! service all use:
//!
//! 1. [`SceneView::load`]: load the scene file, apply an environment, pick the camera, build
//!    the BVH and light set;
//! 2. [`Pipeline::run`]: render progressively and interruptibly (to a sample count or a time
//!    budget), rasterise the guide pass, denoise, each stage timed;
//! 3. [`PipelineRun::write`]: write the image (an EXR with every layer, or a tonemapped 8-bit
//!    file), and [`RenderReport`], what `rtd render --report` serialises.
//!
//! [`DenoiseSources`] is the same for `rtd denoise`: read a noisy image and its guide layers
//! from files of any renderer, check them, and denoise.

#![warn(missing_docs)]

mod denoise_sources;
mod error;
mod pipeline;
mod report;
mod view;

pub use denoise_sources::{DenoiseOutcome, DenoiseSources, Denoised};
pub use error::PipelineError;
pub use pipeline::{denoise_input, Budget, Pipeline, PipelineRun, StageTimings};
pub use report::RenderReport;
pub use view::{CameraChoice, SceneView, DEFAULT_WIDTH};
