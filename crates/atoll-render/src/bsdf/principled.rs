//! The Disney principled BSDF (Burley 2012, "Physically-Based Shading at
//! Disney"; Burley 2015, "Extending the Disney BRDF to a BSDF with
//! Integrated Subsurface Scattering") with the lobes of pbrt-v3's
//! `DisneyMaterial`, less subsurface scattering and the thin-surface mode:
//!
//! - diffuse: Burley's Fresnel-shaped Lambertian `(1 - Fo/2)(1 - Fi/2)` plus
//!   the retro-reflection `Rr (Fo + Fi + Fo Fi (Rr - 1))`, `Rr = 2 r cos²θd`,
//!   and sheen `Csheen · SW(cos θd)`, weighted by `(1 - metallic)(1 -
//!   transmission)`;
//! - specular: GGX reflection whose Fresnel term is Schlick's from
//!   `lerp(0.08 specular · tint, base colour, metallic)`, plus the glass
//!   part's dielectric Fresnel;
//! - glass: pbrt-v4's rough dielectric (reflection and refraction, chosen by
//!   Fresnel) weighted by `(1 - metallic) transmission`, its transmission
//!   tinted by `sqrt(base colour)` (two crossings of a closed object give the
//!   colour, as pbrt-v3 does);
//! - clearcoat: `0.25 clearcoat` times a GTR1 lobe of alpha `lerp(gloss,
//!   0.1, 0.001)` with Schlick's Fresnel from 0.04 and separable GGX masking
//!   of alpha 0.25.
//!
//! `sample` picks a lobe with weights that follow each lobe's share of the
//! energy seen from `wo` (diffuse, specular, glass, clearcoat), samples it
//! (cosine hemisphere, GGX visible normals, the dielectric's sampler, GTR1
//! half vectors), and returns the whole BSDF's value and mixture density
//! for non-delta directions: `eval` and `pdf` agree with it exactly.
//!
//! Where this differs from pbrt-v3, and why:
//! - Energy. pbrt-v3 adds the lobes, and a white surface then reflects more
//!   than it receives (up to 1.56 at grazing angles for roughness 1, from
//!   the retro-reflection; the specular and clearcoat lobes add on top). Three
//!   reciprocal changes keep the directional albedo ≤ 1 (checked by
//!   `tests/bsdf_properties.rs` over every lobe): the diffuse part is
//!   divided by `max(1, A(μo), A(μi))`, `A` being its own albedo in closed
//!   form ([`burley_albedo`]), which only changes it where it exceeded 1; it
//!   is scaled by `1 - F(min(μo, μi))`, the dielectric specular's Schlick
//!   reflectance at the more grazing of the two directions (about what the
//!   single-scattering specular lobe reflects there); and everything under
//!   the clearcoat by `1 - 0.25 clearcoat Fc(min(μo, μi))`. The tinted
//!   specular reflectance and sheen colour are clamped to 1 per channel
//!   (the tint, the base colour at unit luminance, exceeds 1 in saturated
//!   channels). A white dielectric reflects 0.94–0.97 at normal incidence
//!   instead of pbrt-v3's 1.04.
//! - Specular. Both `specular` (Burley 2012's normal-incidence reflectance
//!   `0.08 specular`, tinted by `specular_tint`) and `eta` (the glass) are
//!   parameters; pbrt-v3 derives the first from the second
//!   ([`atoll_scene::Material::specular_from_eta`]) and applies the tint to
//!   metals only.
//! - Masking of the specular lobe is pbrt-v4's height-correlated Smith term
//!   (pbrt-v3's Disney uses the separable one).
//! - The clearcoat's GTR1 normals are sampled with the lobe's own alpha
//!   and its density includes the `cos θh` of the half-vector measure
//!   (pbrt-v3 samples with alpha 0.25 and omits it).
//! - Below `SMOOTH_ALPHA` (roughness ≲ 0.03) the specular and glass lobes are
//!   delta lobes, as for the conductor and dielectric (pbrt-v3 clamps alpha
//!   to 0.001 instead).
//!
//! The surface is two-sided like pbrt-v3's: a `wo` below it sees the same
//! reflection lobes mirrored, and the glass part from inside (`1 / eta`,
//! total internal reflection included).

