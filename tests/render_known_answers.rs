//! Renders with known answers: white furnaces, an analytic irradiance, and delta lights.

mod common;

use common::*;
use glam::Vec3;
use rtd::render::RenderSettings;
use rtd::scene::{Camera, EnvMap, Environment, Light, Material, Projection, Scene};

/// A convex white Lambertian object under a uniform environment of radiance 1 reflects
/// exactly 1 everywhere: any lost or created energy shows up as a deviation.
#[test]
fn white_furnace_lambert_sphere() {
    let mut scene = furnace(1.0);
    scene.materials.push(Material { specular: 0.0, metallic: 0.0, ..material(Vec3::ONE, 1.0, 0.0, 0.0) });
    sphere(&mut scene, Vec3::ZERO, 1.0, 0, 64, 32);
    let cam = Camera::look_at(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, 30.0);
    let film = render(scene, cam, RenderSettings::new(48, 48).seed(1), 32);
    let img = film.beauty();
    let m = mean(&img.pixels);
    assert!((m - 1.0).abs() < 0.01, "mean {m}");
    // Every pixel, sphere or background, converges to 1.
    let worst =
        img.pixels.iter().map(|p| (p.max_element() - 1.0).abs().max((p.min_element() - 1.0).abs())).fold(0.0, f32::max);
    assert!(worst < 0.25, "worst pixel deviation {worst}");
}

/// Clear glass neither absorbs nor emits: inside the furnace it vanishes, which checks
/// Fresnel, total internal reflection and the 1/η² radiance scaling in and out.
#[test]
fn white_furnace_clear_glass_sphere() {
    for ior in [1.01f32, 1.5, 2.4] {
        let mut scene = furnace(1.0);
        scene.materials.push(Material { ior, ..material(Vec3::ONE, 0.0, 0.0, 1.0) });
        sphere(&mut scene, Vec3::ZERO, 1.0, 0, 96, 48);
        let cam = Camera::look_at(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, 30.0);
        let film = render(scene, cam, RenderSettings::new(32, 32).seed(2).max_depth(200), 16);
        let m = mean(&film.beauty().pixels);
        assert!((m - 1.0).abs() < 0.01, "ior {ior}: mean {m}");
    }
}

/// L/η² is invariant along a ray, so a camera inside a clear glass sphere in a white furnace
/// sees radiance η² in every direction: a direct test of the radiance scaling at refraction.
#[test]
fn camera_inside_glass_sees_eta_squared() {
    for ior in [1.33f32, 1.5] {
        let mut scene = furnace(1.0);
        scene.materials.push(Material { ior, ..material(Vec3::ONE, 0.0, 0.0, 1.0) });
        sphere(&mut scene, Vec3::ZERO, 3.0, 0, 96, 48);
        let cam = Camera::look_at(Vec3::new(0.3, 0.2, 0.1), Vec3::new(0.0, 0.0, -1.0), 60.0);
        let film = render(scene, cam, RenderSettings::new(16, 16).seed(5).max_depth(400), 16);
        let m = mean(&film.beauty().pixels);
        let expected = (ior * ior) as f64;
        assert!((m - expected).abs() < 0.01 * expected, "ior {ior}: {m} vs {expected}");
    }
}

