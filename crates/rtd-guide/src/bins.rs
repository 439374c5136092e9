//! Which scene triangles each tile of the image may draw: one parallel pass over every
//! triangle keeps those that draw something as compact [`Span`]s, binned by tile.

use glam::{Vec3, Vec3A};
use rayon::prelude::*;
use rtd_scene::Scene;

use crate::projection::{signed_area, to_camera, Projector, ScreenTri};

/// Tile side in pixels.
pub const TILE: u32 = 16;

/// A scene triangle that draws something, as the tiles see it: its screen vertices when it lies
/// whole in front of the near plane, its index and material, the tiles it may draw into (first
/// and last column, then row), and, for a triangle clipped at the near plane, its place in the
/// list of clipped triangles' screen triangles ([`NOT_CLIPPED`] otherwise).
#[derive(Clone, Copy)]
pub(crate) struct Span {
    v: [Vec3; 3],
    triangle: u32,
    material: u32,
    tiles: [u16; 4],
    clipped: u32,
}

/// [`Span::clipped`] of a triangle whole in front of the near plane.
const NOT_CLIPPED: u32 = u32::MAX;

/// The triangles that draw something and where: every one in the scene's order (ties in depth
/// keep the first), the screen triangles of those clipped at the near plane (built once: a
/// floor crossing the near plane may reach every tile), and for each tile the indices of the
/// spans it may draw.
pub(crate) struct Bins {
    spans: Vec<Span>,
    clipped: Vec<[Option<ScreenTri>; 2]>,
    /// For each tile (row-major), the indices of the spans it may draw, in the scene's order.
    pub(crate) tiles: Vec<Vec<u32>>,
}

impl Bins {
    /// Tests every scene triangle in parallel; the survivors keep their screen vertices, the few
    /// bytes drawing needs besides their index and material, so drawing never reads the scene's
    /// triangles again.
    pub(crate) fn new(scene: &Scene, proj: &Projector, (tiles_x, tiles_y): (u32, u32)) -> Self {
        let mut spans: Vec<Span> =
            scene.triangles.par_iter().enumerate().filter_map(|(i, t)| proj.span(i, t, (tiles_x, tiles_y))).collect();
        let mut clipped = Vec::new();
        for span in spans.iter_mut().filter(|s| s.clipped != NOT_CLIPPED) {
            span.clipped = clipped.len() as u32;
            let i = span.triangle as usize;
            clipped.push(proj.project(i, &scene.triangles[i], true));
        }
        let mut tiles: Vec<Vec<u32>> = vec![Vec::new(); (tiles_x * tiles_y) as usize];
        for (i, span) in spans.iter().enumerate() {
            let [tx0, tx1, ty0, ty1] = span.tiles.map(u32::from);
            for ty in ty0..=ty1 {
                for tx in tx0..=tx1 {
                    tiles[(ty * tiles_x + tx) as usize].push(i as u32);
                }
            }
        }
        Bins { spans, clipped, tiles }
    }

    /// The screen triangles of span `i`: those [`Projector::project`] gives its triangle, built
    /// from the span's screen vertices as `project` builds them, so they are the same.
    #[inline(always)]
    pub(crate) fn screen_tris(&self, proj: &Projector, i: u32) -> [Option<ScreenTri>; 2] {
        let span = &self.spans[i as usize];
        if span.clipped != NOT_CLIPPED {
            return self.clipped[span.clipped as usize];
        }
        let v = span.v;
        let w = v.map(|p| proj.weight(p.z));
        let b = [Vec3A::X, Vec3A::Y, Vec3A::Z];
        [Some(ScreenTri::new(v, w, b, signed_area(&v), (span.triangle, span.material))), None]
    }
}

