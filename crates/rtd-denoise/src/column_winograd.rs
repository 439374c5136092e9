//! Winograd F(4, 3) down the columns and the direct method along the rows, on AVX-512: the fast
//! path's kernel for the dilated 3×3 convolutions, where [`crate::winograd`]'s square tiles
//! would need their pixels gathered a dilation apart.
//!
//! A tile is four output rows a dilation d apart (y, y + d, y + 2d, y + 3d) across the whole
//! width. The six input rows they read (y − d … y + 4d) are carried into the transform domain
//! down each column (Bᵀ d, six values per pixel), where each of the three column taps of the
//! filter becomes six products instead of twelve; Aᵀ m brings the sums back to the four rows.
//! Along the rows nothing changes: the taps read the transformed rows d pixels apart, as whole
//! 16-pixel vectors, so any dilation costs the same. That halves the multiplies of the direct
//! kernel, on its register blocking ([`BLOCK`] output channels × four vectors).

use rayon::prelude::*;

use crate::direct::{available, BLOCK};
use crate::feature_map::{Map, Rows};
use crate::winograd::{G, IN, OUT};

/// 16-pixel vectors computed together along a row.
const VECTORS: usize = 4;
/// Pixels per row segment.
const SEGMENT: usize = 16 * VECTORS;

/// A dilated 3×3 convolution's weights, transformed down the columns and laid out for the
/// kernel: per block of [`BLOCK`] output channels, per transform position, per input channel,
/// per column tap, the block's [`BLOCK`] values side by side (zero past `cout`).
#[derive(Clone, Debug)]
pub(crate) struct ColumnWinogradWeights {
    cin: usize,
    cout: usize,
    dil: usize,
    /// [block][ξ][ci][kx][BLOCK].
    weights: Vec<f32>,
    /// [block][BLOCK].
    bias: Vec<f32>,
}

impl ColumnWinogradWeights {
    /// From weights as rows (ky, kx, ci), columns co (the gemm layout), a bias per output and
    /// the dilation.
    pub(crate) fn new(cin: usize, cout: usize, dil: usize, rows: &[f32], bias: &[f32]) -> Self {
        let blocks = cout.div_ceil(BLOCK);
        let mut weights = vec![0.0; blocks * IN * cin * 3 * BLOCK];
        let mut padded_bias = vec![0.0; blocks * BLOCK];
        for co in 0..cout {
            let (b, r) = (co / BLOCK, co % BLOCK);
            padded_bias[b * BLOCK + r] = bias[co];
            for ci in 0..cin {
                for kx in 0..3 {
                    // U[ξ] = Σ_ky G[ξ][ky] · g[ky][kx], in f64.
                    for (xi, g) in G.iter().enumerate() {
                        let u: f64 =
                            (0..3).map(|ky| g[ky] * f64::from(rows[((ky * 3 + kx) * cin + ci) * cout + co])).sum();
                        weights[(((b * IN + xi) * cin + ci) * 3 + kx) * BLOCK + r] = u as f32;
                    }
                }
            }
        }
        ColumnWinogradWeights { cin, cout, dil, weights, bias: padded_bias }
    }

    /// Writes act(conv(x) + bias) for output rows `to.of_x` of x's grid, stored from row
    /// `to.at` of `dst` (a map of x's width), into planes [offset, offset + cout).
    pub(crate) fn apply_rows(&self, x: &Map, to: Rows, dst: &mut Map, offset: usize, relu: bool) {
        assert!(available(), "the column Winograd kernel needs AVX-512F");
        assert_eq!(x.c, self.cin);
        assert!(offset + self.cout <= dst.c && dst.w == x.w && to.of_x.end <= x.h && to.at + to.of_x.len() <= dst.h);
        let dn = dst.w * dst.h;
        let out = dst.data[offset * dn..(offset + self.cout) * dn].as_mut_ptr() as usize;
        // Tiles start at rows 4d·g + e (e < d) of the range: every row lies in exactly one.
        let d = self.dil;
        let starts: Vec<usize> = (0..to.of_x.len()).filter(|y| y % (OUT * d) < d).collect();
        starts.into_par_iter().for_each(|start| {
            // SAFETY: AVX-512F is present (checked above), and each task writes only rows
            // at + start + d·i (i < 4, inside the range) of the cout planes, which lie in `dst`.
            #[cfg(target_arch = "x86_64")]
            unsafe {
                self.tile(x, (&to, start), ((out as *mut f32).add(to.at * x.w), dn), relu)
            }
            #[cfg(not(target_arch = "x86_64"))]
            let _ = (start, out);
        });
    }

