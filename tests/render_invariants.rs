//! Invariants of the renderer: determinism, progressive continuation, scale invariance, and
//! finite output on random extreme scenes.

mod common;

use common::*;
use glam::Vec3;
use rtd::render::{Film, PathTracer, RenderScene, RenderSettings};
use rtd::scene::{Camera, Environment, Light, Material, Scene};

fn cornell_camera(scene: &Scene) -> Camera {
    scene.select_camera(None).unwrap().0
}

#[test]
fn same_bytes_with_one_and_two_threads() {
    let scene = cornell();
    let cam = cornell_camera(&scene);
    let a = render(scene.clone(), cam.clone(), RenderSettings::new(40, 40).seed(9).threads(Some(1)), 4);
    let b = render(scene.clone(), cam.clone(), RenderSettings::new(40, 40).seed(9).threads(Some(2)), 4);
    assert_eq!(a.layers(), b.layers(), "thread count changed the image");
    let c = render(scene, cam, RenderSettings::new(40, 40).seed(10).threads(Some(2)), 4);
    assert_ne!(a.beauty(), c.beauty(), "the seed must matter");
}

#[test]
fn eight_plus_eight_equals_sixteen() {
    let scene = cornell();
    let cam = cornell_camera(&scene);
    let prepared = RenderScene::new(scene);
    let tracer = PathTracer::new(&prepared, cam, RenderSettings::new(32, 32).seed(3)).unwrap();
    let mut once = tracer.film();
    tracer.render(&mut once, 16).unwrap();
    let mut twice = tracer.film();
    tracer.render(&mut twice, 8).unwrap();
    tracer.render(&mut twice, 8).unwrap();
    assert_eq!(twice.spp, 16);
    assert_eq!(once.layers(), twice.layers(), "continuation differs from a single render");
}

#[test]
fn sample_ranges_merge_to_the_whole_render() {
    let scene = cornell();
    let cam = cornell_camera(&scene);
    let prepared = RenderScene::new(scene);
    let tracer = PathTracer::new(&prepared, cam, RenderSettings::new(24, 20).seed(5)).unwrap();
    let mut whole = tracer.film();
    tracer.render(&mut whole, 7).unwrap();
    // Three ranges, rendered as separate machines would, merged in order: 0..2, 2..3, 3..7.
    let ranges = [(0, 2), (2, 1), (3, 4)];
    let parts: Vec<Film> = ranges
        .iter()
        .map(|&(first, n)| {
            let mut f = Film::starting_at(24, 20, first);
            tracer.render(&mut f, n).unwrap();
            f
        })
        .collect();
    let mut merged = parts[0].clone();
    for p in &parts[1..] {
        merged.merge(p).unwrap();
    }
    assert_eq!(merged, whole, "split render differs from the one-machine film");
    assert_eq!(merged.layers(), whole.layers());
    // Grouped the other way: 0..2 then (2..3 + 3..7).
    let mut tail = parts[1].clone();
    tail.merge(&parts[2]).unwrap();
    let mut other = parts[0].clone();
    other.merge(&tail).unwrap();
    assert_eq!(other, whole, "merge grouping changed the film");
    // A gap or an overlap is refused.
    assert!(parts[0].clone().merge(&parts[2]).is_err());
    assert!(whole.clone().merge(&parts[1]).is_err());
}

