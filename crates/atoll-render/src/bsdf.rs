//! BSDFs with pbrt-v4 semantics for the scene's materials: Lambertian
//! diffuse, conductor (smooth mirror or anisotropic GGX), dielectric
//! (smooth or rough, reflection and transmission), diffuse transmission,
//! thin dielectric, coated diffuse (a stochastic layered BSDF), the
//! Disney-principled BSDF and hair fibres, in RGB.
//!
//! Conventions (pbrt's):
//! - Everything works in the local shading frame ([`Frame`]): the shading
//!   normal is +z. `wo` and `wi` are unit vectors pointing *away* from the
//!   surface; `f` excludes the cosine factor `|wi.z|`.
//! - A dielectric's `eta` is `η_inside / η_outside`, inside being −z. Seen from
//!   below, the interface has index `1 / eta`.
//! - Transmission is in radiance mode: the BTDF carries the `1 / etap²` factor
//!   (pbrt's `TransportMode::Radiance`), `etap` being the relative index seen
//!   from `wo`'s side, reported in [`BsdfSample::eta`].
//! - Specular (delta) lobes are only reachable through [`Bsdf::sample`]:
//!   `eval` and `pdf` return 0 for them, and the sample's `pdf` is the
//!   discrete probability of choosing that lobe.
//!
//! The enum is plain data with one `match` per method and no trait objects,
//! so the CUDA kernels can port it one to one.

mod conductor;
mod dielectric;
pub mod fresnel;
pub mod hair;
pub mod layered;
pub mod measured;
pub mod microfacet;
pub mod principled;
mod thin;

pub use fresnel::{fr_complex, fr_complex_rgb, fr_dielectric, reflect, refract};
pub use hair::Hair;
pub use layered::{Coated, CoatedBase};
pub use microfacet::TrowbridgeReitz;
pub use principled::Principled;

use crate::sampling::{cosine_hemisphere_pdf, sample_cosine_hemisphere};
use atoll_scene::{Material, MeasuredBrdf, Rgb};
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// An orthonormal basis `(x, y, z)` built around a unit normal `z`, to move
/// directions between world space and the local shading frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// First tangent.
    pub x: Vec3,
    /// Second tangent, `z × x`.
    pub y: Vec3,
    /// The normal.
    pub z: Vec3,
}

impl Frame {
    /// Basis around the unit normal `n` by Duff et al. 2017, "Building an
    /// orthonormal basis, revisited": branch-free (a `copysign`), continuous
    /// except across `n.z = 0`, and exact for `n = (0, 0, -1)` where Frisvad's
    /// original version breaks.
    pub fn from_z(n: Vec3) -> Frame {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let x = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let y = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { x, y, z: n }
    }

    /// Basis with `z` the unit normal and `x` the direction of `x_hint` in
    /// the plane normal to it (pbrt's `Frame::FromXZ` after making the two
    /// orthogonal): a hair's frame, whose x is its axis. `from_z` when the
    /// hint is (nearly) zero or along the normal.
    pub fn from_xz(x_hint: Vec3, z: Vec3) -> Frame {
        let x = (x_hint - z * x_hint.dot(z)).normalize_or_zero();
        if x == Vec3::ZERO || !x.is_finite() {
            return Frame::from_z(z);
        }
        Frame { x, y: z.cross(x), z }
    }

    /// World-space vector to local coordinates (components along x, y, z).
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.x), v.dot(self.y), v.dot(self.z))
    }

    /// Local-frame vector back to world space. (Named as pbrt's `FromLocal`;
    /// it maps a vector through the frame, so it takes `self`.)
    #[allow(clippy::wrong_self_convention)]
    #[inline]
    pub fn from_local(&self, v: Vec3) -> Vec3 {
        self.x * v.x + self.y * v.y + self.z * v.z
    }
}

/// Both directions on the same side of the surface (pbrt `SameHemisphere`).
#[inline]
pub(crate) fn same_hemisphere(a: Vec3, b: Vec3) -> bool {
    a.z * b.z > 0.0
}

