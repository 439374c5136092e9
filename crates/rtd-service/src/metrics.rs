//! `GET /metrics` in Prometheus's text format: the queue's state as the database holds it,
//! read at each scrape, so every server of a multi-machine deployment reports the same.

use axum::extract::State;
use axum::http::header;
use axum::response::{IntoResponse, Response};
use prometheus_client::encoding::text::encode;
use prometheus_client::metrics::gauge::Gauge;
use prometheus_client::registry::Registry;
use std::sync::atomic::AtomicU64;

use crate::api::AppState;
use crate::ApiError;

/// The metrics page.
pub async fn metrics(State(state): State<AppState>) -> Result<Response, ApiError> {
    let c = state.store.counts().await?;
    let mut registry = Registry::default();
    let mut int = |name: &str, help: &str, v: i64| {
        let g: Gauge = Gauge::default();
        g.set(v);
        registry.register(name, help, g);
    };
    int("rtd_queue_depth", "Jobs waiting for a worker", c.queued);
    int("rtd_jobs_running", "Jobs being worked on", c.running);
    int("rtd_jobs_done", "Finished jobs still kept", c.done);
    int("rtd_jobs_failed", "Failed jobs still kept", c.failed);
    int("rtd_workers_seen", "Workers that reported in the last minute", c.workers_seen);
    let seconds: Gauge<f64, AtomicU64> = Gauge::default();
    seconds.set(c.done_seconds);
    registry.register("rtd_job_seconds", "Seconds from upload to result, summed over the kept finished jobs", seconds);
    let mut text = String::new();
    encode(&mut text, &registry).map_err(|_| crate::ServiceError::Corrupt("metrics encoding".into()))?;
    Ok(([(header::CONTENT_TYPE, "application/openmetrics-text; version=1.0.0; charset=utf-8")], text).into_response())
}
