//! The guide pass against known answers and against the path tracer's first-hit AOVs.

mod common;

use common::*;
use glam::{Vec2, Vec3, Vec4};
use rtd::guide::{ao_at, pattern, AoPoint, GuidePass, GuideSettings};
use rtd::render::{RenderScene, RenderSettings, SceneBvh, NO_TRIANGLE};
use rtd::scene::{Camera, Material, Projection, Scene, Texture, TextureRef, Triangle, Wrap};

fn guide(scene: &Scene, cam: &Camera, settings: GuideSettings) -> GuidePass {
    let bvh = SceneBvh::build(scene);
    GuidePass::render(scene, &bvh, cam, &settings).unwrap()
}

fn white() -> Material {
    material(Vec3::splat(0.8), 1.0, 0.0, 0.0)
}

/// A big floor at y=0 and, optionally, walls at x=−d1 and z=−d2 (facing the origin).
fn floor_and_walls(walls: &[(Vec3, f32)]) -> Scene {
    let mut s = Scene::default();
    s.materials.push(white());
    let b = 100.0;
    quad(&mut s, Vec3::new(-b, 0.0, b), Vec3::new(b, 0.0, b), Vec3::new(b, 0.0, -b), Vec3::new(-b, 0.0, -b), 0);
    for &(n, d) in walls {
        // A wall through the point −d·n, facing +n, 100 units tall.
        let c = -n * d;
        let t = n.cross(Vec3::Y);
        quad(&mut s, c - t * b, c + t * b, c + t * b + Vec3::Y * b, c - t * b + Vec3::Y * b, 0);
    }
    s
}

/// Cosine-weighted unoccluded fraction of the upper hemisphere for a floor point, where a
/// direction is blocked if `blocked(ω)`; integrated numerically on a fine (θ, φ) grid.
fn analytic_ao(blocked: impl Fn(Vec3) -> bool) -> f64 {
    let (nt, np) = (600, 1200);
    let mut open = 0.0;
    for i in 0..nt {
        let th = (i as f64 + 0.5) / nt as f64 * std::f64::consts::FRAC_PI_2;
        for j in 0..np {
            let ph = (j as f64 + 0.5) / np as f64 * std::f64::consts::TAU;
            let w = Vec3::new((th.sin() * ph.cos()) as f32, th.cos() as f32, (th.sin() * ph.sin()) as f32);
            if !blocked(w) {
                open += th.cos() * th.sin();
            }
        }
    }
    open * (std::f64::consts::FRAC_PI_2 / nt as f64) * (std::f64::consts::TAU / np as f64) / std::f64::consts::PI
}

#[test]
fn ao_is_one_on_an_unoccluded_plane() {
    let s = floor_and_walls(&[]);
    let cam = Camera::look_at(Vec3::new(0.0, 3.0, 3.0), Vec3::ZERO, 40.0);
    let g = guide(&s, &cam, GuideSettings::new(64, 48).ao_radius(Some(2.0)));
    assert!(g.ao.iter().all(|&a| a == 1.0), "AO below 1 on an open plane");
    assert_eq!(g.guide, g.albedo);
}