use atoll_scene::{luminance, PrincipledParams, Rgb};
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

use super::fresnel::{fr_dielectric, reflect};
use super::microfacet::TrowbridgeReitz;
use super::{conductor, dielectric, same_hemisphere, BsdfSample};
use crate::sampling::{cosine_hemisphere_pdf, sample_cosine_hemisphere, spherical_direction};

/// A principled surface: its [`PrincipledParams`] (fields read through
/// `Deref`); values outside their range are clamped when it is evaluated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Principled(pub PrincipledParams);

impl std::ops::Deref for Principled {
    type Target = PrincipledParams;
    fn deref(&self) -> &PrincipledParams {
        &self.0
    }
}

impl std::ops::DerefMut for Principled {
    fn deref_mut(&mut self) -> &mut PrincipledParams {
        &mut self.0
    }
}

/// Largest f32 below 1 (pbrt's `OneMinusEpsilon`), for remapped sample values.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// Schlick's weight `(1 - cos)^5`, cos clamped to [0, 1] (pbrt-v3 `SchlickWeight`).
#[inline]
pub fn schlick_weight(cos: f32) -> f32 {
    let m = (1.0 - cos).clamp(0.0, 1.0);
    let m2 = m * m;
    m2 * m2 * m
}

/// `a + (b - a) t` per channel, written out so the CUDA port matches it.
#[inline]
fn lerp3(a: Rgb, b: Rgb, t: f32) -> Rgb {
    a + (b - a) * t
}

/// The clearcoat's Schlick Fresnel (index 1.5: 0.04 at normal incidence).
#[inline]
fn coat_fresnel(cos: f32) -> f32 {
    0.04 + 0.96 * schlick_weight(cos)
}

/// Directional albedo of the Burley diffuse and retro-reflection terms for
/// a white surface (`π f` integrated against `cos θi / π`), for `|cos θo| =
/// mu` and perceptual roughness `r`. With `Rr = r (1 + wo·wi)`, every term
/// is a polynomial in `cos θi` times powers of Schlick's weight, whose
/// cosine-weighted moments are `E[SW] = 1/21`, `E[μ SW] = 1/84` and
/// `E[μ² SW] = 1/252`; the azimuthal average of `(wo·wi)²` is `μo² μi² + (1 -
/// μo²)(1 - μi²) / 2`. Exceeds 1 for rough surfaces at grazing angles (1.56
/// at `r = 1`, `mu → 0`).
pub fn burley_albedo(mu: f32, r: f32) -> f32 {
    const S1: f32 = 1.0 / 21.0;
    const S2: f32 = 1.0 / 84.0;
    const S3: f32 = 1.0 / 252.0;
    let fo = schlick_weight(mu);
    let sin2 = 1.0 - mu * mu;
    let rr = r * (1.0 + 2.0 / 3.0 * mu);
    let rr_fi = r * (S1 + mu * S2);
    let rr2_fi = r * r * (S1 + 2.0 * mu * S2 + mu * mu * S3 + sin2 * 0.5 * (S1 - S3));
    (1.0 - 0.5 * fo) * (1.0 - 0.5 * S1) + fo * rr + rr_fi + fo * (rr2_fi - rr_fi)
}

/// Burley's GTR1 distribution (`γ = 1`), normalised over projected half
/// vectors; `alpha` in (0, 1).
#[inline]
fn gtr1(cos_h: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    (a2 - 1.0) / (PI * a2.ln() * (1.0 + (a2 - 1.0) * cos_h * cos_h))
}

/// A GTR1 half vector around +z: `cos²θh = (1 - α^(2(1-u))) / (1 - α²)`
/// inverts its CDF, so the density is `gtr1(cos θh) cos θh`.
#[inline]
fn sample_gtr1(alpha: f32, u: Vec2) -> Vec3 {
    let a2 = alpha * alpha;
    let cos2 = ((1.0 - a2.powf(1.0 - u.x)) / (1.0 - a2)).clamp(0.0, 1.0);
    spherical_direction((1.0 - cos2).sqrt(), cos2.sqrt(), 2.0 * PI * u.y)
}

