//! Kernel-predicting output (Bako et al. 2017; multi-scale as Vogels et al. 2018): instead of
//! predicting the denoised colour, each decoder level predicts, per pixel, a normalised
//! K×K kernel that averages the noisy colour at that level's resolution, and the levels are
//! blended coarse to fine by a predicted per-pixel weight. The output is then a positive
//! combination of the noisy samples, which KPCN found to train faster and more stably on
//! small data than direct prediction.

use burn::module::Module;
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::tensor::activation::{sigmoid, softmax};
use burn::tensor::{Device, Tensor};
use rayon::prelude::*;

use crate::feature_map::{Map, Scratch};
use crate::tensor_ops::conv1x1;
use crate::upsample::upsample2;
use crate::vector_math::{exp_m1_row, exp_nonpositive, ln_1p_row, logistic, multiversioned};

/// The side of each predicted kernel unless the model's config says otherwise
/// ([`crate::model::DenoiserConfig::kernel_size`]).
pub const DEFAULT_KERNEL_SIZE: usize = 5;
/// The widest kernel a model may predict (odd sides from 3 up to this).
pub const MAX_KERNEL_SIZE: usize = 9;

/// The kernel and blend heads, one of each per resolution level (the coarsest has no blend).
#[derive(Module, Debug)]
pub struct KernelOutput {
    /// Per level, a 1×1 convolution from the level's decoder features to K² kernel logits.
    pub(crate) kernels: Vec<Conv2d>,
    /// Per level but the coarsest, a 1×1 convolution to the logit of the coarse level's weight.
    pub(crate) blends: Vec<Conv2d>,
    /// Whether the coarser level's correction is upsampled bilinearly (else by nearest
    /// neighbour, whose 2×2 blocks nest into visible 4×4 ones where the correction is large);
    /// from [`crate::model::DenoiserConfig::blends_bilinearly`]. Not a weight.
    pub(crate) bilinear: bool,
    /// The side K of every level's kernels (odd); from
    /// [`crate::model::DenoiserConfig::kernel_size`]. Not a weight.
    pub(crate) size: usize,
}

impl KernelOutput {
    /// Heads predicting `size`×`size` kernels for levels of `channels` channels, full
    /// resolution first, blending through bilinear upsampling if `bilinear`, else nearest.
    pub fn new(channels: &[usize], bilinear: bool, size: usize, device: &Device) -> Self {
        let k2 = size * size;
        let one = |cin: usize, cout: usize| Conv2dConfig::new([cin, cout], [1, 1]).init(device);
        KernelOutput {
            kernels: channels.iter().map(|&c| one(c, k2)).collect(),
            blends: channels[..channels.len() - 1].iter().map(|&c| one(c, 1)).collect(),
            bilinear,
            size,
        }
    }

    /// Multiply-accumulates per full-resolution pixel of `size`×`size` kernels: the heads and
    /// the kernels' application to three colour channels, at each level's share of the pixels.
    pub fn macs(channels: &[usize], size: usize) -> f64 {
        let k2 = size * size;
        let level = |l: usize, c: usize| {
            let blend = if l + 1 < channels.len() { c } else { 0 };
            (c * k2 + blend + 3 * k2) as f64 / (1u64 << (2 * l)) as f64
        };
        channels.iter().enumerate().map(|(l, &c)| level(l, c)).sum()
    }

    /// How far (in full-resolution pixels) `size`×`size` heads reach beyond the features: the
    /// coarsest kernel's half-width at its scale, plus the box pyramid.
    pub fn radius(levels: usize, size: usize) -> usize {
        let coarse = 1 << (levels - 1);
        size / 2 * coarse + coarse
    }

