//! The HTTP API and the pages, as an axum router over the job store. Every refusal is a 4xx
//! (or 503) with a one-sentence JSON error, and a refused upload stores nothing.

use std::net::{IpAddr, SocketAddr};
use std::num::NonZeroU32;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use axum::body::Bytes;
use axum::extract::{ConnectInfo, DefaultBodyLimit, Multipart, Path, State};
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use governor::clock::{Clock, DefaultClock};
use governor::{DefaultKeyedRateLimiter, Quota, RateLimiter};
use serde::Deserialize;

use crate::config::MAX_COMMENT_CHARS;
use crate::jobs::{JobStore, ResultFile};
use crate::upload::read_upload;
use crate::{metrics, pages, ApiError, JobKey, ServiceConfig};

/// What every handler shares.
#[derive(Clone)]
pub struct AppState {
    /// The jobs.
    pub store: JobStore,
    /// Limits and timings.
    pub config: ServiceConfig,
    /// Uploads and ratings per client address.
    limiter: Arc<DefaultKeyedRateLimiter<IpAddr>>,
    /// False once shutdown began: uploads are refused.
    accepting: Arc<AtomicBool>,
}

impl AppState {
    /// The state for `store` under `config`.
    pub fn new(store: JobStore, config: ServiceConfig) -> Self {
        let per_minute = NonZeroU32::new(config.uploads_per_minute.max(1)).unwrap_or(NonZeroU32::MIN);
        let limiter = Arc::new(RateLimiter::keyed(Quota::per_minute(per_minute)));
        AppState { store, config, limiter, accepting: Arc::new(AtomicBool::new(true)) }
    }

    /// Stops taking uploads (the server is shutting down).
    pub fn stop_accepting(&self) {
        self.accepting.store(false, Ordering::SeqCst);
    }

    /// Forgets client addresses whose allowance has refilled, so the limiter's memory stays
    /// bounded by recent clients.
    pub fn forget_idle_clients(&self) {
        self.limiter.retain_recent();
    }

    /// Refuses `client` with 429 if it has used up its uploads for now.
    fn check_rate(&self, client: IpAddr) -> Result<(), ApiError> {
        self.limiter.check_key(&client).map_err(|not_until| {
            let wait = not_until.wait_time_from(DefaultClock::default().now()).as_secs().max(1);
            ApiError::new(StatusCode::TOO_MANY_REQUESTS, "Too many requests from this address; slow down")
                .retry_after(wait)
        })
    }
}

/// The router: API, pages and assets.
pub fn router(state: AppState) -> Router {
    let max_upload = state.config.max_upload;
    Router::new()
        .route("/", get(pages::index))
        .route("/jobs/{key}", get(pages::job_page))
        .route("/assets/{file}", get(pages::asset))
        .route("/healthz", get(healthz))
        .route("/metrics", get(metrics::metrics))
        .route("/api/jobs", post(create_job))
        .route("/api/jobs/{key}", get(job_status))
        .route("/api/jobs/{key}/rating", post(rate_job))
        .route("/api/jobs/{key}/{file}", get(job_file))
        .fallback(|| async { ApiError::new(StatusCode::NOT_FOUND, "Not found") })
        .layer(DefaultBodyLimit::max(max_upload))
        .with_state(state)
}

/// `POST /api/jobs`: check the upload and queue it.
async fn create_job(
    State(state): State<AppState>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    multipart: Multipart,
) -> Result<Response, ApiError> {
    if !state.accepting.load(Ordering::SeqCst) {
        return Err(ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "The server is shutting down").retry_after(30));
    }
    state.check_rate(peer.ip())?;
    let timeout = state.config.upload_timeout;
    let job =
        tokio::time::timeout(timeout, read_upload(multipart, state.config.max_upload, Some(peer.ip().to_string())))
            .await
            .map_err(|_| {
                ApiError::new(
                    StatusCode::REQUEST_TIMEOUT,
                    format!("The upload took longer than {} s", timeout.as_secs()),
                )
            })??;
    let key = state.store.create(&job, state.config.render_chunk_spp, state.config.max_queued).await?;
    tracing::info!(job = %key, kind = job.kind.as_str(), client = %peer.ip(), "job queued");
    let body = serde_json::json!({ "key": key.as_str(), "state": "queued" });
    Ok((StatusCode::CREATED, [(header::LOCATION, format!("/jobs/{key}"))], Json(body)).into_response())
}

/// The key in a path, or a 404 that says nothing about why.
fn key_of(text: &str) -> Result<JobKey, ApiError> {
    JobKey::parse(text).ok_or_else(ApiError::no_such_job)
}

/// `GET /api/jobs/{key}`.
async fn job_status(State(state): State<AppState>, Path(key): Path<String>) -> Result<Response, ApiError> {
    let key = key_of(&key)?;
    let status = state.store.status(&key).await?.ok_or_else(ApiError::no_such_job)?;
    Ok(([(header::CACHE_CONTROL, "no-store")], Json(status)).into_response())
}

/// `GET /api/jobs/{key}/result.exr`, `result.png` and `input.png`: 404 until the job is done.
async fn job_file(
    State(state): State<AppState>,
    Path((key, file)): Path<(String, String)>,
) -> Result<Response, ApiError> {
    let key = key_of(&key)?;
    let (which, mime) = match file.as_str() {
        "result.exr" => (ResultFile::Exr, "image/x-exr"),
        "result.png" => (ResultFile::Png, "image/png"),
        "input.png" => (ResultFile::InputPng, "image/png"),
        _ => return Err(ApiError::new(StatusCode::NOT_FOUND, "Not found")),
    };
    let bytes = state
        .store
        .result(&key, which)
        .await?
        .ok_or_else(|| ApiError::new(StatusCode::NOT_FOUND, "No such result (the job may not be done yet)"))?;
    let disposition = format!("inline; filename=\"rtd-{}-{file}\"", &key.as_str()[..12]);
    Ok(([(header::CONTENT_TYPE, mime.to_string()), (header::CONTENT_DISPOSITION, disposition)], bytes).into_response())
}

/// The body of `POST /api/jobs/{key}/rating`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RatingBody {
    rating: i64,
    comment: Option<String>,
}

/// `POST /api/jobs/{key}/rating`: the thesis's 1–5 rating, with a comment.
async fn rate_job(
    State(state): State<AppState>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    Path(key): Path<String>,
    body: Bytes,
) -> Result<Response, ApiError> {
    let key = key_of(&key)?;
    state.check_rate(peer.ip())?;
    let body: RatingBody = serde_json::from_slice(&body)
        .map_err(|_| ApiError::bad_request("The body must be JSON like {\"rating\": 4, \"comment\": \"…\"}"))?;
    if !(1..=5).contains(&body.rating) {
        return Err(ApiError::bad_request("The rating must be a whole number from 1 to 5"));
    }
    let comment = body.comment.filter(|c| !c.trim().is_empty());
    if comment.as_ref().is_some_and(|c| c.chars().count() > MAX_COMMENT_CHARS) {
        return Err(ApiError::bad_request(format!("The comment is over {MAX_COMMENT_CHARS} characters")));
    }
    if !state.store.rate(&key, body.rating, comment).await? {
        return Err(ApiError::no_such_job());
    }
    Ok(Json(serde_json::json!({ "ok": true })).into_response())
}

/// `GET /healthz`: 200 while the database answers, else 503.
async fn healthz(State(state): State<AppState>) -> Response {
    if state.store.database().ping().await {
        (StatusCode::OK, "ok\n").into_response()
    } else {
        ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "The database does not answer").into_response()
    }
}
