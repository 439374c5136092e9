//! Planar (C×H×W) feature maps and the pool that recycles their buffers between layers and
//! tiles: the data both inference kernels ([`crate::fast`] and [`crate::direct`]) work on, and
//! the shifted-row gather their im2col (and training's, [`crate::same_conv`]) is built from.

/// A C×H×W feature map: one plane per channel.
#[derive(Clone, Debug)]
pub struct Map {
    /// Width in pixels.
    pub w: usize,
    /// Height in pixels.
    pub h: usize,
    /// Number of channels (planes).
    pub c: usize,
    /// Values, index (channel·h + y)·w + x.
    pub data: Vec<f32>,
}

/// Feature buffers recycled between layers and tiles, so a forward pass maps fresh memory
/// (and takes its page faults) only for its first few layers.
#[derive(Default)]
pub struct Scratch {
    free: Vec<Vec<f32>>,
}

impl Scratch {
    /// A w×h×c map whose contents are unspecified: every caller overwrites all of it.
    pub fn map(&mut self, w: usize, h: usize, c: usize) -> Map {
        let len = w * h * c;
        // The smallest free buffer that fits, else the largest (it will grow).
        let pick = (0..self.free.len())
            .filter(|&i| self.free[i].capacity() >= len)
            .min_by_key(|&i| self.free[i].capacity())
            .or_else(|| (0..self.free.len()).max_by_key(|&i| self.free[i].capacity()));
        let mut data = pick.map(|i| self.free.swap_remove(i)).unwrap_or_default();
        data.resize(len, 0.0);
        Map { w, h, c, data }
    }

    /// Returns a map's buffer to the pool.
    pub fn recycle(&mut self, m: Map) {
        self.free.push(m.data);
    }
}

/// Which output rows a convolution computes and where they go: rows `of_x` of its input's grid
/// (each read from the input rows around it), stored from row `at` of the destination.
#[derive(Clone, Debug)]
pub struct Rows {
    /// Output rows, in the input's row numbers.
    pub of_x: std::ops::Range<usize>,
    /// The destination row of the first.
    pub at: usize,
}

/// Fills `dst` with pixels p0, p0 + 1, … of a w-wide plane, each read at offset (dx, dy) from
/// itself, with zero where that falls outside the plane.
pub(crate) fn gather_shifted(plane: &[f32], w: usize, p0: usize, dx: isize, dy: isize, dst: &mut [f32]) {
    let (n, w, p0, len) = (plane.len() as isize, w as isize, p0 as isize, dst.len() as isize);
    // Pixels lo..hi (of dst) are those whose row, shifted by dy, is inside the plane: py + dy in
    // 0..h. Their sources p + dy·w + dx are one contiguous run, copied in one piece.
    let lo = (-dy * w - p0).clamp(0, len);
    let hi = ((n / w - dy) * w - p0).clamp(lo, len);
    let (lo, hi) = (lo as usize, hi as usize);
    dst[..lo].fill(0.0);
    dst[hi..].fill(0.0);
    if hi == lo {
        return;
    }
    // The run's two ends can leave the plane only through a column shift; those pixels are
    // cleared with the other out-of-column ones below.
    let (s0, s1) = (p0 + lo as isize + dy * w + dx, p0 + hi as isize + dy * w + dx);
    let (c0, c1) = (s0.max(0), s1.min(n));
    if c1 > c0 {
        let d0 = lo + (c0 - s0) as usize;
        dst[d0..d0 + (c1 - c0) as usize].copy_from_slice(&plane[c0 as usize..c1 as usize]);
    }
    if dx == 0 {
        return;
    }
    // Columns px with px + dx outside 0..w read the neighbouring row (or outside): zero them.
    let (bad0, bad1) = if dx > 0 { ((w - dx).max(0), w) } else { (0, (-dx).min(w)) };
    let (first, last) = (p0 + lo as isize, p0 + hi as isize);
    for row in first / w..=(last - 1) / w {
        let (a, b) = ((row * w + bad0).max(first) - p0, (row * w + bad1).min(last) - p0);
        if b > a {
            dst[a as usize..b as usize].fill(0.0);
        }
    }
}

/// Pixels per im2col work item: each item fills its own column buffer and runs one `gemm`
/// (the fast path's convolutions and training's, [`crate::same_conv`]).
pub(crate) const IM2COL_CHUNK: usize = 1024;

