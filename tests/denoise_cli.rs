//! `rtd denoise` and `rtd render --denoise` end to end, including every bad-input case.

use std::path::Path;
mod common;

use common::cli::{assert_fails, cornell_path, noisy_exr, rtd};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn render_denoise_writes_denoised_noisy_and_guide_layers_and_reports_timings() {
    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("d.exr");
    let report = dir.path().join("r.json");
    let o = rtd(&[
        "render",
        &cornell_path(),
        "-o",
        s(&exr),
        "--spp",
        "4",
        "--width",
        "40",
        "--height",
        "32",
        "--denoise",
        "--report",
        s(&report),
        "-q",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let layers = rtd::image::read_exr(&exr).unwrap();
    for ch in ["R", "G", "B", "noisy.R", "noisy.G", "noisy.B", "guide.R", "albedo.G", "normal.Z", "depth.Z", "ao.Y"] {
        assert!(layers.get(ch).is_some(), "missing {ch}");
    }
    assert_ne!(layers.get("R"), layers.get("noisy.R"), "R,G,B must be the denoised image");
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    for key in ["render_s", "guide_s", "denoise_s"] {
        assert!(r[key].as_f64().unwrap() > 0.0, "{key}");
    }
    assert!(r["denoise_model"].as_str().unwrap().starts_with("builtin:"));
    // PNG output is the denoised image.
    let png = dir.path().join("d.png");
    let o = rtd(&[
        "render",
        &cornell_path(),
        "-o",
        s(&png),
        "--spp",
        "4",
        "--width",
        "40",
        "--height",
        "32",
        "--denoise",
        "-q",
    ]);
    assert!(o.status.success());
    assert!(png.exists());
}

#[test]
fn denoise_reads_exr_and_png_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let noisy = noisy_exr(dir.path(), 36, 28);
    let out = dir.path().join("o.exr");
    let report = dir.path().join("r.json");
    let o = rtd(&[
        "denoise",
        "--color",
        s(&noisy),
        "--guide",
        s(&noisy),
        "--albedo",
        s(&noisy),
        "--normal",
        s(&noisy),
        "-o",
        s(&out),
        "--report",
        s(&report),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let l = rtd::image::read_exr(&out).unwrap();
    assert_eq!((l.width, l.height), (36, 28));
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert!(r["denoise_s"].as_f64().unwrap() > 0.0);
    // Colour and guide as sRGB PNGs (another renderer's beauty and material render).
    let (cp, gp) = (dir.path().join("c.png"), dir.path().join("g.png"));
    let img = rtd::image::read_exr(&noisy).unwrap();
    rtd::image::write_ldr(&cp, &img.image(rtd::image::Layer::Beauty).unwrap(), 0.0, rtd::image::Tonemap::Clamp)
        .unwrap();
    rtd::image::write_ldr(&gp, &img.image(rtd::image::Layer::Guide).unwrap(), 0.0, rtd::image::Tonemap::Clamp).unwrap();
    let outp = dir.path().join("o.png");
    let o = rtd(&["denoise", "--color", s(&cp), "--guide", s(&gp), "-o", s(&outp)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(outp.exists());
}

#[test]
fn denoise_bad_inputs_fail_cleanly_without_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let a = noisy_exr(d, 24, 16);
    let b = noisy_exr(d, 20, 16);
    let out = d.join("out.exr");
    // Different sizes.
    assert_fails(&rtd(&["denoise", "--color", s(&a), "--guide", s(&b), "-o", s(&out)]), "20x16");
    // Missing image.
    assert_fails(&rtd(&["denoise", "--color", s(&d.join("nope.exr")), "--guide", s(&a), "-o", s(&out)]), "nope.exr");
    // Unreadable (corrupt) image.
    let junk = d.join("junk.png");
    std::fs::write(&junk, b"not a png at all").unwrap();
    assert_fails(&rtd(&["denoise", "--color", s(&junk), "--guide", s(&a), "-o", s(&out)]), "junk.png");
    // A normal without an albedo (a usage error: exit status 2).
    let o = rtd(&["denoise", "--color", s(&a), "--normal", s(&a), "-o", s(&out)]);
    assert_fails(&o, "--albedo");
    assert_eq!(o.status.code(), Some(2));
    // Missing model, corrupt model, and a model whose channels do not match.
    assert_fails(
        &rtd(&["denoise", "--color", s(&a), "--guide", s(&a), "--model", s(&d.join("m.bpk")), "-o", s(&out)]),
        "m.bpk",
    );
    let m = d.join("bad.bpk");
    std::fs::write(&m, b"\x00garbage weights").unwrap();
    std::fs::write(d.join("bad.json"), include_str!("../models/rtd-denoiser.json")).unwrap();
    assert_fails(&rtd(&["denoise", "--color", s(&a), "--guide", s(&a), "--model", s(&m), "-o", s(&out)]), "corrupt");
    let wrong = d.join("wrong.bpk");
    std::fs::copy(Path::new(env!("CARGO_MANIFEST_DIR")).join("models/rtd-denoiser.bpk"), &wrong).unwrap();
    let cfg = include_str!("../models/rtd-denoiser.json").replace("\"input_channels\": 20", "\"input_channels\": 9");
    assert!(cfg.contains("\"input_channels\": 9"), "the shipped config names its input width");
    std::fs::write(d.join("wrong.json"), cfg).unwrap();
    assert_fails(
        &rtd(&["denoise", "--color", s(&a), "--guide", s(&a), "--model", s(&wrong), "-o", s(&out)]),
        "input channels",
    );
    let mismatch = d.join("mismatch.bpk");
    std::fs::copy(Path::new(env!("CARGO_MANIFEST_DIR")).join("models/rtd-denoiser.bpk"), &mismatch).unwrap();
    std::fs::write(
        d.join("mismatch.json"),
        r#"{"channels":[8,8,8],"bottleneck_blocks":2,"prong":5,"input_channels":16}"#,
    )
    .unwrap();
    assert_fails(
        &rtd(&["denoise", "--color", s(&a), "--guide", s(&a), "--model", s(&mismatch), "-o", s(&out)]),
        "do not match",
    );
    // More than 16384 px on a side.
    let wide = d.join("wide.png");
    image::RgbImage::new(16385, 1).save(&wide).unwrap();
    assert_fails(&rtd(&["denoise", "--color", s(&wide), "--guide", s(&wide), "-o", s(&out)]), "16384");
    // A decompression bomb: 45 bytes of PNG declaring 16000 x 16000 (each side allowed, 256 Mpx
    // and 768 MB in all), refused from its header before anything is decoded.
    let bomb = d.join("bomb.png");
    std::fs::write(&bomb, common::bomb::png_bomb(16000, 16000)).unwrap();
    let o = rtd(&["denoise", "--color", s(&bomb), "--guide", s(&a), "-o", s(&out)]);
    assert_fails(&o, &format!("{}: image size 16000x16000 exceeds", bomb.display()));
    assert!(!out.exists(), "no output may be written");
    assert!(std::fs::read_dir(d).unwrap().all(|e| !e.unwrap().file_name().to_string_lossy().ends_with(".tmp")));
}

/// `--ensemble N` runs the library's N-pass self-ensemble (the same bytes), says so in the
/// report, differs from one pass, and refuses counts outside 1–8 in one line without output.
#[test]
fn denoise_ensemble_is_the_librarys_and_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let noisy = noisy_exr(dir.path(), 32, 24);
    let run = |passes: &str, out: &Path, report: &Path| {
        let o = rtd(&[
            "denoise",
            "--color",
            s(&noisy),
            "--guide",
            s(&noisy),
            "--ensemble",
            passes,
            "-o",
            s(out),
            "--report",
            s(report),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(report).unwrap()).unwrap();
        assert_eq!(r["denoise_passes"].as_u64(), Some(passes.parse().unwrap()));
        rtd::image::read_exr(out).unwrap().image(rtd::image::Layer::Beauty).unwrap()
    };
    let four = run("4", &dir.path().join("o4.exr"), &dir.path().join("r4.json"));
    let one = run("1", &dir.path().join("o1.exr"), &dir.path().join("r1.json"));
    let img = rtd::image::read_exr(&noisy).unwrap();
    let (color, guide) = (img.image(rtd::image::Layer::Beauty).unwrap(), img.image(rtd::image::Layer::Guide).unwrap());
    // rtd's own file carries the colour's variance, which the CLI gives the shipped model.
    let variance = img.image(rtd::image::Layer::Variance);
    assert!(variance.is_some());
    let input = rtd::denoise::DenoiseInput::new(&color, &guide).variance(variance.as_ref());
    let library = rtd::denoise::Denoiser::builtin().unwrap().passes(4).denoise(&input).unwrap();
    assert_eq!(four.pixels, library.pixels);
    assert_ne!(four.pixels, one.pixels);
    let out = dir.path().join("o9.exr");
    assert_fails(&rtd(&["denoise", "--color", s(&noisy), "--guide", s(&noisy), "--ensemble", "9", "-o", s(&out)]), "9");
    assert!(!out.exists());
}
