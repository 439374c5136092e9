//! Training's "same"-padded, stride-1 convolutions (the stem, the 3×3, dilated 3×3 and 1×k/k×1
//! branches, the decoder's refine) as one differentiable operation with its own backward.
//!
//! Burn's flex backend runs a convolution's forward through a generic im2col at a few GMAC/s,
//! its input gradient as a transposed convolution through a scalar col2im, and its weight
//! gradient as a convolution with the batch as channels. Here all three are im2col of row runs
//! plus one `gemm` call per chunk of pixels:
//! - forward: y = W · cols(x) + b;
//! - input gradient: the transpose of a same-padded, stride-1 correlation is the same-padded
//!   correlation of the output gradient with the kernel flipped and its channel axes swapped,
//!   so it is the forward again on the (often narrow) output gradient;
//! - weight gradient: ∂W = Σ over images and chunks of g · cols(x)ᵀ, summed in a fixed order,
//!   so the result does not depend on the thread count;
//! - bias gradient: the output gradient summed over images and pixels.
//!
//! Measured in models/README.md ("Training's own speed"); the tests hold values and all three
//! gradients to burn's `Conv2d` module.

use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::backend::autodiff::NodeId;
use burn::backend::flex::FlexTensor;
use burn::backend::ops::FloatTensorOps;
use burn::backend::tensor::FloatTensor;
use burn::backend::TensorMetadata;
use burn::backend::{backend_extension, Autodiff, Backend, Dispatch, Flex};
use burn::nn::conv::Conv2d;
use burn::nn::PaddingConfig2d;
use burn::tensor::{Shape, Tensor, TensorData};
use gemm::{gemm, Parallelism};
use rayon::prelude::*;

use crate::feature_map::{gather_shifted, SendPtr, IM2COL_CHUNK};
use crate::tensor_ops::{dims4, flex_values};

/// A convolution's geometry: kernel height and width, and the dilation of both axes.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Geometry {
    kh: usize,
    kw: usize,
    dilation: usize,
}

impl Geometry {
    /// Offset (dx, dy) of tap (ky, kx) from the output pixel: centred, dilated.
    fn offset(&self, ky: usize, kx: usize) -> (isize, isize) {
        let d = self.dilation as isize;
        ((kx as isize - (self.kw / 2) as isize) * d, (ky as isize - (self.kh / 2) as isize) * d)
    }

    /// Rows of the im2col matrix per input channel.
    fn taps(&self) -> usize {
        self.kh * self.kw
    }
}

/// The differentiable operation, routed by burn's dispatch to flex or to its autodiff wrapper.
#[backend_extension(Flex, Autodiff)]
pub trait SameConvOps: Backend {
    /// y = conv(x, weight) + bias with "same" zero padding, stride 1 and `dilation` on both axes:
    /// x [N, Cin, H, W], weight [Cout, Cin, kh, kw] (odd kh and kw), bias [Cout] → [N, Cout, H, W].
    fn same_conv(
        x: FloatTensor<Self>,
        weight: FloatTensor<Self>,
        bias: FloatTensor<Self>,
        dilation: usize,
    ) -> FloatTensor<Self>;
}

/// A flex tensor's values (borrowed where they are contiguous) and its dimensions.
fn values(t: &FlexTensor) -> (std::borrow::Cow<'_, [f32]>, [usize; 4]) {
    (flex_values(t), dims4(t))
}

/// A flex tensor of `dims` holding `data`.
fn flex(data: Vec<f32>, dims: [usize; 4]) -> FlexTensor {
    FlexTensor::from_data(TensorData::new(data, dims))
}

/// Checks that x [N, Cin, H, W] and weight [Cout, Cin, kh, kw] (odd kh and kw) fit together,
/// and a bias or an output gradient with them: the raw kernels index by these sizes.
fn check(x: [usize; 4], weight: [usize; 4], cout_of: usize, what: &str) {
    let [_, cin, _, _] = x;
    let [cout, wcin, kh, kw] = weight;
    assert!(
        cin == wcin && cout == cout_of && kh % 2 == 1 && kw % 2 == 1,
        "same_conv: {what} does not fit x {x:?} and weight {weight:?} (odd kernels only)"
    );
}

