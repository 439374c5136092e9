//! Criterion benchmarks: BVH build, raw traversal rays/s, full-render paths/s and the guide pass
//! on the bundled scenes. After the criterion groups, one run measures the integrator's rays/s
//! against raw closest-hit traversal on the same scene (the integrator's overhead as a ratio),
//! and the guide pass's time as a share of an 8-spp render from 256² to 4K.

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::{criterion_group, Criterion, Throughput};
use rtd::bench::traversal::{camera_rays, ProbeRay, RawTraversal};
use rtd::guide::{GuidePass, GuideSettings};
use rtd::render::{PathTracer, RenderScene, RenderSettings, SceneBvh};
use rtd::scene::{load_scene, Scene};

const SCENES: [&str; 4] = ["cornell-box", "glass-and-metals", "textured-interior", "small-lights"];

fn scene(name: &str) -> Scene {
    load_scene(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes").join(format!("{name}.gltf"))).unwrap()
}

/// Camera rays through `n` points of a 256² film of the scene's camera.
fn scene_camera_rays(s: &Scene, n: u32) -> Vec<ProbeRay> {
    camera_rays(&s.select_camera(None).unwrap().0, (256, 256), n)
}

fn bvh_build(c: &mut Criterion) {
    let mut g = c.benchmark_group("bvh_build");
    for name in SCENES {
        let s = scene(name);
        g.throughput(Throughput::Elements(s.triangles.len() as u64));
        g.bench_function(name, |b| b.iter(|| black_box(SceneBvh::build(&s))));
    }
    g.finish();
}

fn traversal(c: &mut Criterion) {
    let mut g = c.benchmark_group("traversal_primary");
    for name in SCENES {
        let s = scene(name);
        let bvh = SceneBvh::build(&s);
        let rays = scene_camera_rays(&s, 4096);
        g.throughput(Throughput::Elements(rays.len() as u64));
        g.bench_function(name, |b| {
            b.iter(|| rays.iter().filter(|r| bvh.intersect(&s, r.origin, r.dir, f32::INFINITY).is_some()).count())
        });
    }
    g.finish();
}

fn render(c: &mut Criterion) {
    let mut g = c.benchmark_group("render_1spp_64x64");
    g.sample_size(10);
    for name in SCENES {
        let s = scene(name);
        let cam = s.select_camera(None).unwrap().0;
        let prepared = RenderScene::new(s);
        let tracer = PathTracer::new(&prepared, cam, RenderSettings::new(64, 64)).unwrap();
        g.throughput(Throughput::Elements(64 * 64));
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut film = tracer.film();
                tracer.render(&mut film, 1).unwrap();
                film
            })
        });
    }
    g.finish();
}

fn guide(c: &mut Criterion) {
    let mut g = c.benchmark_group("guide_256x256");
    g.sample_size(10);
    for name in SCENES {
        let s = scene(name);
        let cam = s.select_camera(None).unwrap().0;
        let bvh = SceneBvh::build(&s);
        let settings = GuideSettings::new(256, 256);
        g.throughput(Throughput::Elements(256 * 256));
        g.bench_function(name, |b| b.iter(|| GuidePass::render(&s, &bvh, &cam, &settings).unwrap()));
    }
    g.finish();
}

criterion_group!(benches, bvh_build, traversal, render, guide);

/// The guide pass's cost as a share of an 8-spp render of the same view (the bar is 5%),
/// for every bundled scene at each resolution, measured back to back in one run. Each figure is
/// the fastest of several runs, interleaved (render, then three guides, per round): on a shared
/// machine a short pass is hit harder by a stray interruption than a long one, and the fastest
/// run is the cost without them. Images up to 512² get five rounds, larger ones one (their
/// renders take seconds and vary little).
fn guide_share(resolutions: &[(u32, u32)], scenes: &[&str]) {
    println!("| scene | resolution | render 8 spp (s) | guide (s) | guide / render |");
    println!("|---|---|---|---|---|");
    for &name in scenes {
        let s = scene(name);
        let cam = s.select_camera(None).unwrap().0;
        let prepared = RenderScene::new(s);
        for &(w, h) in resolutions {
            let tracer = PathTracer::new(&prepared, cam.clone(), RenderSettings::new(w, h)).unwrap();
            let rounds = if w * h <= 512 * 512 { 5 } else { 1 };
            let (mut render, mut guide) = (f64::INFINITY, f64::INFINITY);
            for _ in 0..rounds {
                let mut film = tracer.film();
                render = render.min(tracer.render(&mut film, 8).unwrap().seconds);
                for _ in 0..3 {
                    let g = GuidePass::render(&prepared.scene, &prepared.bvh, &cam, &GuideSettings::new(w, h)).unwrap();
                    guide = guide.min(g.seconds);
                }
            }
            println!("| {name} | {w}x{h} | {render:.3} | {guide:.3} | {:.1}% |", 100.0 * guide / render);
        }
    }
}

/// Integrator rays/s against raw closest-hit traversal rays/s on the Cornell box, one run, for
/// camera rays and for one diffuse bounce from each camera hit (incoherent).
fn overhead_ratio(seconds: f64) {
    let s = scene("cornell-box");
    let cam = s.select_camera(None).unwrap().0;
    let prepared = RenderScene::new(s.clone());
    let tracer = PathTracer::new(&prepared, cam.clone(), RenderSettings::new(256, 256)).unwrap();
    let mut film = tracer.film();
    let stats = tracer.render_for(&mut film, Duration::from_secs_f64(seconds), &rtd::image::Quiet).unwrap();
    let integrator = stats.rays as f64 / stats.seconds / 1e6;
    let raw = RawTraversal::measure(&prepared, &cam, (256, 256), 1 << 16, seconds);
    let (camera, bounce) = (raw.camera.unwrap(), raw.bounce.unwrap());
    println!(
        "cornell-box 256x256: integrator {integrator:.2} M rays/s ({:.3} M paths/s); raw traversal {camera:.2} M rays/s \
         on camera rays (ratio {:.2}), {bounce:.2} M rays/s on diffuse bounces (ratio {:.2})",
        stats.paths as f64 / stats.seconds / 1e6,
        integrator / camera,
        integrator / bounce
    );
}

fn main() {
    benches();
    Criterion::default().configure_from_args().final_summary();
    // In `cargo test` mode criterion runs each benchmark once; keep the ratio run short there too.
    let quick = std::env::args().any(|a| a == "--test") || !std::env::args().any(|a| a == "--bench");
    overhead_ratio(if quick { 0.2 } else { 3.0 });
    if quick {
        guide_share(&[(64, 64)], &["cornell-box"]);
    } else {
        guide_share(&[(256, 256), (1024, 1024), (1920, 1080), (3840, 2160)], &SCENES);
    }
}
