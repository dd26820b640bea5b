//! Light sources. Area lights are emission attached to meshes
//! ([`AreaEmission`]); the rest are [`Light`]s.

use std::sync::Arc;

use glam::{Mat3, Vec3};

use crate::EnvironmentImage;

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

impl AreaEmission {
    /// One-sided emission of `radiance`; `None` when it is black. Negative
    /// light is no light, and infinite or NaN radiance would fill the image
    /// with them: both are refused, saying why.
    pub fn one_sided(radiance: Rgb) -> Result<Option<AreaEmission>, String> {
        if !radiance.is_finite() || radiance.min_element() < 0.0 {
            return Err(format!("emission {radiance:?} is negative, infinite or NaN"));
        }
        Ok((radiance.max_element() > 0.0).then_some(AreaEmission { radiance, two_sided: false }))
    }
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
    /// Constant environment light of radiance `radiance` from every
    /// direction (with a `portal`: only through it).
    Infinite { radiance: Rgb, portal: Option<Portal> },
    /// pbrt-v4's spot light: intensity `intensity` (W/sr) along the unit
    /// axis `direction`, scaled by `smoothstep(cos_falloff_end,
    /// cos_falloff_start, cos θ)` away from it (full inside the inner cone,
    /// none outside the outer one).
    Spot { position: Vec3, direction: Vec3, intensity: Rgb, cos_falloff_start: f32, cos_falloff_end: f32 },
    /// An image-based environment: radiance `scale × image(d)` from world
    /// direction `light_to_world × d` (a rotation; `d` in the image's space);
    /// with a `portal`, only through it.
    Environment { image: Arc<EnvironmentImage>, scale: Rgb, light_to_world: Mat3, portal: Option<Portal> },
    /// pbrt-v4's goniometric light: a point whose intensity towards world
    /// direction `w` is `intensity × map(world_to_light × w)`, the map an
    /// equal-area square of directions (its pole is the light's +y, as
    /// pbrt swaps y and z), read at the nearest sample.
    Goniometric { position: Vec3, world_to_light: Mat3, intensity: Rgb, map: Arc<IntensityMap> },
    /// pbrt-v4's projection light: a point projecting an image like a slide
    /// projector. Towards world direction `w` its intensity is `scale ×`
    /// the image's nearest pixel where `world_to_light × w` pierces the
    /// image's frustum (see [`ProjectionImage::towards`]), nothing outside.
    Projection { position: Vec3, world_to_light: Mat3, scale: f32, image: Arc<ProjectionImage> },
}

/// A projection light's image and frustum: linear RGB rows from the top,
/// spread over the screen window at z = 1 of the light's space, the
/// shorter side spanning `tan(fov / 2)` either way (pbrt-v4's
/// `ProjectionLight`).
#[derive(Clone, Debug, PartialEq)]
pub struct ProjectionImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Rgb>,
    /// `tan(fov / 2)`.
    pub tan_half_fov: f32,
}

impl ProjectionImage {
    /// Light-space directions at `z` below this are behind the projector
    /// (pbrt's near plane).
    pub const HITHER: f32 = 1e-3;

    /// Half the screen window at z = 1 before the field of view scales it:
    /// (aspect, 1) for a wide image, (1, 1 / aspect) for a tall one.
    pub fn half_screen(&self) -> glam::Vec2 {
        let aspect = self.width as f32 / self.height as f32;
        if aspect > 1.0 {
            glam::Vec2::new(aspect, 1.0)
        } else {
            glam::Vec2::new(1.0, 1.0 / aspect)
        }
    }

    /// The image towards light-space direction `w` (any length): the
    /// nearest pixel where it crosses the screen window, `None` behind the
    /// projector or outside the window.
    pub fn towards(&self, w: Vec3) -> Option<Rgb> {
        if w.z < Self::HITHER {
            return None;
        }
        let half = self.half_screen();
        let screen = glam::Vec2::new(w.x / w.z, w.y / w.z) / self.tan_half_fov;
        if screen.x.abs() > half.x || screen.y.abs() > half.y {
            return None;
        }
        let uv = (screen + half) / (2.0 * half);
        let texel = |t: f32, n: u32| ((t * n as f32) as i64).clamp(0, n as i64 - 1) as usize;
        Some(self.pixels[texel(uv.y, self.height) * self.width as usize + texel(uv.x, self.width)])
    }