impl SameConvOps for Flex {
    fn same_conv(x: FlexTensor, weight: FlexTensor, bias: FlexTensor, dilation: usize) -> FlexTensor {
        let ((xv, xd), (wv, wd), bv) = (values(&x), values(&weight), flex_values(&bias));
        check(xd, wd, bv.len(), "the bias");
        let ([n, _, h, w], [cout, _, kh, kw]) = (xd, wd);
        flex(correlate(&xv, xd, &wv, cout, Geometry { kh, kw, dilation }, Some(&bv)), [n, cout, h, w])
    }
}

/// ∂x of [`SameConvOps::same_conv`] from the output's gradient: the same correlation of the
/// gradient with the kernel flipped and its channel axes swapped.
fn input_grad(x_dims: [usize; 4], grad: &FlexTensor, weight: &FlexTensor, dilation: usize) -> FlexTensor {
    let ((gv, gd), (wv, wd)) = (values(grad), values(weight));
    check(x_dims, wd, gd[1], "the output gradient");
    assert_eq!([gd[0], gd[2], gd[3]], [x_dims[0], x_dims[2], x_dims[3]], "same_conv: gradient and x differ in size");
    let [cout, cin, kh, kw] = wd;
    // W'[ci][co][ky][kx] = W[co][ci][kh-1-ky][kw-1-kx]: the flipped, channel-swapped kernel.
    let mut flipped = vec![0.0; wv.len()];
    for co in 0..cout {
        for ci in 0..cin {
            for ky in 0..kh {
                for kx in 0..kw {
                    flipped[((ci * cout + co) * kh + ky) * kw + kx] =
                        wv[((co * cin + ci) * kh + (kh - 1 - ky)) * kw + (kw - 1 - kx)];
                }
            }
        }
    }
    flex(correlate(&gv, gd, &flipped, cin, Geometry { kh, kw, dilation }, None), x_dims)
}

/// ∂W [Cout, Cin, kh, kw] of [`SameConvOps::same_conv`] from x and the output's gradient.
fn weight_grad_of(x: &FlexTensor, grad: &FlexTensor, weight_dims: [usize; 4], dilation: usize) -> FlexTensor {
    let ((xv, xd), (gv, gd)) = (values(x), values(grad));
    check(xd, weight_dims, gd[1], "the output gradient");
    assert_eq!([gd[0], gd[2], gd[3]], [xd[0], xd[2], xd[3]], "same_conv: gradient and x differ in size");
    let [cout, _, kh, kw] = weight_dims;
    flex(weight_grad(&xv, xd, &gv, cout, Geometry { kh, kw, dilation }), weight_dims)
}

/// The backward step: input, weight and bias gradients from the output's.
#[derive(Debug)]
struct SameConvBackward;

impl Backward<Flex, 3> for SameConvBackward {
    /// The checkpointed x and weight, and the dilation.
    type State = (NodeId, NodeId, usize);

    fn backward(self, ops: Ops<Self::State, 3>, grads: &mut Gradients, checkpointer: &mut Checkpointer) {
        let [node_x, node_weight, node_bias] = ops.parents;
        let grad: FlexTensor = grads.consume::<Flex>(&ops.node);
        let (x_state, weight_state, dilation) = ops.state;
        // Both are retrieved whichever gradients are wanted, so the checkpointer ends empty.
        let x: FlexTensor = checkpointer.retrieve_node_output(x_state);
        let weight: FlexTensor = checkpointer.retrieve_node_output(weight_state);
        if let Some(node) = node_bias {
            // ∂b[co] = Σ over images and pixels of g[n][co][p].
            let [n, cout, h, w] = grad.shape().dims();
            let g = Flex::float_reshape(Flex::float_swap_dims(grad.clone(), 0, 1), Shape::new([cout, n * h * w]));
            grads.register::<Flex>(node.id, Flex::float_reshape(Flex::float_sum_dim(g, 1), Shape::new([cout])));
        }
        if let Some(node) = node_weight {
            grads.register::<Flex>(node.id, weight_grad_of(&x, &grad, weight.shape().dims(), dilation));
        }
        if let Some(node) = node_x {
            grads.register::<Flex>(node.id, input_grad(x.shape().dims(), &grad, &weight, dilation));
        }
    }
}

