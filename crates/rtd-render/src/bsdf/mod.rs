//! The glTF metallic-roughness BSDF as a closed set of lobes, in the local shading frame (+z is
//! the front-facing shading normal).
//!
//! f = opacity · [ (1−m)(1−t)(diffuse + specular layer) + (1−m)t·dielectric + m·conductor ]
//!   + (1−opacity) · pass-through
//!
//! - diffuse: Lambert × (1 − E_L(cos_o))(1 − E_L(cos_i)) / (1 − E_L,avg), where E_L is the
//!   specular layer's directional albedo ([`crate::energy`]): albedo-scaled layering, reciprocal,
//!   so a white layered surface reflects all it receives (what the layer does not reflect, the
//!   diffuse does);
//! - specular layer: GGX reflection, Schlick Fresnel with F0 = ((η−1)/(η+1))² × specular colour, × s;
//! - dielectric: rough or smooth GGX reflection + refraction with exact Fresnel (Walter et al. 2007),
//!   transmission tinted by the base colour and scaled by 1/η² for radiance;
//! - conductor: GGX with Schlick Fresnel, F0 = base colour, plus Kulla–Conty's multiple-scattering
//!   term F_ms (1 − E(cos_o))(1 − E(cos_i)) / (π (1 − E_avg)), so rough metal keeps the energy
//!   single scattering loses (glass is not compensated yet).
//!
//! Over it, on the front side only, lie a sheen and over that a clear coat, each layered by
//! albedo scaling (what a layer reflects, the layers below do not receive):
//!
//! f_total = coat + C(o)C(i) · [ sheen + S(o)S(i) · f ],  C(w) = 1 − c·E_c(cos_w),
//! S(w) = 1 − max(sheen colour)·E_s(cos_w)
//!
//! - coat: colourless GGX reflection (F0 = 0.04, IOR 1.5) of its own roughness, × weight c;
//! - sheen: the Charlie fibre lobe ([`crate::sheen`]) × sheen colour;
//!
//! and E_c, E_s their tabulated directional albedos, so each layer's energy stays ≤ 1. Light
//! refracted in through glass takes only the outgoing side's factors (C(o)S(o)).
//!
//! Sampling picks one lobe by an estimate of its albedo; non-delta samples are weighted by the
//! full mixture pdf (one-sample MIS over lobes). Opaque lobes are two-sided.

use glam::{Vec2, Vec3};
use rtd_image::luminance;
use std::f32::consts::FRAC_1_PI;

use rtd_scene::LayerParams;

use crate::energy::{ggx_albedo, glass_albedo, multiple_scattering_fresnel};
use crate::microfacet::{fresnel_dielectric, fresnel_schlick, reflect, refract, Ggx};
use crate::sampling::{cosine_hemisphere_pdf, sample_cosine_hemisphere};
use crate::sheen::{sheen_albedo, sheen_pdf, Charlie};

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
    /// The clear coat's GGX reflection over everything else.
    Coat,
    /// The sheen's Charlie lobe between the coat and the base.
    Sheen,
}

/// Number of lobes.
const N_LOBES: usize = 7;
/// Index of the pass-through lobe (the fallback when nothing else is live).
const PASS_THROUGH: usize = 4;

const LOBES: [Lobe; N_LOBES] =
    [Lobe::Diffuse, Lobe::Specular, Lobe::Dielectric, Lobe::Conductor, Lobe::PassThrough, Lobe::Coat, Lobe::Sheen];

/// F0 of the clear coat: a dielectric of IOR 1.5, as `KHR_materials_clearcoat` fixes it.
const COAT_F0: f32 = 0.04;

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
    /// The clear coat and sheen over the base.
    pub layers: LayerParams,
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
            layers: LayerParams::default(),
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
    prob: [f32; N_LOBES],
    /// The specular layer's directional albedo at `wo` (max channel, × specular weight).
    layer_o: f32,
    /// 1 / (1 − the layer's hemispherical-average albedo): the diffuse's normalisation.
    layer_norm: f32,
    /// The conductor's multiple-scattering term without its (1 − E(cos_i)) factor:
    /// F_ms (1 − E(cos_o)) / (π (1 − E_avg)).
    ms_o: Vec3,
    /// Whether each lobe is a delta.
    delta: [bool; N_LOBES],
    /// 1 / the rough dielectric interface's albedo towards `wo`, by which its lobe is scaled so
    /// that no energy is lost to single scattering (1 for smooth or no glass).
    glass_comp: f32,
    /// The clear coat, if any (front side only).
    coat: Option<Coat>,
    /// The sheen, if any (front side only).
    sheen: Option<SheenLayer>,
}

