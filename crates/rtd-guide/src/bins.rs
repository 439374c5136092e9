//! Which scene triangles each tile of the image may draw: one parallel pass over every
//! triangle keeps those that draw something as compact [`Span`]s, binned by tile.

use glam::{Vec3, Vec3A};
use rayon::prelude::*;
use rtd_scene::{Scene, Triangle};

#[cfg(target_arch = "x86_64")]
use crate::lanes::has_avx512;
use crate::lanes::LANES;
use crate::projection::{signed_area, to_camera, Projector, ScreenTri};
use crate::sample_grid::pixels_reached;

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
/// floor crossing the near plane may reach every tile), and for each tile the ids of the spans
/// it may draw.
pub(crate) struct Bins {
    /// The spans of each [`CHUNK`] of scene triangles (a span's id is its chunk's index shifted
    /// by [`CHUNK_BITS`], plus its place in the chunk's list: no copy into one list).
    spans: Vec<Vec<Span>>,
    /// The screen triangles of each triangle clipped at the near plane, in the scene's order
    /// ([`Span::clipped`] indexes it).
    clipped: Vec<[Option<ScreenTri>; 2]>,
    /// For each tile (row-major), the ids of the spans it may draw, in the scene's order.
    pub(crate) tiles: Vec<Vec<u32>>,
}

impl Bins {
    /// Tests every scene triangle in parallel; the survivors keep their screen vertices, the few
    /// bytes drawing needs besides their index and material, so drawing never reads the scene's
    /// triangles again.
    pub(crate) fn new(scene: &Scene, proj: &Projector, (tiles_x, tiles_y): (u32, u32)) -> Self {
        // Chunks of triangles in parallel, each tested LANES at a time; their spans in order.
        let mut spans: Vec<Vec<Span>> = (scene.triangles.par_chunks(CHUNK).enumerate())
            .map(|(c, tris)| {
                // Room for every triangle, then shrunk: a growing list would copy itself as it
                // doubled (glibc shrinks a block in place, and leaves pages never written
                // unmapped).
                let mut out = Vec::with_capacity(tris.len());
                proj.spans_of(c * CHUNK, tris, (tiles_x, tiles_y), &mut out);
                out.shrink_to_fit();
                out
            })
            .collect();
        let mut clipped = Vec::new();
        for span in spans.iter_mut().flatten().filter(|s| s.clipped != NOT_CLIPPED) {
            span.clipped = clipped.len() as u32;
            let i = span.triangle as usize;
            clipped.push(proj.project(i, &scene.triangles[i], true));
        }
        let mut tiles: Vec<Vec<u32>> = vec![Vec::new(); (tiles_x * tiles_y) as usize];
        for (c, chunk) in spans.iter().enumerate() {
            for (k, span) in chunk.iter().enumerate() {
                let id = span_id(c, k);
                let [tx0, tx1, ty0, ty1] = span.tiles.map(u32::from);
                for ty in ty0..=ty1 {
                    for tx in tx0..=tx1 {
                        tiles[(ty * tiles_x + tx) as usize].push(id);
                    }
                }
            }
        }
        Bins { spans, clipped, tiles }
    }

    /// The span with id `id` ([`span_id`]).
    #[inline(always)]
    fn span_by_id(&self, id: u32) -> &Span {
        &self.spans[id as usize >> CHUNK_BITS][id as usize & (CHUNK - 1)]
    }

    /// Appends the screen triangles of the span with id `id` to `tris`: those
    /// [`Projector::project`] gives its triangle, built from the span's screen vertices as
    /// `project` builds them, so they are the same. Returns how many it appended (at most 2).
    #[inline(always)]
    pub(crate) fn push_screen_tris(&self, proj: &Projector, id: u32, tris: &mut Vec<ScreenTri>) -> usize {
        let span = self.span_by_id(id);
        if span.clipped != NOT_CLIPPED {
            let before = tris.len();
            tris.extend(self.clipped[span.clipped as usize].iter().flatten());
            return tris.len() - before;
        }
        let v = span.v;
        let w = v.map(|p| proj.weight(p.z));
        let b = [Vec3A::X, Vec3A::Y, Vec3A::Z];
        tris.push(ScreenTri::new(v, w, b, signed_area(&v), (span.triangle, span.material)));
        1
    }
}

/// log2 of [`CHUNK`].
const CHUNK_BITS: usize = 12;
/// Triangles a parallel job of the triangle pass tests.
const CHUNK: usize = 1 << CHUNK_BITS;

