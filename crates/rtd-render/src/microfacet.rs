//! The isotropic GGX (Trowbridge–Reitz) microfacet distribution with Smith masking and
//! visible-normal sampling (Heitz 2018), in the local frame where the normal is +z.

use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// GGX with roughness parameter α (= perceptual roughness²).
#[derive(Debug, Clone, Copy)]
pub struct Ggx {
    /// Width parameter α.
    pub alpha: f32,
}

/// Below this α a lobe is treated as a perfect (delta) reflector or refractor.
pub const SMOOTH_ALPHA: f32 = 1e-3;

impl Ggx {
    /// The distribution for perceptual roughness `r` (α = r²).
    #[inline]
    pub fn from_roughness(r: f32) -> Self {
        Ggx { alpha: (r * r).max(0.0) }
    }

    /// True if the lobe is effectively a delta.
    #[inline]
    pub fn is_smooth(&self) -> bool {
        self.alpha < SMOOTH_ALPHA
    }

    /// Normal distribution D(m).
    #[inline]
    pub fn d(&self, m: Vec3) -> f32 {
        let cos2 = m.z * m.z;
        if cos2 <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        // D = α² / (π (cos²θ (α² − 1) + 1)²)
        let k = cos2 * (a2 - 1.0) + 1.0;
        a2 / (PI * k * k)
    }

    /// Smith Λ(w).
    #[inline]
    pub fn lambda(&self, w: Vec3) -> f32 {
        let cos2 = w.z * w.z;
        let sin2 = (1.0 - cos2).max(0.0);
        if cos2 <= 0.0 {
            return f32::INFINITY;
        }
        let tan2 = sin2 / cos2;
        ((1.0 + self.alpha * self.alpha * tan2).sqrt() - 1.0) * 0.5
    }

    /// Smith terms for a pair of directions: (height-correlated G2(wo, wi), masking G1(wo)).
    #[inline]
    pub fn smith(&self, wo: Vec3, wi: Vec3) -> (f32, f32) {
        let (lo, li) = (self.lambda(wo), self.lambda(wi));
        (1.0 / (1.0 + lo + li), 1.0 / (1.0 + lo))
    }

    /// Samples a visible normal as seen from `w` (either hemisphere); the result has m.z > 0.
    #[inline]
    pub fn sample_visible(&self, w: Vec3, u: Vec2) -> Vec3 {
        let a = self.alpha;
        // Stretch to the hemisphere configuration.
        let mut wh = Vec3::new(a * w.x, a * w.y, w.z).normalize();
        if wh.z < 0.0 {
            wh = -wh;
        }
        let t1 = if wh.z < 0.99999 { Vec3::Z.cross(wh).normalize() } else { Vec3::X };
        let t2 = wh.cross(t1);
        // Uniform disk sample, warped towards the visible half-disk.
        let r = u.x.sqrt();
        let phi = 2.0 * PI * u.y;
        let (px, py0) = (r * phi.cos(), r * phi.sin());
        let h = (1.0 - px * px).max(0.0).sqrt();
        let s = (1.0 + wh.z) * 0.5;
        let py = (1.0 - s) * h + s * py0;
        let pz = (1.0 - px * px - py * py).max(0.0).sqrt();
        let nh = t1 * px + t2 * py + wh * pz;
        // Unstretch.
        Vec3::new(a * nh.x, a * nh.y, nh.z.max(1e-6)).normalize()
    }
}

/// Unpolarised Fresnel reflectance of a dielectric interface with relative IOR `eta`
/// (inside / outside), for the cosine of the incident angle measured from the outside normal.
#[inline]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let (mut cos_i, mut eta) = (cos_i.clamp(-1.0, 1.0), eta);
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
    }
    let sin2_i = 1.0 - cos_i * cos_i;
    let sin2_t = sin2_i / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0; // total internal reflection
    }
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    (r_parl * r_parl + r_perp * r_perp) * 0.5
}

/// Schlick's approximation F0 + (1 − F0)(1 − cos)^5, per channel.
#[inline]
pub fn fresnel_schlick(f0: Vec3, cos: f32) -> Vec3 {
    let m = (1.0 - cos.abs()).clamp(0.0, 1.0);
    let m5 = (m * m) * (m * m) * m;
    f0 + (Vec3::ONE - f0) * m5
}

/// Refracts `wi` (pointing away from the surface) through normal `n` with relative IOR `eta`.
/// Returns (transmitted direction, the IOR ratio actually used), or None on total internal reflection.
#[inline]
pub fn refract(wi: Vec3, mut n: Vec3, mut eta: f32) -> Option<(Vec3, f32)> {
    let mut cos_i = n.dot(wi);
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
        n = -n;
    }
    let sin2_i = (1.0 - cos_i * cos_i).max(0.0);
    let sin2_t = sin2_i / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((-wi / eta + (cos_i / eta - cos_t) * n, eta))
}

/// Mirror reflection of `wo` about `n`.
#[inline]
pub fn reflect(wo: Vec3, n: Vec3) -> Vec3 {
    -wo + 2.0 * wo.dot(n) * n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn d_is_normalised() {
        // ∫ D(m) cosθ dm = 1, numerically over the hemisphere.
        for &r in &[0.2f32, 0.5, 1.0] {
            let g = Ggx::from_roughness(r);
            let n = 200_000;
            let mut sum = 0.0f64;
            for i in 0..n {
                let ct = (i as f64 + 0.5) / n as f64;
                let m = Vec3::new((1.0 - ct * ct).sqrt() as f32, 0.0, ct as f32);
                sum += g.d(m) as f64 * ct * 2.0 * std::f64::consts::PI / n as f64;
            }
            assert!((sum - 1.0).abs() < 0.02, "r={r}: {sum}");
        }
    }

    #[test]
    fn fresnel_known_values() {
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        assert_eq!(fresnel_dielectric(1.0, 1.0), 0.0);
        assert_eq!(fresnel_dielectric(-0.1, 1.5), 1.0, "TIR from inside at grazing angle");
        let (t, _) = refract(Vec3::new(0.6, 0.0, 0.8), Vec3::Z, 1.5).unwrap();
        // Snell: sinθt = 0.6 / 1.5.
        assert!((t.x + 0.4).abs() < 1e-6 && t.z < 0.0 && (t.length() - 1.0).abs() < 1e-6);
    }
}
