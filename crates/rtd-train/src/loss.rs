//! `rtd train`'s losses on batches `[B, 3, H, W]` of log-encoded colour: L1 on the encoded
//! colour, and two terms on the display transform the validation metrics compare (a squared
//! error, and 1 − MS-SSIM).

use burn::tensor::module::conv2d;
use burn::tensor::ops::ConvOptions;
use burn::tensor::{Tensor, TensorData};

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

/// Side of the Gaussian window SSIM is computed over (Wang et al. 2004: 11 taps, σ = 1.5).
const SSIM_WINDOW: usize = 11;
/// Weights of the first three scales of MS-SSIM (Wang, Simoncelli and Bovik 2003), for the
/// three that 64² crops allow; they are renormalised to the scales used.
const MS_SSIM_WEIGHTS: [f32; 3] = [0.0448, 0.2856, 0.3001];
/// MS-SSIM's stabilisers for a dynamic range of 1: (0.01)² and (0.03)².
const SSIM_C1: f32 = 1e-4;
const SSIM_C2: f32 = 9e-4;
/// Floor of each scale's mean before it is raised to its weight (a negative mean contrast
/// term would make the power undefined).
const MS_SSIM_FLOOR: f32 = 1e-4;

/// 1 − MS-SSIM of output and target batches `[B, 3, H, W]` of encoded colour, both through
/// the display transform of [`display_loss`], with `scale` as there: the structural term OIDN
/// trains with beside L1. Per channel, 11-tap Gaussian windows (σ = 1.5, valid positions only)
/// at each scale whose side is at least the window, halving by 2×2 means between scales (at
/// most three; the contrast-structure means of all but the last, the luminance one too at the
/// last, each raised to its renormalised weight).
pub fn ms_ssim_loss(out: Tensor<4>, target: Tensor<4>, scale: Tensor<4>) -> Tensor<1> {
    let (mut x, mut y) = (display(out, scale.clone()), display(target, scale));
    let [_, _, h, w] = x.dims();
    let mut scales = 1;
    while scales < MS_SSIM_WEIGHTS.len() && (h >> scales) >= SSIM_WINDOW && (w >> scales) >= SSIM_WINDOW {
        scales += 1;
    }
    let total: f32 = MS_SSIM_WEIGHTS[..scales].iter().sum();
    let mut product: Option<Tensor<1>> = None;
    for (j, weight) in MS_SSIM_WEIGHTS[..scales].iter().enumerate() {
        if j > 0 {
            (x, y) = (half(x), half(y));
        }
        let last = j + 1 == scales;
        let term = ssim_terms(x.clone(), y.clone(), last).mean().clamp_min(MS_SSIM_FLOOR).powf_scalar(weight / total);
        product = Some(match product {
            Some(p) => p * term,
            None => term,
        });
    }
    let ms_ssim = product.unwrap_or_else(|| Tensor::<1>::ones([1], &x.device()));
    ms_ssim.neg().add_scalar(1.0)
}

/// 2×2 means: [N, C, H, W] → [N, C, H/2, W/2] (a trailing odd row or column is dropped).
fn half(x: Tensor<4>) -> Tensor<4> {
    let [n, c, h, w] = x.dims();
    let (h2, w2) = (h / 2, w / 2);
    let x = x.slice([0..n, 0..c, 0..2 * h2, 0..2 * w2]);
    x.reshape([n, c, h2, 2, w2, 2]).mean_dim(5).mean_dim(3).reshape([n, c, h2, w2])
}

/// Per valid window position, SSIM's contrast-structure term (2σxy + C2) ÷ (σx² + σy² + C2),
/// times the luminance term (2μxμy + C1) ÷ (μx² + μy² + C1) when `luminance`.
fn ssim_terms(x: Tensor<4>, y: Tensor<4>, luminance: bool) -> Tensor<4> {
    let blur = |t: Tensor<4>| gaussian_blur(t);
    let (mx, my) = (blur(x.clone()), blur(y.clone()));
    let (mxx, myy, mxy) = (mx.clone() * mx.clone(), my.clone() * my.clone(), mx * my);
    let sxx = blur(x.clone() * x.clone()) - mxx.clone();
    let syy = blur(y.clone() * y.clone()) - myy.clone();
    let sxy = blur(x * y) - mxy.clone();
    let cs = (sxy.mul_scalar(2.0).add_scalar(SSIM_C2)) / (sxx + syy).add_scalar(SSIM_C2);
    if luminance {
        cs * (mxy.mul_scalar(2.0).add_scalar(SSIM_C1) / (mxx + myy).add_scalar(SSIM_C1))
    } else {
        cs
    }
}

