//! The shipped denoiser: structural properties that must hold for any trained weights, and the
//! fast inference path held to burn's output.

use glam::Vec3;
use rtd::denoise::{DenoiseInput, Denoiser};
use rtd::image::HdrImage;

mod common;

fn model() -> Denoiser {
    Denoiser::builtin().expect("the built-in model loads")
}

/// A rendered Cornell box at 8 spp with its guide pass: (colour, guide pass).
fn cornell_inputs(w: u32, h: u32) -> (HdrImage, rtd::guide::GuidePass) {
    let scene = rtd::render::RenderScene::new(common::cornell());
    let cam = scene.scene.cameras[0].clone();
    let tracer =
        rtd::render::PathTracer::new(&scene, cam.clone(), rtd::render::RenderSettings::new(w, h).seed(5)).unwrap();
    let mut film = tracer.film();
    tracer.render(&mut film, 8).unwrap();
    let g =
        rtd::guide::GuidePass::render(&scene.scene, &scene.bvh, &cam, &rtd::guide::GuideSettings::new(w, h)).unwrap();
    (film.beauty(), g)
}

fn full_input<'a>(color: &'a HdrImage, g: &'a rtd::guide::GuidePass) -> DenoiseInput<'a> {
    rtd::pipeline::denoise_input(color, g)
}

#[test]
fn tiled_equals_untiled_and_the_fast_path_equals_burn() {
    let (color, g) = cornell_inputs(150, 118);
    let input = full_input(&color, &g);
    let whole = model().tile(1024).denoise(&input).unwrap();
    let tiled = model().tile(40).denoise(&input).unwrap();
    let burn = model().tile(1024).with_burn(true).denoise(&input).unwrap();
    // Compare in the encoded (log) domain scale: relative to the pixel value.
    let rel = |a: &HdrImage, b: &HdrImage| {
        a.pixels
            .iter()
            .zip(&b.pixels)
            .map(|(x, y)| ((*x - *y).abs() / (x.abs().max(y.abs()) + Vec3::splat(1e-3))).max_element())
            .fold(0.0, f32::max)
    };
    assert!(rel(&whole, &tiled) < 1e-4, "tiled vs untiled: {}", rel(&whole, &tiled));
    assert!(rel(&whole, &burn) < 1e-4, "fast vs burn: {}", rel(&whole, &burn));
}

#[test]
fn the_same_input_gives_identical_bytes() {
    let (color, g) = cornell_inputs(64, 48);
    let a = model().denoise(&full_input(&color, &g)).unwrap();
    // The same denoiser again, after another size has left other values in its kept buffers.
    let m = model();
    let (other, og) = cornell_inputs(90, 30);
    m.denoise(&full_input(&other, &og)).unwrap();
    let b = m.denoise(&full_input(&color, &g)).unwrap();
    assert_eq!(a.pixels, b.pixels);
}

#[test]
fn receptive_field_reaches_at_least_15_pixels_and_no_further_than_the_margin() {
    // On encoded planes (auto-exposure is global by design, so it is held fixed here).
    let m = model();
    let radius = m.config().receptive_radius();
    assert!(radius >= 15, "receptive field below 31x31");
    let (w, h) = (160usize, 160usize);
    let c = rtd::denoise::INPUT_CHANNELS;
    let mut planes: Vec<f32> = (0..c * w * h).map(|i| 0.3 + 0.2 * ((i * 37 % 11) as f32 / 11.0)).collect();
    let a = m.run_planes(&planes, w, h);
    planes[80 * w + 80] += 3.0; // colour channel 0 at (80, 80)
    let b = m.run_planes(&planes, w, h);
    // Influence is a change above rounding: the Winograd kernel's 4×4 output tiles share
    // rounding across their pixels, which moves values a few pixels past the receptive field
    // by about one ulp (9e-8 here), while real influence at 38 px is still above 1e-5.
    let mut reach = 0usize;
    for ch in 0..3 {
        for y in 0..h {
            for x in 0..w {
                if (a[ch * w * h + y * w + x] - b[ch * w * h + y * w + x]).abs() > 1e-6 {
                    reach = reach.max(x.abs_diff(80).max(y.abs_diff(80)));
                }
            }
        }
    }
    assert!(reach >= 15, "influence reaches only {reach} px");
    assert!(reach <= radius, "influence reaches {reach} px, beyond the receptive radius {radius}");
}

