//! The glTF metallic-roughness BSDF as a closed set of lobes, in the local shading frame (+z is
//! the front-facing shading normal).
//!
//! f = opacity · [ (1−m)(1−t)(diffuse + specular layer) + (1−m)t·dielectric + m·conductor ]
//!   + (1−opacity) · pass-through
//!
//! - diffuse: Lambert × (1 − s·F(cos_o))(1 − s·F(cos_i)), a reciprocal energy split with the layer;
//! - specular layer: GGX reflection, Schlick Fresnel with F0 = ((η−1)/(η+1))² × specular colour, × s;
//! - dielectric: rough or smooth GGX reflection + refraction with exact Fresnel (Walter et al. 2007),
//!   transmission tinted by the base colour and scaled by 1/η² for radiance;
//! - conductor: GGX with Schlick Fresnel, F0 = base colour.
//!
//! Sampling picks one lobe by an estimate of its albedo; non-delta samples are weighted by the
//! full mixture pdf (one-sample MIS over lobes). Opaque lobes are two-sided.

use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

use crate::microfacet::{fresnel_dielectric, fresnel_schlick, reflect, refract, Ggx};
use crate::sampling::{cosine_hemisphere_pdf, sample_cosine_hemisphere};

/// Relative luminance (Rec. 709).
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// The lobes of the glTF BSDF.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lobe {
    /// Lambertian diffuse under the specular layer.
    Diffuse,
    /// Dielectric GGX specular layer over the diffuse.
    Specular,
    /// Dielectric interface with transmission (glass).
    Dielectric,
    /// GGX conductor (metal).
    Conductor,
    /// Straight pass-through for alpha-blended coverage.
    PassThrough,
}

const LOBES: [Lobe; 5] = [
    Lobe::Diffuse,
    Lobe::Specular,
    Lobe::Dielectric,
    Lobe::Conductor,
    Lobe::PassThrough,
];

/// Material parameters at a surface point, as the BSDF needs them.
#[derive(Debug, Clone, Copy)]
pub struct BsdfParams {
    /// Linear base colour.
    pub base_color: Vec3,
    /// Metallic in [0,1].
    pub metallic: f32,
    /// Perceptual roughness in [0,1].
    pub roughness: f32,
    /// Transmission in [0,1].
    pub transmission: f32,
    /// Index of refraction ≥ 1 (inside over outside).
    pub ior: f32,
    /// Specular weight in [0,1].
    pub specular: f32,
    /// Specular tint.
    pub specular_color: Vec3,
    /// Coverage in [0,1]; the rest passes straight through.
    pub opacity: f32,
}

impl Default for BsdfParams {
    fn default() -> Self {
        BsdfParams {
            base_color: Vec3::splat(0.8),
            metallic: 0.0,
            roughness: 1.0,
            transmission: 0.0,
            ior: 1.5,
            specular: 1.0,
            specular_color: Vec3::ONE,
            opacity: 1.0,
        }
    }
}

/// A sampled direction (local frame).
#[derive(Debug, Clone, Copy)]
pub struct BsdfSample {
    /// Incident direction, local frame.
    pub wi: Vec3,
    /// f · |cos θi| / pdf.
    pub weight: Vec3,
    /// Pdf of the sample in solid angle (for a delta lobe, the discrete lobe probability).
    pub pdf: f32,
    /// True for a delta lobe (no MIS, no light sampling).
    pub delta: bool,
}

/// The BSDF at one point, with its lobe-selection probabilities precomputed for one `wo`.
#[derive(Debug, Clone, Copy)]
pub struct Bsdf {
    p: BsdfParams,
    ggx: Ggx,
    /// Dielectric specular-layer F0 (colour), before the specular weight.
    f0: Vec3,
    /// Lobe selection probabilities in `LOBES` order.
    prob: [f32; 5],
    /// Whether each lobe is a delta.
    delta: [bool; 5],
}

