//! Reading and checking `POST /api/jobs`: the multipart fields, each image judged by its bytes
//! and sized from its header before anything is decoded, the scene checked for files it
//! names, and the render settings held to the command line's limits. A refusal stores nothing.

use std::path::{Path, PathBuf};

use axum::extract::multipart::{Multipart, MultipartError};
use axum::http::StatusCode;
use rtd_pipeline::DenoiseSources;
use rtd_render::{RenderSettings, MAX_SPP};

use crate::config::{DEFAULT_SPP, MAX_TEXT_FIELD_CHARS};
use crate::jobs::{Input, JobKind, NewJob, RenderParams};
use crate::scene_upload::check_scene;
use crate::ApiError;

/// The file fields a job may carry.
const FILE_FIELDS: [&str; 5] = ["color", "guide", "albedo", "normal", "scene"];
/// The text fields a job may carry.
const TEXT_FIELDS: [&str; 6] = ["spp", "width", "height", "camera", "name", "email"];

/// The fields of an upload as they arrived.
#[derive(Default)]
struct Fields {
    files: Vec<(String, Vec<u8>)>,
    text: Vec<(String, String)>,
}

impl Fields {
    fn file(&self, name: &str) -> Option<&[u8]> {
        self.files.iter().find(|(n, _)| n == name).map(|(_, b)| b.as_slice())
    }
    fn text(&self, name: &str) -> Option<&str> {
        self.text.iter().find(|(n, _)| n == name).map(|(_, t)| t.as_str()).filter(|t| !t.is_empty())
    }
}

/// Reads every field of `multipart`, refusing unknown, repeated and empty ones.
async fn read_fields(mut multipart: Multipart, max_upload: usize) -> Result<Fields, ApiError> {
    let mut fields = Fields::default();
    while let Some(field) = multipart.next_field().await.map_err(|e| multipart_error(e, max_upload))? {
        let name = field.name().unwrap_or_default().to_string();
        let is_file = FILE_FIELDS.contains(&name.as_str());
        if !is_file && !TEXT_FIELDS.contains(&name.as_str()) {
            let shown: String = name.chars().take(40).collect();
            return Err(ApiError::bad_request(format!("Unknown field {shown:?}; see the API in the README")));
        }
        if fields.files.iter().any(|(n, _)| *n == name) || fields.text.iter().any(|(n, _)| *n == name) {
            return Err(ApiError::bad_request(format!("The field {name:?} is given twice")));
        }
        let bytes = field.bytes().await.map_err(|e| multipart_error(e, max_upload))?;
        if is_file {
            if bytes.is_empty() {
                return Err(ApiError::bad_request(format!("The file {name:?} is empty")));
            }
            fields.files.push((name, bytes.to_vec()));
        } else {
            let text = String::from_utf8(bytes.to_vec())
                .map_err(|_| ApiError::bad_request(format!("The field {name:?} is not UTF-8 text")))?;
            if text.chars().count() > MAX_TEXT_FIELD_CHARS {
                return Err(ApiError::bad_request(format!(
                    "The field {name:?} is over {MAX_TEXT_FIELD_CHARS} characters"
                )));
            }
            fields.text.push((name, text.trim().to_string()));
        }
    }
    Ok(fields)
}

/// A multipart failure as a refusal: 413 for a body over the limit, else 400.
fn multipart_error(e: MultipartError, max_upload: usize) -> ApiError {
    if e.status() == StatusCode::PAYLOAD_TOO_LARGE {
        ApiError::new(StatusCode::PAYLOAD_TOO_LARGE, format!("The upload is larger than {} MiB", max_upload >> 20))
    } else {
        ApiError::bad_request(format!("The upload is not a readable multipart form ({})", e.body_text()))
    }
}

