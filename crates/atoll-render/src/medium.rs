//! Participating media along path segments: where a segment scatters, what
//! it weighs when it does not, what light the medium emits along it, and
//! the optical depth shadow rays gather. A homogeneous medium has density
//! 1 everywhere; a grid medium's density comes from its [`DensityGrid`],
//! integrated exactly, so both sample distances by inverting the optical
//! depth (no majorants, no null collisions).
//!
//! Distances are sampled as in Cycles' and pbrt-v4's spectral MIS, over the
//! three RGB channels: a channel is picked uniformly, a distance drawn from
//! its exponential, and the sample weighted by the mixture of the three
//! channels' densities. In a grey medium this is plain exponential
//! sampling; in a coloured one no channel's weight can blow up.

use atoll_scene::{Medium, MediumIndex, Scene};
use glam::Vec3;

use crate::density_grid::DensityGrid;

/// One medium's coefficients as shading reads them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MediumCoeffs {
    pub sigma_a: Vec3,
    pub sigma_s: Vec3,
    /// Henyey–Greenstein asymmetry.
    pub g: f32,
    /// Emitted radiance per unit absorption.
    pub le: Vec3,
    /// The density grid scaling σa and σs ([`MediumTable::grids`]), or
    /// `None` for density 1 everywhere.
    pub grid: Option<u32>,
}

/// Where a segment through a medium ends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Segment {
    /// It scatters at distance `t`; the path's throughput is multiplied by
    /// `weight` (transmittance × σs / density).
    Scatter { t: f32, weight: Vec3 },
    /// It reaches its end (the surface hit, or infinity); the throughput is
    /// multiplied by `weight` (transmittance / probability of passing).
    Pass { weight: Vec3 },
}

impl MediumCoeffs {
    /// The extinction cross section σt = σa + σs.
    pub fn sigma_t(&self) -> Vec3 {
        self.sigma_a + self.sigma_s
    }

    /// Samples where a segment scatters, from one uniform number `u`.
    /// `total` is the segment's ∫ density ds (world units; its length
    /// where the density is 1, infinite for a ray escaping an endless
    /// medium); `reach(d)` is the distance along it where that integral
    /// reaches `d`, `None` past its end.
    pub fn sample_segment(&self, u: f32, total: f32, reach: impl FnOnce(f32) -> Option<f32>) -> Segment {
        let sigma_t = self.sigma_t();
        // The channel from the leading third of `u`, the distance from the rest.
        let scaled = u * 3.0;
        let channel = (scaled as usize).min(2);
        let u = (scaled - channel as f32).clamp(0.0, 1.0 - f32::EPSILON);
        // The ∫ density where the chosen channel's optical depth is -ln(1 - u).
        let depth = if sigma_t[channel] > 0.0 {
            crate::sampling::sample_exponential(u, sigma_t[channel])
        } else {
            f32::INFINITY
        };
        if depth < total {
            if let Some(t) = reach(depth) {
                // The density at t cancels between σs and the mixture's pdf.
                let transmittance = (-sigma_t * depth).exp();
                let density = (sigma_t * transmittance).dot(Vec3::splat(1.0 / 3.0));
                let weight = if density > 0.0 { transmittance * self.sigma_s / density } else { Vec3::ZERO };
                return Segment::Scatter { t, weight };
            }
        }
        let transmittance = transmittance(sigma_t, total);
        let passing = transmittance.dot(Vec3::splat(1.0 / 3.0));
        let weight = if passing > 0.0 { transmittance / passing } else { Vec3::ZERO };
        Segment::Pass { weight }
    }

    /// [`MediumCoeffs::sample_segment`] where the density is 1: the
    /// segment is `length` long.
    pub fn sample_uniform_segment(&self, length: f32, u: f32) -> Segment {
        self.sample_segment(u, length, |d| (d < length).then_some(d))
    }