impl Bsdf {
    /// Builds the BSDF for outgoing direction `wo` (local frame).
    pub fn new(p: BsdfParams, wo: Vec3) -> Self {
        let ggx = Ggx::from_roughness(p.roughness);
        let r = (p.ior - 1.0) / (p.ior + 1.0);
        let f0 = (Vec3::splat(r * r) * p.specular_color).min(Vec3::ONE);
        let cos_o = wo.z.abs();
        let (m, t, op, s) = (p.metallic, p.transmission, p.opacity, p.specular);
        let f_layer = s * fresnel_schlick(f0, cos_o).max_element();
        // Selection weights: estimated albedo of each lobe (a floor keeps every live lobe reachable).
        let w = [
            op * (1.0 - m) * (1.0 - t) * luminance(p.base_color) * (1.0 - f_layer),
            op * (1.0 - m) * (1.0 - t) * if s > 0.0 { f_layer.max(0.05) } else { 0.0 },
            op * (1.0 - m) * t,
            op * m * luminance(fresnel_schlick(p.base_color, cos_o)).max(0.05),
            1.0 - op,
        ];
        let total: f32 = w.iter().sum();
        let prob = if total > 0.0 {
            w.map(|x| x / total)
        } else {
            [1.0, 0.0, 0.0, 0.0, 0.0]
        };
        let smooth = ggx.is_smooth();
        let glass_smooth = smooth || (p.ior - 1.0).abs() < 1e-3;
        Bsdf {
            p,
            ggx,
            f0,
            prob,
            delta: [false, smooth, glass_smooth, smooth, true],
        }
    }

    /// True if some lobe with non-zero probability is not a delta (light sampling is useful).
    pub fn has_non_delta(&self) -> bool {
        (0..5).any(|i| self.prob[i] > 0.0 && !self.delta[i])
    }

    /// Dielectric specular-layer Fresnel (max channel), weighted by the specular factor.
    #[inline]
    fn layer_f(&self, cos: f32) -> f32 {
        self.p.specular * fresnel_schlick(self.f0, cos).max_element()
    }

    /// Value of one non-delta lobe (without its mixture weight).
    fn lobe_f(&self, lobe: Lobe, wo: Vec3, wi: Vec3) -> Vec3 {
        match lobe {
            Lobe::Diffuse | Lobe::Specular | Lobe::Conductor => {
                // Opaque lobes are two-sided: mirror both directions into the upper hemisphere.
                if wo.z * wi.z <= 0.0 {
                    return Vec3::ZERO;
                }
                let (wo, wi) = (two_sided(wo), two_sided(wi));
                match lobe {
                    Lobe::Diffuse => {
                        self.p.base_color
                            * FRAC_1_PI
                            * (1.0 - self.layer_f(wo.z))
                            * (1.0 - self.layer_f(wi.z))
                    }
                    Lobe::Specular => self.microfacet_reflection(wo, wi, |c| {
                        Vec3::splat(self.p.specular) * fresnel_schlick(self.f0, c)
                    }),
                    _ => self
                        .microfacet_reflection(wo, wi, |c| fresnel_schlick(self.p.base_color, c)),
                }
            }
            Lobe::Dielectric => self.dielectric_f(wo, wi),
            Lobe::PassThrough => Vec3::ZERO,
        }
    }

    /// GGX reflection D·G·F/(4 cos_o cos_i) for upper-hemisphere wo, wi.
    #[inline]
    fn microfacet_reflection(&self, wo: Vec3, wi: Vec3, fresnel: impl Fn(f32) -> Vec3) -> Vec3 {
        let wm = wo + wi;
        if wo.z <= 0.0 || wi.z <= 0.0 || wm.length_squared() == 0.0 {
            return Vec3::ZERO;
        }
        let wm = wm.normalize();
        fresnel(wo.dot(wm)) * (self.ggx.d(wm) * self.ggx.g(wo, wi) / (4.0 * wo.z * wi.z))
    }

