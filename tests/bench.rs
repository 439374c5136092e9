//! `rtd bench etrt`, `suite` and `speed`: structure and invariants (timings themselves are not
//! tested).

use std::path::Path;

use rtd::bench::reference::ReferenceOptions;
use rtd::bench::report_files::write_etrt;
use rtd::bench::{run_etrt, EtrtOptions};
use rtd::denoise::Denoiser;
use rtd::image::Quiet;
use rtd::pipeline::{CameraChoice, SceneView};

#[test]
fn a_reference_doubles_until_converged_or_capped_and_rounds_do_not_change_it() {
    use rtd::bench::reference::render_reference;
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.gltf");
    let scene = SceneView::load(&path, &CameraChoice::Default, None).unwrap();
    let size = (16, 16, 7);
    let start = ReferenceOptions::default().spp(4).max_spp(16);
    // A target no render meets doubles 4 → 8 → 16 and stops at the cap.
    let (doubled, spp, noise) = render_reference(&scene, size, &start.relmse(1e-30), &Quiet).unwrap();
    assert_eq!(spp, 16);
    // The same 16 spp in one round are the same image: doubling continues the same films.
    let (direct, direct_spp, direct_noise) = render_reference(&scene, size, &start.spp(16), &Quiet).unwrap();
    assert_eq!(direct_spp, 16);
    assert_eq!(doubled.pixels, direct.pixels);
    assert_eq!(noise, direct_noise);
    // A target already met stops after the first round, with a larger estimate.
    let (_, first_spp, first_noise) = render_reference(&scene, size, &start.relmse(1e30), &Quiet).unwrap();
    assert_eq!(first_spp, 4);
    assert!(first_noise > noise && noise > 0.0, "{first_noise} then {noise}");
}

#[test]
fn etrt_report_has_every_image_and_consistent_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.gltf");
    let scene = SceneView::load(&path, &CameraChoice::Default, None).unwrap();
    let reference = ReferenceOptions::default().spp(32).max_spp(32);
    let options = EtrtOptions { spp: 2, width: 32, height: 32, reference, max_plain_factor: 4.0, ..Default::default() };
    let model = Denoiser::builtin().unwrap();
    let (report, images) = run_etrt(&scene, &model, &options, None, &dir.path().join("cache"), &Quiet).unwrap();
    let names: Vec<&str> = report.images.all().iter().map(|i| i.name.as_str()).collect();
    assert_eq!(names, ["noisy", "rtd denoised", "ETRT (equal time)", "ablation: noisy as guide", "guided filter"]);
    let etrt = &report.images.etrt;
    assert!(etrt.spp >= options.spp, "ETRT continues the same render");
    assert!(report.pipeline_s() > report.render_s);
    assert!(report.curve.windows(2).all(|w| w[1].0 >= w[0].0 && w[1].1 >= w[0].1), "curve advances in time and spp");
    assert!(report.time_to_quality_s > 0.0 && report.speedup > 0.0);
    assert!((report.pipeline_time_saved_percent - 100.0 * (1.0 - 1.0 / report.speedup)).abs() < 1e-6);
    assert!(report.reference_relmse.unwrap() >= 0.0);
    for i in report.images.all() {
        assert!(i.metrics.psnr.is_finite() && i.metrics.relmse >= 0.0 && i.metrics.ssim <= 1.0);
    }
    let files = write_etrt(&dir.path().join("out"), &report, &images).unwrap();
    for f in &files {
        assert!(f.exists() && std::fs::metadata(f).unwrap().len() > 0, "{}", f.display());
    }
    let md = std::fs::read_to_string(dir.path().join("out/report.md")).unwrap();
    assert!(md.contains("ETRT (equal time)") && md.contains("speed-up"));
    let img = image::open(dir.path().join("out/side-by-side.png")).unwrap();
    // Four panels side by side, each at least as wide as its two-line label, under which they sit.
    assert_eq!(img.width(), 4 * 230 + 3 * 4, "four panels side by side");
    assert_eq!(img.height(), 44 + 32 + 4 + 32, "labels, images, zooms");
    let labels = rtd::bench::figures::panel_labels(&report);
    let noisy = &report.images.noisy;
    assert_eq!(labels[0][1], format!("{} spp, {:.2} dB", noisy.spp, noisy.metrics.psnr));
    assert!(labels[2][0].contains("equal time") && labels[3][1].ends_with("spp"), "{labels:?}");
    // A second run reuses the cached reference.
    let (again, _) = run_etrt(&scene, &model, &options, None, &dir.path().join("cache"), &Quiet).unwrap();
    assert!(again.reference.contains("cached") && !again.reference.contains("rendered"), "{}", again.reference);
}

