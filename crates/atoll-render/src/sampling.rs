//! Warping functions: map uniform numbers in `[0, 1)^n` to points and
//! directions with known densities (pbrt-v4's `util/sampling.h`), plus the
//! power heuristic for multiple importance sampling and spherical-coordinate
//! helpers. Everything here is plain math with no state so the CUDA kernels can
//! mirror it line by line.

use crate::bsdf::Frame;
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, FRAC_PI_2, FRAC_PI_4, PI};

/// Density of [`sample_uniform_sphere`] with respect to solid angle: `1 / 4π`.
pub const UNIFORM_SPHERE_PDF: f32 = 1.0 / (4.0 * PI);
/// Density of [`sample_uniform_hemisphere`] with respect to solid angle: `1 / 2π`.
pub const UNIFORM_HEMISPHERE_PDF: f32 = 1.0 / (2.0 * PI);

/// Uniform point on the unit disk with Shirley–Chiu's concentric mapping
/// (pbrt-v4 `SampleUniformDiskConcentric`): low distortion, so stratified
/// inputs stay well stratified.
pub fn sample_uniform_disk_concentric(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    // Pick the wedge by the larger coordinate; the other one sets the angle.
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, FRAC_PI_4 * (o.y / o.x))
    } else {
        (o.y, FRAC_PI_2 - FRAC_PI_4 * (o.x / o.y))
    };
    r * Vec2::new(theta.cos(), theta.sin())
}

/// Uniform point on the unit disk with the polar mapping `r = sqrt(u0)`,
/// `phi = 2π u1` (pbrt-v4 `SampleUniformDiskPolar`). The GGX visible-normal
/// sampler relies on this one: its warp assumes `p.x` and `p.y` come from it.
pub fn sample_uniform_disk_polar(u: Vec2) -> Vec2 {
    let r = u.x.sqrt();
    let theta = 2.0 * PI * u.y;
    r * Vec2::new(theta.cos(), theta.sin())
}

/// Cosine-weighted direction on the +z hemisphere by Malley's method (lift a
/// concentric-disk point onto the hemisphere). Density: [`cosine_hemisphere_pdf`].
pub fn sample_cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = sample_uniform_disk_concentric(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

/// Solid-angle density of [`sample_cosine_hemisphere`]: `cos θ / π`.
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta * FRAC_1_PI
}

/// Uniform direction on the unit sphere (pbrt-v4 `SampleUniformSphere`).
/// Density: [`UNIFORM_SPHERE_PDF`].
pub fn sample_uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Density of [`sample_uniform_sphere`]; a function for symmetry with the others.
pub fn uniform_sphere_pdf() -> f32 {
    UNIFORM_SPHERE_PDF
}

