//! Image error metrics with the field's conventions: PSNR and SSIM on a fixed tonemap (exposure
//! 1, clamp to [0,1], sRGB encode, peak 1), relMSE (ε = 0.01), SMAPE, and the seed thesis's SNR.
//! Every metric can skip a border of `crop` pixels.

use crate::{linear_to_srgb, HdrImage};
use glam::Vec3;

/// All metrics of one image against a reference.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Metrics {
    /// PSNR in dB of the tonemapped images (infinite when identical).
    pub psnr: f64,
    /// Mean SSIM of the tonemapped RGB channels (Wang et al.: 11×11 Gaussian window, σ = 1.5).
    pub ssim: f64,
    /// Relative MSE, mean((x−y)²/(y²+0.01)).
    pub relmse: f64,
    /// SMAPE, mean(|x−y|/(|x|+|y|+0.01)).
    pub smape: f64,
    /// The thesis's SNR: mean(reference)/std(reference − test), in dB.
    pub snr_db: f64,
}

fn pixels_in(w: u32, h: u32, crop: u32) -> impl Iterator<Item = (u32, u32)> {
    let (x0, y0) = (crop.min(w / 2), crop.min(h / 2));
    let (x1, y1) = (w - x0, h - y0);
    (y0..y1).flat_map(move |y| (x0..x1).map(move |x| (x, y)))
}

fn tonemapped(v: Vec3) -> Vec3 {
    Vec3::new(
        linear_to_srgb(v.x.clamp(0.0, 1.0)),
        linear_to_srgb(v.y.clamp(0.0, 1.0)),
        linear_to_srgb(v.z.clamp(0.0, 1.0)),
    )
}

/// PSNR on the fixed tonemap, in dB (infinite for identical tonemapped images).
pub fn psnr(test: &HdrImage, reference: &HdrImage, crop: u32) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for (x, y) in pixels_in(reference.width, reference.height, crop) {
        let d = tonemapped(test.get(x, y)) - tonemapped(reference.get(x, y));
        sum += (d * d).to_array().iter().map(|v| *v as f64).sum::<f64>();
        n += 3;
    }
    let mse = sum / n.max(1) as f64;
    if mse == 0.0 {
        f64::INFINITY
    } else {
        -10.0 * mse.log10()
    }
}

/// Mean SSIM of the tonemapped channels as Wang et al. (2004) define it and scikit-image
/// computes it (`gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
/// data_range=1`): local statistics under an 11×11 Gaussian window (σ = 1.5), edges mirrored,
/// averaged over the pixels at least 5 from the edge, then over the channels. An image under
/// 11 pixels a side is averaged over all its pixels.
pub fn ssim(test: &HdrImage, reference: &HdrImage, crop: u32) -> f64 {
    let (w, h) = (reference.width, reference.height);
    let (x0, y0) = (crop.min(w / 2), crop.min(h / 2));
    let (cw, ch) = ((w - 2 * x0) as usize, (h - 2 * y0) as usize);
    let plane = |img: &HdrImage, c: usize| -> Vec<f64> {
        pixels_in(w, h, crop).map(|(x, y)| tonemapped(img.get(x, y))[c] as f64).collect()
    };
    (0..3).map(|c| ssim_plane(&plane(test, c), &plane(reference, c), cw, ch)).sum::<f64>() / 3.0
}

/// SSIM of two `w`×`h` planes of values in [0, 1] (see [`ssim`]).
fn ssim_plane(a: &[f64], b: &[f64], w: usize, h: usize) -> f64 {
    if w == 0 || h == 0 {
        return 1.0;
    }
    let (c1, c2) = (0.01f64 * 0.01, 0.03f64 * 0.03);
    let product = |p: &[f64], q: &[f64]| p.iter().zip(q).map(|(x, y)| x * y).collect::<Vec<f64>>();
    let (ma, mb) = (gaussian_blur(a, w, h), gaussian_blur(b, w, h));
    let (maa, mbb, mab) =
        (gaussian_blur(&product(a, a), w, h), gaussian_blur(&product(b, b), w, h), gaussian_blur(&product(a, b), w, h));
    // The pixels whose window lies inside the image (all of them for a small image).
    let pad = SSIM_RADIUS;
    let (xs, ys) = if w > 2 * pad && h > 2 * pad { (pad..w - pad, pad..h - pad) } else { (0..w, 0..h) };
    let (mut total, mut n) = (0.0, 0usize);
    for y in ys {
        for x in xs.clone() {
            let k = y * w + x;
            let (va, vb, cov) = (maa[k] - ma[k] * ma[k], mbb[k] - mb[k] * mb[k], mab[k] - ma[k] * mb[k]);
            // SSIM at one pixel: luminance × contrast-structure terms.
            total += ((2.0 * ma[k] * mb[k] + c1) * (2.0 * cov + c2))
                / ((ma[k] * ma[k] + mb[k] * mb[k] + c1) * (va + vb + c2));
            n += 1;
        }
    }
    total / n as f64
}

