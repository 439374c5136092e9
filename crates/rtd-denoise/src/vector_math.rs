//! Elementary functions on the denoiser's per-pixel paths in arithmetic the compiler
//! vectorises: no library calls, no branches (selects instead), and float-to-integer
//! conversions done with the round-to-nearest magic number rather than Rust's saturating
//! `as` casts, which compile to scalar code. Each is held to the library's function by a test.
//!
//! [`multiversioned!`] compiles a row function for the widest instruction set this CPU has, so
//! loops of these functions vectorise at that width.

/// 1.5 · 2²³: adding it to an f32 of magnitude below 2²² rounds to the nearest integer (ties to
/// even), which then sits in the sum's low mantissa bits.
const ROUNDER: f32 = 12_582_912.0;

/// ln 2 in two parts, the first with a short mantissa, so n · the first is exact for |n| < 2⁹.
const LN2_HIGH: f32 = 0.693_145_75;
/// The rest of ln 2 after [`LN2_HIGH`].
const LN2_LOW: f32 = 1.428_606_8e-6;

/// Splits x (in [−87.3, 88.3]; from 88.38 on, 2ⁿ overflows to infinity) as x = n · ln 2 + f
/// with n an integer and |f| ≤ ln 2 / 2; returns (2ⁿ, f).
#[inline(always)]
fn reduce(x: f32) -> (f32, f32) {
    let t = x * std::f32::consts::LOG2_E + ROUNDER;
    let n = t - ROUNDER;
    // n as an integer: the low mantissa bits of t, less ROUNDER's own.
    let ni = t.to_bits().wrapping_sub(ROUNDER.to_bits()) as i32;
    let scale = f32::from_bits((ni.wrapping_add(127) as u32) << 23);
    // f = x − n·ln2 in two parts, so the product's rounding does not reach f.
    (scale, (x - n * LN2_HIGH) - n * LN2_LOW)
}

/// e^f − 1 for |f| ≤ ln 2 / 2: the Taylor series to f⁷ (truncation below 2e-8 relative), with
/// no cancellation near 0.
#[inline(always)]
fn exp_m1_reduced(f: f32) -> f32 {
    let tail = 1.0 / 24.0 + f * (1.0 / 120.0 + f * (1.0 / 720.0 + f * (1.0 / 5040.0)));
    f * (1.0 + f * (0.5 + f * (1.0 / 6.0 + f * tail)))
}

/// e^x for x ≤ 0, relative error under 1e-6; 0 below −87 (where e^x nears f32's smallest
/// normal), and e^−87 for NaN, so a broken logit cannot spread NaN. The softmax of the
/// kernel-predicting heads takes 25 per pixel.
#[inline(always)]
pub fn exp_nonpositive(x: f32) -> f32 {
    debug_assert!(!(x > 0.0), "exp_nonpositive({x})");
    let (scale, f) = reduce(x.max(-87.0));
    let e = scale + scale * exp_m1_reduced(f);
    if x < -87.0 {
        0.0
    } else {
        e
    }
}

/// e^x − 1 for x in [0, 88], relative error under 1e-6 (x is clamped to that range; NaN stays
/// NaN, so callers replace it first): the inverse of the colour transfer, once per output
/// pixel and channel.
#[inline(always)]
pub fn exp_m1(x: f32) -> f32 {
    let (scale, f) = reduce(x.clamp(0.0, 88.0));
    // e^x − 1 = 2ⁿ(e^f − 1) + (2ⁿ − 1): exact for n = 0, and no cancellation above.
    scale * exp_m1_reduced(f) + (scale - 1.0)
}

/// The logistic function 1 / (1 + e^−x), through e^−|x| ≤ 1 so nothing overflows; NaN gives
/// about 0.
#[inline(always)]
pub fn logistic(x: f32) -> f32 {
    let e = exp_nonpositive(-x.abs());
    let r = 1.0 / (1.0 + e);
    if x >= 0.0 {
        r
    } else {
        e * r
    }
}

/// ln(1 + x) for x ≥ 0, within 2e-7 of `f32::ln_1p` (absolute where the result is below 1,
/// relative above; tested from 1e-12 to 1e30): the colour transfer, once per input pixel and
/// channel (the library call was half of encoding's time).
#[inline(always)]
pub fn ln_1p(x: f32) -> f32 {
    // u = 1 + x = 2^e · m with m in [√½, √2): ln u = e · ln 2 + ln m.
    let u = 1.0 + x;
    let bits = u.to_bits();
    // Exponent relative to √½'s, so the mantissa lands in [√½, √2).
    let shifted = bits.wrapping_sub(0x3f35_04f3);
    let e = (shifted as i32 >> 23) as f32;
    let m = f32::from_bits((shifted & 0x007f_ffff).wrapping_add(0x3f35_04f3));
    // ln m = 2 atanh(s), s = (m − 1) / (m + 1), |s| ≤ 0.172: the odd series to s⁹.
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let series = 2.0 + s2 * (2.0 / 3.0 + s2 * (2.0 / 5.0 + s2 * (2.0 / 7.0 + s2 * (2.0 / 9.0))));
    e * std::f32::consts::LN_2 + s * series
}

