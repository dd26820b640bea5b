//! Importance sampling of image-based environment lights.
//!
//! A pixel is chosen with probability proportional to its luminance times
//! the solid angle it covers (for lat-long images, `sin θ` at the pixel's
//! centre row, as pbrt does; equal-area pixels are all alike), by a row from
//! the marginal distribution and a column from that row's conditional one;
//! the sample is then uniform inside the pixel. Radiance lookups take the
//! pixel a direction falls in, so the density and what it samples agree
//! exactly (multiple importance sampling needs both). The GPU mirrors
//! [`EnvironmentSampler::sample`] and [`EnvironmentSampler::pdf`] operation
//! for operation over the tables [`EnvironmentSampler::tables`] flattens.

use std::f32::consts::PI;
use std::sync::Arc;

use atoll_scene::{luminance, EnvLayout, EnvironmentImage, Rgb};
use glam::{Mat3, Vec2, Vec3};

/// An environment image with its sampling distribution.
#[derive(Clone, Debug)]
pub struct EnvironmentSampler {
    pub image: Arc<EnvironmentImage>,
    pub scale: Rgb,
    pub light_to_world: Mat3,
    /// Per pixel: the unnormalised selection weight.
    pub func: Vec<f32>,
    /// Row selection: `height + 1` entries from 0 to 1.
    pub marginal_cdf: Vec<f32>,
    /// Per row, `width + 1` entries from 0 to 1 (column selection).
    pub conditional_cdf: Vec<f32>,
    /// Sum of `func`.
    pub func_sum: f32,
    /// Mean radiance luminance over the sphere (for light selection by power).
    pub mean_luminance: f32,
}

/// A cumulative distribution of `weights` (`weights.len() + 1` entries, 0 to
/// exactly 1; uniform when every weight is 0).
fn cdf_of(weights: &[f32]) -> Vec<f32> {
    let total: f64 = weights.iter().map(|&w| w as f64).sum();
    let mut acc = 0.0f64;
    let mut cdf = Vec::with_capacity(weights.len() + 1);
    cdf.push(0.0);
    for (i, &w) in weights.iter().enumerate() {
        acc += if total > 0.0 { w as f64 / total } else { 1.0 / weights.len() as f64 };
        cdf.push(if i + 1 == weights.len() { 1.0 } else { acc as f32 });
    }
    cdf
}

/// The entry `cdf` selects for `u` in [0,1) (its first value above `u`,
/// minus one, skipping empty entries) and `u` rescaled to [0,1) within it.
/// The GPU's `env_select` mirrors it.
pub fn select_in_cdf(cdf: &[f32], u: f32) -> (usize, f32) {
    let n = cdf.len() - 1;
    let i = cdf.partition_point(|&c| c <= u).saturating_sub(1).min(n - 1);
    let width = cdf[i + 1] - cdf[i];
    let t = if width > 0.0 { ((u - cdf[i]) / width).clamp(0.0, 0.99999994) } else { 0.5 };
    (i, t)
}

impl EnvironmentSampler {
    pub fn new(image: Arc<EnvironmentImage>, scale: Rgb, light_to_world: Mat3) -> Self {
        let (w, h) = (image.width as usize, image.height as usize);
        let row_weight = |y: usize| match image.layout {
            EnvLayout::EqualArea => 1.0,
            EnvLayout::LatLong => (PI * (y as f32 + 0.5) / h as f32).sin(),
        };
        let func: Vec<f32> =
            (0..w * h).map(|i| luminance(image.pixels[i] * scale).max(0.0) * row_weight(i / w)).collect();
        let rows: Vec<f32> = (0..h).map(|y| func[y * w..(y + 1) * w].iter().sum()).collect();
        let marginal_cdf = cdf_of(&rows);
        let conditional_cdf = (0..h).flat_map(|y| cdf_of(&func[y * w..(y + 1) * w])).collect();
        let func_sum: f32 = rows.iter().sum();
        // Mean over the sphere: sum of luminance × pixel solid angle / 4π;
        // a pixel covers J(uv) / (w h) steradians.
        let mean_luminance = (0..w * h)
            .map(|i| {
                let uv = Vec2::new(((i % w) as f32 + 0.5) / w as f32, ((i / w) as f32 + 0.5) / h as f32);
                luminance(image.pixels[i] * scale) as f64 * image.layout.solid_angle_per_area(uv) as f64
            })
            .sum::<f64>()
            / (w * h) as f64
            / (4.0 * std::f64::consts::PI);
        EnvironmentSampler {
            image,
            scale,
            light_to_world,
            func,
            marginal_cdf,
            conditional_cdf,
            func_sum,
            mean_luminance: mean_luminance as f32,
        }
    }

    /// Radiance arriving from world direction `w` (a ray escaping along `w`).
    pub fn radiance(&self, w: Vec3) -> Rgb {
        self.image.lookup(self.light_to_world.transpose() * w) * self.scale
    }

