//! pbrt-v4's `DiffuseTransmissionBxDF` and `ThinDielectricBxDF`.

use atoll_scene::Rgb;
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

use super::{fr_dielectric, BsdfSample};
use crate::sampling::{cosine_hemisphere_pdf, sample_cosine_hemisphere};

/// Lobe selection weights of a diffuse-transmission BSDF: the largest
/// channel of each (pbrt's `MaxComponentValue`).
pub fn lobe_weights(reflectance: Rgb, transmittance: Rgb) -> (f32, f32) {
    (reflectance.max_element(), transmittance.max_element())
}

/// Reflection on `wo`'s side with probability `pr / (pr + pt)`, else
/// transmission to the other; cosine-weighted either way.
pub fn sample_diffuse_transmission(
    reflectance: Rgb,
    transmittance: Rgb,
    wo: Vec3,
    uc: f32,
    u: Vec2,
) -> Option<BsdfSample> {
    let (pr, pt) = lobe_weights(reflectance, transmittance);
    if pr + pt == 0.0 {
        return None;
    }
    let mut wi = sample_cosine_hemisphere(u);
    if uc < pr / (pr + pt) {
        if wo.z < 0.0 {
            wi.z = -wi.z;
        }
        let pdf = pr / (pr + pt) * cosine_hemisphere_pdf(wi.z.abs());
        Some(BsdfSample { f: reflectance * FRAC_1_PI, wi, pdf, eta: 1.0, delta: false, transmission: false })
    } else {
        if wo.z > 0.0 {
            wi.z = -wi.z;
        }
        let pdf = pt / (pr + pt) * cosine_hemisphere_pdf(wi.z.abs());
        Some(BsdfSample { f: transmittance * FRAC_1_PI, wi, pdf, eta: 1.0, delta: false, transmission: true })
    }
}

/// Reflectance of a thin slab of index `eta` at `|cos θ| = cos_theta`: the
/// interface's Fresnel reflectance plus every path that bounces inside and
/// leaves on the incident side, `R + T² R / (1 - R²)`.
pub fn thin_reflectance(cos_theta: f32, eta: f32) -> f32 {
    let r = fr_dielectric(cos_theta, eta);
    if r < 1.0 {
        let t = 1.0 - r;
        r + t * t * r / (1.0 - r * r)
    } else {
        r
    }
}

/// Specular reflection with probability `R`, else straight transmission.
pub fn sample_thin_dielectric(eta: f32, wo: Vec3, uc: f32) -> Option<BsdfSample> {
    let r = thin_reflectance(wo.z.abs(), eta);
    let t = 1.0 - r;
    if uc < r / (r + t) {
        let wi = Vec3::new(-wo.x, -wo.y, wo.z);
        let f = Rgb::splat(r / wi.z.abs());
        Some(BsdfSample { f, wi, pdf: r / (r + t), eta: 1.0, delta: true, transmission: false })
    } else {
        let wi = -wo;
        let f = Rgb::splat(t / wi.z.abs());
        Some(BsdfSample { f, wi, pdf: t / (r + t), eta: 1.0, delta: true, transmission: true })
    }
}