/// Defines a function whose body is compiled twice, for the build's baseline (SSE4.2 with the
/// repository's `.cargo/config.toml`) and with AVX2,
/// and runs the AVX2 build where this CPU has it, so the loops of [`exp_m1`] and the like in it
/// run eight lanes wide. No fused multiply-add is enabled, so both builds give the same bits.
/// The body is a function of its own rather than a closure because only an
/// `#[inline(always)]` function is sure to be compiled into the AVX2 caller.
macro_rules! multiversioned {
    ($(#[$meta:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $body:block) => {
        $(#[$meta])*
        $vis fn $name($($arg: $ty),*) {
            #[inline(always)]
            fn body($($arg: $ty),*) $body
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2")]
            unsafe fn avx2($($arg: $ty),*) {
                body($($arg),*)
            }
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2, checked just above.
                return unsafe { avx2($($arg),*) };
            }
            body($($arg),*)
        }
    };
}
pub(crate) use multiversioned;

multiversioned! {
    /// dst = ln(1 + max(dst, 0)) in place: the colour transfer of a row of exposed values.
    pub fn ln_1p_row(dst: &mut [f32]) {
        dst.iter_mut().for_each(|v| *v = ln_1p(v.max(0.0)));
    }
}

multiversioned! {
    /// dst = e^min(src, top) − 1, elementwise, clamped below at 0 (NaN counts as 0): the
    /// colour transfer undone for a row.
    pub fn exp_m1_row(dst: &mut [f32], src: &[f32], top: f32) {
        dst.iter_mut().zip(src).for_each(|(v, &y)| *v = exp_m1(if y.is_nan() { 0.0 } else { y.min(top) }));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points spread geometrically over (lo, hi), with both ends.
    fn spread(lo: f64, hi: f64, n: usize) -> impl Iterator<Item = f32> {
        (0..=n).map(move |i| (lo * (hi / lo).powf(i as f64 / n as f64)) as f32)
    }

    #[test]
    fn exp_nonpositive_matches_the_library_within_1e_minus_6() {
        for x in spread(1e-9, 87.0, 20_000).map(|x| -x) {
            let (a, b) = (exp_nonpositive(x), x.exp());
            assert!((a - b).abs() <= 1e-6 * b, "{x}: {a} vs {b}");
        }
        assert_eq!(exp_nonpositive(-100.0), 0.0);
        assert_eq!(exp_nonpositive(f32::NEG_INFINITY), 0.0);
        assert_eq!(exp_nonpositive(0.0), 1.0);
        assert!(exp_nonpositive(f32::NAN).is_finite());
    }

    #[test]
    fn exp_m1_matches_the_library_relatively_near_zero_and_far_from_it() {
        for x in spread(1e-12, 88.0, 40_000) {
            let (a, b) = (exp_m1(x), x.exp_m1());
            assert!((a - b).abs() <= 1e-6 * b, "{x}: {a} vs {b}");
        }
        assert_eq!(exp_m1(0.0), 0.0);
        assert_eq!(exp_m1(-3.0), 0.0, "clamped to 0");
        assert!(exp_m1(1e9).is_finite(), "clamped to 88");
    }

    #[test]
    fn logistic_matches_its_definition_on_both_sides_and_saturates_cleanly() {
        for x in spread(1e-9, 100.0, 20_000).flat_map(|x| [x, -x]) {
            let want = 1.0 / (1.0 + (-(x as f64)).exp());
            let got = logistic(x) as f64;
            // Below −87, where e^x is flushed to 0, the answer is under 2e-38 and rounds to 0.
            assert!((got - want).abs() <= 1e-6 * want + 2e-38, "{x}: {got} vs {want}");
        }
        assert_eq!(logistic(0.0), 0.5);
        assert_eq!(logistic(f32::INFINITY), 1.0);
        assert_eq!(logistic(f32::NEG_INFINITY), 0.0);
        assert!(logistic(f32::NAN).is_finite());
    }

    #[test]
    fn ln_1p_matches_the_library() {
        for x in spread(1e-12, 1e30, 40_000) {
            let err = (ln_1p(x) - x.ln_1p()).abs();
            assert!(err <= 2e-7 * x.ln_1p().max(1.0), "error {err} at x = {x}");
        }
        assert_eq!(ln_1p(0.0), 0.0);
    }

    #[test]
    fn the_rows_give_the_functions_bits_whichever_build_runs() {
        let xs: Vec<f32> = spread(1e-6, 80.0, 4999).collect();
        let mut logs = xs.clone();
        ln_1p_row(&mut logs);
        let mut exps = vec![0.0; xs.len()];
        exp_m1_row(&mut exps, &xs, 60.0);
        for (i, &x) in xs.iter().enumerate() {
            assert_eq!(logs[i].to_bits(), ln_1p(x).to_bits(), "ln_1p at {x}");
            assert_eq!(exps[i].to_bits(), exp_m1(x.min(60.0)).to_bits(), "exp_m1 at {x}");
        }
        // Nothing non-finite comes out of a row with NaN and infinities in it.
        let bad = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -1.0];
        let mut logs = bad;
        ln_1p_row(&mut logs);
        let mut exps = [1.0; 4];
        exp_m1_row(&mut exps, &bad, 60.0);
        assert!(logs.iter().chain(&exps).all(|v| v.is_finite()), "{logs:?} {exps:?}");
        assert_eq!(exps[0], 0.0, "NaN counts as 0");
    }
}