    /// `noisy`: [N, 3, H, W] encoded noisy colour (ln(1 + x·exposure), see
    /// [`crate::encode::encode_color`]); `features`: each level's decoder output, full
    /// resolution first → [N, 3, H, W] encoded colour.
    pub fn forward(&self, noisy: Tensor<4>, features: &[Tensor<4>]) -> Tensor<4> {
        // Kernels average linear (exposed) colour, so the mean is kept; the log encoding only
        // frames the input and output.
        let mut level = noisy.clamp(0.0, crate::encode::MAX_EXPOSED.ln_1p()).exp().sub_scalar(1.0);
        let mut filtered = Vec::with_capacity(features.len());
        for (l, f) in features.iter().enumerate() {
            if l > 0 {
                level = box_down2(level);
            }
            let weights = softmax(conv1x1(&self.kernels[l], f.clone()), 1); // [N, K², H/2^l, W/2^l]
            filtered.push(apply_kernels(level.clone(), weights, self.size));
        }
        // Coarse to fine: a level's own low band (its 2× box mean, upsampled) is replaced by the
        // coarser result in the proportion the blend head predicts.
        let mut out = filtered.pop().expect("at least one level");
        for (l, fine) in filtered.into_iter().enumerate().rev() {
            let alpha = sigmoid(conv1x1(&self.blends[l], features[l].clone())); // [N, 1, h, w]
            out = if self.bilinear {
                // The same, upsampling the difference once (upsampling is linear).
                let correction = out - box_down2(fine.clone()); // [N, 3, h/2, w/2]
                fine + upsample_bilinear2(correction) * alpha
            } else {
                let low = upsample2(box_down2(fine.clone()));
                fine + (upsample2(out) - low) * alpha
            };
        }
        out.clamp_min(0.0).add_scalar(1.0).log()
    }
}

/// The mean of each 2×2 block: [N, C, H, W] → [N, C, H/2, W/2].
fn box_down2(x: Tensor<4>) -> Tensor<4> {
    let [n, c, h, w] = x.dims();
    x.reshape([n, c, h / 2, 2, w / 2, 2]).mean_dim(5).mean_dim(3).reshape([n, c, h / 2, w / 2])
}

/// Bilinear 2× upsampling with half-pixel centres and edges clamped: nearest upsampling, then
/// the [1, 2, 1] / 4 filter along each axis (edges replicated), which gives each output pixel
/// ¾ of its source pixel and ¼ of the neighbour on its side, per axis.
fn upsample_bilinear2(x: Tensor<4>) -> Tensor<4> {
    let up = upsample2(x);
    let [_, _, h, w] = up.dims();
    let p = pad_replicate(up, 1); // [N, C, h + 2, w + 2]
    let tent = |t: Tensor<4>, dim: usize, len: usize| {
        (t.clone().narrow(dim, 0, len) + t.clone().narrow(dim, 2, len)) * 0.25 + t.narrow(dim, 1, len) * 0.5
    };
    tent(tent(p, 3, w), 2, h)
}

/// Edge-replicated padding of `p` pixels on every side.
fn pad_replicate(x: Tensor<4>, p: usize) -> Tensor<4> {
    let [n, c, h, w] = x.dims();
    let top = x.clone().narrow(2, 0, 1).expand([n, c, p, w]);
    let bottom = x.clone().narrow(2, h - 1, 1).expand([n, c, p, w]);
    let x = Tensor::cat(vec![top, x, bottom], 2);
    let left = x.clone().narrow(3, 0, 1).expand([n, c, h + 2 * p, p]);
    let right = x.clone().narrow(3, w - 1, 1).expand([n, c, h + 2 * p, p]);
    Tensor::cat(vec![left, x, right], 3)
}

/// Per-pixel K×K kernels (K = `size`) applied to every channel:
/// out(y, x) = Σ_(i,j) w_(i,j)(y, x) · in(y + i − r, x + j − r), with `weights` [N, K², H, W]
/// in row-major tap order and `x` [N, C, H, W] edge-replicated.
fn apply_kernels(x: Tensor<4>, weights: Tensor<4>, size: usize) -> Tensor<4> {
    let [_, _, h, w] = x.dims();
    let padded = pad_replicate(x, size / 2);
    let mut sum: Option<Tensor<4>> = None;
    for i in 0..size {
        for j in 0..size {
            let tap = padded.clone().narrow(2, i, h).narrow(3, j, w);
            let wt = weights.clone().narrow(1, i * size + j, 1);
            let term = tap * wt;
            sum = Some(match sum {
                Some(s) => s + term,
                None => term,
            });
        }
    }
    sum.expect("a kernel has taps")
}

/// The noisy colour as the kernels average it, in a map from `scratch`: linear (exposed)
/// values, `exp(y) − 1` of the three encoded colour planes of a `w`×`h` image `noisy`, clamped
/// as [`KernelOutput::forward`] clamps them. The finest level's input.
pub fn exposed_colour(noisy: &[f32], (w, h): (usize, usize), scratch: &mut Scratch) -> Map {
    let top = crate::encode::MAX_EXPOSED.ln_1p();
    let mut level = scratch.map(w, h, 3);
    level.data.par_chunks_mut(w).zip(noisy[..3 * w * h].par_chunks(w)).for_each(|(dst, src)| exp_m1_row(dst, src, top));
    level
}