    /// Generalised half vector for the dielectric: (wm with wm.z > 0, η' ratio), or None.
    #[inline]
    fn dielectric_half(&self, wo: Vec3, wi: Vec3) -> Option<(Vec3, f32, bool)> {
        let (co, ci) = (wo.z, wi.z);
        if co == 0.0 || ci == 0.0 {
            return None;
        }
        let reflect = co * ci > 0.0;
        let etap = if reflect {
            1.0
        } else if co > 0.0 {
            self.p.ior
        } else {
            1.0 / self.p.ior
        };
        let wm = wi * etap + wo;
        if wm.length_squared() == 0.0 {
            return None;
        }
        let mut wm = wm.normalize();
        if wm.z < 0.0 {
            wm = -wm;
        }
        // Discard back-facing microfacets.
        if wm.dot(wi) * ci < 0.0 || wm.dot(wo) * co < 0.0 {
            return None;
        }
        Some((wm, etap, reflect))
    }

    /// Rough dielectric BSDF value (Walter et al. 2007), radiance transport.
    fn dielectric_f(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let Some((wm, etap, reflect)) = self.dielectric_half(wo, wi) else {
            return Vec3::ZERO;
        };
        let f = fresnel_dielectric(wo.dot(wm), self.p.ior);
        let g = self.ggx.g(wo, wi);
        let d = self.ggx.d(wm);
        if reflect {
            Vec3::splat(d * g * f / (4.0 * wi.z * wo.z).abs())
        } else {
            let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2) * wi.z * wo.z;
            let ft = d * (1.0 - f) * g * (wi.dot(wm) * wo.dot(wm) / denom).abs() / (etap * etap);
            self.p.base_color * ft
        }
    }

    /// Pdf of one non-delta lobe's sampling strategy.
    fn lobe_pdf(&self, lobe: Lobe, wo: Vec3, wi: Vec3) -> f32 {
        match lobe {
            Lobe::Diffuse | Lobe::Specular | Lobe::Conductor => {
                if wo.z * wi.z <= 0.0 {
                    return 0.0;
                }
                let (wo, wi) = (two_sided(wo), two_sided(wi));
                if lobe == Lobe::Diffuse {
                    return cosine_hemisphere_pdf(wi.z);
                }
                let wm = (wo + wi).normalize_or_zero();
                if wm == Vec3::ZERO {
                    return 0.0;
                }
                self.ggx.pdf_visible(wo, wm) / (4.0 * wo.dot(wm).abs())
            }
            Lobe::Dielectric => {
                let Some((wm, etap, reflect)) = self.dielectric_half(wo, wi) else {
                    return 0.0;
                };
                let r = fresnel_dielectric(wo.dot(wm), self.p.ior);
                let pm = self.ggx.pdf_visible(wo, wm);
                if reflect {
                    pm / (4.0 * wo.dot(wm).abs()) * r
                } else {
                    let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2);
                    pm * wi.dot(wm).abs() / denom * (1.0 - r)
                }
            }
            Lobe::PassThrough => 0.0,
        }
    }

    /// The BSDF value f(wo, wi) over all non-delta lobes.
    pub fn f(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let mut sum = Vec3::ZERO;
        for (i, &lobe) in LOBES.iter().enumerate() {
            if self.prob[i] > 0.0 && !self.delta[i] {
                sum += self.lobe_weight(lobe) * self.lobe_f(lobe, wo, wi);
            }
        }
        sum
    }

    /// Mixture weight of a lobe in the BSDF (not its sampling probability).
    #[inline]
    fn lobe_weight(&self, lobe: Lobe) -> f32 {
        let (m, t, op) = (self.p.metallic, self.p.transmission, self.p.opacity);
        match lobe {
            Lobe::Diffuse | Lobe::Specular => op * (1.0 - m) * (1.0 - t),
            Lobe::Dielectric => op * (1.0 - m) * t,
            Lobe::Conductor => op * m,
            Lobe::PassThrough => 1.0 - op,
        }
    }

    /// The solid-angle pdf with which [`Bsdf::sample`] produces non-delta direction `wi`.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let mut sum = 0.0;
        for (i, &lobe) in LOBES.iter().enumerate() {
            if self.prob[i] > 0.0 && !self.delta[i] {
                sum += self.prob[i] * self.lobe_pdf(lobe, wo, wi);
            }
        }
        sum
    }

    /// Samples an incident direction. `u_lobe` picks the lobe (and, remapped, reflection versus
    /// refraction); `u` picks the direction.
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        // Choose a lobe and remap u_lobe to [0,1) within it.
        let mut acc = 0.0;
        let mut chosen = 4;
        for i in 0..5 {
            if self.prob[i] > 0.0 && u_lobe < acc + self.prob[i] {
                chosen = i;
                break;
            }
            acc += self.prob[i];
        }
        if self.prob[chosen] <= 0.0 {
            chosen = (0..5).rev().find(|&i| self.prob[i] > 0.0)?;
        }
        let pl = self.prob[chosen];
        let uc = ((u_lobe - acc) / pl).clamp(0.0, 0.999_999);
        let lobe = LOBES[chosen];
        let weight = self.lobe_weight(lobe);
        if self.delta[chosen] {
            return self.sample_delta(lobe, wo, uc, weight / pl, pl);
        }
        let wi = match lobe {
            Lobe::Diffuse => {
                let d = sample_cosine_hemisphere(u);
                if wo.z < 0.0 {
                    Vec3::new(d.x, d.y, -d.z)
                } else {
                    d
                }
            }
            Lobe::Specular | Lobe::Conductor => {
                let wm = self.ggx.sample_visible(two_sided(wo), u);
                let wi = reflect(two_sided(wo), wm);
                if wi.z <= 0.0 {
                    return None;
                }
                if wo.z < 0.0 {
                    Vec3::new(wi.x, wi.y, -wi.z)
                } else {
                    wi
                }
            }
            Lobe::Dielectric => {
                let wm = self.ggx.sample_visible(wo, u);
                let r = fresnel_dielectric(wo.dot(wm), self.p.ior);
                let wi = if uc < r {
                    reflect(wo, wm)
                } else {
                    refract(wo, wm, self.p.ior)?.0
                };
                // A reflection must stay on wo's side and a refraction must cross.
                if (uc < r) != (wo.z * wi.z > 0.0) {
                    return None;
                }
                wi
            }
            Lobe::PassThrough => unreachable!("pass-through is a delta lobe"),
        };
        let pdf = self.pdf(wo, wi);
        if !(pdf > 0.0) || !wi.is_finite() {
            return None;
        }
        let f = self.f(wo, wi);
        Some(BsdfSample {
            wi,
            weight: f * wi.z.abs() / pdf,
            pdf,
            delta: false,
        })
    }

    /// Samples a delta lobe; `scale` is the lobe's mixture weight over its selection probability.
    fn sample_delta(
        &self,
        lobe: Lobe,
        wo: Vec3,
        uc: f32,
        scale: f32,
        pl: f32,
    ) -> Option<BsdfSample> {
        let mirror = Vec3::new(-wo.x, -wo.y, wo.z);
        let (wi, weight) = match lobe {
            Lobe::Specular => (
                mirror,
                Vec3::splat(self.p.specular) * fresnel_schlick(self.f0, wo.z),
            ),
            Lobe::Conductor => (mirror, fresnel_schlick(self.p.base_color, wo.z)),
            Lobe::Dielectric => {
                let r = fresnel_dielectric(wo.z, self.p.ior);
                if uc < r {
                    (mirror, Vec3::ONE)
                } else {
                    let (wi, etap) = refract(wo, Vec3::Z, self.p.ior)?;
                    (wi, self.p.base_color / (etap * etap))
                }
            }
            Lobe::PassThrough => (-wo, Vec3::ONE),
            Lobe::Diffuse => return None,
        };
        Some(BsdfSample {
            wi,
            weight: weight * scale,
            pdf: pl,
            delta: true,
        })
    }
}

/// Mirrors a direction into the upper hemisphere.
#[inline]
fn two_sided(w: Vec3) -> Vec3 {
    Vec3::new(w.x, w.y, w.z.abs())
}