#[test]
fn black_input_gives_black_output_and_constants_stay_constant() {
    let m = model();
    let (w, h) = (48u32, 40u32);
    let zero = HdrImage::new(w, h);
    let grey = HdrImage::from_pixels(w, h, vec![Vec3::splat(0.5); (w * h) as usize]);
    let out = m.denoise(&DenoiseInput::new(&zero, &grey)).unwrap();
    let worst = out.pixels.iter().map(|p| p.max_element()).fold(0.0, f32::max);
    assert!(worst < 2e-3, "black input gave up to {worst}");
    for value in [0.05f32, 0.7, 30.0] {
        let c = HdrImage::from_pixels(w, h, vec![Vec3::splat(value); (w * h) as usize]);
        let out = m.denoise(&DenoiseInput::new(&c, &grey)).unwrap();
        // The centre sees only the constant; edge pixels also see the zero padding beyond the
        // replicated border, which may move them slightly but no further than 1%.
        let centre = out.get(w / 2, h / 2);
        let spread = out.pixels.iter().map(|p| (*p - centre).abs().max_element()).fold(0.0, f32::max) / value;
        assert!(spread <= 0.01, "output of constant {value} varies by {spread} of it");
        assert!(((centre.x / value) - 1.0).abs() < 0.05, "constant {value} became {centre:?}");
    }
    // The same with a constant albedo and normal, which the shipped model demodulates by.
    let (albedo, normal) = (HdrImage::from_pixels(w, h, vec![Vec3::splat(0.6); (w * h) as usize]), {
        HdrImage::from_pixels(w, h, vec![Vec3::Z; (w * h) as usize])
    });
    let c = HdrImage::from_pixels(w, h, vec![Vec3::splat(0.7); (w * h) as usize]);
    let out = m.denoise(&DenoiseInput::new(&c, &grey).albedo_normal(&albedo, &normal)).unwrap();
    let centre = out.get(w / 2, h / 2);
    let spread = out.pixels.iter().map(|p| (*p - centre).abs().max_element()).fold(0.0, f32::max) / 0.7;
    assert!(spread <= 0.01 && ((centre.x / 0.7) - 1.0).abs() < 0.05, "constant with albedo: {centre:?}, {spread}");
}

/// The shipped model denoises lighting: colour is divided by albedo + ε before the network, and
/// its decoded output is multiplied by the same factor. Without albedo nothing is divided.
#[test]
fn the_shipped_model_demodulates_by_albedo_and_multiplies_it_back() {
    use rtd::denoise::encode::{decode_color, DEMOD_EPS};
    use rtd::denoise::plane_encoder::encode_planes;
    let m = model();
    assert!(m.config().demodulates());
    let (color, g) = cornell_inputs(40, 36);
    let (w, h) = (40usize, 36usize);
    let n = w * h;
    for input in [full_input(&color, &g), DenoiseInput::new(&color, &g.guide)] {
        let e = m.config().encoding().exposure(&color);
        let raw = m.run_planes(&encode_planes(&input, e, m.config().encoding()).unwrap(), w, h);
        let out = m.denoise(&input).unwrap();
        for i in 0..n {
            for k in 0..3 {
                let factor = input.albedo_normal.map_or(1.0, |(a, _)| a.pixels[i][k].clamp(0.0, 1.0) + DEMOD_EPS);
                let expected = decode_color(raw[k * n + i], e) * factor;
                assert!((out.pixels[i][k] - expected).abs() <= 1e-6 * expected.max(1.0), "pixel {i} channel {k}");
            }
        }
    }
}