    /// The radiance the medium emits towards a segment's start over
    /// `length` of it: ∫ T(t) σa Le dt, analytically.
    pub fn emission_over(&self, length: f32) -> Vec3 {
        if self.le == Vec3::ZERO {
            return Vec3::ZERO;
        }
        let sigma_t = self.sigma_t();
        let per_channel = |a: f32, le: f32, st: f32| {
            if a == 0.0 || le == 0.0 {
                0.0
            } else if st * length < 1e-4 {
                a * le * length
            } else {
                a * le * (1.0 - (-st * length).exp()) / st
            }
        };
        Vec3::new(
            per_channel(self.sigma_a.x, self.le.x, sigma_t.x),
            per_channel(self.sigma_a.y, self.le.y, sigma_t.y),
            per_channel(self.sigma_a.z, self.le.z, sigma_t.z),
        )
    }
}

/// `exp(-σt · length)` per channel, 1 where σt is 0 even over an infinite length.
pub fn transmittance(sigma_t: Vec3, length: f32) -> Vec3 {
    let one = |s: f32| if s == 0.0 { 1.0 } else { (-s * length).exp() };
    Vec3::new(one(sigma_t.x), one(sigma_t.y), one(sigma_t.z))
}

/// A frame's media, by [`MediumIndex`] (entry 0 is the vacuum).
#[derive(Clone, Debug, PartialEq)]
pub struct MediumTable {
    pub media: Vec<MediumCoeffs>,
    /// The grid media's densities, by [`MediumCoeffs::grid`].
    pub grids: Vec<DensityGrid>,
    /// The medium camera rays start in.
    pub camera: MediumIndex,
    /// How long a shadow ray towards a light at infinity is made when the
    /// scene has media (pbrt's twice the scene's bounding radius), so that
    /// its optical depth is finite.
    pub shadow_reach: f32,
}

impl Default for MediumTable {
    fn default() -> Self {
        MediumTable {
            media: vec![MediumCoeffs::default()],
            grids: Vec::new(),
            camera: 0,
            shadow_reach: f32::INFINITY,
        }
    }
}

impl MediumTable {
    pub fn new(scene: &Scene) -> Self {
        let mut table = MediumTable { camera: scene.settings.camera_medium, ..Default::default() };
        for medium in &scene.media {
            let (h, grid) = match medium {
                Medium::Homogeneous(h) => (h, None),
                Medium::Grid(g) => {
                    table.grids.push(DensityGrid::new(
                        g.resolution,
                        g.density.clone(),
                        g.lo,
                        g.hi,
                        g.world_to_medium,
                    ));
                    (&g.coefficients, Some(table.grids.len() as u32 - 1))
                }
            };
            table.media.push(MediumCoeffs { sigma_a: h.sigma_a, sigma_s: h.sigma_s, g: h.g, le: h.le, grid });
        }
        if table.any() {
            let (lo, hi) = scene.world_bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
            table.shadow_reach = (hi - lo).length().max(1e-3) * 1.01;
        }
        table
    }

    /// Whether the scene has any medium (shading and shadows do more then).
    pub fn any(&self) -> bool {
        self.media.len() > 1
    }

    /// Medium `m`'s coefficients; the vacuum's are zero.
    pub fn get(&self, m: MediumIndex) -> &MediumCoeffs {
        &self.media[(m as usize).min(self.media.len() - 1)]
    }

    /// ∫ density ds in world units along `origin + t · dir`, `t0 <= t <
    /// t1`, through medium `m` (the length, where the density is 1).
    pub fn density_length(&self, m: MediumIndex, origin: Vec3, dir: Vec3, t0: f32, t1: f32) -> f32 {
        let scale = dir.length();
        match self.get(m).grid {
            None => (t1 - t0) * scale,
            Some(g) => self.grids[g as usize].integral(origin, dir, t0, t1) * scale,
        }
    }

    /// The optical depth of medium `m` along `origin + t · dir`, `t0 <= t < t1`.
    pub fn optical_depth(&self, m: MediumIndex, origin: Vec3, dir: Vec3, t0: f32, t1: f32) -> Vec3 {
        let sigma_t = self.get(m).sigma_t();
        if sigma_t == Vec3::ZERO {
            return Vec3::ZERO;
        }
        sigma_t * self.density_length(m, origin, dir, t0, t1)
    }