/// The clear coat at one point: weight, GGX lobe, and its albedo towards `wo`.
#[derive(Debug, Clone, Copy)]
struct Coat {
    weight: f32,
    roughness: f32,
    ggx: Ggx,
    /// c·E_c(cos_o).
    albedo_o: f32,
}

impl Coat {
    /// c·E_c(cos): the coat's directional albedo (for a mirror coat, Schlick's Fresnel itself).
    #[inline]
    fn albedo(&self, cos: f32) -> f32 {
        self.weight * layer_albedo(&self.ggx, self.roughness, 1.0, COAT_F0, cos)
    }
}

/// The sheen at one point: colour, Charlie lobe, and its albedo towards `wo`.
#[derive(Debug, Clone, Copy)]
struct SheenLayer {
    color: Vec3,
    roughness: f32,
    lobe: Charlie,
    /// 1 / max(1, E_s(cos_o)): keeps the lobe's albedo ≤ 1 where the Charlie lobe's exceeds it.
    norm: f32,
    /// max(colour)·min(1, E_s(cos_o)).
    albedo_o: f32,
}

impl SheenLayer {
    /// max(colour)·min(1, E_s(cos)): the bound on the sheen's albedo the base is scaled by.
    #[inline]
    fn albedo(&self, cos: f32) -> f32 {
        self.color.max_element() * sheen_albedo().albedo(self.roughness, cos).min(1.0)
    }
}

impl Bsdf {
    /// Builds the BSDF for outgoing direction `wo` (local frame).
    pub fn new(p: BsdfParams, wo: Vec3) -> Self {
        let ggx = Ggx::from_roughness(p.roughness);
        let r = (p.ior - 1.0) / (p.ior + 1.0);
        let f0 = (Vec3::splat(r * r) * p.specular_color).min(Vec3::ONE);
        let cos_o = wo.z.abs();
        let (m, t, op, s) = (p.metallic, p.transmission, p.opacity, p.specular);
        // Tabulated albedos for the layering and the multiple-scattering term.
        let table = ggx_albedo();
        let f0_max = f0.max_element();
        let layer_o = layer_albedo(&ggx, p.roughness, s, f0_max, cos_o);
        // A mirror's average is Schlick's: F0 + (1 − F0)/21.
        let layer_avg =
            if ggx.is_smooth() { f0_max + (1.0 - f0_max) / 21.0 } else { table.average(p.roughness, f0_max) };
        let layer_norm = 1.0 / (1.0 - s * layer_avg).max(1e-3);
        // Only a rough metal lobe needs the multiple-scattering term.
        let e_avg = if m > 0.0 && !ggx.is_smooth() { table.average(p.roughness, 1.0) } else { 1.0 };
        let ms_o = if e_avg >= 1.0 {
            Vec3::ZERO
        } else {
            multiple_scattering_fresnel(p.base_color, e_avg)
                * ((1.0 - table.albedo(p.roughness, cos_o, 1.0)).max(0.0) * FRAC_1_PI / (1.0 - e_avg))
        };
        let (coat, sheen) = Self::layers(&p.layers, wo);
        // What reaches the base through the layers, towards wo.
        let coat_o = coat.map_or(0.0, |c| c.albedo_o);
        let under_coat = 1.0 - coat_o;
        let base_o = under_coat * (1.0 - sheen.map_or(0.0, |s| s.albedo_o));
        // Selection weights: estimated albedo of each lobe (a floor keeps every live lobe reachable).
        let w = [
            base_o * op * (1.0 - m) * (1.0 - t) * luminance(p.base_color) * (1.0 - layer_o),
            base_o * op * (1.0 - m) * (1.0 - t) * if s > 0.0 { layer_o.max(0.05) } else { 0.0 },
            base_o * op * (1.0 - m) * t,
            base_o * op * m * luminance(fresnel_schlick(p.base_color, cos_o)).max(0.05),
            1.0 - op,
            coat.map_or(0.0, |c| op * c.albedo_o.max(0.02 * c.weight)),
            sheen.map_or(0.0, |s| op * under_coat * s.albedo_o.max(0.02 * s.color.max_element())),
        ];
        let total: f32 = w.iter().sum();
        let mut fallback = [0.0; N_LOBES];
        fallback[0] = 1.0;
        let prob = if total > 0.0 { w.map(|x| x / total) } else { fallback };
        let smooth = ggx.is_smooth();
        let glass_smooth = smooth || (p.ior - 1.0).abs() < 1e-3;
        let coat_smooth = coat.is_some_and(|c| c.ggx.is_smooth());
        let delta = [false, smooth, glass_smooth, smooth, true, coat_smooth, false];
        // Energy compensation of rough glass: E of the side wo is on (η' = 1/IOR from inside).
        let glass_comp = if t > 0.0 && !glass_smooth {
            let eta = if wo.z >= 0.0 { p.ior } else { 1.0 / p.ior };
            1.0 / glass_albedo().albedo(p.roughness, cos_o, eta).max(0.05)
        } else {
            1.0
        };
        Bsdf { p, ggx, f0, prob, layer_o, layer_norm, ms_o, delta, glass_comp, coat, sheen }
    }

