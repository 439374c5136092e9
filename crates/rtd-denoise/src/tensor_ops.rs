//! Tensor operations the burn network is built from, beside its hand-written differentiable
//! operations (`same_conv.rs`, `extreme_pool.rs`, `upsample.rs`). `conv1x1` is a 1×1
//! convolution in the form burn's flex CPU backend differentiates fastest, so training spends
//! less time in it (measured in models/README.md, "Training's own speed"); the tests hold its
//! values and gradients to burn's module.

use std::borrow::Cow;

use burn::backend::flex::FlexTensor;
use burn::backend::TensorMetadata;
use burn::nn::conv::Conv2d;
use burn::nn::PaddingConfig2d;
use burn::tensor::Tensor;

/// A 1×1, stride-1, unpadded convolution as one batched matrix product,
/// [1, Cout, Cin] × [N, Cin, H·W] + bias: what `conv.forward(x)` computes, but its backward
/// runs as two matrix products where flex's convolution goes through im2col, matrix–vector
/// products per input channel and col2im.
pub(crate) fn conv1x1(conv: &Conv2d, x: Tensor<4>) -> Tensor<4> {
    let [n, cin, h, w] = x.dims();
    let [cout, wcin, kh, kw] = conv.weight.dims();
    let unpadded = matches!(conv.padding, PaddingConfig2d::Valid | PaddingConfig2d::Explicit(0, 0, 0, 0));
    assert!(
        (wcin, kh, kw, conv.stride, conv.groups, unpadded) == (cin, 1, 1, [1, 1], 1, true),
        "conv1x1 needs an ungrouped, unpadded, stride-1 1×1 convolution"
    );
    let weight = conv.weight.val().reshape([1, cout, cin]);
    let mut y = weight.matmul(x.reshape([n, cin, h * w])); // [N, Cout, H·W]
    if let Some(bias) = &conv.bias {
        y = y + bias.val().reshape([1, cout, 1]);
    }
    y.reshape([n, cout, h, w])
}

/// A 4-d flex tensor's sizes.
pub(crate) fn dims4(t: &FlexTensor) -> [usize; 4] {
    t.shape().dims()
}

/// A flex tensor's f32 values in order: borrowed where they already are, else a contiguous copy
/// (for the hand-written training operations, `same_conv`, `extreme_pool` and `upsample`).
pub(crate) fn flex_values(t: &FlexTensor) -> Cow<'_, [f32]> {
    match t.as_slice::<f32>() {
        Some(s) if t.is_contiguous() => Cow::Borrowed(s),
        _ => Cow::Owned(t.to_contiguous().as_slice::<f32>().expect("f32 values").to_vec()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::nn::conv::Conv2dConfig;
    use burn::tensor::{Device, TensorData};

    fn values(t: Tensor<4>) -> Vec<f32> {
        t.into_data().try_to_vec().unwrap()
    }

    /// Values from a fixed hash on `levels` levels.
    fn input(dims: [usize; 4], levels: u32) -> Tensor<4> {
        let n: usize = dims.iter().product();
        let v = (0..n as u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 7) % levels).map(|v| v as f32 - 3.0);
        Tensor::from_data(TensorData::new(v.collect::<Vec<_>>(), dims), &Device::flex())
    }

    /// Values and gradients (input, weight, bias) equal the convolution module's, with and
    /// without a bias: the backward is the reason for the matrix product, so it is checked too.
    #[test]
    fn conv1x1_equals_the_convolution_module_forward_and_backward() {
        let device = Device::flex().autodiff();
        for bias in [true, false] {
            let conv = crate::model::drawn_now(|| Conv2dConfig::new([5, 7], [1, 1]).with_bias(bias).init(&device));
            let x = Tensor::<4>::from_data(input([2, 5, 6, 3], 97).into_data(), &device).require_grad();
            // A weighted sum of the outputs, so every output's gradient differs.
            let weights = Tensor::<4>::from_data(input([2, 7, 6, 3], 13).into_data(), &device);
            let run = |y: Tensor<4>| {
                let grads = (y.clone() * weights.clone()).sum().backward();
                let grad = |t: &Tensor<4>| values(t.grad(&grads).expect("a gradient"));
                let bias = conv.bias.as_ref().map(|b| b.val().grad(&grads).expect("a bias gradient"));
                let bias: Vec<f32> = bias.map(|b| b.into_data().try_to_vec().unwrap()).unwrap_or_default();
                (values(y), grad(&x), grad(&conv.weight.val()), bias)
            };
            let (a, b) = (run(conv1x1(&conv, x.clone())), run(conv.forward(x.clone())));
            assert_eq!(a.0.len(), 2 * 7 * 6 * 3);
            assert_eq!(a.3.len(), if bias { 7 } else { 0 });
            for (a, b) in [(a.0, b.0), (a.1, b.1), (a.2, b.2), (a.3, b.3)] {
                assert_eq!(a.len(), b.len());
                for (a, b) in a.iter().zip(&b) {
                    assert!((a - b).abs() <= 1e-4 * b.abs().max(1.0), "{a} vs {b}");
                }
            }
        }
    }

    /// A padded or strided 1×1 convolution is refused, not silently mis-computed.
    #[test]
    #[should_panic(expected = "conv1x1 needs")]
    fn conv1x1_refuses_a_strided_convolution() {
        let device = Device::flex();
        let conv = crate::model::drawn_now(|| Conv2dConfig::new([2, 2], [1, 1]).with_stride([2, 2]).init(&device));
        conv1x1(&conv, input([1, 2, 4, 4], 7));
    }
}
