//! Participating media: what fills the space between surfaces (fog, smoke,
//! the inside of a glass of milk), as pbrt-v4's `MakeNamedMedium` defines
//! it, and which medium lies on each side of a surface (`MediumInterface`).

use crate::Rgb;

/// A medium of the scene, addressed by [`MediumIndex`].
#[derive(Clone, Debug, PartialEq)]
pub enum Medium {
    /// pbrt-v4's `homogeneous`: the same coefficients everywhere.
    Homogeneous(HomogeneousMedium),
    /// pbrt-v4's `uniformgrid` and `rgbgrid`: coefficients interpolated
    /// from voxel samples.
    Grid(GridMedium),
    /// The interior of a [`crate::Material::Subsurface`] surface: light
    /// enters it only through that surface, so light sampling from inside
    /// is always blocked and the renderer walks it without.
    Subsurface(HomogeneousMedium),
}

/// A medium whose coefficients come from samples on a voxel grid,
/// interpolated trilinearly (pbrt-v4's `SampledGrid`): sample `(x, y, z)`
/// sits at the centre of its voxel of the box `lo`..`hi` in the medium's
/// space, missing neighbours count as 0, and outside the box there is no
/// medium. A `uniformgrid` has one channel, the density scaling σa and σs
/// (and a second for `Lescale` where that is a grid); an `rgbgrid` has an
/// RGB triple per sample for each of σa, σs and Le it gives.
#[derive(Clone, Debug, PartialEq)]
pub struct GridMedium {
    /// Samples per axis.
    pub resolution: [u32; 3],
    /// Values per sample.
    pub channels: u32,
    /// Channel by channel (a plane of samples each, so that a grid's first
    /// channel reads as fast alone as a one-channel grid); samples x
    /// fastest, then y, then z.
    pub values: Vec<f32>,
    /// Absorption σa at each point.
    pub sigma_a: GridField,
    /// Scattering σs at each point.
    pub sigma_s: GridField,
    /// Emitted radiance per unit absorption at each point: the medium adds
    /// σa · Le per unit length.
    pub le: GridField,
    /// Henyey–Greenstein asymmetry of the phase function, in (-1, 1).
    pub g: f32,
    /// The grid's box in the medium's space (pbrt's `p0`, `p1`).
    pub lo: glam::Vec3,
    pub hi: glam::Vec3,
    /// World space to the medium's (the inverse of the transform where
    /// `MakeNamedMedium` was).
    pub world_to_medium: glam::Affine3A,
}

/// One coefficient of a [`GridMedium`] at each point inside its box:
/// `scale` times what `source` interpolates there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridField {
    pub scale: Rgb,
    pub source: FieldSource,
}

/// Where a [`GridField`] comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FieldSource {
    /// 1 everywhere in the box.
    Constant,
    /// Channel `k` of the samples, the same for red, green and blue.
    Scalar(u32),
    /// Channels `k`, `k + 1`, `k + 2`: red, green, blue.
    Rgb(u32),
}

impl GridField {
    /// `scale` everywhere in the box.
    pub fn constant(scale: Rgb) -> Self {
        GridField { scale, source: FieldSource::Constant }
    }
}

impl Medium {
    /// Bytes of its data (a grid's samples).
    pub fn bytes(&self) -> u64 {
        match self {
            Medium::Homogeneous(_) | Medium::Subsurface(_) => std::mem::size_of::<HomogeneousMedium>() as u64,
            Medium::Grid(g) => (g.values.len() * std::mem::size_of::<f32>()) as u64,
        }
    }
}

/// Coefficients of a homogeneous medium, per unit of world distance, with
/// pbrt's `scale` already applied to both cross sections and `Lescale` to
/// the emission.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HomogeneousMedium {
    /// Absorption cross section σa.
    pub sigma_a: Rgb,
    /// Scattering cross section σs.
    pub sigma_s: Rgb,
    /// Henyey–Greenstein asymmetry of the phase function, in (-1, 1).
    pub g: f32,
    /// Emitted radiance per unit absorption (pbrt's `Le`: the medium adds
    /// σa · Le per unit length).
    pub le: Rgb,
}

impl HomogeneousMedium {
    /// pbrt-v4's defaults: σa = σs = 1, isotropic, no emission.
    pub fn pbrt_default() -> Self {
        HomogeneousMedium { sigma_a: Rgb::ONE, sigma_s: Rgb::ONE, g: 0.0, le: Rgb::ZERO }
    }

    /// The extinction cross section σt = σa + σs.
    pub fn sigma_t(&self) -> Rgb {
        self.sigma_a + self.sigma_s
    }
}

/// Which medium: 0 is vacuum, `k` is the scene's `media[k - 1]`. Small
/// because a ray record carries it in four bits ([`MAX_MEDIA`]).
pub type MediumIndex = u8;

/// The vacuum: no medium.
pub const VACUUM: MediumIndex = 0;

/// The most media a scene may define: a ray record holds a path's medium
/// in four bits beside its flags.
pub const MAX_MEDIA: usize = 15;

/// The media on the two sides of a surface (pbrt's `MediumInterface`):
/// `inside` is the side the geometric normal points away from. Only
/// surfaces where the two differ carry one ([`MediumInterface::transition`]);
/// elsewhere a ray keeps the medium it is in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MediumInterface {
    pub inside: MediumIndex,
    pub outside: MediumIndex,
}

impl MediumInterface {
    /// The interface when crossing it changes the medium, else `None`
    /// (pbrt's `IsMediumTransition`).
    pub fn transition(inside: MediumIndex, outside: MediumIndex) -> Option<Self> {
        (inside != outside).then_some(MediumInterface { inside, outside })
    }

    /// The medium a direction leaves into, given its cosine with the
    /// geometric normal (pbrt's `GetMedium(w)`).
    pub fn towards(&self, cos_to_normal: f32) -> MediumIndex {
        if cos_to_normal > 0.0 {
            self.outside
        } else {
            self.inside
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interfaces_follow_the_normal() {
        assert_eq!(MediumInterface::transition(2, 2), None);
        let i = MediumInterface::transition(1, VACUUM).unwrap();
        assert_eq!(i.towards(0.5), VACUUM);
        assert_eq!(i.towards(-0.5), 1);
        assert_eq!(HomogeneousMedium::pbrt_default().sigma_t(), Rgb::splat(2.0));
    }
}