/// One level's kernels, applied to rows as their logits come: the level's three colour planes
/// with every row edge-padded by the kernel's reach, so that a tap's shifted row is a slice.
/// The fast path filters the finest level band by band inside its last decoder, so that the
/// K² + 1 logit planes never exist for the whole tile.
pub struct RowFilter {
    /// The three planes, rows of `w + 2r` (r = size / 2), `h` rows each.
    padded: Map,
    w: usize,
    h: usize,
    size: usize,
}

impl RowFilter {
    /// The filter of K×K kernels (K = `size`) over `img`'s three planes, its padded rows in a
    /// map from `scratch` (give it back with [`RowFilter::recycle`]).
    pub fn new(img: &Map, size: usize, scratch: &mut Scratch) -> Self {
        let (w, h, r) = (img.w, img.h, size / 2);
        let pw = w + 2 * r;
        let mut padded = scratch.map(pw, h, 3);
        padded.data.par_chunks_mut(pw).zip(img.data[..3 * w * h].par_chunks(w)).for_each(|(dst, src)| {
            dst[..r].fill(src[0]);
            dst[r..r + w].copy_from_slice(src);
            dst[r + w..].fill(src[w - 1]);
        });
        RowFilter { padded, w, h, size }
    }

    /// Filters rows [y0, y0 + logits.h) into planes 0–2 of `out` (the level's size): each
    /// pixel's softmax-normalised kernel from the first K² planes of `logits`, whose row 0 is
    /// row y0 (any further planes are not read).
    pub fn filter_rows(&self, logits: &Map, y0: usize, out: &mut Map) {
        let (w, h, size) = (self.w, self.h, self.size);
        assert!(logits.w == w && logits.c >= size * size && out.w == w && out.h == h && y0 + logits.h <= h);
        let source = (&self.padded.data[..], w + size / 2 * 2, size, h);
        rgb_rows(&mut out.data, w, h).enumerate().skip(y0).take(logits.h).for_each_init(
            || (vec![0.0f32; size * size * w], vec![0.0f32; w]),
            |(taps, norm), (y, dst)| filter_row((logits, y - y0), source, y, (taps, norm), dst),
        );
    }

    /// [`RowFilter::filter_rows`], then the blend logit (plane K² of `logits`, which the finest
    /// level of a network of several has) copied to the same rows of plane 3 of `out`.
    pub fn filter_band(&self, logits: &Map, y0: usize, out: &mut Map) {
        self.filter_rows(logits, y0, out);
        let (w, h, k2) = (self.w, self.h, self.size * self.size);
        if logits.c > k2 {
            let from = &logits.data[k2 * logits.h * w..][..logits.h * w];
            out.data[(3 * h + y0) * w..(3 * h + y0 + logits.h) * w].copy_from_slice(from);
        }
    }

    /// Gives the padded rows back to `scratch`.
    pub fn recycle(self, scratch: &mut Scratch) {
        scratch.recycle(self.padded);
    }
}

