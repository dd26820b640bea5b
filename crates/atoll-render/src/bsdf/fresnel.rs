//! Fresnel reflectance and the law of reflection/refraction (pbrt-v4's
//! `util/scattering.h`: `Reflect`, `Refract`, `FrDielectric`, `FrComplex`).
//!
//! Convention (pbrt's): `eta` is the relative index of refraction
//! `η_inside / η_outside`, where "inside" is the side the normal points away
//! from (−z in the shading frame). A cosine below zero means the incident
//! direction is inside, and the functions use `1 / eta`.

use atoll_scene::Rgb;
use glam::Vec3;

/// Mirror `wo` about the normal `n` (both unit, `wo` pointing away from the
/// surface); the result also points away from it (pbrt-v4 `Reflect`).
#[inline]
pub fn reflect(wo: Vec3, n: Vec3) -> Vec3 {
    -wo + 2.0 * wo.dot(n) * n
}

/// Refract `wi` (unit, pointing away from the surface) through the interface
/// with normal `n` and relative index `eta` (pbrt-v4 `Refract`). Works from
/// either side: when `wi` is on the side opposite `n`, the interface is seen
/// with `1 / eta` and a flipped normal. Returns the transmitted direction
/// (unit, pointing away on the other side) and the relative index `etap`
/// actually used, or `None` on total internal reflection.
#[inline]
pub fn refract(wi: Vec3, n: Vec3, eta: f32) -> Option<(Vec3, f32)> {
    let mut cos_i = n.dot(wi);
    let (mut eta, mut n) = (eta, n);
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
        n = -n;
    }
    // Snell's law in terms of squared sines.
    let sin2_i = (1.0 - cos_i * cos_i).max(0.0);
    let sin2_t = sin2_i / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    Some((-wi / eta + (cos_i / eta - cos_t) * n, eta))
}

/// Unpolarised Fresnel reflectance of a dielectric interface (pbrt-v4
/// `FrDielectric`): `cos_theta_i` is the cosine between the incident direction
/// and the normal; a negative cosine means the ray arrives from inside and the
/// interface is seen with `1 / eta`. Returns 1 on total internal reflection.
#[inline]
pub fn fr_dielectric(cos_theta_i: f32, eta: f32) -> f32 {
    let mut cos_i = cos_theta_i.clamp(-1.0, 1.0);
    let mut eta = eta;
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
    }
    let sin2_i = 1.0 - cos_i * cos_i;
    let sin2_t = sin2_i / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    (r_parl * r_parl + r_perp * r_perp) / 2.0
}

/// A minimal complex number for [`fr_complex`]; only what it needs.
#[derive(Clone, Copy, Debug)]
struct Complex {
    re: f32,
    im: f32,
}

impl Complex {
    const fn new(re: f32, im: f32) -> Self {
        Complex { re, im }
    }
    fn add(self, o: Complex) -> Complex {
        Complex::new(self.re + o.re, self.im + o.im)
    }
    fn sub(self, o: Complex) -> Complex {
        Complex::new(self.re - o.re, self.im - o.im)
    }
    fn mul(self, o: Complex) -> Complex {
        Complex::new(self.re * o.re - self.im * o.im, self.re * o.im + self.im * o.re)
    }
    fn scale(self, s: f32) -> Complex {
        Complex::new(self.re * s, self.im * s)
    }
    /// Squared magnitude (pbrt's `norm`).
    fn norm(self) -> f32 {
        self.re * self.re + self.im * self.im
    }
    fn div(self, o: Complex) -> Complex {
        let s = 1.0 / o.norm();
        Complex::new((self.re * o.re + self.im * o.im) * s, (self.im * o.re - self.re * o.im) * s)
    }
    /// Principal square root, computed as pbrt-v4's `pstd::sqrt(complex)` does
    /// to stay accurate when the real part dominates.
    fn sqrt(self) -> Complex {
        let n = self.norm().sqrt();
        if n == 0.0 {
            return Complex::new(0.0, 0.0);
        }
        let t1 = (0.5 * (n + self.re.abs())).sqrt();
        let t2 = 0.5 * self.im / t1;
        if self.re >= 0.0 {
            Complex::new(t1, t2)
        } else {
            Complex::new(t2.abs(), t1.copysign(self.im))
        }
    }
}

/// The share of light from a Lambertian (cosine-weighted) source inside a
/// smooth boundary of relative index `eta` (inside / outside) that it lets
/// out: 1 − 2 ∫₀¹ Fr(μ, η) μ dμ, with μ the cosine outside (Fresnel
/// transmittance is the same both ways). It normalises pbrt-v4's
/// `NormalizedFresnelBxDF`, the lobe light leaves a subsurface medium by;
/// integrated here rather than taken from pbrt's polynomial fit of the
/// moment, so that the lobe conserves energy exactly.
pub fn diffuse_transmittance(eta: f32) -> f32 {
    // The midpoint rule over x = μ², since 2 Fr(μ) μ dμ = Fr(√x) dx.
    const STEPS: u32 = 256;
    let reflected: f64 = (0..STEPS)
        .map(|i| {
            let mu2 = (i as f64 + 0.5) / STEPS as f64;
            fr_dielectric(mu2.sqrt() as f32, eta) as f64
        })
        .sum::<f64>()
        / STEPS as f64;
    (1.0 - reflected) as f32
}

/// Unpolarised Fresnel reflectance of a conductor with complex index
/// `eta + i k` (pbrt-v4 `FrComplex`); `cos_theta_i` is clamped to `[0, 1]`
/// since conductors are opaque and seen from outside only. With `k = 0` it
/// equals [`fr_dielectric`].
#[inline]
pub fn fr_complex(cos_theta_i: f32, eta: f32, k: f32) -> f32 {
    let cos_i = cos_theta_i.clamp(0.0, 1.0);
    let eta = Complex::new(eta, k);
    let sin2_i = 1.0 - cos_i * cos_i;
    let sin2_t = Complex::new(sin2_i, 0.0).div(eta.mul(eta));
    let cos_t = Complex::new(1.0, 0.0).sub(sin2_t).sqrt();
    let ci = Complex::new(cos_i, 0.0);
    let eci = eta.scale(cos_i);
    let r_parl = eci.sub(cos_t).div(eci.add(cos_t));
    let ect = eta.mul(cos_t);
    let r_perp = ci.sub(ect).div(ci.add(ect));
    (r_parl.norm() + r_perp.norm()) / 2.0
}

/// [`fr_complex`] per RGB channel (pbrt evaluates it per wavelength).
#[inline]
pub fn fr_complex_rgb(cos_theta_i: f32, eta: Rgb, k: Rgb) -> Rgb {
    Rgb::new(
        fr_complex(cos_theta_i, eta.x, k.x),
        fr_complex(cos_theta_i, eta.y, k.y),
        fr_complex(cos_theta_i, eta.z, k.z),
    )
}