/// The film's variance is each pixel's sample variance over N: rendered as 12 one-sample
/// ranges, the same pixels' samples give it by the textbook formula. (It is not the error
/// of the mean: Owen-scrambled Sobol samples are stratified, and on this box at 16 spp the
/// squared difference of two independent renders is about a fifth of what the i.i.d. formula
/// predicts. The denoiser learns that relation from rtd's own renders.)
#[test]
fn reported_variance_is_the_sample_variance_of_the_pixel_samples() {
    let scene = cornell();
    let cam = cornell_camera(&scene);
    let prepared = RenderScene::new(scene);
    let (w, h, n) = (20u32, 16u32, 12u32);
    let tracer = PathTracer::new(&prepared, cam, RenderSettings::new(w, h).seed(4)).unwrap();
    let mut whole = tracer.film();
    tracer.render(&mut whole, n).unwrap();
    let samples: Vec<Vec<Vec3>> = (0..n)
        .map(|k| {
            let mut one = Film::starting_at(w, h, k);
            tracer.render(&mut one, 1).unwrap();
            one.beauty().pixels
        })
        .collect();
    let reported = whole.variance().unwrap();
    let mut lit = 0;
    for i in 0..(w * h) as usize {
        let mean = samples.iter().map(|s| s[i].as_dvec3()).sum::<glam::DVec3>() / n as f64;
        let spread = samples.iter().map(|s| (s[i].as_dvec3() - mean).powf(2.0)).sum::<glam::DVec3>();
        let expected = spread / ((n - 1) as f64 * n as f64);
        let got = reported.pixels[i].as_dvec3();
        let tolerance = 1e-5 * expected.max_element().max(1e-3);
        assert!((got - expected).abs().max_element() <= tolerance, "pixel {i}: {got} against {expected}");
        lit += (expected.max_element() > 1e-4) as usize;
    }
    assert!(lit > 100, "only {lit} pixels vary: the check would prove little");
    let mut one = tracer.film();
    tracer.render(&mut one, 1).unwrap();
    assert!(one.variance().is_none() && one.layers().image(rtd::image::Layer::Variance).is_none());
}

/// The camera's near clip (glTF `znear`): a wall just in front of the lens but nearer than the
/// clip is not seen, by the path tracer's camera rays or by the guide pass, and depth is still
/// measured from the eye. Without the clip the wall fills the view.
#[test]
fn the_near_clip_hides_what_lies_in_front_of_it() {
    let scene = cornell();
    let cam = cornell_camera(&scene);
    // A dark wall facing the camera, 0.05 in front of it.
    let mut walled = scene.clone();
    let m = walled.materials.len() as u32;
    walled.materials.push(material(Vec3::splat(0.02), 1.0, 0.0, 0.0));
    let c = cam.position + cam.forward * 0.05;
    let (r, u) = (cam.right * 10.0, cam.up * 10.0);
    quad(&mut walled, c - r - u, c + r - u, c + r + u, c - r + u, m);
    quad(&mut walled, c - r - u, c - r + u, c + r + u, c + r - u, m);
    let settings = RenderSettings::new(24, 24).seed(2);
    let aovs = |scene: &Scene, cam: &Camera| {
        let f = render(scene.clone(), cam.clone(), settings.clone(), 1);
        let l = f.layers();
        [rtd::image::Layer::Albedo, rtd::image::Layer::Normal].map(|k| l.image(k).unwrap()).to_vec()
    };
    let depth = |scene: &Scene, cam: &Camera| render(scene.clone(), cam.clone(), settings.clone(), 1).depth();
    let clipped = cam.clone().with_znear(0.1);
    // The same clipped camera rays with and without the wall: the same first hits.
    assert!(aovs(&walled, &clipped) == aovs(&scene, &clipped), "the clip must hide the wall");
    // Depth is measured from the eye, as without a clip.
    let (near, far) = (depth(&walled, &clipped), depth(&scene, &cam));
    for (a, b) in near.iter().zip(&far) {
        assert!((a - b).abs() <= 1e-4 * b.max(1.0), "depth {a} against {b}");
    }
    assert!(aovs(&walled, &cam) != aovs(&scene, &cam), "without the clip the wall is seen");
    let guide = |scene: &Scene, cam: &Camera| {
        let prepared = RenderScene::new(scene.clone());
        let g =
            rtd::guide::GuidePass::render(&prepared.scene, &prepared.bvh, cam, &rtd::guide::GuideSettings::new(24, 24))
                .unwrap();
        (g.albedo, g.normal)
    };
    assert!(guide(&walled, &clipped) == guide(&scene, &clipped), "the guide pass clips too");
    assert!(guide(&walled, &cam) != guide(&scene, &cam));
}