/// The id of span `index` of chunk `chunk`: the chunk shifted by [`CHUNK_BITS`], plus the
/// index (a chunk has at most [`CHUNK`] spans).
#[inline(always)]
fn span_id(chunk: usize, index: usize) -> u32 {
    (chunk << CHUNK_BITS | index) as u32
}

impl Projector<'_> {
    /// Appends the spans of scene triangles `first..first + tris.len()` (`tris`) to `out`, in
    /// order: what [`Projector::span`] gives each, tested [`LANES`] at a time (with AVX-512
    /// where the CPU has it).
    fn spans_of(&self, first: usize, tris: &[Triangle], tiles: (u32, u32), out: &mut Vec<Span>) {
        #[cfg(target_arch = "x86_64")]
        if has_avx512() {
            // SAFETY: the CPU has the features the function is compiled for.
            return unsafe { self.spans_of_avx512(first, tris, tiles, out) };
        }
        self.spans_in_lanes(first, tris, tiles, out)
    }

    /// [`Projector::spans_in_lanes`] compiled for AVX-512 (sixteen f32 lanes a register).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq")] // as `has_avx512` checks
    fn spans_of_avx512(&self, first: usize, tris: &[Triangle], tiles: (u32, u32), out: &mut Vec<Span>) {
        self.spans_in_lanes(first, tris, tiles, out)
    }

    /// The body of [`Projector::spans_of`]: the lane-wise test, then a span for each triangle
    /// it keeps and the scalar path for each it says to clip.
    #[inline(always)]
    fn spans_in_lanes(&self, first: usize, tris: &[Triangle], tiles: (u32, u32), out: &mut Vec<Span>) {
        for (b, batch) in tris.chunks(LANES).enumerate() {
            let test = self.test_lanes(batch);
            for (l, t) in batch.iter().enumerate() {
                let i = first + b * LANES + l;
                if test.keep[l] {
                    out.extend(self.unclipped_span(test.vertices(l), i, t, tiles));
                } else if test.clip[l] {
                    out.extend(self.span(i, t, tiles));
                }
            }
        }
    }

    /// Scene triangle `i` as the tiles see it ([`Span`]; a clipped one is marked, not yet
    /// placed), or None when it draws nothing. Most triangles of a dense mesh are whole in front
    /// of the eye and cover no sample: their screen box settles it, without building their
    /// screen triangles. The pass in lanes gives the same for every triangle and calls this for
    /// those it finds crossing the near plane.
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
            return self.unclipped_span(v, i, t, tiles);
        }
        let pieces = self.project(i, t, true).map(|s| s.and_then(|s| self.tile_range(&s.v, tiles)));
        let tiles = match pieces {
            [Some(a), Some(b)] => [a[0].min(b[0]), a[1].max(b[1]), a[2].min(b[2]), a[3].max(b[3])],
            [a, b] => a.or(b)?,
        };
        Some(Span { v: [Vec3::ZERO; 3], triangle, material, tiles, clipped: 0 })
    }

    /// The span of scene triangle `i` (`t`), whole in front of the near plane with screen
    /// vertices `v` and drawing a sample, or None when it reaches no pixel of the image.
    #[inline(always)]
    fn unclipped_span(&self, v: [Vec3; 3], i: usize, t: &Triangle, tiles: (u32, u32)) -> Option<Span> {
        let tiles = self.tile_range(&v, tiles)?;
        Some(Span { v, triangle: i as u32, material: t.material, tiles, clipped: NOT_CLIPPED })
    }

    /// The tiles holding the pixels whose samples a screen triangle's bounding box can touch
    /// ([`pixels_reached`], which the rasteriser visits), or None when no such pixel is in the
    /// image.
    #[inline(always)]
    fn tile_range(&self, v: &[Vec3; 3], (tiles_x, tiles_y): (u32, u32)) -> Option<[u16; 4]> {
        let [lx, hx, ly, hy] = pixels_reached(v, self.reach);
        let (w, h) = (self.width as f32, self.height as f32);
        if !(lx <= hx && ly <= hy && hx >= 0.0 && hy >= 0.0 && lx < w && ly < h) {
            return None;
        }
        let tx0 = (lx.max(0.0) as u32 / TILE).min(tiles_x - 1);
        let ty0 = (ly.max(0.0) as u32 / TILE).min(tiles_y - 1);
        let tx1 = (hx.min(w - 1.0) as u32 / TILE).min(tiles_x - 1);
        let ty1 = (hy.min(h - 1.0) as u32 / TILE).min(tiles_y - 1);
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
        out.extend(t.grad().map(f32::to_bits));
        out.extend([t.area.to_bits() as u32, (t.area.to_bits() >> 32) as u32]);
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
            let ids = bins.spans.iter().enumerate().flat_map(|(c, chunk)| (0..chunk.len()).map(move |k| span_id(c, k)));
            let spans: Vec<&Span> = bins.spans.iter().flatten().collect();
            assert!(spans.len() > 500, "{} spans", spans.len());
            for (id, span) in ids.zip(&spans) {
                let t = span.triangle as usize;
                let want = proj.project(t, &scene.triangles[t], true).map(|s| s.as_ref().map(bits));
                let mut got = Vec::new();
                bins.push_screen_tris(&proj, id, &mut got);
                let got: Vec<Vec<u32>> = got.iter().map(bits).collect();
                let want: Vec<Vec<u32>> = want.into_iter().flatten().collect();
                assert_eq!(got, want, "span {id} (triangle {t})");
            }
            let clipped = spans.iter().filter(|s| s.clipped != NOT_CLIPPED).count();
            assert_eq!(clipped, matches!(cam.projection, Projection::Perspective { .. }) as usize);
        }
    }

    /// A span as bits, to compare two passes exactly.
    fn span_bits(s: &Span) -> Vec<u32> {
        let mut out: Vec<u32> = s.v.iter().flat_map(|v| v.to_array()).map(f32::to_bits).collect();
        out.extend([s.triangle, s.material, s.clipped]);
        out.extend(s.tiles.map(u32::from));
        out
    }

    /// The pass in lanes (as dispatched, and compiled for the baseline CPU) keeps exactly the
    /// triangles the one-triangle path keeps, with the same screen vertices to the bit, on a
    /// soup of tiny and large triangles with non-finite, degenerate, behind-the-eye and
    /// near-clipped ones among them, under perspective and orthographic projection, at a
    /// count that leaves a partial batch.
    #[test]
    fn the_pass_in_lanes_keeps_what_the_one_triangle_path_keeps() {
        let scene = soup(
            5003,
            11,
            |u| 0.4 * u * u * u,
            |k, p| match k % 7 {
                1 if k % 3 == 0 => p[0].x = f32::NAN,
                2 if k % 3 == 0 => p[2] = p[1],
                3 if k % 3 == 0 => p.iter_mut().for_each(|q| q.z += 5.0),
                4 if k % 3 == 0 => p[0].z = 1.0,
                5 if k % 3 == 0 => p[1].y = f32::INFINITY,
                6 if k % 5 == 0 => p[2] *= 1e30,
                _ => {}
            },
        );
        let perspective = Camera::look_at(Vec3::ZERO, Vec3::NEG_Z, 60.0);
        let mut orthographic = perspective.clone();
        orthographic.projection = Projection::Orthographic { ymag: 1.5 };
        for cam in [perspective, orthographic] {
            for (w, h) in [(61, 47), (256, 256)] {
                let proj = Projector::new(&cam, (w, h), 1e-3);
                let tiles = (w.div_ceil(TILE), h.div_ceil(TILE));
                let want: Vec<Vec<u32>> = (scene.triangles.iter().enumerate())
                    .filter_map(|(i, t)| proj.span(i, t, tiles))
                    .map(|s| span_bits(&s))
                    .collect();
                let clipped = want.iter().filter(|s| s[11] != NOT_CLIPPED).count();
                let perspective = matches!(cam.projection, Projection::Perspective { .. });
                assert!(want.len() > 300 && want.len() < 4000, "{} of 5003 kept", want.len());
                assert!(!perspective || clipped > 50, "{clipped} clipped");
                let mut lanes = Vec::new();
                let mut dispatched = Vec::new();
                for (c, tris) in scene.triangles.chunks(1000).enumerate() {
                    let (mut a, mut b) = (Vec::new(), Vec::new());
                    proj.spans_in_lanes(c * 1000, tris, tiles, &mut a);
                    proj.spans_of(c * 1000, tris, tiles, &mut b);
                    lanes.extend(a.iter().map(span_bits));
                    dispatched.extend(b.iter().map(span_bits));
                }
                assert_eq!(lanes, want, "baseline lanes, {w}x{h}");
                assert_eq!(dispatched, want, "dispatched lanes, {w}x{h}");
            }
        }
    }
}
