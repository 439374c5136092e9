use std::io::Write;
use std::path::Path;

use crate::ImageError;

/// The directory a file at `path` lives in (`.` for a bare file name).
pub fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Writes a file atomically: `write` fills a temporary file in the destination's directory,
/// which is then renamed over `path`. On any error the temporary file is removed, so a
/// half-written output never appears under the final name.
pub fn write_atomic<F>(path: &Path, write: F) -> Result<(), ImageError>
where
    F: FnOnce(&mut std::io::BufWriter<&mut std::fs::File>) -> Result<(), ImageError>,
{
    let dir = parent_dir(path);
    let mut tmp = tempfile::Builder::new()
        .prefix(".rtd-")
        .suffix(".tmp")
        .tempfile_in(dir)
        .map_err(|e| ImageError::io(path, e))?;
    {
        let mut buffered = std::io::BufWriter::new(tmp.as_file_mut());
        write(&mut buffered)?;
        buffered.flush().map_err(|e| ImageError::io(path, e))?;
    }
    // Temporary files are created private (0600); a finished output gets the usual 0644.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        tmp.as_file().set_permissions(std::fs::Permissions::from_mode(0o644)).map_err(|e| ImageError::io(path, e))?;
    }
    tmp.persist(path).map_err(|e| ImageError::io(path, e.error))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("x.bin");
        let r = write_atomic(&out, |w| {
            w.write_all(b"partial").unwrap();
            Err(ImageError::invalid(&out, "boom"))
        });
        assert!(r.is_err());
        assert!(!out.exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "temp file left behind");
    }

    #[test]
    fn successful_write_replaces() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("x.bin");
        std::fs::write(&out, b"old").unwrap();
        write_atomic(&out, |w| w.write_all(b"new").map_err(|e| ImageError::io(&out, e))).unwrap();
        assert_eq!(std::fs::read(&out).unwrap(), b"new");
    }
}