#[test]
fn the_shipped_model_reads_depth_and_ao_and_no_depth_models_are_refused() {
    // The output moves with the depth layer and with AO: the encoding fills both planes.
    let m = model();
    let (color, g) = cornell_inputs(40, 32);
    let far: Vec<f32> = g.depth.iter().map(|d| d * 3.0 + 1.0).collect();
    let dark: Vec<f32> = g.ao.iter().map(|a| a * 0.5).collect();
    let an = DenoiseInput::new(&color, &g.guide).albedo_normal(&g.albedo, &g.normal);
    let out = |ao: &[f32], depth: &[f32]| m.denoise(&an.ao_depth(ao, depth)).unwrap().pixels;
    let base = out(&g.ao, &g.depth);
    assert_ne!(base, out(&g.ao, &far));
    assert_ne!(base, out(&dark, &g.depth));
    // A model whose config says it was trained without depth (the removed `rtd train
    // --no-depth`) is refused rather than run as if it read depth.
    let root = common::repo_path("models");
    let json = std::fs::read_to_string(root.join("rtd-denoiser.json")).unwrap();
    let weights = std::fs::read(root.join("rtd-denoiser.bpk")).unwrap();
    let mut config: serde_json::Value = serde_json::from_str(&json).unwrap();
    config["depth"] = serde_json::Value::Bool(false);
    let e = Denoiser::from_bytes(&config.to_string(), weights.clone(), "m").err().expect("refused").to_string();
    assert!(e.contains("--no-depth"), "{e}");
    config["depth"] = serde_json::Value::Bool(true);
    assert!(Denoiser::from_bytes(&config.to_string(), weights.clone(), "m").is_ok());
    // An even prong has no centre tap (its branch would come out a pixel short); refused before
    // the weights are read, whatever their shapes.
    config["prong"] = serde_json::json!(4);
    let e = Denoiser::from_bytes(&config.to_string(), weights, "m").err().expect("refused").to_string();
    assert!(e.contains("implausible prong 4 (an odd width from 1 to 15)"), "{e}");
}

#[test]
fn nan_and_inf_inputs_give_finite_output() {
    let (mut color, g) = cornell_inputs(40, 40);
    color.set(3, 3, Vec3::new(f32::NAN, 1.0, 1.0));
    color.set(20, 20, Vec3::splat(f32::INFINITY));
    color.set(30, 10, Vec3::splat(1e6));
    color.set(31, 10, Vec3::splat(-4.0));
    let out = model().denoise(&full_input(&color, &g)).unwrap();
    assert!(out.is_finite());
}

/// A network that reads the variance planes, with random weights (the shipped model's are
/// trained to depend on them only weakly), over a rendered box and the film's variance.
#[test]
fn variance_planes_are_read_and_hold_to_burn_tiling_and_nan() {
    use rtd::denoise::DenoiserConfig;
    let config = DenoiserConfig::new(vec![8, 12, 16]).with_demodulate(Some(true));
    assert_eq!(config.input_channels, rtd::denoise::INPUT_CHANNELS);
    let model = || Denoiser::untrained(config.clone(), 11);
    let scene = rtd::render::RenderScene::new(common::cornell());
    let cam = scene.scene.cameras[0].clone();
    let (w, h) = (90, 70);
    let tracer = rtd::render::PathTracer::new(&scene, cam.clone(), rtd::render::RenderSettings::new(w, h)).unwrap();
    let mut film = tracer.film();
    tracer.render(&mut film, 8).unwrap();
    let g =
        rtd::guide::GuidePass::render(&scene.scene, &scene.bvh, &cam, &rtd::guide::GuideSettings::new(w, h)).unwrap();
    let (color, mut variance) = (film.beauty(), film.variance().unwrap());
    let input = full_input(&color, &g).variance(Some(&variance));
    let whole = model().denoise(&input).unwrap();
    let tiled = model().tile(24).denoise(&input).unwrap();
    let burn = model().with_burn(true).denoise(&input).unwrap();
    let rel = |a: &HdrImage, b: &HdrImage| {
        a.pixels
            .iter()
            .zip(&b.pixels)
            .map(|(x, y)| ((*x - *y).abs() / (x.abs().max(y.abs()) + Vec3::splat(1e-3))).max_element())
            .fold(0.0, f32::max)
    };
    assert!(rel(&whole, &tiled) < 1e-4, "tiled vs untiled: {}", rel(&whole, &tiled));
    assert!(rel(&whole, &burn) < 1e-4, "fast vs burn: {}", rel(&whole, &burn));
    let without = model().denoise(&full_input(&color, &g)).unwrap();
    assert!(rel(&whole, &without) > 1e-3, "the variance planes changed nothing");
    variance.set(5, 5, Vec3::new(f32::NAN, f32::INFINITY, -1.0));
    variance.set(6, 5, Vec3::splat(1e30));
    let odd = model().denoise(&full_input(&color, &g).variance(Some(&variance))).unwrap();
    assert!(odd.is_finite());
    // A variance image of another size is named.
    let small = HdrImage::new(4, 4);
    let e = model().denoise(&full_input(&color, &g).variance(Some(&small))).unwrap_err().to_string();
    assert!(e.contains("variance") && e.contains("4x4"), "{e}");
}

