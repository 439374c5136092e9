//! The service's errors. [`ServiceError`] is what library calls return; [`ApiError`] is what
//! a refused HTTP request answers: a status and one sentence, as JSON.

use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};

/// What can go wrong in the service, each with its cause.
#[derive(Debug, thiserror::Error)]
pub enum ServiceError {
    /// A setting or URL is unusable.
    #[error("{0}")]
    Config(String),
    /// The database could not be reached.
    #[error("cannot connect to {url}: {source}")]
    Connect {
        /// The URL, password hidden.
        url: String,
        /// What sqlx said.
        source: sqlx::Error,
    },
    /// The schema could not be brought up to date.
    #[error("cannot migrate the schema of {url}: {source}")]
    Migrate {
        /// The URL, password hidden.
        url: String,
        /// What sqlx said.
        source: sqlx::migrate::MigrateError,
    },
    /// A query failed.
    #[error("database: {0}")]
    Database(#[from] sqlx::Error),
    /// The pipeline refused or failed the work.
    #[error(transparent)]
    Pipeline(#[from] rtd_pipeline::PipelineError),
    /// A dataset could not be read, added to or rendered.
    #[error(transparent)]
    Dataset(#[from] rtd_train::TrainError),
    /// The job's inputs could not be worked on; the sentence is for its user.
    #[error("{0}")]
    Job(String),
    /// A stored record is not what the schema promises.
    #[error("corrupt record: {0}")]
    Corrupt(String),
    /// The OS's random source failed.
    #[error("no random key: {0}")]
    Random(getrandom::Error),
    /// A file or socket operation failed.
    #[error("{what}: {source}")]
    Io {
        /// What was being done.
        what: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Uploads are refused until the queue drains.
    #[error("the queue is full")]
    QueueFull,
}

impl ServiceError {
    /// An I/O failure while doing `what`.
    pub fn io(what: impl Into<String>, source: std::io::Error) -> Self {
        ServiceError::Io { what: what.into(), source }
    }
}

/// A refused or failed request: an HTTP status and one sentence for the user.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ApiError {
    /// The status answered.
    pub status: StatusCode,
    /// The sentence, ending with a full stop.
    pub message: String,
    /// Seconds after which the client may try again (503 and 429).
    pub retry_after: Option<u64>,
}

impl ApiError {
    /// A refusal with `status` and `message` (a full stop is added if missing).
    pub fn new(status: StatusCode, message: impl Into<String>) -> Self {
        let mut message: String = message.into().replace('\n', " ");
        if !message.ends_with('.') {
            message.push('.');
        }
        ApiError { status, message, retry_after: None }
    }
    /// 400: the request itself is wrong.
    pub fn bad_request(message: impl Into<String>) -> Self {
        ApiError::new(StatusCode::BAD_REQUEST, message)
    }
    /// 404 that says only that there is no such job, whatever the key was.
    pub fn no_such_job() -> Self {
        ApiError::new(StatusCode::NOT_FOUND, "No such job")
    }
    /// Adds a `Retry-After` header.
    pub fn retry_after(mut self, seconds: u64) -> Self {
        self.retry_after = Some(seconds);
        self
    }
}

impl From<ServiceError> for ApiError {
    fn from(e: ServiceError) -> Self {
        match e {
            ServiceError::QueueFull => {
                ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "The queue is full; try again later").retry_after(30)
            }
            other => {
                tracing::error!(error = %other, "request failed");
                ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, "The server could not complete the request")
            }
        }
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let body = serde_json::json!({ "error": self.message });
        let mut response = (self.status, axum::Json(body)).into_response();
        if let Some(s) = self.retry_after {
            response.headers_mut().insert(header::RETRY_AFTER, HeaderValue::from(s));
        }
        response
    }
}
