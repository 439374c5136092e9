//! A tiled, multi-sampled triangle rasteriser producing a visibility buffer.
//!
//! Triangles are moved to camera space, clipped against the near plane (clipped vertices keep
//! barycentrics of the original triangle), projected, and binned into tiles. Each tile is
//! rasterised independently with a z-buffer per sample, so tiles run in parallel and the result
//! never depends on the thread count. Each pixel has a fixed set of sample positions drawn from the
//! same tent filter that the path tracer importance-samples, so edges line up with the beauty
//! (`sample_grid.rs`); triangles that fall between all samples are dropped before binning.

use glam::{Vec2, Vec3, Vec3A};
use rayon::prelude::*;
use rtd_render::prefetch;
use rtd_scene::{Aabb, AlphaMode, Camera, Scene};

use crate::bins::Bins;
pub use crate::bins::TILE;
#[cfg(target_arch = "x86_64")]
use crate::lanes::has_avx512;
use crate::projection::{drawable, Projector, ScreenTri};
use crate::sample_grid::pixels_reached;
pub use crate::sample_grid::{sample_offsets, SAMPLES, SAMPLES_1D};

/// What one sample sees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleHit {
    /// Scene triangle index.
    pub triangle: u32,
    /// Barycentrics in the original triangle.
    pub bary: Vec3,
    /// The screen triangle within the tile being drawn and the sample's screen-space
    /// barycentrics (for [`Footprints`]: a hit is read only with the footprints handed to the
    /// same call of the shading callback).
    screen: u32,
    e: Vec2,
}

/// Screen-space derivatives of the samples' barycentrics, for filtering textures over a sample's
/// footprint; handed to the shading callback of [`rasterize`] with the hits they belong to (they
/// hold the screen triangles of one tile only).
pub struct Footprints<'a> {
    tris: &'a [ScreenTri],
}

impl Footprints<'_> {
    /// Barycentric steps across `step` pixels along screen x and along screen y at the sample:
    /// `step` × the screen derivatives of its perspective-correct barycentrics.
    #[inline]
    pub fn bary_steps(&self, hit: &SampleHit, step: f32) -> [Vec3; 2] {
        let t = &self.tris[hit.screen as usize];
        // bary = N / D with N = Σ bᵢ eᵢ wᵢ and D = Σ eᵢ wᵢ, where the screen-space barycentrics
        // eᵢ are affine in (x, y); so ∂bary = (∂N − bary ∂D) / D.
        let e = [hit.e.x, hit.e.y, 1.0 - hit.e.x - hit.e.y];
        let d: f32 = (0..3).map(|i| e[i] * t.w[i]).sum();
        let along = |de0: f32, de1: f32| {
            let de = [de0, de1, -de0 - de1];
            let dn: Vec3 = (0..3).map(|i| t.b[i] * (de[i] * t.w[i])).sum::<Vec3A>().into();
            let dd: f32 = (0..3).map(|i| de[i] * t.w[i]).sum();
            (dn - hit.bary * dd) * (step / d)
        };
        let grad = t.grad();
        [along(grad[0], grad[2]), along(grad[1], grad[3])]
    }
}