/// Denoising commutes with exposure: a render scaled by k (colour by k, its variance by k²), as
/// from a scene in other units or an exposure change before export, denoises to the unscaled
/// render's output times k, because auto-exposure maps both to the same encoded planes (before
/// 2026-12-06 a fixed luminance floor and a fixed input bound broke this: the worst pixel was
/// off by 1% of the image's mean at k = 1e-4 and 20% at k = 1e6).
#[test]
fn denoising_commutes_with_scaling_the_render_from_1e_minus_12_to_1e12() {
    let scene = rtd::render::RenderScene::new(common::cornell());
    let cam = scene.scene.cameras[0].clone();
    let (w, h) = (64, 48);
    let settings = rtd::render::RenderSettings::new(w, h).seed(9);
    let tracer = rtd::render::PathTracer::new(&scene, cam.clone(), settings).unwrap();
    let mut film = tracer.film();
    tracer.render(&mut film, 8).unwrap();
    let g =
        rtd::guide::GuidePass::render(&scene.scene, &scene.bvh, &cam, &rtd::guide::GuideSettings::new(w, h)).unwrap();
    let (color, variance) = (film.beauty(), film.variance().unwrap());
    let m = model();
    let base = m.denoise(&full_input(&color, &g).variance(Some(&variance))).unwrap();
    let mean = base.pixels.iter().map(|p| p.element_sum() as f64).sum::<f64>() / (3 * base.pixels.len()) as f64;
    assert!(mean > 1e-3, "the box is lit: mean {mean}");
    let scaled = |img: &HdrImage, k: f32| HdrImage::from_pixels(w, h, img.pixels.iter().map(|p| *p * k).collect());
    for k in [1e-12f32, 1e-9, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 0.37, 37.0, 1e3, 1e4, 1e5, 1e6, 1e9, 1e12] {
        let (c, v) = (scaled(&color, k), scaled(&variance, k * k));
        let out = m.denoise(&full_input(&c, &g).variance(Some(&v))).unwrap();
        // Largest difference from k × the unscaled output, relative to the pixel (floored at a
        // hundredth of the image's mean, for the box's black pixels).
        let worst = out
            .pixels
            .iter()
            .zip(&base.pixels)
            .map(|(o, b)| {
                let (o, b) = (o.as_dvec3() / k as f64, b.as_dvec3());
                ((o - b).abs() / (b.abs() + glam::DVec3::splat(0.01 * mean))).max_element()
            })
            .fold(0.0, f64::max);
        assert!(worst < 2e-5, "k = {k}: the output differs from k x the unscaled one by {worst}, relative");
    }
}

#[test]
fn one_pixel_and_odd_sizes_work() {
    for (w, h) in [(1u32, 1u32), (3, 17), (17, 5)] {
        let c = HdrImage::from_pixels(w, h, vec![Vec3::new(0.3, 0.2, 0.1); (w * h) as usize]);
        let out = model().denoise(&DenoiseInput::new(&c, &c)).unwrap();
        assert_eq!((out.width, out.height), (w, h));
        assert!(out.is_finite());
    }
}