#[test]
fn speed_report_holds_the_render_against_raw_traversal() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.gltf");
    let scene = SceneView::load(&path, &CameraChoice::Default, None).unwrap();
    let model = Denoiser::builtin().unwrap();
    let report = rtd::bench::speed::run_speed(&scene, &model, (32, 32), 1, 1, &Quiet).unwrap();
    assert_eq!(report.runs, 1);
    let (camera, bounce) = (report.raw_camera_mrays_per_s.unwrap(), report.raw_bounce_mrays_per_s.unwrap());
    for rate in [camera, bounce, report.mrays_per_s.median] {
        assert!(rate.is_finite() && rate > 0.0, "{report:?}");
    }
    // The table shows each raw rate and the render's rays/s over it, in that order.
    let md = report.markdown();
    let figures = |label: &str| -> Vec<f64> {
        let line = md.lines().find(|l| l.starts_with(&format!("| {label} |"))).unwrap_or_else(|| panic!("{md}"));
        line.split('|').filter_map(|cell| cell.trim().parse().ok()).collect()
    };
    for (label, raw) in [("camera rays", camera), ("diffuse bounces from the camera hits", bounce)] {
        let [shown_raw, shown_share] = figures(label)[..] else { panic!("{md}") };
        assert!((shown_raw - raw).abs() <= 5e-4 * raw.max(1.0), "{label}: {shown_raw} against {raw}\n{md}");
        let share = report.mrays_per_s.median / raw;
        assert!((shown_share - share).abs() <= 0.006, "{label}: {shown_share} against {share}\n{md}");
    }
    // The JSON keeps the raw rates, and a report written before they existed still reads.
    let json = serde_json::to_value(&report).unwrap();
    assert_eq!(json["raw_bounce_mrays_per_s"].as_f64(), Some(bounce));
    let mut old = json.clone();
    old.as_object_mut().unwrap().remove("raw_camera_mrays_per_s");
    old.as_object_mut().unwrap().remove("raw_bounce_mrays_per_s");
    old.as_object_mut().unwrap().remove("denoise_warm_s_per_mpixel");
    let old: rtd::bench::speed::SpeedReport = serde_json::from_value(old).unwrap();
    assert_eq!(old.raw_bounce_mrays_per_s, None);
    assert!(old.markdown().contains("| camera rays | not measured |"), "{}", old.markdown());
    assert!(old.markdown().contains(", warm (1 pass) | not measured |"), "{}", old.markdown());
    // The warm denoiser figure: five timed calls after one untimed, shown beside the pipeline's.
    let warm = report.denoise_warm_s_per_mpixel.expect("measured");
    assert!(warm.min > 0.0 && warm.min <= warm.median && warm.median <= warm.max, "{warm:?}");
    let [median] = figures("denoise s / Mpixel, warm (1 pass, 5 calls)")[..] else { panic!("{md}") };
    assert!((median - warm.median).abs() <= 5e-4, "{median} against {warm:?}\n{md}");
    assert_eq!(json["denoise_warm_s_per_mpixel"]["median"].as_f64(), Some(warm.median));
    // Its rate: two FLOPs per multiply-accumulate of the shipped network, per pixel and pass.
    let macs = model.config().macs_per_pixel();
    let gflops = report.denoise_gflops().expect("measured");
    assert!((gflops.median - 2.0 * macs / (warm.median * 1e3)).abs() <= 1e-9 * gflops.median, "{gflops:?}");
    assert!(gflops.min <= gflops.median && gflops.median <= gflops.max, "{gflops:?}");
    let label = format!("denoise GFLOP/s, warm (2 × {:.1}k MAC/px as direct convolution)", macs / 1e3);
    let [shown] = figures(&label)[..] else { panic!("{md}") };
    assert!((shown - gflops.median).abs() <= 5e-4, "{shown} against {gflops:?}\n{md}");
    assert!(old.markdown().contains("| denoise GFLOP/s, warm | not measured |"), "{}", old.markdown());
}
