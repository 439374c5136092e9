//! Output files of the commands: early checks that an output can be written (before minutes of
//! work), and warnings printed for the user.

use std::path::Path;

use anyhow::{bail, Context};

use rtd_image::ImageFormat;

/// Fails early, before any work, if `path` cannot be written as an image.
pub fn check_output(path: &Path) -> anyhow::Result<ImageFormat> {
    let format = ImageFormat::from_path(path)?;
    let dir = existing_dir(path, "output")?;
    if path.is_dir() {
        bail!("{}: is a directory", path.display());
    }
    // What an earlier run killed mid-write left beside the output goes now.
    rtd_image::remove_orphans_once(dir);
    // An unnamed file: nothing is left behind even if the process is killed right here.
    tempfile::tempfile_in(dir).with_context(|| format!("{}: output directory is not writable", path.display()))?;
    Ok(format)
}

/// Fails early if the report's directory does not exist.
pub fn check_report_path(path: &Path) -> anyhow::Result<()> {
    existing_dir(path, "report").map(|_| ())
}

/// The directory `path` will be written in, or an error naming it if it does not exist.
fn existing_dir<'p>(path: &'p Path, what: &str) -> anyhow::Result<&'p Path> {
    let dir = rtd_image::parent_dir(path);
    if !dir.is_dir() {
        bail!("{}: {what} directory {} does not exist", path.display(), dir.display());
    }
    Ok(dir)
}

/// Prints load warnings on standard error, each naming the scene file.
pub fn warn_all<'w>(scene: &Path, warnings: impl IntoIterator<Item = &'w str>) {
    for w in warnings {
        eprintln!("rtd: warning: {}: {w}", scene.display());
    }
}