/// A BSDF at a hit point, in the local shading frame; it borrows the
/// scene's tables where it has any (measured BRDFs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Bsdf<'a> {
    /// Lambertian reflection on both sides of the surface.
    Diffuse {
        /// Hemispherical reflectance (albedo) per channel.
        reflectance: Rgb,
    },
    /// Metal with complex index `eta + i k` per channel; a mirror when both
    /// alphas are below [`microfacet::SMOOTH_ALPHA`], anisotropic GGX otherwise.
    Conductor {
        /// Real part of the index of refraction.
        eta: Rgb,
        /// Absorption coefficient (imaginary part).
        k: Rgb,
        /// GGX roughness along local x.
        alpha_x: f32,
        /// GGX roughness along local y.
        alpha_y: f32,
    },
    /// Glass-like interface with relative index `eta` (inside / outside);
    /// specular when smooth or when `eta == 1` (then pure pass-through).
    Dielectric {
        /// Relative index of refraction `η_inside / η_outside`.
        eta: f32,
        /// GGX roughness along local x.
        alpha_x: f32,
        /// GGX roughness along local y.
        alpha_y: f32,
    },
    /// Lambertian reflection on `wo`'s side and Lambertian transmission to
    /// the other, lobes chosen by their largest channel (pbrt-v4's
    /// `DiffuseTransmissionBxDF`).
    DiffuseTransmission {
        /// Reflectance per channel.
        reflectance: Rgb,
        /// Transmittance per channel.
        transmittance: Rgb,
    },
    /// A thin slab of index `eta`: specular reflection including the slab's
    /// inner bounces, straight transmission (pbrt-v4's `ThinDielectricBxDF`).
    ThinDielectric {
        /// Index of refraction of the slab.
        eta: f32,
    },
    /// A dielectric coating over a Lambertian or conductor base with a
    /// medium between (pbrt-v4's `CoatedDiffuseBxDF`, `CoatedConductorBxDF`);
    /// `eval`, `pdf` and `sample` are random-walk estimates ([`Coated`]).
    Coated(Coated),
    /// The Disney-principled BSDF: diffuse with retro-reflection and sheen,
    /// GGX specular, clearcoat and rough glass, lobes picked by weight
    /// ([`Principled`]).
    Principled(Principled),
    /// A hair fibre (pbrt-v4's `HairBxDF`, [`Hair`]), in a frame whose x is
    /// the fibre's axis ([`Frame::from_xz`]). It scatters to both sides.
    Hair(Hair),
    /// A tabulated BRDF (pbrt-v4's `MeasuredBxDF`, [`measured`]).
    Measured(&'a MeasuredBrdf),
}

/// The result of [`Bsdf::sample`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// BSDF value for `(wo, wi)`, cosine excluded. For delta lobes this is the
    /// delta's weight divided by `|cos θ_i|`, so `f |wi.z| / pdf` is the
    /// throughput either way.
    pub f: Rgb,
    /// Sampled incident direction (unit, local frame, pointing away).
    pub wi: Vec3,
    /// Solid-angle density of `wi`, or the discrete probability of the chosen
    /// lobe when `delta` is set.
    pub pdf: f32,
    /// Relative index of refraction crossed (pbrt's `BSDFSample::eta`): `etap`
    /// for transmission, 1 for reflection. Path integrators track the product
    /// of its squares for Russian roulette (pbrt's `etaScale`).
    pub eta: f32,
    /// Specular lobe: `pdf` is a probability and `eval`/`pdf` would return 0.
    pub delta: bool,
    /// `wi` is on the other side of the surface from `wo`.
    pub transmission: bool,
}

