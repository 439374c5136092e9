//! The `rtd` binary end to end: outputs, reports and every bad-input case.

use std::path::{Path, PathBuf};
mod common;

use common::cli::{assert_fails, cornell_path, rtd};
use std::process::Command;

fn files_in(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect()
}

#[test]
fn renders_exr_with_all_layers_and_a_report() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("c.exr");
    let report = dir.path().join("r.json");
    let o = rtd(&[
        "render",
        &cornell_path(),
        "-o",
        out.to_str().unwrap(),
        "--spp",
        "2",
        "--width",
        "24",
        "--height",
        "16",
        "--report",
        report.to_str().unwrap(),
        "-q",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("paths/s") && stdout.contains("rays/s"), "{stdout}");
    let layers = rtd::image::read_exr(&out).unwrap();
    assert_eq!((layers.width, layers.height), (24, 16));
    for ch in ["R", "G", "B", "albedo.R", "albedo.G", "albedo.B", "normal.X", "normal.Y", "normal.Z", "depth.Z"] {
        assert!(layers.get(ch).is_some(), "missing channel {ch}");
    }
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    for key in [
        "load_s",
        "bvh_s",
        "render_s",
        "spp",
        "paths_per_s",
        "rays_per_s",
        "nonfinite_samples",
        "triangles",
        "emissive_triangles",
    ] {
        assert!(r.get(key).is_some(), "report lacks {key}");
    }
    assert_eq!(r["spp"], 2);
    assert_eq!(r["triangles"], 32);
    assert_eq!(r["emissive_triangles"], 2);
    // Only the two outputs: no temporary files left behind.
    assert_eq!(files_in(dir.path()).len(), 2);
}

#[test]
fn same_command_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, threads: &str| {
        let p = dir.path().join(name);
        let o = rtd(&[
            "render",
            &cornell_path(),
            "-o",
            p.to_str().unwrap(),
            "--spp",
            "2",
            "--width",
            "20",
            "--height",
            "20",
            "--threads",
            threads,
            "-q",
        ]);
        assert!(o.status.success());
        std::fs::read(p).unwrap()
    };
    assert_eq!(run("a.png", "1"), run("b.png", "2"));
}

#[test]
fn png_jpeg_and_time_budget() {
    let dir = tempfile::tempdir().unwrap();
    for (name, extra) in
        [("a.png", vec!["--tonemap", "aces", "--exposure", "-1"]), ("b.jpg", vec![]), ("c.jpeg", vec!["--time", "0.2"])]
    {
        let p = dir.path().join(name);
        let c = cornell_path();
        let mut args = vec!["render", &c, "-o", p.to_str().unwrap(), "--width", "16", "--height", "16", "-q"];
        args.extend(extra.iter());
        let o = rtd(&args);
        assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
        assert!(rtd::image::read_ldr(&p).is_ok(), "{name} unreadable");
    }
}