/// Reads and checks an upload into a job ready to queue, from client `client`.
pub async fn read_upload(multipart: Multipart, max_upload: usize, client: Option<String>) -> Result<NewJob, ApiError> {
    let fields = read_fields(multipart, max_upload).await?;
    let mut job = match (fields.file("scene"), fields.file("color")) {
        (Some(_), Some(_)) => return Err(ApiError::bad_request("Give either a scene or images to denoise, not both")),
        (Some(scene), None) => render_job(&fields, scene)?,
        (None, Some(_)) => denoise_job(&fields)?,
        (None, None) => {
            return Err(ApiError::bad_request("Give a noisy image (color) with its guide, or a scene to render"))
        }
    };
    job.name = fields.text("name").map(str::to_string);
    job.email = fields.text("email").map(str::to_string);
    job.client = client;
    Ok(job)
}

/// A denoise job: the images' kinds from their bytes, sizes from their headers, all equal.
fn denoise_job(fields: &Fields) -> Result<NewJob, ApiError> {
    for name in ["spp", "width", "height", "camera"] {
        if fields.text(name).is_some() {
            return Err(ApiError::bad_request(format!("The field {name:?} applies to render jobs only")));
        }
    }
    // The set of inputs must make sense before any is looked at: the same rule as `rtd denoise`.
    let named = |n: &str| fields.file(n).map(|_| PathBuf::from(n));
    let sources = DenoiseSources::new("color").guide(named("guide")).albedo(named("albedo")).normal(named("normal"));
    sources.check().map_err(|e| ApiError::bad_request(capitalised(&e.to_string())))?;
    let mut inputs = Vec::new();
    let mut size = None;
    for name in ["color", "guide", "albedo", "normal"] {
        let Some(bytes) = fields.file(name) else { continue };
        let header = rtd_image::read_image_header(Path::new(name), bytes)
            .map_err(|e| ApiError::bad_request(capitalised(&e.to_string())))?;
        let this = (header.width, header.height);
        match size {
            None => size = Some(this),
            Some(s) if s != this => {
                return Err(ApiError::bad_request(format!(
                    "The {name} image is {}x{} but the color image is {}x{}",
                    this.0, this.1, s.0, s.1
                )))
            }
            Some(_) => {}
        }
        inputs.push(Input { name: name.into(), format: header.format.extension().into(), data: bytes.to_vec() });
    }
    Ok(NewJob {
        kind: JobKind::Denoise,
        params: RenderParams::default(),
        name: None,
        email: None,
        client: None,
        size: size.unwrap_or((0, 0)),
        inputs,
    })
}

/// A render job: a self-contained scene and settings within the command line's limits.
fn render_job(fields: &Fields, scene: &[u8]) -> Result<NewJob, ApiError> {
    for name in ["guide", "albedo", "normal"] {
        if fields.file(name).is_some() {
            return Err(ApiError::bad_request(format!("The file {name:?} applies to denoise jobs only")));
        }
    }
    let number = |name: &str| -> Result<Option<u32>, ApiError> {
        fields
            .text(name)
            .map(|t| {
                t.parse::<u32>()
                    .map_err(|_| ApiError::bad_request(format!("The field {name:?} must be a whole number")))
            })
            .transpose()
    };
    let spp = number("spp")?.unwrap_or(DEFAULT_SPP);
    if spp == 0 || spp > MAX_SPP {
        return Err(ApiError::bad_request(format!("spp must be in 1..={MAX_SPP}")));
    }
    let (width, height) = (number("width")?, number("height")?);
    // The sides given are checked as `rtd render` checks them (the other side follows the camera).
    RenderSettings::new(width.or(height).unwrap_or(1), height.or(width).unwrap_or(1))
        .validate()
        .map_err(|e| ApiError::bad_request(capitalised(&e.to_string())))?;
    let format = check_scene(scene).map_err(|e| ApiError::bad_request(capitalised(&e)))?;
    Ok(NewJob {
        kind: JobKind::Render,
        params: RenderParams { spp, width, height, camera: fields.text("camera").map(str::to_string) },
        name: None,
        email: None,
        client: None,
        size: (width.unwrap_or(0), height.unwrap_or(0)),
        inputs: vec![Input { name: "scene".into(), format: format.into(), data: scene.to_vec() }],
    })
}

/// `s` with its first letter in upper case, as the API's sentences begin.
pub fn capitalised(s: &str) -> String {
    let mut c = s.chars();
    match c.next() {
        Some(f) => f.to_uppercase().collect::<String>() + c.as_str(),
        None => String::new(),
    }
}