/// The fast path's [`KernelOutput::forward`] on planar maps, after the finest level's filter:
/// `level` is the finest level's [`exposed_colour`], `finest` its filtered colour (planes 0–2)
/// and, with coarser levels, its blend logit (plane 3), as [`RowFilter::filter_band`] writes
/// them, and `coarse[l − 1]` the heads' outputs at level l ≥ 1 (K² kernel logits, then the
/// blend logit at every level but the coarsest). `bilinear` and `size` (K) are
/// [`KernelOutput`]'s fields of those names. Returns the three encoded output planes (in
/// `finest`'s buffer); every image-sized buffer comes from and goes back to `scratch`, so
/// repeated calls touch no fresh memory (only the row-sized scratch of each task is allocated
/// anew).
pub fn blend_levels(
    mut level: Map,
    finest: Map,
    coarse: &[Map],
    (bilinear, size): (bool, usize),
    scratch: &mut Scratch,
) -> Map {
    let mut filtered = Vec::with_capacity(coarse.len() + 1);
    filtered.push(finest);
    for lg in coarse {
        let down = box_down2_planar(&level, scratch);
        scratch.recycle(std::mem::replace(&mut level, down));
        filtered.push(filter_planar(&level, lg, size, scratch));
    }
    scratch.recycle(level);
    // Coarse to fine, as the burn version blends.
    let mut out = filtered.pop().expect("at least one level");
    for (l, mut fine) in filtered.into_iter().enumerate().rev() {
        let (lw, lh) = (fine.w, fine.h);
        // The coarser result's difference from this level's own low band, once per coarse pixel.
        let mut correction = box_down2_planar(&fine, scratch);
        correction.data.par_chunks_mut(lw / 2).zip(out.data.par_chunks(lw / 2)).for_each(|(low, o)| {
            low.iter_mut().zip(o).for_each(|(l, o)| *l = o - *l);
        });
        // Its rows doubled along x once, for the two output rows that read each.
        let wide = widen_rows(&correction, bilinear, scratch);
        scratch.recycle(correction);
        let (rgb, rest) = fine.data.split_at_mut(3 * lw * lh);
        let blend = match l {
            0 => &rest[..lw * lh],
            _ => &coarse[l - 1].data[size * size * lw * lh..][..lw * lh],
        };
        let up = (&wide.data[..], wide.w, wide.h);
        rgb_rows(rgb, lw, lh).enumerate().for_each_init(
            || vec![0.0f32; lw],
            |alpha, (y, dst)| blend_row(dst, &blend[y * lw..][..lw], up, y, bilinear, alpha),
        );
        scratch.recycle(wide);
        scratch.recycle(std::mem::replace(&mut out, fine));
    }
    // The finest map's blend plane is not part of the result.
    out.c = 3;
    out.data.truncate(3 * out.w * out.h);
    out.data.par_chunks_mut(out.w).for_each(ln_1p_row);
    out
}

multiversioned! {
    /// Adds to `dst`, row y of the three channels at a level, the coarser level's correction
    /// upsampled to it, weighted by the logistic of the row's `blend` logits. `wide` holds the
    /// correction's rows already doubled along x by [`widen_rows`] (three planes of w × ch);
    /// `alpha` is a row of scratch for the weights.
    fn blend_row(
        dst: [&mut [f32]; 3],
        blend: &[f32],
        wide: (&[f32], usize, usize),
        y: usize,
        bilinear: bool,
        alpha: &mut [f32],
    ) {
        let (wide, w, ch) = wide;
        // Logistic weight of the coarser level's band over this level's own, once per pixel.
        alpha.iter_mut().zip(blend).for_each(|(a, &b)| *a = logistic(b));
        // Bilinear: ¾ of the source row and ¼ of the neighbouring one on this row's side.
        let far_y = if y.is_multiple_of(2) { (y / 2).saturating_sub(1) } else { (y / 2 + 1).min(ch - 1) };
        for (c, out) in dst.into_iter().enumerate() {
            let at = |cy: usize| &wide[(c * ch + cy) * w..][..w];
            let (near, far) = (at(y / 2), at(far_y));
            if bilinear {
                for ((v, &a), (&n, &f)) in out.iter_mut().zip(alpha.iter()).zip(near.iter().zip(far)) {
                    *v += (0.75 * n + 0.25 * f) * a;
                }
            } else {
                out.iter_mut().zip(alpha.iter()).zip(near).for_each(|((v, &a), &n)| *v += n * a);
            }
        }
    }
}

/// The three planes of `coarse` with every row doubled along x, into a map from `scratch`: by
/// the bilinear tent if `bilinear` (each output pixel ¾ of its source pixel and ¼ of the
/// neighbour on its side, the ends clamped), else by repeating each pixel.
fn widen_rows(coarse: &Map, bilinear: bool, scratch: &mut Scratch) -> Map {
    let mut wide = scratch.map(2 * coarse.w, coarse.h, 3);
    wide.data.par_chunks_mut(2 * coarse.w).zip(coarse.data.par_chunks(coarse.w)).for_each(|(dst, src)| {
        let last = src.len() - 1;
        for (cx, pair) in dst.chunks_exact_mut(2).enumerate() {
            if bilinear {
                pair[0] = 0.75 * src[cx] + 0.25 * src[cx.saturating_sub(1)];
                pair[1] = 0.75 * src[cx] + 0.25 * src[(cx + 1).min(last)];
            } else {
                pair.fill(src[cx]);
            }
        }
    });
    wide
}