/// Rasterises `scene` (whose bounding box is `bounds`: [`Scene::bounds`]) through `cam` and
/// calls `shade` with what each pixel's [`SAMPLES`] samples see (and their [`Footprints`]). The
/// image is cut into bands of [`TILE`] rows: `bands` holds one output per band (top first, as many as `height.div_ceil(TILE)`), and
/// `shade(band, i, samples, footprints)` stores pixel `i` of the band (row-major within it), so
/// the caller's outputs are written in place. Bands are independent, so `shade` runs in
/// parallel and the result never depends on the thread count.
pub fn rasterize<B, F>(scene: &Scene, bounds: &Aabb, cam: &Camera, width: u32, height: u32, bands: Vec<B>, shade: F)
where
    B: Send,
    F: Fn(&mut B, usize, &[Option<SampleHit>], &Footprints) + Sync,
{
    assert_eq!(bands.len(), height.div_ceil(TILE) as usize, "one output per band of TILE rows");
    let near = near_plane(bounds, cam);
    let proj = Projector::new(cam, (width, height), near);
    let offsets = sample_offsets();
    let tiles_x = width.div_ceil(TILE);
    let tiles_y = height.div_ceil(TILE);
    let bins = Bins::new(scene, &proj, (tiles_x, tiles_y));
    // One job per band (row of tiles), writing straight into the caller's outputs.
    bands.into_par_iter().enumerate().for_each(|(ty, mut band)| {
        let y0 = ty as u32 * TILE;
        let th = TILE.min(height - y0) as usize;
        let mut depth = vec![f32::NEG_INFINITY; TILE as usize * TILE as usize * SAMPLES];
        let mut cover = vec![Cover::NONE; TILE as usize * TILE as usize * SAMPLES];
        // The screen triangles of the tile being drawn.
        let mut tris: Vec<ScreenTri> = Vec::new();
        for tx in 0..tiles_x {
            let x0 = tx * TILE;
            let tw = TILE.min(width - x0) as usize;
            let n = tw * th * SAMPLES;
            depth[..n].fill(f32::NEG_INFINITY);
            cover[..n].fill(Cover::NONE);
            tris.clear();
            let tile = TileRect { x0, y0, w: tw, h: th };
            let list = &bins.tiles[(ty as u32 * tiles_x + tx) as usize];
            let draw = TileDraw { scene, bins: &bins, proj: &proj, offsets: &offsets, tile };
            draw.run(list, &mut tris, (&mut depth[..n], &mut cover[..n]));
            let footprints = Footprints { tris: &tris };
            for (k, px) in cover[..n].chunks(SAMPLES).enumerate() {
                // Barycentrics only for the samples' final triangles.
                let hits: [Option<SampleHit>; SAMPLES] = std::array::from_fn(|s| {
                    let c = px[s];
                    (c.tri != u32::MAX).then(|| {
                        let bary = tris[c.tri as usize].bary(c.e0, c.e1);
                        SampleHit {
                            triangle: tris[c.tri as usize].triangle,
                            bary,
                            screen: c.tri,
                            e: Vec2::new(c.e0, c.e1),
                        }
                    })
                });
                shade(&mut band, (k / tw) * width as usize + x0 as usize + k % tw, &hits, &footprints);
            }
        }
    });
}

/// What drawing one tile's triangles needs besides its buffers.
struct TileDraw<'a> {
    scene: &'a Scene,
    bins: &'a Bins,
    proj: &'a Projector<'a>,
    offsets: &'a [Vec2; SAMPLES],
    tile: TileRect,
}

impl TileDraw<'_> {
    /// Draws the spans `list` into the tile's depth and coverage, appending their screen
    /// triangles to `tris` (with AVX-512 where the CPU has it).
    fn run(&self, list: &[u32], tris: &mut Vec<ScreenTri>, buffers: (&mut [f32], &mut [Cover])) {
        #[cfg(target_arch = "x86_64")]
        if has_avx512() {
            // SAFETY: the CPU has the features the function is compiled for.
            return unsafe { self.run_avx512(list, tris, buffers) };
        }
        self.run_inline(list, tris, buffers)
    }

    /// [`TileDraw::run_inline`] compiled for AVX-512.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq")] // as `has_avx512` checks
    fn run_avx512(&self, list: &[u32], tris: &mut Vec<ScreenTri>, buffers: (&mut [f32], &mut [Cover])) {
        self.run_inline(list, tris, buffers)
    }

    /// The body of [`TileDraw::run`].
    #[inline(always)]
    fn run_inline(&self, list: &[u32], tris: &mut Vec<ScreenTri>, (depth, cover): (&mut [f32], &mut [Cover])) {
        for &i in list {
            let first = tris.len();
            let added = self.bins.push_screen_tris(self.proj, i, tris);
            // Shading reads the scene triangle a sample ends on: start loading it now, so it is
            // in cache when the tile is shaded.
            if added > 0 {
                prefetch(&self.scene.triangles[tris[first].triangle as usize]);
            }
            for index in first..first + added {
                raster_tri(
                    self.scene,
                    tris,
                    index as u32,
                    self.tile,
                    self.offsets,
                    self.proj.reach,
                    (&mut *depth, &mut *cover),
                );
            }
        }
    }
}

