//! pbrt-v4's `MeasuredBxDF` in RGB: a tabulated BRDF (Dupuy and Jakob
//! 2018) over [`atoll_scene::MeasuredBrdf`]'s tables.
//!
//! Directions map to the unit square by `θ → sqrt(2θ/π)` and `φ → φ/2π +
//! 1/2`; the microfacet normal's square is reached from a uniform sample
//! through the luminance warp, then the visible-normal warp; the BRDF is
//! the reflectance there times `D(wm) / (4 σ(wo) cos θi)`. Reflection only,
//! mirrored to the side of `wo`.

use std::f32::consts::PI;

use atoll_scene::measured::IncidentLookup;
use atoll_scene::{MeasuredBrdf, Rgb};
use glam::{Vec2, Vec3};

use super::{reflect, same_hemisphere, BsdfSample};

/// pbrt's `theta2u`.
#[inline]
fn theta_to_u(theta: f32) -> f32 {
    (theta * (2.0 / PI)).sqrt()
}

/// pbrt's `phi2u`.
#[inline]
fn phi_to_u(phi: f32) -> f32 {
    phi * (0.5 / PI) + 0.5
}

/// pbrt's `SphericalTheta` of a unit vector, as an arctangent. Not
/// [`crate::sampling::spherical_theta`]'s `acos(z)`: that loses the small
/// angles near the pole, where the tables' density goes to zero with the
/// angle, to f32 rounding of `z` to 1.
#[inline]
fn polar_angle(w: Vec3) -> f32 {
    (w.x * w.x + w.y * w.y).sqrt().atan2(w.z)
}

/// The Jacobian of the map from the normal's unit square to solid angle
/// times the reflection's `4 wo·wm` (pbrt's, floored as it floors it).
#[inline]
fn jacobian(wo: Vec3, wm: Vec3, u_wm_x: f32, sin_theta_m: f32) -> f32 {
    4.0 * wo.dot(wm) * (2.0 * PI * PI * u_wm_x * sin_theta_m).max(1e-6)
}

/// The incident direction's parameters: its azimuth and elevation, the
/// tables' lookup, and its square (`u_wo`).
struct Incident {
    phi: f32,
    at: IncidentLookup,
    u_wo: Vec2,
}

fn incident(brdf: &MeasuredBrdf, wo: Vec3) -> Incident {
    let (theta, phi) = (polar_angle(wo), wo.y.atan2(wo.x));
    Incident { phi, at: brdf.incident(phi, theta), u_wo: Vec2::new(theta_to_u(theta), phi_to_u(phi)) }
}

/// The normal between `wo` and `wi` in the unit square (relative to
/// `wo`'s azimuth for an isotropic BRDF), or `None` for opposite directions.
fn normal_square(brdf: &MeasuredBrdf, inc: &Incident, wo: Vec3, wi: Vec3) -> Option<(Vec3, Vec2)> {
    let wm = wo + wi;
    if wm.length_squared() == 0.0 {
        return None;
    }
    let wm = wm.normalize();
    let phi_m = wm.y.atan2(wm.x);
    let v = phi_to_u(if brdf.isotropic { phi_m - inc.phi } else { phi_m });
    Some((wm, Vec2::new(theta_to_u(polar_angle(wm)), v - v.floor())))
}

/// The reflectance at sample-square point `s` times `D(wm) / (4 σ(wo) cos θi)`.
fn value(brdf: &MeasuredBrdf, inc: &Incident, s: Vec2, u_wm: Vec2, cos_theta_i: f32) -> Rgb {
    let rgb = Rgb::from_array([0, 1, 2].map(|c| brdf.rgb.evaluate(s, &inc.at, c).max(0.0)));
    let single = IncidentLookup::SINGLE;
    rgb * (brdf.ndf.evaluate(u_wm, &single, 0)
        / (4.0 * brdf.sigma.evaluate(inc.u_wo, &single, 0) * cos_theta_i))
}

/// What `eval` and `pdf` both need of a pair of directions: mirrored to
/// `wo`'s side being +z (as pbrt flips them), the incident parameters, the
/// normal between them and its square, and the sample that maps to it.
struct Pair {
    wo: Vec3,
    wi: Vec3,
    inc: Incident,
    wm: Vec3,
    u_wm: Vec2,
    s: Vec2,
    vndf_pdf: f32,
}

/// The [`Pair`] of `wo` and `wi`; `None` across the surface or for
/// opposite directions.
fn pair(brdf: &MeasuredBrdf, wo: Vec3, wi: Vec3) -> Option<Pair> {
    if !same_hemisphere(wo, wi) {
        return None;
    }
    let (wo, wi) = if wo.z < 0.0 { (-wo, -wi) } else { (wo, wi) };
    let inc = incident(brdf, wo);
    let (wm, u_wm) = normal_square(brdf, &inc, wo, wi)?;
    let (s, vndf_pdf) = brdf.vndf.invert(u_wm, &inc.at);
    Some(Pair { wo, wi, inc, wm, u_wm, s, vndf_pdf })
}

/// pbrt's `MeasuredBxDF::f`.
pub fn eval(brdf: &MeasuredBrdf, wo: Vec3, wi: Vec3) -> Rgb {
    pair(brdf, wo, wi).map_or(Rgb::ZERO, |q| value(brdf, &q.inc, q.s, q.u_wm, q.wi.z))
}

/// pbrt's `MeasuredBxDF::PDF`.
pub fn pdf(brdf: &MeasuredBrdf, wo: Vec3, wi: Vec3) -> f32 {
    let Some(q) = pair(brdf, wo, wi) else {
        return 0.0;
    };
    let luminance_pdf = brdf.luminance.evaluate(q.s, &q.inc.at, 0);
    let sin_theta_m = (q.wm.x * q.wm.x + q.wm.y * q.wm.y).sqrt();
    q.vndf_pdf * luminance_pdf / jacobian(q.wo, q.wm, q.u_wm.x, sin_theta_m)
}

/// pbrt's `MeasuredBxDF::Sample_f`.
pub fn sample(brdf: &MeasuredBrdf, wo: Vec3, u: Vec2) -> Option<BsdfSample> {
    let flip = wo.z <= 0.0;
    let wo = if flip { -wo } else { wo };
    let inc = incident(brdf, wo);
    let (s, luminance_pdf) = brdf.luminance.sample(u, &inc.at);
    let (u_wm, vndf_pdf) = brdf.vndf.sample(s, &inc.at);
    let mut phi_m = (2.0 * u_wm.y - 1.0) * PI;
    if brdf.isotropic {
        phi_m += inc.phi;
    }
    let theta_m = u_wm.x * u_wm.x * (PI / 2.0);
    let (sin_theta_m, cos_theta_m) = theta_m.sin_cos();
    let wm = Vec3::new(sin_theta_m * phi_m.cos(), sin_theta_m * phi_m.sin(), cos_theta_m);
    let wi = reflect(wo, wm);
    if wi.z <= 0.0 {
        return None;
    }
    let f = value(brdf, &inc, s, u_wm, wi.z);
    let pdf = vndf_pdf * luminance_pdf / jacobian(wo, wm, u_wm.x, sin_theta_m);
    let wi = if flip { -wi } else { wi };
    Some(BsdfSample { f, wi, pdf, eta: 1.0, delta: false, transmission: false })
}
