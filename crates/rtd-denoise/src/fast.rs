//! A fast inference path for [`DenoiserNet`]: the same function evaluated on planar (CHW)
//! feature maps with im2col + the `gemm` crate, threaded over pixel chunks, and branch outputs
//! written straight into their planes of the concatenation. Planar maps put pixels, not
//! channels, along the gemm kernel's vector lanes, so the narrow (6- and 12-channel) branch
//! convolutions fill them. A test holds it to burn's output.

use gemm::{gemm, Parallelism};
use rayon::prelude::*;

use crate::model::{DenoiserNet, InceptionBlock};

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

    /// Writes conv(x) (+ bias, optionally ReLU) into planes [offset, offset + cout) of `dst`,
    /// a map of the same size as `x` with `dst.c` planes.
    fn apply(&self, x: &Map, dst: &mut Map, offset: usize, relu: bool) {
        assert_eq!(x.c, self.cin);
        assert!(offset + self.cout <= dst.c && (dst.w, dst.h) == (x.w, x.h));
        let (w, h, k) = (x.w, x.h, self.kh * self.kw * self.cin);
        let (ph, pw) = (((self.kh - 1) / 2 * self.dil) as isize, ((self.kw - 1) / 2 * self.dil) as isize);
        let n = w * h;
        let out = SendPtr(dst.data.as_mut_ptr());
        (0..n.div_ceil(CHUNK)).into_par_iter().for_each(|chunk| {
            let p0 = chunk * CHUNK;
            let rows = CHUNK.min(n - p0);
            COL.with(|cell| {
                let mut col = cell.borrow_mut();
                let (lhs, lhs_cs) = if self.kh == 1 && self.kw == 1 {
                    // A 1×1 convolution reads the planes in place.
                    (x.data[p0..].as_ptr(), n)
                } else {
                    // im2col: column (ky, kx, ci) holds plane ci shifted to tap (ky, kx) for each
                    // of the chunk's pixels, zero outside the map.
                    if col.len() < rows * k {
                        col.resize(rows * k, 0.0);
                    }
                    for (j, column) in col[..rows * k].chunks_exact_mut(rows).enumerate() {
                        let (tap, ci) = (j / self.cin, j % self.cin);
                        let dy = (tap / self.kw * self.dil) as isize - ph;
                        let dx = (tap % self.kw * self.dil) as isize - pw;
                        gather_shifted(&x.data[ci * n..][..n], w, p0, dx, dy, column);
                    }
                    (col.as_ptr(), rows)
                };
                let base = unsafe { out.get().add(offset * n + p0) };
                // dst[rows × cout] = lhs[rows × k] · weights[k × cout]; dst and lhs are column-major
                // (pixels contiguous, one plane or im2col column apart), the weights row-major.
                unsafe {
                    gemm(
                        rows,
                        self.cout,
                        k,
                        base,
                        n as isize,
                        1,
                        false,
                        lhs,
                        lhs_cs as isize,
                        1,
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
                for (co, b) in self.bias.iter().enumerate() {
                    let plane = unsafe { std::slice::from_raw_parts_mut(base.add(co * n), rows) };
                    for v in plane {
                        *v += b;
                        if relu {
                            *v = v.max(0.0);
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

/// Fills `dst` with pixels p0, p0 + 1, … of a w-wide plane, each read at offset (dx, dy) from
/// itself, with zero where that falls outside the plane.
fn gather_shifted(plane: &[f32], w: usize, p0: usize, dx: isize, dy: isize, dst: &mut [f32]) {
    let h = (plane.len() / w) as isize;
    let mut r = 0;
    while r < dst.len() {
        // One image row's run of the chunk: pixels (px.., py).
        let (px, py) = ((p0 + r) % w, (p0 + r) / w);
        let run = (w - px).min(dst.len() - r);
        let seg = &mut dst[r..r + run];
        let sy = py as isize + dy;
        if sy < 0 || sy >= h {
            seg.fill(0.0);
        } else {
            // Run positions i with 0 ≤ px + i + dx < w read the plane; the rest are zero.
            let lo = (-(px as isize + dx)).clamp(0, run as isize) as usize;
            let hi = (w as isize - px as isize - dx).clamp(lo as isize, run as isize) as usize;
            seg[..lo].fill(0.0);
            if hi > lo {
                let src = (sy as usize * w + px + lo).wrapping_add_signed(dx);
                seg[lo..hi].copy_from_slice(&plane[src..src + (hi - lo)]);
            }
            seg[hi..].fill(0.0);
        }
        r += run;
    }
}

/// 3×3 stride-1 max and min pooling over the valid neighbours, separably per plane: planes
/// [0, c) hold the max, [c, 2c) the min.
fn pool3_max_min(x: &Map, scratch: &mut Scratch) -> Map {
    let mut out = scratch.map(x.w, x.h, 2 * x.c);
    let (w, h, n) = (x.w, x.h, x.w * x.h);
    let (maxes, mins) = out.data.split_at_mut(x.c * n);
    // A neighbour outside the plane is replaced by the centre, which leaves a max or min as is.
    maxes.par_chunks_mut(n).zip(mins.par_chunks_mut(n)).enumerate().for_each(|(c, (mx, mn))| {
        let plane = &x.data[c * n..][..n];
        let (mut hi, mut lo) = (vec![0.0f32; w], vec![0.0f32; w]);
        for y in 0..h {
            // Vertical max/min over rows y−1..=y+1, then horizontal over x−1..=x+1.
            let mid = &plane[y * w..][..w];
            let up = &plane[y.saturating_sub(1) * w..][..w];
            let down = &plane[(y + 1).min(h - 1) * w..][..w];
            for ((((a, b), m), u), d) in hi.iter_mut().zip(lo.iter_mut()).zip(mid).zip(up).zip(down) {
                *a = m.max(*u).max(*d);
                *b = m.min(*u).min(*d);
            }
            let (mx, mn) = (&mut mx[y * w..][..w], &mut mn[y * w..][..w]);
            for px in 0..w {
                let (l, r) = (px.saturating_sub(1), (px + 1).min(w - 1));
                mx[px] = hi[px].max(hi[l]).max(hi[r]);
                mn[px] = lo[px].min(lo[l]).min(lo[r]);
            }
        }
    });
    out
}

/// 2×2 stride-2 max pooling (even sizes).
fn downsample(x: &Map, scratch: &mut Scratch) -> Map {
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

/// `dst += nearest 2× upsampling of x` (`dst` twice the size, same channels).
fn add_upsampled(x: &Map, dst: &mut Map) {
    let n = dst.w * dst.h;
    dst.data.par_chunks_mut(n).enumerate().for_each(|(c, plane)| {
        let src = &x.data[c * x.w * x.h..][..x.w * x.h];
        for (y, row) in plane.chunks_exact_mut(dst.w).enumerate() {
            let s = &src[(y / 2) * x.w..][..x.w];
            for (px, d) in row.iter_mut().enumerate() {
                *d += s[px / 2];
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
        // Branches write ReLU'd outputs into their planes of the concatenation.
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
            bottleneck: net.bottleneck.iter().map(FastBlock::from).collect(),
            decoders: net.decoders.iter().map(FastDecoder::from).collect(),
            output: Conv::from(&net.output),
        }
    }

    /// The same function as [`DenoiserNet::forward`] for one image: `x` is the encoded input
    /// (CHW); returns the 3-channel encoded colour (CHW). Buffers come from and go back to
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
        let configs = [
            DenoiserConfig::new(vec![8, 12, 16]).with_bottleneck_blocks(2),
            DenoiserConfig::new(vec![8]).with_bottleneck_blocks(1),
            DenoiserConfig::new(vec![8, 12]).with_bottleneck_blocks(0),
        ];
        // (config, width, height): 52×44 spans several pixel chunks, whose edges fall mid-row.
        for (i, w, h) in [(0, 20, 12), (1, 20, 12), (2, 20, 12), (0, 52, 44)] {
            let config = &configs[i];
            let net = config.init(&device);
            let c = config.input_channels;
            let chw: Vec<f32> = (0..c * w * h).map(|i| (i * 7919 % 1000) as f32 / 500.0 - 1.0).collect();
            let reference = net.forward(Tensor::<4>::from_data(TensorData::new(chw.clone(), [1, c, h, w]), &device));
            let reference: Vec<f32> = reference.into_data().try_to_vec::<f32>().unwrap();
            let fast = FastNet::from_net(&net).forward(&Map { w, h, c, data: chw }, &mut Scratch::default());
            assert_eq!(fast.data.len(), reference.len());
            let worst = fast.data.iter().zip(&reference).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
            assert!(worst < 1e-4, "{:?} at {w}x{h}: fast path differs from burn by {worst}", config.channels);
        }
    }
}
