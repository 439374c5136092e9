//! The upload page, the job page and their assets, compiled into the binary: the service
//! fetches nothing from elsewhere and works with no network beyond itself.

use axum::extract::Path;
use axum::http::{header, StatusCode};
use axum::response::{Html, IntoResponse, Response};

use crate::ApiError;

/// `GET /`: the upload page.
pub async fn index() -> Html<&'static str> {
    Html(include_str!("../assets/index.html"))
}

/// `GET /jobs/{key}`: the job page (one page for every key; its script asks the API).
pub async fn job_page(Path(_key): Path<String>) -> Html<&'static str> {
    Html(include_str!("../assets/job.html"))
}

/// `GET /assets/{file}`: the pages' style sheet and scripts.
pub async fn asset(Path(file): Path<String>) -> Response {
    let (body, mime) = match file.as_str() {
        "app.css" => (include_str!("../assets/app.css"), "text/css; charset=utf-8"),
        "upload.js" => (include_str!("../assets/upload.js"), "text/javascript; charset=utf-8"),
        "job.js" => (include_str!("../assets/job.js"), "text/javascript; charset=utf-8"),
        _ => return ApiError::new(StatusCode::NOT_FOUND, "Not found").into_response(),
    };
    ([(header::CONTENT_TYPE, mime)], body).into_response()
}
