//! Winograd F(4×4, 3×3) convolution on planar (CHW) maps with AVX-512: the fast path's kernel
//! for the network's undilated 3×3 convolutions where the CPU has AVX-512F (Lavin & Gray,
//! "Fast Algorithms for Convolutional Neural Networks", 2016).
//!
//! Each 4×4 block of output pixels (a tile) is computed from the 6×6 input pixels around it.
//! The input tile d and each 3×3 filter g are carried into a 6×6 transform domain (Bᵀ d B and
//! G g Gᵀ), where the convolution becomes 36 independent dot products over the input
//! channels; Aᵀ m A brings the 36 sums back to the 4×4 outputs. That is 36 multiplies per
//! tile, channel pair and 16 outputs, against 144 for the direct convolution, plus transforms
//! whose cost is shared by every output (or input) channel.
//!
//! Vectors hold 16 tiles side by side along a row (in a fixed shuffled order, undone when the
//! outputs are stored), so the dot products run on the same register blocking as
//! [`crate::direct`]: [`BLOCK`] output channels × four vectors of tiles. Tiles are laid from the
//! first row computed (the map's own grid when that row is a multiple of 4, as the fast path's
//! bands are) and the order of summation is fixed per output value, so the result does not
//! depend on threads.

use rayon::prelude::*;

use crate::direct::{available, BLOCK};
use crate::feature_map::{Map, Rows};

/// Output pixels along each side of a tile.
pub(crate) const OUT: usize = 4;
/// Input pixels along each side of a tile: the outputs plus the filter's reach either side.
pub(crate) const IN: usize = OUT + 2;
/// Values of a tile in the transform domain.
const XI: usize = IN * IN;
/// Tiles per vector.
const LANES: usize = 16;
/// Vectors of tiles transformed and multiplied together.
const VECTORS: usize = 4;
/// Tiles per batch.
const BATCH: usize = LANES * VECTORS;

/// G, the 6×3 filter transform for the interpolation points 0, ±1, ±2 and ∞.
pub(crate) const G: [[f64; 3]; IN] = [
    [1.0 / 4.0, 0.0, 0.0],
    [-1.0 / 6.0, -1.0 / 6.0, -1.0 / 6.0],
    [-1.0 / 6.0, 1.0 / 6.0, -1.0 / 6.0],
    [1.0 / 24.0, 1.0 / 12.0, 1.0 / 6.0],
    [1.0 / 24.0, -1.0 / 12.0, 1.0 / 6.0],
    [0.0, 0.0, 1.0],
];

/// A 3×3, stride-1, undilated convolution's weights in the transform domain, laid out for the
/// kernel: per block of [`BLOCK`] output channels, per transform position, per input channel,
/// the block's [`BLOCK`] values side by side (zero past `cout`).
#[derive(Clone, Debug)]
pub(crate) struct WinogradWeights {
    cin: usize,
    cout: usize,
    /// [block][ξ][ci][BLOCK].
    weights: Vec<f32>,
    /// [block][BLOCK].
    bias: Vec<f32>,
}

impl WinogradWeights {
    /// From weights as rows (ky, kx, ci), columns co (the gemm layout) and a bias per output.
    pub(crate) fn new(cin: usize, cout: usize, rows: &[f32], bias: &[f32]) -> Self {
        let blocks = cout.div_ceil(BLOCK);
        let mut weights = vec![0.0; blocks * XI * cin * BLOCK];
        let mut padded_bias = vec![0.0; blocks * BLOCK];
        for co in 0..cout {
            let (b, r) = (co / BLOCK, co % BLOCK);
            padded_bias[b * BLOCK + r] = bias[co];
            for ci in 0..cin {
                let g = |ky: usize, kx: usize| f64::from(rows[((ky * 3 + kx) * cin + ci) * cout + co]);
                // U = G g Gᵀ, in f64 so that only the final rounding to f32 remains.
                for i in 0..IN {
                    for j in 0..IN {
                        let mut u = 0.0;
                        for (a, ga) in G[i].iter().enumerate() {
                            for (c, gc) in G[j].iter().enumerate() {
                                u += ga * g(a, c) * gc;
                            }
                        }
                        weights[((b * XI + i * IN + j) * cin + ci) * BLOCK + r] = u as f32;
                    }
                }
            }
        }
        WinogradWeights { cin, cout, weights, bias: padded_bias }
    }