#[test]
fn bad_arguments_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.png");
    let o = out.to_str().unwrap();
    let c = cornell_path();
    assert_fails(&rtd(&["render", &c, "-o", o, "--spp", "0"]), "spp");
    // Usage errors exit with 2, other errors with 1.
    assert_eq!(rtd(&["render", &c, "-o", o, "--spp", "0"]).status.code(), Some(2));
    assert_eq!(rtd(&["frobnicate"]).status.code(), Some(2));
    assert_eq!(rtd(&["render", &c, "-o", o, "--camera", "nope"]).status.code(), Some(1));
    assert_fails(&rtd(&["render", &c, "-o", o, "--width", "0"]), "width");
    assert_fails(&rtd(&["render", &c, "-o", o, "--height", "100000"]), "height");
    assert_fails(&rtd(&["render", &c, "-o", o, "--width", "16384", "--height", "16384"]), "16384x16384");
    assert_fails(&rtd(&["render", &c, "-o", o, "--time", "-1"]), "time");
    assert_fails(&rtd(&["render", &c, "-o", o, "--spp", "4", "--time", "1"]), "time");
    assert_fails(&rtd(&["render", &c, "-o", o, "--max-depth", "0"]), "max-depth");
    assert_fails(&rtd(&["render", &c, "-o", o, "--camera", "nope"]), "nope");
    assert_fails(&rtd(&["render", &c, "-o", o, "--env", "1,2"]), "--env");
    assert_fails(&rtd(&["render", &c, "-o", o, "--env", "missing-sky.exr"]), "missing-sky.exr");
    assert_fails(&rtd(&["render", &c, "-o", dir.path().join("o.tiff").to_str().unwrap()]), "o.tiff");
    assert_fails(&rtd(&["render", &c, "-o", "/nonexistent-dir/o.png"]), "/nonexistent-dir/o.png");
    assert_fails(&rtd(&["render", &c, "-o", dir.path().to_str().unwrap()]), "");
    assert_fails(&rtd(&["render", &c, "-o", o, "--report", "/nonexistent-dir/r.json"]), "r.json");
    assert_fails(&rtd(&["frobnicate"]), "frobnicate");
    // `bench suite` without scenes reads the bundled folder, which is missing outside the
    // repository: named as missing (not as an unknown scene format), before any output exists.
    let suite =
        Command::new(env!("CARGO_BIN_EXE_rtd")).current_dir(dir.path()).args(["bench", "suite", "-o", "s"]).output();
    assert_fails(&suite.unwrap(), "scenes: no such folder");
    // Missing arguments are named, not just announced.
    assert_fails(&rtd(&["render", "-o", o]), "<SCENE>");
    assert_fails(&rtd(&["train", "-o", o]), "--data <DATA>");
    // The experiment harnesses removed in the architecture clean-up are unknown flags now.
    for removed in [vec!["--grow", "64"], vec!["--gradient-loss", "0.5"], vec!["--no-depth"], vec!["--variant", "unet"]]
    {
        let mut args = vec!["train", "--data", o, "-o", o];
        args.extend_from_slice(&removed);
        assert_fails(&rtd(&args), &format!("unexpected argument '{}'", removed[0]));
    }
    assert_fails(&rtd(&["train", "--data", o, "-o", o, "--exposure-key", "0"]), "--exposure-key");
    assert_fails(
        &rtd(&["train", "--data", o, "-o", o, "--bilinear-blend"]),
        "--bilinear-blend: the network predicts colour directly",
    );
    // Absurd sample counts and spans: refused as arguments, before any work (1e20 s once reached
    // a panic in Duration; an i64::MAX-ms lease overflowed the queue's clock).
    assert_fails(&rtd(&["render", &c, "-o", o, "--spp", "99999999999"]), "--spp");
    assert_fails(&rtd(&["bench", "lights", "-o", o, "--seconds", "1e20"]), "--seconds");
    // (A database and a data folder that cannot be opened, so that a regression fails rather
    // than starting a worker or a server that runs for ever.)
    let worker = ["worker", "--database", "sqlite:///dev/null/x.db", "--lease", "9223372036854775807ms"];
    assert_fails(&rtd(&worker), "--lease");
    assert_fails(&rtd(&["serve", "--data", "/dev/null/rtd-data", "--keep", "300000000000000ms"]), "--keep");
    assert_fails(
        &rtd(&["bench", "scaling", "-o", o, "--point", "texture=4000000000"]),
        "texture 4000000000 is outside",
    );
    // Refreshing a dataset's guides keeps its own generation settings.
    for (flag, value) in
        [("--scenes", "3"), ("--size", "64"), ("--seed", "2"), ("--views", "1"), ("--reference-spp", "8")]
    {
        assert_fails(&rtd(&["datagen", "-o", o, "--refresh-guides", flag, value]), flag);
    }
    assert!(files_in(dir.path()).is_empty(), "a failed command left files: {:?}", files_in(dir.path()));
}

