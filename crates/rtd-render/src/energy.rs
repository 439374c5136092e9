//! Energy compensation for GGX: tabulated directional albedos of the single-scattering lobe, for
//! Kulla and Conty's multiple-scattering term ("Revisiting Physically Based Shading at
//! Imageworks", 2017) and for albedo-scaled layering of the specular layer over the diffuse;
//! and of the rough dielectric interface (reflection plus transmission, [`glass_albedo`]), by
//! whose inverse a rough glass lobe is scaled so that it loses no energy.
//!
//! With Schlick's Fresnel F = F0 + (1 − F0)(1 − c)⁵, the single-scattering albedo splits into
//! E(μ) = F0·A(μ, r) + B(μ, r): A weights the lobe by 1 − (1 − c)⁵ and B by (1 − c)⁵, both with
//! F = 1 otherwise. Both are tabulated once over roughness r and μ = cos θ, by quadrature of the
//! visible-normal estimator G2/G1, and looked up bilinearly.

use std::sync::OnceLock;

use glam::{Vec2, Vec3};

use crate::microfacet::{reflect, Ggx};

/// Table points per axis (roughness and μ).
const N: usize = 32;
/// Quadrature points per axis for each table entry.
const Q: usize = 24;
/// Smallest μ tabulated (the first point, μ = 0, is computed here).
const MU_MIN: f32 = 1e-4;

/// Single-scattering GGX albedo tables.
pub struct GgxAlbedo {
    /// A(μ, r) at [r][μ].
    a: Vec<[f32; N]>,
    /// B(μ, r) at [r][μ].
    b: Vec<[f32; N]>,
    /// Cosine-weighted hemispherical averages 2∫A μ dμ and 2∫B μ dμ, per roughness.
    avg: Vec<(f32, f32)>,
}

/// The shared tables, computed on first use (a few milliseconds).
pub fn ggx_albedo() -> &'static GgxAlbedo {
    static TABLE: OnceLock<GgxAlbedo> = OnceLock::new();
    TABLE.get_or_init(GgxAlbedo::compute)
}

/// The μ of table column `j`: columns are spaced evenly in √μ, so that grazing angles, where the
/// albedo changes fastest, get more of them.
fn mu_at(j: usize) -> f32 {
    let x = j as f32 / (N - 1) as f32;
    (x * x).max(MU_MIN)
}

impl GgxAlbedo {
    fn compute() -> Self {
        let (mut a, mut b, mut avg) = (Vec::with_capacity(N), Vec::with_capacity(N), Vec::with_capacity(N));
        for k in 0..N {
            let ggx = Ggx::from_roughness(k as f32 / (N - 1) as f32);
            let (mut ra, mut rb) = ([0.0f32; N], [0.0f32; N]);
            for j in 0..N {
                let mu = mu_at(j);
                let wo = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
                let (mut sa, mut sb) = (0.0f64, 0.0f64);
                for s in 0..Q * Q {
                    let u = Vec2::new(((s % Q) as f32 + 0.5) / Q as f32, ((s / Q) as f32 + 0.5) / Q as f32);
                    // Visible-normal sampling: f·cos/pdf = F·G2/G1.
                    let wm = ggx.sample_visible(wo, u);
                    let wi = reflect(wo, wm);
                    if wi.z <= 0.0 {
                        continue;
                    }
                    let (g2, g1) = ggx.smith(wo, wi);
                    let w = (g2 / g1) as f64;
                    let m = (1.0 - wo.dot(wm).clamp(0.0, 1.0)) as f64;
                    let m5 = m * m * m * m * m;
                    sa += w * (1.0 - m5);
                    sb += w * m5;
                }
                ra[j] = (sa / (Q * Q) as f64) as f32;
                rb[j] = (sb / (Q * Q) as f64) as f32;
            }
            // 2∫ E μ dμ by the trapezoid rule over the μ grid.
            let avg_of = |t: &[f32; N]| {
                let mut s = 0.0f32;
                let mut prev = (0.0f32, t[0]);
                for (j, &v) in t.iter().enumerate().skip(1) {
                    let mu = mu_at(j);
                    s += (mu - prev.0) * (mu * v + prev.0 * prev.1);
                    prev = (mu, v);
                }
                s
            };
            avg.push((avg_of(&ra), avg_of(&rb)));
            a.push(ra);
            b.push(rb);
        }
        GgxAlbedo { a, b, avg }
    }