    /// Writes act(conv(x) + bias) for output rows `to.of_x` of x's grid (tiles start at its
    /// first; zero padding outside x), stored from row `to.at` of `dst` (a map of x's width)
    /// into planes [offset, offset + cout).
    pub(crate) fn apply_rows(&self, x: &Map, to: Rows, dst: &mut Map, offset: usize, relu: bool) {
        assert!(available(), "the Winograd kernel needs AVX-512F");
        assert_eq!(x.c, self.cin);
        assert!(offset + self.cout <= dst.c && dst.w == x.w && to.of_x.end <= x.h && to.at + to.of_x.len() <= dst.h);
        let dn = dst.w * dst.h;
        let out = dst.data[offset * dn..(offset + self.cout) * dn].as_mut_ptr() as usize;
        // One task per batch of tiles (up to BATCH of a row of tiles); tasks write disjoint
        // pixels of every output plane.
        let batches = x.w.div_ceil(OUT).div_ceil(BATCH);
        (0..to.of_x.len().div_ceil(OUT) * batches).into_par_iter().for_each(|task| {
            // SAFETY: AVX-512F is present (checked above), and each task writes only its tiles'
            // pixels inside rows [at, at + len) of the cout output planes, which lie in `dst`.
            #[cfg(target_arch = "x86_64")]
            unsafe {
                let planes = Target {
                    plane: (out as *mut f32).add(to.at * x.w),
                    plane_len: dn,
                    w: x.w,
                    h: to.of_x.len(),
                    x: 0,
                    y: 0,
                };
                self.batch(x, (to.of_x.start, task / batches, task % batches * BATCH), planes, relu)
            }
            #[cfg(not(target_arch = "x86_64"))]
            let _ = (task, out);
        });
    }

    /// Every output channel of tiles [t0, t0 + BATCH) ∩ the row's tiles, of row of tiles `ty`
    /// counted from x's row `y0`: output rows [y0 + 4·ty, y0 + 4·ty + 4), columns [4·t0,
    /// 4·t0 + 4·BATCH), those inside `planes` (whose row 0 is x's row y0).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn batch(&self, x: &Map, (y0, ty, t0): (usize, usize, usize), planes: Target, relu: bool) {
        let vectors = (x.w.div_ceil(OUT) - t0).div_ceil(LANES).min(VECTORS);
        BUFFERS.with(|cell| {
            let buffers = &mut *cell.borrow_mut();
            let stride = fill_panel(x, (y0 + OUT * ty, t0), vectors, &mut buffers.panel);
            buffers.transformed.resize(XI * self.cin * BATCH, 0.0);
            buffers.products.resize(XI * BLOCK * BATCH, 0.0);
            let (panel, v, m) =
                (buffers.panel.as_ptr(), buffers.transformed.as_mut_ptr(), buffers.products.as_mut_ptr());
            // Bᵀ d B for every input channel's tiles of the batch.
            for ci in 0..self.cin {
                for k in 0..vectors {
                    let src = panel.add(ci * IN * stride + OUT * LANES * k);
                    input_transform(src, stride, v.add(ci * BATCH + LANES * k), self.cin * BATCH);
                }
            }
            for block in 0..self.cout.div_ceil(BLOCK) {
                match vectors {
                    1 => self.multiply::<1>(block, v, m),
                    2 => self.multiply::<2>(block, v, m),
                    3 => self.multiply::<3>(block, v, m),
                    _ => self.multiply::<4>(block, v, m),
                }
                for r in 0..BLOCK.min(self.cout - block * BLOCK) {
                    let co = block * BLOCK + r;
                    for k in 0..vectors {
                        let plane = planes.plane.add(co * planes.plane_len);
                        let target = Target { plane, x: OUT * (t0 + LANES * k), y: OUT * ty, ..planes };
                        output_transform(m.add(r * BATCH + LANES * k), BLOCK * BATCH, self.bias[co], relu, target);
                    }
                }
            }
        });
    }

    /// The transform-domain products of one block of output channels: for each position ξ,
    /// m[ξ][r][tile] = Σ_ci U[ξ][ci][r] · V[ξ][ci][tile], over `NV` vectors of tiles.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn multiply<const NV: usize>(&self, block: usize, v: *const f32, m: *mut f32) {
        use std::arch::x86_64::*;
        let weights = self.weights.as_ptr().add(block * XI * self.cin * BLOCK);
        for xi in 0..XI {
            let mut acc = [[_mm512_setzero_ps(); NV]; BLOCK];
            let (vs, ws) = (v.add(xi * self.cin * BATCH), weights.add(xi * self.cin * BLOCK));
            for ci in 0..self.cin {
                let tiles: [__m512; NV] = std::array::from_fn(|k| _mm512_loadu_ps(vs.add(ci * BATCH + LANES * k)));
                for (r, lanes) in acc.iter_mut().enumerate() {
                    let wr = _mm512_set1_ps(*ws.add(ci * BLOCK + r));
                    for (a, t) in lanes.iter_mut().zip(&tiles) {
                        *a = _mm512_fmadd_ps(wr, *t, *a);
                    }
                }
            }
            for (r, lanes) in acc.iter().enumerate() {
                for (k, a) in lanes.iter().enumerate() {
                    _mm512_storeu_ps(m.add((xi * BLOCK + r) * BATCH + LANES * k), *a);
                }
            }
        }
    }
}