/// Uniform direction on the +z hemisphere (pbrt-v4 `SampleUniformHemisphere`).
/// Density: [`UNIFORM_HEMISPHERE_PDF`].
pub fn sample_uniform_hemisphere(u: Vec2) -> Vec3 {
    let z = u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Density of [`sample_uniform_hemisphere`].
pub fn uniform_hemisphere_pdf() -> f32 {
    UNIFORM_HEMISPHERE_PDF
}

/// Uniformly distributed barycentrics `[b0, b1, b2]` on a triangle, with
/// Heitz's low-distortion square-to-triangle map (pbrt-v4
/// `SampleUniformTriangle`). The point is `b0 p0 + b1 p1 + b2 p2`; the area
/// density is `1 / area`.
pub fn sample_uniform_triangle(u: Vec2) -> [f32; 3] {
    let (b0, b1) = if u.x < u.y {
        let b0 = u.x / 2.0;
        (b0, u.y - b0)
    } else {
        let b1 = u.y / 2.0;
        (u.x - b1, b1)
    };
    [b0, b1, 1.0 - b0 - b1]
}

/// Veach's power heuristic (beta = 2) for one sample from each of two
/// strategies: the MIS weight of the strategy with density `f_pdf`. pbrt-v4's
/// version also takes sample counts; every caller here uses one each. Returns
/// 1 when `f_pdf²` overflows and 0 when both densities are zero (pbrt would
/// give NaN there).
pub fn power_heuristic(f_pdf: f32, g_pdf: f32) -> f32 {
    let f2 = f_pdf * f_pdf;
    let g2 = g_pdf * g_pdf;
    if f2.is_infinite() {
        return 1.0;
    }
    if f2 + g2 == 0.0 {
        return 0.0;
    }
    f2 / (f2 + g2)
}

/// A distance with the exponential density `a e^(-a x)`, sampled by
/// inverting its CDF (pbrt-v4 `SampleExponential`): `-ln(1 - u) / a`.
pub fn sample_exponential(u: f32, a: f32) -> f32 {
    -(1.0 - u).ln() / a
}

/// The Henyey–Greenstein phase function for the cosine between `wo` and
/// `wi` (pbrt-v4 `HenyeyGreenstein`). Both point away from the scattering
/// point, so forward scattering (`g > 0`) peaks at `cos_theta = -1`. `g` is
/// clamped to ±0.99, where the function is still numerically stable.
pub fn henyey_greenstein(cos_theta: f32, g: f32) -> f32 {
    let g = g.clamp(-0.99, 0.99);
    let denom = 1.0 + g * g + 2.0 * g * cos_theta;
    (1.0 / (4.0 * PI)) * (1.0 - g * g) / (denom * denom.max(0.0).sqrt())
}

/// Samples the Henyey–Greenstein distribution around `wo` exactly (pbrt-v4
/// `SampleHenyeyGreenstein`): `cos θ` by inverting its CDF, the azimuth
/// uniformly. Returns `wi` and its density, which equals the phase function.
pub fn sample_henyey_greenstein(wo: Vec3, g: f32, u: Vec2) -> (Vec3, f32) {
    let g = g.clamp(-0.99, 0.99);
    let cos_theta = if g.abs() < 1e-3 {
        1.0 - 2.0 * u.x
    } else {
        let s = (1.0 - g * g) / (1.0 + g - 2.0 * g * u.x);
        -1.0 / (2.0 * g) * (1.0 + g * g - s * s)
    };
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    let wi = Frame::from_z(wo).from_local(spherical_direction(sin_theta, cos_theta, phi));
    (wi, henyey_greenstein(cos_theta, g))
}

/// Unit vector from spherical coordinates, with `sin θ` and `cos θ` given
/// (pbrt-v4 `SphericalDirection`); `sin θ` is clamped to `[-1, 1]`.
pub fn spherical_direction(sin_theta: f32, cos_theta: f32, phi: f32) -> Vec3 {
    let s = sin_theta.clamp(-1.0, 1.0);
    Vec3::new(s * phi.cos(), s * phi.sin(), cos_theta.clamp(-1.0, 1.0))
}

/// Polar angle `θ ∈ [0, π]` of a unit vector, measured from +z.
pub fn spherical_theta(v: Vec3) -> f32 {
    v.z.clamp(-1.0, 1.0).acos()
}

/// Azimuth `φ ∈ [0, 2π)` of a vector around +z, measured from +x.
pub fn spherical_phi(v: Vec3) -> f32 {
    let p = v.y.atan2(v.x);
    if p < 0.0 {
        p + 2.0 * PI
    } else {
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator of points in `[0, 1)^2` (a 2-D Halton
    /// sequence) so the tests need no RNG dependency.
    fn halton(i: u32) -> Vec2 {
        fn radical_inverse(mut i: u32, base: u32) -> f32 {
            let (mut inv, mut f) = (0.0f64, 1.0f64 / base as f64);
            while i > 0 {
                inv += (i % base) as f64 * f;
                i /= base;
                f /= base as f64;
            }
            inv as f32
        }
        Vec2::new(radical_inverse(i, 2), radical_inverse(i, 3))
    }

    #[test]
    fn concentric_disk_is_inside_and_uniform() {
        let n = 20_000;
        let mut inner = 0;
        let mut quadrant = [0u32; 4];
        for i in 0..n {
            let p = sample_uniform_disk_concentric(halton(i));
            assert!(p.length() <= 1.0 + 1e-6, "{p}");
            // The disk of radius 1/√2 holds half the area.
            if p.length_squared() < 0.5 {
                inner += 1;
            }
            quadrant[(p.x < 0.0) as usize * 2 + (p.y < 0.0) as usize] += 1;
        }
        assert!((inner as f32 / n as f32 - 0.5).abs() < 0.01, "{inner}");
        for q in quadrant {
            assert!((q as f32 / n as f32 - 0.25).abs() < 0.01, "{quadrant:?}");
        }
        assert_eq!(sample_uniform_disk_concentric(Vec2::splat(0.5)), Vec2::ZERO);
    }

    #[test]
    fn polar_disk_is_uniform() {
        let n = 20_000;
        let inner = (0..n).filter(|&i| sample_uniform_disk_polar(halton(i)).length_squared() < 0.25).count();
        assert!((inner as f32 / n as f32 - 0.25).abs() < 0.01, "{inner}");
    }

    #[test]
    fn cosine_hemisphere_moments() {
        // E[cos θ] = ∫ cos² / π dω = 2/3; E[cos² θ] = 1/2; directions are unit.
        let n = 20_000;
        let (mut m1, mut m2) = (0.0f64, 0.0f64);
        for i in 0..n {
            let w = sample_cosine_hemisphere(halton(i));
            assert!((w.length() - 1.0).abs() < 1e-5 && w.z >= 0.0, "{w}");
            m1 += w.z as f64;
            m2 += (w.z * w.z) as f64;
        }
        assert!((m1 / n as f64 - 2.0 / 3.0).abs() < 2e-3, "{}", m1 / n as f64);
        assert!((m2 / n as f64 - 0.5).abs() < 2e-3, "{}", m2 / n as f64);
        assert!((cosine_hemisphere_pdf(1.0) - FRAC_1_PI).abs() < 1e-7);
    }

    #[test]
    fn uniform_sphere_and_hemisphere() {
        let n = 20_000;
        let (mut mean, mut upper, mut mean_z2) = (Vec3::ZERO, 0, 0.0f64);
        for i in 0..n {
            let w = sample_uniform_sphere(halton(i));
            assert!((w.length() - 1.0).abs() < 1e-5, "{w}");
            mean += w;
            upper += (w.z > 0.0) as u32;
            let h = sample_uniform_hemisphere(halton(i));
            assert!((h.length() - 1.0).abs() < 1e-5 && h.z >= 0.0, "{h}");
            mean_z2 += (h.z * h.z) as f64;
        }
        assert!((mean / n as f32).length() < 0.01, "{mean}");
        assert!((upper as f32 / n as f32 - 0.5).abs() < 0.01, "{upper}");
        // Uniform on the hemisphere: cos θ is uniform, so E[cos²] = 1/3.
        assert!((mean_z2 / n as f64 - 1.0 / 3.0).abs() < 2e-3);
        assert!((uniform_sphere_pdf() * 4.0 * PI - 1.0).abs() < 1e-6);
        assert!((uniform_hemisphere_pdf() * 2.0 * PI - 1.0).abs() < 1e-6);
    }

    #[test]
    fn triangle_barycentrics_are_valid_and_uniform() {
        let n = 30_000;
        let mut mean = [0.0f64; 3];
        let mut near_v0 = 0;
        for i in 0..n {
            let b = sample_uniform_triangle(halton(i));
            assert!(b.iter().all(|&x| (-1e-6..=1.0 + 1e-6).contains(&x)), "{b:?}");
            assert!((b[0] + b[1] + b[2] - 1.0).abs() < 1e-6);
            for k in 0..3 {
                mean[k] += b[k] as f64;
            }
            // b0 > 1/2 is the corner triangle at vertex 0: a quarter of the area.
            near_v0 += (b[0] > 0.5) as u32;
        }
        for m in mean {
            assert!((m / n as f64 - 1.0 / 3.0).abs() < 3e-3, "{mean:?}");
        }
        assert!((near_v0 as f32 / n as f32 - 0.25).abs() < 0.01, "{near_v0}");
    }

    #[test]
    fn power_heuristic_values() {
        assert_eq!(power_heuristic(1.0, 0.0), 1.0);
        assert_eq!(power_heuristic(0.0, 1.0), 0.0);
        assert_eq!(power_heuristic(0.0, 0.0), 0.0);
        assert!((power_heuristic(1.0, 1.0) - 0.5).abs() < 1e-7);
        assert!((power_heuristic(2.0, 1.0) - 0.8).abs() < 1e-6);
        assert!((power_heuristic(2.0, 1.0) + power_heuristic(1.0, 2.0) - 1.0).abs() < 1e-6);
        assert_eq!(power_heuristic(f32::INFINITY, 1.0), 1.0);
    }

    /// Henyey–Greenstein: normalised over the sphere, sampled exactly (the
    /// returned density is the phase function of the sampled direction), and
    /// with pbrt's orientation: mean cosine between `wo` and `wi` is `-g`.
    #[test]
    fn henyey_greenstein_is_normalised_and_sampled_exactly() {
        let wo = Vec3::new(0.3, -0.5, 0.8).normalize();
        for g in [-0.7f32, -0.2, 0.0, 0.5, 0.9] {
            let n = 40_000;
            // ∫ p dω over the sphere, cos θ uniform in [-1, 1] by the midpoint rule.
            let cos = |i: u32| 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let sum: f64 = (0..n).map(|i| henyey_greenstein(cos(i), g) as f64).sum();
            let integral = sum * 4.0 * std::f64::consts::PI / n as f64;
            assert!((integral - 1.0).abs() < 1e-3, "g={g}: {integral}");
            let mut mean_cos = 0.0f64;
            for i in 0..n {
                let (wi, pdf) = sample_henyey_greenstein(wo, g, halton(i));
                assert!((wi.length() - 1.0).abs() < 1e-4, "{wi}");
                let p = henyey_greenstein(wo.dot(wi), g);
                assert!((pdf - p).abs() <= 2e-3 * p, "g={g}: {pdf} vs {p}");
                mean_cos += wo.dot(wi) as f64;
            }
            assert!((mean_cos / n as f64 + g as f64).abs() < 5e-3, "g={g}: {}", mean_cos / n as f64);
        }
    }

    #[test]
    fn exponential_distances_have_mean_one_over_rate() {
        let n = 20_000;
        let mean = (0..n).map(|i| sample_exponential(halton(i).x, 4.0) as f64).sum::<f64>() / n as f64;
        assert!((mean - 0.25).abs() < 2e-3, "{mean}");
        assert_eq!(sample_exponential(0.0, 2.0), 0.0);
    }

    #[test]
    fn spherical_round_trip() {
        for i in 0..1000 {
            let w = sample_uniform_sphere(halton(i));
            let (theta, phi) = (spherical_theta(w), spherical_phi(w));
            assert!((0.0..=PI).contains(&theta) && (0.0..2.0 * PI).contains(&phi));
            let back = spherical_direction(theta.sin(), theta.cos(), phi);
            assert!((back - w).length() < 1e-5, "{w} {back}");
        }
        assert!((spherical_phi(Vec3::new(0.0, -1.0, 0.0)) - 1.5 * PI).abs() < 1e-6);
    }
}
