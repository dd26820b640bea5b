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
    /// pbrt-v4's `coateddiffuse`: a dielectric coating (index `eta`, GGX
    /// roughness) over a Lambertian base of `reflectance`, with a medium of
    /// `thickness` between them that absorbs (albedo 0) or scatters with
    /// single-scattering `albedo` and Henyey–Greenstein asymmetry `g`. Light
    /// between the layers is followed by a random walk of at most
    /// `max_depth` events, `n_samples` walks per evaluation.
    CoatedDiffuse(CoatedDiffuseParams),
    /// pbrt-v4's `coatedconductor`: the same coating and medium over a
    /// conductor (smooth or GGX-rough) instead of a Lambertian base.
    CoatedConductor(CoatedConductorParams),
    /// A Disney-principled surface (Burley 2012/2015, as pbrt-v3's `disney`
    /// material; glTF's metallic-roughness maps onto it): Burley diffuse
    /// with retro-reflection and sheen, a GGX specular lobe whose
    /// normal-incidence reflectance goes from `0.08 specular` (tinted
    /// towards the base colour's hue by `specular_tint`) to `base_color` as
    /// `metallic` goes to 1, a GTR1 clearcoat, and rough dielectric
    /// transmission of index `eta` weighted by `transmission`. `roughness`
    /// is perceptual (GGX alpha = roughness²); every weight is in [0, 1].
    /// No subsurface scattering, no thin-surface mode.
    Principled(PrincipledParams),
    /// pbrt-v4's `hair`: a dielectric fibre with an absorbing interior and
    /// tilted cuticle scales (`HairBxDF`, Chiang et al. 2016). Its axis is
    /// the surface's `dpdu` at the hit, as for pbrt's curves.
    Hair(HairParams),
    /// pbrt-v4's `measured`: a tabulated BRDF read from a `.bsdf` file,
    /// `Scene::measured[brdf]`.
    Measured { brdf: MeasuredId },
    /// pbrt-v4's `subsurface`: a dielectric boundary around a scattering
    /// interior. The scene gives the interior its own medium
    /// ([`crate::Medium::Subsurface`], [`crate::Scene::attach_subsurface_interiors`]).
    Subsurface(SubsurfaceParams),
}

/// A [`Material::Subsurface`]: its boundary, and the homogeneous medium
/// inside it (coefficients per unit of world distance, pbrt's `scale`
/// applied; no emission).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SubsurfaceParams {
    /// Relative index of refraction of the boundary (inside / outside).
    pub eta: f32,
    /// GGX roughness of the boundary along local x.
    pub alpha_x: f32,
    /// GGX roughness of the boundary along local y.
    pub alpha_y: f32,
    pub interior: crate::HomogeneousMedium,
}

/// Index of a measured BRDF in [`crate::Scene::measured`].
pub type MeasuredId = u32;

/// The dielectric coating of a layered surface ([`Material::CoatedDiffuse`],
/// [`Material::CoatedConductor`]) and the medium under it, shared with the
/// renderer's layered BSDF.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coating {
    /// Relative index of refraction of the coating (inside / outside).
    pub eta: f32,
    /// GGX roughness of the coating along local x.
    pub alpha_x: f32,
    /// GGX roughness of the coating along local y.
    pub alpha_y: f32,
    /// Optical depth of the medium between coating and base.
    pub thickness: f32,
    /// Single-scattering albedo of the medium; zero for a purely absorbing one.
    pub albedo: Rgb,
    /// Henyey–Greenstein asymmetry of the medium's phase function.
    pub g: f32,
    /// Most scattering events of one random walk.
    pub max_depth: u32,
    /// Random walks averaged per estimate.
    pub n_samples: u32,
}

impl Coating {
    /// pbrt-v4's defaults for both coated materials: a smooth coating of
    /// index 1.5 over an absorbing medium of thickness 0.01, walks of at most
    /// 10 events, one walk per estimate.
    pub const PBRT_DEFAULT: Coating = Coating {
        eta: 1.5,
        alpha_x: 0.0,
        alpha_y: 0.0,
        thickness: 0.01,
        albedo: Rgb::ZERO,
        g: 0.0,
        max_depth: 10,
        n_samples: 1,
    };
}

/// The parameters of a [`Material::CoatedDiffuse`] surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoatedDiffuseParams {
    /// Lambertian reflectance of the base.
    pub reflectance: Rgb,
    pub coating: Coating,
}

/// The parameters of a [`Material::CoatedConductor`] surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoatedConductorParams {
    /// The conductor's complex index of refraction `eta + i k` relative to
    /// the outside (pbrt's `conductor.eta`, `conductor.k`); the layered BSDF
    /// divides it by the coating's index, as pbrt-v4 does.
    pub eta: Rgb,
    pub k: Rgb,
    /// The conductor's GGX roughness.
    pub alpha_x: f32,
    pub alpha_y: f32,
    pub coating: Coating,
}

