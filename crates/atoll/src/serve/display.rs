//! What a viewer sees of the linear film: exposure, a tone curve, sRGB,
//! then a JPEG. Each viewer chooses its own exposure and curve; the
//! saved image stays the linear film.

use atoll_render::film::linear_to_srgb;
use glam::{UVec2, Vec3};
use jpeg_encoder::{ColorType, Encoder};
use rayon::prelude::*;

/// How radiance becomes display values in [0, 1].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ToneCurve {
    /// Clipped at 1, as `atoll render`'s PNG.
    #[default]
    Clip,
    /// x / (1 + x) per channel: nothing clips.
    Reinhard,
    /// Narkowicz's fit of the ACES filmic curve.
    Filmic,
}

impl ToneCurve {
    pub fn parse(name: &str) -> Option<ToneCurve> {
        match name {
            "clip" => Some(ToneCurve::Clip),
            "reinhard" => Some(ToneCurve::Reinhard),
            "filmic" => Some(ToneCurve::Filmic),
            _ => None,
        }
    }

    fn apply(self, x: f32) -> f32 {
        let x = x.max(0.0);
        match self {
            ToneCurve::Clip => x,
            ToneCurve::Reinhard => x / (1.0 + x),
            ToneCurve::Filmic => (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14),
        }
    }
}

/// One viewer's display settings.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Display {
    /// Stops of exposure (radiance times 2^ev).
    pub exposure_ev: f32,
    pub curve: ToneCurve,
}

/// JPEG quality of frames: noise stays visible, a 1080p frame stays
/// small enough for a few a second through an SSH tunnel.
const QUALITY: u8 = 85;

impl Display {
    /// The 8-bit sRGB value of `radiance`.
    pub fn srgb8(&self, radiance: Vec3) -> [u8; 3] {
        let scale = self.exposure_ev.exp2();
        radiance.to_array().map(|c| (linear_to_srgb(self.curve.apply(c * scale)) * 255.0 + 0.5) as u8)
    }

    /// `pixels` (mean radiance, row-major) as a JPEG.
    pub fn jpeg(&self, pixels: &[Vec3], resolution: UVec2) -> Result<Vec<u8>, String> {
        let too_big = || format!("{}x{}: JPEG frames end at 65535 pixels a side", resolution.x, resolution.y);
        let width = u16::try_from(resolution.x).map_err(|_| too_big())?;
        let height = u16::try_from(resolution.y).map_err(|_| too_big())?;
        let rgb: Vec<u8> = pixels.par_iter().flat_map_iter(|p| self.srgb8(*p)).collect();
        let mut bytes = Vec::new();
        Encoder::new(&mut bytes, QUALITY)
            .encode(&rgb, width, height, ColorType::Rgb)
            .map_err(|e| e.to_string())?;
        Ok(bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn curves_map_black_to_black_and_keep_order() {
        for curve in [ToneCurve::Clip, ToneCurve::Reinhard, ToneCurve::Filmic] {
            let d = Display { exposure_ev: 0.0, curve };
            assert_eq!(d.srgb8(Vec3::ZERO), [0, 0, 0]);
            let (a, b) = (d.srgb8(Vec3::splat(0.2))[0], d.srgb8(Vec3::splat(0.4))[0]);
            assert!(a < b, "{curve:?}: {a} {b}");
            assert_eq!(ToneCurve::parse(&format!("{curve:?}").to_lowercase()), Some(curve));
        }
        // Clip is the PNG writer's mapping; one stop up doubles the radiance.
        let clip = Display::default();
        assert_eq!(clip.srgb8(Vec3::new(1.0, 2.0, f32::NAN)), [255, 255, 0]);
        let up = Display { exposure_ev: 1.0, ..clip };
        assert_eq!(up.srgb8(Vec3::splat(0.25)), clip.srgb8(Vec3::splat(0.5)));
        assert!(Display { curve: ToneCurve::Reinhard, ..clip }.srgb8(Vec3::splat(1e6))[0] == 255);
    }

    #[test]
    fn frames_are_jpegs_of_the_image_size() {
        let res = UVec2::new(16, 8);
        let pixels: Vec<Vec3> = (0..128).map(|i| Vec3::splat(i as f32 / 128.0)).collect();
        let bytes = Display::default().jpeg(&pixels, res).unwrap();
        assert_eq!(&bytes[..2], &[0xff, 0xd8]);
        let decoded = image::load_from_memory(&bytes).unwrap();
        assert_eq!((decoded.width(), decoded.height()), (16, 8));
    }
}