/// Radiance of a Lambertian point under a parallel rectangular emitter:
/// L = ρ · Le · F, with F the form factor from a differential area to the rectangle.
#[test]
fn analytic_irradiance_from_rectangular_emitter() {
    let (rho, le, h, a) = (0.6f32, 2.0f32, 1.0f32, 1.5f32);
    let mut scene = Scene::default();
    scene.materials.push(Material { specular: 0.0, metallic: 0.0, ..material(Vec3::splat(rho), 1.0, 0.0, 0.0) });
    // The emitter is black (it reflects nothing) and faces down.
    scene.materials.push(Material {
        emissive: Vec3::splat(le),
        specular: 0.0,
        metallic: 0.0,
        ..material(Vec3::ZERO, 1.0, 0.0, 0.0)
    });
    let big = 50.0;
    quad(
        &mut scene,
        Vec3::new(-big, 0.0, big),
        Vec3::new(big, 0.0, big),
        Vec3::new(big, 0.0, -big),
        Vec3::new(-big, 0.0, -big),
        0,
    );
    quad(&mut scene, Vec3::new(-a, h, -a), Vec3::new(a, h, -a), Vec3::new(a, h, a), Vec3::new(-a, h, a), 1);
    // An orthographic camera between the planes looks straight down at a tiny patch.
    let mut cam = Camera::look_at(Vec3::new(0.0, 0.5 * h, 0.0), Vec3::new(0.0, -1.0, 0.0), 10.0);
    cam.projection = Projection::Orthographic { ymag: 0.002 };
    let film = render(scene, cam, RenderSettings::new(8, 8).seed(3), 1024);
    // Form factor to an a×a rectangle with a corner above the point (four of them).
    let corner = |x: f64, y: f64| {
        let (ax, by) = (x / h as f64, y / h as f64);
        let (sa, sb) = ((1.0 + ax * ax).sqrt(), (1.0 + by * by).sqrt());
        (ax / sa * (by / sa).atan() + by / sb * (ax / sb).atan()) / (2.0 * std::f64::consts::PI)
    };
    let f = 4.0 * corner(a as f64, a as f64);
    let expected = rho as f64 * le as f64 * f;
    let m = mean(&film.beauty().pixels);
    assert!((m - expected).abs() < 0.01 * expected, "measured {m}, analytic {expected}");
}

/// Delta lights in glTF units: a directional light of irradiance E at incidence θ and a point
/// light of intensity I at distance d give L = ρ/π · E·cosθ and ρ/π · I·cosθ/d².
#[test]
fn delta_lights_match_their_units() {
    let rho = 0.5f32;
    let make = |light: Light| {
        let mut scene = Scene::default();
        scene.materials.push(Material { specular: 0.0, metallic: 0.0, ..material(Vec3::splat(rho), 1.0, 0.0, 0.0) });
        quad(
            &mut scene,
            Vec3::new(-5.0, 0.0, 5.0),
            Vec3::new(5.0, 0.0, 5.0),
            Vec3::new(5.0, 0.0, -5.0),
            Vec3::new(-5.0, 0.0, -5.0),
            0,
        );
        scene.lights.push(light);
        let mut cam = Camera::look_at(Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 0.0, 0.0), 10.0);
        cam.projection = Projection::Orthographic { ymag: 0.001 };
        mean(&render(scene, cam, RenderSettings::new(4, 4).max_depth(1), 4).beauty().pixels)
    };
    let cos = 0.6f32;
    let dir = Vec3::new(-(1.0 - cos * cos).sqrt(), -cos, 0.0);
    let l = make(Light::Directional { direction: dir, irradiance: Vec3::splat(3.0) });
    let expected = (rho / std::f32::consts::PI * 3.0 * cos) as f64;
    assert!((l - expected).abs() < 1e-3 * expected, "directional: {l} vs {expected}");
    let l = make(Light::Point { position: Vec3::new(0.0, 2.0, 0.0), intensity: Vec3::splat(8.0) });
    let expected = (rho / std::f32::consts::PI * 8.0 / 4.0) as f64;
    assert!((l - expected).abs() < 1e-3 * expected, "point: {l} vs {expected}");
}

/// An environment map that is constant must light exactly like the constant environment,
/// which checks the map's importance sampling and its MIS weights.
#[test]
fn environment_map_matches_constant_environment() {
    let img = rtd::image::HdrImage::from_pixels(32, 16, vec![Vec3::splat(0.7); 512]);
    let build = |env: Environment| {
        let mut scene = Scene { environment: env, ..Scene::default() };
        scene.materials.push(material(Vec3::new(0.8, 0.5, 0.3), 0.5, 0.0, 0.0));
        sphere(&mut scene, Vec3::ZERO, 1.0, 0, 48, 24);
        let cam = Camera::look_at(Vec3::new(0.0, 1.0, 4.0), Vec3::ZERO, 30.0);
        mean(&render(scene, cam, RenderSettings::new(32, 32).seed(4), 32).beauty().pixels)
    };
    let a = build(Environment::Constant(Vec3::splat(0.7)));
    let b = build(Environment::Map(EnvMap { image: img, rotation: 2.0 }));
    assert!((a - b).abs() < 0.01 * a, "constant {a} vs map {b}");
}