    /// A direction towards the environment for numbers `u`: (world
    /// direction, radiance, solid-angle density). `None` where the density
    /// vanishes (an all-black image, a lat-long pole).
    pub fn sample(&self, u: Vec2) -> Option<(Vec3, Rgb, f32)> {
        if self.func_sum <= 0.0 {
            return None;
        }
        let (w, h) = (self.image.width as usize, self.image.height as usize);
        let (y, v) = select_in_cdf(&self.marginal_cdf, u.y);
        let (x, t) = select_in_cdf(&self.conditional_cdf[y * (w + 1)..(y + 1) * (w + 1)], u.x);
        let uv = Vec2::new((x as f32 + t) / w as f32, (y as f32 + v) / h as f32);
        let jacobian = self.image.layout.solid_angle_per_area(uv);
        let p_pixel = self.func[y * w + x] / self.func_sum;
        if jacobian <= 0.0 || p_pixel <= 0.0 {
            return None;
        }
        let d = self.image.layout.direction(uv);
        let wi = (self.light_to_world * d).normalize();
        let pdf = p_pixel * (w * h) as f32 / jacobian;
        Some((wi, self.image.pixels[y * w + x] * self.scale, pdf))
    }

    /// The solid-angle density with which [`Self::sample`] picks world direction `w`.
    pub fn pdf(&self, w: Vec3) -> f32 {
        if self.func_sum <= 0.0 {
            return 0.0;
        }
        let uv = self.image.layout.uv(self.light_to_world.transpose() * w);
        let jacobian = self.image.layout.solid_angle_per_area(uv);
        if jacobian <= 0.0 {
            return 0.0;
        }
        let (width, height) = (self.image.width as usize, self.image.height as usize);
        self.func[self.image.pixel_index(uv)] / self.func_sum * (width * height) as f32 / jacobian
    }

    /// Appends this environment's tables to `out` for the GPU: pixels (RGB,
    /// scale included), `func`, the marginal then the conditional CDFs.
    /// Returns the offset of its first word.
    pub fn tables(&self, out: &mut Vec<f32>) -> u32 {
        let offset = out.len() as u32;
        out.extend(self.image.pixels.iter().flat_map(|p| (*p * self.scale).to_array()));
        out.extend_from_slice(&self.func);
        out.extend_from_slice(&self.marginal_cdf);
        out.extend_from_slice(&self.conditional_cdf);
        offset
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    /// A lat-long or equal-area image with a bright patch and a dim rest.
    fn image(layout: EnvLayout) -> Arc<EnvironmentImage> {
        let (w, h) = if layout == EnvLayout::LatLong { (32, 16) } else { (24, 24) };
        let pixels = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if (4..8).contains(&x) && (5..9).contains(&y) {
                    Rgb::new(40.0, 30.0, 20.0)
                } else {
                    Rgb::splat(0.2 + 0.01 * (x + y) as f32)
                }
            })
            .collect();
        Arc::new(EnvironmentImage::new(w as u32, h as u32, pixels, layout))
    }

    fn rnd(i: u32, k: u32) -> f32 {
        let x = (i.wrapping_mul(0x9e37_79b9) ^ k.wrapping_mul(0x85eb_ca6b)).wrapping_mul(0xc2b2_ae35);
        (x >> 8) as f32 / (1u32 << 24) as f32
    }

    /// Sampling and the density agree: the density at every sample equals
    /// the one `pdf` reports, the radiance equals the lookup, and the
    /// estimate of the irradiance-like integral ∫ L(w) dw by importance
    /// sampling matches the one by uniform sphere sampling.
    #[test]
    fn sampling_agrees_with_density_and_lookup() {
        for layout in [EnvLayout::LatLong, EnvLayout::EqualArea] {
            let rotation = Mat3::from_quat(Quat::from_rotation_x(0.7) * Quat::from_rotation_z(0.3));
            let env = EnvironmentSampler::new(image(layout), Rgb::new(1.0, 0.5, 2.0), rotation);
            let n = 200_000u32;
            let mut importance = 0.0f64;
            let mut uniform = 0.0f64;
            let mut at_edges = 0;
            for i in 0..n {
                let (wi, radiance, pdf) = env.sample(Vec2::new(rnd(i, 1), rnd(i, 2))).expect("sample");
                assert!((wi.length() - 1.0).abs() < 1e-4);
                importance += (luminance(radiance) / pdf) as f64;
                // A sample within float rounding of a pixel edge may map
                // back into the neighbouring pixel; elsewhere all agree.
                if (env.pdf(wi) - pdf).abs() > 1e-3 * pdf {
                    at_edges += 1;
                } else {
                    assert!((radiance - env.radiance(wi)).abs().max_element() < 1e-4);
                }
                let d = crate::sampling::sample_uniform_sphere(Vec2::new(rnd(i, 3), rnd(i, 4)));
                uniform += (luminance(env.radiance(d)) / crate::sampling::UNIFORM_SPHERE_PDF) as f64;
            }
            assert!(at_edges < n / 200, "{layout:?}: {at_edges} samples disagree with the density");
            let (importance, uniform) = (importance / n as f64, uniform / n as f64);
            let mean = 4.0 * std::f64::consts::PI * env.mean_luminance as f64;
            assert!((importance - mean).abs() < 0.01 * mean, "{layout:?}: importance {importance} vs {mean}");
            assert!((uniform - mean).abs() < 0.03 * mean, "{layout:?}: uniform {uniform} vs {mean}");
        }
    }

    #[test]
    fn a_black_image_is_never_sampled() {
        let img = Arc::new(EnvironmentImage::new(4, 2, vec![Rgb::ZERO; 8], EnvLayout::LatLong));
        let env = EnvironmentSampler::new(img, Rgb::ONE, Mat3::IDENTITY);
        assert!(env.sample(Vec2::new(0.3, 0.6)).is_none());
        assert_eq!(env.pdf(Vec3::Z), 0.0);
        assert_eq!(env.mean_luminance, 0.0);
    }
}