/// `rtd train` with crops the dataset's views cannot give or a network shape no model may have,
/// and `rtd bench validation` at a sample count they were not rendered at: one error line each,
/// and no run or report written; `rtd train` of a shape of its own saves that shape.
#[test]
fn train_and_bench_validation_refuse_what_a_tiny_dataset_cannot_serve() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let options = rtd::train::dataset::DatasetOptions::default()
        .scenes(3)
        .views_per_scene(1)
        .size(24)
        .reference_spp(16)
        .validation_every(3);
    let manifest = rtd::train::dataset::generate_dataset(&data, &options, &rtd::image::Quiet).unwrap();
    assert!(manifest.views.iter().any(|v| !v.validation), "the dataset needs a training view");
    let (run, report) = (dir.path().join("run"), dir.path().join("report"));
    let (d, r) = (data.to_str().unwrap(), run.to_str().unwrap());
    // Crops larger than the 24² views, or not a multiple of the U-Net's 4-px alignment.
    let too_large = rtd(&["train", "--data", d, "-o", r, "--crop", "32", "-q"]);
    assert_fails(&too_large, "crop side 32 px is larger than the dataset's 24x24 px views");
    assert_fails(&rtd(&["train", "--data", d, "-o", r, "--crop", "18", "-q"]), "not a positive multiple of 4");
    // Network shapes no model may have, and a shape beside --init (which sets it): refused.
    use rtd::denoise::model::{MAX_BOTTLENECK_BLOCKS, MAX_LEVELS, MAX_LEVEL_CHANNELS};
    let over = format!("8,{}", MAX_LEVEL_CHANNELS + 1);
    let wide = rtd(&["train", "--data", d, "-o", r, "--channels", &over, "-q"]);
    assert_fails(&wide, "--channels");
    assert_eq!(wide.status.code(), Some(2), "a usage error exits 2");
    let many = (MAX_BOTTLENECK_BLOCKS + 1).to_string();
    let blocks = rtd(&["train", "--data", d, "-o", r, "--bottleneck-blocks", &many, "-q"]);
    assert_fails(&blocks, "--bottleneck-blocks");
    assert_eq!(blocks.status.code(), Some(2), "a usage error exits 2");
    let quick = dir.path().join("quick-data");
    let (q, levels) = (quick.to_str().unwrap(), ["8"; MAX_LEVELS + 1].join(","));
    let deep = rtd(&["train", "--quick", "--data", q, "-o", r, "--channels", &levels, "-q"]);
    assert_fails(&deep, &format!("the network's shape: implausible channel list {:?}", vec![8; MAX_LEVELS + 1]));
    assert!(!quick.exists(), "a refused --quick run made its dataset");
    let scored = rtd(&["train", "--quick", "--data", q, "-o", r, "--validation-data", d, "-q"]);
    assert_fails(&scored, "--validation-data");
    assert_eq!(scored.status.code(), Some(2), "a usage error exits 2");
    assert!(!quick.exists(), "a refused --quick run made its dataset");
    let model = dir.path().join("model.bpk");
    std::fs::write(&model, b"not read").unwrap();
    let both = rtd(&["train", "--data", d, "-o", r, "--channels", "8", "--init", model.to_str().unwrap(), "-q"]);
    assert_fails(&both, "--channels");
    assert_eq!(both.status.code(), Some(2), "a usage error exits 2");
    assert!(!run.exists(), "a refused run wrote {}", run.display());
    // A shape of its own, from random weights: the model saved says so and loads.
    let shape = ["--channels", "8,12", "--bottleneck-blocks", "1", "--steps", "2", "--epoch-steps", "2"];
    let trained = rtd(&[&["train", "--data", d, "-o", r, "--batch", "1", "--crop", "8", "-q"][..], &shape].concat());
    assert!(trained.status.success(), "{}", String::from_utf8_lossy(&trained.stderr));
    let made = rtd::denoise::Denoiser::load(&run.join("model.bpk")).unwrap();
    assert_eq!((&made.config().channels, made.config().bottleneck_blocks), (&vec![8, 12], 1));
    let bench = rtd(&["bench", "validation", "--data", d, "--spp", "3", "-o", report.to_str().unwrap(), "-q"]);
    assert_fails(&bench, "has no noisy render at 3 spp (it has 1, 2, 4, 8, 16, 32, 64 spp)");
    assert!(!report.exists(), "a refused benchmark made {}", report.display());
}