impl<C: CheckpointStrategy> SameConvOps for Autodiff<Flex, C> {
    fn same_conv(
        x: FloatTensor<Self>,
        weight: FloatTensor<Self>,
        bias: FloatTensor<Self>,
        dilation: usize,
    ) -> FloatTensor<Self> {
        match SameConvBackward.prepare::<C>([x.node(), weight.node(), bias.node()]).compute_bound().stateful() {
            OpsKind::Tracked(mut prep) => {
                let (x_state, weight_state) = (prep.checkpoint(&x), prep.checkpoint(&weight));
                let y = Flex::same_conv(x.into_primitive(), weight.into_primitive(), bias.into_primitive(), dilation);
                prep.finish((x_state, weight_state, dilation), y)
            }
            OpsKind::UnTracked(prep) => prep.finish(Flex::same_conv(
                x.into_primitive(),
                weight.into_primitive(),
                bias.into_primitive(),
                dilation,
            )),
        }
    }
}

/// `conv.forward(x)` for a stride-1, ungrouped convolution with an odd kernel, a bias and "same"
/// padding ((k − 1)/2 · dilation on each side), as [`SameConvOps::same_conv`].
pub(crate) fn same_conv(conv: &Conv2d, x: Tensor<4>) -> Tensor<4> {
    let [_, _, kh, kw] = conv.weight.dims();
    let d = conv.dilation;
    let same =
        PaddingConfig2d::Explicit((kh - 1) / 2 * d[0], (kw - 1) / 2 * d[1], (kh - 1) / 2 * d[0], (kw - 1) / 2 * d[1]);
    let bias = conv.bias.as_ref().expect("same_conv needs a convolution with a bias");
    assert!(
        kh % 2 == 1 && kw % 2 == 1 && d[0] == d[1] && conv.stride == [1, 1] && conv.groups == 1 && conv.padding == same,
        "same_conv needs an odd, stride-1, ungrouped convolution with \"same\" padding"
    );
    let out = <Dispatch as SameConvOps>::same_conv(
        x.into_dispatch(),
        conv.weight.val().into_dispatch(),
        bias.val().into_dispatch(),
        d[0],
    );
    Tensor::from_dispatch(out)
}

/// The work items of an [N, C, H, W] map: (image, first pixel, pixel count).
fn chunks(n: usize, hw: usize) -> Vec<(usize, usize, usize)> {
    (0..n).flat_map(|i| (0..hw).step_by(IM2COL_CHUNK).map(move |p0| (i, p0, IM2COL_CHUNK.min(hw - p0)))).collect()
}

/// im2col of pixels p0.. (len of them) of image `image`: rows (ci, ky, kx), `len` columns.
fn im2col(
    x: &[f32],
    dims: [usize; 4],
    geometry: Geometry,
    (image, p0, len): (usize, usize, usize),
    cols: &mut Vec<f32>,
) {
    let [_, cin, h, w] = dims;
    cols.resize(cin * geometry.taps() * len, 0.0);
    let mut rows = cols.chunks_exact_mut(len);
    for ci in 0..cin {
        let plane = &x[(image * cin + ci) * h * w..][..h * w];
        for ky in 0..geometry.kh {
            for kx in 0..geometry.kw {
                let (dx, dy) = geometry.offset(ky, kx);
                gather_shifted(plane, w, p0, dx, dy, rows.next().expect("a row per tap"));
            }
        }
    }
}