/// The separable 11-tap Gaussian (σ = 1.5, normalised) over each channel, valid positions
/// only: [N, C, H, W] → [N, C, H − 10, W − 10].
fn gaussian_blur(x: Tensor<4>) -> Tensor<4> {
    let [_, c, _, _] = x.dims();
    let device = x.device();
    let taps: Vec<f32> = (0..SSIM_WINDOW).map(|i| (-((i as f32 - 5.0).powi(2)) / (2.0 * 1.5 * 1.5)).exp()).collect();
    let sum: f32 = taps.iter().sum();
    let taps: Vec<f32> = (0..c).flat_map(|_| taps.iter().map(|t| t / sum)).collect();
    let kernel = |shape: [usize; 4]| Tensor::<4>::from_data(TensorData::new(taps.clone(), shape), &device);
    let options = || ConvOptions::new([1, 1], [0, 0], [1, 1], c);
    let down = conv2d(x, kernel([c, 1, SSIM_WINDOW, 1]), None, options());
    conv2d(down, kernel([c, 1, 1, SSIM_WINDOW]), None, options())
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Device;

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

    fn batch(f: impl Fn(usize, usize, usize) -> f32, side: usize, device: &Device) -> Tensor<4> {
        let data: Vec<f32> = (0..3 * side * side).map(|i| f(i / (side * side), i / side % side, i % side)).collect();
        Tensor::<4>::from_data(TensorData::new(data, [1, 3, side, side]), device)
    }

    #[test]
    fn ms_ssim_loss_has_known_values_and_finite_gradients() {
        let device = Device::flex();
        let ones = |side| batch(|_, _, _| 1.0, side, &device);
        // Encoded so that the display values are flat: e^y − 1 = x, x then sRGB.
        let flat = |x: f32, side| batch(move |_, _, _| (1.0 + x).ln(), side, &device);
        let texture =
            |side| batch(|c, r, k| (1.0 + 0.5 + 0.4 * ((r * 7 + k * 3 + c) % 5) as f32 / 4.0).ln(), side, &device);
        let loss = |a: Tensor<4>, b: Tensor<4>, side| value(ms_ssim_loss(a, b, ones(side)));
        // Equal images: 0 at every size, one scale (12²) to three (64²).
        for side in [12, 24, 64] {
            assert!(loss(texture(side), texture(side), side).abs() < 1e-6, "{side}");
        }
        // Two flat images: the contrast-structure terms are C2 / C2 = 1 at every scale and the
        // loss is 1 minus the luminance term at the last scale raised to its weight share.
        let (a, b) = (0.2f32, 0.5f32);
        let srgb = |x: f32| rtd_image::linear_to_srgb(x);
        let (sa, sb) = (srgb(a), srgb(b));
        let l = (2.0 * sa * sb + SSIM_C1) / (sa * sa + sb * sb + SSIM_C1);
        let share = MS_SSIM_WEIGHTS[2] / MS_SSIM_WEIGHTS.iter().sum::<f32>();
        // (Within 1e-3: σ² = E[x²] − μ² cancels in f32 to about −2e-7, which against C2 moves
        // each contrast term by about 2e-4.)
        let got = loss(flat(a, 64), flat(b, 64), 64);
        assert!((got - (1.0 - l.powf(share))).abs() < 1e-3, "{got} against {}", 1.0 - l.powf(share));
        // At 12² there is one scale, whose weight share is 1.
        assert!((loss(flat(a, 12), flat(b, 12), 12) - (1.0 - l)).abs() < 1e-3);
        // Noise costs more than nothing and more noise more.
        let noisy = |amp: f32| {
            batch(move |c, r, k| (1.5 + amp * (((r * 31 + k * 17 + c * 7) % 13) as f32 / 6.0 - 1.0)).ln(), 64, &device)
        };
        let (small, large) = (loss(noisy(0.05), flat(0.5, 64), 64), loss(noisy(0.2), flat(0.5, 64), 64));
        assert!(0.0 < small && small < large && large <= 1.0, "{small} {large}");
        // Gradients are finite and non-zero.
        let ad = Device::flex().autodiff();
        let out = batch(|c, r, k| (1.0 + ((r + 2 * k + c) % 9) as f32 / 8.0).ln(), 64, &ad).require_grad();
        let target = batch(|c, r, k| (1.0 + ((r + k + c) % 7) as f32 / 6.0).ln(), 64, &ad);
        let l = ms_ssim_loss(out.clone(), target, batch(|_, _, _| 1.0, 64, &ad));
        let grad = out.grad(&l.backward()).unwrap().into_data().try_into_vec::<f32>().unwrap();
        assert!(grad.iter().all(|g| g.is_finite()) && grad.iter().any(|g| *g != 0.0));
    }
}