    /// The power the image sends out per unit of scale, channel by channel:
    /// the window's area at z = 1 times the mean over pixels of their
    /// value times cos³θ (solid angle per unit of window area), as pbrt-v4's
    /// `ProjectionLight::Phi` sums it.
    pub fn power(&self) -> Rgb {
        let half = self.half_screen() * self.tan_half_fov;
        let area = 4.0 * half.x as f64 * half.y as f64;
        let mut sum = [0.0f64; 3];
        for y in 0..self.height {
            for x in 0..self.width {
                let sx = -half.x + 2.0 * half.x * (x as f32 + 0.5) / self.width as f32;
                let sy = -half.y + 2.0 * half.y * (y as f32 + 0.5) / self.height as f32;
                let cos = 1.0 / (sx * sx + sy * sy + 1.0).sqrt();
                let p = self.pixels[(y * self.width + x) as usize];
                for (s, v) in sum.iter_mut().zip(p.to_array()) {
                    *s += v.max(0.0) as f64 * (cos as f64).powi(3);
                }
            }
        }
        let n = (self.width as f64 * self.height as f64).max(1.0);
        Rgb::from_array(sum.map(|s| (area * s / n) as f32))
    }
}

/// A goniometric light's distribution: `resolution`² values over pbrt's
/// equal-area square (rows from the top), the average of an image's
/// red, green and blue.
#[derive(Clone, Debug, PartialEq)]
pub struct IntensityMap {
    pub resolution: u32,
    pub values: Vec<f32>,
}

impl IntensityMap {
    /// The value at the nearest sample to `uv` in [0, 1]² (pbrt's
    /// `LookupNearest`, clamped at the edges).
    pub fn nearest(&self, uv: glam::Vec2) -> f32 {
        let n = self.resolution;
        let texel = |t: f32| ((t * n as f32) as i64).clamp(0, n as i64 - 1) as usize;
        self.values[texel(uv.y) * n as usize + texel(uv.x)]
    }

    /// The value towards unit direction `d` of the light's space
    /// (pole +y): the equal-area square's sample there.
    pub fn towards(&self, d: Vec3) -> f32 {
        self.nearest(crate::environment::equal_area_sphere_to_square(Vec3::new(d.x, d.z, d.y)))
    }

    /// The mean value: the light's power is 4π times this times its intensity.
    pub fn mean(&self) -> f32 {
        (self.values.iter().map(|&v| v as f64).sum::<f64>() / self.values.len().max(1) as f64) as f32
    }
}

/// pbrt-v4's infinite-light `portal`: a rectangle in world space (corners
/// in order) through which alone its environment shines: a ray sees the
/// environment only if it leaves through the rectangle, from its back
/// (the side its frame's z faces away from; pbrt's `PortalImageInfiniteLight`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Portal {
    pub corners: [Vec3; 4],
}

impl Portal {
    /// The portal with these corners, if they make a rectangle (pbrt's
    /// test: opposite edges parallel and adjacent edges perpendicular,
    /// within 0.001 in their cosines).
    pub fn new(corners: [Vec3; 4]) -> Result<Portal, String> {
        let [p0, p1, p2, p3] = corners.map(|c| c.as_dvec3());
        let edges = [p1 - p0, p2 - p1, p2 - p3, p3 - p0];
        if edges.iter().any(|e| e.length() == 0.0 || !e.is_finite()) {
            return Err("the portal has corners that coincide".into());
        }
        let [p01, p12, p32, p03] = edges.map(|e| e.normalize());
        let parallel = (p01.dot(p32) - 1.0).abs() <= 1e-3 && (p12.dot(p03) - 1.0).abs() <= 1e-3;
        let perpendicular =
            [p01.dot(p12), p12.dot(p32), p32.dot(p03), p03.dot(p01)].iter().all(|c| c.abs() <= 1e-3);
        if !(parallel && perpendicular) {
            return Err("the portal is not a planar rectangle (corners in order)".into());
        }
        Ok(Portal { corners })
    }
}

impl Light {
    /// A spot light from pbrt's parameters: cone half-angle `cone_angle` and
    /// falloff width `cone_delta`, in degrees (`coneangle`, `conedelta`).
    pub fn spot(position: Vec3, direction: Vec3, intensity: Rgb, cone_angle: f32, cone_delta: f32) -> Light {
        let end = cone_angle.clamp(0.0, 180.0);
        let start = (cone_angle - cone_delta).clamp(0.0, end);
        Light::Spot {
            position,
            direction: direction.normalize_or(Vec3::Z),
            intensity,
            cos_falloff_start: start.to_radians().cos(),
            cos_falloff_end: end.to_radians().cos(),
        }
    }

    /// pbrt-v4's `SpotLight` power factor: the solid angle a unit intensity
    /// fills, `2π ((1 - cos_start) + (cos_start - cos_end) / 2)`.
    pub fn spot_solid_angle(cos_falloff_start: f32, cos_falloff_end: f32) -> f32 {
        2.0 * std::f32::consts::PI * ((1.0 - cos_falloff_start) + (cos_falloff_start - cos_falloff_end) / 2.0)
    }
}
