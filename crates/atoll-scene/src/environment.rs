//! Environment images for image-based infinite lights: loading (OpenEXR,
//! PNG) and the two parameterisations of the sphere pbrt uses.
//!
//! - [`EnvLayout::EqualArea`]: pbrt-v4's square equal-area octahedral map
//!   (Clarberg 2008): every pixel covers the same solid angle.
//! - [`EnvLayout::LatLong`]: pbrt-v3's latitude-longitude map: `u` is the
//!   azimuth `φ = 2πu` around +z, `v` the polar angle `θ = πv` from +z.
//!
//! Directions are in the light's own space (+z up, as in pbrt); the light's
//! transform takes them to the world. Square images are read as equal-area
//! maps, others as lat-long ones (pbrt-v4 itself accepts only square ones).

use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};
use std::path::Path;

use glam::{Vec2, Vec3};

use crate::{ImageLoadError, Rgb};

/// How an environment image covers the sphere of directions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EnvLayout {
    EqualArea,
    LatLong,
}

/// An environment image: linear RGB, row-major from the top row.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Rgb>,
    pub layout: EnvLayout,
}

impl EnvLayout {
    /// The unit direction (light space) at image coordinates `uv` in [0,1]².
    pub fn direction(self, uv: Vec2) -> Vec3 {
        match self {
            EnvLayout::LatLong => {
                let (theta, phi) = (PI * uv.y, 2.0 * PI * uv.x);
                let sin_theta = theta.sin();
                Vec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), theta.cos())
            }
            EnvLayout::EqualArea => equal_area_square_to_sphere(uv),
        }
    }

    /// The image coordinates of the unit direction `d` (light space).
    pub fn uv(self, d: Vec3) -> Vec2 {
        match self {
            EnvLayout::LatLong => {
                let theta = d.z.clamp(-1.0, 1.0).acos();
                let mut phi = d.y.atan2(d.x);
                if phi < 0.0 {
                    phi += 2.0 * PI;
                }
                Vec2::new(phi / (2.0 * PI), theta / PI)
            }
            EnvLayout::EqualArea => equal_area_sphere_to_square(d),
        }
    }

    /// `d(solid angle) / d(image area)` at `uv` (the Jacobian relating a
    /// density over the image square to one over directions).
    pub fn solid_angle_per_area(self, uv: Vec2) -> f32 {
        match self {
            EnvLayout::EqualArea => 4.0 * PI,
            EnvLayout::LatLong => 2.0 * PI * PI * (PI * uv.y).sin(),
        }
    }
}

/// pbrt-v4's `EqualAreaSquareToSphere`.
pub fn equal_area_square_to_sphere(p: Vec2) -> Vec3 {
    let (u, v) = (2.0 * p.x - 1.0, 2.0 * p.y - 1.0);
    let (up, vp) = (u.abs(), v.abs());
    let signed_distance = 1.0 - (up + vp);
    let d = signed_distance.abs();
    let r = 1.0 - d;
    let phi = if r == 0.0 { 1.0 } else { (vp - up) / r + 1.0 } * FRAC_PI_4;
    let z = (1.0 - r * r).copysign(signed_distance);
    let cos_phi = phi.cos().copysign(u);
    let sin_phi = phi.sin().copysign(v);
    let s = r * (2.0 - r * r).max(0.0).sqrt();
    Vec3::new(cos_phi * s, sin_phi * s, z)
}

/// pbrt-v4's `WrapEqualAreaSquare`: a point past an edge of the
/// equal-area square, folded back to the point of the sphere beside it.
pub fn wrap_equal_area_square(mut uv: Vec2) -> Vec2 {
    if uv.x < 0.0 {
        uv = Vec2::new(-uv.x, 1.0 - uv.y);
    } else if uv.x > 1.0 {
        uv = Vec2::new(2.0 - uv.x, 1.0 - uv.y);
    }
    if uv.y < 0.0 {
        uv = Vec2::new(1.0 - uv.x, -uv.y);
    } else if uv.y > 1.0 {
        uv = Vec2::new(1.0 - uv.x, 2.0 - uv.y);
    }
    uv
}

