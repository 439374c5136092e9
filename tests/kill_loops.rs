//! Long work killed with SIGKILL at random moments, again and again: `rtd render`, `rtd datagen`
//! and `rtd train --resume`. After every kill the outputs are either absent or complete (never
//! torn), and a rerun finishes with the bytes of an uninterrupted run. The kill moments are
//! spread over an uninterrupted run's duration by a fixed-seed generator; `RTD_KILLS` sets how
//! many per test (default 20; RELIABILITY.md records the long runs).

mod common;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{dataset_files, files_under};

/// Kills per test.
fn kills() -> u32 {
    std::env::var("RTD_KILLS").ok().and_then(|s| s.parse().ok()).unwrap_or(20)
}

/// Kill moments: a fixed-seed xorshift over `[0, span)`; the kill counts printed come from it.
struct Moments(u64);

impl Moments {
    fn next(&mut self, span: Duration) -> Duration {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        span.mul_f64((self.0 >> 11) as f64 / (1u64 << 53) as f64)
    }
}

fn rtd(args: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_rtd"));
    c.args(args).stdout(Stdio::null()).stderr(Stdio::null());
    c
}

/// Runs `args` to the end and returns how long it took.
fn run_to_end(args: &[&str]) -> Duration {
    let t = Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_rtd")).args(args).output().unwrap();
    assert!(out.status.success(), "rtd {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    t.elapsed()
}

/// Starts `args` and kills it with SIGKILL after `after` (if it has not finished by then).
/// Returns true if it was killed.
fn kill_after(args: &[&str], after: Duration) -> bool {
    let mut child = rtd(args).spawn().unwrap();
    let t = Instant::now();
    while t.elapsed() < after {
        if child.try_wait().unwrap().is_some() {
            return false;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let killed = child.try_wait().unwrap().is_none();
    let _ = child.kill();
    child.wait().unwrap();
    killed
}

/// Kills `args(dir)` at random moments over `[0, span)` until `n` runs were killed: each
/// cycle starts a fresh `dir` under `root` and reruns the job after every kill, checking the
/// leftovers with `after_kill`, until a run finishes by itself; `finished` then checks the
/// result. Returns (kills, cycles).
fn kill_cycles(
    n: u32,
    span: Duration,
    root: &Path,
    args: &dyn Fn(&Path) -> Vec<String>,
    after_kill: &dyn Fn(&Path),
    finished: &dyn Fn(&Path),
    moments: &mut Moments,
) -> (u32, u32) {
    let (mut killed, mut cycles) = (0, 0);
    while killed < n {
        let dir = root.join(format!("cycle{cycles}"));
        let a = args(&dir);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        while killed < n && kill_after(&a, moments.next(span)) {
            killed += 1;
            after_kill(&dir);
        }
        run_to_end(&a);
        finished(&dir);
        cycles += 1;
    }
    (killed, cycles)
}

/// Temporary files of atomic writes (`.rtd-PID-….tmp`) under `dir`.
fn temp_files(dir: &Path) -> Vec<String> {
    files_under(dir).into_keys().filter(|k| k.rsplit('/').next().is_some_and(|n| n.starts_with(".rtd-"))).collect()
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn a_killed_render_leaves_its_previous_output_or_none() {
    let dir = tempfile::tempdir().unwrap();
    let scene = env!("CARGO_MANIFEST_DIR").to_string() + "/scenes/cornell-box.gltf";
    let reference = dir.path().join("reference.exr");
    let out = dir.path().join("out").join("out.exr");
    std::fs::create_dir(out.parent().unwrap()).unwrap();
    let args = |o: &Path| -> Vec<String> {
        ["render", &scene, "--spp", "24", "--width", "40", "--threads", "1", "--denoise", "-q", "-o", path(o)]
            .iter()
            .map(|s| s.to_string())
            .collect()
    };
    let a = args(&reference);
    let span = run_to_end(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let expected = std::fs::read(&reference).unwrap();
    let b = args(&out);
    let b: Vec<&str> = b.iter().map(String::as_str).collect();
    let mut moments = Moments(0x9E37_79B9_7F4A_7C15);
    // Runs until `kills()` runs were killed mid-way: under load (the other loops run beside
    // this one) more runs finish before their moment, and those are checked too.
    let (mut killed, mut present, mut runs) = (0, 0, 0);
    while killed < kills() && runs < 10 * kills() {
        runs += 1;
        killed += kill_after(&b, moments.next(span.mul_f64(1.2))) as u32;
        if out.exists() {
            present += 1;
            assert!(std::fs::read(&out).unwrap() == expected, "after a kill, out.exr is not a complete render");
        }
    }
    assert_eq!(killed, kills(), "only {killed} of {runs} runs were killed mid-way");
    run_to_end(&b);
    assert!(std::fs::read(&out).unwrap() == expected);
    assert!(temp_files(out.parent().unwrap()).is_empty(), "{:?}", temp_files(out.parent().unwrap()));
    eprintln!("render: {killed} kills in {runs} runs, out.exr complete {present} times and absent otherwise");
}

#[test]
fn a_dataset_killed_again_and_again_equals_an_uninterrupted_one() {
    let root = tempfile::tempdir().unwrap();
    let whole = root.path().join("whole");
    let args = |d: &Path| -> Vec<String> {
        ["datagen", "-o", path(d), "--scenes", "3", "--views", "2", "--size", "24", "--reference-spp", "8", "-q"]
            .iter()
            .map(|s| s.to_string())
            .collect()
    };
    let w = args(&whole);
    let span = run_to_end(&w.iter().map(String::as_str).collect::<Vec<_>>());
    let expected = dataset_files(&whole);
    let after_kill = |dir: &Path| {
        let manifest = dir.join("manifest.json");
        if !manifest.exists() {
            return;
        }
        let m: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&manifest).unwrap()).expect("after a kill, manifest.json is torn");
        let views = m["views"].as_array().unwrap();
        for v in views {
            let view = dir.join(v["file"].as_str().unwrap());
            let layers = rtd::image::read_exr(&view).expect("a view in the manifest is missing or torn");
            assert!(layers.width == 24 && layers.get("reference.R").is_some(), "{}", view.display());
        }
        let mut keys: Vec<(u64, u64)> =
            views.iter().map(|v| (v["scene"].as_u64().unwrap(), v["view"].as_u64().unwrap())).collect();
        let n = keys.len();
        keys.dedup();
        assert_eq!(keys.len(), n, "a view is recorded twice");
    };
    let finished = |dir: &Path| {
        assert!(dataset_files(dir) == expected, "a killed and resumed dataset differs from the uninterrupted one");
        assert!(temp_files(dir).is_empty(), "{:?}", temp_files(dir));
    };
    let mut moments = Moments(0xD1B5_4A32_D192_ED03);
    let (killed, cycles) =
        kill_cycles(kills(), span.mul_f64(0.7), root.path(), &args, &after_kill, &finished, &mut moments);
    eprintln!("datagen: {killed} kills over {cycles} datasets, each byte-identical to the uninterrupted one");
}

#[test]
fn training_killed_again_and_again_resumes_to_the_same_model() {
    let root = tempfile::tempdir().unwrap();
    let data = root.path().join("data");
    let d =
        ["datagen", "-o", path(&data), "--scenes", "2", "--views", "1", "--size", "32", "--reference-spp", "16", "-q"];
    run_to_end(&d);
    let args = |out: &Path| -> Vec<String> {
        let steps = ["--steps", "12", "--epoch-steps", "2", "--batch", "2", "--crop", "16", "--resume", "-q"];
        ["train", "--data", path(&data), "-o", path(out)].iter().chain(&steps).map(|s| s.to_string()).collect()
    };
    let whole = root.path().join("whole");
    let w = args(&whole);
    let span = run_to_end(&w.iter().map(String::as_str).collect::<Vec<_>>());
    let model_files =
        ["model.bpk", "model.json", "checkpoints/00000012/weights.bpk", "checkpoints/00000012/optimizer.bpk"];
    let after_kill = |dir: &Path| {
        let state = dir.join("state.json");
        if state.exists() {
            let s: serde_json::Value =
                serde_json::from_slice(&std::fs::read(&state).unwrap()).expect("state.json is torn");
            let step = s["step"].as_u64().unwrap();
            assert!(step <= 12);
            // The checkpoint it names is whole (a kill between its files and state.json
            // used to pair one step's weights with another's state).
            let named = dir.join(format!("checkpoints/{step:08}"));
            for f in ["weights.bpk", "optimizer.bpk"] {
                assert!(named.join(f).exists(), "state.json names step {step}, whose {f} is missing");
            }
        }
    };
    let finished = |dir: &Path| {
        for f in model_files {
            let (a, b) = (std::fs::read(whole.join(f)).unwrap(), std::fs::read(dir.join(f)).unwrap());
            assert!(a == b, "{f} after kills and resumes differs from the uninterrupted run's");
        }
        let kept: Vec<_> =
            std::fs::read_dir(dir.join("checkpoints")).unwrap().flatten().map(|e| e.file_name()).collect();
        assert_eq!(kept.len(), 1, "only the last checkpoint is kept: {kept:?}");
        assert!(temp_files(dir).is_empty(), "{:?}", temp_files(dir));
    };
    // Half as many kills as the other loops: each run builds a network before it trains.
    let mut moments = Moments(0x8CB9_2BA7_2F3D_8DD7);
    let (killed, cycles) =
        kill_cycles(kills().div_ceil(2), span.mul_f64(0.8), root.path(), &args, &after_kill, &finished, &mut moments);
    eprintln!("train: {killed} kills over {cycles} runs, each resumed to byte-identical model files");
}