/// Row y of each of three w × h planes, together: `[red, green, blue]` per item, in parallel.
fn rgb_rows(planes: &mut [f32], w: usize, h: usize) -> impl IndexedParallelIterator<Item = [&mut [f32]; 3]> {
    let (red, rest) = planes[..3 * w * h].split_at_mut(w * h);
    let (green, blue) = rest.split_at_mut(w * h);
    red.par_chunks_mut(w).zip(green.par_chunks_mut(w)).zip(blue.par_chunks_mut(w)).map(|((r, g), b)| [r, g, b])
}

/// The mean of each 2×2 block of the three planes of `img` (both sides even), in a map from
/// `scratch`.
fn box_down2_planar(img: &Map, scratch: &mut Scratch) -> Map {
    let (w, h) = (img.w, img.h);
    let (hw, hh) = (w / 2, h / 2);
    let mut out = scratch.map(hw, hh, 3);
    out.data.par_chunks_mut(hw).enumerate().for_each(|(row, dst)| {
        let (c, y) = (row / hh, row % hh);
        let upper = &img.data[(c * h + 2 * y) * w..][..w];
        let lower = &img.data[(c * h + 2 * y + 1) * w..][..w];
        for (i, v) in dst.iter_mut().enumerate() {
            *v = ((upper[2 * i] + upper[2 * i + 1]) * 0.5 + (lower[2 * i] + lower[2 * i + 1]) * 0.5) * 0.5;
        }
    });
    out
}

/// Each pixel's softmax-normalised K×K kernel (K = `size`, from the first K² planes of
/// `logits`) applied to the three planes of `img`, which has the logits' size, with edges
/// replicated; into a map from `scratch`. Row by row, every loop runs along the row, so the
/// compiler vectorises it.
fn filter_planar(img: &Map, logits: &Map, size: usize, scratch: &mut Scratch) -> Map {
    let filter = RowFilter::new(img, size, scratch);
    let mut out = scratch.map(img.w, img.h, 3);
    filter.filter_rows(logits, 0, &mut out);
    filter.recycle(scratch);
    out
}