/// A room lit by 60 small emitters of different powers, sides and colours, a point light, a
/// spot, a sun and a sky: every kind of light the selectors handle.
fn many_lights_room() -> (Scene, Camera) {
    let mut s = Scene::default();
    s.materials.push(material(Vec3::splat(0.6), 0.7, 0.0, 0.0));
    // A rough metal: a glossier one reflects the delta lights into fireflies that no light
    // selection can help (no MIS for a delta light).
    s.materials.push(material(Vec3::new(0.8, 0.7, 0.5), 0.6, 1.0, 0.0));
    let (lo, hi) = (Vec3::new(-4.0, 0.0, -4.0), Vec3::new(4.0, 3.0, 4.0));
    quad(
        &mut s,
        Vec3::new(lo.x, 0.0, hi.z),
        Vec3::new(hi.x, 0.0, hi.z),
        Vec3::new(hi.x, 0.0, lo.z),
        Vec3::new(lo.x, 0.0, lo.z),
        0,
    );
    quad(
        &mut s,
        Vec3::new(lo.x, 0.0, lo.z),
        Vec3::new(hi.x, 0.0, lo.z),
        Vec3::new(hi.x, 3.0, lo.z),
        Vec3::new(lo.x, 3.0, lo.z),
        0,
    );
    sphere(&mut s, Vec3::new(0.5, 0.8, -1.0), 0.8, 1, 24, 12);
    for i in 0..60 {
        let mut m = material(Vec3::ZERO, 1.0, 0.0, 0.0);
        m.emissive = Vec3::new(1.0 + (i % 3) as f32, 1.0 + (i % 5) as f32 * 0.5, 2.0) * (1.0 + (i % 7) as f32 * 3.0);
        m.double_sided = i % 4 == 0;
        s.materials.push(m);
        let (x, z) = (-3.5 + (i % 10) as f32 * 0.75, -3.5 + (i / 10) as f32 * 1.2);
        let (y, h) = (2.9, 0.12);
        // Most face down; every fifth faces a wall.
        let (a, b, c, d) = if i % 5 == 0 {
            (Vec3::new(x, y - h, z), Vec3::new(x, y - h, z + h), Vec3::new(x, y, z + h), Vec3::new(x, y, z))
        } else {
            (Vec3::new(x, y, z), Vec3::new(x + h, y, z), Vec3::new(x + h, y, z + h), Vec3::new(x, y, z + h))
        };
        let m = s.materials.len() as u32 - 1;
        quad(&mut s, a, b, c, d, m);
    }
    s.lights.push(Light::Point { position: Vec3::new(-2.0, 1.5, 1.0), intensity: Vec3::new(6.0, 4.0, 2.0) });
    s.lights.push(Light::spot(
        Vec3::new(2.0, 2.5, 2.0),
        Vec3::new(-0.3, -1.0, -0.5).normalize(),
        Vec3::splat(30.0),
        0.3,
        0.5,
    ));
    s.lights
        .push(Light::Directional { direction: Vec3::new(0.3, -1.0, -0.2).normalize(), irradiance: Vec3::splat(0.5) });
    s.environment = Environment::Constant(Vec3::new(0.05, 0.07, 0.1));
    (s, Camera::look_at(Vec3::new(0.0, 1.6, 3.9), Vec3::new(0.0, 1.0, -2.0), 70.0))
}