    /// The tile whose first output row is row `start` of the range `to.of_x`; `out` is the
    /// first plane's row of the range's first row, and the planes' length.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn tile(&self, x: &Map, (to, start): (&Rows, usize), (out, dn): (*mut f32, usize), relu: bool) {
        use std::arch::x86_64::*;
        let (w, d) = (x.w, self.dil);
        let segments = w.div_ceil(SEGMENT);
        // Transformed rows: d zeros, the row, zeros to whole segments plus the taps' reach.
        let stride = segments * SEGMENT + (2 * d).next_multiple_of(16);
        BUFFERS.with(|cell| {
            let buffers = &mut *cell.borrow_mut();
            buffers.transformed.resize(IN * self.cin * stride, 0.0);
            buffers.rows.resize(IN * stride, 0.0);
            buffers.products.resize(IN * BLOCK * SEGMENT, 0.0);
            let v = buffers.transformed.as_mut_ptr();
            for ci in 0..self.cin {
                // The six input rows start − d + d·r (zero outside the map), padded.
                for r in 0..IN {
                    let row = &mut buffers.rows[r * stride..][..stride];
                    let sy = (to.of_x.start + start + d * r).checked_sub(d).filter(|&sy| sy < x.h);
                    match sy {
                        Some(sy) => {
                            row[..d].fill(0.0);
                            row[d..d + w].copy_from_slice(&x.data[(ci * x.h + sy) * w..][..w]);
                            row[d + w..].fill(0.0);
                        }
                        None => row.fill(0.0),
                    }
                }
                // Bᵀ down each column, sixteen columns at a time.
                let rows = buffers.rows.as_ptr();
                for c in (0..stride).step_by(16) {
                    let t =
                        crate::winograd::input_1d(std::array::from_fn(|r| _mm512_loadu_ps(rows.add(r * stride + c))));
                    for (xi, value) in t.iter().enumerate() {
                        _mm512_storeu_ps(v.add((xi * self.cin + ci) * stride + c), *value);
                    }
                }
            }
            let m = buffers.products.as_mut_ptr();
            for x0 in (0..w).step_by(SEGMENT) {
                let vectors = (w - x0).div_ceil(16).min(VECTORS);
                for block in 0..self.cout.div_ceil(BLOCK) {
                    match vectors {
                        1 => self.multiply::<1>(block, v.add(x0), stride, m),
                        2 => self.multiply::<2>(block, v.add(x0), stride, m),
                        3 => self.multiply::<3>(block, v.add(x0), stride, m),
                        _ => self.multiply::<4>(block, v.add(x0), stride, m),
                    }
                    let (bias, zero) = (&self.bias[block * BLOCK..][..BLOCK], _mm512_setzero_ps());
                    for (r, b) in bias.iter().enumerate().take(self.cout - block * BLOCK) {
                        let plane = out.add((block * BLOCK + r) * dn);
                        for k in 0..vectors {
                            let mv: [__m512; IN] =
                                std::array::from_fn(|xi| _mm512_loadu_ps(m.add((xi * BLOCK + r) * SEGMENT + 16 * k)));
                            let px = x0 + 16 * k;
                            let mask = ((1u32 << (w - px).min(16)) - 1) as u16;
                            for (i, value) in crate::winograd::output_1d(mv).iter().enumerate() {
                                let y = start + d * i;
                                if y >= to.of_x.len() {
                                    break;
                                }
                                let value = _mm512_add_ps(*value, _mm512_set1_ps(*b));
                                let value = if relu { _mm512_max_ps(value, zero) } else { value };
                                _mm512_mask_storeu_ps(plane.add(y * w + px), mask, value);
                            }
                        }
                    }
                }
            }
        });
    }

    /// The transform-domain products of one block of output channels over one row segment
    /// (`v` at its first pixel, rows `stride` apart): m[ξ][r][px] = Σ_ci Σ_kx U[ξ][ci][kx][r] ·
    /// V[ξ][ci][px + d·kx], the transformed rows padded by d on the left.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn multiply<const NV: usize>(&self, block: usize, v: *const f32, stride: usize, m: *mut f32) {
        use std::arch::x86_64::*;
        let weights = self.weights.as_ptr().add(block * IN * self.cin * 3 * BLOCK);
        for xi in 0..IN {
            let mut acc = [[_mm512_setzero_ps(); NV]; BLOCK];
            for ci in 0..self.cin {
                let row = v.add((xi * self.cin + ci) * stride);
                for kx in 0..3 {
                    let wt = weights.add(((xi * self.cin + ci) * 3 + kx) * BLOCK);
                    let tap = row.add(kx * self.dil);
                    let pixels: [__m512; NV] = std::array::from_fn(|k| _mm512_loadu_ps(tap.add(16 * k)));
                    for (r, lanes) in acc.iter_mut().enumerate() {
                        let wr = _mm512_set1_ps(*wt.add(r));
                        for (a, p) in lanes.iter_mut().zip(&pixels) {
                            *a = _mm512_fmadd_ps(wr, *p, *a);
                        }
                    }
                }
            }
            for (r, lanes) in acc.iter().enumerate() {
                for (k, a) in lanes.iter().enumerate() {
                    _mm512_storeu_ps(m.add((xi * BLOCK + r) * SEGMENT + 16 * k), *a);
                }
            }
        }
    }
}