#[test]
fn ao_matches_analytic_values_next_to_walls_and_in_a_corner() {
    let radius = 1.0f32;
    let dirs = pattern(4096);
    let s = floor_and_walls(&[(Vec3::X, 0.3), (Vec3::Z, 0.0)]);
    let bvh = SceneBvh::build(&s);
    // Wall 1 at x = −0.3; wall 2 at z = 0 (the floor point sits on its foot: a corner line).
    // (Points exactly on a wall's plane would start their rays inside it; stay 1e-4 away.)
    for (p, label) in
        [(Vec3::new(0.0, 0.0, 5.0), "0.3 from one wall"), (Vec3::new(-0.2999, 0.0, 1e-4), "in the corner")]
    {
        let pt = AoPoint { p, p_error: Vec3::splat(1e-6), n: Vec3::Y, depth: 1.0, triangle: NO_TRIANGLE };
        let ao = ao_at(&s, &bvh, &pt, &dirs, radius) as f64;
        let (dx, dz) = (p.x + 0.3, p.z);
        let expected = analytic_ao(|w| {
            // Blocked by a wall if it lies within the radius along ω.
            (w.x < 0.0 && dx / -w.x < radius) || (w.z < 0.0 && dz / -w.z < radius)
        });
        assert!((ao - expected).abs() < 0.01, "{label}: AO {ao} vs analytic {expected}");
    }
    // The corner value is known in closed form: a quarter of the hemisphere stays open.
    let pt = AoPoint {
        p: Vec3::new(-0.2999, 0.0, 1e-4),
        p_error: Vec3::splat(1e-6),
        n: Vec3::Y,
        depth: 1.0,
        triangle: NO_TRIANGLE,
    };
    assert!((ao_at(&s, &bvh, &pt, &dirs, radius) - 0.25).abs() < 0.01);
}

/// Pixels whose 3×3 neighbourhood has one albedo, normal and depth: away from all edges.
fn interior_pixels(g: &GuidePass) -> Vec<usize> {
    let (w, h) = (g.albedo.width as usize, g.albedo.height as usize);
    let mut out = Vec::new();
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let i = y * w + x;
            if g.depth[i] <= 0.0 {
                continue;
            }
            let same = (0..9).all(|k| {
                let j = (y + k / 3 - 1) * w + (x + k % 3 - 1);
                (g.albedo.pixels[j] - g.albedo.pixels[i]).abs().max_element() < 1e-4
                    && (g.normal.pixels[j] - g.normal.pixels[i]).abs().max_element() < 0.05
                    && (g.depth[j] - g.depth[i]).abs() < 0.05 * g.depth[i]
            });
            if same {
                out.push(i);
            }
        }
    }
    out
}

/// The raster albedo equals the path tracer's first-hit albedo away from edges (≥ 99% of
/// interior pixels within 1e-3), and everywhere the two agree closely, so edges line up.
#[test]
fn albedo_agrees_with_the_path_tracer_and_edges_line_up() {
    for name in ["cornell-box", "glass-and-metals", "textured-interior", "small-lights"] {
        let scene = rtd::scene::load_scene(&repo_path(&format!("scenes/{name}.gltf"))).unwrap();
        let cam = scene.select_camera(None).unwrap().0;
        let (w, h) = (96, 72);
        let g = guide(&scene, &cam, GuideSettings::new(w, h));
        let film = render(scene.clone(), cam.clone(), RenderSettings::new(w, h).seed(1).max_depth(1), 256);
        let pt = film.albedo();
        let interior = interior_pixels(&g);
        assert!(interior.len() >= 200, "{name}: only {} interior pixels", interior.len());
        let good =
            interior.iter().filter(|&&i| (g.albedo.pixels[i] - pt.pixels[i]).abs().max_element() <= 1e-3).count();
        let frac = good as f64 / interior.len() as f64;
        assert!(frac >= 0.99, "{name}: {:.2}% of interior pixels within 1e-3", 100.0 * frac);
        // Edges: on untextured scenes the mean difference over all pixels, edges included, stays
        // near the 256-spp estimate's noise; a filter off by half a pixel fails this. (Textures
        // finer than a pixel alias differently under 9 fixed and 256 random samples.)
        if scene.textures.is_empty() {
            let diffs: Vec<f32> =
                g.albedo.pixels.iter().zip(&pt.pixels).map(|(a, b)| (*a - *b).abs().max_element()).collect();
            let mean = diffs.iter().sum::<f32>() / diffs.len() as f32;
            assert!(mean < 0.007, "{name}: mean |raster − path-traced albedo| = {mean}");
        }
        let depth = film.depth();
        let bad_depth = interior.iter().filter(|&&i| (g.depth[i] - depth[i]).abs() > 1e-2 * depth[i]).count();
        assert!(bad_depth * 100 <= interior.len(), "{name}: {bad_depth} interior depths disagree");
    }
}

