//! Direct convolution on planar (CHW) maps with AVX-512, the fast path's kernel where the CPU
//! has it. Each output value is its bias plus the sum over input channels and taps of weight ×
//! input, accumulated in registers: six output channels × four 16-pixel vectors at a time, the
//! weights broadcast, the input read in place (masked at the image edges, which reads zero
//! padding). Nothing is copied first, as im2col + gemm must, and bias, ReLU and a residual
//! are applied as the values are stored. The order of summation is fixed per output value, so
//! the result does not depend on threads or tiling.

use rayon::prelude::*;

use crate::feature_map::{Map, Rows};

/// Output channels computed together (their weights broadcast, one register each per vector).
pub(crate) const BLOCK: usize = 6;
/// 16-pixel vectors computed together along a row.
const VECTORS: usize = 4;
/// Pixels per row segment.
const SEGMENT: usize = 16 * VECTORS;

/// Whether this CPU runs the direct kernel (AVX-512F); elsewhere the fast path uses gemm.
pub fn available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512f")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// A convolution's weights laid out for the kernel: per block of [`BLOCK`] output channels,
/// per input channel, per tap, the block's [`BLOCK`] weights side by side (zero for the
/// channels past `cout` in the last block).
#[derive(Clone, Debug)]
pub(crate) struct DirectWeights {
    cin: usize,
    cout: usize,
    kh: usize,
    kw: usize,
    dil: usize,
    /// [block][ci][ky][kx][BLOCK].
    weights: Vec<f32>,
    /// [block][BLOCK].
    bias: Vec<f32>,
}

impl DirectWeights {
    /// From weights as rows (ky, kx, ci), columns co (the gemm layout) and a bias per output.
    pub(crate) fn new(
        cin: usize,
        cout: usize,
        (kh, kw, dil): (usize, usize, usize),
        rows: &[f32],
        bias: &[f32],
    ) -> Self {
        let blocks = cout.div_ceil(BLOCK);
        let mut weights = vec![0.0; blocks * cin * kh * kw * BLOCK];
        let mut padded_bias = vec![0.0; blocks * BLOCK];
        for co in 0..cout {
            let (b, r) = (co / BLOCK, co % BLOCK);
            padded_bias[b * BLOCK + r] = bias[co];
            for ci in 0..cin {
                for tap in 0..kh * kw {
                    weights[((b * cin + ci) * kh * kw + tap) * BLOCK + r] = rows[(tap * cin + ci) * cout + co];
                }
            }
        }
        DirectWeights { cin, cout, kh, kw, dil, weights, bias: padded_bias }
    }

    /// Writes act(conv(x) + bias) (+ `residual`, after the ReLU) for output rows `to.of_x` of
    /// x's grid (reading the rows around them that exist; zero padding outside x), stored from
    /// row `to.at` of `dst` (a map of x's width) into planes [offset, offset + cout).
    /// `residual`, if given, holds `cout` planes on dst's grid.
    pub(crate) fn apply_rows(
        &self,
        x: &Map,
        to: Rows,
        dst: &mut Map,
        offset: usize,
        relu: bool,
        residual: Option<&Map>,
    ) {
        assert!(available(), "the direct kernel needs AVX-512F");
        assert_eq!(x.c, self.cin);
        assert!(offset + self.cout <= dst.c && dst.w == x.w && to.of_x.end <= x.h && to.at + to.of_x.len() <= dst.h);
        if let Some(r) = residual {
            assert!(r.c == self.cout && (r.w, r.h) == (dst.w, dst.h));
        }
        let dn = dst.w * dst.h;
        let out = dst.data[offset * dn..(offset + self.cout) * dn].as_mut_ptr() as usize;
        // One task per output row; rows write disjoint pixels of every output plane.
        to.of_x.clone().into_par_iter().for_each(|y| {
            // SAFETY: AVX-512F is present (checked above), and each task writes only row
            // y − start + at of the cout output planes, which lie inside `dst`.
            #[cfg(target_arch = "x86_64")]
            unsafe {
                let out_y = y - to.of_x.start + to.at;
                let residual = residual.map(|r| r.data[out_y * x.w..].as_ptr());
                self.row(x, y, ((out as *mut f32).add(out_y * x.w), dn), relu, residual)
            }
            #[cfg(not(target_arch = "x86_64"))]
            let _ = (y, out);
        });
    }