/// Half-width of SSIM's Gaussian window: 3.5σ rounded, as scipy truncates it.
const SSIM_RADIUS: usize = 5;

/// `plane` convolved with the normalised Gaussian of σ = 1.5 over ±[`SSIM_RADIUS`], along x
/// then y, edges mirrored as scipy's `reflect` mode (d c b a | a b c d | d c b a).
fn gaussian_blur(plane: &[f64], w: usize, h: usize) -> Vec<f64> {
    let sigma = 1.5f64;
    let taps: Vec<f64> = (-(SSIM_RADIUS as i64)..=SSIM_RADIUS as i64)
        .map(|d| (-((d * d) as f64) / (2.0 * sigma * sigma)).exp())
        .collect();
    let norm: f64 = taps.iter().sum();
    let reflect = |mut i: i64, n: usize| -> usize {
        let n = n as i64;
        while i < 0 || i >= n {
            i = if i < 0 { -i - 1 } else { 2 * n - i - 1 };
        }
        i as usize
    };
    let r = SSIM_RADIUS as i64;
    let mut rows = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let s: f64 =
                taps.iter().enumerate().map(|(t, k)| k * plane[y * w + reflect(x as i64 + t as i64 - r, w)]).sum();
            rows[y * w + x] = s / norm;
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let s: f64 =
                taps.iter().enumerate().map(|(t, k)| k * rows[reflect(y as i64 + t as i64 - r, h) * w + x]).sum();
            out[y * w + x] = s / norm;
        }
    }
    out
}

/// Relative MSE: mean over channels of (x−y)²/(y²+0.01).
pub fn relmse(test: &HdrImage, reference: &HdrImage, crop: u32) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for (x, y) in pixels_in(reference.width, reference.height, crop) {
        let (a, b) = (test.get(x, y), reference.get(x, y));
        for c in 0..3 {
            let (a, b) = (a[c] as f64, b[c] as f64);
            sum += (a - b) * (a - b) / (b * b + 0.01);
            n += 1;
        }
    }
    sum / n.max(1) as f64
}

/// SMAPE: mean over channels of |x−y|/(|x|+|y|+0.01).
pub fn smape(test: &HdrImage, reference: &HdrImage, crop: u32) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for (x, y) in pixels_in(reference.width, reference.height, crop) {
        let (a, b) = (test.get(x, y), reference.get(x, y));
        for c in 0..3 {
            let (a, b) = (a[c] as f64, b[c] as f64);
            sum += (a - b).abs() / (a.abs() + b.abs() + 0.01);
            n += 1;
        }
    }
    sum / n.max(1) as f64
}

/// The thesis's SNR in dB: 20·log10(mean(reference) / std(reference − test)).
pub fn snr_db(test: &HdrImage, reference: &HdrImage, crop: u32) -> f64 {
    let (mut sr, mut sd, mut sdd, mut n) = (0.0f64, 0.0f64, 0.0f64, 0usize);
    for (x, y) in pixels_in(reference.width, reference.height, crop) {
        let (a, b) = (test.get(x, y), reference.get(x, y));
        for c in 0..3 {
            let d = (b[c] - a[c]) as f64;
            sr += b[c] as f64;
            sd += d;
            sdd += d * d;
            n += 1;
        }
    }
    let n = n.max(1) as f64;
    let std = (sdd / n - (sd / n).powi(2)).max(0.0).sqrt();
    if std == 0.0 {
        f64::INFINITY
    } else {
        20.0 * ((sr / n).abs() / std).log10()
    }
}

/// Combines two independent, equally sampled renders `a` and `b` of one view into their mean
/// and an estimate of the relMSE (ε = 0.01) still left in that mean: the mean of two halves has
/// per-pixel variance E[(a−b)²]/4.
pub fn mean_of_halves_with_noise(a: &HdrImage, b: &HdrImage) -> (HdrImage, f64) {
    let mean = HdrImage::from_pixels(
        a.width,
        a.height,
        a.pixels.iter().zip(&b.pixels).map(|(x, y)| (*x + *y) * 0.5).collect(),
    );
    let sum: f64 = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .zip(&mean.pixels)
        .map(|((x, y), r)| {
            (0..3).map(|c| ((x[c] - y[c]) as f64 * 0.5).powi(2) / ((r[c] as f64).powi(2) + 0.01)).sum::<f64>()
        })
        .sum();
    (mean, sum / (3 * a.pixels.len()).max(1) as f64)
}