#[test]
fn a_closed_standard_output_is_not_an_error() {
    // `rtd … | head` can close the pipe before rtd prints its summary: rtd still succeeds and
    // writes its files, without a panic.
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("g.png");
    let (c, p) = (cornell_path(), png.to_str().unwrap().to_string());
    for args in [vec!["train", "--help"], vec!["guide", &c, "-o", &p, "--width", "16", "--height", "16"]] {
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let out = Command::new(env!("CARGO_BIN_EXE_rtd")).args(&args).stdout(writer).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success() && err.trim().is_empty(), "{args:?}: {:?} {err}", out.status);
    }
    assert!(rtd::image::read_ldr(&png).is_ok());
}

#[test]
fn bad_scenes_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.png");
    let o = out.to_str().unwrap();
    let scene = |name: &str, body: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, body).unwrap();
        p.display().to_string()
    };
    assert_fails(&rtd(&["render", dir.path().join("missing.gltf").to_str().unwrap(), "-o", o]), "missing.gltf");
    assert_fails(&rtd(&["render", &scene("broken.gltf", "{\"asset\": "), "-o", o]), "broken.gltf");
    assert_fails(&rtd(&["render", &scene("broken.glb", "glTF garbage"), "-o", o]), "broken.glb");
    let draco = r#"{"asset":{"version":"2.0"},"extensionsUsed":["KHR_draco_mesh_compression"],"extensionsRequired":["KHR_draco_mesh_compression"]}"#;
    assert_fails(&rtd(&["render", &scene("draco.gltf", draco), "-o", o]), "KHR_draco_mesh_compression");
    let meshopt = r#"{"asset":{"version":"2.0"},"extensionsUsed":["EXT_meshopt_compression"],"extensionsRequired":["EXT_meshopt_compression"]}"#;
    assert_fails(&rtd(&["render", &scene("meshopt.gltf", meshopt), "-o", o]), "EXT_meshopt_compression");
    assert_fails(&rtd(&["render", &scene("bad.obj", "v 0 0 0\nf 1 2 banana\n"), "-o", o]), "bad.obj");
    assert_fails(&rtd(&["render", &scene("scene.fbx", "x"), "-o", o]), "scene.fbx");
    let files: Vec<_> =
        files_in(dir.path()).into_iter().filter(|p| p.extension().is_some_and(|e| e == "png")).collect();
    assert!(files.is_empty(), "outputs written on failure: {files:?}");
}

/// A glTF whose POSITION accessor claims 10⁹ vertices in a 48-byte buffer view is refused with one
/// line naming the file, the mesh and the accessor, and nothing is written.
#[test]
fn a_corrupt_gltf_accessor_fails_the_render() {
    let dir = tempfile::tempdir().unwrap();
    // Four vertices of a unit quad, little-endian f32.
    let positions = concat!(
        "data:application/octet-stream;base64,",
        "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAACAPwAAgD8AAAAAAAAAAAAAgD8AAAAA"
    );
    let doc = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"name": "Quad", "primitives": [{"attributes": {"POSITION": 0}}]}],
        "buffers": [{"byteLength": 48, "uri": positions}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 1_000_000_000u64, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}]
    });
    let scene = dir.path().join("corrupt.gltf");
    std::fs::write(&scene, doc.to_string()).unwrap();
    let out = dir.path().join("out.png");
    let o = rtd(&["render", scene.to_str().unwrap(), "-o", out.to_str().unwrap(), "--spp", "1", "-q"]);
    assert_fails(
        &o,
        "corrupt.gltf: mesh 0 (\"Quad\"), accessor 0: 1000000000 elements of 12 bytes run past the end of \
         buffer view 0 (48 bytes)",
    );
    assert!(!out.exists(), "a refused scene must not leave an image");
    assert_eq!(files_in(dir.path()), vec![scene], "nothing but the scene is left in the directory");
}

/// A scene with no lights, and no environment or a black one, renders black with one clear
/// warning, rather than failing or leaving the user to guess.
#[test]
fn a_scene_without_lights_under_a_black_sky_renders_black_with_a_clear_warning() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("dark.obj");
    std::fs::write(&obj, "v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    for env in [None, Some("0,0,0")] {
        let out = dir.path().join("dark.exr");
        let (s, o) = (obj.to_str().unwrap(), out.to_str().unwrap());
        let mut args = vec!["render", s, "-o", o, "--spp", "2", "--width", "8", "--height", "8", "-q"];
        args.extend(["--look-from", "0,0,3", "--look-at", "0,0,0"]);
        if let Some(e) = env {
            args.extend(["--env", e]);
        }
        let run = rtd(&args);
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(run.status.success(), "{env:?}: {err}");
        assert!(err.contains("scene has no lights and no environment; the image will be black"), "{env:?}: {err}");
        let beauty = rtd::image::read_exr(&out).unwrap().image(rtd::image::Layer::Beauty).unwrap();
        assert!(beauty.pixels.iter().all(|p| *p == glam::Vec3::ZERO), "{env:?}: not black");
        std::fs::remove_file(&out).unwrap();
    }
}