/// Each worker's buffers, reused across rows of tiles and layers.
#[derive(Default)]
struct Buffers {
    /// The input rows a row of tiles reads, zero-padded: [ci][row][stride].
    panel: Vec<f32>,
    /// Transformed input tiles of a batch: [ξ][ci][tile].
    transformed: Vec<f32>,
    /// Transform-domain products of a batch for one block of outputs: [ξ][r][tile].
    products: Vec<f32>,
}

thread_local! {
    static BUFFERS: std::cell::RefCell<Buffers> = std::cell::RefCell::new(Buffers::default());
}

/// Copies the input pixels that `vectors` vectors of tiles from tile t0 of the row of tiles
/// whose top output row is `y` read into `panel`: for every channel, the six rows [y − 1,
/// y + 5) and the columns from 4·t0 − 1 (panel column c is image column 4·t0 + c − 1) through
/// one vector of lookahead past the last tile, zero outside the image. Returns the panel's
/// row stride.
fn fill_panel(x: &Map, (y, t0): (usize, usize), vectors: usize, panel: &mut Vec<f32>) -> usize {
    let (w, h) = (x.w, x.h);
    let stride = OUT * LANES * vectors + LANES;
    panel.resize(x.c * IN * stride, 0.0);
    // Image columns [c0, c1) land at panel columns [c0 + 1 − 4·t0, …).
    let (c0, c1) = ((OUT * t0).saturating_sub(1), (OUT * t0 + stride - 1).min(w));
    let at = c0 + 1 - OUT * t0;
    for ci in 0..x.c {
        for r in 0..IN {
            let dst = &mut panel[(ci * IN + r) * stride..][..stride];
            match (y + r).checked_sub(1).filter(|&sy| sy < h) {
                Some(sy) => {
                    dst[..at].fill(0.0);
                    dst[at..at + c1 - c0].copy_from_slice(&x.data[(ci * h + sy) * w + c0..][..c1 - c0]);
                    dst[at + c1 - c0..].fill(0.0);
                }
                None => dst.fill(0.0),
            }
        }
    }
    stride
}

/// 4×4 transposes within each 128-bit lane across four vectors. Applied to four vectors of 16
/// consecutive pixels it gives, for each phase c = 0..3, the pixel 4j + c of each tile j, tile
/// 4k + g in lane 4g + k; applied to those four phase vectors it gives the pixels back.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
fn transpose4(a: [std::arch::x86_64::__m512; 4]) -> [std::arch::x86_64::__m512; 4] {
    use std::arch::x86_64::*;
    let t0 = _mm512_castps_pd(_mm512_unpacklo_ps(a[0], a[1]));
    let t1 = _mm512_castps_pd(_mm512_unpacklo_ps(a[2], a[3]));
    let t2 = _mm512_castps_pd(_mm512_unpackhi_ps(a[0], a[1]));
    let t3 = _mm512_castps_pd(_mm512_unpackhi_ps(a[2], a[3]));
    [
        _mm512_castpd_ps(_mm512_unpacklo_pd(t0, t1)),
        _mm512_castpd_ps(_mm512_unpackhi_pd(t0, t1)),
        _mm512_castpd_ps(_mm512_unpacklo_pd(t2, t3)),
        _mm512_castpd_ps(_mm512_unpackhi_pd(t2, t3)),
    ]
}

