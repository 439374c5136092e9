//! Durability of rtd's outputs, checked on the system calls themselves: `strace` records every
//! `fsync` and rename of a real `rtd` run, and the test checks their order. A file is durable
//! only if its data is flushed before it takes its final name, and the directory after, so that
//! a power cut leaves either the previous file or the whole new one, never a renamed but empty
//! file. `.ci/services` installs strace from Debian's packages; `RTD_TEST_STRACE` names it.

use std::path::Path;
use std::process::Command;

mod common;

/// The `fsync` and rename calls of `rtd args…`, as strace prints them with file descriptors
/// shown as paths (`fsync(3</dir/file>)`), one call per line, in the order they began.
fn syscalls(trace_dir: &Path, args: &[&str]) -> Vec<String> {
    let strace = std::env::var("RTD_TEST_STRACE").unwrap_or_else(|_| "strace".into());
    let trace = trace_dir.join("trace.txt");
    let out = Command::new(&strace)
        .args(["-f", "--seccomp-bpf", "-y", "-o", trace.to_str().unwrap()])
        .args(["-e", "trace=fsync,fdatasync,rename,renameat,renameat2"])
        .arg(env!("CARGO_BIN_EXE_rtd"))
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("{strace}: {e} (run the tests through .ci/test, which installs strace)"));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = std::fs::read_to_string(&trace).unwrap();
    // Drop the pid column and strace's "<... resumed>" halves; keep each call as it began.
    text.lines()
        .filter_map(|l| l.split_once(' ').map(|(_, call)| call.trim().to_string()))
        .filter(|call| !call.starts_with("<...") && !call.starts_with("+++"))
        .collect()
}

/// The path strace shows for the first file descriptor of `call`: `fsync(3</a/b>)` → `/a/b`.
fn fd_path(call: &str) -> Option<&str> {
    let start = call.find('<')? + 1;
    Some(&call[start..start + call[start..].find('>')?])
}

#[test]
fn a_render_is_flushed_before_its_rename_and_its_directory_after() {
    let tmp = tempfile::tempdir().unwrap();
    // strace shows paths as the kernel resolves them.
    let dir = tmp.path().canonicalize().unwrap();
    let out = dir.join("out.exr");
    let cornell = common::cli::cornell_path();
    let args = ["render", &cornell, "-o", out.to_str().unwrap(), "--spp", "1", "--width", "8", "--height", "8", "-q"];
    let calls = syscalls(&dir, &args);
    let final_name = format!("\"{}\"", out.display());
    let renamed = calls
        .iter()
        .position(|c| c.starts_with("rename") && c.contains(&final_name))
        .unwrap_or_else(|| panic!("no rename onto {final_name} in {calls:#?}"));
    // The temporary file renamed onto out.exr: the first quoted path of the rename.
    let temp = calls[renamed].split('"').nth(1).unwrap().to_string();
    assert!(temp.ends_with(".tmp") && temp != out.display().to_string(), "{}", calls[renamed]);
    let synced = |c: &String, path: &str| c.starts_with("fsync") && fd_path(c) == Some(path);
    assert!(
        calls[..renamed].iter().any(|c| synced(c, &temp)),
        "the data was not flushed before the rename: {calls:#?}"
    );
    let dir_path = dir.display().to_string();
    assert!(
        calls[renamed + 1..].iter().any(|c| synced(c, &dir_path)),
        "the directory was not flushed after the rename: {calls:#?}"
    );
}

/// A training run's checkpoint folder is created durably: its new entry is flushed (an `fsync`
/// of the folder that holds it) before any file inside it is renamed into place.
#[test]
fn a_new_folder_is_flushed_before_files_are_renamed_into_it() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().canonicalize().unwrap();
    let nested = dir.join("a").join("b");
    rtd::image::create_dir_durably(&nested).unwrap();
    assert!(nested.is_dir());
    // The same call on an existing folder is a no-op and succeeds.
    rtd::image::create_dir_durably(&nested).unwrap();
    // Through the binary: a one-step training run writes its checkpoint folder under `run/`.
    let data = dir.join("data");
    let (d, r) = (data.to_str().unwrap(), dir.join("run"));
    let datagen = ["datagen", "-o", d, "--scenes", "2", "--views", "1", "--size", "32", "--reference-spp", "16", "-q"];
    let made = Command::new(env!("CARGO_BIN_EXE_rtd")).args(datagen).output().unwrap();
    assert!(made.status.success(), "{}", String::from_utf8_lossy(&made.stderr));
    let run = r.clone();
    let steps = ["--steps", "2", "--epoch-steps", "2", "--batch", "2", "--crop", "16", "-q"];
    let mut args = vec!["train", "--data", d, "-o", r.to_str().unwrap()];
    args.extend(steps);
    let calls = syscalls(&dir, &args);
    let checkpoints = run.join("checkpoints").display().to_string();
    let first_rename_inside = calls
        .iter()
        .position(|c| c.starts_with("rename") && c.contains(&format!("\"{checkpoints}/")))
        .unwrap_or_else(|| panic!("no file renamed into {checkpoints}: {calls:#?}"));
    let synced =
        |path: &str| calls[..first_rename_inside].iter().any(|c| c.starts_with("fsync") && fd_path(c) == Some(path));
    assert!(synced(&checkpoints), "{checkpoints} was not flushed before files went in: {calls:#?}");
    assert!(synced(&run.display().to_string()), "the run folder was not flushed: {calls:#?}");
    // The run folder's own entry, in the folder that holds it.
    assert!(synced(&dir.display().to_string()), "{} was not flushed when run/ was made: {calls:#?}", dir.display());
}
