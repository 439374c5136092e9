//! A fast inference path for [`DenoiserNet`]: the same function evaluated on planar (CHW)
//! feature maps, with branch outputs written straight into their planes of the concatenation.
//! Where the CPU has AVX-512F, 3×3 convolutions run as Winograd ([`crate::winograd`],
//! [`crate::column_winograd`]) and the rest on the direct kernel ([`crate::direct`]); elsewhere
//! all run as im2col + the `gemm` crate, threaded over pixel chunks. Planar maps put pixels, not
//! channels, along the vector lanes, so the narrow (6- and 12-channel) branch convolutions
//! fill them. A test holds every [`Kernel`] to burn's output.

use gemm::{gemm, Parallelism};
use rayon::prelude::*;

use crate::column_winograd::ColumnWinogradWeights;
use crate::direct::DirectWeights;
use crate::feature_map::{gather_shifted, SendPtr, IM2COL_CHUNK};
pub use crate::feature_map::{Map, Rows, Scratch};
use crate::kernel_output::{blend_levels, exposed_colour, RowFilter};
use crate::model::{DenoiserNet, InceptionBlock};
use crate::pooling::{add_upsampled_relu, downsample, pool3_max_min};
use crate::winograd::WinogradWeights;

/// Which convolution kernel the fast path runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    /// The AVX-512 direct convolution, with the undilated 3×3 convolutions by Winograd
    /// F(4×4, 3×3) ([`crate::winograd`]) and the dilated ones by Winograd F(4, 3) down the
    /// columns ([`crate::column_winograd`]; only where [`crate::direct::available`]).
    Winograd,
    /// The AVX-512 direct convolution for every convolution (only where
    /// [`crate::direct::available`]).
    Direct,
    /// im2col + gemm, on any CPU.
    Gemm,
}

impl Kernel {
    /// The fastest kernel this CPU runs.
    pub fn best() -> Self {
        if crate::direct::available() {
            Kernel::Winograd
        } else {
            Kernel::Gemm
        }
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
    /// The same weights as the kernel that runs them reads them.
    prepared: Prepared,
}

/// A convolution's weights prepared for the kernel that runs it.
enum Prepared {
    /// im2col + gemm, which reads [`Conv`]'s own weights.
    Gemm,
    /// The AVX-512 direct kernel's layout.
    Direct(DirectWeights),
    /// The Winograd kernel's transformed weights.
    Winograd(WinogradWeights),
    /// The column Winograd kernel's transformed weights (dilated 3×3).
    ColumnWinograd(ColumnWinogradWeights),
}

thread_local! {
    /// The band maps of [`Conv::apply_rows`] on the gemm path, reused across bands and layers.
    static BAND_MAPS: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
    /// Each worker's im2col buffer, reused across chunks and layers.
    static COL: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
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
        Conv { cin, cout, kh, kw, dil: conv.dilation[0], weights, bias, prepared: Prepared::Gemm }
    }

    /// Prepares the weights for `kernel`.
    fn for_kernel(mut self, kernel: Kernel) -> Self {
        let three = (self.kh, self.kw) == (3, 3);
        self.prepared = match kernel {
            Kernel::Gemm => Prepared::Gemm,
            Kernel::Winograd if three && self.dil == 1 => {
                Prepared::Winograd(WinogradWeights::new(self.cin, self.cout, &self.weights, &self.bias))
            }
            Kernel::Winograd if three => Prepared::ColumnWinograd(ColumnWinogradWeights::new(
                self.cin,
                self.cout,
                self.dil,
                &self.weights,
                &self.bias,
            )),
            Kernel::Winograd | Kernel::Direct => Prepared::Direct(DirectWeights::new(
                self.cin,
                self.cout,
                (self.kh, self.kw, self.dil),
                &self.weights,
                &self.bias,
            )),
        };
        self
    }

    /// Two 1×1 convolutions of one input, their outputs stacked: x → [a(x), b(x)].
    fn side_by_side(a: &Conv, b: &Conv) -> Self {
        assert!(a.kh == 1 && a.kw == 1 && b.kh == 1 && b.kw == 1 && a.cin == b.cin);
        let (cin, cout) = (a.cin, a.cout + b.cout);
        let mut weights = Vec::with_capacity(cin * cout);
        for ci in 0..cin {
            weights.extend_from_slice(&a.weights[ci * a.cout..][..a.cout]);
            weights.extend_from_slice(&b.weights[ci * b.cout..][..b.cout]);
        }
        let bias = [a.bias.clone(), b.bias.clone()].concat();
        Conv { cin, cout, kh: 1, kw: 1, dil: 1, weights, bias, prepared: Prepared::Gemm }
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
        Conv {
            cin,
            cout,
            kh: 1,
            kw: 1,
            dil: 1,
            weights,
            bias: [a.bias.clone(), b.bias.clone()].concat(),
            prepared: Prepared::Gemm,
        }
    }