/// The near clip of a view of a scene bounded by `bounds`: far enough in front of the eye to keep
/// 1/z well conditioned (a millionth of the farthest distance), or the camera's own near clip.
fn near_plane(bounds: &Aabb, cam: &Camera) -> f32 {
    let size = if bounds.is_empty() { 1.0 } else { bounds.diagonal().length().max(f32::MIN_POSITIVE) };
    let far = if bounds.is_empty() { 1.0 } else { (bounds.center() - cam.position).length() + size };
    (far * 1e-6).max(f32::MIN_POSITIVE).max(cam.znear)
}

/// What a sample sees while its tile is drawn: the screen triangle and its edge functions e0, e1.
#[derive(Debug, Clone, Copy)]
struct Cover {
    tri: u32,
    e0: f32,
    e1: f32,
}

impl Cover {
    const NONE: Cover = Cover { tri: u32::MAX, e0: 0.0, e1: 0.0 };
}

/// A tile of the image: its top-left pixel and its size.
#[derive(Clone, Copy)]
struct TileRect {
    x0: u32,
    y0: u32,
    w: usize,
    h: usize,
}

/// The edge functions e0, e1, e2 of screen triangle `t` over `tile` as (A, B, C), or None when
/// the triangle is not drawable or one edge excludes every place a sample of the tile can lie.
#[inline(always)]
fn edge_planes(t: &ScreenTri, tile: TileRect) -> Option<[(f32, f32, f32); 3]> {
    let TileRect { x0, y0, w: tw, h: th } = tile;
    let [a, b, c] = t.v;
    // Edge functions as planes e(p) = A·(x − x0) + B·(y − y0) + C over the tile, set up in f64
    // (clipped vertices can project far off screen) and normalised by twice the signed area:
    // e0, e1, e2 are the screen-space barycentrics of vertices a, b, c. Either winding is drawn.
    let (ax, ay, bx, by, cx, cy) = (a.x as f64, a.y as f64, b.x as f64, b.y as f64, c.x as f64, c.y as f64);
    let area = t.area;
    if !drawable(area) {
        return None;
    }
    let (ox, oy) = (x0 as f64, y0 as f64);
    let inv_area = 1.0 / area;
    let plane = |px: f64, py: f64, qx: f64, qy: f64| {
        let (ea, eb) = ((py - qy) * inv_area, (qx - px) * inv_area);
        let ec = (px * qy - py * qx) * inv_area + ea * ox + eb * oy;
        (ea as f32, eb as f32, ec as f32)
    };
    let (a0, b0, c0) = plane(bx, by, cx, cy);
    let (a1, b1, c1) = plane(cx, cy, ax, ay);
    // e2 has its own plane rather than 1 − e0 − e1: near the edge a–b of a triangle clipped at the
    // near plane, e0 ≈ 1 and e2 is far below the rounding of 1 − e0 − e1 (a vertex projected
    // millions of pixels away leaves e2 changing by ~1e-7 per pixel), which let samples up to
    // a pixel outside that edge in.
    let (a2, b2, c2) = plane(ax, ay, bx, by);
    // Reject the tile when one edge is negative everywhere samples can lie: x ∈ [−1, tw+1],
    // y ∈ [−1, th+1] in tile coordinates (pixel centres ± the filter radius).
    let (w, h) = (tw as f32 + 1.0, th as f32 + 1.0);
    let max_over = |ea: f32, eb: f32, ec: f32| ec + (ea * w).max(-ea) + (eb * h).max(-eb);
    if max_over(a0, b0, c0) < 0.0 || max_over(a1, b1, c1) < 0.0 || max_over(a2, b2, c2) < 0.0 {
        return None;
    }
    Some([(a0, b0, c0), (a1, b1, c1), (a2, b2, c2)])
}

