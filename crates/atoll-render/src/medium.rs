//! Participating media along path segments: where a segment scatters, what
//! it weighs when it does not, what light the medium emits along it, and
//! the optical depth shadow rays gather. A homogeneous medium's optical
//! depth is its length times σt; a grid medium's comes from its
//! [`DensityGrid`], integrated exactly, so both sample distances by
//! inverting the optical depth (no majorants, no null collisions). A
//! homogeneous medium's emission along a segment is integrated in closed
//! form; a grid's is estimated where the segment scatters.
//!
//! Distances are sampled as in Cycles' spectral MIS, over the three RGB
//! channels: a channel is picked with probability proportional to the
//! path's throughput in it, a distance drawn from its exponential, and the
//! sample weighted by the mixture of the channels' densities. In a grey
//! medium this is plain exponential sampling; in a coloured one no
//! channel's weight can blow up in one step, and weighting the choice by
//! the throughput keeps long walks (subsurface scattering) from
//! multiplying up channels the path has all but lost.

use atoll_scene::{Medium, MediumIndex, Scene};
use glam::Vec3;

use crate::density_grid::DensityGrid;

/// One medium's coefficients as shading reads them: a homogeneous
/// medium's, or the scales of a grid medium's fields (σt ≤ σa + σs times
/// the largest sample).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MediumCoeffs {
    pub sigma_a: Vec3,
    pub sigma_s: Vec3,
    /// Henyey–Greenstein asymmetry.
    pub g: f32,
    /// Emitted radiance per unit absorption.
    pub le: Vec3,
    /// The grid the coefficients come from ([`MediumTable::grids`]), or
    /// `None` for the same everywhere.
    pub grid: Option<u32>,
    /// The interior of a subsurface material ([`Medium::Subsurface`]):
    /// paths walk it without light sampling, which its boundary always
    /// blocks, and leave it by the exit lobe (`stages::shade`).
    pub subsurface: bool,
}

