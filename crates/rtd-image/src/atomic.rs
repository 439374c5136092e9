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

/// Temporary files are `.rtd-PID-XXXXXX.tmp`: named after the process writing them, so that
/// one left by a killed process (`kill -9`, a power cut) can be told from one being written.
const TEMP_PREFIX: &str = ".rtd-";
const TEMP_SUFFIX: &str = ".tmp";

fn temp_prefix(pid: u32) -> String {
    format!("{TEMP_PREFIX}{pid}-")
}

/// The process id in a temporary file's name, if `name` is one of ours.
fn temp_owner(name: &str) -> Option<u32> {
    let rest = name.strip_prefix(TEMP_PREFIX)?.strip_suffix(TEMP_SUFFIX)?;
    rest.split_once('-')?.0.parse().ok()
}

/// Removes the temporary files in `dir` left by processes that no longer run (killed while
/// writing), the first time this process calls it for `dir`: commands call it as they start,
/// and every atomic write does, so a directory of many files is scanned once, not per write.
/// Only where process ids can be checked (`/proc`); errors are ignored, as the files are
/// harmless leftovers.
pub fn remove_orphans_once(dir: &Path) {
    static SWEPT: std::sync::Mutex<Vec<std::path::PathBuf>> = std::sync::Mutex::new(Vec::new());
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(canonical) = dir.canonicalize() else { return };
    {
        let mut swept = SWEPT.lock().unwrap_or_else(|e| e.into_inner());
        if swept.contains(&canonical) {
            return;
        }
        swept.push(canonical);
    }
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(temp_owner) else { continue };
        if !Path::new(&format!("/proc/{pid}")).exists() {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// Writes a file atomically and durably: `write` fills a temporary file in the destination's
/// directory, which is flushed to disk (`fsync`), renamed over `path`, and the directory is
/// flushed after the rename. On any error the temporary file is removed, so a half-written
/// output never appears under the final name, and a power cut cannot leave a renamed but
/// empty file.
pub fn write_atomic<F>(path: &Path, write: F) -> Result<(), ImageError>
where
    F: FnOnce(&mut std::io::BufWriter<&mut std::fs::File>) -> Result<(), ImageError>,
{
    let dir = parent_dir(path);
    remove_orphans_once(dir);
    let mut tmp = tempfile::Builder::new()
        .prefix(&temp_prefix(std::process::id()))
        .suffix(TEMP_SUFFIX)
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
    tmp.as_file().sync_all().map_err(|e| ImageError::io(path, e))?;
    tmp.persist(path).map_err(|e| ImageError::io(path, e.error))?;
    sync_dir(dir).map_err(|e| ImageError::io(path, e))
}

/// Writes `bytes` to `path` through [`write_atomic`].
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<(), ImageError> {
    write_atomic(path, |w| w.write_all(bytes).map_err(|e| ImageError::io(path, e)))
}

/// Writes `value` as pretty JSON to `path` through [`write_atomic`] (reports, manifests).
pub fn write_json<T: serde::Serialize + ?Sized>(path: &Path, value: &T) -> Result<(), ImageError> {
    let bytes = serde_json::to_vec_pretty(value)
        .map_err(|e| ImageError::invalid(path, format!("cannot serialise as JSON: {e}")))?;
    write_bytes_atomic(path, &bytes)
}

/// Creates `dir` and any missing parents durably: each new directory's entry is flushed to disk
/// (`fsync` of the folder that holds it), so a file later written inside cannot outlive, after
/// a power cut, the directory entry that leads to it.
pub fn create_dir_durably(dir: &Path) -> std::io::Result<()> {
    let missing: Vec<&Path> = dir.ancestors().take_while(|d| !d.as_os_str().is_empty() && !d.exists()).collect();
    std::fs::create_dir_all(dir)?;
    for created in missing.iter().rev() {
        sync_dir(parent_dir(created))?;
    }
    Ok(())
}

/// Flushes a directory's entries to disk, so a rename in it survives a power cut. Where the
/// platform cannot open a directory as a file this does nothing.
fn sync_dir(dir: &Path) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        std::fs::File::open(dir)?.sync_all()?;
    }
    #[cfg(not(unix))]
    let _ = dir;
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
    fn a_killed_writers_temp_file_is_removed_by_the_next_write() {
        let dir = tempfile::tempdir().unwrap();
        // A process id that cannot be running (beyond Linux's pid_max), and one that is.
        let dead = dir.path().join(format!("{}abc123{TEMP_SUFFIX}", temp_prefix(99_999_999)));
        let alive = dir.path().join(format!("{}abc123{TEMP_SUFFIX}", temp_prefix(std::process::id())));
        let other = dir.path().join(".rtd-notes.tmp");
        for f in [&dead, &alive, &other] {
            std::fs::write(f, b"partial").unwrap();
        }
        write_bytes_atomic(&dir.path().join("x.bin"), b"new").unwrap();
        assert!(!dead.exists(), "a dead process's temporary file is removed");
        assert!(alive.exists(), "a running process's temporary file is kept");
        assert!(other.exists(), "a file that is not one of ours is kept");
        assert_eq!(temp_owner(".rtd-42-Xy9.tmp"), Some(42));
        assert_eq!(temp_owner(".rtd-x-Xy9.tmp"), None);
    }

    #[test]
    fn successful_write_replaces() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("x.bin");
        std::fs::write(&out, b"old").unwrap();
        write_bytes_atomic(&out, b"new").unwrap();
        assert_eq!(std::fs::read(&out).unwrap(), b"new");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "temp file left behind");
    }
}