/// Each worker's buffers, reused across tiles and layers.
#[derive(Default)]
struct Buffers {
    /// One channel's six padded input rows: [r][stride].
    rows: Vec<f32>,
    /// The tile's transformed rows: [ξ][ci][stride].
    transformed: Vec<f32>,
    /// One segment's products for one block of outputs: [ξ][r][SEGMENT].
    products: Vec<f32>,
}

thread_local! {
    static BUFFERS: std::cell::RefCell<Buffers> = std::cell::RefCell::new(Buffers::default());
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::feature_map::{convolution_by_definition, test_convolution};

    /// The kernel against a plain loop of the convolution's definition, for the dilations the
    /// network has, on sizes that leave partial tiles, segments and blocks, for a range of rows
    /// stored lower in a taller map.
    #[test]
    fn column_winograd_convolution_equals_the_definition() {
        if !available() {
            eprintln!("no AVX-512F here: the column Winograd kernel is not used on this CPU");
            return;
        }
        // Vectors per row segment: 3; 4 + 1; 4 + 4 + 1; 1; 4 + 2.
        for (cin, cout, dil, w, h) in
            [(5, 7, 2, 37, 19), (24, 6, 2, 70, 13), (6, 13, 4, 130, 21), (3, 2, 4, 5, 3), (4, 3, 2, 90, 9)]
        {
            let n = w * h;
            let (rows, bias, x) = test_convolution(cin, cout, 9, w, h);
            let conv = ColumnWinogradWeights::new(cin, cout, dil, &rows, &bias);
            for (relu, range) in [(false, 0..h), (true, 1..h - 1)] {
                let at = 2;
                let tall_h = range.len() + 3;
                let mut dst = Map { w, h: tall_h, c: cout + 2, data: vec![9.0; (cout + 2) * w * tall_h] };
                conv.apply_rows(&x, Rows { of_x: range.clone(), at }, &mut dst, 1, relu);
                let reference = convolution_by_definition(&x, (&rows, &bias), (3, 3, dil), relu);
                for c in 0..cout + 2 {
                    for y in 0..tall_h {
                        for px in 0..w {
                            let got = dst.data[(c * tall_h + y) * w + px];
                            let py = (y + range.start).checked_sub(at).filter(|py| range.contains(py));
                            let (co, py) = match (c.checked_sub(1).filter(|co| *co < cout), py) {
                                (Some(co), Some(py)) => (co, py),
                                _ => {
                                    assert_eq!(got, 9.0, "plane {c} row {y} was written");
                                    continue;
                                }
                            };
                            let want = reference.data[co * n + py * w + px];
                            assert!(
                                (got - want).abs() < 1e-4 * (1.0 + want.abs()),
                                "{cin}->{cout} d{dil} {w}x{h}: ({px},{py}) {got} vs {want}"
                            );
                        }
                    }
                }
            }
        }
    }
}
