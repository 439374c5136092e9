//! Helpers for tests that run the `rtd` binary.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the `rtd` binary with `args`.
pub fn rtd(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rtd")).args(args).output().expect("run rtd")
}

/// The bundled Cornell box's path as a string.
pub fn cornell_path() -> String {
    super::repo_path("scenes/cornell-box.gltf").display().to_string()
}

/// Asserts a clean failure: non-zero exit, one stderr line `rtd: error: …` mentioning `needle`,
/// no panic.
pub fn assert_fails(out: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "expected failure, got success; stderr: {err}");
    assert!(!err.contains("panicked"), "panic: {err}");
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "expected one error line, got: {err}");
    assert!(lines[0].starts_with("rtd: error: "), "{err}");
    assert!(err.contains(needle), "error should mention '{needle}': {err}");
}

/// Renders a small noisy EXR of the Cornell box with all guide layers (`--aov`) into `dir`;
/// returns its path.
pub fn noisy_exr(dir: &Path, w: u32, h: u32) -> PathBuf {
    let out = dir.join(format!("noisy{w}x{h}.exr"));
    let (w, h) = (w.to_string(), h.to_string());
    let args = ["render", &cornell_path(), "-o", out.to_str().unwrap(), "--spp", "4", "--width", &w, "--height", &h];
    let o = rtd(&[&args[..], &["--aov", "-q"]].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    out
}

/// [`noisy_exr`] without its `variance.*` channels: what other software's files hold, so that
/// denoising it from rtd's layer names and from another program's gives the same input.
pub fn noisy_exr_without_variance(dir: &Path, w: u32, h: u32) -> PathBuf {
    let path = noisy_exr(dir, w, h);
    let mut layers = rtd::image::read_exr(&path).unwrap();
    assert!(layers.channels.iter().any(|(n, _)| n.starts_with("variance.")), "rtd's render has a variance");
    layers.channels.retain(|(n, _)| !n.starts_with("variance."));
    rtd::image::write_exr(&path, &layers).unwrap();
    path
}