/// Rasterises screen triangle `index` into a tile's sample buffers, depth keys and coverage
/// (greater depth key wins; ties keep the first).
#[inline(always)]
fn raster_tri(
    scene: &Scene,
    tris: &[ScreenTri],
    index: u32,
    tile: TileRect,
    offsets: &[Vec2; SAMPLES],
    reach: f32,
    (depth, cover): (&mut [f32], &mut [Cover]),
) {
    let TileRect { x0, y0, w: tw, h: th } = tile;
    let t = &tris[index as usize];
    let [a, b, c] = t.v;
    // The tile's pixels whose samples can touch the triangle's bounding box; often none, for a
    // small triangle near the tile's edge (the tile's neighbour draws it).
    let [lx, hx, ly, hy] = pixels_reached(&t.v, reach);
    let px0 = (lx.max(x0 as f32) as usize).saturating_sub(x0 as usize);
    let py0 = (ly.max(y0 as f32) as usize).saturating_sub(y0 as usize);
    let px1 = ((hx + 1.0 - x0 as f32).max(0.0) as usize).min(tw);
    let py1 = ((hy + 1.0 - y0 as f32).max(0.0) as usize).min(th);
    if px0 >= px1 || py0 >= py1 {
        return;
    }
    let Some([(a0, b0, c0), (a1, b1, c1), (a2, b2, c2)]) = edge_planes(t, tile) else {
        return;
    };
    // Depth key is affine in screen space: key = c.z + e0·(a.z − c.z) + e1·(b.z − c.z).
    let (ka, kb) = (a.z - c.z, b.z - c.z);
    let material = &scene.materials[t.material as usize];
    let cutoff = match material.alpha_mode {
        AlphaMode::Mask(c) => Some(c),
        _ => None,
    };
    // Per-sample offsets of the three edge functions from the pixel centre.
    let d0: [f32; SAMPLES] = std::array::from_fn(|s| a0 * offsets[s].x + b0 * offsets[s].y);
    let d1: [f32; SAMPLES] = std::array::from_fn(|s| a1 * offsets[s].x + b1 * offsets[s].y);
    let d2: [f32; SAMPLES] = std::array::from_fn(|s| a2 * offsets[s].x + b2 * offsets[s].y);
    // Largest sample offsets of e0, e1 and e2: a pixel whose centre value plus the largest offset
    // is negative has every sample outside that edge (exact: addition is monotonic).
    let max = |d: &[f32; SAMPLES]| d.iter().copied().fold(f32::MIN, f32::max);
    let (m0, m1, m2) = (max(&d0), max(&d1), max(&d2));
    for py in py0..py1 {
        for px in px0..px1 {
            let (cxp, cyp) = (px as f32 + 0.5, py as f32 + 0.5);
            let e0c = a0 * cxp + b0 * cyp + c0;
            let e1c = a1 * cxp + b1 * cyp + c1;
            let e2c = a2 * cxp + b2 * cyp + c2;
            if e0c + m0 < 0.0 || e1c + m1 < 0.0 || e2c + m2 < 0.0 {
                continue;
            }
            let at = (py * tw + px) * SAMPLES;
            let (depth, cover) = (&mut depth[at..at + SAMPLES], &mut cover[at..at + SAMPLES]);
            // Every sample's tests without branches (the compiler runs them across SIMD lanes),
            // then the stores for the samples that pass: inside all three edges, nearer than what
            // the sample holds, and with positive perspective-correct weights (in front of the eye).
            let mut key = [0.0f32; SAMPLES];
            let mut pass = [false; SAMPLES];
            for s in 0..SAMPLES {
                let (e0, e1, e2) = (e0c + d0[s], e1c + d1[s], e2c + d2[s]);
                key[s] = c.z + e0 * ka + e1 * kb;
                pass[s] = (e0 >= 0.0)
                    & (e1 >= 0.0)
                    & (e2 >= 0.0)
                    & (key[s] > depth[s])
                    & (e0 * t.w[0] + e1 * t.w[1] + e2 * t.w[2] > 0.0);
            }
            for s in 0..SAMPLES {
                if !pass[s] {
                    continue;
                }
                let (e0, e1) = (e0c + d0[s], e1c + d1[s]);
                if let Some(cut) = cutoff {
                    let bary = t.bary(e0, e1);
                    if material.alpha(&scene.textures, scene.tex_coords(t.triangle, bary)) < cut {
                        continue;
                    }
                }
                depth[s] = key[s];
                cover[s] = Cover { tri: index, e0, e1 };
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::projection::to_camera;
    use crate::sample_grid::sample_reach;
    use crate::test_soup::{project_all, soup};

    /// Draws `tris` (all of them, in order) into one tile: its depth keys and coverage.
    fn draw_tile(scene: &Scene, tris: &[ScreenTri], tile: TileRect) -> (Vec<f32>, Vec<Cover>) {
        let n = tile.w * tile.h * SAMPLES;
        let (mut depth, mut cover) = (vec![f32::NEG_INFINITY; n], vec![Cover::NONE; n]);
        let offsets = sample_offsets();
        for i in 0..tris.len() as u32 {
            raster_tri(scene, tris, i, tile, &offsets, sample_reach(), (&mut depth, &mut cover));
        }
        (depth, cover)
    }

    /// Drops of triangles that cover no sample change no sample: a dense soup of tiny triangles
    /// (most of them between samples), some degenerate, drawn with and without the drop, gives
    /// the same triangle and depth at every sample.
    #[test]
    fn dropping_triangles_that_cover_no_sample_changes_no_sample() {
        // Sides of 0.002–0.12 (about 0.03–1.5 px); every 50th degenerate.
        let degenerate = |i: usize, p: &mut [Vec3; 3]| {
            if i.is_multiple_of(50) {
                p[2] = p[1];
            }
        };
        let scene = soup(40_000, 7, |u| 0.002 + 0.118 * u.powi(2), degenerate);
        let cam = Camera::look_at(Vec3::ZERO, Vec3::NEG_Z, 60.0);
        let (w, h) = (40u32, 36u32);
        let draw = |drop: bool| {
            let tris = project_all(&Projector::new(&cam, (w, h), 1e-3), &scene, drop);
            let (depth, cover) = draw_tile(&scene, &tris, TileRect { x0: 0, y0: 0, w: w as usize, h: h as usize });
            let seen: Vec<(u32, u32)> = cover
                .iter()
                .zip(&depth)
                .map(|(c, d)| (if c.tri == u32::MAX { u32::MAX } else { tris[c.tri as usize].triangle }, d.to_bits()))
                .collect();
            (tris.len(), seen)
        };
        let (all, every) = draw(false);
        let (kept, dropped) = draw(true);
        assert!(kept * 2 < all, "most triangles cover no sample ({kept} of {all} kept)");
        let covered = every.iter().filter(|s| s.0 != u32::MAX).count();
        assert!(covered > every.len() / 2, "the soup covers most samples ({covered} of {})", every.len());
        eprintln!("{kept} of {all} kept, {covered} of {} samples covered", every.len());
        assert_eq!(every, dropped, "the same triangle and depth at every sample");
    }

    /// Binning into tiles and building screen triangles tile by tile (from the spans' vertices,
    /// or once for clipped triangles) give every sample the triangle and barycentrics that
    /// drawing every projected triangle into every tile gives.
    #[test]
    fn tiled_drawing_equals_one_pass_over_every_triangle() {
        use rtd_scene::Triangle;
        let mut scene = soup(20_000, 11, |u| 0.002 + 0.3 * u.powi(3), |_, _| {});
        // Two triangles clipped at the near plane (one gives a quad: two screen triangles).
        for p in [
            [Vec3::new(-2.0, 1.0, -3.0), Vec3::new(3.0, 1.0, -4.5), Vec3::new(0.5, 1.0, 5.0)],
            [Vec3::new(-3.0, -1.0, -6.0), Vec3::new(0.5, -1.0, 4.0), Vec3::new(3.0, -1.0, 4.0)],
        ] {
            scene.push_triangle(Triangle { p, n: [Vec3::Y; 3], uv: [Vec2::ZERO; 3], material: 0 });
        }
        let cam = Camera::look_at(Vec3::ZERO, Vec3::NEG_Z, 60.0);
        let (w, h) = (97u32, 61u32);
        let bounds = scene.bounds();
        let near = near_plane(&bounds, &cam);
        // Every projected triangle drawn into every tile (the edge functions are set up per
        // tile, so the reference draws the same tiles), no binning.
        let tris = project_all(&Projector::new(&cam, (w, h), near), &scene, true);
        assert!(tris.iter().filter(|t| t.triangle >= 20_000).count() == 3, "the clipped pair gives 3 triangles");
        let n = (w * h) as usize * SAMPLES;
        let mut one_pass: Vec<Option<(u32, Vec3)>> = vec![None; n];
        for (y0, x0) in (0..h).step_by(TILE as usize).flat_map(|y| (0..w).step_by(TILE as usize).map(move |x| (y, x))) {
            let tile = TileRect { x0, y0, w: TILE.min(w - x0) as usize, h: TILE.min(h - y0) as usize };
            let (_, cover) = draw_tile(&scene, &tris, tile);
            for (k, c) in cover.iter().enumerate() {
                let (px, s) = (k / SAMPLES, k % SAMPLES);
                let (x, y) = (x0 as usize + px % tile.w, y0 as usize + px / tile.w);
                one_pass[(y * w as usize + x) * SAMPLES + s] =
                    (c.tri != u32::MAX).then(|| (tris[c.tri as usize].triangle, tris[c.tri as usize].bary(c.e0, c.e1)));
            }
        }
        // The tiled rasteriser, pixel by pixel through its callback.
        let tiled = std::sync::Mutex::new(vec![None; n]);
        let bands: Vec<usize> = (0..h.div_ceil(TILE) as usize).collect();
        rasterize(&scene, &bounds, &cam, w, h, bands, |band, i, px, _| {
            let (x, y) = (i % w as usize, *band * TILE as usize + i / w as usize);
            let at = (y * w as usize + x) * SAMPLES;
            let mut out = tiled.lock().unwrap();
            for (s, hit) in px.iter().enumerate() {
                out[at + s] = hit.map(|h| (h.triangle, h.bary));
            }
        });
        let tiled = tiled.into_inner().unwrap();
        let covered = one_pass.iter().filter(|s| s.is_some()).count();
        assert!(covered > n / 2, "most samples are covered ({covered} of {n})");
        let clipped = one_pass.iter().flatten().filter(|(t, _)| *t >= 20_000).count();
        assert!(clipped > 1000, "the clipped triangles are drawn ({clipped} samples)");
        assert!(one_pass == tiled, "the same triangle and barycentrics at every sample");
    }

    /// A ceiling triangle that reaches behind the camera is clipped at the near plane, which
    /// projects its clipped corners millions of pixels off screen. Its visible edge must still be
    /// drawn where it projects: no sample on the far side of that edge may be covered.
    #[test]
    fn near_clipped_triangles_do_not_cover_samples_past_their_edges() {
        use rtd_scene::{Material, Triangle};
        let mut scene = Scene::default();
        scene.materials.push(Material::default());
        // Ceiling at y = 1: edge a–b in view, c behind the camera.
        let p = [Vec3::new(-2.0, 1.0, -3.0), Vec3::new(3.0, 1.0, -4.5), Vec3::new(0.5, 1.0, 5.0)];
        scene.push_triangle(Triangle { p, n: [Vec3::NEG_Y; 3], uv: [Vec2::ZERO; 3], material: 0 });
        let cam = Camera::look_at(Vec3::ZERO, Vec3::NEG_Z, 60.0);
        let (w, h) = (97u32, 61u32);
        // Screen positions of a and b in f64, as `Projector::to_screen` computes them.
        let (sy, sx) = (1.0 / (30f64.to_radians()).tan(), 1.0 / ((30f64.to_radians()).tan() * w as f64 / h as f64));
        let screen = |q: Vec3| {
            let c = to_camera(&cam, q);
            let (x, y, z) = (c.x as f64, c.y as f64, c.z as f64);
            ((x * sx / z + 1.0) * 0.5 * w as f64, (1.0 - y * sy / z) * 0.5 * h as f64)
        };
        let (a, b) = (screen(p[0]), screen(p[1]));
        // Signed distance in pixels from the line a–b, positive on the ceiling's side (up).
        let (ex, ey) = (b.0 - a.0, b.1 - a.1);
        let len = (ex * ex + ey * ey).sqrt();
        let side = |x: f64, y: f64| ((x - a.0) * ey - (y - a.1) * ex) / len;
        assert!(side(a.0, a.1 - 5.0) > 0.0, "the ceiling lies above its far edge on screen");
        // Each band's output is its index, so that the callback knows its pixel.
        let bands: Vec<usize> = (0..h.div_ceil(TILE) as usize).collect();
        let offsets = sample_offsets();
        let covered = std::sync::Mutex::new(Vec::new());
        rasterize(&scene, &scene.bounds(), &cam, w, h, bands, |band, i, px, _| {
            let (x, y) = (i % w as usize, *band * TILE as usize + i / w as usize);
            for (s, hit) in px.iter().enumerate() {
                if hit.is_some() {
                    let o = offsets[s];
                    covered.lock().unwrap().push(side(x as f64 + 0.5 + o.x as f64, y as f64 + 0.5 + o.y as f64));
                }
            }
        });
        let covered = covered.into_inner().unwrap();
        assert!(covered.len() > 1000, "the ceiling is drawn ({} samples)", covered.len());
        let worst = covered.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(worst > -1e-3, "a covered sample lies {:.4} px past the ceiling's edge", -worst);
    }

    #[test]
    fn bary_steps_match_finite_differences_under_perspective() {
        use rtd_scene::{Material, Triangle};
        let mut scene = Scene::default();
        scene.materials.push(Material::default());
        // A floor triangle seen obliquely, so perspective makes the barycentrics non-affine.
        let p = [Vec3::new(-3.0, 0.0, 1.0), Vec3::new(3.0, 0.0, 1.0), Vec3::new(0.0, 0.0, -9.0)];
        scene.push_triangle(Triangle { p, n: [Vec3::Y; 3], uv: [Vec2::ZERO; 3], material: 0 });
        let cam = Camera::look_at(Vec3::new(0.0, 1.0, 3.0), Vec3::new(0.0, 0.0, -2.0), 50.0);
        let tris = project_all(&Projector::new(&cam, (64, 64), 1e-3), &scene, true);
        assert_eq!(tris.len(), 1);
        let t = &tris[0];
        let fp = Footprints { tris: &tris };
        // Screen-space barycentrics of pixel (x, y) from the screen vertices.
        let e_at = |x: f32, y: f32| {
            let grad = t.grad();
            let e0 = grad[0] * (x - t.v[2].x) + grad[1] * (y - t.v[2].y);
            let e1 = grad[2] * (x - t.v[2].x) + grad[3] * (y - t.v[2].y);
            Vec2::new(e0, e1)
        };
        for (x, y) in [(32.0, 40.0), (20.5, 50.2), (40.0, 30.0)] {
            let e = e_at(x, y);
            let hit = SampleHit { triangle: 0, bary: t.bary(e.x, e.y), screen: 0, e };
            let [sx, sy] = fp.bary_steps(&hit, 1.0);
            let h = 0.01;
            let fd = |dx: f32, dy: f32| {
                let (a, b) = (e_at(x + dx * h, y + dy * h), e_at(x - dx * h, y - dy * h));
                (t.bary(a.x, a.y) - t.bary(b.x, b.y)) / (2.0 * h)
            };
            for (got, want) in [(sx, fd(1.0, 0.0)), (sy, fd(0.0, 1.0))] {
                assert!((got - want).length() <= 1e-3 * (1.0 + want.length()), "({x}, {y}): {got} vs {want}");
            }
            assert!(sy.length() > 1e-3, "the floor's barycentrics change down the screen");
        }
    }
}