/// pbrt-v4's `EqualAreaSphereToSquare` (with an exact arctangent).
pub fn equal_area_sphere_to_square(d: Vec3) -> Vec2 {
    let (x, y, z) = (d.x.abs(), d.y.abs(), d.z.abs());
    let r = (1.0 - z).max(0.0).sqrt();
    let a = x.max(y);
    let b = if a == 0.0 { 0.0 } else { x.min(y) / a };
    let mut phi = b.atan() / FRAC_PI_2;
    if x < y {
        phi = 1.0 - phi;
    }
    let mut v = phi * r;
    let mut u = r - v;
    if d.z < 0.0 {
        (u, v) = (1.0 - v, 1.0 - u);
    }
    Vec2::new((u.copysign(d.x) + 1.0) * 0.5, (v.copysign(d.y) + 1.0) * 0.5)
}

impl EnvironmentImage {
    /// A `width × height` image of `layout` (square: equal-area expected).
    pub fn new(width: u32, height: u32, pixels: Vec<Rgb>, layout: EnvLayout) -> Self {
        assert_eq!(pixels.len(), (width * height) as usize, "pixel count");
        EnvironmentImage { width, height, pixels, layout }
    }

    /// Loads an OpenEXR (RGB(A), linear) or PNG (sRGB, decoded to linear)
    /// image; square images are equal-area maps, others lat-long ones.
    pub fn load(path: &Path) -> Result<Self, ImageLoadError> {
        let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
        if matches!(ext.as_deref(), Some("exr" | "png")) {
            crate::input::check_regular(path).map_err(ImageLoadError::io(path))?;
        }
        let (width, height, pixels) = match ext.as_deref() {
            Some("exr") => {
                let img = exr::prelude::read_first_rgba_layer_from_file(
                    path,
                    |res, _| (res.width(), vec![Rgb::ZERO; res.width() * res.height()]),
                    |(w, px): &mut (usize, Vec<Rgb>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                        px[pos.y() * *w + pos.x()] = Rgb::new(r, g, b)
                    },
                )
                .map_err(ImageLoadError::exr(path))?;
                let size = img.layer_data.size;
                (size.width() as u32, size.height() as u32, img.layer_data.channel_data.pixels.1)
            }
            Some("png") => {
                let img = image::open(path).map_err(ImageLoadError::decode(path))?.to_rgb32f();
                let (w, h) = img.dimensions();
                let srgb = |c: f32| if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) };
                (w, h, img.pixels().map(|p| Rgb::new(srgb(p[0]), srgb(p[1]), srgb(p[2]))).collect())
            }
            _ => return Err(ImageLoadError::EnvironmentFormat { path: path.to_path_buf() }),
        };
        if width == 0 || height == 0 {
            return Err(ImageLoadError::Empty { path: path.to_path_buf() });
        }
        if let Some(bad) = pixels.iter().position(|p| !p.is_finite() || p.min_element() < 0.0) {
            let (x, y) = (bad as u32 % width, bad as u32 / width);
            return Err(ImageLoadError::BadEnvironmentPixel { path: path.to_path_buf(), x, y });
        }
        let layout = if width == height { EnvLayout::EqualArea } else { EnvLayout::LatLong };
        Ok(EnvironmentImage { width, height, pixels, layout })
    }

    /// The pixel holding image coordinates `uv` (nearest, clamped).
    pub fn pixel_index(&self, uv: Vec2) -> usize {
        let x = ((uv.x * self.width as f32) as u32).min(self.width - 1);
        let y = ((uv.y * self.height as f32) as u32).min(self.height - 1);
        (y * self.width + x) as usize
    }

    /// The radiance seen along light-space direction `d` (the pixel it falls in).
    pub fn lookup(&self, d: Vec3) -> Rgb {
        self.pixels[self.pixel_index(self.layout.uv(d))]
    }

    /// Illuminance (in luminance units) the image casts on a surface facing
    /// light-space +z: `∫ luminance(L(ω)) cos θ dω` over the upper
    /// hemisphere, summed over pixel centres (pbrt-v4's `k_e` for the
    /// infinite light's `illuminance` parameter).
    pub fn upper_hemisphere_illuminance(&self) -> f64 {
        let (w, h) = (self.width as f64, self.height as f64);
        let mut sum = 0.0;
        for y in 0..self.height {
            for x in 0..self.width {
                let uv = Vec2::new(((x as f64 + 0.5) / w) as f32, ((y as f64 + 0.5) / h) as f32);
                let d = self.layout.direction(uv);
                if d.z > 0.0 {
                    let pixel = self.pixels[(y * self.width + x) as usize];
                    let solid_angle = self.layout.solid_angle_per_area(uv) as f64 / (w * h);
                    sum += crate::luminance(pixel) as f64 * d.z as f64 * solid_angle;
                }
            }
        }
        sum
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_area_round_trips_and_covers_the_sphere() {
        let mut mean = Vec3::ZERO;
        let n = 64;
        for j in 0..n {
            for i in 0..n {
                let uv = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let d = equal_area_square_to_sphere(uv);
                assert!((d.length() - 1.0).abs() < 1e-5, "{d}");
                let back = equal_area_sphere_to_square(d);
                assert!((back - uv).abs().max_element() < 1e-4, "{uv} -> {d} -> {back}");
                mean += d;
            }
        }
        // Equal areas: directions of a regular grid average to (almost) zero.
        assert!((mean / (n * n) as f32).length() < 1e-3, "{mean}");
    }

    /// A uniform image of radiance 1 casts π on an upward surface, in
    /// either layout; one bright only below the horizon casts nothing.
    #[test]
    fn upper_hemisphere_illuminance_of_uniform_and_lower_skies() {
        for (w, h, layout) in [(64, 64, EnvLayout::EqualArea), (128, 64, EnvLayout::LatLong)] {
            let uniform = EnvironmentImage::new(w, h, vec![Rgb::ONE; (w * h) as usize], layout);
            let e = uniform.upper_hemisphere_illuminance();
            assert!((e - std::f64::consts::PI).abs() < 0.01, "{layout:?}: {e}");
            let pixels = (0..w * h)
                .map(|i| {
                    let uv = Vec2::new(((i % w) as f32 + 0.5) / w as f32, ((i / w) as f32 + 0.5) / h as f32);
                    if layout.direction(uv).z < 0.0 {
                        Rgb::splat(5.0)
                    } else {
                        Rgb::ZERO
                    }
                })
                .collect();
            assert_eq!(EnvironmentImage::new(w, h, pixels, layout).upper_hemisphere_illuminance(), 0.0);
        }
    }

    #[test]
    fn lat_long_round_trips() {
        for (u, v) in [(0.1, 0.2), (0.7, 0.5), (0.95, 0.9)] {
            let uv = Vec2::new(u, v);
            let d = EnvLayout::LatLong.direction(uv);
            assert!((EnvLayout::LatLong.uv(d) - uv).abs().max_element() < 1e-5);
        }
        assert!((EnvLayout::LatLong.direction(Vec2::new(0.3, 0.0)) - Vec3::Z).length() < 1e-6);
    }

    #[test]
    fn loading_checks_the_file() {
        let dir = std::env::temp_dir().join(format!("atoll-env-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("sky.exr");
        exr::prelude::write_rgb_file(&path, 4, 2, |x, y| (x as f32, y as f32, 0.5)).unwrap();
        let img = EnvironmentImage::load(&path).unwrap();
        assert_eq!((img.width, img.height, img.layout), (4, 2, EnvLayout::LatLong));
        assert_eq!(img.pixels[4 + 3], Rgb::new(3.0, 1.0, 0.5));
        assert!(EnvironmentImage::load(&dir.join("missing.exr")).is_err());
        std::fs::write(dir.join("bad.exr"), b"not an exr").unwrap();
        assert!(EnvironmentImage::load(&dir.join("bad.exr")).is_err());
        assert!(EnvironmentImage::load(&dir.join("sky.tga"))
            .unwrap_err()
            .to_string()
            .contains(".exr or .png"));
        std::fs::remove_dir_all(&dir).ok();
    }
}
