//! Conductor BSDF (pbrt-v4 `ConductorBxDF`): a perfect mirror when the
//! distribution is effectively smooth, a GGX microfacet reflector otherwise,
//! both with the complex Fresnel term per channel. Two-sided: `wo` below the
//! surface is the mirror image of `wo` above.

use super::fresnel::{fr_complex_rgb, reflect};
use super::microfacet::TrowbridgeReitz;
use super::{same_hemisphere, BsdfSample};
use atoll_scene::Rgb;
use glam::{Vec2, Vec3};

/// `f = D G F / (4 cos_o cos_i)` with the half vector `wo + wi`; zero for a
/// smooth conductor (delta) or directions on opposite sides.
pub(super) fn eval(eta: Rgb, k: Rgb, mf: TrowbridgeReitz, wo: Vec3, wi: Vec3) -> Rgb {
    if !same_hemisphere(wo, wi) || mf.effectively_smooth() {
        return Rgb::ZERO;
    }
    let (cos_o, cos_i) = (wo.z.abs(), wi.z.abs());
    let wm = wi + wo;
    if cos_i == 0.0 || cos_o == 0.0 || wm.length_squared() == 0.0 {
        return Rgb::ZERO;
    }
    let wm = wm.normalize();
    let f = fr_complex_rgb(wo.dot(wm).abs(), eta, k);
    f * (mf.d(wm) * mf.g(wo, wi) / (4.0 * cos_i * cos_o))
}

/// Visible-normal density mapped through the reflection Jacobian:
/// `D_wo(wm) / (4 |wo·wm|)`.
pub(super) fn pdf(mf: TrowbridgeReitz, wo: Vec3, wi: Vec3) -> f32 {
    if !same_hemisphere(wo, wi) || mf.effectively_smooth() || wo.z == 0.0 {
        return 0.0;
    }
    let wm = wo + wi;
    if wm.length_squared() == 0.0 {
        return 0.0;
    }
    // Face forward so the normal is in the distribution's (upper) hemisphere.
    let wm = wm.normalize() * wm.z.signum();
    mf.pdf(wo, wm) / (4.0 * wo.dot(wm).abs())
}

/// Mirror reflection (smooth) or reflection about a visible GGX normal.
pub(super) fn sample(eta: Rgb, k: Rgb, mf: TrowbridgeReitz, wo: Vec3, u: Vec2) -> Option<BsdfSample> {
    if wo.z == 0.0 {
        return None;
    }
    if mf.effectively_smooth() {
        let wi = Vec3::new(-wo.x, -wo.y, wo.z);
        let cos = wi.z.abs();
        let f = fr_complex_rgb(cos, eta, k) / cos;
        return Some(BsdfSample { f, wi, pdf: 1.0, eta: 1.0, delta: true, transmission: false });
    }
    let wm = mf.sample_wm(wo, u);
    let wi = reflect(wo, wm);
    if !same_hemisphere(wo, wi) {
        return None;
    }
    let (cos_o, cos_i) = (wo.z.abs(), wi.z.abs());
    if cos_i == 0.0 {
        return None;
    }
    let pdf = mf.pdf(wo, wm) / (4.0 * wo.dot(wm).abs());
    let f = fr_complex_rgb(wo.dot(wm).abs(), eta, k) * (mf.d(wm) * mf.g(wo, wi) / (4.0 * cos_i * cos_o));
    Some(BsdfSample { f, wi, pdf, eta: 1.0, delta: false, transmission: false })
}
