//! rtd as a web service, as the 2017 thesis served its denoiser (sections 5 and 6.5): an upload
//! page and a JSON API that check an upload and queue it in a database, render nodes that
//! claim the work, and the result served under an unguessable key, with a 1–5 rating.
//!
//! - [`Database`]: embedded SQLite on one machine, PostgreSQL for many, one set of queries.
//! - [`JobStore`]: jobs, inputs, results, ratings and retention.
//! - [`JobQueue`]: tasks claimed with a lease (`FOR UPDATE SKIP LOCKED` on PostgreSQL),
//!   renewed while worked on and completed exactly once.
//! - [`Worker`]: a render node's loop; [`execute`] does one task with the same library calls
//!   as the command line, so results have the command line's bytes. A render job is split into
//!   sample ranges that any workers render, merged exactly ([`rtd_render::Film::merge`]).
//! - [`DatasetJob`]: `rtd datagen --database`, a training set rendered a scene per task on
//!   any workers and gathered into one directory, the same as a one-machine run.
//! - [`router`]: the axum router; [`start_server`] and [`run_worker`] are `rtd serve` and
//!   `rtd worker`.

#![warn(missing_docs)]

mod api;
mod config;
mod database;
mod dataset_job;
mod error;
pub mod execute;
mod jobs;
mod key;
mod metrics;
mod pages;
mod queue;
mod scene_upload;
mod server;
mod upload;
mod worker;

pub use api::{router, AppState};
pub use config::{
    ServiceConfig, DEFAULT_KEEP, DEFAULT_MAX_QUEUED, DEFAULT_MAX_UPLOAD, DEFAULT_SPP, MAX_ATTEMPTS, MAX_COMMENT_CHARS,
    MAX_RANGES_PER_JOB, MAX_SPAN, MAX_TEXT_FIELD_CHARS, MIN_LEASE,
};
pub use database::{now_ms, redact, sqlite_url, Backend, Database};
pub use dataset_job::{DatasetJob, DatasetRun, QUEUE_FILE};
pub use error::{ApiError, ServiceError};
pub use execute::{execute, TaskInputs, TaskProgress};
pub use jobs::{Input, JobKind, JobStatus, JobStore, NewJob, QueueCounts, Rating, RenderParams, ResultFile};
pub use key::JobKey;
pub use queue::{Claim, JobQueue, TaskKind, TaskOutput};
pub use scene_upload::check_scene;
pub use server::{run_worker, shutdown_signal, start_server, RunningServer};
pub use worker::Worker;