    /// The coat and sheen towards `wo`; none on the back side, where there are no layers.
    fn layers(l: &LayerParams, wo: Vec3) -> (Option<Coat>, Option<SheenLayer>) {
        if wo.z <= 0.0 {
            return (None, None);
        }
        let coat = (l.clearcoat > 0.0).then(|| {
            let mut c = Coat {
                weight: l.clearcoat,
                roughness: l.clearcoat_roughness,
                ggx: Ggx::from_roughness(l.clearcoat_roughness),
                albedo_o: 0.0,
            };
            c.albedo_o = c.albedo(wo.z);
            c
        });
        let sheen = (l.sheen_color.max_element() > 0.0).then(|| {
            let mut s = SheenLayer {
                color: l.sheen_color,
                roughness: l.sheen_roughness,
                lobe: Charlie::from_roughness(l.sheen_roughness),
                norm: 1.0 / sheen_albedo().albedo(l.sheen_roughness, wo.z).max(1.0),
                albedo_o: 0.0,
            };
            s.albedo_o = s.albedo(wo.z);
            s
        });
        (coat, sheen)
    }

    /// C(o)C(i): the coat's attenuation of what lies under it, for incident `wi` (a refracted
    /// `wi` below the surface takes only the outgoing factor).
    #[inline]
    fn coat_scale(&self, wi: Vec3) -> f32 {
        self.coat.map_or(1.0, |c| (1.0 - c.albedo_o) * if wi.z > 0.0 { 1.0 - c.albedo(wi.z) } else { 1.0 })
    }

    /// C(o)C(i)·S(o)S(i): what the base receives through both layers, for incident `wi`.
    #[inline]
    fn base_scale(&self, wi: Vec3) -> f32 {
        let sheen =
            self.sheen.map_or(1.0, |s| (1.0 - s.albedo_o) * if wi.z > 0.0 { 1.0 - s.albedo(wi.z) } else { 1.0 });
        self.coat_scale(wi) * sheen
    }

    /// True if some lobe with non-zero probability is not a delta (light sampling is useful).
    pub fn has_non_delta(&self) -> bool {
        (0..N_LOBES).any(|i| self.prob[i] > 0.0 && !self.delta[i])
    }

    /// The specular layer's directional albedo at `cos` (max channel, × the specular weight).
    #[inline]
    fn layer_albedo(&self, cos: f32) -> f32 {
        layer_albedo(&self.ggx, self.p.roughness, self.p.specular, self.f0.max_element(), cos)
    }

