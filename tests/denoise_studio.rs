//! `rtd denoise` on studio files as they come: Blender's multi-part half-float EXR, Houdini's
//! and Nuke's layer names, named layers, OIDN's PFM/PHM and flag names, 16-bit PNG, and the
//! colour-only and colour + albedo modes; with every bad input of these loaders.

use std::path::Path;
mod common;

use common::cli::{assert_fails, noisy_exr, noisy_exr_without_variance, rtd};
use rtd::image::{HdrImage, Layer, Layers};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn ok(args: &[&str]) {
    let o = rtd(args);
    assert!(o.status.success(), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
}

/// The channels of `layer` in `l` as (name, samples) pairs under the suffixes `names`.
fn planes(l: &Layers, layer: Layer, names: [&'static str; 3]) -> Vec<(&'static str, Vec<f32>)> {
    let img = l.image(layer).unwrap();
    names.iter().enumerate().map(|(c, n)| (*n, img.channel(c))).collect()
}

/// Rounds every value to half precision, as a half-float file stores it.
fn halved(img: &HdrImage) -> HdrImage {
    let h = |v: f32| exr::prelude::f16::from_f32(v).to_f32();
    HdrImage::from_pixels(
        img.width,
        img.height,
        img.pixels.iter().map(|p| glam::Vec3::from_array(p.to_array().map(h))).collect(),
    )
}

/// An rtd-layout EXR holding `color`, `albedo` and `normal` exactly.
fn rtd_file(path: &Path, color: &HdrImage, albedo: &HdrImage, normal: &HdrImage) {
    let mut l = Layers::new(color.width, color.height);
    l.put_image(Layer::Beauty, color);
    l.put_image(Layer::Albedo, albedo);
    l.put_image(Layer::Normal, normal);
    rtd::image::write_exr(path, &l).unwrap();
}

#[test]
fn blenders_half_float_multipart_exr_denoises_as_it_comes_and_keeps_its_passes() {
    let dir = tempfile::tempdir().unwrap();
    let noisy = noisy_exr(dir.path(), 24, 20);
    let l = rtd::image::read_exr(&noisy).unwrap();
    let mut combined = planes(&l, Layer::Beauty, ["R", "G", "B"]);
    let alpha: Vec<f32> = (0..24 * 20).map(|i| (i % 7) as f32 / 6.0).collect();
    combined.push(("A", alpha.clone()));
    let depth = l.plane(Layer::Depth).unwrap().to_vec();
    let blender = dir.path().join("cycles.exr");
    common::write_multipart_exr_as(
        &blender,
        (24, 20),
        &[
            ("ViewLayer.Combined", combined),
            ("ViewLayer.Denoising Albedo", planes(&l, Layer::Albedo, ["R", "G", "B"])),
            ("ViewLayer.Denoising Normal", planes(&l, Layer::Normal, ["X", "Y", "Z"])),
            ("ViewLayer.Depth", vec![("Z", depth.clone())]),
        ],
        true,
    );
    let out = dir.path().join("out.exr");
    ok(&["denoise", "--color", s(&blender), "--albedo", s(&blender), "--normal", s(&blender), "-o", s(&out)]);
    // The same inputs, rounded to half, in rtd's own layout: the denoised colour is the same.
    let half = |layer| halved(&l.image(layer).unwrap());
    let own = dir.path().join("own.exr");
    rtd_file(&own, &half(Layer::Beauty), &half(Layer::Albedo), &half(Layer::Normal));
    let own_out = dir.path().join("own-out.exr");
    ok(&["denoise", "--color", s(&own), "--albedo", s(&own), "--normal", s(&own), "-o", s(&own_out)]);
    let want = halved(&rtd::image::read_exr(&own_out).unwrap().image(Layer::Beauty).unwrap());
    let got = rtd::image::read_exr(&out).unwrap();
    let names = ["R", "G", "B"].map(|c| format!("ViewLayer.Combined.{c}"));
    assert_eq!(got.image_in(&names), want, "the denoised colour replaces Combined");
    // Alpha, depth and the denoising passes are kept, in half precision as they came.
    assert_eq!(
        got.get("ViewLayer.Combined.A").unwrap(),
        halved(&HdrImage::from_planes(24, 20, &alpha, &alpha, &alpha)).channel(0)
    );
    assert_eq!(
        got.get("ViewLayer.Depth.Z").unwrap(),
        halved(&HdrImage::from_planes(24, 20, &depth, &depth, &depth)).channel(0)
    );
    assert!(got.get("ViewLayer.Denoising Albedo.G").is_some() && got.get("noisy.R").is_none());
    for c in ["R", "G", "B", "A"] {
        assert!(got.half_channels.contains(&format!("ViewLayer.Combined.{c}")), "{c} stays half");
    }
    // A file without a colour pass: the error lists the layers it has.
    let normals_only = dir.path().join("normals.exr");
    common::write_multipart_exr(
        &normals_only,
        (24, 20),
        &[("ViewLayer.Denoising Normal", planes(&l, Layer::Normal, ["X", "Y", "Z"]))],
    );
    let bad = dir.path().join("bad.exr");
    assert_fails(
        &rtd(&["denoise", "--color", s(&normals_only), "-o", s(&bad)]),
        "normals.exr: no colour layer (looked for bare R,G,B and passes named Combined, rgba, C, beauty; layers found: ViewLayer.Denoising Normal)",
    );
    assert!(!bad.exists());
}

#[test]
fn houdini_and_nuke_names_are_found_and_any_layer_can_be_named() {
    let dir = tempfile::tempdir().unwrap();
    let noisy = noisy_exr_without_variance(dir.path(), 20, 16);
    let l = rtd::image::read_exr(&noisy).unwrap();
    let reference = dir.path().join("ref.exr");
    ok(&["denoise", "--color", s(&noisy), "--albedo", s(&noisy), "--normal", s(&noisy), "-o", s(&reference)]);
    let want = rtd::image::read_exr(&reference).unwrap().image(Layer::Beauty).unwrap();
    // Houdini: C.r/g/b, albedo.r/g/b, N.x/y/z, found without being named.
    let houdini = dir.path().join("karma.exr");
    let mut h = Layers::new(20, 16);
    for (prefix, layer, names) in [
        ("C", Layer::Beauty, ["r", "g", "b"]),
        ("albedo", Layer::Albedo, ["r", "g", "b"]),
        ("N", Layer::Normal, ["x", "y", "z"]),
    ] {
        for (n, samples) in planes(&l, layer, names) {
            h.push(format!("{prefix}.{n}"), samples);
        }
    }
    rtd::image::write_exr(&houdini, &h).unwrap();
    let out = dir.path().join("h.exr");
    // OIDN's flag names.
    ok(&["denoise", "--hdr", s(&houdini), "--alb", s(&houdini), "--nrm", s(&houdini), "-o", s(&out)]);
    assert_eq!(rtd::image::read_exr(&out).unwrap().image_in(&["C.r", "C.g", "C.b"].map(String::from)), want);
    // Nuke-style names no search knows: named on the command line, by their last part.
    let nuke = dir.path().join("comp.exr");
    let mut n = Layers::new(20, 16);
    for (prefix, layer) in [("rgba", Layer::Beauty), ("comp.diffcolour", Layer::Albedo), ("comp.nrm", Layer::Normal)] {
        for (c, samples) in planes(&l, layer, ["red", "green", "blue"]) {
            n.push(format!("{prefix}.{c}"), samples);
        }
    }
    rtd::image::write_exr(&nuke, &n).unwrap();
    let out = dir.path().join("n.exr");
    let args = ["denoise", "--color", s(&nuke), "--albedo", s(&nuke), "--normal", s(&nuke), "-o", s(&out)];
    assert_fails(&rtd(&args), "no albedo layer");
    ok(&[&args[..], &["--layer-albedo", "DiffColour", "--layer-normal", "comp.nrm"]].concat());
    assert_eq!(
        rtd::image::read_exr(&out).unwrap().image_in(&["rgba.red", "rgba.green", "rgba.blue"].map(String::from)),
        want
    );
    let o = rtd(&[&args[..], &["--layer-albedo", "nothing"]].concat());
    assert_fails(&o, "comp.exr: no albedo layer (looked for the layer named \"nothing\"; layers found: comp.diffcolour, comp.nrm, rgba)");
}

#[test]
fn pfm_and_phm_in_and_out_match_the_exr_route() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let noisy = noisy_exr_without_variance(d, 20, 16);
    let l = rtd::image::read_exr(&noisy).unwrap();
    for (name, layer) in [("c.pfm", Layer::Beauty), ("a.pfm", Layer::Albedo), ("n.pfm", Layer::Normal)] {
        rtd::image::write_pfm(&d.join(name), &l.image(layer).unwrap(), false).unwrap();
    }
    let exr_out = d.join("e.exr");
    ok(&["denoise", "--color", s(&noisy), "--albedo", s(&noisy), "--normal", s(&noisy), "-o", s(&exr_out)]);
    let want = rtd::image::read_exr(&exr_out).unwrap().image(Layer::Beauty).unwrap();
    let (pfm, phm) = (d.join("o.pfm"), d.join("o.phm"));
    let (c, a, n) = (d.join("c.pfm"), d.join("a.pfm"), d.join("n.pfm"));
    let pfm_args = ["denoise", "--hdr", s(&c), "--alb", s(&a), "--nrm", s(&n)];
    ok(&[&pfm_args[..], &["-o", s(&pfm)]].concat());
    ok(&[&pfm_args[..], &["-o", s(&phm)]].concat());
    assert_eq!(rtd::image::read_pfm(&pfm).unwrap(), want);
    assert_eq!(rtd::image::read_pfm(&phm).unwrap(), halved(&want));
    assert!(std::fs::read(&phm).unwrap().starts_with(b"PH\n20 16\n"));
    // A half-float colour input gives a half-float EXR.
    rtd::image::write_pfm(&d.join("c.phm"), &l.image(Layer::Beauty).unwrap(), true).unwrap();
    let from_half = d.join("h.exr");
    ok(&["denoise", "--hdr", s(&d.join("c.phm")), "--alb", s(&d.join("a.pfm")), "-o", s(&from_half)]);
    assert!(rtd::image::read_exr(&from_half).unwrap().half_channels.contains(&"R".to_string()));
    // A render straight to PFM is the EXR's beauty.
    let (r_pfm, r_exr) = (d.join("r.pfm"), d.join("r.exr"));
    for out in [&r_pfm, &r_exr] {
        let scene = common::cli::cornell_path();
        ok(&["render", &scene, "-o", s(out), "--spp", "2", "--width", "12", "--height", "10", "-q"]);
    }
    assert_eq!(
        rtd::image::read_pfm(&r_pfm).unwrap(),
        rtd::image::read_exr(&r_exr).unwrap().image(Layer::Beauty).unwrap()
    );
}

#[test]
fn colour_only_and_colour_with_albedo_are_modes_of_their_own() {
    let dir = tempfile::tempdir().unwrap();
    let noisy = noisy_exr_without_variance(dir.path(), 24, 16);
    let l = rtd::image::read_exr(&noisy).unwrap();
    let color = l.image(Layer::Beauty).unwrap();
    let albedo = l.image(Layer::Albedo).unwrap();
    let model = rtd::denoise::Denoiser::builtin().unwrap();
    let only = dir.path().join("only.exr");
    let plain = dir.path().join("plain.exr");
    let mut p = Layers::new(24, 16);
    p.put_image(Layer::Beauty, &color);
    rtd::image::write_exr(&plain, &p).unwrap();
    ok(&["denoise", "--color", s(&plain), "-o", s(&only)]);
    let want = model.denoise(&rtd::denoise::DenoiseInput::new(&color, &color)).unwrap();
    assert_eq!(
        rtd::image::read_exr(&only).unwrap().image(Layer::Beauty).unwrap(),
        want,
        "the noisy colour is its own guide"
    );
    let with_albedo = dir.path().join("albedo.exr");
    ok(&["denoise", "--color", s(&noisy), "--albedo", s(&noisy), "-o", s(&with_albedo)]);
    let want = model.denoise(&rtd::denoise::DenoiseInput::new(&color, &albedo)).unwrap();
    assert_eq!(rtd::image::read_exr(&with_albedo).unwrap().image(Layer::Beauty).unwrap(), want);
}

#[test]
fn bad_studio_inputs_fail_in_one_line_without_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let noisy = noisy_exr(d, 20, 16);
    let out = d.join("out.exr");
    let denoise =
        |color: &Path, extra: &[&str]| rtd(&[&["denoise", "--color", s(color), "-o", s(&out)][..], extra].concat());
    // A truncated PFM, a PFM with a zero or non-numeric scale, and one with a bad kind.
    let cases: [(&str, &[u8], &str); 4] = [
        (
            "short.pfm",
            b"PF\n4 4\n-1.0\n\0\0\0\0",
            "short.pfm: a 4x4 3-channel file needs 192 bytes of pixels, it has 4",
        ),
        (
            "zero.pfm",
            b"PF\n1 1\n0\n\0\0\0\0\0\0\0\0\0\0\0\0",
            "zero.pfm: PFM scale \"0\" is not a non-zero finite number",
        ),
        ("word.pfm", b"PF\n1 1\nbig\n\0\0\0\0\0\0\0\0\0\0\0\0", "word.pfm: PFM scale \"big\""),
        ("kind.pfm", b"P6\n1 1\n255\n\0\0\0", "kind.pfm: not a PFM/PHM file: the kind is not PF, Pf, PH or Ph"),
    ];
    for (name, bytes, message) in cases {
        std::fs::write(d.join(name), bytes).unwrap();
        assert_fails(&denoise(&d.join(name), &[]), message);
    }
    // A 16-bit PNG albedo of another size than the colour.
    let wide = d.join("wide16.png");
    image::ImageBuffer::<image::Rgb<u16>, Vec<u16>>::new(21, 16).save(&wide).unwrap();
    assert_fails(&denoise(&noisy, &["--albedo", s(&wide)]), "wide16.png: image is 21x16 but the colour image is 20x16");
    // A named colour layer that is not there.
    assert_fails(&denoise(&noisy, &["--layer-color", "Combined"]), "noisy20x16.exr: no colour layer (looked for the layer named \"Combined\"; layers found: (bare channels), albedo, ao, depth, guide, normal, variance)");
    assert!(!out.exists());
    assert!(std::fs::read_dir(d).unwrap().all(|e| !e.unwrap().file_name().to_string_lossy().ends_with(".tmp")));
}
