//! Which of a hit's f16 material coefficients ([`RayRecord::coeffs`], and
//! the GPU material table's copy of them) holds which parameter, per
//! [`MaterialKind`]: one module of slot constants per kind.
//!
//! This is the only place the slots are written down. Packing and
//! unpacking ([`crate::material_coeffs`]) and texture stores
//! ([`crate::texture`]) use these names, and atoll-cuda's header generator
//! writes [`LAYOUTS`] into `kernels/materials.cuh` as
//! `COEFF_<KIND>_<PARAMETER>` for the kernels, so the CPU and the GPU cannot
//! disagree about where a parameter lives.
//!
//! [`RayRecord::coeffs`]: crate::RayRecord::coeffs

use std::ops::Range;

use crate::record::MaterialKind;

/// One material kind's coefficient layout.
#[derive(Debug)]
pub struct Layout {
    pub kind: MaterialKind,
    /// The name of the kind's module here (`conductor`), which the CUDA
    /// names repeat in capitals.
    pub name: &'static str,
    /// Each parameter's constant name and the slots it fills (three for a
    /// colour), in slot order.
    pub params: &'static [(&'static str, Range<usize>)],
}

/// Declares, for each kind, a module of `usize` slot constants (a
/// parameter's first slot) and its [`LAYOUTS`] entry, from one list, so the
/// table the CUDA names come from cannot miss a constant.
macro_rules! layouts {
    (@slots $start:literal) => { $start..$start + 1 };
    (@slots $start:literal $end:literal) => { $start..$end };
    ($(
        $(#[$kind_doc:meta])*
        $kind:ident => $module:ident {
            $($(#[$doc:meta])* $param:ident: $start:literal $(.. $end:literal)?,)*
        }
    )*) => {
        $(
            $(#[$kind_doc])*
            pub mod $module {
                $($(#[$doc])* pub const $param: usize = $start;)*
            }
        )*

        /// Every kind that has coefficients, for the generated CUDA names
        /// and the layout checks.
        pub const LAYOUTS: &[Layout] = &[$(
            Layout {
                kind: MaterialKind::$kind,
                name: stringify!($module),
                params: &[$((stringify!($param), layouts!(@slots $start $($end)?)),)*],
            },
        )*];
    };
}

layouts! {
    /// [`MaterialKind::Diffuse`].
    Diffuse => diffuse {
        REFLECTANCE: 0..3,
    }
    /// [`MaterialKind::Conductor`].
    Conductor => conductor {
        ETA: 0..3,
        K: 3..6,
        ALPHA_X: 6,
        ALPHA_Y: 7,
        /// The surface's `dpdu` at the hit: not a material parameter,
        /// written with the hit where the roughness is anisotropic
        /// ([`crate::material_coeffs::store_tangent`]), since the
        /// roughness's x axis follows it.
        TANGENT: 8..11,
    }
    /// [`MaterialKind::Dielectric`].
    Dielectric => dielectric {
        ETA: 0,
        ALPHA_X: 1,
        ALPHA_Y: 2,
        /// The surface's `dpdu` at the hit: not a material parameter,
        /// written with the hit where the roughness is anisotropic
        /// ([`crate::material_coeffs::store_tangent`]), since the
        /// roughness's x axis follows it.
        TANGENT: 3..6,
    }
    /// [`MaterialKind::DiffuseTransmission`].
    DiffuseTransmission => diffuse_transmission {
        REFLECTANCE: 0..3,
        TRANSMITTANCE: 3..6,
    }
    /// [`MaterialKind::ThinDielectric`].
    ThinDielectric => thin_dielectric {
        ETA: 0,
    }
    /// [`MaterialKind::Mix`], in GPU
    /// material tables only (a record never holds a mix).
    Mix => mix {
        /// Start and length (two u32, four coefficients) of the texture
        /// program of a textured `amount`.
        AMOUNT_PROGRAM: 0..4,
    }
    /// [`MaterialKind::CoatedDiffuse`].
    /// Reflectance and roughness come first, where per-hit textures
    /// overwrite them.
    CoatedDiffuse => coated_diffuse {
        REFLECTANCE: 0..3,
        ALPHA_X: 3,
        ALPHA_Y: 4,
        ETA: 5,
        THICKNESS: 6,
        ALBEDO: 7..10,
        G: 10,
        /// A count as an f16 integer, exact up to 2048
        /// (`Material::COATED_MAX_COUNT`).
        MAX_DEPTH: 11,
        /// As [`MAX_DEPTH`].
        N_SAMPLES: 12,
        /// As [`conductor::TANGENT`], for the coating's roughness.
        ///
        /// [`conductor::TANGENT`]: super::conductor::TANGENT
        TANGENT: 13..16,
    }
    /// [`MaterialKind::CoatedConductor`]: every coefficient is used, so
    /// its walk is fixed (`Material::COATED_CONDUCTOR_WALK`).
    /// The conductor's index comes first and `K` lies as far from `ETA` as
    /// in [`conductor`]: a textured `reflectance` stores both the same way.
    CoatedConductor => coated_conductor {
        /// Relative to the outside, as the scene gives it.
        ETA: 0..3,
        K: 3..6,
        CONDUCTOR_ALPHA_X: 6,
        CONDUCTOR_ALPHA_Y: 7,
        INTERFACE_ALPHA_X: 8,
        INTERFACE_ALPHA_Y: 9,
        INTERFACE_ETA: 10,
        THICKNESS: 11,
        ALBEDO: 12..15,
        G: 15,
    }
    /// [`MaterialKind::Principled`].
    /// Base colour, metallic and roughness come first: per-hit textures
    /// overwrite them in place.
    Principled => principled {
        BASE_COLOR: 0..3,
        METALLIC: 3,
        /// Perceptual roughness, not alpha.
        ROUGHNESS: 4,
        SPECULAR: 5,
        SPECULAR_TINT: 6,
        SHEEN: 7,
        SHEEN_TINT: 8,
        CLEARCOAT: 9,
        CLEARCOAT_GLOSS: 10,
        TRANSMISSION: 11,
        ETA: 12,
    }
    /// [`MaterialKind::Hair`].
    Hair => hair {
        SIGMA_A: 0..3,
        ETA: 3,
        BETA_M: 4,
        BETA_N: 5,
        /// Degrees.
        ALPHA: 6,
        /// The fibre's axis at the hit (the surface's `dpdu`, unit length):
        /// not a material parameter, written with every hit, since the
        /// hair BSDF's frame turns about it.
        TANGENT: 7..10,
        /// The offset `h` across the fibre (pbrt's `-1 + 2v`), written
        /// with the hit; a packed material holds
        /// `hair::OFFSET_FROM_NORMAL` until then.
        OFFSET: 10,
    }
    /// [`MaterialKind::Measured`].
    Measured => measured {
        /// The BRDF's index in the scene's measured BRDFs (an f16 integer).
        BRDF: 0,
        /// As [`conductor::TANGENT`], written with every hit: an
        /// anisotropic table's azimuth is measured from it.
        ///
        /// [`conductor::TANGENT`]: super::conductor::TANGENT
        TANGENT: 1..4,
    }
    /// [`MaterialKind::Subsurface`]: its boundary where paths enter,
    /// as [`dielectric`]'s.
    Subsurface => subsurface {
        ETA: 0,
        ALPHA_X: 1,
        ALPHA_Y: 2,
        /// As [`dielectric::TANGENT`].
        ///
        /// [`dielectric::TANGENT`]: super::dielectric::TANGENT
        TANGENT: 3..6,
        /// Where paths leave: the share of diffuse light from inside the
        /// boundary lets out, which normalises the exit lobe
        /// ([`crate::bsdf::fresnel::diffuse_transmittance`]).
        EXIT_NORMALISATION: 6,
    }
}

/// The first of the three slots where a kind's hit carries the surface's
/// `dpdu` (every kind's `TANGENT`), which the BSDF's frame takes its x
/// axis from; `None` for kinds whose BSDF does not turn about the normal
/// or that have no room for it (the coated conductor, whose anisotropic
/// roughness turns with the frame about the normal alone).
pub const fn tangent_slot(kind: MaterialKind) -> Option<usize> {
    match kind {
        MaterialKind::Conductor => Some(conductor::TANGENT),
        MaterialKind::Dielectric => Some(dielectric::TANGENT),
        MaterialKind::CoatedDiffuse => Some(coated_diffuse::TANGENT),
        MaterialKind::Hair => Some(hair::TANGENT),
        MaterialKind::Measured => Some(measured::TANGENT),
        MaterialKind::Subsurface => Some(subsurface::TANGENT),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::MATERIAL_COEFFS;

    /// Each kind's parameters fit the coefficients without overlapping, and
    /// every kind but `None` has a layout.
    #[test]
    fn layouts_fit_and_do_not_overlap() {
        for layout in LAYOUTS {
            let mut end = 0;
            for (param, slots) in layout.params {
                assert!(slots.start >= end, "{}::{param} overlaps the parameter before it", layout.name);
                assert!(slots.start < slots.end, "{}::{param} is empty", layout.name);
                end = slots.end;
            }
            assert!(end <= MATERIAL_COEFFS, "{} needs {end} coefficients", layout.name);
        }
        let kinds = (1..).map(MaterialKind::from_u16).take_while(|&k| k != MaterialKind::None);
        for kind in kinds {
            assert_eq!(LAYOUTS.iter().filter(|l| l.kind == kind).count(), 1, "{kind:?}");
        }
    }

    /// [`tangent_slot`] names exactly the kinds whose layout has a
    /// `TANGENT`, at its slots.
    #[test]
    fn tangent_slots_are_the_layouts_tangents() {
        for layout in LAYOUTS {
            let tangent = layout.params.iter().find(|(name, _)| *name == "TANGENT");
            assert_eq!(tangent_slot(layout.kind), tangent.map(|(_, slots)| slots.start), "{}", layout.name);
            if let Some((_, slots)) = tangent {
                assert_eq!(slots.len(), 3, "{}", layout.name);
            }
        }
    }

    /// A textured conductor `reflectance` writes eta at the slot it is given
    /// and k at the conductor's distance from it, for both conductor kinds.
    #[test]
    fn conductor_indices_lie_alike() {
        assert_eq!(coated_conductor::K - coated_conductor::ETA, conductor::K - conductor::ETA);
    }
}