    /// Value (without the lobe's mixture weight) and sampling pdf of one non-delta lobe,
    /// sharing the half vector, D and the Smith terms between the two.
    ///
    /// Never inlined: inlined into [`Bsdf::eval`]'s loop over the lobes, the maths of lobes the
    /// BSDF does not have (square roots, divisions, table lookups) was computed ahead of the test
    /// that skips them, as the sheen's was (see [`crate::sheen::Charlie::f`]).
    #[inline(never)]
    fn lobe_eval(&self, lobe: Lobe, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        const NONE: (Vec3, f32) = (Vec3::ZERO, 0.0);
        match lobe {
            Lobe::Diffuse | Lobe::Specular | Lobe::Conductor => {
                // Opaque lobes are two-sided: mirror both directions into the upper hemisphere.
                if wo.z * wi.z <= 0.0 {
                    return NONE;
                }
                let (wo, wi) = (two_sided(wo), two_sided(wi));
                if lobe == Lobe::Diffuse {
                    // Albedo-scaled layering, normalised so the diffuse's albedo is ρ(1 − E_L(cos_o)).
                    let split = (1.0 - self.layer_o) * (1.0 - self.layer_albedo(wi.z)) * self.layer_norm;
                    return (self.p.base_color * (FRAC_1_PI * split.max(0.0)), cosine_hemisphere_pdf(wi.z));
                }
                let wm = wo + wi;
                if wm.length_squared() == 0.0 {
                    return NONE;
                }
                let wm = wm.normalize();
                let cos_om = wo.dot(wm);
                let fresnel = if lobe == Lobe::Specular {
                    Vec3::splat(self.p.specular) * fresnel_schlick(self.f0, cos_om)
                } else {
                    fresnel_schlick(self.p.base_color, cos_om)
                };
                let d = self.ggx.d(wm);
                let (g2, g1) = self.ggx.smith(wo, wi);
                // f = F·D·G2/(4 cos_o cos_i); pdf = D_wo(wm)/(4 wo·wm) = G1(wo)·D/(4 cos_o).
                let mut f = fresnel * (d * g2 / (4.0 * wo.z * wi.z));
                if lobe == Lobe::Conductor && self.ms_o != Vec3::ZERO {
                    // Kulla–Conty: the energy single scattering lost, spread over wi.
                    let e_i = ggx_albedo().albedo(self.p.roughness, wi.z, 1.0);
                    f += self.ms_o * (1.0 - e_i).max(0.0);
                }
                (f, d * g1 / (4.0 * wo.z))
            }
            Lobe::Dielectric => {
                let Some((wm, etap, reflect)) = self.dielectric_half(wo, wi) else {
                    return NONE;
                };
                let (cos_om, cos_im) = (wo.dot(wm), wi.dot(wm));
                let fr = fresnel_dielectric(cos_om, self.p.ior);
                let d = self.ggx.d(wm);
                let (g, g1) = self.ggx.smith(wo, wi);
                // Visible-normal density D_wo(wm) = G1(wo)·D·|wo·wm|/|cos_o|.
                let pm = g1 * d * cos_om.abs() / wo.z.abs();
                // Both lobes scaled by glass_comp, the single-scattering loss restored.
                if reflect {
                    let fr_value = d * g * fr / (4.0 * wi.z * wo.z).abs() * self.glass_comp;
                    (Vec3::splat(fr_value), pm / (4.0 * cos_om.abs()) * fr)
                } else {
                    // Walter et al. 2007 transmission, with the 1/η'² radiance scaling.
                    let denom = (cos_im + cos_om / etap).powi(2);
                    let ft = d * (1.0 - fr) * g * (cos_im * cos_om / (denom * wi.z * wo.z)).abs() / (etap * etap);
                    (self.p.base_color * (ft * self.glass_comp), pm * cos_im.abs() / denom * (1.0 - fr))
                }
            }
            Lobe::Coat => {
                let Some(c) = self.coat else { return NONE };
                if wo.z <= 0.0 || wi.z <= 0.0 {
                    return NONE;
                }
                let wm = (wo + wi).normalize_or_zero();
                if wm == Vec3::ZERO {
                    return NONE;
                }
                let d = c.ggx.d(wm);
                let (g2, g1) = c.ggx.smith(wo, wi);
                let fresnel = c.weight * fresnel_schlick(Vec3::splat(COAT_F0), wo.dot(wm)).x;
                (Vec3::splat(fresnel * d * g2 / (4.0 * wo.z * wi.z)), d * g1 / (4.0 * wo.z))
            }
            Lobe::Sheen => {
                let Some(sh) = self.sheen else { return NONE };
                (sh.color * (sh.lobe.f(wo, wi) * sh.norm), sheen_pdf(wi))
            }
            Lobe::PassThrough => NONE,
        }
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

    /// The BSDF value f(wo, wi) over all non-delta lobes, and the solid-angle pdf with which
    /// [`Bsdf::sample`] produces `wi`.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let (mut f, mut pdf) = (Vec3::ZERO, 0.0);
        let layered = self.coat.is_some() || self.sheen.is_some();
        let (coat_scale, base_scale) = if layered { (self.coat_scale(wi), self.base_scale(wi)) } else { (1.0, 1.0) };
        for (i, &lobe) in LOBES.iter().enumerate() {
            if self.prob[i] > 0.0 && !self.delta[i] {
                let (lf, lp) = self.lobe_eval(lobe, wo, wi);
                let scale = match lobe {
                    Lobe::Coat | Lobe::PassThrough => 1.0,
                    Lobe::Sheen => coat_scale,
                    _ => base_scale,
                };
                f += (self.lobe_weight(lobe) * scale) * lf;
                pdf += self.prob[i] * lp;
            }
        }
        (f, pdf)
    }

