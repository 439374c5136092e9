//! rtd's benchmarks, all on the one [`rtd_pipeline::Pipeline`]: the equal-time comparison
//! ([`etrt`]) of a denoised low-spp render against plain path tracing given the same wall time,
//! the multi-scene [`suite`] with its spp sweep, [`speed`] figures (against raw BVH
//! [`traversal`]), and the [`validation`]
//! comparison on a dataset's held-out views, with pictures ([`figures`]).

#![warn(missing_docs)]

mod error;
pub mod etrt;
pub mod figures;
pub mod light_selection;
pub mod procedural;
pub mod reference;
pub mod report_files;
pub mod scaling;
pub mod speed;
pub mod suite;
pub mod traversal;
pub mod validation;

pub use error::BenchError;
pub use etrt::{run_etrt, EtrtOptions, EtrtReport};

/// Border, in pixels, excluded from every metric a benchmark reports.
pub const METRIC_BORDER: u32 = 8;