    /// Row y (of x's grid) of every block: output channel co's row goes to `out.0 + co·out.1`,
    /// plus the residual's row at `residual + co·out.1`.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn row(&self, x: &Map, y: usize, (out, dn): (*mut f32, usize), relu: bool, residual: Option<*const f32>) {
        use std::arch::x86_64::*;
        let (w, n) = (x.w, x.w * x.h);
        let taps = self.kh * self.kw;
        PANEL.with(|cell| {
            let mut panel = cell.borrow_mut();
            // A 1×1 convolution reads its row in place (it needs no neighbours); the others
            // read a panel of the rows they need.
            let pointwise = taps == 1;
            let stride = if pointwise { 0 } else { self.fill_panel(x, y, &mut panel) };
            let zero = _mm512_setzero_ps();
            for x0 in (0..w).step_by(SEGMENT) {
                let mut store = [0u16; VECTORS];
                for (v, mask) in store.iter_mut().enumerate() {
                    *mask = lane_mask(x0 + 16 * v, 0, w);
                }
                for block in 0..self.cout.div_ceil(BLOCK) {
                    let bias = &self.bias[block * BLOCK..][..BLOCK];
                    let mut acc = [[zero; VECTORS]; BLOCK];
                    for (r, lanes) in acc.iter_mut().enumerate() {
                        *lanes = [_mm512_set1_ps(bias[r]); VECTORS];
                    }
                    let block_weights = self.weights.as_ptr().add(block * self.cin * taps * BLOCK);
                    if pointwise {
                        for ci in 0..self.cin {
                            let row = x.data.as_ptr().add(ci * n + y * w).wrapping_add(x0);
                            let wt = block_weights.add(ci * BLOCK);
                            let mut v = [zero; VECTORS];
                            for (k, lanes) in v.iter_mut().enumerate() {
                                *lanes = _mm512_maskz_loadu_ps(store[k], row.wrapping_add(16 * k));
                            }
                            for (r, lanes) in acc.iter_mut().enumerate() {
                                let wr = _mm512_set1_ps(*wt.add(r));
                                for (a, xv) in lanes.iter_mut().zip(&v) {
                                    *a = _mm512_fmadd_ps(wr, *xv, *a);
                                }
                            }
                        }
                    }
                    for ci in (0..self.cin).filter(|_| !pointwise) {
                        for ky in 0..self.kh {
                            // Panel row (ci, ky) starts pw zeros left of the image row.
                            let row = panel.as_ptr().add((ci * self.kh + ky) * stride + x0);
                            for kx in 0..self.kw {
                                let wt = block_weights.add(((ci * self.kh + ky) * self.kw + kx) * BLOCK);
                                let mut v = [zero; VECTORS];
                                for (k, lanes) in v.iter_mut().enumerate() {
                                    *lanes = _mm512_loadu_ps(row.add(16 * k + kx * self.dil));
                                }
                                for (r, lanes) in acc.iter_mut().enumerate() {
                                    let wr = _mm512_set1_ps(*wt.add(r));
                                    for (a, xv) in lanes.iter_mut().zip(&v) {
                                        *a = _mm512_fmadd_ps(wr, *xv, *a);
                                    }
                                }
                            }
                        }
                    }
                    // Store the block's real channels: bias included, then ReLU, then the residual.
                    for (r, lanes) in acc.iter().enumerate() {
                        let co = block * BLOCK + r;
                        if co >= self.cout {
                            break;
                        }
                        let dst = out.add(co * dn + x0);
                        for (k, a) in lanes.iter().enumerate() {
                            let mut value = if relu { _mm512_max_ps(*a, zero) } else { *a };
                            if let Some(res) = residual {
                                let src = res.add(co * dn).wrapping_add(x0 + 16 * k);
                                value = _mm512_add_ps(value, _mm512_maskz_loadu_ps(store[k], src));
                            }
                            _mm512_mask_storeu_ps(dst.wrapping_add(16 * k), store[k], value);
                        }
                    }
                }
            }
        });
    }

    /// Copies the input rows output row `y` reads into `panel`: for each input channel and row
    /// tap, the image row (zeros above or below the image) with `pw` zeros on its left and
    /// enough on its right for whole segments. One contiguous block, so the planes' large
    /// power-of-two strides do not make their rows compete for the same cache sets. Returns
    /// the panel's row stride.
    fn fill_panel(&self, x: &Map, y: usize, panel: &mut Vec<f32>) -> usize {
        let (w, h) = (x.w, x.h);
        let (ph, pw) = ((self.kh - 1) / 2 * self.dil, (self.kw - 1) / 2 * self.dil);
        let stride = w.div_ceil(SEGMENT) * SEGMENT + 2 * pw;
        panel.resize(self.cin * self.kh * stride, 0.0);
        for ci in 0..self.cin {
            for ky in 0..self.kh {
                let dst = &mut panel[(ci * self.kh + ky) * stride..][..stride];
                match (y + ky * self.dil).checked_sub(ph).filter(|&sy| sy < h) {
                    Some(sy) => {
                        dst[..pw].fill(0.0);
                        dst[pw..pw + w].copy_from_slice(&x.data[(ci * h + sy) * w..][..w]);
                        dst[pw + w..].fill(0.0);
                    }
                    None => dst.fill(0.0),
                }
            }
        }
        stride
    }
}

