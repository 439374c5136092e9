//! The pipeline as a library call: render + guide + denoise without the binary, the same bytes
//! as `rtd render`, cancellation between passes, and settings checked before any work.

mod common;

use std::sync::atomic::{AtomicU64, Ordering};

use common::cli::{cornell_path, rtd};
use rtd::denoise::Denoiser;
use rtd::guide::GuideSettings;
use rtd::image::{Layer, Progress, Quiet, Tonemap};
use rtd::pipeline::{Budget, CameraChoice, Pipeline, PipelineError, SceneView};
use rtd::render::RenderSettings;

fn cornell() -> SceneView {
    SceneView::load(&common::repo_path("scenes/cornell-box.gltf"), &CameraChoice::Default, None).unwrap()
}

#[test]
fn render_and_denoise_through_the_library_give_the_cli_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let view = cornell();
    let model = Denoiser::builtin().unwrap();
    let run = Pipeline::new(&view, RenderSettings::new(40, 24).seed(3))
        .denoise(&model)
        .run(Budget::Samples(4), &Quiet)
        .unwrap();
    assert_eq!(run.film.spp, 4);
    assert!(!run.interrupted);
    let (Some(guide), Some(denoised)) = (&run.guide, &run.denoised) else { panic!("guide and denoiser ran") };
    assert_eq!((denoised.width, denoised.height), (40, 24));
    assert!(denoised.is_finite() && guide.guide.is_finite());
    assert_ne!(*denoised, run.film.beauty(), "the denoiser changed the image");
    let t = run.timings;
    assert!(t.guide_s.is_some() && t.denoise_s.is_some() && t.pipeline_s() >= t.render_s);
    for ext in ["exr", "png"] {
        let lib = dir.path().join(format!("lib.{ext}"));
        run.write(&lib, 0.0, Tonemap::Clamp).unwrap();
        let cli = dir.path().join(format!("cli.{ext}"));
        let c = cornell_path();
        let args = ["render", &c, "--width", "40", "--height", "24", "--spp", "4", "--seed", "3", "--denoise", "-q"];
        let out = rtd(&[&args[..], &["-o", cli.to_str().unwrap()]].concat());
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        assert_eq!(std::fs::read(&lib).unwrap(), std::fs::read(&cli).unwrap(), "{ext}: library and CLI differ");
    }
    let layers = rtd::image::read_exr(&dir.path().join("lib.exr")).unwrap();
    assert_eq!(layers.image(Layer::Beauty).as_ref(), Some(denoised));
    assert_eq!(layers.image(Layer::Noisy), Some(run.film.beauty()));
    assert_eq!(layers.image(Layer::Guide).as_ref(), Some(&guide.guide));
    assert!(layers.plane(Layer::Ao).is_some() && layers.plane(Layer::Depth).is_some());
}

/// Cancels once `after` image rows are reported.
struct CancelAfter {
    rows: AtomicU64,
    after: u64,
}

impl Progress for CancelAfter {
    fn inc(&self, n: u64) {
        self.rows.fetch_add(n, Ordering::SeqCst);
    }
    fn cancelled(&self) -> bool {
        self.rows.load(Ordering::SeqCst) >= self.after
    }
}

#[test]
fn a_cancelled_run_keeps_whole_passes_and_still_denoises_them() {
    let view = cornell();
    let model = Denoiser::builtin().unwrap();
    let settings = RenderSettings::new(32, 16);
    // Cancelled 5 rows into the third pass: that pass finishes, no fourth starts.
    let stop = CancelAfter { rows: AtomicU64::new(0), after: 2 * 16 + 5 };
    let run = Pipeline::new(&view, settings.clone()).denoise(&model).run(Budget::Samples(8), &stop).unwrap();
    assert_eq!(run.film.spp, 3);
    assert!(run.interrupted && run.denoised.is_some());
    let three = Pipeline::new(&view, settings.clone()).run(Budget::Samples(3), &Quiet).unwrap();
    assert_eq!(run.film.beauty(), three.film.beauty(), "the kept passes are those of a 3-spp render");
    assert!(!three.interrupted && three.guide.is_none() && three.denoised.is_none());
    // Cancelled before any pass: no image at all, and an error saying so.
    let at_once = CancelAfter { rows: AtomicU64::new(0), after: 0 };
    let err = Pipeline::new(&view, settings).run(Budget::Samples(8), &at_once).err().unwrap();
    assert!(matches!(err, PipelineError::NothingRendered), "{err}");
}

