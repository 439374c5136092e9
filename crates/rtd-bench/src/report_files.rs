//! A benchmark's files: the JSON and Markdown reports and the figures, written atomically.

use std::path::{Path, PathBuf};

use crate::etrt::{EtrtImages, EtrtReport};
use crate::BenchError;

use rtd_image::write_json;

/// Writes `text` to `path`, atomically.
pub fn write_text(path: &Path, text: &str) -> Result<(), BenchError> {
    Ok(rtd_image::write_bytes_atomic(path, text.as_bytes())?)
}

/// Writes `report.json`, `report.md`, `side-by-side.png` and `error-vs-time.png` into `dir`.
pub fn write_etrt(dir: &Path, report: &EtrtReport, images: &EtrtImages) -> Result<Vec<PathBuf>, BenchError> {
    std::fs::create_dir_all(dir).map_err(|e| BenchError::io(dir, e))?;
    let json = dir.join("report.json");
    write_json(&json, report)?;
    let md = dir.join("report.md");
    write_text(&md, &report.markdown())?;
    let side = dir.join("side-by-side.png");
    crate::figures::side_by_side(&side, images, report)?;
    let plot = dir.join("error-vs-time.png");
    crate::figures::error_plot(&plot, std::slice::from_ref(report))?;
    Ok(vec![json, md, side, plot])
}