    /// Bilinear lookup of a table at roughness `r` and cosine `mu`.
    fn lookup(table: &[[f32; N]], r: f32, mu: f32) -> f32 {
        let (fr, fm) = (r.clamp(0.0, 1.0) * (N - 1) as f32, mu.abs().clamp(0.0, 1.0).sqrt() * (N - 1) as f32);
        let (k, j) = ((fr as usize).min(N - 2), (fm as usize).min(N - 2));
        let (tr, tm) = (fr - k as f32, fm - j as f32);
        let row = |k: usize| table[k][j] * (1.0 - tm) + table[k][j + 1] * tm;
        row(k) * (1.0 - tr) + row(k + 1) * tr
    }

    /// Single-scattering albedo at cosine `mu` of a GGX lobe of roughness `r` with Schlick
    /// Fresnel from `f0`: F0·A + B.
    pub fn albedo(&self, r: f32, mu: f32, f0: f32) -> f32 {
        f0 * Self::lookup(&self.a, r, mu) + Self::lookup(&self.b, r, mu)
    }

    /// Its cosine-weighted hemispherical average 2∫ E(μ) μ dμ.
    pub fn average(&self, r: f32, f0: f32) -> f32 {
        let fr = r.clamp(0.0, 1.0) * (N - 1) as f32;
        let k = (fr as usize).min(N - 2);
        let t = fr - k as f32;
        let at = |k: usize| f0 * self.avg[k].0 + self.avg[k].1;
        at(k) * (1.0 - t) + at(k + 1) * t
    }
}

/// Kulla–Conty's Fresnel of the multiply-scattered energy, per channel:
/// F_avg² E_avg / (1 − F_avg (1 − E_avg)), with Schlick's F_avg = F0 + (1 − F0)/21.
pub fn multiple_scattering_fresnel(f0: Vec3, e_avg: f32) -> Vec3 {
    let f_avg = f0 + (Vec3::ONE - f0) / 21.0;
    f_avg * f_avg * e_avg / (Vec3::ONE - f_avg * (1.0 - e_avg)).max(Vec3::splat(1e-6))
}

/// Points of the glass table along roughness and cosine.
const GN: usize = 16;
/// Points of the glass table along the relative IOR.
const GE: usize = 32;
/// Relative IORs tabulated: log-spaced over [1/GLASS_ETA_MAX, GLASS_ETA_MAX].
const GLASS_ETA_MAX: f32 = 4.0;
/// Quadrature points per axis for each glass table entry.
const GQ: usize = 16;

/// Directional albedo of the single-scattering rough dielectric interface: the energy that
/// reflection and transmission together keep (the transmission without its 1/η² radiance
/// factor, which a round trip cancels), tabulated over roughness, μ and the relative IOR η'
/// of the side light arrives from (η' < 1 from inside, where total internal reflection
/// returns the rest).
pub struct GlassAlbedo {
    /// E at [η'][r][μ].
    e: Vec<[[f32; GN]; GN]>,
}

/// The shared glass table, computed on first use (about 0.2 s on two cores; only renders
/// with rough glass need it).
pub fn glass_albedo() -> &'static GlassAlbedo {
    static TABLE: OnceLock<GlassAlbedo> = OnceLock::new();
    TABLE.get_or_init(GlassAlbedo::compute)
}

/// η' of table slice `k`, log-spaced from 1/GLASS_ETA_MAX to GLASS_ETA_MAX.
fn glass_eta_at(k: usize) -> f32 {
    GLASS_ETA_MAX.powf(2.0 * k as f32 / (GE - 1) as f32 - 1.0)
}

/// μ of glass column `j`, evenly in √μ.
fn glass_mu_at(j: usize) -> f32 {
    let x = j as f32 / (GN - 1) as f32;
    (x * x).max(MU_MIN)
}

impl GlassAlbedo {
    fn compute() -> Self {
        use rayon::prelude::*;
        let e = (0..GE)
            .into_par_iter()
            .map(|k| {
                let eta = glass_eta_at(k);
                let mut slice = [[0.0f32; GN]; GN];
                for (ri, row) in slice.iter_mut().enumerate() {
                    let ggx = Ggx::from_roughness(ri as f32 / (GN - 1) as f32);
                    for (j, v) in row.iter_mut().enumerate() {
                        *v = Self::estimate(&ggx, glass_mu_at(j), eta);
                    }
                }
                slice
            })
            .collect();
        GlassAlbedo { e }
    }