/// The parameters of a [`Material::Principled`] surface, shared with the
/// renderer's principled BSDF (one field list for the scene, the BSDF, the
/// GPU packing and the writer).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrincipledParams {
    pub base_color: Rgb,
    pub metallic: f32,
    /// Perceptual roughness: GGX alpha is its square.
    pub roughness: f32,
    pub specular: f32,
    pub specular_tint: f32,
    pub sheen: f32,
    pub sheen_tint: f32,
    pub clearcoat: f32,
    pub clearcoat_gloss: f32,
    pub transmission: f32,
    /// Relative index of refraction of the glass part (inside / outside).
    pub eta: f32,
}

/// The parameters of a [`Material::Hair`] fibre, shared with the
/// renderer's hair BSDF.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HairParams {
    /// Absorption coefficient of the fibre's interior, per unit of its
    /// diameter (pbrt's `sigma_a`, or the one its `reflectance` or melanin
    /// concentrations give).
    pub sigma_a: Rgb,
    /// Index of refraction of the fibre.
    pub eta: f32,
    /// Longitudinal roughness, in [0.01, 1] (pbrt clamps it so).
    pub beta_m: f32,
    /// Azimuthal roughness, in [0.01, 1].
    pub beta_n: f32,
    /// Tilt of the cuticle's scales, in degrees.
    pub alpha: f32,
}

impl HairParams {
    /// pbrt-v4's defaults: brown hair (eumelanin 1.3), index 1.55, both
    /// roughnesses 0.3, scales tilted by 2°.
    pub fn pbrt_default() -> HairParams {
        HairParams {
            sigma_a: HairParams::sigma_a_from_concentration(1.3, 0.0),
            eta: 1.55,
            beta_m: 0.3,
            beta_n: 0.3,
            alpha: 2.0,
        }
    }

    /// The absorption of a fibre holding these concentrations of eumelanin
    /// (brown-black) and pheomelanin (red-yellow): pbrt-v4's
    /// `SigmaAFromConcentration`, with its RGB absorption per unit
    /// concentration of each pigment (d'Eon et al. 2011).
    pub fn sigma_a_from_concentration(eumelanin: f32, pheomelanin: f32) -> Rgb {
        Self::EUMELANIN_SIGMA_A * eumelanin.max(0.0) + Self::PHEOMELANIN_SIGMA_A * pheomelanin.max(0.0)
    }

    /// The absorption of a unit concentration of eumelanin (pbrt-v4's).
    pub const EUMELANIN_SIGMA_A: Rgb = Rgb::new(0.419, 0.697, 1.37);
    /// The absorption of a unit concentration of pheomelanin (pbrt-v4's).
    pub const PHEOMELANIN_SIGMA_A: Rgb = Rgb::new(0.187, 0.4, 1.05);

    /// The absorption that gives hair of azimuthal roughness `beta_n` about
    /// the colour `c` after multiple scattering: pbrt-v4's
    /// `SigmaAFromReflectance` (Chiang et al. 2016's fit), per channel.
    pub fn sigma_a_from_reflectance(c: Rgb, beta_n: f32) -> Rgb {
        let b = beta_n;
        let fit =
            5.969 - 0.215 * b + 2.532 * b * b - 10.73 * b.powi(3) + 5.574 * b.powi(4) + 0.245 * b.powi(5);
        // A black channel absorbs as a reflectance of 1e-6 does: T is about 1e-5
        // per crossing, where log(0) would make an infinity that f16 keeps.
        let channel = |c: f32| (c.clamp(1e-6, 1.0).ln() / fit).powi(2);
        Rgb::new(channel(c.x), channel(c.y), channel(c.z))
    }
}

impl Material {
    /// Largest `max_depth` and `n_samples` of a [`Material::CoatedDiffuse`]:
    /// hits carry them as f16 integers, exact up to 2048.
    pub const COATED_MAX_COUNT: u32 = 2048;

    /// The walk of every [`Material::CoatedConductor`] (`max_depth`,
    /// `n_samples`): pbrt-v4's defaults. Its hits fill all sixteen of a
    /// record's coefficients with the conductor, the coating and the
    /// medium, leaving no room for the counts; the loader warns when a
    /// scene asks for others.
    pub const COATED_CONDUCTOR_WALK: (u32, u32) = (10, 1);

    /// The material pbrt uses when none was given: diffuse 0.5 grey.
    pub fn default_diffuse() -> Self {
        Material::Diffuse { reflectance: Rgb::splat(0.5) }
    }

    /// pbrt-v4's `TrowbridgeReitzDistribution::RoughnessToAlpha`.
    pub fn roughness_to_alpha(roughness: f32) -> f32 {
        roughness.max(0.0).sqrt()
    }

    /// The principled `specular` whose dielectric reflectance at normal
    /// incidence (`0.08 specular`) is that of an interface of index `eta`,
    /// `((eta - 1) / (eta + 1))²`: 0.5 for `eta` 1.5. pbrt-v3's `disney` and
    /// glTF derive the specular reflection from the index this way.
    pub fn specular_from_eta(eta: f32) -> f32 {
        let r0 = ((eta - 1.0) / (eta + 1.0)).powi(2);
        r0 / 0.08
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
