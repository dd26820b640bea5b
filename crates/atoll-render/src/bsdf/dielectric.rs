//! Dielectric BSDF (pbrt-v4 `DielectricBxDF`): a specular interface when the
//! distribution is effectively smooth or `eta == 1`, otherwise the rough
//! dielectric of Walter et al. 2007 in pbrt-v4's form (generalised half
//! vector, separate reflection and transmission lobes chosen by Fresnel).
//!
//! Transmission is evaluated in pbrt's `TransportMode::Radiance`: the BTDF is
//! divided by `etap²`, the squared relative index seen from `wo`'s side, since
//! radiance is compressed into the smaller solid angle inside the denser
//! medium. Multiplying a transmission sample's `f` by `eta²` (the sample's
//! [`BsdfSample::eta`]) gives the `Importance`-mode value.
//!
//! The `*_with` forms take pbrt's transport mode and sampling-lobe flags
//! (`BxDFReflTransFlags`), which the layered BSDF needs: it samples the
//! coating's transmission alone, and follows light backwards from `wi`.

use super::fresnel::{fr_dielectric, reflect, refract};
use super::microfacet::TrowbridgeReitz;
use super::{same_hemisphere, BsdfSample};
use atoll_scene::Rgb;
use glam::{Vec2, Vec3};

/// True when the interface scatters only in delta directions: index-matched
/// (pure pass-through, as pbrt) or effectively smooth.
#[inline]
pub(super) fn is_specular(eta: f32, mf: TrowbridgeReitz) -> bool {
    eta == 1.0 || mf.effectively_smooth()
}

/// pbrt's `TransportMode`: what a path carries. Only transmission differs:
/// radiance-mode BTDFs carry the `1 / etap²` factor, importance-mode ones
/// (light followed backwards from its source) do not.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Mode {
    Radiance,
    Importance,
}

/// pbrt's `BxDFReflTransFlags`: which lobes `sample_with` may choose and
/// `pdf_with` accounts for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Lobes {
    All,
    Reflection,
    Transmission,
}

impl Lobes {
    /// The Fresnel weights `(R, T)` with the excluded lobe's set to zero.
    #[inline]
    fn weights(self, r: f32, t: f32) -> (f32, f32) {
        match self {
            Lobes::All => (r, t),
            Lobes::Reflection => (r, 0.0),
            Lobes::Transmission => (0.0, t),
        }
    }
}

/// The generalised half vector of pbrt-v4's rough dielectric, shared by
/// `eval` and `pdf`: `wm ∝ etap wi + wo`, face-forwarded to +z, with
/// `etap = 1` for reflection and the relative index seen from `wo` for
/// transmission. `None` where the configuration is impossible (grazing,
/// degenerate, or a back-facing microfacet).
#[inline]
fn half_vector(eta: f32, wo: Vec3, wi: Vec3) -> Option<(Vec3, f32, bool)> {
    let (cos_o, cos_i) = (wo.z, wi.z);
    let reflect = cos_i * cos_o > 0.0;
    let etap = if reflect {
        1.0
    } else if cos_o > 0.0 {
        eta
    } else {
        1.0 / eta
    };
    let wm = wi * etap + wo;
    if cos_i == 0.0 || cos_o == 0.0 || wm.length_squared() == 0.0 {
        return None;
    }
    let wm = wm.normalize() * wm.z.signum();
    // Discard back-facing microfacets: both directions must see the facet
    // from the same side as they see the macro-surface.
    if wm.dot(wi) * cos_i < 0.0 || wm.dot(wo) * cos_o < 0.0 {
        return None;
    }
    Some((wm, etap, reflect))
}

/// BSDF value (radiance mode); zero for the specular cases.
pub(super) fn eval(eta: f32, mf: TrowbridgeReitz, wo: Vec3, wi: Vec3) -> Rgb {
    eval_with(eta, mf, wo, wi, Mode::Radiance)
}

/// BSDF value in transport `mode`; zero for the specular cases.
pub(super) fn eval_with(eta: f32, mf: TrowbridgeReitz, wo: Vec3, wi: Vec3, mode: Mode) -> Rgb {
    if is_specular(eta, mf) {
        return Rgb::ZERO;
    }
    let Some((wm, etap, reflect)) = half_vector(eta, wo, wi) else {
        return Rgb::ZERO;
    };
    let fr = fr_dielectric(wo.dot(wm), eta);
    let (cos_o, cos_i) = (wo.z, wi.z);
    let f = if reflect {
        mf.d(wm) * mf.g(wo, wi) * fr / (4.0 * cos_i * cos_o).abs()
    } else {
        let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2) * cos_i * cos_o;
        let ft = mf.d(wm) * (1.0 - fr) * mf.g(wo, wi) * (wi.dot(wm) * wo.dot(wm) / denom).abs();
        radiance_scaled(ft, etap, mode)
    };
    Rgb::splat(f)
}

/// `f / etap²` in radiance mode, `f` in importance mode.
#[inline]
fn radiance_scaled(f: f32, etap: f32, mode: Mode) -> f32 {
    match mode {
        Mode::Radiance => f / (etap * etap),
        Mode::Importance => f,
    }
}

