//! Light sources. Area lights are emission attached to meshes
//! ([`AreaEmission`]); the rest are [`Light`]s.

use glam::Vec3;

use crate::Rgb;

/// Emission of a diffuse area light attached to a mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AreaEmission {
    /// Emitted radiance (already multiplied by the light's `scale`).
    pub radiance: Rgb,
    /// pbrt's `twosided`: emit from both faces instead of only along the
    /// geometric normal.
    pub two_sided: bool,
}

/// A light that is not attached to geometry. Positions and directions are in
/// world space; every value already includes the light's `scale`.
#[derive(Clone, Debug, PartialEq)]
pub enum Light {
    /// Isotropic point light with radiant intensity `intensity` (W/sr).
    Point { position: Vec3, intensity: Rgb },
    /// Directional light: radiance `radiance` arriving along `direction`
    /// (the direction light travels, normalised).
    Distant { direction: Vec3, radiance: Rgb },
    /// Constant environment light of radiance `radiance` from every direction.
    Infinite { radiance: Rgb },
}