#[test]
fn a_time_budget_renders_whole_passes_and_settings_are_checked_first() {
    let view = cornell();
    let run = Pipeline::new(&view, RenderSettings::new(16, 16)).run(Budget::Time(Default::default()), &Quiet).unwrap();
    assert_eq!(run.film.spp, 1, "a zero budget still renders one pass");
    let bad = Pipeline::new(&view, RenderSettings::new(0, 16)).run(Budget::Samples(1), &Quiet).err().unwrap();
    assert!(bad.to_string().contains("0x16"), "{bad}");
    let guide = GuideSettings::new(8, 8);
    let err = Pipeline::new(&view, RenderSettings::new(16, 16)).guide(guide).run(Budget::Samples(1), &Quiet);
    assert!(matches!(err, Err(PipelineError::GuideSize { guide: (8, 8), render: (16, 16) })));
    // Guide settings a library caller can set by field are checked before the render too.
    let g = GuideSettings::new(16, 16);
    for (bad, needle) in [
        (GuideSettings { ao_rays: 0, ..g.clone() }, "AO rays 0"),
        (GuideSettings { ao_radius: Some(f32::NAN), ..g.clone() }, "AO radius NaN"),
        (GuideSettings { ao_step: 0, ..g.clone() }, "AO step"),
        (g.clone().threads(Some(0)), "threads"),
    ] {
        let err = Pipeline::new(&view, RenderSettings::new(16, 16)).guide(bad).run(Budget::Samples(1), &Quiet);
        assert!(err.err().unwrap().to_string().contains(needle), "{needle}");
    }
}

#[test]
fn a_look_at_camera_is_checked_by_the_library() {
    let path = common::repo_path("scenes/cornell-box.gltf");
    let look = |from: glam::Vec3, fov: f32| {
        SceneView::load(&path, &CameraChoice::LookAt { from, at: glam::Vec3::ZERO, fov }, None)
    };
    assert!(look(glam::Vec3::Z, 40.0).is_ok());
    for (from, fov) in
        [(glam::Vec3::Z, 0.0), (glam::Vec3::Z, 180.0), (glam::Vec3::Z, f32::NAN), (glam::Vec3::NAN, 40.0)]
    {
        let err = look(from, fov).err().unwrap();
        assert!(
            matches!(err, PipelineError::LookAtInvalid { .. }) && err.to_string().contains("cornell-box.gltf"),
            "{err}"
        );
    }
    assert!(matches!(look(glam::Vec3::ZERO, 40.0), Err(PipelineError::LookAtItself { .. })));
}

/// The Cornell box with its camera made for `aspect` (written into `dir`).
fn cornell_with_aspect(dir: &std::path::Path, aspect: f64) -> std::path::PathBuf {
    let mut doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(common::repo_path("scenes/cornell-box.gltf")).unwrap()).unwrap();
    doc["cameras"][0]["perspective"]["aspectRatio"] = serde_json::json!(aspect);
    let path = dir.join("wide.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    path
}

#[test]
fn the_image_size_follows_the_cameras_aspect_ratio_unless_both_sides_are_given() {
    let dir = tempfile::tempdir().unwrap();
    let wide = SceneView::load(&cornell_with_aspect(dir.path(), 2.0), &CameraChoice::Default, None).unwrap();
    assert_eq!(wide.camera.aspect_ratio, Some(2.0));
    assert_eq!(wide.resolution(None, None), (512, 256, None));
    assert_eq!(wide.resolution(Some(101), None), (101, 51, None));
    assert_eq!(wide.resolution(None, Some(100)), (200, 100, None));
    assert_eq!(wide.resolution(Some(300), Some(150)), (300, 150, None));
    let (w, h, warning) = wide.resolution(Some(100), Some(100));
    assert_eq!((w, h), (100, 100));
    assert!(warning.unwrap().contains("aspect ratio 2.000 but the image is 100x100"));
    // A file without an aspect ratio renders square by default.
    assert_eq!(cornell().resolution(None, None), (512, 512, None));
    assert_eq!(cornell().resolution(Some(64), None), (64, 64, None));
    // The command line follows it: one side given sets the other; both given warn on a mismatch.
    let scene = cornell_with_aspect(dir.path(), 16.0 / 9.0);
    let (s, out) = (scene.to_str().unwrap(), dir.path().join("o.png"));
    let o = rtd(&["render", s, "--width", "64", "--spp", "1", "-q", "-o", out.to_str().unwrap()]);
    assert!(o.status.success() && o.stderr.is_empty(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(image::image_dimensions(&out).unwrap(), (64, 36));
    let o = rtd(&["render", s, "--width", "64", "--height", "64", "--spp", "1", "-q", "-o", out.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && err.contains("warning") && err.contains("64x64"), "{err}");
    assert_eq!(image::image_dimensions(&out).unwrap(), (64, 64));
}
