//! rtd's benchmarks: the equal-time comparison ([`etrt`]) of a denoised low-spp render against
//! plain path tracing given the same wall time, with pictures ([`figures`]).

pub mod etrt;
pub mod figures;
pub mod speed;
pub mod suite;

pub use etrt::{run_etrt, EtrtOptions, EtrtReport};
pub use rtd_train::{Progress, Quiet, TrainError as BenchError};
