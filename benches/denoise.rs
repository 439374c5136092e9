//! Criterion benchmarks of the denoiser: the fast im2col + gemm path and the burn path on a
//! 512×512 Cornell box render with its guide pass, and the guided-filter baseline.

use std::hint::black_box;
use std::path::Path;

use criterion::{criterion_group, Criterion, Throughput};
use rtd::denoise::filter::GuidedFilter;
use rtd::denoise::Denoiser;
use rtd::guide::{GuidePass, GuideSettings};
use rtd::render::{PathTracer, RenderScene, RenderSettings};

fn size() -> u32 {
    // `cargo test --all-targets` runs each benchmark once: keep that quick.
    if std::env::args().any(|a| a == "--bench") {
        512
    } else {
        64
    }
}

fn denoise(c: &mut Criterion) {
    let n = size();
    let scene = RenderScene::new(
        rtd::scene::load_scene(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.gltf")).unwrap(),
    );
    let cam = scene.scene.cameras[0].clone();
    let tracer = PathTracer::new(&scene, cam.clone(), RenderSettings::new(n, n)).unwrap();
    let mut film = tracer.film();
    tracer.render(&mut film, 8).unwrap();
    let color = film.beauty();
    let g = GuidePass::render(&scene.scene, &scene.bvh, &cam, &GuideSettings::new(n, n)).unwrap();
    let input = rtd::pipeline::denoise_input(&color, &g);
    let mut group = c.benchmark_group(format!("denoise_{n}x{n}"));
    group.sample_size(10).throughput(Throughput::Elements((n * n) as u64));
    let fast = Denoiser::builtin().unwrap();
    group.bench_function("fast_path", |b| b.iter(|| black_box(fast.denoise(&input).unwrap())));
    let burn = Denoiser::builtin().unwrap().with_burn(true);
    group.bench_function("burn_flex", |b| b.iter(|| black_box(burn.denoise(&input).unwrap())));
    let filter = GuidedFilter::default();
    group.bench_function("guided_filter_baseline", |b| b.iter(|| black_box(filter.filter(&input).unwrap())));
    group.finish();
}

criterion_group!(benches, denoise);

fn main() {
    benches();
    Criterion::default().configure_from_args().final_summary();
}