/// A segment through a medium: where it ends, and the radiance the medium
/// emits along it towards its start (to be weighted by the throughput
/// before the segment).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SegmentSample {
    pub end: Segment,
    pub emitted: Vec3,
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

    /// Samples where a segment of `length` scatters, from one uniform
    /// number `u`, picking channels with probabilities `channels`
    /// ([`channel_probabilities`]).
    pub fn sample_uniform_segment(&self, length: f32, u: f32, channels: Vec3) -> Segment {
        let sigma_t = self.sigma_t();
        let (channel, target) = channel_and_depth(u, channels);
        let depth = if sigma_t[channel] > 0.0 { target / sigma_t[channel] } else { f32::INFINITY };
        if depth < length {
            // The same σt at every point: T σs / mix(σt T).
            let transmittance = (-sigma_t * depth).exp();
            let density = (sigma_t * transmittance).dot(channels);
            let weight = if density > 0.0 { transmittance * self.sigma_s / density } else { Vec3::ZERO };
            return Segment::Scatter { t: depth, weight };
        }
        pass(transmittance(sigma_t, length), channels)
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

/// The probabilities with which a segment picks each channel to sample its
/// distance by: proportional to the magnitude of the path's throughput
/// `beta` there (uniform where it has none).
pub fn channel_probabilities(beta: Vec3) -> Vec3 {
    let magnitude = beta.abs();
    let sum = magnitude.x + magnitude.y + magnitude.z;
    if sum > 0.0 && sum.is_finite() {
        magnitude / sum
    } else {
        Vec3::splat(1.0 / 3.0)
    }
}

/// The channel a uniform number `u` picks with probabilities `channels`
/// (its leading share), and the optical depth the rest of it reaches in
/// that channel, `-ln(1 - u')`.
fn channel_and_depth(u: f32, channels: Vec3) -> (usize, f32) {
    let (channel, start) = if u < channels.x || channels.y + channels.z == 0.0 {
        (0, 0.0)
    } else if u < channels.x + channels.y || channels.z == 0.0 {
        (1, channels.x)
    } else {
        (2, channels.x + channels.y)
    };
    let u = ((u - start) / channels[channel]).clamp(0.0, 1.0 - f32::EPSILON);
    (channel, crate::sampling::sample_exponential(u, 1.0))
}

/// A segment passing with `transmittance`, weighted by the mixture's
/// probability of passing with channel probabilities `channels`.
fn pass(transmittance: Vec3, channels: Vec3) -> Segment {
    let passing = transmittance.dot(channels);
    Segment::Pass { weight: if passing > 0.0 { transmittance / passing } else { Vec3::ZERO } }
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
            table.media.push(match medium {
                Medium::Homogeneous(h) | Medium::Subsurface(h) => MediumCoeffs {
                    sigma_a: h.sigma_a,
                    sigma_s: h.sigma_s,
                    g: h.g,
                    le: h.le,
                    grid: None,
                    subsurface: matches!(medium, Medium::Subsurface(_)),
                },
                Medium::Grid(g) => {
                    table.grids.push(DensityGrid::new(g));
                    MediumCoeffs {
                        sigma_a: g.sigma_a.scale,
                        sigma_s: g.sigma_s.scale,
                        g: g.g,
                        le: g.le.scale,
                        grid: Some(table.grids.len() as u32 - 1),
                        subsurface: false,
                    }
                }
            });
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

    /// Whether a grid's coefficients differ by colour from sample to
    /// sample, or its σa and σs read different samples (an `rgbgrid`),
    /// rather than both scaling one density, its first plane (a
    /// `uniformgrid`): the GPU kernels have a lighter specialisation for
    /// the latter, which reads the density there.
    pub fn has_rgb_grids(&self) -> bool {
        self.grids.iter().any(|g| {
            let [a, s, le] = g.fields;
            !(a.source == s.source
                && a.source == atoll_scene::FieldSource::Scalar(0)
                && !matches!(le.source, atoll_scene::FieldSource::Rgb(_)))
        })
    }

    /// Medium `m`'s coefficients; the vacuum's are zero.
    pub fn get(&self, m: MediumIndex) -> &MediumCoeffs {
        &self.media[(m as usize).min(self.media.len() - 1)]
    }

    /// The optical depth of medium `m` along `origin + t · dir`, `t0 <= t < t1`.
    pub fn optical_depth(&self, m: MediumIndex, origin: Vec3, dir: Vec3, t0: f32, t1: f32) -> Vec3 {
        let coeffs = self.get(m);
        if coeffs.sigma_t() == Vec3::ZERO {
            return Vec3::ZERO;
        }
        let scale = dir.length();
        match coeffs.grid {
            None => coeffs.sigma_t() * ((t1 - t0) * scale),
            Some(g) => self.grids[g as usize].integral(origin, dir, t0, t1) * scale,
        }
    }

    /// Where the segment `origin + t · dir`, `0 <= t < t_max`, through
    /// medium `m` scatters, from one uniform number `u`, for a path of
    /// throughput `beta`, and what the medium emits along it; a scattering
    /// distance is in world units.
    pub fn sample_segment(
        &self,
        m: MediumIndex,
        origin: Vec3,
        dir: Vec3,
        t_max: f32,
        u: f32,
        beta: Vec3,
    ) -> SegmentSample {
        let coeffs = self.get(m);
        let scale = dir.length();
        let channels = channel_probabilities(beta);
        let Some(g) = coeffs.grid else {
            let length = t_max * scale;
            return SegmentSample {
                end: coeffs.sample_uniform_segment(length, u, channels),
                emitted: coeffs.emission_over(length),
            };
        };
        let grid = &self.grids[g as usize];
        let (channel, target) = channel_and_depth(u, channels);
        // In units of t: the optical depth over |dir|.
        let target = target / scale;
        let total = grid.integral(origin, dir, 0.0, t_max);
        if target < total[channel] {
            if let Some((t, depth)) = grid.invert(origin, dir, 0.0, t_max, channel, target) {
                // The mixture's density of stopping at t, and what the
                // medium scatters and emits there.
                let at = grid.point(origin + dir * t);
                let transmittance = (-depth * scale).exp();
                let density = ((at.sigma_a + at.sigma_s) * transmittance).dot(channels);
                let (weight, emitted) = if density > 0.0 {
                    (transmittance * at.sigma_s / density, transmittance * at.emission / density)
                } else {
                    (Vec3::ZERO, Vec3::ZERO)
                };
                return SegmentSample { end: Segment::Scatter { t: t * scale, weight }, emitted };
            }
        }
        SegmentSample { end: pass((-total * scale).exp(), channels), emitted: Vec3::ZERO }
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
    /// medium (the estimator is unbiased channel by channel), whatever the
    /// throughput the channels are picked by.
    #[test]
    fn segments_are_unbiased_per_channel() {
        for beta in [Vec3::ONE, Vec3::new(0.9, 0.05, 0.3), Vec3::new(0.0, 2.0, 0.0)] {
            segments_are_unbiased_with(channel_probabilities(beta));
        }
    }

    fn segments_are_unbiased_with(channels: Vec3) {
        let m = MediumCoeffs {
            sigma_a: Vec3::new(0.2, 0.5, 1.0),
            sigma_s: Vec3::new(1.0, 0.3, 0.05),
            ..Default::default()
        };
        let length = 1.7;
        let n = 200_000;
        let (mut passed, mut scattered) = (Vec3::ZERO, Vec3::ZERO);
        for i in 0..n {
            match m.sample_uniform_segment(length, (i as f32 + 0.5) / n as f32, channels) {
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
        // A channel never picked is estimated by the others' samples alone.
        let (passed, expected_pass) = (passed * channels.signum(), expected_pass * channels.signum());
        let (scattered, expected_scatter) =
            (scattered * channels.signum(), expected_scatter * channels.signum());
        assert!((passed - expected_pass).abs().max_element() < 2e-3, "{passed} vs {expected_pass}");
        assert!(
            (scattered - expected_scatter).abs().max_element() < 2e-3,
            "{scattered} vs {expected_scatter}"
        );
    }

    #[test]
    fn grey_media_weigh_their_albedo() {
        let m = grey(0.25, 0.75);
        let uniform = Vec3::splat(1.0 / 3.0);
        match m.sample_uniform_segment(f32::INFINITY, 0.4, uniform) {
            Segment::Scatter { weight, .. } => {
                assert!((weight - Vec3::splat(0.75)).abs().max_element() < 1e-6)
            }
            other => panic!("{other:?}"),
        }
        // Nothing escapes an endless medium; a vacuum channel always passes.
        let clear_red = MediumCoeffs { sigma_s: Vec3::new(0.0, 1.0, 1.0), ..Default::default() };
        match clear_red.sample_uniform_segment(f32::INFINITY, 0.1, uniform) {
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

    /// Through an `rgbgrid` whose σa, σs and Le vary by colour and place,
    /// the expected weights of passing and scattering, and the expected
    /// emission, equal the transmittance, ∫ T σs dt and ∫ T σa Le dt by
    /// fine quadrature, channel by channel.
    #[test]
    fn grid_segments_and_emission_are_unbiased_per_channel() {
        use atoll_scene::{FieldSource, GridField, GridMedium};
        let values: Vec<f32> = (0..3 * 2 * 2 * 9).map(|i| ((i * 7) % 11) as f32 * 0.15).collect();
        let medium = GridMedium {
            resolution: [3, 2, 2],
            channels: 9,
            values,
            sigma_a: GridField { scale: Vec3::splat(1.5), source: FieldSource::Rgb(0) },
            sigma_s: GridField { scale: Vec3::splat(1.5), source: FieldSource::Rgb(3) },
            le: GridField { scale: Vec3::splat(2.0), source: FieldSource::Rgb(6) },
            g: 0.0,
            lo: Vec3::new(-1.0, -0.5, -0.5),
            hi: Vec3::new(1.0, 0.5, 0.5),
            world_to_medium: glam::Affine3A::IDENTITY,
        };
        let table = MediumTable {
            media: vec![MediumCoeffs::default(), {
                let mut c = MediumCoeffs {
                    sigma_a: Vec3::splat(1.5),
                    sigma_s: Vec3::splat(1.5),
                    ..Default::default()
                };
                c.le = Vec3::splat(2.0);
                c.grid = Some(0);
                c
            }],
            grids: vec![DensityGrid::new(&medium)],
            ..Default::default()
        };
        let grid = &table.grids[0];
        let (origin, dir, t_max) = (Vec3::new(-1.5, 0.1, -0.2), Vec3::new(2.0, 0.05, 0.2), 1.4);
        // Fine quadrature of the three integrals (in world units: |dir| per t).
        let steps = 50_000;
        let h = t_max / steps as f32;
        let speed = dir.length();
        let (mut depth, mut scattered, mut emitted) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
        for i in 0..steps {
            let p = origin + dir * ((i as f32 + 0.5) * h);
            let at = grid.point(p);
            let sigma_t = at.sigma_a + at.sigma_s;
            let step = h * speed;
            let t = (-(depth + sigma_t * (0.5 * step))).exp();
            scattered += t * at.sigma_s * step;
            emitted += t * at.emission * step;
            depth += sigma_t * step;
        }
        let passing = (-depth).exp();
        assert!(depth.min_element() > 0.3, "the segment misses the grid: {depth}");
        let n = 200_000;
        let (mut pass_sum, mut scatter_sum, mut emission_sum) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
        for i in 0..n {
            let s = table.sample_segment(1, origin, dir, t_max, (i as f32 + 0.5) / n as f32, Vec3::ONE);
            emission_sum += s.emitted;
            match s.end {
                Segment::Pass { weight } => pass_sum += weight,
                Segment::Scatter { t, weight } => {
                    assert!(t > 0.0 && t < t_max * speed);
                    scatter_sum += weight;
                }
            }
        }
        let n = n as f32;
        for (what, got, want) in [
            ("passing", pass_sum / n, passing),
            ("scattering", scatter_sum / n, scattered),
            ("emission", emission_sum / n, emitted),
        ] {
            assert!(
                (got - want).abs().max_element() < 3e-3 * want.max_element().max(1.0),
                "{what}: {got} vs {want}"
            );
        }
        // Shadow rays see the same depth.
        let shadow = table.optical_depth(1, origin, dir, 0.0, t_max);
        assert!((shadow - depth).abs().max_element() < 1e-3 * depth.max_element(), "{shadow} vs {depth}");
    }
}