/// Sparse AO with upsampling is as close to converged AO (256 rays at every pixel) as AO with
/// the same rays evaluated at every pixel. (The fixed pattern bands: dense AO steps by one ray's
/// share where a ray starts to hit, and the sparse lattice smooths those steps, so the
/// converged AO is the fair reference.) Interpolating across surfaces, or too coarse a lattice,
/// fails this.
#[test]
fn sparse_ao_is_as_close_to_converged_ao_as_dense_ao() {
    for name in ["cornell-box", "textured-interior", "glass-and-metals", "small-lights"] {
        let scene = rtd::scene::load_scene(&repo_path(&format!("scenes/{name}.gltf"))).unwrap();
        let cam = scene.select_camera(None).unwrap().0;
        let sparse = guide(&scene, &cam, GuideSettings::new(128, 96));
        let dense = guide(&scene, &cam, GuideSettings::new(128, 96).ao_step(1));
        let converged = guide(&scene, &cam, GuideSettings::new(128, 96).ao_step(1).ao_rays(256));
        // Mean |error| and the share of pixels within 0.05 of the converged AO.
        let error = |ao: &[f32]| {
            let d: Vec<f32> = ao.iter().zip(&converged.ao).map(|(a, b)| (a - b).abs()).collect();
            (d.iter().sum::<f32>() / d.len() as f32, d.iter().filter(|&&x| x <= 0.05).count() as f32 / d.len() as f32)
        };
        let ((sparse_mean, sparse_within), (dense_mean, dense_within)) = (error(&sparse.ao), error(&dense.ao));
        assert!(
            sparse_mean <= dense_mean + 0.004 && sparse_within >= dense_within - 0.02,
            "{name}: sparse mean {sparse_mean}, {:.1}% within 0.05; dense mean {dense_mean}, {:.1}%",
            100.0 * sparse_within,
            100.0 * dense_within
        );
    }
}

/// Large guides interpolate AO from a coarser lattice (`default_ao_step`), sized so that its
/// error stays below that of a 256² guide's lattice.
#[test]
fn large_guides_coarser_ao_lattice_is_as_accurate_as_a_small_guides() {
    let big = 864;
    assert_eq!(rtd::guide::default_ao_step(256, 256), 4);
    assert!(rtd::guide::default_ao_step(big, big) > 4, "the big guide must use a coarser lattice");
    for name in ["cornell-box", "small-lights"] {
        let scene = rtd::scene::load_scene(&repo_path(&format!("scenes/{name}.gltf"))).unwrap();
        let cam = scene.select_camera(None).unwrap().0;
        // Mean |sparse − per-pixel AO| at a resolution.
        let error = |size: u32| {
            let sparse = guide(&scene, &cam, GuideSettings::new(size, size));
            let dense = guide(&scene, &cam, GuideSettings::new(size, size).ao_step(1));
            sparse.ao.iter().zip(&dense.ao).map(|(a, b)| (a - b).abs() as f64).sum::<f64>() / sparse.ao.len() as f64
        };
        let (small, large) = (error(256), error(big));
        assert!(large <= small, "{name}: mean AO error {large} at {big}² vs {small} at 256²");
    }
}

#[test]
fn deterministic_across_runs_and_threads() {
    let scene = rtd::scene::load_scene(&repo_path("scenes/textured-interior.gltf")).unwrap();
    let cam = scene.select_camera(None).unwrap().0;
    let a = guide(&scene, &cam, GuideSettings::new(80, 60).threads(Some(1)));
    let b = guide(&scene, &cam, GuideSettings::new(80, 60).threads(Some(2)));
    assert_eq!(a.layers(), b.layers());
}