    /// Where the segment `origin + t · dir`, `0 <= t < t_max`, through
    /// medium `m` scatters, from one uniform number `u`; a scattering
    /// distance is in world units.
    pub fn sample_segment(&self, m: MediumIndex, origin: Vec3, dir: Vec3, t_max: f32, u: f32) -> Segment {
        let coeffs = self.get(m);
        let scale = dir.length();
        match coeffs.grid {
            None => coeffs.sample_uniform_segment(t_max * scale, u),
            Some(g) => {
                let grid = &self.grids[g as usize];
                let total = grid.integral(origin, dir, 0.0, t_max) * scale;
                coeffs.sample_segment(u, total, |d| {
                    grid.invert(origin, dir, 0.0, t_max, d / scale).map(|t| t * scale)
                })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grey(sigma_a: f32, sigma_s: f32) -> MediumCoeffs {
        MediumCoeffs { sigma_a: Vec3::splat(sigma_a), sigma_s: Vec3::splat(sigma_s), ..Default::default() }
    }

    /// The expected weight of passing plus scattering reproduces the
    /// transmittance and the scattered fraction, per channel, in a coloured
    /// medium (the estimator is unbiased channel by channel).
    #[test]
    fn segments_are_unbiased_per_channel() {
        let m = MediumCoeffs {
            sigma_a: Vec3::new(0.2, 0.5, 1.0),
            sigma_s: Vec3::new(1.0, 0.3, 0.05),
            ..Default::default()
        };
        let length = 1.7;
        let n = 200_000;
        let (mut passed, mut scattered) = (Vec3::ZERO, Vec3::ZERO);
        for i in 0..n {
            match m.sample_uniform_segment(length, (i as f32 + 0.5) / n as f32) {
                Segment::Pass { weight } => passed += weight,
                Segment::Scatter { t, weight } => {
                    assert!(t >= 0.0 && t < length);
                    scattered += weight;
                }
            }
        }
        let sigma_t = m.sigma_t();
        let expected_pass = transmittance(sigma_t, length);
        // ∫0^L T(t) σs dt = σs (1 - T(L)) / σt.
        let expected_scatter = m.sigma_s * (Vec3::ONE - expected_pass) / sigma_t;
        let (passed, scattered) = (passed / n as f32, scattered / n as f32);
        assert!((passed - expected_pass).abs().max_element() < 2e-3, "{passed} vs {expected_pass}");
        assert!(
            (scattered - expected_scatter).abs().max_element() < 2e-3,
            "{scattered} vs {expected_scatter}"
        );
    }

    #[test]
    fn grey_media_weigh_their_albedo() {
        let m = grey(0.25, 0.75);
        match m.sample_uniform_segment(f32::INFINITY, 0.4) {
            Segment::Scatter { weight, .. } => {
                assert!((weight - Vec3::splat(0.75)).abs().max_element() < 1e-6)
            }
            other => panic!("{other:?}"),
        }
        // Nothing escapes an endless medium; a vacuum channel always passes.
        let clear_red = MediumCoeffs { sigma_s: Vec3::new(0.0, 1.0, 1.0), ..Default::default() };
        match clear_red.sample_uniform_segment(f32::INFINITY, 0.1) {
            Segment::Pass { weight } => assert_eq!(weight, Vec3::new(3.0, 0.0, 0.0)),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn emission_integrates_along_the_segment() {
        let m = MediumCoeffs { le: Vec3::splat(2.0), ..grey(0.5, 0.5) };
        let e = m.emission_over(3.0);
        let expected = 0.5 * 2.0 * (1.0 - (-3.0f32).exp());
        assert!((e.x - expected).abs() < 1e-5);
        assert_eq!(MediumCoeffs { le: Vec3::ONE, ..grey(0.5, 0.0) }.emission_over(0.0), Vec3::ZERO);
        assert!(
            (MediumCoeffs { le: Vec3::ONE, ..grey(0.5, 0.0) }.emission_over(f32::INFINITY).x - 1.0).abs()
                < 1e-6
        );
    }
}