/// The light tree and power-proportional selection are two ways to pick the same lights: both
/// converge to the same image (means over the image and over 8×8 blocks agree within noise),
/// and on this many-lights room the tree's median per-pixel variance at equal samples is lower.
#[test]
fn the_light_tree_converges_to_the_power_selections_image_with_less_noise() {
    use rtd::render::LightSelection;
    let (scene, cam) = many_lights_room();
    let film = |selection| {
        let prepared = RenderScene::with_light_selection(scene.clone(), selection);
        let tracer = PathTracer::new(&prepared, cam.clone(), RenderSettings::new(32, 24).seed(8)).unwrap();
        let mut f = tracer.film();
        tracer.render(&mut f, 256).unwrap();
        f
    };
    let (tree, power) = (film(LightSelection::Tree), film(LightSelection::Power));
    let (a, b) = (tree.beauty(), power.beauty());
    let (ma, mb) = (mean(&a.pixels), mean(&b.pixels));
    assert!((ma / mb - 1.0).abs() < 0.02, "image means differ: tree {ma}, power {mb}");
    // 8×8 blocks: 12 of them, each within 6% (their noise at 256 spp is a few percent).
    for by in 0..3 {
        for bx in 0..4 {
            let block = |img: &rtd::image::HdrImage| {
                let px: Vec<Vec3> = (0..8)
                    .flat_map(|y| (0..8).map(move |x| (bx * 8 + x, by * 8 + y)))
                    .map(|(x, y)| img.get(x, y))
                    .collect();
                mean(&px)
            };
            let (x, y) = (block(&a), block(&b));
            assert!((x / y - 1.0).abs() < 0.06, "block ({bx}, {by}): tree {x}, power {y}");
        }
    }
    // The median pixel's variance: the tree picks lights that matter where it is.
    let median = |f: &Film| {
        let mut v: Vec<f32> = f.variance().unwrap().pixels.iter().map(|p| p.x + p.y + p.z).collect();
        v.sort_by(|a, b| a.total_cmp(b));
        v[v.len() / 2]
    };
    let (nt, np) = (median(&tree), median(&power));
    assert!(nt < 0.8 * np, "median variance: tree {nt} against power's {np}");
}

/// Root-mean-square difference of two images.
fn rmse(a: &rtd::image::HdrImage, b: &rtd::image::HdrImage) -> f64 {
    let s: f64 = a.pixels.iter().zip(&b.pixels).map(|(x, y)| (*x - *y).length_squared() as f64).sum();
    (s / a.pixels.len() as f64).sqrt()
}

/// The Cornell box at 1/1000 scale, and at 1000× scale moved 1e5 away, renders the same image
/// within noise: no acne, no light leaks, no lost precision far from the origin.
#[test]
fn cornell_box_is_scale_and_offset_invariant() {
    let scene = cornell();
    let settings = |seed| RenderSettings::new(48, 48).seed(seed);
    let spp = 64;
    let base = render(scene.clone(), cornell_camera(&scene), settings(1), spp).beauty();
    let noise = rmse(&base, &render(scene.clone(), cornell_camera(&scene), settings(2), spp).beauty());
    for (scale, offset) in [(1e-3f32, Vec3::ZERO), (1e3, Vec3::new(1e5, -1e5, 1e5))] {
        let s = scene.transformed(scale, offset);
        let cam = cornell_camera(&s);
        let img = render(s, cam, settings(2), spp).beauty();
        let diff = rmse(&base, &img);
        let (m0, m1) = (mean(&base.pixels), mean(&img.pixels));
        assert!((m0 - m1).abs() < 0.01 * m0, "scale {scale}: mean {m1} vs {m0}");
        assert!(diff < 1.25 * noise, "scale {scale}: rmse {diff} vs seed-to-seed noise {noise}");
    }
}

/// A tiny deterministic generator for the fuzz test.
struct Lcg(u64);
impl Lcg {
    fn f(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32) / (1u64 << 24) as f32
    }
    fn pick<T: Copy>(&mut self, v: &[T]) -> T {
        v[((self.f() * v.len() as f32) as usize).min(v.len() - 1)]
    }
    fn v3(&mut self, s: f32) -> Vec3 {
        Vec3::new(self.f() - 0.5, self.f() - 0.5, self.f() - 0.5) * s
    }
}