/// Bᵀ d along one direction: six values of a tile (pixels 0..6) to its six transform values.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
pub(crate) fn input_1d(d: [std::arch::x86_64::__m512; IN]) -> [std::arch::x86_64::__m512; IN] {
    use std::arch::x86_64::*;
    let (four, neg_four, neg_five, two) =
        (_mm512_set1_ps(4.0), _mm512_set1_ps(-4.0), _mm512_set1_ps(-5.0), _mm512_set1_ps(2.0));
    // Rows of Bᵀ: (4, 0, −5, 0, 1, 0), (0, −4, −4, 1, 1, 0), (0, 4, −4, −1, 1, 0),
    // (0, −2, −1, 2, 1, 0), (0, 2, −1, −2, 1, 0), (0, 4, 0, −5, 0, 1).
    let s = _mm512_fmadd_ps(neg_four, d[2], d[4]);
    let u = _mm512_fmadd_ps(neg_four, d[1], d[3]);
    let p = _mm512_sub_ps(d[4], d[2]);
    let q = _mm512_mul_ps(two, _mm512_sub_ps(d[3], d[1]));
    [
        _mm512_fmadd_ps(neg_five, d[2], _mm512_fmadd_ps(four, d[0], d[4])),
        _mm512_add_ps(s, u),
        _mm512_sub_ps(s, u),
        _mm512_add_ps(p, q),
        _mm512_sub_ps(p, q),
        _mm512_fmadd_ps(neg_five, d[3], _mm512_fmadd_ps(four, d[1], d[5])),
    ]
}

/// Aᵀ m along one direction: six transform-domain values to four outputs.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
pub(crate) fn output_1d(m: [std::arch::x86_64::__m512; IN]) -> [std::arch::x86_64::__m512; OUT] {
    use std::arch::x86_64::*;
    // Rows of Aᵀ: (1, 1, 1, 1, 1, 0), (0, 1, −1, 2, −2, 0), (0, 1, 1, 4, 4, 0), (0, 1, −1, 8, −8, 1).
    let (a, b) = (_mm512_add_ps(m[1], m[2]), _mm512_sub_ps(m[1], m[2]));
    let (c, d) = (_mm512_add_ps(m[3], m[4]), _mm512_sub_ps(m[3], m[4]));
    [
        _mm512_add_ps(_mm512_add_ps(m[0], a), c),
        _mm512_fmadd_ps(_mm512_set1_ps(2.0), d, b),
        _mm512_fmadd_ps(_mm512_set1_ps(4.0), c, a),
        _mm512_add_ps(_mm512_fmadd_ps(_mm512_set1_ps(8.0), d, b), m[5]),
    ]
}

/// V = Bᵀ d B for one vector of 16 tiles of one channel: `src` is the panel at the first tile's
/// top-left input pixel, `dst` receives transform value ξ at `dst + ξ·xi_stride`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
unsafe fn input_transform(src: *const f32, stride: usize, dst: *mut f32, xi_stride: usize) {
    use std::arch::x86_64::*;
    // Lane 4g + k holds tile 4k + g; phases 4 and 5 are phases 0 and 1 of the next tile: lane
    // + 4 within a vector, or the first lanes (tile 16 being the next vector's first pixels).
    let next0 = _mm512_set_epi32(16, 3, 2, 1, 15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4);
    let next1 = _mm512_set_epi32(17, 3, 2, 1, 15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4);
    let mut rows = [[_mm512_setzero_ps(); IN]; IN];
    for (r, row) in rows.iter_mut().enumerate() {
        let p = src.add(r * stride);
        let [c0, c1, c2, c3] = transpose4(std::array::from_fn(|k| _mm512_loadu_ps(p.add(LANES * k))));
        let ahead = _mm512_loadu_ps(p.add(OUT * LANES));
        // Tile 16's phase 0 is pixel 64 (index 16: lane 0 of `ahead`), its phase 1 pixel 65.
        let c4 = _mm512_permutex2var_ps(c0, next0, ahead);
        let c5 = _mm512_permutex2var_ps(c1, next1, ahead);
        *row = input_1d([c0, c1, c2, c3, c4, c5]);
    }
    let columns: [[__m512; IN]; IN] = std::array::from_fn(|j| std::array::from_fn(|r| rows[r][j]));
    for (j, column) in columns.into_iter().enumerate() {
        for (i, value) in input_1d(column).iter().enumerate() {
            _mm512_storeu_ps(dst.add((i * IN + j) * xi_stride), *value);
        }
    }
}

/// Where one vector of tiles' outputs go: a plane of a w×h map, from pixel (x, y).
#[derive(Clone, Copy)]
struct Target {
    plane: *mut f32,
    /// Values from one plane to the next (for a first plane; one vector's target uses `plane`).
    plane_len: usize,
    w: usize,
    h: usize,
    x: usize,
    y: usize,
}

