//! The sheen lobe of `KHR_materials_sheen`: Estevez and Kulla's "Charlie" fibre distribution
//! ("Production Friendly Microfacet Sheen BRDF", 2017) with the paper's fitted Smith shadowing
//! (the extension's recommended visibility), and its tabulated directional albedo for layering
//! the sheen over the base.

use std::f32::consts::{FRAC_1_PI, PI};
use std::sync::OnceLock;

use glam::Vec3;

/// The smallest perceptual roughness rendered (Filament's floor): below it the distribution is
/// narrower than f32 and a quadrature resolve.
pub const MIN_SHEEN_ROUGHNESS: f32 = 0.07;

/// Table points per axis (roughness and μ).
const N: usize = 32;

/// The Charlie sheen lobe of one perceptual roughness, without its colour.
#[derive(Debug, Clone, Copy)]
pub struct Charlie {
    /// 1/α, the exponent of sin θ_h (α = roughness²).
    inv_alpha: f32,
}

impl Charlie {
    /// The lobe of perceptual roughness `r` (clamped to [`MIN_SHEEN_ROUGHNESS`], 1).
    #[inline]
    pub fn from_roughness(r: f32) -> Self {
        let r = r.clamp(MIN_SHEEN_ROUGHNESS, 1.0);
        Charlie { inv_alpha: 1.0 / (r * r) }
    }

    /// D(h) = (2 + 1/α) sin^(1/α) θ_h / (2π).
    #[inline]
    fn d(&self, h: Vec3) -> f32 {
        let sin2 = (1.0 - h.z * h.z).max(0.0);
        (2.0 + self.inv_alpha) * sin2.powf(0.5 * self.inv_alpha) / (2.0 * PI)
    }

    /// f(wo, wi) = D(h) · V(wo, wi) for a white sheen, both directions above the surface, with
    /// Estevez and Kulla's height-correlated visibility V = 1 / ((1 + Λ(wo) + Λ(wi)) 4 cos_o cos_i).
    ///
    /// Never inlined: inlined into [`crate::bsdf::Bsdf::eval`]'s loop over the lobes, its `powf`
    /// and two `expf` were run for every evaluation of every BSDF, sheen or not (the optimiser
    /// computed the lobe ahead of the test that skips it, its maths being free of side effects),
    /// about 4% of a render's time on scenes without a sheen.
    #[inline(never)]
    pub fn f(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let h = (wo + wi).normalize_or_zero();
        if h == Vec3::ZERO {
            return 0.0;
        }
        let v = 1.0 / ((1.0 + self.lambda(wo.z) + self.lambda(wi.z)) * 4.0 * wo.z * wi.z);
        let f = self.d(h) * v;
        if f.is_finite() {
            f
        } else {
            0.0
        }
    }

    /// The paper's fitted Smith Λ(cos θ) of the Charlie distribution: exp(L(cos θ)) below
    /// cos θ = 0.5 and its mirrored continuation exp(2L(0.5) − L(1 − cos θ)) above.
    #[inline]
    fn lambda(&self, cos: f32) -> f32 {
        if cos < 0.5 {
            self.fit(cos).exp()
        } else {
            (2.0 * self.fit(0.5) - self.fit(1.0 - cos)).exp()
        }
    }

    /// L(x) = a / (1 + b xᶜ) + d x + e, its coefficients interpolated between the paper's
    /// fits at α = 0 and α = 1 by (1 − α)².
    #[inline]
    fn fit(&self, x: f32) -> f32 {
        let t = (1.0 - 1.0 / self.inv_alpha).powi(2);
        let mix = |at1: f32, at0: f32| at1 + (at0 - at1) * t;
        let (a, b, c) = (mix(21.5473, 25.3245), mix(3.82987, 3.32435), mix(0.19823, 0.16801));
        let (d, e) = (mix(-1.97760, -1.27393), mix(-4.32054, -4.85967));
        a / (1.0 + b * x.powf(c)) + d * x + e
    }
}

/// Directional albedos of the white Charlie lobe, E(μ, r) = ∫ f cos θ_i dω_i.
///
/// The lobe is not energy-conserving everywhere: towards grazing at low roughness E exceeds 1
/// (about 1.1 at μ = 0.05 and 2.5 at μ = 0.01 for roughness 0.07), so the BSDF divides the sheen
/// by max(1, E(μ_o)).
pub struct SheenAlbedo {
    /// ln E at [roughness][μ]: roughness evenly spaced on [`MIN_SHEEN_ROUGHNESS`, 1], μ evenly
    /// in √μ. E spans twenty decades at low roughness, nearly exponentially in μ, so the table
    /// interpolates its logarithm.
    ln_e: Vec<[f32; N]>,
}

/// The perceptual roughness of table row `k`.
fn roughness_at(k: usize) -> f32 {
    MIN_SHEEN_ROUGHNESS + (1.0 - MIN_SHEEN_ROUGHNESS) * k as f32 / (N - 1) as f32
}