#[test]
fn nan_vertices_fail_the_render_and_degenerate_triangles_are_skipped_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("n.png");
    let render = |name: &str, body: &str| {
        let obj = dir.path().join(name);
        std::fs::write(&obj, body).unwrap();
        let args =
            ["--spp", "1", "--width", "8", "--height", "8", "--look-from", "0.3,0.3,2", "--look-at", "0.3,0.3,0"];
        let mut all = vec!["render", obj.to_str().unwrap(), "-o", out.to_str().unwrap(), "--env", "1", "-q"];
        all.extend(args);
        rtd(&all)
    };
    // A zero-area triangle is harmless (it covers nothing): dropped, with a warning.
    let o = render("flat.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\n");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && err.contains("skipped 1 degenerate"), "{err}");
    assert!(out.exists());
    std::fs::remove_file(&out).unwrap();
    // A NaN or infinite position has no right place: the file is refused, and nothing written.
    let o = render("nan.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv nan 1 0\nf 1 2 3\nf 1 2 4\n");
    assert_fails(&o, "nan.obj: a triangle has a NaN or infinite vertex position");
    let o = render("inf.obj", "v 0 0 0\nv 1 0 0\nv inf 1 0\nf 1 2 3\nf 3 2 1\n");
    assert_fails(&o, "inf.obj: 2 triangles have NaN or infinite vertex positions");
    // A face naming a vertex the file does not have.
    let o = render("index.obj", "o Box\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    assert_fails(&o, "index.obj: cannot load OBJ: face vertex index out of bounds");
    assert!(!out.exists(), "an output was written for a refused scene");
}

