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
    fn zeros(w: usize, h: usize, c: usize) -> Self {
        Map { w, h, c, data: vec![0.0; w * h * c] }
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
                    col.clear();
                    col.resize(rows * k, 0.0);
                    for r in 0..rows {
                        let (px, py) = ((p0 + r) % w, (p0 + r) / w);
                        for ky in 0..self.kh {
                            let sy = py as isize + (ky * self.dil) as isize - ph as isize;
                            if sy < 0 || sy >= h as isize {
                                continue;
                            }
                            for kx in 0..self.kw {
                                let sx = px as isize + (kx * self.dil) as isize - pw as isize;
                                if sx < 0 || sx >= w as isize {
                                    continue;
                                }
                                let src = (sy as usize * w + sx as usize) * self.cin;
                                let d = r * k + (ky * self.kw + kx) * self.cin;
                                col[d..d + self.cin].copy_from_slice(&x.data[src..src + self.cin]);
                            }
                        }
                    }
                    (&col[..], k)
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

    fn run(&self, x: &Map, relu: bool) -> Map {
        let mut out = Map::zeros(x.w, x.h, self.cout);
        self.apply(x, &mut out, 0, relu);
        out
    }
}

/// 3×3 stride-1 max (or min) pooling over the valid neighbours.
fn pool3(x: &Map, min: bool) -> Map {
    let mut out = Map::zeros(x.w, x.h, x.c);
    let c = x.c;
    out.data.par_chunks_mut(x.w * c).enumerate().for_each(|(y, row)| {
        for px in 0..x.w {
            let o = &mut row[px * c..(px + 1) * c];
            o.fill(if min { f32::INFINITY } else { f32::NEG_INFINITY });
            for sy in y.saturating_sub(1)..(y + 2).min(x.h) {
                for sx in px.saturating_sub(1)..(px + 2).min(x.w) {
                    let s = &x.data[(sy * x.w + sx) * c..][..c];
                    for (a, b) in o.iter_mut().zip(s) {
                        *a = if min { a.min(*b) } else { a.max(*b) };
                    }
                }
            }
        }
    });
    out
}

/// 2×2 stride-2 max pooling (even sizes).
fn downsample(x: &Map) -> Map {
    let (w, h, c) = (x.w / 2, x.h / 2, x.c);
    let mut out = Map::zeros(w, h, c);
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

/// Nearest 2× upsampling of `x` written into channels [0, x.c) of `dst` (twice the size).
fn upsample_into(x: &Map, dst: &mut Map) {
    let c = x.c;
    let dc = dst.c;
    let dw = dst.w;
    dst.data.par_chunks_mut(dw * dc).enumerate().for_each(|(y, row)| {
        for px in 0..dw {
            let s = &x.data[((y / 2) * x.w + px / 2) * c..][..c];
            row[px * dc..px * dc + c].copy_from_slice(s);
        }
    });
}

/// Copies `x` into channels [offset, offset + x.c) of `dst` (same size).
fn copy_into(x: &Map, dst: &mut Map, offset: usize) {
    let (c, dc) = (x.c, dst.c);
    dst.data.par_chunks_mut(dc).zip(x.data.par_chunks(c)).for_each(|(d, s)| d[offset..offset + c].copy_from_slice(s));
}

struct FastBlock {
    one: Conv,
    three: Conv,
    dilated: Conv,
    prong_h: Conv,
    prong_v: Conv,
    max_proj: Conv,
    min_proj: Conv,
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
            max_proj: Conv::from(&b.max_proj),
            min_proj: Conv::from(&b.min_proj),
            mix: Conv::from(&b.mix),
            residual: b.residual,
        }
    }

    fn forward(&self, x: &Map) -> Map {
        // Branches write ReLU'd outputs into their slice of the concatenation.
        let mut cat = Map::zeros(x.w, x.h, self.mix.cin);
        let mut off = 0;
        for conv in [&self.one, &self.three, &self.dilated] {
            conv.apply(x, &mut cat, off, true);
            off += conv.cout;
        }
        let prong = self.prong_h.run(x, true);
        self.prong_v.apply(&prong, &mut cat, off, true);
        off += self.prong_v.cout;
        self.max_proj.apply(&pool3(x, false), &mut cat, off, true);
        off += self.max_proj.cout;
        self.min_proj.apply(&pool3(x, true), &mut cat, off, true);
        let mut y = self.mix.run(&cat, true);
        if self.residual {
            y.data.par_iter_mut().zip(x.data.par_iter()).for_each(|(a, b)| *a += b);
        }
        y
    }
}

/// [`DenoiserNet`] converted for the fast path.
pub struct FastNet {
    stem: Conv,
    encoders: Vec<FastBlock>,
    bottleneck: Vec<FastBlock>,
    decoders: Vec<(Conv, Conv)>,
    output: Conv,
}

impl FastNet {
    /// Copies the weights out of a burn network.
    pub fn from_net(net: &DenoiserNet) -> Self {
        FastNet {
            stem: Conv::from(&net.stem),
            encoders: net.encoders.iter().map(FastBlock::from).collect(),
            bottleneck: net.bottleneck.iter().map(FastBlock::from).collect(),
            decoders: net.decoders.iter().map(|d| (Conv::from(&d.fuse), Conv::from(&d.refine))).collect(),
            output: Conv::from(&net.output),
        }
    }

    /// The same function as [`DenoiserNet::forward`] for one image: `x` is the encoded input
    /// (HWC); returns the 3-channel encoded colour (HWC).
    pub fn forward(&self, x: &Map) -> Map {
        let mut skips = vec![];
        let mut y = self.stem.run(x, true);
        for (l, enc) in self.encoders.iter().enumerate() {
            if l > 0 {
                y = downsample(&y);
            }
            y = enc.forward(&y);
            skips.push(y.clone());
        }
        for b in &self.bottleneck {
            y = b.forward(&y);
        }
        skips.pop();
        for dec in self.decoders.iter().rev() {
            let skip = skips.pop().expect("one skip per decoder level");
            let mut cat = Map::zeros(skip.w, skip.h, y.c + skip.c);
            upsample_into(&y, &mut cat);
            copy_into(&skip, &mut cat, y.c);
            y = dec.1.run(&dec.0.run(&cat, true), true);
        }
        self.output.run(&y, false)
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
            let fast = FastNet::from_net(&net).forward(&hwc);
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