/// Geometry behind the camera and crossing the near plane neither crashes nor smears: the
/// raster agrees with the path tracer's first hits, and no layer holds NaN.
#[test]
fn near_plane_and_behind_camera_geometry() {
    let mut s = floor_and_walls(&[(Vec3::X, 2.0), (Vec3::Z, 2.0), (-Vec3::Z, 2.0)]);
    s.materials.push(material(Vec3::new(0.2, 0.5, 0.9), 1.0, 0.0, 0.0));
    // A box straddling the camera position.
    sphere(&mut s, Vec3::new(0.0, 1.0, 0.5), 0.6, 1, 32, 16);
    let cam = Camera::look_at(Vec3::new(0.0, 1.0, 1.0), Vec3::new(0.3, 0.5, -2.0), 100.0);
    let g = guide(&s, &cam, GuideSettings::new(64, 48));
    for (name, ch) in &g.layers().channels {
        assert!(ch.iter().all(|v| v.is_finite()), "non-finite {name}");
    }
    let film = render(s, cam, RenderSettings::new(64, 48).max_depth(1), 64);
    let pt = film.albedo();
    let interior = interior_pixels(&g);
    let good = interior.iter().filter(|&&i| (g.albedo.pixels[i] - pt.pixels[i]).abs().max_element() <= 1e-3).count();
    assert!(good * 100 >= interior.len() * 99, "{good} of {}", interior.len());
}

/// Tiny and huge scene scales give the same guide (AO's radius follows the scene).
#[test]
fn scale_invariant() {
    let scene = cornell();
    let cam = scene.select_camera(None).unwrap().0;
    let base = guide(&scene, &cam, GuideSettings::new(64, 64));
    for (scale, offset) in [(1e-3f32, Vec3::ZERO), (1e3, Vec3::new(1e5, -1e5, 1e5))] {
        let s = scene.transformed(scale, offset);
        let c = s.select_camera(None).unwrap().0;
        let g = guide(&s, &c, GuideSettings::new(64, 64));
        let albedo_diff = g
            .albedo
            .pixels
            .iter()
            .zip(&base.albedo.pixels)
            .filter(|(a, b)| (**a - **b).abs().max_element() > 1e-3)
            .count();
        let ao_diff = g.ao.iter().zip(&base.ao).map(|(a, b)| (a - b).abs()).sum::<f32>() / g.ao.len() as f32;
        assert!(albedo_diff <= 40, "scale {scale}: {albedo_diff} albedo pixels differ");
        assert!(ao_diff < 0.01, "scale {scale}: mean AO difference {ao_diff}");
    }
}

#[test]
fn orthographic_guide_matches_path_tracer_depth() {
    let s = floor_and_walls(&[(Vec3::X, 1.0)]);
    let mut cam = Camera::look_at(Vec3::new(0.5, 4.0, 0.2), Vec3::new(0.5, 0.0, 0.0), 40.0);
    cam.projection = Projection::Orthographic { ymag: 2.0 };
    let g = guide(&s, &cam, GuideSettings::new(40, 40));
    let film = render(s, cam, RenderSettings::new(40, 40).max_depth(1), 16);
    let d = film.depth();
    let interior = interior_pixels(&g);
    assert!(!interior.is_empty());
    for i in interior {
        assert!((g.depth[i] - d[i]).abs() < 1e-3, "pixel {i}: {} vs {}", g.depth[i], d[i]);
    }
    let _ = Vec2::ZERO;
    let _ = RenderScene::new;
}