/// Ctrl-C (SIGINT) stops after the pass in flight and still writes the finished passes.
#[test]
fn interrupt_keeps_finished_passes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("i.exr");
    let report = dir.path().join("i.json");
    let child = Command::new(env!("CARGO_BIN_EXE_rtd"))
        .args([
            "render",
            &cornell_path(),
            "-o",
            out.to_str().unwrap(),
            "--spp",
            "1000000",
            "--width",
            "32",
            "--height",
            "32",
        ])
        .args(["--report", report.to_str().unwrap(), "-q"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Wait until it has rendered for a while, then interrupt it like a terminal would.
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let kill = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(kill.success());
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    // 130 (128 + SIGINT) after the finished passes are written, with one line saying so.
    assert_eq!(o.status.code(), Some(130), "{err}");
    assert!(err.trim().starts_with("rtd: interrupted: ") && err.trim().lines().count() == 1, "{err}");
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(r["interrupted"], true);
    let spp = r["spp"].as_u64().unwrap();
    assert!(spp > 0 && spp < 1_000_000, "spp {spp}");
    assert!(rtd::image::read_exr(&out).unwrap().image(rtd::image::Layer::Beauty).unwrap().is_finite());
}

#[test]
fn guide_writes_all_layers_png_and_report() {
    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("g.exr");
    let report = dir.path().join("g.json");
    let c = cornell_path();
    let o = rtd(&[
        "guide",
        &c,
        "-o",
        exr.to_str().unwrap(),
        "--width",
        "32",
        "--height",
        "24",
        "--report",
        report.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let layers = rtd::image::read_exr(&exr).unwrap();
    for ch in [
        "guide.R", "guide.G", "guide.B", "albedo.R", "albedo.G", "albedo.B", "normal.X", "normal.Y", "normal.Z",
        "depth.Z", "ao.Y",
    ] {
        let v = layers.get(ch).unwrap_or_else(|| panic!("missing {ch}"));
        assert!(v.iter().all(|x| x.is_finite()), "non-finite {ch}");
    }
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert!(r["guide_s"].as_f64().unwrap() > 0.0);
    let png = dir.path().join("g.png");
    assert!(rtd(&["guide", &c, "-o", png.to_str().unwrap(), "--width", "16", "--height", "16"]).status.success());
    assert!(rtd::image::read_ldr(&png).is_ok());
    assert_fails(
        &rtd(&["guide", dir.path().join("none.gltf").to_str().unwrap(), "-o", png.to_str().unwrap()]),
        "none.gltf",
    );
    assert_fails(&rtd(&["guide", &c, "-o", dir.path().join("g.bmp").to_str().unwrap()]), "g.bmp");
}

#[test]
fn render_with_aov_adds_the_guide_layers() {
    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("r.exr");
    let report = dir.path().join("r.json");
    let c = cornell_path();
    let o = rtd(&[
        "render",
        &c,
        "-o",
        exr.to_str().unwrap(),
        "--spp",
        "2",
        "--width",
        "24",
        "--height",
        "24",
        "--aov",
        "--report",
        report.to_str().unwrap(),
        "-q",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let layers = rtd::image::read_exr(&exr).unwrap();
    for ch in ["R", "G", "B", "guide.R", "albedo.R", "normal.X", "depth.Z", "ao.Y"] {
        assert!(layers.get(ch).is_some(), "missing {ch}");
    }
    // The albedo layer is the guide pass's: identical to what `rtd guide` writes.
    let g = dir.path().join("g.exr");
    assert!(rtd(&["guide", &c, "-o", g.to_str().unwrap(), "--width", "24", "--height", "24"]).status.success());
    let gl = rtd::image::read_exr(&g).unwrap();
    assert_eq!(layers.get("albedo.R"), gl.get("albedo.R"));
    assert_eq!(layers.get("ao.Y"), gl.get("ao.Y"));
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert!(r["guide_s"].as_f64().unwrap() > 0.0);
    // Denoised from the colour alone (OIDN's modes go by the inputs named), the file's guide
    // layers go unread, and rtd denoise says so; named as those inputs, they are read.
    let (d, e) = (dir.path().join("d.exr"), exr.to_str().unwrap());
    let alone = rtd(&["denoise", "--color", e, "-o", d.to_str().unwrap()]);
    let said = String::from_utf8_lossy(&alone.stdout).to_string();
    assert!(alone.status.success(), "{}", String::from_utf8_lossy(&alone.stderr));
    assert!(
        said.contains("from color, variance;") && said.contains("guide, albedo, normal layers, not read"),
        "{said}"
    );
    let all = rtd(&["denoise", "--color", e, "--guide", e, "--albedo", e, "--normal", e, "-o", d.to_str().unwrap()]);
    let said = String::from_utf8_lossy(&all.stdout).to_string();
    assert!(said.contains("from color, albedo, normal, guide, variance") && !said.contains("not read"), "{said}");
}

#[test]
fn environment_map_from_exr() {
    let dir = tempfile::tempdir().unwrap();
    // A sky that is bright above the horizon and dark below.
    let (w, h) = (32u32, 16u32);
    let sky = rtd::image::HdrImage::from_pixels(
        w,
        h,
        (0..w * h)
            .map(|i| if i / w < h / 2 { glam::Vec3::new(2.0, 2.0, 3.0) } else { glam::Vec3::splat(0.05) })
            .collect(),
    );
    let mut layers = rtd::image::Layers::new(w, h);
    layers.put_image(rtd::image::Layer::Beauty, &sky);
    let sky_path = dir.path().join("sky.exr");
    rtd::image::write_exr(&sky_path, &layers).unwrap();
    let obj = dir.path().join("p.obj");
    std::fs::write(dir.path().join("p.mtl"), "newmtl lambert\nKd 0.8 0.8 0.8\nKs 0 0 0\n").unwrap();
    std::fs::write(
        &obj,
        "mtllib p.mtl\nusemtl lambert\nv -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nvn 0 1 0\nf 1//1 4//1 3//1 2//1\n",
    )
    .unwrap();
    let out = dir.path().join("e.exr");
    let o = rtd(&[
        "render",
        obj.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--env",
        sky_path.to_str().unwrap(),
        "--spp",
        "16",
        "--width",
        "8",
        "--height",
        "8",
        "--look-from",
        "0,3,0.01",
        "--look-at",
        "0,0,0",
        "--fov",
        "20",
        "-q",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // A Lambertian floor of albedo 0.8 under a uniform upper sky of radiance (2, 2, 3) reflects
    // L = 0.8 · (2, 2, 3); the dark lower half cannot reach its upper side.
    let img = rtd::image::read_exr(&out).unwrap().image(rtd::image::Layer::Beauty).unwrap();
    let m = img.mean();
    assert!((m.x - 1.6).abs() < 0.08 && (m.z - 2.4).abs() < 0.12, "floor radiance {m}");
}

/// `--env` reads Radiance `.hdr` and PFM maps as it reads EXR ones, `--env-strength 2`
/// doubles every pixel (radiance scaling is exact in binary floating point and light selection
/// is scale-invariant, so only the film's last bit may differ), and bad environment settings
/// fail in one line.
#[test]
fn environment_maps_from_hdr_and_pfm_and_strength_scales() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (w, h) = (32u32, 16u32);
    // Values exact in RGBE's shared-exponent encoding, so the three files hold the same sky.
    let sky = |x: u32, y: u32| match (y < h / 2, x < w / 2) {
        (true, true) => [2.0f32, 2.0, 3.0],
        (true, false) => [0.5, 1.0, 0.25],
        _ => [0.0625; 3],
    };
    let img = rtd::image::HdrImage::from_pixels(
        w,
        h,
        (0..w * h).map(|i| glam::Vec3::from_array(sky(i % w, i / w))).collect(),
    );
    let mut layers = rtd::image::Layers::new(w, h);
    layers.put_image(rtd::image::Layer::Beauty, &img);
    rtd::image::write_exr(&d.join("sky.exr"), &layers).unwrap();
    rtd::image::write_pfm(&d.join("sky.pfm"), &img, false).unwrap();
    let rgbe = image::Rgb32FImage::from_fn(w, h, |x, y| image::Rgb(sky(x, y)));
    image::DynamicImage::ImageRgb32F(rgbe).save(d.join("sky.hdr")).unwrap();
    // A floor and a wall, lit by the sky alone (no emitter whose share of light selection the
    // strength would change).
    std::fs::write(d.join("p.mtl"), "newmtl lambert\nKd 0.8 0.6 0.4\nKs 0 0 0\n").unwrap();
    let obj = "mtllib p.mtl\nusemtl lambert\nv -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nv -1 1 -1\nv 1 1 -1\n\
               f 1 4 3 2\nf 1 2 6 5\n";
    std::fs::write(d.join("p.obj"), obj).unwrap();
    let c = d.join("p.obj").display().to_string();
    let render = |env: &str, extra: &[&str]| {
        let out = d.join(format!("out-{}-{}.exr", env.replace('.', "-"), extra.join("_")));
        let sky = d.join(env);
        let args = ["render", &c, "-o", out.to_str().unwrap(), "--env", sky.to_str().unwrap(), "--spp", "4"];
        let view = ["--look-from", "0.3,1.5,3", "--look-at", "0,0.3,0", "--fov", "50"];
        let o = rtd(&[&args[..], &["--width", "16", "--height", "16", "-q"], &view, extra].concat());
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        rtd::image::read_exr(&out).unwrap().image(rtd::image::Layer::Beauty).unwrap()
    };
    let exr = render("sky.exr", &[]);
    assert_eq!(render("sky.hdr", &[]), exr);
    assert_eq!(render("sky.pfm", &[]), exr);
    let doubled = render("sky.hdr", &["--env-strength", "2"]);
    let twice: Vec<glam::Vec3> = exr.pixels.iter().map(|p| *p * 2.0).collect();
    // Equal to the last bits the film's fixed-point sums keep (their grid is absolute, so a
    // doubled value can round once differently).
    let off =
        |(a, b): (&glam::Vec3, &glam::Vec3)| ((*a - *b).abs() / b.abs().max(glam::Vec3::splat(1e-6))).max_element();
    let worst = doubled.pixels.iter().zip(&twice).map(off).fold(0.0f32, f32::max);
    assert!(worst < 1e-6, "strength 2 is not twice the image: relative difference {worst}");
    assert_ne!(render("sky.hdr", &["--env-rotation", "-90"]), exr, "a turn of a lopsided sky shows");
    // Bad settings and files: one line, no output.
    let o = d.join("bad.exr");
    let bad = |extra: &[&str]| rtd(&[&["render", &c, "-o", o.to_str().unwrap(), "-q"][..], extra].concat());
    let sky_hdr = d.join("sky.hdr");
    let sky_hdr = sky_hdr.to_str().unwrap();
    let usage = bad(&["--env", sky_hdr, "--env-strength", "-1"]);
    assert_fails(&usage, "--env-strength");
    assert_eq!(usage.status.code(), Some(2));
    assert_fails(&bad(&["--env-rotation", "10"]), "--env");
    assert_fails(&bad(&["--env", sky_hdr, "--env-rotation", "inf"]), "finite");
    let corrupt = d.join("corrupt.hdr");
    std::fs::write(&corrupt, b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 16 +X 16\n\x02\x02").unwrap();
    assert_fails(&bad(&["--env", corrupt.to_str().unwrap()]), "corrupt.hdr");
    let huge = d.join("huge.hdr");
    std::fs::write(&huge, b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 100000\n").unwrap();
    assert_fails(&bad(&["--env", huge.to_str().unwrap()]), "huge.hdr: image size 100000x100000 is outside");
    let tiff = d.join("sky.tiff");
    std::fs::write(&tiff, b"II*\0").unwrap();
    assert_fails(&bad(&["--env", tiff.to_str().unwrap()]), "an environment map must be .exr, .hdr, .pfm or .phm");
    assert!(!o.exists());
}

/// `--scene NAME|INDEX` picks one of a glTF file's scenes; without it a file of several
/// scenes renders its default one and says so; an unknown scene lists the scenes.
#[test]
fn scene_choice_picks_one_of_several_scenes() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = common::cornell_json();
    // Scene 1, "no-blocks": the room, its light and camera without the two blocks.
    doc["scenes"][0]["name"] = "full".into();
    doc["scenes"].as_array_mut().unwrap().push(serde_json::json!({"name": "no-blocks", "nodes": [0, 1, 2, 3, 6]}));
    let path = dir.path().join("two.gltf");
    std::fs::write(&path, serde_json::to_string(&doc).unwrap()).unwrap();
    let p = path.to_str().unwrap();
    let run = |extra: &[&str]| {
        let report = dir.path().join("r.json");
        let out = dir.path().join("o.exr");
        let args = ["render", p, "-o", out.to_str().unwrap(), "--spp", "1", "--width", "8", "--height", "8"];
        let o = rtd(&[&args[..], &["-q", "--report", report.to_str().unwrap()], extra].concat());
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
        (r["triangles"].as_u64().unwrap(), String::from_utf8_lossy(&o.stderr).to_string())
    };
    let (all, warning) = run(&[]);
    assert!(warning.contains("the file has 2 scenes; rendering scene 0 \"full\" (choose with --scene)"), "{warning}");
    let (by_name, quiet) = run(&["--scene", "no-blocks"]);
    assert!(by_name < all && quiet.trim().is_empty(), "{by_name} of {all}: {quiet}");
    assert_eq!(run(&["--scene", "1"]).0, by_name);
    assert_eq!(run(&["--scene", "full"]).0, all);
    let o = dir.path().join("bad.exr");
    let bad = rtd(&["render", p, "-o", o.to_str().unwrap(), "--scene", "attic", "-q"]);
    assert_fails(&bad, "two.gltf: no scene \"attic\" (scenes: 0 \"full\", 1 \"no-blocks\")");
    let obj = dir.path().join("t.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let args = [
        "render",
        obj.to_str().unwrap(),
        "-o",
        o.to_str().unwrap(),
        "--scene",
        "0",
        "--look-from",
        "0,0,3",
        "--look-at",
        "0,0,0",
    ];
    assert_fails(&rtd(&args), "t.obj: an OBJ file holds one scene");
    assert!(!o.exists());
}
