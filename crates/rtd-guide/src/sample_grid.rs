//! The guide's samples within a pixel: a 3×3 grid drawn from the path tracer's tent filter,
//! and the test that a screen box holds one of them (which lets the rasteriser drop triangles
//! that fall between samples).

use glam::{Vec2, Vec3};

/// Samples per pixel side: the pixel takes SAMPLES_1D² samples.
pub const SAMPLES_1D: usize = 3;
/// Samples per pixel.
pub const SAMPLES: usize = SAMPLES_1D * SAMPLES_1D;

/// Sample offsets from the pixel centre: stratum centres of the tent filter's CDF (radius 1 px),
/// the deterministic counterpart of the path tracer's importance-sampled tent.
pub fn sample_offsets() -> [Vec2; SAMPLES] {
    let tent = |u: f32| if u < 0.5 { (2.0 * u).sqrt() - 1.0 } else { 1.0 - (2.0 - 2.0 * u).sqrt() };
    let mut out = [Vec2::ZERO; SAMPLES];
    for j in 0..SAMPLES_1D {
        for i in 0..SAMPLES_1D {
            let u = (i as f32 + 0.5) / SAMPLES_1D as f32;
            let v = (j as f32 + 0.5) / SAMPLES_1D as f32;
            out[j * SAMPLES_1D + i] = Vec2::new(tent(u), tent(v));
        }
    }
    out
}

/// How far a sample can lie from its pixel's centre, along x or y.
pub(crate) fn sample_reach() -> f32 {
    sample_offsets().iter().map(|o| o.abs().max_element()).fold(0.0, f32::max)
}

/// The pixels whose samples can touch the bounding box of screen vertices `v`, as the first and
/// last column, then row (whole numbers in f32; first above last when none can; image
/// coordinates, not clamped to the image). Pixel p's samples lie within `reach`
/// ([`sample_reach`]) of its centre p + 0.5, so p spans [lo − 0.5 − reach, hi − 0.5 + reach],
/// widened by a margin far above the edge functions' rounding. The rasteriser visits these
/// pixels, and the tiles a triangle is binned to are the tiles they lie in.
#[inline(always)]
pub(crate) fn pixels_reached(v: &[Vec3; 3], reach: f32) -> [f32; 4] {
    let lo = v[0].min(v[1]).min(v[2]) - Vec3::splat(0.5 + reach + 0.05);
    let hi = v[0].max(v[1]).max(v[2]) + Vec3::splat(reach + 0.05 - 0.5);
    [lo.x.ceil(), hi.x.floor(), lo.y.ceil(), hi.y.floor()]
}

/// Where in its pixel each sample lies along x, and along y (the offsets are a product grid):
/// 0.5 + the offsets of the first row, ascending and strictly inside (0, 1) (the sample test
/// relies on both; `offsets_follow_the_tent` checks them).
pub(crate) fn sample_fractions() -> [f32; SAMPLES_1D] {
    let offsets = sample_offsets();
    std::array::from_fn(|i| 0.5 + offsets[i].x)
}

/// Pixels by which [`covers_a_sample`] widens a bounding box, so that it never drops a triangle
/// the rasteriser would draw: 1/128 px, far above the rounding of the test's own f32 arithmetic
/// at the largest image side (an ulp is 1/1024 px between 8192 and 16384) and of the edge
/// functions, and far below the samples' spacing (0.155 px at the least).
const COVER_MARGIN: f32 = 1.0 / 128.0;

/// Whether the interval [lo, hi] (pixels) holds a sample coordinate k + f, for a pixel k in
/// 0..n and f one of `fractions` (or may: wide intervals answer yes).
#[inline(always)]
fn interval_holds_sample(lo: f32, hi: f32, n: u32, fractions: &[f32; SAMPLES_1D]) -> bool {
    let (lo, hi) = (lo - COVER_MARGIN, hi + COVER_MARGIN);
    let n = n as f32;
    // A wide interval holds a sample when it meets the image.
    let wide = hi > 0.0 && lo < n;
    // Else the first sample at or after lo (no earlier than the image's first pixel): in pixel
    // k = ⌊max(lo, 0)⌋ at the first fraction not below lo − k, else in pixel k + 1 at the first
    // fraction. The interval holds a sample when that one lies in the image and within hi.
    // (Selects and non-short-circuit `&`, no branches: the triangle pass asks this of sixteen
    // boxes at once in vector lanes, and of millions of boxes on a dense mesh.)
    let x = lo.max(0.0);
    let k = x.floor();
    let r = x - k;
    let [f0, f1, f2] = *fractions;
    let f = if r <= f0 {
        f0
    } else if r <= f1 {
        f1
    } else if r <= f2 {
        f2
    } else {
        f0
    };
    let pixel = if r <= f2 { k } else { k + 1.0 };
    let narrow = (x < n) & (pixel < n) & (pixel + f <= hi);
    if hi - lo >= 1.0 {
        wide
    } else {
        narrow
    }
}

