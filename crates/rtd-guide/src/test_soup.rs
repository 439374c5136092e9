//! Random triangle soups and reference drawing for the rasteriser's tests.

use glam::{Vec2, Vec3};
use rtd_scene::{Material, Scene, Triangle};

use crate::projection::{Projector, ScreenTri};

/// A small deterministic generator for the tests' random inputs, in [0, 1).
pub(crate) fn lcg(state: &mut u64) -> f32 {
    *state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    (*state >> 40) as f32 / (1u64 << 24) as f32
}

/// A scene of `n` random triangles in front of a camera at the origin looking down −z: centres
/// over x, y in −1.2..1.2 and z in −3..−2, corners spread by `size(u)` for a uniform `u`, and
/// `edit(k, corners)` applied to triangle `k` before it is added (material 0).
pub(crate) fn soup(n: usize, seed: u64, size: impl Fn(f32) -> f32, edit: impl Fn(usize, &mut [Vec3; 3])) -> Scene {
    let mut scene = Scene::default();
    scene.materials.push(Material::default());
    let mut state = seed;
    for k in 0..n {
        let c = Vec3::new(lcg(&mut state) * 2.4 - 1.2, lcg(&mut state) * 2.4 - 1.2, -2.0 - lcg(&mut state));
        let size = size(lcg(&mut state));
        let mut corner = || Vec3::new(lcg(&mut state) - 0.5, lcg(&mut state) - 0.5, lcg(&mut state) - 0.5) * size;
        let mut p = [c + corner(), c + corner(), c + corner()];
        edit(k, &mut p);
        scene.push_triangle(Triangle { p, n: [Vec3::Z; 3], uv: [Vec2::ZERO; 3], material: 0 });
    }
    scene
}

/// Every scene triangle's screen triangles, in the scene's order, without binning.
pub(crate) fn project_all(proj: &Projector, scene: &Scene, drop_uncovering: bool) -> Vec<ScreenTri> {
    (scene.triangles.iter().enumerate())
        .flat_map(|(i, t)| proj.project(i, t, drop_uncovering).into_iter().flatten())
        .collect()
}
