//! A fast inference path for [`DenoiserNet`]: the same function evaluated on HWC feature maps
//! with im2col + the `gemm` crate, threaded over pixel chunks, and branch outputs written
//! straight into their slice of the concatenation. A test holds it to burn's output.

use gemm::{gemm, Parallelism};
use rayon::prelude::*;

use crate::model::{DenoiserNet, InceptionBlock};

/// An H×W×C feature map, channels fastest.
#[derive(Clone, Debug)]
pub struct Map {
    /// Width.
    pub w: usize,
    /// Height.
    pub h: usize,
    /// Channels.
    pub c: usize,
    /// Values, index (y·w + x)·c + channel.
    pub data: Vec<f32>,
}

impl Map {
    #[cfg(test)]
    fn zeros(w: usize, h: usize, c: usize) -> Self {
        Map { w, h, c, data: vec![0.0; w * h * c] }
    }
}

/// Feature buffers recycled between layers and tiles, so a forward pass maps fresh memory
/// (and takes its page faults) only for its first few layers.
#[derive(Default)]
pub struct Scratch {
    free: Vec<Vec<f32>>,
}

impl Scratch {
    /// A w×h×c map whose contents are unspecified: every caller overwrites all of it.
    fn map(&mut self, w: usize, h: usize, c: usize) -> Map {
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

/// A convolution's weights as a (kh·kw·cin) × cout matrix, plus its bias and geometry.
struct Conv {
    cin: usize,
    cout: usize,
    kh: usize,
    kw: usize,
    dil: usize,
    weights: Vec<f32>,
    bias: Vec<f32>,
}

thread_local! {
    /// Each worker's im2col buffer, reused across chunks and layers.
    static COL: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Pixels per work item: each item runs im2col and one gemm on its own buffer.
const CHUNK: usize = 1024;

struct SendPtr(*mut f32);
unsafe impl Send for SendPtr {}
unsafe impl Sync for SendPtr {}
impl SendPtr {
    fn get(&self) -> *mut f32 {
        self.0
    }
}

impl Conv {
    fn from(conv: &burn::nn::conv::Conv2d) -> Self {
        let [cout, cin, kh, kw] = conv.weight.val().dims();
        let w: Vec<f32> = conv.weight.val().into_data().convert::<f32>().try_to_vec::<f32>().expect("f32 weights");
        // Reorder [cout][cin][ky][kx] into rows (ky, kx, ci), columns co.
        let mut weights = vec![0.0; kh * kw * cin * cout];
        for co in 0..cout {
            for ci in 0..cin {
                for ky in 0..kh {
                    for kx in 0..kw {
                        weights[((ky * kw + kx) * cin + ci) * cout + co] = w[((co * cin + ci) * kh + ky) * kw + kx];
                    }
                }
            }
        }
        let bias = match &conv.bias {
            Some(b) => b.val().into_data().convert::<f32>().try_to_vec::<f32>().expect("f32 bias"),
            None => vec![0.0; cout],
        };
        Conv { cin, cout, kh, kw, dil: conv.dilation[0], weights, bias }
    }

    /// Two 1×1 convolutions side by side: [a_in, b_in] → [a(a_in), b(b_in)].
    fn block_diagonal(a: &Conv, b: &Conv) -> Self {
        assert!(a.kh == 1 && a.kw == 1 && b.kh == 1 && b.kw == 1);
        let (cin, cout) = (a.cin + b.cin, a.cout + b.cout);
        let mut weights = vec![0.0; cin * cout];
        for ci in 0..a.cin {
            weights[ci * cout..ci * cout + a.cout].copy_from_slice(&a.weights[ci * a.cout..(ci + 1) * a.cout]);
        }
        for ci in 0..b.cin {
            let row = (a.cin + ci) * cout + a.cout;
            weights[row..row + b.cout].copy_from_slice(&b.weights[ci * b.cout..(ci + 1) * b.cout]);
        }
        Conv { cin, cout, kh: 1, kw: 1, dil: 1, weights, bias: [a.bias.clone(), b.bias.clone()].concat() }
    }

    /// Writes conv(x) (+ bias, optionally ReLU) into channels [offset, offset + cout) of `dst`,
    /// a map of the same size as `x` with `dst.c` channels.
    fn apply(&self, x: &Map, dst: &mut Map, offset: usize, relu: bool) {
        assert_eq!(x.c, self.cin);
        let (w, h, k) = (x.w, x.h, self.kh * self.kw * self.cin);
        let (ph, pw) = ((self.kh - 1) / 2 * self.dil, (self.kw - 1) / 2 * self.dil);
        let stride = dst.c;
        let out = SendPtr(dst.data.as_mut_ptr());
        let n = w * h;
        (0..n.div_ceil(CHUNK)).into_par_iter().for_each(|chunk| {
            let p0 = chunk * CHUNK;
            let rows = CHUNK.min(n - p0);
            COL.with(|cell| {
                let mut col = cell.borrow_mut();
                let (lhs, lhs_rs) = if self.kh == 1 && self.kw == 1 {
                    (&x.data[p0 * self.cin..], self.cin)
                } else {
                    // im2col: one row of kh·kw·cin taps per output pixel, zeros outside the map.
                    // Every entry is written, so the buffer is not cleared first.
                    if col.len() < rows * k {
                        col.resize(rows * k, 0.0);
                    }
                    let cin = self.cin;
                    let row_taps = self.kw * cin;
                    for (r, taps) in col[..rows * k].chunks_exact_mut(k).enumerate() {
                        let (px, py) = ((p0 + r) % w, (p0 + r) / w);
                        for (ky, seg) in taps.chunks_exact_mut(row_taps).enumerate() {
                            let sy = py as isize + (ky * self.dil) as isize - ph as isize;
                            if sy < 0 || sy >= h as isize {
                                seg.fill(0.0);
                                continue;
                            }
                            let line = sy as usize * w;
                            if self.dil == 1 && px >= pw && px + pw < w {
                                // Undilated and inside: the row's taps are contiguous in the map.
                                let src = (line + px - pw) * cin;
                                seg.copy_from_slice(&x.data[src..src + row_taps]);
                                continue;
                            }
                            for (kx, tap) in seg.chunks_exact_mut(cin).enumerate() {
                                let sx = px as isize + (kx * self.dil) as isize - pw as isize;
                                if sx < 0 || sx >= w as isize {
                                    tap.fill(0.0);
                                } else {
                                    let src = (line + sx as usize) * cin;
                                    tap.copy_from_slice(&x.data[src..src + cin]);
                                }
                            }
                        }
                    }
                    (&col[..rows * k], k)
                };
                let base = unsafe { out.get().add(p0 * stride + offset) };
                // dst[rows × cout] = lhs[rows × k] · weights[k × cout]
                unsafe {
                    gemm(
                        rows,
                        self.cout,
                        k,
                        base,
                        1,
                        stride as isize,
                        false,
                        lhs.as_ptr(),
                        1,
                        lhs_rs as isize,
                        self.weights.as_ptr(),
                        1,
                        self.cout as isize,
                        0.0,
                        1.0,
                        false,
                        false,
                        false,
                        Parallelism::None,
                    );
                }
                for r in 0..rows {
                    let row = unsafe { std::slice::from_raw_parts_mut(base.add(r * stride), self.cout) };
                    for (v, b) in row.iter_mut().zip(&self.bias) {
                        *v += b;
                        if relu && *v < 0.0 {
                            *v = 0.0;
                        }
                    }
                }
            });
        });
    }

    fn run(&self, x: &Map, relu: bool, scratch: &mut Scratch) -> Map {
        let mut out = scratch.map(x.w, x.h, self.cout);
        self.apply(x, &mut out, 0, relu);
        out
    }
}

/// 3×3 stride-1 max and min pooling over the valid neighbours, in one separable pass:
/// channels [0, c) hold the max, [c, 2c) the min.
fn pool3_max_min(x: &Map, scratch: &mut Scratch) -> Map {
    let mut out = scratch.map(x.w, x.h, 2 * x.c);
    let (w, c) = (x.w, x.c);
    out.data.par_chunks_mut(w * 2 * c).enumerate().for_each(|(y, row)| {
        // Vertical max/min over rows y−1..=y+1, then horizontal over x−1..=x+1.
        let mut hi = x.data[y * w * c..(y + 1) * w * c].to_vec();
        let mut lo = hi.clone();
        for sy in [y.wrapping_sub(1), y + 1] {
            if sy < x.h {
                let src = &x.data[sy * w * c..(sy + 1) * w * c];
                for ((a, b), v) in hi.iter_mut().zip(lo.iter_mut()).zip(src) {
                    *a = a.max(*v);
                    *b = b.min(*v);
                }
            }
        }
        for px in 0..w {
            let (mx, mn) = row[px * 2 * c..(px + 1) * 2 * c].split_at_mut(c);
            mx.copy_from_slice(&hi[px * c..(px + 1) * c]);
            mn.copy_from_slice(&lo[px * c..(px + 1) * c]);
            for sx in [px.wrapping_sub(1), px + 1] {
                if sx < w {
                    for k in 0..c {
                        mx[k] = mx[k].max(hi[sx * c + k]);
                        mn[k] = mn[k].min(lo[sx * c + k]);
                    }
                }
            }
        }
    });
    out
}

/// 2×2 stride-2 max pooling (even sizes).
fn downsample(x: &Map, scratch: &mut Scratch) -> Map {
    let (w, h, c) = (x.w / 2, x.h / 2, x.c);
    let mut out = scratch.map(w, h, c);
    out.data.par_chunks_mut(w * c).enumerate().for_each(|(y, row)| {
        for px in 0..w {
            for ch in 0..c {
                let at = |dx: usize, dy: usize| x.data[((2 * y + dy) * x.w + 2 * px + dx) * c + ch];
                row[px * c + ch] = at(0, 0).max(at(1, 0)).max(at(0, 1)).max(at(1, 1));
            }
        }
    });
    out
}

/// `dst += nearest 2× upsampling of x` (`dst` twice the size, same channels).
fn add_upsampled(x: &Map, dst: &mut Map) {
    let c = x.c;
    let dw = dst.w;
    dst.data.par_chunks_mut(dw * c).enumerate().for_each(|(y, row)| {
        for px in 0..dw {
            let s = &x.data[((y / 2) * x.w + px / 2) * c..][..c];
            for (d, v) in row[px * c..(px + 1) * c].iter_mut().zip(s) {
                *d += v;
            }
        }
    });
}

struct FastBlock {
    one: Conv,
    three: Conv,
    dilated: Conv,
    prong_h: Conv,
    prong_v: Conv,
    /// max_proj and min_proj as one block-diagonal 1×1 conv over [max-pooled, min-pooled].
    pool_proj: Conv,
    mix: Conv,
    residual: bool,
}

impl FastBlock {
    fn from(b: &InceptionBlock) -> Self {
        FastBlock {
            one: Conv::from(&b.one),
            three: Conv::from(&b.three),
            dilated: Conv::from(&b.dilated),
            prong_h: Conv::from(&b.prong_h),
            prong_v: Conv::from(&b.prong_v),
            pool_proj: Conv::block_diagonal(&Conv::from(&b.max_proj), &Conv::from(&b.min_proj)),
            mix: Conv::from(&b.mix),
            residual: b.residual,
        }
    }

    fn forward(&self, x: &Map, scratch: &mut Scratch) -> Map {
        // Branches write ReLU'd outputs into their slice of the concatenation.
        let mut cat = scratch.map(x.w, x.h, self.mix.cin);
        let mut off = 0;
        for conv in [&self.one, &self.three, &self.dilated] {
            conv.apply(x, &mut cat, off, true);
            off += conv.cout;
        }
        let prong = self.prong_h.run(x, true, scratch);
        self.prong_v.apply(&prong, &mut cat, off, true);
        scratch.recycle(prong);
        off += self.prong_v.cout;
        let pooled = pool3_max_min(x, scratch);
        self.pool_proj.apply(&pooled, &mut cat, off, true);
        scratch.recycle(pooled);
        let mut y = self.mix.run(&cat, true, scratch);
        scratch.recycle(cat);
        if self.residual {
            y.data.par_iter_mut().zip(x.data.par_iter()).for_each(|(a, b)| *a += b);
        }
        y
    }
}

/// One decoder level for the fast path. The 1×1 fuse of [upsampled coarse, skip] is split by
/// input: its coarse half commutes with nearest upsampling, so it runs at the coarse resolution
/// (a quarter of the pixels) and is upsampled-added onto the skip half.
struct FastDecoder {
    fuse_coarse: Conv,
    fuse_skip: Conv,
    refine: Conv,
}

impl FastDecoder {
    fn from(d: &crate::model::Decoder) -> Self {
        let fuse = Conv::from(&d.fuse);
        let coarse = fuse.cin - fuse.cout; // fuse: [c(l+1) + c(l)] → c(l)
        let split = |rows: std::ops::Range<usize>, bias: bool| Conv {
            cin: rows.len(),
            cout: fuse.cout,
            kh: 1,
            kw: 1,
            dil: 1,
            weights: fuse.weights[rows.start * fuse.cout..rows.end * fuse.cout].to_vec(),
            bias: if bias { fuse.bias.clone() } else { vec![0.0; fuse.cout] },
        };
        FastDecoder {
            fuse_coarse: split(0..coarse, false),
            fuse_skip: split(coarse..fuse.cin, true),
            refine: Conv::from(&d.refine),
        }
    }

    /// relu(refine(relu(fuse([up(coarse), skip])))).
    fn forward(&self, coarse: &Map, skip: &Map, scratch: &mut Scratch) -> Map {
        let low = self.fuse_coarse.run(coarse, false, scratch);
        let mut fused = self.fuse_skip.run(skip, false, scratch);
        add_upsampled(&low, &mut fused);
        scratch.recycle(low);
        fused.data.par_iter_mut().for_each(|v| *v = v.max(0.0));
        let y = self.refine.run(&fused, true, scratch);
        scratch.recycle(fused);
        y
    }
}

/// [`DenoiserNet`] converted for the fast path.
pub struct FastNet {
    stem: Conv,
    encoders: Vec<FastBlock>,
    level_blocks: Vec<Vec<FastBlock>>,
    bottleneck: Vec<FastBlock>,
    decoders: Vec<FastDecoder>,
    output: Conv,
}

impl FastNet {
    /// Copies the weights out of a burn network.
    pub fn from_net(net: &DenoiserNet) -> Self {
        FastNet {
            stem: Conv::from(&net.stem),
            encoders: net.encoders.iter().map(FastBlock::from).collect(),
            level_blocks: net.level_blocks.iter().map(|l| l.iter().map(FastBlock::from).collect()).collect(),
            bottleneck: net.bottleneck.iter().map(FastBlock::from).collect(),
            decoders: net.decoders.iter().map(FastDecoder::from).collect(),
            output: Conv::from(&net.output),
        }
    }

    /// The same function as [`DenoiserNet::forward`] for one image: `x` is the encoded input
    /// (HWC); returns the 3-channel encoded colour (HWC). Buffers come from and go back to
    /// `scratch`.
    pub fn forward(&self, x: &Map, scratch: &mut Scratch) -> Map {
        let mut skips: Vec<Map> = vec![];
        let mut y = self.stem.run(x, true, scratch);
        for (l, enc) in self.encoders.iter().enumerate() {
            if l > 0 {
                let down = downsample(&y, scratch);
                skips.push(std::mem::replace(&mut y, down));
            }
            let next = enc.forward(&y, scratch);
            scratch.recycle(std::mem::replace(&mut y, next));
            for b in self.level_blocks.get(l).into_iter().flatten() {
                let next = b.forward(&y, scratch);
                scratch.recycle(std::mem::replace(&mut y, next));
            }
        }
        for b in &self.bottleneck {
            let next = b.forward(&y, scratch);
            scratch.recycle(std::mem::replace(&mut y, next));
        }
        for dec in self.decoders.iter().rev() {
            let skip = skips.pop().expect("one skip per decoder level");
            let next = dec.forward(&y, &skip, scratch);
            scratch.recycle(std::mem::replace(&mut y, next));
            scratch.recycle(skip);
        }
        let out = self.output.run(&y, false, scratch);
        scratch.recycle(y);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::DenoiserConfig;
    use burn::tensor::{Device, Tensor, TensorData};

    #[test]
    fn fast_path_matches_burn_within_1e_4() {
        let device = Device::flex();
        device.seed(3);
        for config in [
            DenoiserConfig::new(vec![8, 12, 16]).with_bottleneck_blocks(2),
            DenoiserConfig::new(vec![8]).with_bottleneck_blocks(1),
            DenoiserConfig::new(vec![8, 12, 16]).with_level_blocks(Some(vec![0, 2])),
        ] {
            let net = config.init(&device);
            let (w, h, c) = (20usize, 12usize, config.input_channels);
            let chw: Vec<f32> = (0..c * w * h).map(|i| (i * 7919 % 1000) as f32 / 500.0 - 1.0).collect();
            let reference = net.forward(Tensor::<4>::from_data(TensorData::new(chw.clone(), [1, c, h, w]), &device));
            let reference: Vec<f32> = reference.into_data().try_to_vec::<f32>().unwrap();
            let mut hwc = Map::zeros(w, h, c);
            for ch in 0..c {
                for p in 0..w * h {
                    hwc.data[p * c + ch] = chw[ch * w * h + p];
                }
            }
            let fast = FastNet::from_net(&net).forward(&hwc, &mut Scratch::default());
            let mut worst = 0.0f32;
            for ch in 0..3 {
                for p in 0..w * h {
                    worst = worst.max((fast.data[p * 3 + ch] - reference[ch * w * h + p]).abs());
                }
            }
            assert!(worst < 1e-4, "{:?}: fast path differs from burn by {worst}", config.channels);
        }
    }
}
