//! Raw BVH traversal throughput, the yardstick for the integrator's rays/s: closest-hit queries
//! alone, on all cores, for camera rays (coherent) and for one cosine-distributed bounce from
//! each camera hit (incoherent, as the integrator's secondary rays are). The integrator's rays/s
//! over these estimates, from above, how much of a render ray's time traversal alone takes (the
//! render's shadow rays stop at their first hit and at the light).

use std::time::Instant;

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use rtd_render::sampling::{sample_cosine_hemisphere, Frame};
use rtd_render::surface::Surface;
use rtd_render::{RenderScene, Sampler, NO_TRIANGLE};
use rtd_scene::Camera;

/// One closest-hit query: origin, unit direction, and the scene triangle the ray leaves
/// ([`NO_TRIANGLE`] for camera rays), as the integrator passes it.
#[derive(Clone, Copy, Debug)]
pub struct ProbeRay {
    /// Origin.
    pub origin: Vec3,
    /// Unit direction.
    pub dir: Vec3,
    /// The triangle the ray leaves, skipped by the query.
    pub leaving: u32,
}

/// Raw closest-hit traversal rates of one view, millions of rays per second (one measurement
/// each; None where there was nothing to trace).
#[derive(Clone, Copy, Debug)]
pub struct RawTraversal {
    /// Camera rays through the film.
    pub camera: Option<f64>,
    /// One diffuse bounce from each camera hit (incoherent rays).
    pub bounce: Option<f64>,
}

impl RawTraversal {
    /// Traces `n` camera rays of a `width`×`height` view of `scene` through `camera`, and one
    /// bounce from each of their hits ([`bounce_rays`]), each set for at least `seconds`.
    pub fn measure(scene: &RenderScene, camera: &Camera, size: (u32, u32), n: u32, seconds: f64) -> Self {
        let cameras = camera_rays(camera, size, n);
        let bounces = bounce_rays(scene, &cameras);
        let rate = |rays: &[ProbeRay]| (!rays.is_empty()).then(|| traversal_mrays_per_s(scene, rays, seconds));
        RawTraversal { camera: rate(&cameras), bounce: rate(&bounces) }
    }
}

/// Camera rays through `n` points of a `width`×`height` film, placed by the sampler of seed 1.
pub fn camera_rays(camera: &Camera, (width, height): (u32, u32), n: u32) -> Vec<ProbeRay> {
    let film = Vec2::new(width as f32, height as f32);
    (0..n)
        .map(|i| {
            let (origin, dir) = camera.ray(Sampler::new(1, 0, i).get_2d() * film, width, height);
            ProbeRay { origin, dir, leaving: NO_TRIANGLE }
        })
        .collect()
}

/// One bounce from the hit of each ray in `rays` that hits something: a cosine-weighted
/// direction about the geometric normal on the side the ray came from, leaving from the hit
/// point offset off the surface. Every hit is treated as diffuse (glass and emitters too), and
/// about the geometric rather than the shading normal, so these are the integrator's diffuse
/// bounce rays in kind, not a copy of the rays a render traces.
pub fn bounce_rays(scene: &RenderScene, rays: &[ProbeRay]) -> Vec<ProbeRay> {
    rays.iter()
        .enumerate()
        .filter_map(|(i, r)| {
            let hit = scene.bvh.intersect_leaving(&scene.scene, r.origin, r.dir, f32::INFINITY, r.leaving)?;
            let s = Surface::new(&scene.scene, &hit);
            let n = if r.dir.dot(s.ng) < 0.0 { s.ng } else { -s.ng };
            let local = sample_cosine_hemisphere(Sampler::new(2, 0, i as u32).get_2d());
            let dir = Frame::from_normal(n).to_world(local).normalize_or_zero();
            (dir != Vec3::ZERO).then(|| ProbeRay { origin: s.spawn_origin(dir), dir, leaving: s.triangle })
        })
        .collect()
}

/// Millions of closest-hit queries per second over `rays`, traced on all cores (rayon's pool),
/// the whole set again and again until at least `seconds` have passed (once at least; 0 for
/// no rays).
pub fn traversal_mrays_per_s(scene: &RenderScene, rays: &[ProbeRay], seconds: f64) -> f64 {
    let timed = trace_repeatedly(scene, rays, seconds);
    (timed.passes * rays.len() as u64) as f64 / timed.seconds.max(1e-9) / 1e6
}

/// What [`trace_repeatedly`] traced: whole passes over the set, and the seconds it took.
#[derive(Clone, Copy, Debug)]
struct Traced {
    passes: u64,
    seconds: f64,
}