/// Y = Aᵀ m A for one vector of 16 tiles of one output channel, plus `bias`, optionally
/// ReLU'd, stored to the 4 × 64 pixels of `target` that lie inside the map.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
unsafe fn output_transform(m: *const f32, xi_stride: usize, bias: f32, relu: bool, target: Target) {
    use std::arch::x86_64::*;
    let mut rows = [[_mm512_setzero_ps(); OUT]; IN];
    for (i, row) in rows.iter_mut().enumerate() {
        *row = output_1d(std::array::from_fn(|j| _mm512_loadu_ps(m.add((i * IN + j) * xi_stride))));
    }
    let mut out = [[_mm512_setzero_ps(); OUT]; OUT];
    for j in 0..OUT {
        let column = output_1d(std::array::from_fn(|i| rows[i][j]));
        for (a, value) in column.iter().enumerate() {
            out[a][j] = *value;
        }
    }
    let (bias, zero) = (_mm512_set1_ps(bias), _mm512_setzero_ps());
    for (a, phases) in out.iter().enumerate() {
        let y = target.y + a;
        if y >= target.h {
            break;
        }
        let pixels = transpose4(std::array::from_fn(|c| {
            let v = _mm512_add_ps(phases[c], bias);
            if relu {
                _mm512_max_ps(v, zero)
            } else {
                v
            }
        }));
        for (k, v) in pixels.iter().enumerate() {
            let x = target.x + LANES * k;
            let inside = target.w.saturating_sub(x).min(LANES);
            let mask = ((1u32 << inside) - 1) as u16;
            _mm512_mask_storeu_ps(target.plane.add(y * target.w).wrapping_add(x), mask, *v);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::feature_map::{convolution_by_definition, test_convolution};

    /// The kernel against a plain loop of the convolution's definition, on sizes that leave
    /// partial tiles, vectors, batches and blocks.
    #[test]
    fn winograd_convolution_equals_the_definition() {
        if !available() {
            eprintln!("no AVX-512F here: the Winograd kernel is not used on this CPU");
            return;
        }
        // Tiles per row 10, 75 (64 + 11), 18, 1, 133 (64 + 64 + 5) and 38: one to four vectors.
        for (cin, cout, w, h) in
            [(5, 7, 37, 9), (20, 24, 300, 6), (24, 6, 70, 13), (3, 13, 1, 1), (8, 12, 530, 4), (4, 5, 150, 5)]
        {
            let n = w * h;
            let (rows, bias, x) = test_convolution(cin, cout, 9, w, h);
            let conv = WinogradWeights::new(cin, cout, &rows, &bias);
            for relu in [false, true] {
                let mut dst = Map { w, h, c: cout + 2, data: vec![9.0; (cout + 2) * n] };
                conv.apply_rows(&x, Rows { of_x: 0..h, at: 0 }, &mut dst, 1, relu);
                let reference = convolution_by_definition(&x, (&rows, &bias), (3, 3, 1), relu);
                for co in 0..cout {
                    for p in 0..n {
                        let (want, got) = (reference.data[co * n + p], dst.data[(1 + co) * n + p]);
                        let (px, py) = (p % w, p / w);
                        assert!(
                            (got - want).abs() < 1e-4 * (1.0 + want.abs()),
                            "{cin}->{cout} {w}x{h}: ({px},{py}) {got} vs {want}"
                        );
                    }
                }
                // The planes around the written ones are untouched.
                assert!(dst.data[..n].iter().chain(&dst.data[(cout + 1) * n..]).all(|v| *v == 9.0));
                // Rows [1, h − 1) alone, stored from row 2 of a taller map, are the same rows
                // (tiles starting one row lower round differently), and nothing else is written.
                let rows = if h > 2 { 1..h - 1 } else { 0..h };
                let mut tall = Map { w, h: h + 3, c: cout, data: vec![7.0; cout * w * (h + 3)] };
                conv.apply_rows(&x, Rows { of_x: rows.clone(), at: 2 }, &mut tall, 0, relu);
                for co in 0..cout {
                    for y in 0..h + 3 {
                        for px in 0..w {
                            let got = tall.data[(co * (h + 3) + y) * w + px];
                            let source = (y >= 2).then(|| y - 2 + rows.start).filter(|sy| rows.contains(sy));
                            match source {
                                Some(sy) => {
                                    let want = dst.data[(1 + co) * n + sy * w + px];
                                    assert!(
                                        (got - want).abs() < 1e-4 * (1.0 + want.abs()),
                                        "row {sy}: {got} vs {want}"
                                    );
                                }
                                None => assert_eq!(got, 7.0, "row {y} of the taller map was written"),
                            }
                        }
                    }
                }
            }
        }
    }
}