    /// [`Conv::apply`] for output rows `to.of_x` of x's grid only, stored from row `to.at` of
    /// `dst`, a map of x's width.
    fn apply_rows(&self, x: &Map, to: Rows, dst: &mut Map, offset: usize, relu: bool) {
        match &self.prepared {
            Prepared::Direct(direct) => direct.apply_rows(x, to, dst, offset, relu, None),
            Prepared::Winograd(winograd) => winograd.apply_rows(x, to, dst, offset, relu),
            Prepared::ColumnWinograd(winograd) => winograd.apply_rows(x, to, dst, offset, relu),
            Prepared::Gemm => {
                // im2col + gemm computes whole maps: the rows wanted and those they read, in
                // buffers this thread keeps (a fresh pool if a caller on it holds them).
                let reach = self.reach();
                let (a, b) = (to.of_x.start.saturating_sub(reach), (to.of_x.end + reach).min(x.h));
                BAND_MAPS.with(|cell| {
                    let mut own = Scratch::default();
                    let mut kept = cell.try_borrow_mut();
                    let scratch = kept.as_deref_mut().unwrap_or(&mut own);
                    let mut band = scratch.map(x.w, b - a, x.c);
                    put_rows(x, a..b, &mut band, 0, 0);
                    let mut out = scratch.map(x.w, b - a, self.cout);
                    self.apply(&band, &mut out, 0, relu);
                    put_rows(&out, to.of_x.start - a..to.of_x.end - a, dst, offset, to.at);
                    scratch.recycle(band);
                    scratch.recycle(out);
                });
            }
        }
    }