/// Random scenes with extreme parameters never produce NaN/Inf pixels or samples.
#[test]
fn no_nan_over_random_extreme_scenes() {
    let mut rng = Lcg(12345);
    for case in 0..40 {
        let scale = rng.pick(&[1e-4f32, 1.0, 1e4]);
        let mut scene = Scene::default();
        for _ in 0..6 {
            scene.materials.push(Material {
                base_color: Vec3::new(rng.f(), rng.f(), rng.f()).extend(1.0),
                roughness: rng.pick(&[0.0, 1e-4, 0.02, 0.5, 1.0]),
                metallic: rng.pick(&[0.0, 0.5, 1.0]),
                transmission: rng.pick(&[0.0, 1.0, 0.5]),
                ior: rng.pick(&[1.0, 1.0001, 1.0009, 1.5, 3.0]),
                specular: rng.pick(&[0.0, 1.0]),
                emissive: Vec3::splat(rng.pick(&[0.0, 0.0, 1.0, 1e6])),
                double_sided: rng.f() < 0.5,
                ..Material::default()
            });
        }
        let n = 1 + (rng.f() * 60.0) as usize;
        for _ in 0..n {
            let c = rng.v3(4.0 * scale);
            let size = scale * rng.pick(&[1e-6, 1e-3, 0.5, 3.0, 1e3]);
            let m = (rng.f() * 6.0) as u32 % 6;
            let p = [c + rng.v3(size), c + rng.v3(size), c + rng.v3(size)];
            tri(&mut scene, p, m);
            if rng.f() < 0.2 {
                // Nearly degenerate sliver sharing an edge.
                tri(&mut scene, [p[0], p[1], p[1] + (p[1] - p[0]) * 1e-7 + Vec3::splat(1e-9 * scale)], m);
            }
        }
        if rng.f() < 0.5 {
            scene
                .lights
                .push(Light::Point { position: rng.v3(2.0 * scale), intensity: Vec3::splat(scale * scale * 1e6) });
        }
        if rng.f() < 0.3 {
            scene
                .lights
                .push(Light::Directional { direction: rng.v3(1.0).normalize_or(Vec3::NEG_Y), irradiance: Vec3::ONE });
        }
        if rng.f() < 0.5 {
            scene.environment = Environment::Constant(Vec3::splat(rng.pick(&[0.5, 1e6])));
        }
        if scene.triangles.is_empty() {
            continue;
        }
        let cam = Camera::look_at(Vec3::new(0.0, 0.0, 12.0 * scale), Vec3::ZERO, 50.0);
        let film = render(scene, cam, RenderSettings::new(12, 12).seed(case), 3);
        assert_eq!(film.nonfinite_samples, 0, "case {case}: non-finite samples");
        for (name, ch) in &film.layers().channels {
            assert!(ch.iter().all(|v| v.is_finite()), "case {case}: non-finite {name}");
        }
    }
}

/// 1 spp and very high spp both work; the estimate at 16k spp of a furnace is exactly 1 with
/// f64 accumulation keeping precision.
#[test]
fn extreme_sample_counts() {
    let mut scene = furnace(1.0);
    scene.materials.push(Material { specular: 0.0, metallic: 0.0, ..material(Vec3::ONE, 1.0, 0.0, 0.0) });
    sphere(&mut scene, Vec3::ZERO, 1.0, 0, 64, 32);
    let cam = Camera::look_at(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, 30.0);
    let one = render(scene.clone(), cam.clone(), RenderSettings::new(8, 8), 1);
    assert!(one.beauty().is_finite());
    let many = render(scene, cam, RenderSettings::new(2, 2), 16384);
    let m = mean(&many.beauty().pixels);
    assert!((m - 1.0).abs() < 2e-3, "16k spp furnace mean {m}");
}