/// Solid-angle density of [`sample`] for the rough case; zero when specular.
pub(super) fn pdf(eta: f32, mf: TrowbridgeReitz, wo: Vec3, wi: Vec3) -> f32 {
    pdf_with(eta, mf, wo, wi, Lobes::All)
}

/// Solid-angle density of [`sample_with`] restricted to `lobes`; zero when
/// specular or when `wi` lies in an excluded lobe.
pub(super) fn pdf_with(eta: f32, mf: TrowbridgeReitz, wo: Vec3, wi: Vec3, lobes: Lobes) -> f32 {
    if is_specular(eta, mf) {
        return 0.0;
    }
    let Some((wm, etap, reflect)) = half_vector(eta, wo, wi) else {
        return 0.0;
    };
    let r = fr_dielectric(wo.dot(wm), eta);
    let (pr, pt) = lobes.weights(r, 1.0 - r);
    if pr == 0.0 && pt == 0.0 {
        return 0.0;
    }
    if reflect {
        mf.pdf(wo, wm) / (4.0 * wo.dot(wm).abs()) * pr / (pr + pt)
    } else {
        // Jacobian of the generalised half vector with respect to wi.
        let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2);
        let dwm_dwi = wi.dot(wm).abs() / denom;
        mf.pdf(wo, wm) * dwm_dwi * pt / (pr + pt)
    }
}

/// Sample reflection or transmission with probability `R / (R + T)` from `uc`;
/// the direction comes from the specular law or from a visible GGX normal.
pub(super) fn sample(eta: f32, mf: TrowbridgeReitz, wo: Vec3, uc: f32, u: Vec2) -> Option<BsdfSample> {
    sample_with(eta, mf, wo, uc, u, Mode::Radiance, Lobes::All)
}

/// [`sample`] in transport `mode`, choosing only among `lobes` (the
/// excluded lobe's Fresnel weight is zero, as in pbrt).
pub(super) fn sample_with(
    eta: f32,
    mf: TrowbridgeReitz,
    wo: Vec3,
    uc: f32,
    u: Vec2,
    mode: Mode,
    lobes: Lobes,
) -> Option<BsdfSample> {
    if wo.z == 0.0 {
        return None;
    }
    if eta == 1.0 {
        // Index-matched: the surface is invisible, light passes straight on
        // (pbrt's R = 0, T = 1).
        if lobes == Lobes::Reflection {
            return None;
        }
        let wi = -wo;
        let f = Rgb::splat(1.0 / wi.z.abs());
        return Some(BsdfSample { f, wi, pdf: 1.0, eta: 1.0, delta: true, transmission: true });
    }
    if mf.effectively_smooth() {
        let r = fr_dielectric(wo.z, eta);
        let t = 1.0 - r;
        let (pr, pt) = lobes.weights(r, t);
        if pr == 0.0 && pt == 0.0 {
            return None;
        }
        if uc < pr / (pr + pt) {
            let wi = Vec3::new(-wo.x, -wo.y, wo.z);
            let f = Rgb::splat(r / wi.z.abs());
            let pdf = pr / (pr + pt);
            return Some(BsdfSample { f, wi, pdf, eta: 1.0, delta: true, transmission: false });
        }
        let (wi, etap) = refract(wo, Vec3::Z, eta)?;
        if wi.z == 0.0 {
            return None;
        }
        let f = Rgb::splat(radiance_scaled(t / wi.z.abs(), etap, mode));
        return Some(BsdfSample { f, wi, pdf: pt / (pr + pt), eta: etap, delta: true, transmission: true });
    }

    let wm = mf.sample_wm(wo, u);
    let r = fr_dielectric(wo.dot(wm), eta);
    let t = 1.0 - r;
    let (pr, pt) = lobes.weights(r, t);
    if pr == 0.0 && pt == 0.0 {
        return None;
    }
    let p_reflect = pr / (pr + pt);
    if uc < p_reflect {
        let wi = reflect(wo, wm);
        if !same_hemisphere(wo, wi) {
            return None;
        }
        let pdf = mf.pdf(wo, wm) / (4.0 * wo.dot(wm).abs()) * p_reflect;
        let f = mf.d(wm) * mf.g(wo, wi) * r / (4.0 * wi.z * wo.z).abs();
        return Some(BsdfSample { f: Rgb::splat(f), wi, pdf, eta: 1.0, delta: false, transmission: false });
    }
    let (wi, etap) = refract(wo, wm, eta)?;
    if same_hemisphere(wo, wi) || wi.z == 0.0 {
        return None;
    }
    let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2);
    let dwm_dwi = wi.dot(wm).abs() / denom;
    let pdf = mf.pdf(wo, wm) * dwm_dwi * (pt / (pr + pt));
    let ft = t * mf.d(wm) * mf.g(wo, wi) * (wi.dot(wm) * wo.dot(wm) / (wi.z * wo.z * denom)).abs();
    let f = Rgb::splat(radiance_scaled(ft, etap, mode));
    Some(BsdfSample { f, wi, pdf, eta: etap, delta: false, transmission: true })
}