/// Self-ensemble passes read the transformed image in place: each symmetry's output is the
/// network's output on an explicitly transformed copy, mapped back, bit for bit (tiled, on a
/// size that is neither square nor aligned).
#[test]
fn each_ensemble_pass_equals_the_network_on_a_transformed_copy() {
    use rtd::denoise::infer::Dihedral;
    let m = model().tile(40);
    let (w, h) = (70usize, 45usize);
    let c = rtd::denoise::INPUT_CHANNELS;
    let planes: Vec<f32> = (0..c * w * h).map(|i| 0.2 + 0.5 * ((i * 7919 % 101) as f32 / 101.0)).collect();
    let mut sources = vec![];
    for t in Dihedral::ORDER {
        let (tw, th) = t.size(w, h);
        let source: Vec<usize> = (0..th).flat_map(|y| (0..tw).map(move |x| t.source(x, y, w, h))).collect();
        let mut seen = vec![false; w * h];
        source.iter().for_each(|&i| seen[i] = true);
        assert!(seen.iter().all(|s| *s), "{t:?} is not a permutation of the pixels");
        let copy: Vec<f32> =
            (0..c).flat_map(|ch| source.iter().map(|&i| planes[ch * w * h + i]).collect::<Vec<_>>()).collect();
        let direct = m.run_planes(&copy, tw, th);
        let mapped = m.run_planes_as(&planes, w, h, t);
        for ch in 0..3 {
            for (p, &i) in source.iter().enumerate() {
                assert_eq!(mapped[ch * w * h + i], direct[ch * w * h + p], "{t:?}, channel {ch}, pixel {p}");
            }
        }
        sources.push(source);
    }
    sources.sort();
    sources.dedup();
    assert_eq!(sources.len(), 8, "the eight passes are not the eight symmetries");
}

/// The full eight-pass ensemble commutes with the symmetries: denoising a transposed (or
/// mirrored) render gives the transposed (mirrored) result of denoising the render, up to the
/// order of the sum. A single pass does not, so the test can tell them apart.
#[test]
fn the_eight_pass_ensemble_is_equivariant_and_one_pass_is_not() {
    use rtd::denoise::infer::Dihedral;
    // Both sides multiples of the network's alignment, so no side gets extra padding.
    let (color, g) = cornell_inputs(48, 32);
    let (w, h) = (48usize, 32usize);
    for t in [Dihedral::ORDER[1], Dihedral::ORDER[4]] {
        let (tw, th) = t.size(w, h);
        let map = |x: usize, y: usize| t.source(x, y, w, h);
        let image = |img: &HdrImage| {
            let px = (0..th).flat_map(|y| (0..tw).map(move |x| (x, y))).map(|(x, y)| img.pixels[map(x, y)]).collect();
            HdrImage::from_pixels(tw as u32, th as u32, px)
        };
        let plane = |v: &[f32]| (0..th).flat_map(|y| (0..tw).map(move |x| (x, y))).map(|(x, y)| v[map(x, y)]).collect();
        let (tc, tg, ta, tn) = (image(&color), image(&g.guide), image(&g.albedo), image(&g.normal));
        let (tao, tdepth): (Vec<f32>, Vec<f32>) = (plane(&g.ao), plane(&g.depth));
        let moved = DenoiseInput::new(&tc, &tg).albedo_normal(&ta, &tn).ao_depth(&tao, &tdepth);
        let worst = |passes: usize| {
            let a = image(&model().passes(passes).denoise(&full_input(&color, &g)).unwrap());
            let b = model().passes(passes).denoise(&moved).unwrap();
            a.pixels
                .iter()
                .zip(&b.pixels)
                .map(|(x, y)| ((*x - *y).abs() / (x.abs().max(y.abs()) + Vec3::splat(1e-3))).max_element())
                .fold(0.0, f32::max)
        };
        let (eight, one) = (worst(8), worst(1));
        assert!(eight < 1e-5, "{t:?}: eight passes differ by {eight}");
        assert!(one > 1e-3, "{t:?}: one pass is already equivariant ({one}), the test proves nothing");
    }
}