/// `--env-rotation 90` is the same map with its columns moved a quarter turn: a scene lit by
/// one bright quadrant of sky renders the same either way (what reaches the sphere is the
/// same light from the same directions; only the sampling's rounding differs).
#[test]
fn a_turned_environment_equals_the_map_moved_by_whole_texels() {
    let (w, h) = (32usize, 16usize);
    // The bright quadrant in front of the camera and to its left (u in [1/4, 1/2)), so a
    // quarter turn moves it behind.
    let sky = |x: usize, y: usize| {
        if (w / 4..w / 2).contains(&x) && y < h / 2 {
            Vec3::new(6.0, 5.0, 4.0)
        } else {
            Vec3::splat(0.05)
        }
    };
    let image = |shift: usize| {
        let px = (0..w * h).map(|i| sky((i % w + shift) % w, i / w)).collect();
        rtd::image::HdrImage::from_pixels(w as u32, h as u32, px)
    };
    let build = |env: Environment| {
        let mut scene = Scene { environment: env, ..Scene::default() };
        scene.materials.push(material(Vec3::new(0.8, 0.5, 0.3), 0.5, 0.0, 0.0));
        sphere(&mut scene, Vec3::ZERO, 1.0, 0, 48, 24);
        let cam = Camera::look_at(Vec3::new(0.0, 1.0, 4.0), Vec3::ZERO, 30.0);
        mean(&render(scene, cam, RenderSettings::new(32, 32).seed(4), 64).beauty().pixels)
    };
    let turned = build(Environment::Map(EnvMap { image: image(0), rotation: std::f32::consts::FRAC_PI_2 }));
    let moved = build(Environment::Map(EnvMap::new(image(w / 4))));
    let unturned = build(Environment::Map(EnvMap::new(image(0))));
    assert!((turned - moved).abs() < 0.01 * moved, "turned {turned} vs moved {moved}");
    assert!((turned - unturned).abs() > 0.1 * unturned, "the turn must change the picture: {turned} vs {unturned}");
}

/// A Lambertian ground of albedo ρ under a uniform environment of radiance 1 reflects ρ. The
/// ground is a thousand units wide at height 0.1 and a small triangle lies far below it, so the
/// ground's BVH box reaches above it. Rays leaving the ground used to hit the very triangle they
/// left (the triangle test's rounding grows with the triangle's size, its offset with the
/// height), which blocked light.
#[test]
fn large_ground_under_the_sky_reflects_its_albedo() {
    let (rho, y) = (0.5f32, 0.1f32);
    let mut scene = furnace(1.0);
    scene.materials.push(Material { specular: 0.0, metallic: 0.0, ..material(Vec3::splat(rho), 1.0, 0.0, 0.0) });
    let big = 1000.0;
    quad(
        &mut scene,
        Vec3::new(-big, y, big),
        Vec3::new(big, y, big),
        Vec3::new(big, y, -big),
        Vec3::new(-big, y, -big),
        0,
    );
    tri(&mut scene, [Vec3::new(0.0, -50.0, 0.0), Vec3::new(1.0, -50.0, 0.0), Vec3::new(0.0, -50.0, 1.0)], 0);
    let mut cam = Camera::look_at(Vec3::new(3.0, 1.0, 2.0), Vec3::new(3.0, -1.0, 2.0), 10.0);
    cam.projection = Projection::Orthographic { ymag: 0.5 };
    let film = render(scene, cam, RenderSettings::new(16, 16).seed(5), 256);
    let m = mean(&film.beauty().pixels);
    assert!((m - rho as f64).abs() < 0.01 * rho as f64, "measured {m}, expected {rho}");
}

