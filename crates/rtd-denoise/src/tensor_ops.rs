//! Tensor operations the burn network is built from, in the forms burn's flex CPU backend runs
//! fastest under autodiff: training spends its time here. Each computes what the plain burn
//! module would (the tests below hold them to it); only the route through the backend differs.
//! Measured in models/README.md ("Training speed").

use burn::nn::conv::Conv2d;
use burn::tensor::Tensor;

/// A 1×1, stride-1, unpadded convolution as one batched matrix product,
/// [1, Cout, Cin] × [N, Cin, H·W] + bias: what `conv.forward(x)` computes, but its backward
/// runs as two matrix products where flex's convolution goes through im2col, matrix–vector
/// products per input channel and col2im.
pub(crate) fn conv1x1(conv: &Conv2d, x: Tensor<4>) -> Tensor<4> {
    let [n, cin, h, w] = x.dims();
    let [cout, wcin, kh, kw] = conv.weight.dims();
    debug_assert_eq!((wcin, kh, kw), (cin, 1, 1), "conv1x1 needs an ungrouped 1×1 kernel");
    let weight = conv.weight.val().reshape([1, cout, cin]);
    let mut y = weight.matmul(x.reshape([n, cin, h * w])); // [N, Cout, H·W]
    if let Some(bias) = &conv.bias {
        y = y + bias.val().reshape([1, cout, 1]);
    }
    y.reshape([n, cout, h, w])
}

/// The maximum over each pixel's 3×3 neighbourhood (stride 1). Equal to max-pooling with the
/// border left out of the window, because a border pixel is already in its own window.
pub(crate) fn max3x3(x: Tensor<4>) -> Tensor<4> {
    extreme3x3(x, Tensor::max_pair)
}

/// The minimum over each pixel's 3×3 neighbourhood (stride 1): −max3x3(−x) without the negations.
pub(crate) fn min3x3(x: Tensor<4>) -> Tensor<4> {
    extreme3x3(x, Tensor::min_pair)
}

/// A 3-wide window's extreme along width, then along height (separable). Along one axis of
/// length L: m(i) = pick(x(i), x(i+1)) for i < L − 1, then out(0) = m(0), out(L−1) = m(L−2)
/// and out(i) = pick(m(i−1), m(i)) between.
fn extreme3x3(x: Tensor<4>, pick: fn(Tensor<4>, Tensor<4>) -> Tensor<4>) -> Tensor<4> {
    let along = |x: Tensor<4>, dim: usize| -> Tensor<4> {
        let len = x.dims()[dim];
        if len == 1 {
            return x;
        }
        let pairs = pick(x.clone().narrow(dim, 0, len - 1), x.narrow(dim, 1, len - 1)); // L − 1
        if len == 2 {
            return Tensor::cat(vec![pairs.clone(), pairs], dim);
        }
        let inner = pick(pairs.clone().narrow(dim, 0, len - 2), pairs.clone().narrow(dim, 1, len - 2));
        Tensor::cat(vec![pairs.clone().narrow(dim, 0, 1), inner, pairs.narrow(dim, len - 2, 1)], dim)
    };
    along(along(x, 3), 2)
}

/// Nearest-neighbour 2× upsampling: [N, C, H, W] → [N, C, 2H, 2W].
pub(crate) fn upsample2(x: Tensor<4>) -> Tensor<4> {
    let [n, c, h, w] = x.dims();
    x.reshape([n, c, h, 1, w, 1]).expand([n, c, h, 2, w, 2]).reshape([n, c, 2 * h, 2 * w])
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::nn::conv::Conv2dConfig;
    use burn::nn::pool::MaxPool2dConfig;
    use burn::nn::PaddingConfig2d;
    use burn::tensor::{Device, TensorData};

    fn values(t: Tensor<4>) -> Vec<f32> {
        t.into_data().try_to_vec().unwrap()
    }

    /// Values from a fixed hash, with ties (a coarse grid of levels) so the pooling sees them.
    fn input(dims: [usize; 4], levels: u32) -> Tensor<4> {
        let n: usize = dims.iter().product();
        let v = (0..n as u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 7) % levels).map(|v| v as f32 - 3.0);
        Tensor::from_data(TensorData::new(v.collect::<Vec<_>>(), dims), &Device::flex())
    }

    #[test]
    fn conv1x1_equals_the_convolution_module() {
        let device = Device::flex();
        let conv = Conv2dConfig::new([5, 7], [1, 1]).init(&device);
        let x = input([2, 5, 6, 3], 97);
        let (a, b) = (values(conv1x1(&conv, x.clone())), values(conv.forward(x)));
        assert_eq!(a.len(), 2 * 7 * 6 * 3);
        for (a, b) in a.iter().zip(&b) {
            assert!((a - b).abs() <= 1e-5 * b.abs().max(1.0), "{a} vs {b}");
        }
    }

    #[test]
    fn separable_extremes_equal_max_pooling() {
        let pool = MaxPool2dConfig::new([3, 3])
            .with_strides([1, 1])
            .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
            .init();
        for dims in [[2, 3, 7, 5], [1, 2, 1, 4], [1, 1, 2, 2], [1, 2, 3, 1]] {
            let x = input(dims, 5);
            assert_eq!(values(max3x3(x.clone())), values(pool.forward(x.clone())), "max {dims:?}");
            assert_eq!(values(min3x3(x.clone())), values(-pool.forward(-x)), "min {dims:?}");
        }
    }

    #[test]
    fn upsampling_repeats_each_pixel_in_a_2x2_block() {
        let x = Tensor::<4>::from_data(TensorData::new(vec![1.0f32, 2.0, 3.0, 4.0], [1, 1, 2, 2]), &Device::flex());
        let expected = [1., 1., 2., 2., 1., 1., 2., 2., 3., 3., 4., 4., 3., 3., 4., 4.];
        assert_eq!(values(upsample2(x)), expected);
    }
}
