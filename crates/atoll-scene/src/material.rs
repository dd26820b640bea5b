//! Materials as described by the scene (pbrt-v4 names and parameters).
//! The renderer turns them into BSDFs at hit points.

use crate::Rgb;

/// Index of a material in [`crate::Scene::materials`].
pub type MaterialId = u32;

/// A surface material. Roughness values are stored as GGX (Trowbridge–Reitz)
/// `alpha`, already remapped where the scene asked for `remaproughness`.
#[derive(Clone, Debug, PartialEq)]
pub enum Material {
    /// Lambertian reflection.
    Diffuse { reflectance: Rgb },
    /// Metal with complex index of refraction `eta + i k`; smooth when both
    /// alphas are (near) zero, GGX microfacet otherwise.
    Conductor { eta: Rgb, k: Rgb, alpha_x: f32, alpha_y: f32 },
    /// Glass-like interface with relative index `eta`; smooth when both alphas
    /// are (near) zero.
    Dielectric { eta: f32, alpha_x: f32, alpha_y: f32 },
    /// No surface at all (pbrt's `interface`/`""`): rays pass straight through.
    Interface,
    /// pbrt-v4's `diffusetransmission`: Lambertian reflection on the side
    /// light comes from, Lambertian transmission to the other (leaves, paper).
    DiffuseTransmission { reflectance: Rgb, transmittance: Rgb },
    /// pbrt-v4's `thindielectric`: a thin slab of index `eta` (window glass,
    /// bubbles): specular reflection with the slab's internal bounces summed,
    /// and straight-through transmission without bending.
    ThinDielectric { eta: f32 },
    /// pbrt's `mix`: at each hit, `materials[1]` with probability `amount`,
    /// else `materials[0]` (the choice is a random number of the path
    /// vertex, so every device picks alike).
    Mix { materials: [MaterialId; 2], amount: f32 },
}

impl Material {
    /// The material pbrt uses when none was given: diffuse 0.5 grey.
    pub fn default_diffuse() -> Self {
        Material::Diffuse { reflectance: Rgb::splat(0.5) }
    }

    /// pbrt-v4's `TrowbridgeReitzDistribution::RoughnessToAlpha`.
    pub fn roughness_to_alpha(roughness: f32) -> f32 {
        roughness.max(0.0).sqrt()
    }

    /// pbrt-v4 turns a conductor's `reflectance` into `eta = 1` and this `k`,
    /// which makes the normal-incidence Fresnel reflectance equal `r`.
    pub fn conductor_k_from_reflectance(r: Rgb) -> Rgb {
        let r = r.clamp(Rgb::ZERO, Rgb::splat(0.9999));
        Rgb::new(
            2.0 * r.x.sqrt() / (1.0 - r.x).sqrt(),
            2.0 * r.y.sqrt() / (1.0 - r.y).sqrt(),
            2.0 * r.z.sqrt() / (1.0 - r.z).sqrt(),
        )
    }
}