/// An unlit surface (KHR_materials_unlit) shows its base colour exactly, in the dark and in a
/// furnace alike, and lights nothing: a diffuse floor facing only an unlit wall stays black.
#[test]
fn unlit_surfaces_show_their_colour_and_light_nothing() {
    let colour = Vec3::new(0.3, 0.5, 0.7);
    let unlit = Material { unlit: true, ..material(colour, 1.0, 0.0, 0.0) };
    for env in [0.0, 1.0] {
        let mut scene = furnace(env);
        scene.materials.push(unlit.clone());
        quad(
            &mut scene,
            Vec3::new(-5.0, -5.0, 0.0),
            Vec3::new(5.0, -5.0, 0.0),
            Vec3::new(5.0, 5.0, 0.0),
            Vec3::new(-5.0, 5.0, 0.0),
            0,
        );
        let cam = Camera::look_at(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 40.0);
        let img = render(scene, cam, RenderSettings::new(8, 8).seed(3), 4).beauty();
        for p in &img.pixels {
            assert!((*p - colour).abs().max_element() < 1e-5, "env {env}: {p} is not {colour}");
        }
    }
    // A wall of unlit white in front of a diffuse floor, nothing else: the floor is black.
    let mut scene = furnace(0.0);
    scene.materials.push(Material { unlit: true, ..material(Vec3::ONE, 1.0, 0.0, 0.0) });
    scene.materials.push(material(Vec3::splat(0.8), 1.0, 0.0, 0.0));
    quad(
        &mut scene,
        Vec3::new(-5.0, 0.0, -1.0),
        Vec3::new(5.0, 0.0, -1.0),
        Vec3::new(5.0, 5.0, -1.0),
        Vec3::new(-5.0, 5.0, -1.0),
        0,
    );
    quad(
        &mut scene,
        Vec3::new(-5.0, 0.0, -1.0),
        Vec3::new(-5.0, 0.0, 5.0),
        Vec3::new(5.0, 0.0, 5.0),
        Vec3::new(5.0, 0.0, -1.0),
        1,
    );
    // Looking down at the floor in front of the wall (the wall itself out of view).
    let cam = Camera::look_at(Vec3::new(0.0, 3.0, 2.0), Vec3::new(0.0, 0.0, 2.01), 30.0);
    let img = render(scene, cam, RenderSettings::new(8, 8).seed(3), 16).beauty();
    assert!(img.pixels.iter().all(|p| *p == Vec3::ZERO), "the floor must stay black: {:?}", img.pixels);
}

/// Beer–Lambert: a ray through two clear absorbing spheres (ior 1, so nothing refracts or
/// reflects) in a white furnace keeps exp(−σ_a·d) of the light, with d the length it spends
/// inside them and not the gap between them.
#[test]
fn absorbing_volumes_attenuate_by_the_distance_inside_them() {
    let sigma = Vec3::new(0.7, 0.2, 1.6);
    let mut scene = furnace(1.0);
    scene.materials.push(Material { ior: 1.0, absorption: sigma, ..material(Vec3::ONE, 0.0, 0.0, 1.0) });
    // Radius 0.5 each, 0.6 apart along the view axis: 2 units of chord through the centres.
    sphere(&mut scene, Vec3::new(0.0, 0.0, 0.8), 0.5, 0, 128, 64);
    sphere(&mut scene, Vec3::new(0.0, 0.0, -0.8), 0.5, 0, 128, 64);
    let cam = Camera::look_at(Vec3::new(0.0, 0.0, 6.0), Vec3::ZERO, 0.5);
    let film = render(scene, cam, RenderSettings::new(32, 32).seed(9), 32);
    let m = film.beauty().pixels.iter().fold(Vec3::ZERO, |a, &p| a + p) / 1024.0;
    let want = (-sigma * 2.0).exp();
    // Russian roulette after the fourth crossing keeps each path with probability 0.68 (the
    // green transmittance), an unbiased 0.4% standard error over 32768 paths: allow 1.5%.
    assert!(((m / want) - Vec3::ONE).abs().max_element() < 0.015, "{m} vs {want}");
}