    /// The BSDF value f(wo, wi) over all non-delta lobes.
    pub fn f(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval(wo, wi).0
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
            Lobe::Coat | Lobe::Sheen => op,
        }
    }

    /// The solid-angle pdf with which [`Bsdf::sample`] produces non-delta direction `wi`.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval(wo, wi).1
    }

    /// Samples an incident direction. `u_lobe` picks the lobe (and, remapped, reflection versus
    /// refraction); `u` picks the direction.
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        // Choose a lobe and remap u_lobe to [0,1) within it.
        let mut acc = 0.0;
        let mut chosen = PASS_THROUGH;
        for i in 0..N_LOBES {
            if self.prob[i] > 0.0 && u_lobe < acc + self.prob[i] {
                chosen = i;
                break;
            }
            acc += self.prob[i];
        }
        if self.prob[chosen] <= 0.0 {
            chosen = (0..N_LOBES).rev().find(|&i| self.prob[i] > 0.0)?;
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
                let wi = if uc < r { reflect(wo, wm) } else { refract(wo, wm, self.p.ior)?.0 };
                // A reflection must stay on wo's side and a refraction must cross.
                if (uc < r) != (wo.z * wi.z > 0.0) {
                    return None;
                }
                wi
            }
            Lobe::Coat => {
                // Only built for wo above the surface.
                let c = self.coat?;
                let wi = reflect(wo, c.ggx.sample_visible(wo, u));
                if wi.z <= 0.0 {
                    return None;
                }
                wi
            }
            Lobe::Sheen => sample_cosine_hemisphere(u),
            Lobe::PassThrough => unreachable!("pass-through is a delta lobe"),
        };
        let (f, pdf) = self.eval(wo, wi);
        if !(pdf > 0.0) || !wi.is_finite() {
            return None;
        }
        Some(BsdfSample { wi, weight: f * wi.z.abs() / pdf, pdf, delta: false })
    }

    /// Samples a delta lobe; `scale` is the lobe's mixture weight over its selection probability.
    fn sample_delta(&self, lobe: Lobe, wo: Vec3, uc: f32, scale: f32, pl: f32) -> Option<BsdfSample> {
        let mirror = Vec3::new(-wo.x, -wo.y, wo.z);
        let (wi, weight) = match lobe {
            Lobe::Coat => {
                let c = self.coat?;
                (mirror, Vec3::splat(c.weight * fresnel_schlick(Vec3::splat(COAT_F0), wo.z).x))
            }
            Lobe::Specular => (mirror, Vec3::splat(self.p.specular) * fresnel_schlick(self.f0, wo.z)),
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
            Lobe::Diffuse | Lobe::Sheen => return None,
        };
        // A base lobe's light passes the layers on its way in and out.
        let layers = if matches!(lobe, Lobe::Coat | Lobe::PassThrough) { 1.0 } else { self.base_scale(wi) };
        Some(BsdfSample { wi, weight: weight * (scale * layers), pdf: pl, delta: true })
    }
}

/// The specular layer's directional albedo at `cos`: specular weight × (the tabulated GGX
/// albedo, or for a mirror Schlick's Fresnel itself), for F0 `f0`.
#[inline]
fn layer_albedo(ggx: &Ggx, roughness: f32, specular: f32, f0: f32, cos: f32) -> f32 {
    let e =
        if ggx.is_smooth() { fresnel_schlick(Vec3::splat(f0), cos).x } else { ggx_albedo().albedo(roughness, cos, f0) };
    specular * e
}

/// Mirrors a direction into the upper hemisphere.
#[inline]
fn two_sided(w: Vec3) -> Vec3 {
    Vec3::new(w.x, w.y, w.z.abs())
}

#[cfg(test)]
mod tests;
