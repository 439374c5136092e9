//! Tensor operations the burn network is built from, in the forms burn's flex CPU backend runs
//! fastest under autodiff: training spends its time here. Each computes what the plain burn
//! module would (the tests below hold them to it); only the route through the backend differs.
//! Measured in models/README.md ("Training's own speed").

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

/// Nearest-neighbour 2× upsampling: [N, C, H, W] → [N, C, 2H, 2W].
pub(crate) fn upsample2(x: Tensor<4>) -> Tensor<4> {
    let [n, c, h, w] = x.dims();
    x.reshape([n, c, h, 1, w, 1]).expand([n, c, h, 2, w, 2]).reshape([n, c, 2 * h, 2 * w])
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
    fn upsampling_repeats_each_pixel_in_a_2x2_block() {
        let x = Tensor::<4>::from_data(TensorData::new(vec![1.0f32, 2.0, 3.0, 4.0], [1, 1, 2, 2]), &Device::flex());
        let expected = [1., 1., 2., 2., 1., 1., 2., 2., 3., 3., 4., 4., 3., 3., 4., 4.];
        assert_eq!(values(upsample2(x)), expected);
    }
}