/// Everything the methods derive from the parameters.
struct Lobes {
    /// Base colour in [0, 1].
    c: Rgb,
    /// Perceptual roughness in [0, 1].
    r: f32,
    /// Dielectric specular reflectance at normal incidence (tinted, ≤ 1).
    f0: Rgb,
    /// Sheen colour times sheen weight (≤ 1).
    sheen: Rgb,
    /// `(1 - m)(1 - t)`, `m + (1 - m)(1 - t)`, `(1 - m) t`.
    w_diffuse: f32,
    w_opaque: f32,
    w_glass: f32,
    /// Normal-incidence reflectance of the opaque specular: `m c + (1 - m)(1 - t) f0`;
    /// it rises to `w_opaque` at grazing angles.
    k0: Rgb,
    /// `0.25 clearcoat` and the GTR1 alpha.
    coat: f32,
    coat_alpha: f32,
    eta: f32,
    mf: TrowbridgeReitz,
}

impl Principled {
    fn lobes(&self) -> Lobes {
        let unit = |x: f32| x.clamp(0.0, 1.0);
        let c = self.base_color.clamp(Rgb::ZERO, Rgb::ONE);
        let (m, t, r) = (unit(self.metallic), unit(self.transmission), unit(self.roughness));
        // The base colour's hue and saturation at unit luminance (pbrt-v3's `Ctint`).
        let lum = luminance(c);
        let tint = if lum > 0.0 { c / lum } else { Rgb::ONE };
        let f0 =
            (0.08 * self.specular.max(0.0) * lerp3(Rgb::ONE, tint, unit(self.specular_tint))).min(Rgb::ONE);
        let sheen = (unit(self.sheen) * lerp3(Rgb::ONE, tint, unit(self.sheen_tint))).min(Rgb::ONE);
        let w_diffuse = (1.0 - m) * (1.0 - t);
        let alpha = r * r;
        Lobes {
            c,
            r,
            f0,
            sheen,
            w_diffuse,
            w_opaque: m + w_diffuse,
            w_glass: (1.0 - m) * t,
            k0: m * c + w_diffuse * f0,
            coat: 0.25 * unit(self.clearcoat),
            coat_alpha: 0.1 + (0.001 - 0.1) * unit(self.clearcoat_gloss),
            eta: self.eta,
            mf: TrowbridgeReitz::new(alpha, alpha),
        }
    }

    /// Lobe selection weights (diffuse, specular, glass, clearcoat) for
    /// `wo`: roughly the energy each lobe reflects, from its Fresnel term at
    /// the macro normal.
    fn weights(l: &Lobes, wo: Vec3) -> [f32; 4] {
        let mu = wo.z.abs();
        let sw = schlick_weight(mu);
        let coat = l.coat * coat_fresnel(mu);
        let under = 1.0 - coat;
        let dielectric = lerp3(l.f0, Rgb::ONE, sw);
        [
            under * l.w_diffuse * (1.0 - luminance(dielectric)),
            under * luminance(lerp3(l.k0, Rgb::splat(l.w_opaque), sw)),
            under * l.w_glass,
            coat,
        ]
    }

    /// The diffuse, retro-reflection and sheen terms for a reflection pair
    /// (before the `w_diffuse` weight and the clearcoat's attenuation).
    fn diffuse(l: &Lobes, mu_o: f32, mu_i: f32, cos_d: f32) -> Rgb {
        let (fo, fi) = (schlick_weight(mu_o), schlick_weight(mu_i));
        let rr = 2.0 * l.r * cos_d * cos_d;
        let burley = (1.0 - 0.5 * fo) * (1.0 - 0.5 * fi) + rr * (fo + fi + fo * fi * (rr - 1.0));
        let norm = burley_albedo(mu_o, l.r).max(burley_albedo(mu_i, l.r)).max(1.0);
        let f = l.c * (FRAC_1_PI * burley / norm) + l.sheen * schlick_weight(cos_d);
        // What the dielectric specular reflects at the more grazing direction is not
        // available to the diffuse layer.
        f * (Rgb::ONE - lerp3(l.f0, Rgb::ONE, schlick_weight(mu_o.min(mu_i))))
    }