thread_local! {
    /// Each worker's panel of input rows, reused across rows and layers.
    static PANEL: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// The lanes i of the 16-pixel vector starting at pixel `x` of a `w`-wide row whose source
/// pixel x + i + dx lies in [0, w), as a bit mask (bit i for lane i).
fn lane_mask(x: usize, dx: isize, w: usize) -> u16 {
    let mut mask = 0u16;
    for i in 0..16 {
        let out = x + i;
        let src = out as isize + dx;
        if out < w && src >= 0 && (src as usize) < w {
            mask |= 1 << i;
        }
    }
    mask
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::feature_map::{convolution_by_definition, test_convolution, test_value};

    #[test]
    fn lane_masks_cover_exactly_the_pixels_inside_the_row() {
        assert_eq!(lane_mask(0, 0, 40), 0xffff);
        assert_eq!(lane_mask(32, 0, 40), 0x00ff, "pixels 40.. are past the row");
        assert_eq!(lane_mask(0, -2, 40), 0xfffc, "pixels 0 and 1 read left of the row");
        assert_eq!(lane_mask(16, 2, 40), 0xffff);
        assert_eq!(lane_mask(32, 2, 40), 0x003f, "pixels 38 and 39 read past it");
    }

    /// The kernel against a plain loop of the convolution's definition, on sizes that leave
    /// partial segments and blocks, with every tap shape the network has.
    #[test]
    fn direct_convolution_equals_the_definition() {
        if !available() {
            eprintln!("no AVX-512F here: the direct kernel is not used on this CPU");
            return;
        }
        for (cin, cout, kh, kw, dil, w, h) in [
            (5, 7, 3, 3, 1, 37, 9),
            (4, 6, 3, 3, 2, 70, 5),
            (3, 13, 1, 5, 1, 19, 4),
            (6, 2, 5, 1, 1, 65, 7),
            (8, 3, 1, 1, 1, 16, 3),
        ] {
            let n = w * h;
            let (rows, bias, x) = test_convolution(cin, cout, kh * kw, w, h);
            let res = Map { w, h, c: cout, data: (0..cout * n).map(|i| test_value(i, 4)).collect() };
            let conv = DirectWeights::new(cin, cout, (kh, kw, dil), &rows, &bias);
            for (relu, residual) in [(false, None), (true, Some(&res))] {
                let mut dst = Map { w, h, c: cout + 2, data: vec![9.0; (cout + 2) * n] };
                conv.apply_rows(&x, Rows { of_x: 0..h, at: 0 }, &mut dst, 1, relu, residual);
                let want = convolution_by_definition(&x, (&rows, &bias), (kh, kw, dil), relu);
                for co in 0..cout {
                    for p in 0..n {
                        let sum = want.data[co * n + p] + residual.map_or(0.0, |r| r.data[co * n + p]);
                        let got = dst.data[(1 + co) * n + p];
                        let (px, py) = (p % w, p / w);
                        assert!((got - sum).abs() < 1e-4, "{cin}->{cout} {kh}x{kw} d{dil}: ({px},{py}) {got} vs {sum}");
                    }
                }
                // The planes around the written ones are untouched.
                assert!(dst.data[..n].iter().chain(&dst.data[(cout + 1) * n..]).all(|v| *v == 9.0));
                // Rows [1, h − 1) alone, stored from row 2 of a taller map: the same values,
                // and nothing else written.
                let rows = if h > 2 { 1..h - 1 } else { 0..h };
                let mut tall = Map { w, h: h + 3, c: cout, data: vec![7.0; cout * w * (h + 3)] };
                // The residual, on the taller map's grid: row y of x's grid is row y + 2 − start.
                let mut res_tall = Map { w, h: h + 3, c: cout, data: vec![0.0; cout * w * (h + 3)] };
                for co in 0..cout {
                    res_tall.data[(co * (h + 3) + 2 - rows.start) * w..][..n].copy_from_slice(&res.data[co * n..][..n]);
                }
                let residual = residual.map(|_| &res_tall);
                conv.apply_rows(&x, Rows { of_x: rows.clone(), at: 2 }, &mut tall, 0, relu, residual);
                for co in 0..cout {
                    for y in 0..h + 3 {
                        let got = &tall.data[(co * (h + 3) + y) * w..][..w];
                        match (y >= 2).then(|| y - 2 + rows.start).filter(|sy| rows.contains(sy)) {
                            Some(sy) => assert_eq!(
                                got,
                                &dst.data[(1 + co) * n + sy * w..][..w],
                                "{cin}->{cout} {kh}x{kw} relu {relu} co {co} row {sy}"
                            ),
                            None => assert!(got.iter().all(|v| *v == 7.0), "row {y} of the taller map was written"),
                        }
                    }
                }
            }
        }
    }
}
