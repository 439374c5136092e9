//! `rtd train`'s losses on batches `[B, 3, H, W]` of log-encoded colour: L1 on the encoded
//! colour, and a squared error on the display transform the validation metrics compare.

use burn::tensor::Tensor;

/// The training loss of output and target batches `[B, 3, H, W]` of log-encoded colour: the
/// mean |out − target|.
pub fn training_loss(out: Tensor<4>, target: Tensor<4>) -> Tensor<1> {
    (out - target).abs().mean()
}

/// Encoded colour that decodes beyond this is clipped by the display transform anyway; the
/// clamp keeps e^y finite for wild outputs.
const DISPLAY_MAX_ENCODED: f32 = 30.0;

/// The mean squared error of output and target batches `[B, 3, H, W]` of encoded colour on the
/// display transform that [`rtd_image::metrics::psnr`] compares: each is decoded to linear
/// radiance, (e^y − 1) × `scale` (demodulation factor ÷ exposure, per pixel), clamped to
/// [0, 1] and sRGB-encoded. Minimising it maximises the validation PSNR; pixels brighter than
/// 1 add nothing, so it is meant beside [`training_loss`], not instead of it.
pub fn display_loss(out: Tensor<4>, target: Tensor<4>, scale: Tensor<4>) -> Tensor<1> {
    let diff = display(out, scale.clone()) - display(target, scale);
    (diff.clone() * diff).mean()
}

/// Encoded colour `y` through the display transform the metrics compare: decoded to linear
/// radiance, (e^y − 1) × `scale`, clamped to [0, 1] and sRGB-encoded.
fn display(y: Tensor<4>, scale: Tensor<4>) -> Tensor<4> {
    // Linear radiance in [0, 1].
    let x = y.clamp(0.0, DISPLAY_MAX_ENCODED).exp().sub_scalar(1.0) * scale;
    let x = x.clamp(0.0, 1.0);
    // The sRGB transfer: 12.92 x up to 0.0031308, 1.055 x^(1/2.4) − 0.055 above (the power
    // taken of x ≥ 0.0031308 only, so its derivative stays finite).
    let dark = x.clone().lower_equal_elem(0.003_130_8);
    let curve = x.clone().clamp_min(0.003_130_8).powf_scalar(1.0 / 2.4).mul_scalar(1.055).sub_scalar(0.055);
    curve.mask_where(dark, x.mul_scalar(12.92))
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::{Device, TensorData};

    /// Three channels of two equal rows.
    fn image(row: &[f32]) -> Tensor<4> {
        let data: Vec<f32> = (0..6).flat_map(|_| row.iter().copied()).collect();
        Tensor::<4>::from_data(TensorData::new(data, [1, 3, 2, row.len()]), &Device::flex())
    }

    fn value(t: Tensor<1>) -> f32 {
        t.into_data().try_into_vec::<f32>().unwrap()[0]
    }

    #[test]
    fn training_loss_is_the_mean_absolute_error() {
        // A step edge 0 → 1 across 4 pixels, a blurred copy, and a copy offset by a constant.
        let edge = image(&[0.0, 0.0, 1.0, 1.0]);
        let blurred = image(&[0.0, 0.25, 0.75, 1.0]);
        let offset = image(&[0.25, 0.25, 1.25, 1.25]);
        let l1 = |a: &Tensor<4>, b: &Tensor<4>| value(training_loss(a.clone(), b.clone()));
        assert!((l1(&blurred, &edge) - 0.125).abs() < 1e-6);
        assert!((l1(&offset, &edge) - 0.25).abs() < 1e-6);
        assert!((l1(&edge, &offset) - 0.25).abs() < 1e-6);
        assert_eq!(l1(&edge, &edge), 0.0);
    }

    #[test]
    fn display_loss_is_the_squared_error_psnr_measures_with_finite_gradients() {
        // Encoded values from black through the sRGB toe and mid-tones to far past white, with
        // per-pixel scales as demodulation and exposure make them.
        let n = 8;
        let out: Vec<f32> = (0..3 * n).map(|i| [0.0, 1e-4, 0.004, 0.3, 1.2, 2.5, 9.0, 80.0][i % n]).collect();
        let target: Vec<f32> = (0..3 * n).map(|i| [0.0, 0.002, 0.01, 0.1, 1.0, 3.0, 12.0, 0.5][i % n]).collect();
        let scale: Vec<f32> = (0..3 * n).map(|i| [0.05, 0.3, 1.0, 0.7][i % 4]).collect();
        // The same on the host, with the metric's own transfer.
        let display = |y: f32, s: f32| rtd_image::linear_to_srgb(y.min(DISPLAY_MAX_ENCODED).exp_m1() * s);
        let expected =
            (0..3 * n).map(|i| (display(out[i], scale[i]) - display(target[i], scale[i])).powi(2)).sum::<f32>()
                / (3 * n) as f32;
        assert!(expected > 1e-3, "the example compares unequal images");
        let device = Device::flex().autodiff();
        let tensor = |v: &[f32]| Tensor::<4>::from_data(TensorData::new(v.to_vec(), [1, 3, 1, n]), &device);
        let out_t = tensor(&out).require_grad();
        let loss = display_loss(out_t.clone(), tensor(&target), tensor(&scale));
        let got = loss.clone().into_data().try_into_vec::<f32>().unwrap()[0];
        assert!((got - expected).abs() < 1e-5 * expected.max(1.0), "{got} vs {expected}");
        // Gradients are finite everywhere (the black pixel and the 80 far past white included),
        // zero where the output is clipped to white, and push a too-dark output up.
        let grad = out_t.grad(&loss.backward()).unwrap().into_data().try_into_vec::<f32>().unwrap();
        assert!(grad.iter().all(|g| g.is_finite()), "{grad:?}");
        assert_eq!(grad[7], 0.0, "80 encoded decodes far past white: the clamp leaves no gradient");
        assert!(grad[2] < 0.0, "0.004 is darker than its 0.01 target: the loss falls as it rises");
        // Equal images: zero loss.
        assert_eq!(value(display_loss(tensor(&target), tensor(&target), tensor(&scale))), 0.0);
    }
}