/// Traces the whole of `rays` again and again until at least `seconds` have passed (a NaN or
/// negative `seconds`: once; no rays: not at all).
fn trace_repeatedly(scene: &RenderScene, rays: &[ProbeRay], seconds: f64) -> Traced {
    let start = Instant::now();
    let mut passes = 0u64;
    while !rays.is_empty() {
        let hits = rays
            .par_iter()
            .filter(|r| scene.bvh.intersect_leaving(&scene.scene, r.origin, r.dir, f32::INFINITY, r.leaving).is_some())
            .count();
        std::hint::black_box(hits);
        passes += 1;
        if !(start.elapsed().as_secs_f64() < seconds) {
            break;
        }
    }
    Traced { passes, seconds: start.elapsed().as_secs_f64() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtd_scene::{Material, Scene, Triangle};

    /// A closed box of 12 triangles around the origin, seen from inside.
    fn closed_box() -> RenderScene {
        let mut scene = Scene::default();
        scene.materials.push(Material::default());
        let c = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
        // Each face as two triangles; winding does not matter to the traversal.
        for axis in 0..3 {
            for side in [-1.0f32, 1.0] {
                let corner = |a: f32, b: f32| {
                    let mut v = [0.0; 3];
                    v[axis] = side;
                    v[(axis + 1) % 3] = a;
                    v[(axis + 2) % 3] = b;
                    c(v[0], v[1], v[2])
                };
                let (p00, p10, p11, p01) = (corner(-1., -1.), corner(1., -1.), corner(1., 1.), corner(-1., 1.));
                for p in [[p00, p10, p11], [p00, p11, p01]] {
                    let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
                    scene.push_triangle(Triangle { p, n: [n; 3], uv: [Vec2::ZERO; 3], material: 0 });
                }
            }
        }
        RenderScene::new(scene)
    }

    #[test]
    fn bounces_inside_a_closed_box_all_hit_another_wall() {
        let scene = closed_box();
        let from_centre: Vec<ProbeRay> = (0..500)
            .map(|i| {
                let u = Sampler::new(3, 0, i).get_2d();
                let z = 1.0 - 2.0 * u.x;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let phi = std::f32::consts::TAU * u.y;
                ProbeRay { origin: Vec3::ZERO, dir: Vec3::new(r * phi.cos(), r * phi.sin(), z), leaving: NO_TRIANGLE }
            })
            .collect();
        let bounces = bounce_rays(&scene, &from_centre);
        // Every ray from the centre hits a wall, and every bounce goes back into the box, from
        // the wall it leaves (named) and just inside it.
        assert_eq!(bounces.len(), from_centre.len());
        for b in &bounces {
            assert!(b.origin.abs().max_element() <= 1.0, "{b:?}");
            assert!(b.origin.abs().max_element() > 1.0 - 1e-4, "{b:?}");
            let left = &scene.scene.triangles[b.leaving as usize];
            let on_plane = (b.origin - left.p[0]).dot((left.p[1] - left.p[0]).cross(left.p[2] - left.p[0]).normalize());
            assert!(on_plane.abs() < 1e-4, "{b:?} is not on the triangle it names");
            let hit = scene.bvh.intersect_leaving(&scene.scene, b.origin, b.dir, f32::INFINITY, b.leaving);
            let hit = hit.expect("a bounce inside a closed box must hit a wall");
            assert_ne!(hit.triangle, b.leaving);
            assert!(hit.t > 0.0);
        }
        // Cosine-distributed about the inward normal: the mean cosine is 2/3.
        let mean_cos: f32 = bounces
            .iter()
            .map(|b| {
                let q = b.origin;
                let axis = (0..3).max_by(|&i, &j| q[i].abs().total_cmp(&q[j].abs())).unwrap();
                -b.dir[axis] * q[axis].signum()
            })
            .sum::<f32>()
            / bounces.len() as f32;
        assert!((mean_cos - 2.0 / 3.0).abs() < 0.03, "mean cosine {mean_cos}");
    }

    #[test]
    fn repeated_tracing_counts_every_pass_and_stops() {
        let scene = closed_box();
        let rays = vec![ProbeRay { origin: Vec3::ZERO, dir: Vec3::X, leaving: NO_TRIANGLE }; 1000];
        let timed = trace_repeatedly(&scene, &rays, 0.02);
        assert!(timed.passes >= 1 && timed.seconds >= 0.02, "{timed:?}");
        // A NaN or negative time traces the set once; no rays, never (and no endless loop).
        for seconds in [f64::NAN, -1.0] {
            assert_eq!(trace_repeatedly(&scene, &rays, seconds).passes, 1);
        }
        assert_eq!(trace_repeatedly(&scene, &[], 1.0).passes, 0);
        assert_eq!(traversal_mrays_per_s(&scene, &[], 0.01), 0.0);
        let rate = traversal_mrays_per_s(&scene, &rays, 0.01);
        assert!(rate.is_finite() && rate > 0.0, "{rate}");
    }
}