    /// E by quadrature over visible normals: each normal reflects with probability F and
    /// transmits with 1 − F, and either keeps G2/G1 of the energy.
    fn estimate(ggx: &Ggx, mu: f32, eta: f32) -> f32 {
        let wo = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
        let mut sum = 0.0f64;
        for s in 0..GQ * GQ {
            let u = Vec2::new(((s % GQ) as f32 + 0.5) / GQ as f32, ((s / GQ) as f32 + 0.5) / GQ as f32);
            let wm = ggx.sample_visible(wo, u);
            let f = crate::microfacet::fresnel_dielectric(wo.dot(wm), eta);
            let wr = reflect(wo, wm);
            if wr.z > 0.0 {
                let (g2, g1) = ggx.smith(wo, wr);
                sum += (f * g2 / g1) as f64;
            }
            if let Some((wt, _)) = crate::microfacet::refract(wo, wm, eta) {
                if wt.z < 0.0 {
                    let (g2, g1) = ggx.smith(wo, wt);
                    sum += ((1.0 - f) * g2 / g1) as f64;
                }
            }
        }
        (sum / (GQ * GQ) as f64) as f32
    }

    /// E at roughness `r`, cosine `mu` (from the side light arrives on) and relative IOR `eta`
    /// of that side, trilinearly.
    pub fn albedo(&self, r: f32, mu: f32, eta: f32) -> f32 {
        let t = |x: f32, n: usize| x.clamp(0.0, 1.0) * (n - 1) as f32;
        let fe = t((eta.max(1e-6).ln() / GLASS_ETA_MAX.ln() + 1.0) * 0.5, GE);
        let (fr, fm) = (t(r, GN), t(mu.abs().sqrt(), GN));
        let (k, i, j) = ((fe as usize).min(GE - 2), (fr as usize).min(GN - 2), (fm as usize).min(GN - 2));
        let (te, tr, tm) = (fe - k as f32, fr - i as f32, fm - j as f32);
        let at = |k: usize, i: usize| self.e[k][i][j] * (1.0 - tm) + self.e[k][i][j + 1] * tm;
        let slice = |k: usize| at(k, i) * (1.0 - tr) + at(k, i + 1) * tr;
        slice(k) * (1.0 - te) + slice(k + 1) * te
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smooth_lobes_reflect_everything_and_rough_ones_lose_energy() {
        let t = ggx_albedo();
        // Roughness 0: a mirror, E = F exactly (A + B = 1 for F0 = 1).
        for &mu in &[1.0f32, 0.5, 0.1] {
            assert!((t.albedo(0.0, mu, 1.0) - 1.0).abs() < 1e-3, "{mu}");
        }
        // At roughness 1 (α = 1) D is uniform, 1/π, and G2 = 2μ/(1 + μ) at normal incidence, so
        // E(1) = ∫ 2μ/(1 + μ) dμ / 2 · 2 = 1 − ln 2. Towards grazing E grows (forward scattering).
        let e = t.albedo(1.0, 1.0, 1.0);
        assert!((e - (1.0 - std::f32::consts::LN_2)).abs() < 2e-3, "{e}");
        assert!(t.albedo(1.0, 0.1, 1.0) > e);
        let avg = t.average(1.0, 1.0);
        assert!(avg > e && avg < t.albedo(1.0, 0.02, 1.0), "{avg}");
        // Roughness 0 at grazing: Schlick's (1 − μ)⁵ itself, which B tabulates for F0 = 0.
        for &mu in &[0.001f32, 0.005, 0.05] {
            assert!((t.albedo(0.0, mu, 0.0) - (1.0 - mu).powi(5)).abs() < 2e-3, "{mu}");
        }
        // With F0 = 1 the compensation's Fresnel is 1: white metal keeps all its energy.
        assert!((multiple_scattering_fresnel(Vec3::ONE, avg) - Vec3::ONE).abs().max_element() < 1e-6);
    }

    #[test]
    fn a_smooth_interface_keeps_all_energy_and_a_rough_one_loses_some() {
        let g = glass_albedo();
        // Smooth: reflection and transmission add to one at every angle and IOR (Fresnel).
        for eta in [0.25f32, 0.67, 1.5, 4.0] {
            for mu in [1.0f32, 0.5, 0.1] {
                let e = g.albedo(0.0, mu, eta);
                assert!((e - 1.0).abs() < 2e-3, "η {eta}, μ {mu}: {e}");
            }
        }
        // Rough: lost to single scattering, more at higher IOR contrast; no energy is made.
        let (e15, e4) = (g.albedo(1.0, 1.0, 1.5), g.albedo(1.0, 1.0, 4.0));
        assert!(e15 < 0.98 && e4 < e15 && e4 > 0.3, "{e15} {e4}");
        assert!((0..GE).all(|k| g.e[k].iter().flatten().all(|v| *v <= 1.0 + 1e-3)));
    }
}