/// y[n][co] = Σ over (ci, ky, kx) of weight[co][ci][ky][kx] · x[n][ci] shifted by the tap, + bias[co]
/// (none: + 0). The callers have checked that x, weight and bias fit `dims` and `cout`.
fn correlate(
    x: &[f32],
    dims: [usize; 4],
    weight: &[f32],
    cout: usize,
    geometry: Geometry,
    bias: Option<&[f32]>,
) -> Vec<f32> {
    let [n, cin, h, w] = dims;
    let (hw, k) = (h * w, cin * geometry.taps());
    let mut y = vec![0.0f32; n * cout * hw];
    let out = SendPtr(y.as_mut_ptr());
    chunks(n, hw).into_par_iter().for_each_init(Vec::new, |cols, item| {
        let (image, p0, len) = item;
        im2col(x, dims, geometry, item, cols);
        let dst = unsafe { out.get().add(image * cout * hw + p0) };
        for (co, b) in bias.unwrap_or_default().iter().enumerate() {
            // Each item owns pixels p0..p0+len of every output plane of its image.
            unsafe { std::slice::from_raw_parts_mut(dst.add(co * hw), len) }.fill(*b);
        }
        // dstᵀ [len × cout] = (bias, if any) + colsᵀ [len × k] · weightᵀ [k × cout]
        unsafe {
            gemm(
                len,
                cout,
                k,
                dst,
                hw as isize,
                1,
                bias.is_some(),
                cols.as_ptr(),
                len as isize,
                1,
                weight.as_ptr(),
                k as isize,
                1,
                if bias.is_some() { 1.0 } else { 0.0 },
                1.0,
                false,
                false,
                false,
                Parallelism::None,
            );
        }
    });
    y
}