/// Every metric at once.
pub fn metrics(test: &HdrImage, reference: &HdrImage, crop: u32) -> Metrics {
    Metrics {
        psnr: psnr(test, reference, crop),
        ssim: ssim(test, reference, crop),
        relmse: relmse(test, reference, crop),
        smape: smape(test, reference, crop),
        snr_db: snr_db(test, reference, crop),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: u32, h: u32, f: impl Fn(u32, u32) -> Vec3) -> HdrImage {
        HdrImage::from_pixels(w, h, (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| f(x, y)).collect())
    }

    #[test]
    fn identical_images_are_perfect() {
        let a = image(32, 24, |x, y| Vec3::new(x as f32 / 32.0, y as f32 / 24.0, 0.3));
        let m = metrics(&a, &a, 2);
        assert!(m.psnr.is_infinite() && m.snr_db.is_infinite());
        assert!((m.ssim - 1.0).abs() < 1e-12);
        assert_eq!((m.relmse, m.smape), (0.0, 0.0));
    }

    #[test]
    fn a_known_error_gives_the_expected_psnr_and_relmse() {
        // A reference of sRGB value 0.5 everywhere and a test off by ±0.1 in sRGB space
        // (alternating): MSE = 0.01 → PSNR = 20 dB exactly.
        let lin = crate::srgb_to_linear;
        let r = image(40, 40, |_, _| Vec3::splat(lin(0.5)));
        let t = image(40, 40, |x, y| Vec3::splat(lin(if (x + y) % 2 == 0 { 0.6 } else { 0.4 })));
        assert!((psnr(&t, &r, 0) - 20.0).abs() < 1e-3, "{}", psnr(&t, &r, 0));
        // relMSE of a constant relative error e on a bright image ≈ e².
        let r = image(16, 16, |_, _| Vec3::splat(10.0));
        let t = image(16, 16, |_, _| Vec3::splat(11.0));
        assert!((relmse(&t, &r, 0) - 1.0 / 100.01).abs() < 1e-9);
        assert!((smape(&t, &r, 0) - 1.0 / 21.01).abs() < 1e-9);
    }

    #[test]
    fn gaussian_like_noise_gives_the_expected_snr_and_lower_ssim() {
        // Deterministic ±s noise: std = s, mean reference m → SNR = 20 log10(m/s).
        let r = image(64, 64, |_, _| Vec3::splat(0.4));
        let t = image(64, 64, |x, y| Vec3::splat(0.4 + if (x * 7 + y * 3) % 2 == 0 { 0.04 } else { -0.04 }));
        assert!((snr_db(&t, &r, 0) - 20.0).abs() < 1e-3);
        let s = ssim(&t, &r, 0);
        assert!(s < 0.99 && s > 0.0, "{s}");
    }

    #[test]
    fn ssim_matches_scikit_image() {
        // scikit-image 0.26: structural_similarity(a, b, gaussian_weights=True, sigma=1.5,
        // use_sample_covariance=False, data_range=1.0, channel_axis=-1) on these 24×20 planes
        // gives 0.038557160751500875 (unrelated patterns) and 0.9945014710004022 (a vs
        // 0.9 a + 0.05), averaged over the three channels.
        let (w, h) = (24usize, 20usize);
        let plane = |f: &dyn Fn(usize, usize) -> f64| -> Vec<f64> {
            (0..h).flat_map(|j| (0..w).map(move |i| (i, j))).map(|(i, j)| f(i, j)).collect()
        };
        let mean_over_channels = |pair: &dyn Fn(usize) -> (Vec<f64>, Vec<f64>)| {
            (0..3)
                .map(|c| {
                    let (a, b) = pair(c);
                    ssim_plane(&a, &b, w, h)
                })
                .sum::<f64>()
                / 3.0
        };
        let a = |c: usize| plane(&move |i, j| ((i * 7 + j * 13 + c * 29) % 17) as f64 / 16.0);
        let b = |c: usize| plane(&move |i, j| ((i * 5 + j * 11 + c * 3 + (i * j) % 7) % 19) as f64 / 18.0);
        let unrelated = mean_over_channels(&|c| (a(c), b(c)));
        assert!((unrelated - 0.038557160751500875).abs() < 1e-12, "{unrelated}");
        let dimmed = mean_over_channels(&|c| (a(c), a(c).iter().map(|v| (v * 0.9 + 0.05).clamp(0.0, 1.0)).collect()));
        assert!((dimmed - 0.9945014710004022).abs() < 1e-12, "{dimmed}");
        assert_eq!(ssim_plane(&a(0), &a(0), w, h), 1.0);
    }

    #[test]
    fn the_noise_of_a_mean_of_halves_is_a_quarter_of_their_squared_difference() {
        let a = image(4, 4, |_, _| Vec3::splat(1.2));
        let b = image(4, 4, |_, _| Vec3::splat(0.8));
        let (mean, noise) = mean_of_halves_with_noise(&a, &b);
        assert!(mean.pixels.iter().all(|p| (*p - Vec3::ONE).abs().max_element() < 1e-6));
        assert!((noise - 0.04 / 1.01).abs() < 1e-6, "{noise}");
    }

    #[test]
    fn the_crop_excludes_the_border() {
        let r = image(20, 20, |_, _| Vec3::splat(0.5));
        let t = image(20, 20, |x, _| Vec3::splat(if x < 3 { 0.0 } else { 0.5 }));
        assert!(psnr(&t, &r, 3).is_infinite());
        assert!(psnr(&t, &r, 2).is_finite());
    }
}