multiversioned! {
    /// Row `y` of [`RowFilter::filter_rows`]: the three channels' filtered rows into `dst`, from
    /// row `ly` of `logits` and the `padded` source planes (rows of `pw`, `h` rows each) with
    /// K×K kernels, with `taps` (K² rows) and `norm` (one) as scratch.
    fn filter_row(
        logits: (&Map, usize),
        padded: (&[f32], usize, usize, usize),
        y: usize,
        scratch: (&mut [f32], &mut [f32]),
        dst: [&mut [f32]; 3],
    ) {
        let (logits, ly) = logits;
        let (w, lh) = (logits.w, logits.h);
        let (padded, pw, size, h) = padded;
        let (taps, norm) = scratch;
        let (k2, r) = (size * size, size / 2);
        // Softmax over the taps, per pixel: exp(logit − max) / Σ.
        let tap_row = |t: usize| &logits.data[(t * lh + ly) * w..][..w];
        norm.copy_from_slice(tap_row(0));
        for t in 1..k2 {
            norm.iter_mut().zip(tap_row(t)).for_each(|(m, &v)| *m = m.max(v));
        }
        for t in 0..k2 {
            let e = &mut taps[t * w..][..w];
            e.iter_mut().zip(tap_row(t)).zip(norm.iter()).for_each(|((e, &v), &m)| *e = exp_nonpositive(v - m));
        }
        norm.fill(0.0);
        for t in 0..k2 {
            norm.iter_mut().zip(&taps[t * w..][..w]).for_each(|(s, &e)| *s += e);
        }
        norm.iter_mut().for_each(|s| *s = 1.0 / *s);
        // Σ over taps of weight × the source row shifted by the tap, edges replicated.
        for (c, out) in dst.into_iter().enumerate() {
            out.fill(0.0);
            for i in 0..size {
                let sy = (y + i).saturating_sub(r).min(h - 1);
                let src = &padded[(c * h + sy) * pw..][..pw];
                for j in 0..size {
                    let e = &taps[(i * size + j) * w..][..w];
                    out.iter_mut().zip(e).zip(&src[j..j + w]).for_each(|((o, &e), &v)| *o += e * v);
                }
            }
            out.iter_mut().zip(norm.iter()).for_each(|(o, &n)| *o *= n);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::TensorData;

    fn tensor(data: Vec<f32>, shape: [usize; 4]) -> Tensor<4> {
        Tensor::<4>::from_data(TensorData::new(data, shape), &Device::flex())
    }

    fn values(t: Tensor<4>) -> Vec<f32> {
        t.into_data().try_into_vec::<f32>().unwrap()
    }

    /// A one-hot kernel shifts the image by its tap's offset, with edges replicated, whatever
    /// the kernel's size.
    #[test]
    fn one_hot_kernels_shift_the_image() {
        let (h, w) = (4, 6);
        let img: Vec<f32> = (0..h * w).map(|i| i as f32).collect();
        for size in [3, DEFAULT_KERNEL_SIZE, 7] {
            let (k2, r) = (size * size, size / 2);
            // Tap (i, j) = (r, r + 1): one pixel to the right.
            let tap = r * size + r + 1;
            let mut weights = vec![0.0f32; k2 * h * w];
            weights[tap * h * w..][..h * w].fill(1.0);
            let out = values(apply_kernels(tensor(img.clone(), [1, 1, h, w]), tensor(weights, [1, k2, h, w]), size));
            for y in 0..h {
                for x in 0..w {
                    assert_eq!(out[y * w + x], img[y * w + (x + 1).min(w - 1)], "size {size}, pixel ({x}, {y})");
                }
            }
        }
    }

    /// Bilinear upsampling is ¾ of the source pixel and ¼ of its neighbour on the output
    /// pixel's side, per axis, with the edges clamped; on odd and one-pixel sizes too.
    #[test]
    fn bilinear_upsampling_matches_its_definition() {
        for (h, w) in [(3, 5), (1, 4), (2, 1), (1, 1)] {
            let src: Vec<f32> = (0..2 * h * w).map(|i| ((i * 7919) % 17) as f32 - 8.0).collect();
            let out = values(upsample_bilinear2(tensor(src.clone(), [1, 2, h, w])));
            let at = |c: usize, y: isize, x: isize| {
                src[(c * h + y.clamp(0, h as isize - 1) as usize) * w + x.clamp(0, w as isize - 1) as usize]
            };
            for c in 0..2 {
                for y in 0..2 * h {
                    for x in 0..2 * w {
                        let (sy, sx) = ((y / 2) as isize, (x / 2) as isize);
                        let (ny, nx) = (sy + if y % 2 == 0 { -1 } else { 1 }, sx + if x % 2 == 0 { -1 } else { 1 });
                        let row = |r| 0.75 * at(c, r, sx) + 0.25 * at(c, r, nx);
                        let want = 0.75 * row(sy) + 0.25 * row(ny);
                        let got = out[(c * 2 * h + y) * 2 * w + x];
                        assert!(
                            (got - want).abs() < 1e-5,
                            "{h}x{w} channel {c} pixel ({x}, {y}): {got} against {want}"
                        );
                    }
                }
            }
        }
    }

    /// Normalised kernels keep a flat image flat at every level, whatever the heads predict,
    /// so the output of a constant input is that constant (the encoding round-trips), with
    /// either upsampling in the blend and kernels of any size.
    #[test]
    fn a_flat_image_comes_out_unchanged() {
        for (bilinear, size) in [(false, DEFAULT_KERNEL_SIZE), (true, DEFAULT_KERNEL_SIZE), (true, 7)] {
            flat_stays_flat(bilinear, size);
        }
    }

    fn flat_stays_flat(bilinear: bool, size: usize) {
        let device = Device::flex();
        let channels = [4, 6, 8];
        let heads = KernelOutput::new(&channels, bilinear, size, &device);
        let (h, w) = (8, 12);
        let level = |l: usize, c: usize| {
            let (hh, ww) = (h >> l, w >> l);
            tensor((0..c * hh * ww).map(|i| ((i * 7919) % 13) as f32 / 3.0 - 2.0).collect(), [1, c, hh, ww])
        };
        let features: Vec<_> = channels.iter().enumerate().map(|(l, &c)| level(l, c)).collect();
        let encoded = (1.0f32 + 0.37).ln();
        let out = values(heads.forward(tensor(vec![encoded; 3 * h * w], [1, 3, h, w]), &features));
        for v in out {
            assert!((v - encoded).abs() < 1e-5, "{v} against {encoded}");
        }
    }
}