    /// BSDF value `f(wo, wi)` without the cosine; delta lobes excluded.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        let l = self.lobes();
        let (mu_o, mu_i) = (wo.z.abs(), wi.z.abs());
        if mu_o == 0.0 || mu_i == 0.0 {
            return Rgb::ZERO;
        }
        let under = 1.0 - l.coat * coat_fresnel(mu_o.min(mu_i));
        if !same_hemisphere(wo, wi) {
            if l.w_glass == 0.0 {
                return Rgb::ZERO;
            }
            let t = dielectric::eval(l.eta, l.mf, wo, wi);
            return t * l.c.map(f32::sqrt) * (l.w_glass * under);
        }
        let wh = wo + wi;
        if wh.length_squared() == 0.0 {
            return Rgb::ZERO;
        }
        let wh = wh.normalize();
        let cos_d = wo.dot(wh);
        // The half vector on the distributions' (upper) side.
        let wm = wh * wh.z.signum();
        let mut f = Rgb::ZERO;
        if l.w_diffuse > 0.0 {
            f += Self::diffuse(&l, mu_o, mu_i, cos_d) * l.w_diffuse;
        }
        if !l.mf.effectively_smooth() {
            let opaque = lerp3(l.k0, Rgb::splat(l.w_opaque), schlick_weight(cos_d));
            let glass = if l.w_glass > 0.0 { l.w_glass * fr_dielectric(wo.dot(wm), l.eta) } else { 0.0 };
            f += (opaque + Rgb::splat(glass)) * (l.mf.d(wm) * l.mf.g(wo, wi) / (4.0 * mu_o * mu_i));
        }
        f *= under;
        if l.coat > 0.0 {
            let coat = TrowbridgeReitz::new(0.25, 0.25);
            let g = coat.g1(wo) * coat.g1(wi);
            f +=
                Rgb::splat(l.coat * gtr1(wm.z, l.coat_alpha) * coat_fresnel(cos_d) * g / (4.0 * mu_o * mu_i));
        }
        f
    }

    /// Solid-angle density with which [`Self::sample`] returns `wi` (delta
    /// lobes excluded, but counted in the lobe probabilities).
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let l = self.lobes();
        let [pd, ps, pg, pc] = Self::weights(&l, wo);
        let total = pd + ps + pg + pc;
        if total == 0.0 || wo.z == 0.0 || wi.z == 0.0 {
            return 0.0;
        }
        let glass = if pg > 0.0 { pg * dielectric::pdf(l.eta, l.mf, wo, wi) } else { 0.0 };
        if !same_hemisphere(wo, wi) {
            return glass / total;
        }
        let mut p = glass + pd * cosine_hemisphere_pdf(wi.z.abs());
        if ps > 0.0 {
            p += ps * conductor::pdf(l.mf, wo, wi);
        }
        if pc > 0.0 {
            let wh = wo + wi;
            if wh.length_squared() > 0.0 {
                let wm = wh.normalize() * wh.z.signum();
                p += pc * gtr1(wm.z, l.coat_alpha) * wm.z / (4.0 * wo.dot(wm).abs());
            }
        }
        p / total
    }

    /// Picks a lobe with `uc`, samples it with `u`. Non-delta samples carry
    /// the whole [`Self::eval`] and [`Self::pdf`]; delta ones (smooth
    /// specular or glass) their own weight and the probability of their lobe.
    pub fn sample(&self, wo: Vec3, uc: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let l = self.lobes();
        let [pd, ps, pg, pc] = Self::weights(&l, wo);
        let total = pd + ps + pg + pc;
        if total <= 0.0 {
            return None;
        }
        let x = uc * total;
        let mu_o = wo.z.abs();
        // Reflection lobes must keep `wi` on `wo`'s side.
        let reflected = |wi: Vec3| same_hemisphere(wo, wi).then_some((wi, 1.0));
        let (wi, eta) = if x < pd {
            let mut wi = sample_cosine_hemisphere(u);
            if wo.z < 0.0 {
                wi.z = -wi.z;
            }
            (wi, 1.0)
        } else if x < pd + ps {
            if l.mf.effectively_smooth() {
                // A mirror with the opaque specular's Fresnel at the macro normal.
                let wi = Vec3::new(-wo.x, -wo.y, wo.z);
                let fr = lerp3(l.k0, Rgb::splat(l.w_opaque), schlick_weight(mu_o));
                let under = 1.0 - l.coat * coat_fresnel(mu_o);
                let f = fr * (under / mu_o);
                return Some(BsdfSample {
                    f,
                    wi,
                    pdf: ps / total,
                    eta: 1.0,
                    delta: true,
                    transmission: false,
                });
            }
            reflected(reflect(wo, l.mf.sample_wm(wo, u)))?
        } else if x < pd + ps + pg {
            let u_glass = ((x - pd - ps) / pg).min(ONE_MINUS_EPSILON);
            let s = dielectric::sample(l.eta, l.mf, wo, u_glass, u)?;
            if s.delta {
                let tint = if s.transmission { l.c.map(f32::sqrt) } else { Rgb::ONE };
                let under = 1.0 - l.coat * coat_fresnel(mu_o.min(s.wi.z.abs()));
                return Some(BsdfSample {
                    f: s.f * tint * (l.w_glass * under),
                    pdf: s.pdf * (pg / total),
                    ..s
                });
            }
            (s.wi, s.eta)
        } else {
            let wm = sample_gtr1(l.coat_alpha, u);
            reflected(reflect(wo, if wo.z < 0.0 { -wm } else { wm }))?
        };
        if wi.z == 0.0 {
            return None;
        }
        let transmission = !same_hemisphere(wo, wi);
        Some(BsdfSample { f: self.eval(wo, wi), wi, pdf: self.pdf(wo, wi), eta, delta: false, transmission })
    }

    /// True when every lobe with weight is a delta lobe (smooth metal or
    /// glass without clearcoat): light sampling is pointless then.
    pub fn is_delta(&self) -> bool {
        let l = self.lobes();
        let rough_specular = !l.mf.effectively_smooth() && l.w_opaque > 0.0;
        let rough_glass = l.w_glass > 0.0 && !dielectric::is_specular(l.eta, l.mf);
        !(l.w_diffuse > 0.0 || l.coat > 0.0 || rough_specular || rough_glass)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn burley_albedo_matches_quadrature() {
        // Midpoint quadrature over cos θi and φ of the diffuse + retro terms.
        for &(mu, r) in &[(1.0f32, 0.0f32), (0.5, 0.5), (0.2, 1.0), (0.02, 1.0), (0.7, 0.3)] {
            let wo = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
            let (n_mu, n_phi) = (400, 200);
            let mut sum = 0.0f64;
            for i in 0..n_mu {
                // Cosine-weighted: μi = sqrt(v), v uniform, density 1 per (v, φ/2π).
                let v = (i as f32 + 0.5) / n_mu as f32;
                let mu_i = v.sqrt();
                for j in 0..n_phi {
                    let phi = 2.0 * PI * (j as f32 + 0.5) / n_phi as f32;
                    let s = (1.0 - mu_i * mu_i).sqrt();
                    let wi = Vec3::new(s * phi.cos(), s * phi.sin(), mu_i);
                    let cos_d = wo.dot((wo + wi).normalize());
                    let (fo, fi) = (schlick_weight(mu), schlick_weight(mu_i));
                    let rr = 2.0 * r * cos_d * cos_d;
                    sum +=
                        ((1.0 - 0.5 * fo) * (1.0 - 0.5 * fi) + rr * (fo + fi + fo * fi * (rr - 1.0))) as f64;
                }
            }
            let quad = sum / (n_mu * n_phi) as f64;
            let closed = burley_albedo(mu, r) as f64;
            assert!((quad - closed).abs() < 2e-3, "mu {mu} r {r}: {quad} vs {closed}");
        }
        assert!((burley_albedo(0.0, 1.0) - 1.557).abs() < 1e-3);
        assert!((burley_albedo(1.0, 0.0) - (1.0 - 0.5 / 21.0)).abs() < 1e-6);
    }
}