/// Emitters and an emitting environment are white in the albedo layer, in the guide pass and in
/// the path tracer's AOV alike (a denoiser dividing colour by albedo then leaves light sources
/// as they are), and a black environment stays black.
#[test]
fn emitters_and_an_emitting_environment_have_white_albedo() {
    let mut s = Scene::default();
    s.materials.push(white());
    let mut light = material(Vec3::ZERO, 1.0, 0.0, 0.0);
    light.emissive = Vec3::new(5.0, 4.0, 3.0);
    s.materials.push(light);
    let b = 100.0;
    quad(&mut s, Vec3::new(-b, 0.0, b), Vec3::new(b, 0.0, b), Vec3::new(b, 0.0, -b), Vec3::new(-b, 0.0, -b), 0);
    // An emitting panel standing on the floor, facing the camera.
    quad(
        &mut s,
        Vec3::new(-1.0, 0.5, 0.0),
        Vec3::new(1.0, 0.5, 0.0),
        Vec3::new(1.0, 2.5, 0.0),
        Vec3::new(-1.0, 2.5, 0.0),
        1,
    );
    let cam = Camera::look_at(Vec3::new(0.0, 1.5, 6.0), Vec3::new(0.0, 1.5, 0.0), 50.0);
    let (w, h) = (48, 36);
    let (panel, sky, floor) = ((w / 2 + h / 2 * w) as usize, (w / 2) as usize, (w / 2 + (h - 1) * w) as usize);
    for (env, sky_albedo) in [(Vec3::ZERO, 0.0), (Vec3::splat(0.5), 1.0)] {
        s.environment = rtd::scene::Environment::Constant(env);
        let g = guide(&s, &cam, GuideSettings::new(w as u32, h as u32));
        let film = render(s.clone(), cam.clone(), RenderSettings::new(w as u32, h as u32).seed(3).max_depth(1), 16);
        let pt = film.albedo();
        for (label, i, want) in [("panel", panel, 1.0), ("sky", sky, sky_albedo), ("floor", floor, 0.8)] {
            assert_eq!(g.albedo.pixels[i], Vec3::splat(want), "guide, {label}, environment {env}");
            assert!(
                (pt.pixels[i] - Vec3::splat(want)).abs().max_element() < 1e-6,
                "path tracer, {label}: {}",
                pt.pixels[i]
            );
        }
    }
}

/// A texture far finer than a pixel (a one-texel checker, about 9 texels per pixel, the floor
/// seen obliquely) comes out of the guide as its mean, as the path tracer's many samples per
/// pixel average it: 9 point samples would alias it into a pattern.
#[test]
fn textures_finer_than_a_pixel_are_averaged_not_aliased() {
    let n = 64;
    let texels = (0..n * n).map(|i| Vec4::splat(((i % n + i / n) % 2) as f32)).collect();
    let mut s = Scene::default();
    s.textures.push(Texture::new(n, n, texels, Wrap::Repeat, Wrap::Repeat, false));
    let mut m = white();
    m.base_color = Vec4::ONE;
    m.base_color_texture = Some(TextureRef::plain(0));
    s.materials.push(m);
    // A 40 × 40 floor with the texture repeated every half unit.
    let b = 20.0;
    let corner = |x: f32, z: f32| (Vec3::new(x, 0.0, z), Vec2::new(x, z) * 2.0);
    let c = [corner(-b, b), corner(b, b), corner(b, -b), corner(-b, -b)];
    for [i, j, k] in [[0, 1, 2], [0, 2, 3]] {
        s.push_triangle(Triangle {
            p: [c[i].0, c[j].0, c[k].0],
            n: [Vec3::Y; 3],
            uv: [c[i].1, c[j].1, c[k].1],
            material: 0,
        });
    }
    let cam = Camera::look_at(Vec3::new(0.0, 2.0, 4.0), Vec3::new(0.0, 0.0, -2.0), 40.0);
    let g = guide(&s, &cam, GuideSettings::new(64, 48));
    let floor: Vec<f32> =
        (0..g.depth.len()).filter(|&i| g.depth[i] > 0.0).map(|i| (g.albedo.pixels[i].x - 0.5).abs()).collect();
    assert!(floor.len() > 1000);
    let mean = floor.iter().sum::<f32>() / floor.len() as f32;
    let worst = floor.iter().copied().fold(0.0, f32::max);
    assert!(mean < 0.02 && worst < 0.15, "|albedo − 0.5|: mean {mean}, worst {worst}");
}
