//! The anisotropic Trowbridge–Reitz (GGX) microfacet distribution with Smith
//! masking and visible-normal sampling (pbrt-v4's
//! `TrowbridgeReitzDistribution`, `util/scattering.h`). All directions are in
//! the local shading frame (normal = +z).

use crate::sampling::sample_uniform_disk_polar;
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// Below this roughness the distribution is treated as a perfect mirror /
/// perfectly smooth interface (pbrt-v4 `EffectivelySmooth`).
pub const SMOOTH_ALPHA: f32 = 1e-3;

/// GGX distribution with roughness `alpha_x`, `alpha_y` along the local x and
/// y axes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrowbridgeReitz {
    /// Roughness along local x.
    pub alpha_x: f32,
    /// Roughness along local y.
    pub alpha_y: f32,
}

impl TrowbridgeReitz {
    /// As pbrt-v4's constructor: if the distribution is rough at all, neither
    /// alpha may be (near) zero, or `D` blows up along the smooth axis.
    pub fn new(alpha_x: f32, alpha_y: f32) -> Self {
        let mut d = TrowbridgeReitz { alpha_x, alpha_y };
        if !d.effectively_smooth() {
            d.alpha_x = d.alpha_x.max(1e-4);
            d.alpha_y = d.alpha_y.max(1e-4);
        }
        d
    }

    /// True when both alphas are below [`SMOOTH_ALPHA`]: callers then use the
    /// specular (delta) form of their BSDF.
    #[inline]
    pub fn effectively_smooth(&self) -> bool {
        self.alpha_x.max(self.alpha_y) < SMOOTH_ALPHA
    }

    /// Normal distribution `D(wm)` for a unit microfacet normal in the upper
    /// hemisphere. pbrt writes it with `tan²θ` and `cos⁴θ`; multiplying those
    /// out gives the equivalent branch-free form
    /// `1 / (π αx αy (x²/αx² + y²/αy² + z²)²)`.
    #[inline]
    pub fn d(&self, wm: Vec3) -> f32 {
        let (sx, sy) = (wm.x / self.alpha_x, wm.y / self.alpha_y);
        let q = sx * sx + sy * sy + wm.z * wm.z;
        1.0 / (PI * self.alpha_x * self.alpha_y * q * q)
    }

    /// Smith's auxiliary function `Λ(w)` (pbrt-v4 `Lambda`), with
    /// `α² tan²θ = (αx² x² + αy² y²) / z²`. Infinite at grazing `w`, which makes
    /// the masking terms zero there.
    #[inline]
    pub fn lambda(&self, w: Vec3) -> f32 {
        let (ax, ay) = (self.alpha_x * w.x, self.alpha_y * w.y);
        let a2_tan2 = (ax * ax + ay * ay) / (w.z * w.z);
        ((1.0 + a2_tan2).sqrt() - 1.0) / 2.0
    }

    /// Smith masking for one direction, `G1 = 1 / (1 + Λ)`.
    #[inline]
    pub fn g1(&self, w: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    /// Height-correlated masking-shadowing `G = 1 / (1 + Λ(wo) + Λ(wi))`.
    #[inline]
    pub fn g(&self, wo: Vec3, wi: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// Distribution of normals visible from `w` (pbrt-v4 `D(w, wm)`):
    /// `G1(w) |w·wm| D(wm) / |cos θ_w|`. Integrates to 1 over the microfacet
    /// normals that face `w`.
    #[inline]
    pub fn d_visible(&self, w: Vec3, wm: Vec3) -> f32 {
        self.g1(w) / w.z.abs() * self.d(wm) * w.dot(wm).abs()
    }

    /// Density of [`Self::sample_wm`] with respect to the solid angle of `wm`.
    #[inline]
    pub fn pdf(&self, w: Vec3, wm: Vec3) -> f32 {
        self.d_visible(w, wm)
    }

    /// Sample a microfacet normal from the distribution of normals visible
    /// from `w` (pbrt-v4 `Sample_wm`, Heitz 2018 "Sampling the GGX
    /// distribution of visible normals"): stretch `w` into the hemisphere
    /// configuration (alpha = 1), sample the projected hemisphere as a disk
    /// warped toward the visible half, lift and unstretch. Works for `w` below
    /// the surface by sampling for `-w` (the result always has `z > 0`).
    pub fn sample_wm(&self, w: Vec3, u: Vec2) -> Vec3 {
        let mut wh = Vec3::new(self.alpha_x * w.x, self.alpha_y * w.y, w.z).normalize();
        if wh.z < 0.0 {
            wh = -wh;
        }
        // Orthonormal basis around wh; at normal incidence any tangent works.
        let t1 = if wh.z < 0.99999 { Vec3::Z.cross(wh).normalize() } else { Vec3::X };
        let t2 = wh.cross(t1);
        let mut p = sample_uniform_disk_polar(u);
        // Squash the lower half of the disk so the points cover the projection
        // of the visible hemisphere only.
        let h = (1.0 - p.x * p.x).max(0.0).sqrt();
        let s = (1.0 + wh.z) / 2.0;
        p.y = (1.0 - s) * h + s * p.y;
        let pz = (1.0 - p.length_squared()).max(0.0).sqrt();
        let nh = p.x * t1 + p.y * t2 + pz * wh;
        Vec3::new(self.alpha_x * nh.x, self.alpha_y * nh.y, nh.z.max(1e-6)).normalize()
    }
}