/// Whether a screen triangle's bounding box holds one of the image's samples. A triangle whose
/// box holds none covers none, so it is dropped before binning: most triangles of a mesh denser
/// than the image's samples are (about 80% of a 2M-triangle instanced mesh at 256²). The samples
/// form a product grid, so the box holds one exactly when its x and y ranges each hold a sample
/// coordinate.
#[inline(always)]
pub(crate) fn covers_a_sample(v: &[Vec3; 3], width: u32, height: u32, fractions: &[f32; SAMPLES_1D]) -> bool {
    let lo = v[0].min(v[1]).min(v[2]);
    let hi = v[0].max(v[1]).max(v[2]);
    interval_holds_sample(lo.x, hi.x, width, fractions) & interval_holds_sample(lo.y, hi.y, height, fractions)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_follow_the_tent() {
        let o = sample_offsets();
        assert_eq!(o[SAMPLES / 2], Vec2::ZERO, "the centre sample is the pixel centre");
        assert!(o.iter().all(|v| v.x.abs() < 1.0 && v.y.abs() < 1.0));
        let f = sample_fractions();
        assert!(f.windows(2).all(|w| w[0] < w[1]) && f[0] > 0.0 && f[SAMPLES_1D - 1] < 1.0, "{f:?}");
        let mean: Vec2 = o.iter().copied().sum::<Vec2>() / SAMPLES as f32;
        assert!(mean.length() < 1e-6);
    }

    /// Intervals off the image or unbounded: answered by whether they hold one of the image's
    /// sample coordinates, as for intervals inside it (the branch-free test computes every
    /// case's value and selects, so each must be right on its own).
    #[test]
    fn the_sample_test_answers_intervals_off_the_image_and_unbounded() {
        let f = sample_fractions();
        let n = 5u32;
        let (inf, last) = (f32::INFINITY, n as f32 - 1.0 + f[SAMPLES_1D - 1]);
        let cases = [
            ((-inf, inf), true),
            ((-inf, -0.5), false),
            ((-inf, f[0]), true),
            ((-3.0, -2.5), false),
            ((-0.3, f[0] - 0.1), false),
            ((last + 0.1, inf), false),
            ((n as f32, n as f32 + 0.4), false),
            ((n as f32 + 2.0, n as f32 + 9.0), false),
            ((last - 0.01, last + 0.01), true),
            ((1e30, 2e30), false),
            ((-2e30, -1e30), false),
            ((-1e30, 1e30), true),
        ];
        for ((lo, hi), want) in cases {
            assert_eq!(interval_holds_sample(lo, hi, n, &f), want, "[{lo}, {hi}] in {n} pixels");
        }
    }

    #[test]
    fn the_sample_test_never_drops_an_interval_that_holds_a_sample() {
        let fractions = sample_fractions();
        let n = 7u32;
        let coords: Vec<f32> = (0..n).flat_map(|k| fractions.map(|f| k as f32 + f)).collect();
        let (mut held, mut empty) = (0, 0);
        // Every start from −2 to n + 2 in steps of 0.0037 px, with widths around the samples'
        // spacings (0.155 and 0.423 px).
        for step in 0..((n as f32 + 4.0) / 0.0037) as u32 {
            let lo = -2.0 + step as f32 * 0.0037;
            for width in [0.0, 0.004, 0.05, 0.15, 0.16, 0.3, 0.42, 0.43, 0.6, 0.84, 0.99, 1.3] {
                let hi = lo + width;
                let answer = interval_holds_sample(lo, hi, n, &fractions);
                let holds = coords.iter().any(|&c| lo <= c && c <= hi);
                assert!(answer || !holds, "[{lo}, {hi}] holds a sample but was dropped");
                // And the test is tight: a narrow interval it keeps has a sample within its margin.
                let near = coords.iter().any(|&c| lo - 2.0 * COVER_MARGIN <= c && c <= hi + 2.0 * COVER_MARGIN);
                assert!(!answer || near || width >= 1.0 - 2.0 * COVER_MARGIN, "[{lo}, {hi}] kept without a sample");
                if holds {
                    held += 1
                } else {
                    empty += 1
                }
            }
        }
        assert!(held > 5_000 && empty > 5_000, "both cases are exercised ({held}, {empty})");
    }
}