impl<'a> Bsdf<'a> {
    /// The BSDF for a scene material whose measured BRDFs are `measured`
    /// (the scene's); `None` for [`Material::Interface`], which has no
    /// surface, and for [`Material::Mix`], resolved per hit.
    pub fn from_material(m: &Material, measured: &'a [std::sync::Arc<MeasuredBrdf>]) -> Option<Bsdf<'a>> {
        match *m {
            Material::Diffuse { reflectance } => Some(Bsdf::Diffuse { reflectance }),
            Material::Conductor { eta, k, alpha_x, alpha_y } => {
                Some(Bsdf::Conductor { eta, k, alpha_x, alpha_y })
            }
            Material::Dielectric { eta, alpha_x, alpha_y } => {
                Some(Bsdf::Dielectric { eta, alpha_x, alpha_y })
            }
            Material::Interface => None,
            Material::DiffuseTransmission { reflectance, transmittance } => {
                Some(Bsdf::DiffuseTransmission { reflectance, transmittance })
            }
            Material::ThinDielectric { eta } => Some(Bsdf::ThinDielectric { eta }),
            Material::CoatedDiffuse(params) => Some(Bsdf::Coated(Coated::diffuse(params))),
            Material::CoatedConductor(params) => Some(Bsdf::Coated(Coated::conductor(params))),
            // A mix is one of its materials per hit (`FrameContext::material_at`).
            Material::Mix { .. } => None,
            Material::Principled(params) => Some(Bsdf::Principled(Principled(params))),
            Material::Hair(params) => Some(Bsdf::Hair(Hair::new(&params))),
            Material::Measured { brdf } => Some(Bsdf::Measured(&measured[brdf as usize])),
            // The boundary where paths enter.
            Material::Subsurface(p) => {
                Some(Bsdf::Dielectric { eta: p.eta, alpha_x: p.alpha_x, alpha_y: p.alpha_y })
            }
        }
    }

    /// BSDF value `f(wo, wi)` without the cosine; 0 for delta lobes.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        match *self {
            Bsdf::Diffuse { reflectance } => {
                if same_hemisphere(wo, wi) {
                    reflectance * FRAC_1_PI
                } else {
                    Rgb::ZERO
                }
            }
            Bsdf::Conductor { eta, k, alpha_x, alpha_y } => {
                conductor::eval(eta, k, TrowbridgeReitz::new(alpha_x, alpha_y), wo, wi)
            }
            Bsdf::Dielectric { eta, alpha_x, alpha_y } => {
                dielectric::eval(eta, TrowbridgeReitz::new(alpha_x, alpha_y), wo, wi)
            }
            Bsdf::DiffuseTransmission { reflectance, transmittance } => {
                if same_hemisphere(wo, wi) {
                    reflectance * FRAC_1_PI
                } else {
                    transmittance * FRAC_1_PI
                }
            }
            Bsdf::ThinDielectric { .. } => Rgb::ZERO,
            Bsdf::Coated(c) => c.eval(wo, wi),
            Bsdf::Principled(p) => p.eval(wo, wi),
            Bsdf::Hair(h) => h.eval(wo, wi),
            Bsdf::Measured(m) => measured::eval(m, wo, wi),
        }
    }

    /// Solid-angle density with which [`Self::sample`] returns `wi` given `wo`;
    /// 0 for delta lobes.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match *self {
            Bsdf::Diffuse { .. } => {
                if same_hemisphere(wo, wi) {
                    cosine_hemisphere_pdf(wi.z.abs())
                } else {
                    0.0
                }
            }
            Bsdf::Conductor { alpha_x, alpha_y, .. } => {
                conductor::pdf(TrowbridgeReitz::new(alpha_x, alpha_y), wo, wi)
            }
            Bsdf::Dielectric { eta, alpha_x, alpha_y } => {
                dielectric::pdf(eta, TrowbridgeReitz::new(alpha_x, alpha_y), wo, wi)
            }
            Bsdf::DiffuseTransmission { reflectance, transmittance } => {
                let (pr, pt) = thin::lobe_weights(reflectance, transmittance);
                if pr + pt == 0.0 {
                    return 0.0;
                }
                let lobe = if same_hemisphere(wo, wi) { pr } else { pt };
                lobe / (pr + pt) * cosine_hemisphere_pdf(wi.z.abs())
            }
            Bsdf::ThinDielectric { .. } => 0.0,
            Bsdf::Coated(c) => c.pdf(wo, wi),
            Bsdf::Principled(p) => p.pdf(wo, wi),
            Bsdf::Hair(h) => h.pdf(wo, wi),
            Bsdf::Measured(m) => measured::pdf(m, wo, wi),
        }
    }

    /// Importance-sample an incident direction. `uc` picks the lobe
    /// (reflection vs transmission), `u` the direction within it. `None` when
    /// no valid direction was produced (grazing `wo`, a sampled microfacet
    /// that sends the ray to the wrong side, zero density).
    pub fn sample(&self, wo: Vec3, uc: f32, u: Vec2) -> Option<BsdfSample> {
        // Grazing wo: no side to scatter on (and eval would return 0).
        if wo.z == 0.0 {
            return None;
        }
        let s = match *self {
            Bsdf::Diffuse { reflectance } => {
                // Cosine-weighted on wo's side (pbrt flips z for wo below).
                let mut wi = sample_cosine_hemisphere(u);
                if wo.z < 0.0 {
                    wi.z = -wi.z;
                }
                let pdf = cosine_hemisphere_pdf(wi.z.abs());
                let f = reflectance * FRAC_1_PI;
                BsdfSample { f, wi, pdf, eta: 1.0, delta: false, transmission: false }
            }
            Bsdf::Conductor { eta, k, alpha_x, alpha_y } => {
                conductor::sample(eta, k, TrowbridgeReitz::new(alpha_x, alpha_y), wo, u)?
            }
            Bsdf::Dielectric { eta, alpha_x, alpha_y } => {
                dielectric::sample(eta, TrowbridgeReitz::new(alpha_x, alpha_y), wo, uc, u)?
            }
            Bsdf::DiffuseTransmission { reflectance, transmittance } => {
                thin::sample_diffuse_transmission(reflectance, transmittance, wo, uc, u)?
            }
            Bsdf::ThinDielectric { eta } => thin::sample_thin_dielectric(eta, wo, uc)?,
            Bsdf::Coated(c) => c.sample(wo, uc, u)?,
            Bsdf::Principled(p) => p.sample(wo, uc, u)?,
            Bsdf::Hair(h) => h.sample(wo, uc, u)?,
            Bsdf::Measured(m) => measured::sample(m, wo, u)?,
        };
        // As pbrt's `BSDF::Sample_f`: drop samples the integrator can't use.
        if s.pdf > 0.0 && s.wi.z != 0.0 && s.f.is_finite() {
            Some(s)
        } else {
            None
        }
    }

    /// True when every lobe is specular (smooth conductor or dielectric,
    /// index-matched dielectric): light sampling is pointless then.
    pub fn is_delta(&self) -> bool {
        match *self {
            Bsdf::Diffuse { .. } => false,
            Bsdf::Conductor { alpha_x, alpha_y, .. } => {
                TrowbridgeReitz::new(alpha_x, alpha_y).effectively_smooth()
            }
            Bsdf::Dielectric { eta, alpha_x, alpha_y } => {
                dielectric::is_specular(eta, TrowbridgeReitz::new(alpha_x, alpha_y))
            }
            Bsdf::DiffuseTransmission { .. } => false,
            Bsdf::ThinDielectric { .. } => true,
            Bsdf::Coated(c) => c.is_delta(),
            Bsdf::Principled(p) => p.is_delta(),
            Bsdf::Hair(_) | Bsdf::Measured(_) => false,
        }
    }

    /// True when a sample's `pdf` is only proportional to the density of
    /// its direction (pbrt's `BSDFSample::pdfIsProportional`): its
    /// `f |cos| / pdf` is still the right path weight, but MIS at the next
    /// vertex must use [`Self::pdf`] instead. So far only the layered BSDF,
    /// whose samples come from random walks whose density is not that of
    /// the direction they leave in.
    pub fn sampled_pdf_is_proportional(&self) -> bool {
        matches!(self, Bsdf::Coated(_))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::sample_uniform_sphere;

    fn assert_orthonormal(f: &Frame) {
        for (a, b) in [(f.x, f.y), (f.y, f.z), (f.z, f.x)] {
            assert!(a.dot(b).abs() < 1e-5, "{f:?}");
        }
        for v in [f.x, f.y, f.z] {
            assert!((v.length() - 1.0).abs() < 1e-5, "{f:?}");
        }
        // Right-handed: x × y = z.
        assert!((f.x.cross(f.y) - f.z).length() < 1e-5, "{f:?}");
    }

    #[test]
    fn frame_is_orthonormal_for_any_normal() {
        let mut normals = vec![Vec3::Z, -Vec3::Z, Vec3::X, -Vec3::Y, Vec3::new(0.0, 1e-7, -1.0).normalize()];
        let mut state = 0x1234_5678u32;
        for _ in 0..2000 {
            // A small xorshift RNG keeps the test free of dependencies.
            let mut next = || {
                state ^= state << 13;
                state ^= state >> 17;
                state ^= state << 5;
                state as f32 / 4_294_967_296.0
            };
            normals.push(sample_uniform_sphere(Vec2::new(next(), next())));
        }
        for n in normals {
            let f = Frame::from_z(n);
            assert_orthonormal(&f);
            let v = Vec3::new(0.3, -0.5, 0.8);
            assert!((f.from_local(f.to_local(v)) - v).length() < 1e-5);
            assert!((f.to_local(n) - Vec3::Z).length() < 1e-5);
        }
        let down = Frame::from_z(-Vec3::Z);
        assert_eq!(down.z, -Vec3::Z);
        assert!(down.x.is_finite() && down.y.is_finite());
    }

    #[test]
    fn from_material_maps_every_variant() {
        let d = Material::Diffuse { reflectance: Rgb::splat(0.25) };
        assert_eq!(Bsdf::from_material(&d, &[]), Some(Bsdf::Diffuse { reflectance: Rgb::splat(0.25) }));
        let c = Material::Conductor { eta: Rgb::ONE, k: Rgb::splat(3.0), alpha_x: 0.1, alpha_y: 0.2 };
        assert_eq!(
            Bsdf::from_material(&c, &[]),
            Some(Bsdf::Conductor { eta: Rgb::ONE, k: Rgb::splat(3.0), alpha_x: 0.1, alpha_y: 0.2 })
        );
        let g = Material::Dielectric { eta: 1.5, alpha_x: 0.0, alpha_y: 0.0 };
        assert_eq!(
            Bsdf::from_material(&g, &[]),
            Some(Bsdf::Dielectric { eta: 1.5, alpha_x: 0.0, alpha_y: 0.0 })
        );
        assert_eq!(Bsdf::from_material(&Material::Interface, &[]), None);
    }

    #[test]
    fn delta_classification() {
        let smooth_metal = Bsdf::Conductor { eta: Rgb::ONE, k: Rgb::ONE, alpha_x: 0.0, alpha_y: 5e-4 };
        let rough_metal = Bsdf::Conductor { eta: Rgb::ONE, k: Rgb::ONE, alpha_x: 0.0, alpha_y: 0.1 };
        assert!(smooth_metal.is_delta());
        assert!(!rough_metal.is_delta());
        assert!(Bsdf::Dielectric { eta: 1.5, alpha_x: 0.0, alpha_y: 0.0 }.is_delta());
        assert!(Bsdf::Dielectric { eta: 1.0, alpha_x: 0.5, alpha_y: 0.5 }.is_delta());
        assert!(!Bsdf::Dielectric { eta: 1.5, alpha_x: 0.3, alpha_y: 0.3 }.is_delta());
        assert!(!Bsdf::Diffuse { reflectance: Rgb::ONE }.is_delta());
        // Delta lobes are invisible to eval/pdf.
        let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
        let wi = Vec3::new(-wo.x, -wo.y, wo.z);
        assert_eq!(smooth_metal.eval(wo, wi), Rgb::ZERO);
        assert_eq!(smooth_metal.pdf(wo, wi), 0.0);
    }

    #[test]
    fn index_matched_dielectric_passes_straight_through() {
        let b = Bsdf::Dielectric { eta: 1.0, alpha_x: 0.3, alpha_y: 0.3 };
        for wo in [Vec3::new(0.3, 0.1, 0.9).normalize(), Vec3::new(0.5, -0.2, -0.4).normalize()] {
            for uc in [0.0, 0.5, 0.999] {
                let s = b.sample(wo, uc, Vec2::new(0.3, 0.7)).unwrap();
                assert!(s.delta && s.transmission && s.pdf == 1.0);
                assert!((s.wi + wo).length() < 1e-6);
                assert!((s.f.x * s.wi.z.abs() - 1.0).abs() < 1e-6);
            }
        }
    }
}