/// The μ of table column `j`: spaced evenly in √μ, so that grazing angles, where the albedo
/// changes fastest, get more of them.
fn mu_at(j: usize) -> f32 {
    let x = j as f32 / (N - 1) as f32;
    (x * x).max(1e-4)
}

/// The shared table, computed on first use (tens of milliseconds, and only by scenes with a
/// sheen).
pub fn sheen_albedo() -> &'static SheenAlbedo {
    static TABLE: OnceLock<SheenAlbedo> = OnceLock::new();
    TABLE.get_or_init(SheenAlbedo::compute)
}

impl SheenAlbedo {
    fn compute() -> Self {
        // Midpoint rule over cos θ_i = x² (points gather at grazing, where the lobe peaks) and
        // φ over [0, π] (the integrand is even in φ for wo in the xz-plane).
        const NX: usize = 96;
        const NP: usize = 32;
        let e = (0..N)
            .map(|k| {
                let lobe = Charlie::from_roughness(roughness_at(k));
                let mut row = [0.0f32; N];
                for (j, out) in row.iter_mut().enumerate() {
                    let mu = mu_at(j);
                    let wo = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
                    let mut sum = 0.0f64;
                    for a in 0..NX {
                        let x = (a as f32 + 0.5) / NX as f32;
                        let ci = x * x;
                        let si = (1.0 - ci * ci).max(0.0).sqrt();
                        for b in 0..NP {
                            let phi = PI * (b as f32 + 0.5) / NP as f32;
                            let wi = Vec3::new(si * phi.cos(), si * phi.sin(), ci);
                            // dω = dcos dφ = 2x dx dφ.
                            sum += (lobe.f(wo, wi) * ci * 2.0 * x) as f64;
                        }
                    }
                    // Both halves of φ: 2 · π/NP · 1/NX per point.
                    *out = (sum * 2.0 * PI as f64 / (NP * NX) as f64).max(1e-30).ln() as f32;
                }
                row
            })
            .collect();
        SheenAlbedo { ln_e: e }
    }

    /// E(μ) of the white lobe of perceptual roughness `r`, bilinear in the table.
    pub fn albedo(&self, r: f32, mu: f32) -> f32 {
        let r = (r.clamp(MIN_SHEEN_ROUGHNESS, 1.0) - MIN_SHEEN_ROUGHNESS) / (1.0 - MIN_SHEEN_ROUGHNESS);
        let (fr, fm) = (r * (N - 1) as f32, mu.clamp(0.0, 1.0).sqrt() * (N - 1) as f32);
        let (k, j) = ((fr as usize).min(N - 2), (fm as usize).min(N - 2));
        let (tr, tm) = (fr - k as f32, fm - j as f32);
        let row = |k: usize| self.ln_e[k][j] * (1.0 - tm) + self.ln_e[k][j + 1] * tm;
        (row(k) * (1.0 - tr) + row(k + 1) * tr).exp()
    }
}

/// The cosine-weighted pdf the sheen is sampled with.
#[inline]
pub fn sheen_pdf(wi: Vec3) -> f32 {
    wi.z.max(0.0) * FRAC_1_PI
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_charlie_distribution_is_normalised_and_its_albedo_tabulated() {
        // ∫ D(h) cos θ_h dω_h = 1 over the hemisphere, for every roughness.
        for &r in &[0.07f32, 0.2, 0.5, 1.0] {
            let lobe = Charlie::from_roughness(r);
            let n = 4000;
            let sum: f64 = (0..n)
                .map(|i| {
                    let c = (i as f32 + 0.5) / n as f32;
                    let h = Vec3::new((1.0 - c * c).sqrt(), 0.0, c);
                    (lobe.d(h) * c) as f64 * 2.0 * PI as f64 / n as f64
                })
                .sum();
            assert!((sum - 1.0).abs() < 2e-3, "r {r}: ∫D cos = {sum}");
        }
        // The table against a fine midpoint rule over the hemisphere (2000 × 400 points).
        let t = sheen_albedo();
        for &(r, mu) in &[(0.07f32, 0.2f32), (0.3, 0.05), (0.3, 0.6), (1.0, 0.02), (1.0, 1.0)] {
            let lobe = Charlie::from_roughness(r);
            let wo = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
            let (nc, np) = (2000, 400);
            let mut sum = 0.0f64;
            for a in 0..nc {
                let c = (a as f32 + 0.5) / nc as f32;
                let s = (1.0 - c * c).sqrt();
                for b in 0..np {
                    let phi = 2.0 * PI * (b as f32 + 0.5) / np as f32;
                    sum += (lobe.f(wo, Vec3::new(s * phi.cos(), s * phi.sin(), c)) * c) as f64;
                }
            }
            let e = sum * 2.0 * PI as f64 / (nc * np) as f64;
            let got = t.albedo(r, mu) as f64;
            assert!((got - e).abs() < 2e-3 + 0.02 * e, "r {r} μ {mu}: table {got} vs {e}");
        }
    }
}
