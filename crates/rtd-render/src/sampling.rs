//! Warping functions from [0,1)² to geometric domains, discrete distributions and MIS weights.

use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

/// An orthonormal basis around a unit normal `n` (Duff et al. 2017, branchless).
#[derive(Debug, Clone, Copy)]
pub struct Frame {
    /// Tangent.
    pub s: Vec3,
    /// Bitangent.
    pub t: Vec3,
    /// Normal.
    pub n: Vec3,
}

impl Frame {
    /// A frame whose z axis is the unit vector `n`.
    #[inline]
    pub fn from_normal(n: Vec3) -> Self {
        let sign = 1f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { s, t, n }
    }

    /// World to local.
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    /// Local to world.
    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// Concentric map of the square to the unit disk (Shirley–Chiu).
#[inline]
pub fn sample_disk_concentric(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) =
        if o.x.abs() > o.y.abs() { (o.x, PI / 4.0 * (o.y / o.x)) } else { (o.y, PI / 2.0 - PI / 4.0 * (o.x / o.y)) };
    let (s, c) = theta.sin_cos();
    Vec2::new(r * c, r * s)
}

/// Cosine-weighted direction on the +z hemisphere; pdf = cosθ/π.
#[inline]
pub fn sample_cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = sample_disk_concentric(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

/// Pdf of [`sample_cosine_hemisphere`].
#[inline]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * FRAC_1_PI
}

/// Uniform direction on the unit sphere; pdf = 1/(4π).
#[inline]
pub fn sample_uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (s, c) = (2.0 * PI * u.y).sin_cos();
    Vec3::new(r * c, r * s, z)
}

/// Uniform barycentrics (b0, b1, b2) on a triangle.
#[inline]
pub fn sample_triangle(u: Vec2) -> Vec3 {
    let su = u.x.sqrt();
    let b0 = 1.0 - su;
    let b1 = u.y * su;
    Vec3::new(b0, b1, (1.0 - b0 - b1).max(0.0))
}

/// Importance-samples the tent (triangle) filter of radius 1 along one axis: returns an
/// offset in (−1, 1) with density 1 − |x|, so every filter sample has weight 1.
#[inline]
pub fn sample_tent(u: f32) -> f32 {
    if u < 0.5 {
        (2.0 * u).sqrt() - 1.0
    } else {
        1.0 - (2.0 - 2.0 * u).sqrt()
    }
}

/// Power heuristic (β = 2) weight of strategy `f` against strategy `g`.
#[inline]
pub fn power_heuristic(pdf_f: f32, pdf_g: f32) -> f32 {
    let (f, g) = (pdf_f * pdf_f, pdf_g * pdf_g);
    if f.is_infinite() {
        return 1.0;
    }
    if f + g > 0.0 {
        f / (f + g)
    } else {
        0.0
    }
}

/// A piecewise-constant 1D distribution over `n` bins of [0,1), sampled by inverting its CDF.
#[derive(Debug, Clone)]
pub struct Distribution1D {
    /// Bin weights (non-negative).
    pub func: Vec<f32>,
    /// CDF with `n + 1` entries from 0 to 1.
    pub cdf: Vec<f32>,
    /// Sum of weights divided by n (the integral over [0,1)).
    pub integral: f32,
}

impl Distribution1D {
    /// Builds the distribution; all-zero or non-finite weights fall back to uniform.
    pub fn new(weights: &[f32]) -> Self {
        let n = weights.len().max(1);
        let func: Vec<f32> =
            (0..n).map(|i| weights.get(i).copied().filter(|w| w.is_finite() && *w > 0.0).unwrap_or(0.0)).collect();
        let mut cdf = Vec::with_capacity(n + 1);
        let mut acc = 0.0f64;
        cdf.push(0.0);
        for &w in &func {
            acc += w as f64 / n as f64;
            cdf.push(acc as f32);
        }
        let integral = acc as f32;
        if integral > 0.0 {
            for c in cdf.iter_mut() {
                *c = (*c as f64 / acc) as f32;
            }
        } else {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f32 / n as f32;
            }
        }
        cdf[n] = 1.0;
        Distribution1D { func, cdf, integral }
    }

    /// Number of bins.
    pub fn len(&self) -> usize {
        self.func.len()
    }

    /// True if the distribution has no bins (never, after `new`).
    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }

    /// Probability of bin `i` under discrete sampling.
    #[inline]
    pub fn pmf(&self, i: usize) -> f32 {
        self.cdf[i + 1] - self.cdf[i]
    }

    /// Samples a bin: returns (bin, probability of that bin, u remapped to [0,1) within it).
    #[inline]
    pub fn sample_discrete(&self, u: f32) -> (usize, f32, f32) {
        let i = self.cdf.partition_point(|&c| c <= u).saturating_sub(1).min(self.len() - 1);
        let p = self.pmf(i);
        let remapped = if p > 0.0 { ((u - self.cdf[i]) / p).clamp(0.0, 1.0 - f32::EPSILON) } else { 0.0 };
        (i, p, remapped)
    }

    /// Samples a continuous value in [0,1): returns (x, density at x, bin).
    #[inline]
    pub fn sample_continuous(&self, u: f32) -> (f32, f32, usize) {
        let (i, p, du) = self.sample_discrete(u);
        let n = self.len() as f32;
        ((i as f32 + du) / n, p * n, i)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_is_orthonormal() {
        for n in [Vec3::Z, Vec3::NEG_Z, Vec3::new(0.3, -0.4, 0.866).normalize(), Vec3::new(0.0, -1.0, 1e-7).normalize()]
        {
            let f = Frame::from_normal(n);
            assert!((f.s.length() - 1.0).abs() < 1e-5 && (f.t.length() - 1.0).abs() < 1e-5);
            assert!(f.s.dot(f.t).abs() < 1e-5 && f.s.dot(n).abs() < 1e-5 && f.t.dot(n).abs() < 1e-5);
            let v = Vec3::new(0.1, 0.2, 0.3);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-5);
        }
    }

    #[test]
    fn tent_samples_have_tent_density() {
        // CDF of the tent at 0 is 1/2, at -0.5 it is 1/8.
        assert!((sample_tent(0.5)).abs() < 1e-6);
        assert!((sample_tent(0.125) + 0.5).abs() < 1e-6);
        assert!((sample_tent(0.875) - 0.5).abs() < 1e-6);
    }

    #[test]
    fn distribution_samples_proportionally() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0]);
        assert!((d.pmf(0) - 0.25).abs() < 1e-6 && d.pmf(1) == 0.0 && (d.pmf(2) - 0.75).abs() < 1e-6);
        assert_eq!(d.sample_discrete(0.2).0, 0);
        assert_eq!(d.sample_discrete(0.25).0, 2);
        assert_eq!(d.sample_discrete(0.999_999).0, 2);
        let (x, pdf, _) = d.sample_continuous(0.5);
        assert!(x > 2.0 / 3.0 && (pdf - 2.25).abs() < 1e-5);
        let z = Distribution1D::new(&[0.0, f32::NAN]);
        assert!((z.pmf(0) - 0.5).abs() < 1e-6);
    }
}