    /// Writes conv(x) (+ bias, optionally ReLU) into planes [offset, offset + cout) of `dst`,
    /// a map of the same size as `x` with `dst.c` planes.
    fn apply(&self, x: &Map, dst: &mut Map, offset: usize, relu: bool) {
        // The vector kernels compute any range of rows; this is all of them.
        if !matches!(self.prepared, Prepared::Gemm) {
            return self.apply_rows(x, Rows { of_x: 0..x.h, at: 0 }, dst, offset, relu);
        }
        assert_eq!(x.c, self.cin);
        assert!(offset + self.cout <= dst.c && (dst.w, dst.h) == (x.w, x.h));
        let (w, h, k) = (x.w, x.h, self.kh * self.kw * self.cin);
        let (ph, pw) = (((self.kh - 1) / 2 * self.dil) as isize, ((self.kw - 1) / 2 * self.dil) as isize);
        let n = w * h;
        let out = SendPtr(dst.data.as_mut_ptr());
        (0..n.div_ceil(IM2COL_CHUNK)).into_par_iter().for_each(|chunk| {
            let p0 = chunk * IM2COL_CHUNK;
            let rows = IM2COL_CHUNK.min(n - p0);
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

    /// How many rows above and below an output row its value reads.
    fn reach(&self) -> usize {
        (self.kh - 1) / 2 * self.dil
    }

    fn run(&self, x: &Map, relu: bool, scratch: &mut Scratch) -> Map {
        let mut out = scratch.map(x.w, x.h, self.cout);
        self.apply(x, &mut out, 0, relu);
        out
    }

    /// relu(conv(x)) (+ `residual`, on dst's grid) for rows `to.of_x` of x, stored from row
    /// `to.at` of `dst`, a map of `cout` planes.
    fn apply_rows_residual(&self, x: &Map, to: Rows, dst: &mut Map, residual: Option<&Map>) {
        match (&self.prepared, residual) {
            (Prepared::Direct(direct), _) => direct.apply_rows(x, to, dst, 0, true, residual),
            (_, None) => self.apply_rows(x, to, dst, 0, true),
            (_, Some(r)) => {
                let (w, n, rows) = (dst.w, dst.w * dst.h, to.at..to.at + to.of_x.len());
                self.apply_rows(x, to, dst, 0, true);
                dst.data.par_chunks_mut(n).zip(r.data.par_chunks(n)).for_each(|(plane, res)| {
                    let (plane, res) = (&mut plane[rows.start * w..rows.end * w], &res[rows.start * w..rows.end * w]);
                    plane.iter_mut().zip(res).for_each(|(a, b)| *a += b);
                });
            }
        }
    }
}

/// Output rows per band of [`FastBlock::forward`] and [`FastDecoder::forward`].
const BAND: usize = 32;

/// Copies rows `rows` of every plane of `src` into planes [offset, offset + src.c) of `dst`,
/// from row `at` on.
fn put_rows(src: &Map, rows: std::ops::Range<usize>, dst: &mut Map, offset: usize, at: usize) {
    let (w, sh, dh) = (src.w, src.h, dst.h);
    let planes = &mut dst.data[offset * w * dh..(offset + src.c) * w * dh];
    planes.par_chunks_mut(w * dh).enumerate().for_each(|(c, plane)| {
        plane[at * w..][..w * rows.len()].copy_from_slice(&src.data[(c * sh + rows.start) * w..][..w * rows.len()]);
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
    /// The block, band by band of [`BAND`] output rows: each band's branch outputs (the
    /// concatenation, the pooled planes) exist only for that band, so they stay in cache
    /// instead of streaming whole images through memory. The branch convolutions read `x` in place.
    fn forward(&self, x: &Map, scratch: &mut Scratch) -> Map {
        let mut out = scratch.map(x.w, x.h, self.mix.cout);
        for y0 in (0..x.h).step_by(BAND) {
            let band = y0..(y0 + BAND).min(x.h);
            self.band(x, band, &mut out, scratch);
        }
        out
    }

    fn from(b: &InceptionBlock, kernel: Kernel) -> Self {
        let conv = |c: &burn::nn::conv::Conv2d| Conv::from(c).for_kernel(kernel);
        FastBlock {
            one: conv(&b.one),
            three: conv(&b.three),
            dilated: conv(&b.dilated),
            prong_h: conv(&b.prong_h),
            prong_v: conv(&b.prong_v),
            pool_proj: Conv::block_diagonal(&Conv::from(&b.max_proj), &Conv::from(&b.min_proj)).for_kernel(kernel),
            mix: conv(&b.mix),
            residual: b.residual,
        }
    }

    /// Rows `rows` of the block's output, into the same rows of `out`.
    fn band(&self, x: &Map, rows: std::ops::Range<usize>, out: &mut Map, scratch: &mut Scratch) {
        // Branches write ReLU'd outputs into their planes of the band's concatenation.
        let (w, len) = (x.w, rows.len());
        let here = Rows { of_x: rows.clone(), at: 0 };
        let mut cat = scratch.map(w, len, self.mix.cin);
        let mut off = 0;
        for conv in [&self.one, &self.three, &self.dilated] {
            conv.apply_rows(x, here.clone(), &mut cat, off, true);
            off += conv.cout;
        }
        // The vertical prong reads the horizontal one's rows around the band.
        let reach = self.prong_v.reach();
        let around = rows.start.saturating_sub(reach)..(rows.end + reach).min(x.h);
        let mut prong = scratch.map(w, around.len(), self.prong_h.cout);
        self.prong_h.apply_rows(x, Rows { of_x: around.clone(), at: 0 }, &mut prong, 0, true);
        let inside = rows.start - around.start..rows.end - around.start;
        self.prong_v.apply_rows(&prong, Rows { of_x: inside, at: 0 }, &mut cat, off, true);
        scratch.recycle(prong);
        off += self.prong_v.cout;
        let pooled = pool3_max_min(x, rows.clone(), scratch);
        self.pool_proj.apply_rows(&pooled, Rows { of_x: 0..len, at: 0 }, &mut cat, off, true);
        scratch.recycle(pooled);
        let to = Rows { of_x: 0..len, at: rows.start };
        self.mix.apply_rows_residual(&cat, to, out, self.residual.then_some(x));
        scratch.recycle(cat);
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
    fn from(d: &crate::model::Decoder, kernel: Kernel) -> Self {
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
            prepared: Prepared::Gemm,
        };
        FastDecoder {
            fuse_coarse: split(0..coarse, false).for_kernel(kernel),
            fuse_skip: split(coarse..fuse.cin, true).for_kernel(kernel),
            refine: Conv::from(&d.refine).for_kernel(kernel),
        }
    }

    /// relu(refine(relu(fuse([up(coarse), skip])))), followed by `output`'s convolution
    /// (without ReLU) if it has one, and by its kernels' filter if it has one too. Band by band
    /// of [`BAND`] rows: the fused map exists only for a band and the row either side of it, and
    /// with an output convolution so does the refined one, so neither streams a whole
    /// full-resolution map through memory; with a filter, neither do the K² + 1 logit planes.
    fn forward(&self, coarse: &Map, skip: &Map, output: Output, scratch: &mut Scratch) -> Map {
        let low = self.fuse_coarse.run(coarse, false, scratch);
        let (w, h) = (skip.w, skip.h);
        let planes = match output {
            Output::Refined => self.refine.cout,
            Output::Direct(conv) => conv.cout,
            Output::Kernels(..) => 4,
        };
        let mut out = scratch.map(w, h, planes);
        let reach = self.refine.reach();
        for y0 in (0..h).step_by(BAND) {
            let y1 = (y0 + BAND).min(h);
            let (a, b) = (y0.saturating_sub(reach), (y1 + reach).min(h));
            let mut fused = scratch.map(w, b - a, self.fuse_skip.cout);
            self.fuse_skip.apply_rows(skip, Rows { of_x: a..b, at: 0 }, &mut fused, 0, false);
            add_upsampled_relu(&low, &mut fused, a);
            let band = Rows { of_x: y0 - a..y1 - a, at: y0 };
            let conv = match output {
                Output::Refined => None,
                Output::Direct(conv) | Output::Kernels(conv, _) => Some(conv),
            };
            match conv {
                None => self.refine.apply_rows(&fused, band, &mut out, 0, true),
                Some(conv) => {
                    let mut refined = scratch.map(w, y1 - y0, self.refine.cout);
                    self.refine.apply_rows(&fused, Rows { at: 0, ..band }, &mut refined, 0, true);
                    if let Output::Kernels(_, filter) = output {
                        let mut logits = scratch.map(w, y1 - y0, conv.cout);
                        conv.apply_rows(&refined, Rows { of_x: 0..y1 - y0, at: 0 }, &mut logits, 0, false);
                        filter.filter_band(&logits, y0, &mut out);
                        scratch.recycle(logits);
                    } else {
                        conv.apply_rows(&refined, Rows { of_x: 0..y1 - y0, at: y0 }, &mut out, 0, false);
                    }
                    scratch.recycle(refined);
                }
            }
            scratch.recycle(fused);
        }
        scratch.recycle(low);
        out
    }
}

/// What the finest decoder level ends with.
#[derive(Clone, Copy)]
enum Output<'a> {
    /// Its refined features (a level above the finest).
    Refined,
    /// A convolution of them: the encoded colour of direct prediction.
    Direct(&'a Conv),
    /// The kernel heads' convolution, whose kernels are applied at once: the filtered colour
    /// and the blend logit ([`RowFilter::filter_band`]).
    Kernels(&'a Conv, &'a RowFilter),
}

/// [`DenoiserNet`] converted for the fast path.
pub struct FastNet {
    stem: Conv,
    encoders: Vec<FastBlock>,
    bottleneck: Vec<FastBlock>,
    decoders: Vec<FastDecoder>,
    output: Conv,
    /// Per level, full resolution first, the kernel-predicting heads (kernel logits, then the
    /// blend logit where there is one), which replace `output` when present.
    heads: Option<Vec<Conv>>,
    /// Whether the heads' levels are blended through bilinear upsampling (else nearest).
    bilinear: bool,
    /// The side of the heads' kernels.
    kernel_size: usize,
}

impl FastNet {
    /// Copies the weights out of a burn network, for the fastest kernel this CPU runs.
    pub fn from_net(net: &DenoiserNet) -> Self {
        Self::with_kernel(net, Kernel::best())
    }

    /// Copies the weights out of a burn network, for `kernel` (which must run on this CPU).
    pub fn with_kernel(net: &DenoiserNet, kernel: Kernel) -> Self {
        FastNet {
            stem: Conv::from(&net.stem).for_kernel(kernel),
            encoders: net.encoders.iter().map(|b| FastBlock::from(b, kernel)).collect(),
            bottleneck: net.bottleneck.iter().map(|b| FastBlock::from(b, kernel)).collect(),
            decoders: net.decoders.iter().map(|d| FastDecoder::from(d, kernel)).collect(),
            output: Conv::from(&net.output).for_kernel(kernel),
            heads: net.kernel.as_ref().map(|k| {
                let head = |(l, kc)| {
                    let kc = Conv::from(kc);
                    let both = k.blends.get(l).map(|b| Conv::side_by_side(&kc, &Conv::from(b)));
                    both.unwrap_or(kc).for_kernel(kernel)
                };
                k.kernels.iter().enumerate().map(head).collect()
            }),
            bilinear: net.kernel.as_ref().is_some_and(|k| k.bilinear),
            kernel_size: net.kernel.as_ref().map_or(crate::kernel_output::DEFAULT_KERNEL_SIZE, |k| k.size),
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
        let output = self.heads.as_ref().map_or(&self.output, |h| &h[0]);
        // Kernel heads' logits at each level below the finest, coarsest first.
        let mut logits = vec![];
        let mut filter = None;
        if self.decoders.is_empty() {
            let out = output.run(&y, false, scratch);
            scratch.recycle(y);
            y = match self.heads.is_some() {
                true => {
                    let (level, f) = self.finest_filter(x, scratch);
                    let mut filtered = scratch.map(out.w, out.h, 4);
                    f.filter_band(&out, 0, &mut filtered);
                    scratch.recycle(out);
                    filter = Some((level, f));
                    filtered
                }
                false => out,
            };
        }
        // The finest decoder level also runs the output convolution, band by band, and with
        // kernel heads their filter.
        for (l, dec) in self.decoders.iter().enumerate().rev() {
            if let Some(heads) = &self.heads {
                logits.push(heads[l + 1].run(&y, false, scratch));
            }
            if l == 0 && self.heads.is_some() {
                filter = Some(self.finest_filter(x, scratch));
            }
            let finest = match &filter {
                Some((_, f)) => Output::Kernels(output, f),
                None => Output::Direct(output),
            };
            let skip = skips.pop().expect("one skip per decoder level");
            let next = dec.forward(&y, &skip, if l == 0 { finest } else { Output::Refined }, scratch);
            scratch.recycle(std::mem::replace(&mut y, next));
            scratch.recycle(skip);
        }
        let Some((level, f)) = filter else { return y };
        f.recycle(scratch);
        logits.reverse();
        let out = blend_levels(level, y, &logits, (self.bilinear, self.kernel_size), scratch);
        logits.into_iter().for_each(|m| scratch.recycle(m));
        out
    }

    /// The noisy colour of `x` as the kernels average it, and the finest level's filter over it.
    fn finest_filter(&self, x: &Map, scratch: &mut Scratch) -> (Map, RowFilter) {
        let level = exposed_colour(&x.data, (x.w, x.h), scratch);
        let filter = RowFilter::new(&level, self.kernel_size, scratch);
        (level, filter)
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
        let configs = [
            DenoiserConfig::new(vec![8, 12, 16]).with_bottleneck_blocks(2),
            DenoiserConfig::new(vec![8]).with_bottleneck_blocks(1),
            DenoiserConfig::new(vec![8, 12]).with_bottleneck_blocks(0),
            DenoiserConfig::new(vec![8, 12, 16]).with_kernel_output(Some(true)),
            DenoiserConfig::new(vec![8]).with_kernel_output(Some(true)),
            DenoiserConfig::new(vec![8, 12, 16]).with_kernel_output(Some(true)).with_bilinear_blend(Some(true)),
            DenoiserConfig::new(vec![8, 12])
                .with_kernel_output(Some(true))
                .with_bilinear_blend(Some(true))
                .with_kernel_size(Some(7)),
        ];
        // (config, width, height): 52×44 spans several pixel chunks, whose edges fall mid-row;
        // 24×100 runs the full-resolution blocks in bands, the last one short.
        // 136×72 runs several Winograd vectors and batches per row, and bands at the coarse levels.
        let sizes = [
            (0, 20, 12),
            (1, 20, 12),
            (2, 20, 12),
            (0, 52, 44),
            (1, 24, 100),
            (0, 136, 72),
            (3, 52, 44),
            (4, 20, 12),
            (5, 52, 44),
            (6, 52, 44),
        ];
        for (i, w, h) in sizes {
            let config = &configs[i];
            let net = config.init_seeded(&device, 3);
            let c = config.input_channels;
            let chw: Vec<f32> = (0..c * w * h).map(|i| (i * 7919 % 1000) as f32 / 500.0 - 1.0).collect();
            let reference = net.forward(Tensor::<4>::from_data(TensorData::new(chw.clone(), [1, c, h, w]), &device));
            let reference: Vec<f32> = reference.into_data().try_to_vec::<f32>().unwrap();
            let kernels = if crate::direct::available() {
                vec![Kernel::Gemm, Kernel::Direct, Kernel::Winograd]
            } else {
                vec![Kernel::Gemm]
            };
            for kernel in kernels {
                let map = Map { w, h, c, data: chw.clone() };
                let fast = FastNet::with_kernel(&net, kernel).forward(&map, &mut Scratch::default());
                assert_eq!(fast.data.len(), reference.len());
                let worst = fast.data.iter().zip(&reference).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
                assert!(
                    worst < 1e-4,
                    "{:?} at {w}x{h}, {kernel:?}: fast path differs from burn by {worst}",
                    config.channels
                );
            }
        }
    }
}