/// A raw pointer that parallel work items share, each writing only its own part of the buffer.
pub(crate) struct SendPtr(pub(crate) *mut f32);
unsafe impl Send for SendPtr {}
unsafe impl Sync for SendPtr {}
impl SendPtr {
    /// The pointer (a method, so closures capture the whole `Sync` wrapper, not its field).
    pub(crate) fn get(&self) -> *mut f32 {
        self.0
    }
}

/// The kernels' tests' reference: act(conv(x) + bias) straight from the definition, summed in
/// f64, for weights as rows (ky, kx, ci), columns co (the gemm layout) and zero padding: `cout`
/// (= `bias.len()`) planes of x's size.
#[cfg(test)]
pub(crate) fn convolution_by_definition(
    x: &Map,
    (rows, bias): (&[f32], &[f32]),
    (kh, kw, dil): (usize, usize, usize),
    relu: bool,
) -> Map {
    let (w, h, cin, cout, n) = (x.w, x.h, x.c, bias.len(), x.w * x.h);
    let (ph, pw) = ((kh - 1) / 2 * dil, (kw - 1) / 2 * dil);
    let mut out = Map { w, h, c: cout, data: vec![0.0; cout * n] };
    for co in 0..cout {
        for py in 0..h {
            for px in 0..w {
                let mut sum = f64::from(bias[co]);
                for ky in 0..kh {
                    for kx in 0..kw {
                        let sy = (py + ky * dil).checked_sub(ph).filter(|&sy| sy < h);
                        let sx = (px + kx * dil).checked_sub(pw).filter(|&sx| sx < w);
                        let (Some(sy), Some(sx)) = (sy, sx) else { continue };
                        for ci in 0..cin {
                            let weight = rows[((ky * kw + kx) * cin + ci) * cout + co];
                            sum += f64::from(weight) * f64::from(x.data[ci * n + sy * w + sx]);
                        }
                    }
                }
                out.data[co * n + py * w + px] = if relu { sum.max(0.0) } else { sum } as f32;
            }
        }
    }
    out
}

/// The kernels' tests' fixed value number `i` of stream `m`, in [-1, 1): weights (1), bias (2),
/// input (3), residual (4).
#[cfg(test)]
pub(crate) fn test_value(i: usize, m: usize) -> f32 {
    ((i * 7919 + m) % 1009) as f32 / 500.0 - 1.0
}

/// The kernels' tests' convolution: weights as rows (`taps` × cin, then cout), bias, and a
/// cin-plane w × h input, all from [`test_value`].
#[cfg(test)]
pub(crate) fn test_convolution(cin: usize, cout: usize, taps: usize, w: usize, h: usize) -> (Vec<f32>, Vec<f32>, Map) {
    let rows = (0..taps * cin * cout).map(|i| test_value(i, 1)).collect();
    let bias = (0..cout).map(|i| test_value(i, 2)).collect();
    let x = Map { w, h, c: cin, data: (0..cin * w * h).map(|i| test_value(i, 3)).collect() };
    (rows, bias, x)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shifted gather equals its per-pixel definition for runs that start and end mid-row,
    /// span one or many rows, and shift by less than, exactly and more than a row or the plane,
    /// into a buffer holding stale values (every value must be written).
    #[test]
    fn gather_shifted_equals_its_definition() {
        let (w, h) = (7usize, 5usize);
        let plane: Vec<f32> = (0..w * h).map(|i| i as f32 + 1.0).collect();
        let shifts = [-8isize, -7, -6, -3, -2, -1, 0, 1, 2, 3, 6, 7, 8];
        for (p0, len) in [(0, w * h), (3, 1), (3, 9), (10, 20), (0, 7), (28, 7), (33, 2)] {
            for &dx in &shifts {
                for &dy in &shifts {
                    let mut dst = vec![f32::NAN; len];
                    gather_shifted(&plane, w, p0, dx, dy, &mut dst);
                    let expected: Vec<f32> = (p0..p0 + len)
                        .map(|p| {
                            let (sx, sy) = ((p % w) as isize + dx, (p / w) as isize + dy);
                            let inside = (0..w as isize).contains(&sx) && (0..h as isize).contains(&sy);
                            if inside {
                                plane[sy as usize * w + sx as usize]
                            } else {
                                0.0
                            }
                        })
                        .collect();
                    assert_eq!(dst, expected, "p0 {p0} len {len} dx {dx} dy {dy}");
                }
            }
        }
    }
}