impl Projector<'_> {
    /// Scene triangle `i` as the tiles see it ([`Span`]; a clipped one is marked, not yet
    /// placed), or None when it draws nothing. Most triangles of a dense mesh are whole in front
    /// of the eye and cover no sample: their screen box settles it, without building their
    /// screen triangles.
    #[inline(always)]
    fn span(&self, i: usize, t: &rtd_scene::Triangle, tiles: (u32, u32)) -> Option<Span> {
        let c = t.p.map(|p| to_camera(self.cam, p));
        let (triangle, material) = (i as u32, t.material);
        if c.iter().all(|v| v.z >= self.near) {
            let v = c.map(|c| self.to_screen(c).0);
            // Unclipped, finite, covering a sample and not degenerate: one screen triangle.
            if !v.iter().all(|p| p.is_finite()) || !self.draws_a_sample(&v, signed_area(&v)) {
                return None;
            }
            let tiles = self.tile_range(&v, tiles)?;
            return Some(Span { v, triangle, material, tiles, clipped: NOT_CLIPPED });
        }
        let pieces = self.project(i, t, true).map(|s| s.and_then(|s| self.tile_range(&s.v, tiles)));
        let tiles = match pieces {
            [Some(a), Some(b)] => [a[0].min(b[0]), a[1].max(b[1]), a[2].min(b[2]), a[3].max(b[3])],
            [a, b] => a.or(b)?,
        };
        Some(Span { v: [Vec3::ZERO; 3], triangle, material, tiles, clipped: 0 })
    }

    /// The tiles a screen triangle's bounding box, grown by the 1-px filter radius, touches.
    #[inline(always)]
    fn tile_range(&self, v: &[Vec3; 3], (tiles_x, tiles_y): (u32, u32)) -> Option<[u16; 4]> {
        let lo = v[0].min(v[1]).min(v[2]);
        let hi = v[0].max(v[1]).max(v[2]);
        let (w, h) = (self.width as f32, self.height as f32);
        if hi.x < -1.0 || hi.y < -1.0 || lo.x > w + 1.0 || lo.y > h + 1.0 {
            return None;
        }
        let tx0 = ((lo.x - 1.0).max(0.0) as u32 / TILE).min(tiles_x - 1);
        let ty0 = ((lo.y - 1.0).max(0.0) as u32 / TILE).min(tiles_y - 1);
        let tx1 = (((hi.x + 1.0).max(0.0) as u32) / TILE).min(tiles_x - 1);
        let ty1 = (((hi.y + 1.0).max(0.0) as u32) / TILE).min(tiles_y - 1);
        Some([tx0, tx1, ty0, ty1].map(|t| t as u16))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_soup::soup;
    use glam::Vec2;
    use rtd_scene::{Camera, Projection, Triangle};

    fn bits(t: &ScreenTri) -> Vec<u32> {
        let mut out: Vec<u32> = t.v.iter().flat_map(|v| v.to_array()).map(f32::to_bits).collect();
        out.extend(t.w.map(f32::to_bits));
        out.extend(t.b.iter().flat_map(|b| b.to_array()).map(f32::to_bits));
        out.extend(t.grad.map(f32::to_bits));
        out.extend([t.triangle, t.material]);
        out
    }

    /// Every span's screen triangles, rebuilt from its stored vertices (or taken from the list
    /// of clipped ones), are bit for bit those `Projector::project` builds from the scene
    /// triangle, under perspective and orthographic projection.
    #[test]
    fn spans_rebuild_the_projected_screen_triangles_exactly() {
        let mut scene = soup(3000, 5, |_| 0.4, |_, _| {});
        scene.triangles.iter_mut().enumerate().for_each(|(k, t)| t.material = k as u32 % 3);
        // Crossing the near plane: a quad's worth, split in two screen triangles.
        let p = [Vec3::new(-3.0, -1.0, -6.0), Vec3::new(0.5, -1.0, 4.0), Vec3::new(3.0, -1.0, 4.0)];
        scene.push_triangle(Triangle { p, n: [Vec3::Y; 3], uv: [Vec2::ZERO; 3], material: 0 });
        let perspective = Camera::look_at(Vec3::ZERO, Vec3::NEG_Z, 60.0);
        let mut orthographic = perspective.clone();
        orthographic.projection = Projection::Orthographic { ymag: 1.5 };
        for cam in [perspective, orthographic] {
            let proj = Projector::new(&cam, (61, 47), 1e-3);
            let tiles = (61u32.div_ceil(TILE), 47u32.div_ceil(TILE));
            let bins = Bins::new(&scene, &proj, tiles);
            assert!(bins.spans.len() > 500, "{} spans", bins.spans.len());
            for (i, span) in bins.spans.iter().enumerate() {
                let t = span.triangle as usize;
                let want = proj.project(t, &scene.triangles[t], true).map(|s| s.as_ref().map(bits));
                let got = bins.screen_tris(&proj, i as u32).map(|s| s.as_ref().map(bits));
                assert_eq!(got, want, "span {i} (triangle {t})");
            }
            let clipped = bins.spans.iter().filter(|s| s.clipped != NOT_CLIPPED).count();
            assert_eq!(clipped, matches!(cam.projection, Projection::Perspective { .. }) as usize);
        }
    }
}
