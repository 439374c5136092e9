//! The fast path's layers that are not convolutions, on planar (CHW) feature maps: 3×3
//! stride-1 max and min pooling (the inception blocks' pooled branches), 2×2 max-pool
//! downsampling between encoder levels, and the decoders' nearest 2× upsampling.

use rayon::prelude::*;

use crate::feature_map::{Map, Scratch};

/// 3×3 stride-1 max and min pooling over the valid neighbours, separably per plane, of rows
/// `rows` of x: planes [0, c) of the result hold the max, [c, 2c) the min, one row per row.
pub(crate) fn pool3_max_min(x: &Map, rows: std::ops::Range<usize>, scratch: &mut Scratch) -> Map {
    let mut out = scratch.map(x.w, rows.len(), 2 * x.c);
    let (w, h, n, on) = (x.w, x.h, x.w * x.h, x.w * rows.len());
    let (maxes, mins) = out.data.split_at_mut(x.c * on);
    let tasks = maxes.par_chunks_mut(on).map(|p| (p, true)).chain(mins.par_chunks_mut(on).map(|p| (p, false)));
    tasks.enumerate().for_each(|(task, (dst, is_max))| {
        let plane = &x.data[(task % x.c) * n..][..n];
        // Plain comparisons (inputs are finite), which map to single vector instructions.
        if is_max {
            pool3(plane, (w, h), rows.clone(), dst, |a, b| if a > b { a } else { b });
        } else {
            pool3(plane, (w, h), rows.clone(), dst, |a, b| if a < b { a } else { b });
        }
    });
    out
}

/// Rows `rows` of one plane's 3×3 extreme under `pick` (max or min; generic, so each is
/// compiled to vector code), over the valid neighbours: the clamped row indices and the
/// shorter edge windows leave out what lies outside the plane.
#[inline(always)]
fn pool3(
    plane: &[f32],
    (w, h): (usize, usize),
    rows: std::ops::Range<usize>,
    dst: &mut [f32],
    pick: impl Fn(f32, f32) -> f32 + Copy,
) {
    let mut line = vec![0.0f32; w];
    let y0 = rows.start;
    for y in rows {
        // Vertical extreme over rows y−1..=y+1 (the row itself stands in for a missing one).
        let mid = &plane[y * w..][..w];
        let up = &plane[y.saturating_sub(1) * w..][..w];
        let down = &plane[(y + 1).min(h - 1) * w..][..w];
        for (((l, m), u), d) in line.iter_mut().zip(mid).zip(up).zip(down) {
            *l = pick(pick(*m, *u), *d);
        }
        // Horizontal extreme over columns x−1..=x+1.
        let row = &mut dst[(y - y0) * w..][..w];
        if w == 1 {
            row[0] = line[0];
            continue;
        }
        row[0] = pick(line[0], line[1]);
        row[w - 1] = pick(line[w - 1], line[w - 2]);
        for ((r, a), (b, c)) in row[1..w - 1].iter_mut().zip(&line[..w - 2]).zip(line[1..].iter().zip(&line[2..])) {
            *r = pick(pick(*a, *b), *c);
        }
    }
}

/// 2×2 stride-2 max pooling (even sizes).
pub(crate) fn downsample(x: &Map, scratch: &mut Scratch) -> Map {
    let (w, h) = (x.w / 2, x.h / 2);
    let mut out = scratch.map(w, h, x.c);
    out.data.par_chunks_mut(w * h).enumerate().for_each(|(c, plane)| {
        let src = &x.data[c * x.w * x.h..][..x.w * x.h];
        for (y, row) in plane.chunks_exact_mut(w).enumerate() {
            let (a, b) = (&src[2 * y * x.w..][..x.w], &src[(2 * y + 1) * x.w..][..x.w]);
            for (px, v) in row.iter_mut().enumerate() {
                *v = a[2 * px].max(a[2 * px + 1]).max(b[2 * px]).max(b[2 * px + 1]);
            }
        }
    });
    out
}

/// `dst = relu(dst + nearest 2× upsampling of x)`, where `dst` holds rows [y0, y0 + dst.h) of
/// a map twice x's size (same channels).
pub(crate) fn add_upsampled_relu(x: &Map, dst: &mut Map, y0: usize) {
    let n = dst.w * dst.h;
    dst.data.par_chunks_mut(n).enumerate().for_each(|(c, plane)| {
        let src = &x.data[c * x.w * x.h..][..x.w * x.h];
        for (y, row) in plane.chunks_exact_mut(dst.w).enumerate() {
            let s = &src[((y0 + y) / 2) * x.w..][..x.w];
            for (px, d) in row.iter_mut().enumerate() {
                *d = (*d + s[px / 2]).max(0.0);
            }
        }
    });
}