/// ∂W[co][ci][ky][kx] = Σ over images and pixels of g[n][co][p] · x[n][ci][p shifted by the tap].
fn weight_grad(x: &[f32], dims: [usize; 4], g: &[f32], cout: usize, geometry: Geometry) -> Vec<f32> {
    let [n, cin, h, w] = dims;
    let (hw, k) = (h * w, cin * geometry.taps());
    // One partial sum per work item, added in item order: the same bits at any thread count.
    let partials: Vec<Vec<f32>> = chunks(n, hw)
        .into_par_iter()
        .map_init(Vec::new, |cols, item| {
            let (image, p0, len) = item;
            im2col(x, dims, geometry, item, cols);
            let mut part = vec![0.0f32; k * cout];
            let grad = g[image * cout * hw + p0..].as_ptr();
            // part [cout × k, stored k-major] = g [cout × len] · colsᵀ [len × k]. With the output
            // channels as gemm's rows it packs only the narrow g; with the (k-long) im2col rows as
            // its rows it would pack, transposing, the whole im2col matrix (up to twice the time).
            unsafe {
                gemm(
                    cout,
                    k,
                    len,
                    part.as_mut_ptr(),
                    cout as isize,
                    1,
                    false,
                    grad,
                    1,
                    hw as isize,
                    cols.as_ptr(),
                    len as isize,
                    1,
                    0.0,
                    1.0,
                    false,
                    false,
                    false,
                    Parallelism::None,
                );
            }
            part
        })
        .collect();
    let mut sum = vec![0.0f32; k * cout];
    for part in &partials {
        sum.iter_mut().zip(part).for_each(|(s, p)| *s += p);
    }
    // From [k][cout] to the weight's [cout][k].
    (0..cout * k).map(|i| sum[(i % k) * cout + i / k]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::nn::conv::Conv2dConfig;
    use burn::tensor::Device;

    fn to_vec(t: Tensor<4>) -> Vec<f32> {
        t.into_data().try_to_vec().unwrap()
    }

    /// Values from a fixed hash on `levels` levels.
    fn input(dims: [usize; 4], levels: u32, device: &Device) -> Tensor<4> {
        let n: usize = dims.iter().product();
        let v = (0..n as u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 7) % levels).map(|v| v as f32 - 3.0);
        Tensor::from_data(TensorData::new(v.collect::<Vec<_>>(), dims), device)
    }

    fn close(a: &[f32], b: &[f32]) {
        assert_eq!(a.len(), b.len());
        for (a, b) in a.iter().zip(b) {
            assert!((a - b).abs() <= 1e-4 * b.abs().max(1.0), "{a} vs {b}");
        }
    }

    /// Values and the input, weight and bias gradients equal burn's module's, for every kernel
    /// shape the network uses (3×3, dilated 3×3, 1×k, k×1), on planes larger than one chunk.
    #[test]
    fn same_conv_equals_the_convolution_module_forward_and_backward() {
        let device = Device::flex().autodiff();
        // Every plane is larger than one work chunk (1024 px) and 33 px wide, so chunks start
        // mid-row; in the fifth case x does not require a gradient (the stem's case); the last
        // has more output channels than gemm's widest row block (16).
        for (cin, cout, k, d, hw, x_grad) in [
            (5, 7, [3, 3], 1, [37, 33], true),
            (4, 3, [3, 3], 2, [35, 33], true),
            (6, 2, [1, 5], 1, [32, 33], true),
            (2, 6, [5, 1], 1, [33, 33], true),
            (3, 4, [3, 3], 4, [34, 33], false),
            (3, 17, [3, 3], 1, [33, 33], true),
        ] {
            let (ph, pw) = ((k[0] - 1) / 2 * d, (k[1] - 1) / 2 * d);
            let conv = crate::model::drawn_now(|| {
                Conv2dConfig::new([cin, cout], k)
                    .with_dilation([d, d])
                    .with_padding(PaddingConfig2d::Explicit(ph, pw, ph, pw))
                    .init(&device)
            });
            let x = input([2, cin, hw[0], hw[1]], 97, &device);
            let x = if x_grad { x.require_grad() } else { x };
            // A weighted sum of the outputs, so every output's gradient differs.
            let weights = input([2, cout, hw[0], hw[1]], 13, &device);
            let run = |y: Tensor<4>| {
                let grads = (y.clone() * weights.clone()).sum().backward();
                let grad = |t: &Tensor<4>| to_vec(t.grad(&grads).expect("a gradient"));
                let bias = conv.bias.as_ref().unwrap().val().grad(&grads).expect("a bias gradient");
                let dx = if x_grad { grad(&x) } else { vec![] };
                (to_vec(y), dx, grad(&conv.weight.val()), bias.into_data().try_to_vec::<f32>().unwrap())
            };
            let (a, b) = (run(same_conv(&conv, x.clone())), run(conv.forward(x.clone())));
            close(&a.0, &b.0);
            close(&a.1, &b.1);
            close(&a.2, &b.2);
            close(&a.3, &b.3);
        }
    }

    /// Without autodiff (inference tensors) the operation runs flex's forward alone.
    #[test]
    fn same_conv_runs_on_plain_flex_tensors() {
        let device = Device::flex();
        let conv = crate::model::drawn_now(|| {
            Conv2dConfig::new([3, 4], [3, 3]).with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1)).init(&device)
        });
        let x = input([1, 3, 6, 5], 11, &device);
        close(&to_vec(same_conv(&conv, x.clone())), &to_vec(conv.forward(x)));
    }

    /// A convolution whose padding is not "same" is refused, not silently mis-computed.
    #[test]
    #[should_panic(expected = "same_conv needs")]
    fn same_conv_refuses_a_valid_padded_convolution() {
        let device = Device::flex();
        let conv = crate::model::drawn_now(|| Conv2dConfig::new([2, 2], [3, 3]).init(&device));
        same_conv(&conv, input([1, 2, 4, 4], 7, &device));
    }

    /// The weight gradient's sum runs in a fixed order: one thread and two give the same bits.
    #[test]
    fn the_weight_gradient_does_not_depend_on_the_thread_count() {
        let g = Geometry { kh: 3, kw: 3, dilation: 1 };
        let dims = [3, 4, 40, 30];
        let x: Vec<f32> = (0..dims.iter().product::<usize>()).map(|i| ((i * 37) % 101) as f32 * 0.013 - 0.6).collect();
        let grad: Vec<f32> = (0..3 * 5 * 1200).map(|i| ((i * 53) % 89) as f32 * 0.021 - 0.9).collect();
        let on = |threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| weight_grad(&x, dims, &grad, 5, g))
        };
        assert_eq!(on(1), on(2));
    }

    #[test]
    fn im2col_chunks_cover_every_pixel_once() {
        let items = chunks(2, 2500);
        assert_eq!(items.len(), 6);
        assert_eq!(items.iter().map(|c| c.2).sum::<usize>(), 5000);
        assert_eq!(items[2], (0, 2048, 452));
    }
}
