//! Integrals of a grid medium's extinction along rays, exactly: pbrt-v4's
//! `SampledGrid` interpolates its samples trilinearly (sample `i` sits at
//! `(i + 0.5) / n` of the bounds, missing neighbours count as 0), so along
//! a ray, inside one cell of the sample lattice, each channel is a product
//! of three linear functions of `t`: a cubic, which two-point
//! Gauss–Legendre quadrature integrates exactly; σt is a sum of such
//! channels (a `uniformgrid`'s density times σt, an `rgbgrid`'s σa and σs
//! per colour). Walking the cells the ray
//! crosses (Amanatides & Woo's DDA) gives the optical depth of any segment
//! without noise, and inverting it gives exact distance sampling (regular
//! tracking), so grid media need neither delta nor ratio tracking's
//! majorants. The CUDA kernels (`kernels/media.cuh`) walk the same cells.

use atoll_scene::{FieldSource, GridField, GridMedium};
use glam::{Affine3A, Vec3};

/// A grid medium's samples placed in the world, with the fields that read them.
#[derive(Clone, Debug, PartialEq)]
pub struct DensityGrid {
    /// Samples per axis.
    pub resolution: [u32; 3],
    /// Values per sample.
    pub channels: u32,
    /// `channels` planes of samples ([`GridMedium::values`]).
    pub values: Vec<f32>,
    /// σa, σs and Le ([`GridMedium`]'s fields).
    pub fields: [GridField; 3],
    /// World space to the grid's sample lattice: sample `i` at integer `i`,
    /// the bounds from -0.5 to `n - 0.5`.
    pub world_to_lattice: Affine3A,
}

/// The coefficients of a grid medium at one point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GridPoint {
    pub sigma_a: Vec3,
    pub sigma_s: Vec3,
    /// σa · Le: the radiance emitted per unit length.
    pub emission: Vec3,
}

/// Abscissa of two-point Gauss–Legendre quadrature on [-1, 1]: 1/√3.
const GAUSS: f32 = 0.577_350_26;

impl DensityGrid {
    /// The grid of `medium`, placed by its transform.
    pub fn new(medium: &GridMedium) -> Self {
        let n =
            Vec3::new(medium.resolution[0] as f32, medium.resolution[1] as f32, medium.resolution[2] as f32);
        let scale = n / (medium.hi - medium.lo);
        let to_lattice = Affine3A::from_translation(Vec3::splat(-0.5))
            * Affine3A::from_scale(scale)
            * Affine3A::from_translation(-medium.lo);
        DensityGrid {
            resolution: medium.resolution,
            channels: medium.channels,
            values: medium.values.clone(),
            fields: [medium.sigma_a, medium.sigma_s, medium.le],
            world_to_lattice: to_lattice * medium.world_to_medium,
        }
    }

    /// Channel `k` of sample `(x, y, z)`, 0 outside the grid.
    fn sample(&self, x: i32, y: i32, z: i32, k: u32) -> f32 {
        let [nx, ny, nz] = self.resolution.map(|n| n as i32);
        if x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz {
            return 0.0;
        }
        let plane = (nx * ny * nz) as usize;
        self.values[k as usize * plane + ((z * ny + y) * nx + x) as usize]
    }

    /// Channel `k` at lattice point `s` inside cell `c` (trilinear).
    fn channel_in(&self, c: [i32; 3], s: Vec3, k: u32) -> f32 {
        let d = s - Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32);
        let v = |i, j, l| self.sample(c[0] + i, c[1] + j, c[2] + l, k);
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let x00 = lerp(v(0, 0, 0), v(1, 0, 0), d.x);
        let x10 = lerp(v(0, 1, 0), v(1, 1, 0), d.x);
        let x01 = lerp(v(0, 0, 1), v(1, 0, 1), d.x);
        let x11 = lerp(v(0, 1, 1), v(1, 1, 1), d.x);
        lerp(lerp(x00, x10, d.y), lerp(x01, x11, d.y), d.z)
    }

    /// What `source` interpolates at lattice point `s` of cell `c`.
    fn source_in(&self, source: FieldSource, c: [i32; 3], s: Vec3) -> Vec3 {
        match source {
            FieldSource::Constant => Vec3::ONE,
            FieldSource::Scalar(k) => Vec3::splat(self.channel_in(c, s, k)),
            FieldSource::Rgb(k) => Vec3::new(
                self.channel_in(c, s, k),
                self.channel_in(c, s, k + 1),
                self.channel_in(c, s, k + 2),
            ),
        }
    }

    /// σt = σa + σs at lattice point `s` of cell `c` (one lookup where
    /// both scale the same samples, as a `uniformgrid`'s density).
    fn extinction_in(&self, c: [i32; 3], s: Vec3) -> Vec3 {
        let [a, sc, _] = self.fields;
        if a.source == sc.source {
            return (a.scale + sc.scale) * self.source_in(a.source, c, s);
        }
        a.scale * self.source_in(a.source, c, s) + sc.scale * self.source_in(sc.source, c, s)
    }

    /// The lattice point of world point `p` and its cell, `None` outside the bounds.
    fn locate(&self, p: Vec3) -> Option<([i32; 3], Vec3)> {
        let s = self.world_to_lattice.transform_point3(p);
        let n = Vec3::new(self.resolution[0] as f32, self.resolution[1] as f32, self.resolution[2] as f32);
        if s.cmplt(Vec3::splat(-0.5)).any() || s.cmpgt(n - 0.5).any() {
            return None;
        }
        let c = s.floor();
        Some(([c.x as i32, c.y as i32, c.z as i32], s))
    }

    /// The coefficients at world point `p` (pbrt's `SamplePoint`; none
    /// outside the bounds).
    pub fn point(&self, p: Vec3) -> GridPoint {
        let Some((c, s)) = self.locate(p) else { return GridPoint::default() };
        let field = |f: &GridField| f.scale * self.source_in(f.source, c, s);
        let [a, sc, le] = &self.fields;
        let sigma_a = field(a);
        GridPoint { sigma_a, sigma_s: field(sc), emission: sigma_a * field(le) }
    }

    /// σt at world point `p` (0 outside the bounds).
    pub fn extinction(&self, p: Vec3) -> Vec3 {
        self.locate(p).map_or(Vec3::ZERO, |(c, s)| self.extinction_in(c, s))
    }

    /// Walks the cells the ray `origin + t · dir` crosses for `t0 <= t <
    /// t1`, calling `cell(cell, s0, ds, ta, tb)` for each piece: the
    /// lattice point at `t` is `s0 + t · ds`. `cell` returns false to stop.
    fn walk(
        &self,
        origin: Vec3,
        dir: Vec3,
        t0: f32,
        t1: f32,
        mut cell: impl FnMut([i32; 3], Vec3, Vec3, f32, f32) -> bool,
    ) {
        let s0 = self.world_to_lattice.transform_point3(origin);
        let ds = self.world_to_lattice.transform_vector3(dir);
        let n = Vec3::new(self.resolution[0] as f32, self.resolution[1] as f32, self.resolution[2] as f32);
        // Clip to the bounds, the lattice box [-0.5, n - 0.5].
        let (mut ta, mut tb) = (t0, t1);
        for a in 0..3 {
            let (lo, hi) = ((-0.5 - s0[a]) / ds[a], (n[a] - 0.5 - s0[a]) / ds[a]);
            if ds[a] == 0.0 {
                if s0[a] < -0.5 || s0[a] > n[a] - 0.5 {
                    return;
                }
                continue;
            }
            ta = ta.max(lo.min(hi));
            tb = tb.min(lo.max(hi));
        }
        if ta.is_nan() || tb.is_nan() || ta >= tb {
            return;
        }
        // Amanatides–Woo from the cell holding the middle of the first step.
        let start = s0 + ds * ta;
        let mut c = [0i32; 3];
        let (mut next, mut step, mut delta) = ([f32::INFINITY; 3], [0i32; 3], [f32::INFINITY; 3]);
        for a in 0..3 {
            c[a] = (start[a].floor() as i32).clamp(-1, self.resolution[a] as i32 - 1);
            if ds[a] > 0.0 {
                step[a] = 1;
                next[a] = (c[a] as f32 + 1.0 - s0[a]) / ds[a];
                delta[a] = 1.0 / ds[a];
            } else if ds[a] < 0.0 {
                step[a] = -1;
                next[a] = (c[a] as f32 - s0[a]) / ds[a];
                delta[a] = -1.0 / ds[a];
            }
        }
        let mut t = ta;
        while t < tb {
            let a = if next[0] <= next[1] && next[0] <= next[2] {
                0
            } else if next[1] <= next[2] {
                1
            } else {
                2
            };
            let end = next[a].min(tb);
            if end > t && !cell(c, s0, ds, t, end) {
                return;
            }
            t = end;
            c[a] += step[a];
            next[a] += delta[a];
            if c[a] < -1 || c[a] >= self.resolution[a] as i32 {
                return;
            }
        }
    }

    /// ∫ σt dt over `ta..tb` inside cell `c` (exact: a cubic per channel).
    fn cell_integral(&self, c: [i32; 3], s0: Vec3, ds: Vec3, ta: f32, tb: f32) -> Vec3 {
        let (mid, half) = (0.5 * (ta + tb), 0.5 * (tb - ta));
        let at = |t: f32| self.extinction_in(c, s0 + ds * t);
        half * (at(mid - half * GAUSS) + at(mid + half * GAUSS))
    }

    /// ∫ σt dt along `origin + t · dir` for `t0 <= t < t1`, per channel
    /// (in units of `t`: times `|dir|` for the optical depth).
    pub fn integral(&self, origin: Vec3, dir: Vec3, t0: f32, t1: f32) -> Vec3 {
        let mut sum = Vec3::ZERO;
        self.walk(origin, dir, t0, t1, |c, s0, ds, ta, tb| {
            sum += self.cell_integral(c, s0, ds, ta, tb);
            true
        });
        sum
    }

    /// The `t` in `t0..t1` where channel `channel` of
    /// [`DensityGrid::integral`] from `t0` reaches `target`, with the
    /// whole integral up to it; `None` when the segment holds less.
    pub fn invert(
        &self,
        origin: Vec3,
        dir: Vec3,
        t0: f32,
        t1: f32,
        channel: usize,
        target: f32,
    ) -> Option<(f32, Vec3)> {
        let mut sum = Vec3::ZERO;
        let mut found = None;
        self.walk(origin, dir, t0, t1, |c, s0, ds, ta, tb| {
            let here = self.cell_integral(c, s0, ds, ta, tb);
            if sum[channel] + here[channel] < target {
                sum += here;
                return true;
            }
            // Bisection on the exact partial integral, which grows with t.
            let (mut lo, mut hi) = (ta, tb);
            for _ in 0..30 {
                let t = 0.5 * (lo + hi);
                if sum[channel] + self.cell_integral(c, s0, ds, ta, t)[channel] < target {
                    lo = t;
                } else {
                    hi = t;
                }
            }
            let t = 0.5 * (lo + hi);
            found = Some((t, sum + self.cell_integral(c, s0, ds, ta, t)));
            false
        });
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `uniformgrid` of `values` with σa 0.25 and σs 0.75.
    fn density_grid(resolution: [u32; 3], values: Vec<f32>, lo: Vec3, hi: Vec3, m: Affine3A) -> DensityGrid {
        let field = |scale| GridField { scale: Vec3::splat(scale), source: FieldSource::Scalar(0) };
        DensityGrid::new(&GridMedium {
            resolution,
            channels: 1,
            values,
            sigma_a: field(0.25),
            sigma_s: field(0.75),
            le: GridField::constant(Vec3::ZERO),
            g: 0.0,
            lo,
            hi,
            world_to_medium: m,
        })
    }

    fn grid() -> DensityGrid {
        // 3 × 2 × 2 samples with varied values over [-1, 2] × [0, 1] × [0, 2].
        let values = (0..12).map(|i| ((i * 7) % 5) as f32 * 0.5 + 0.25).collect();
        let m = Affine3A::from_rotation_y(0.3).inverse();
        density_grid([3, 2, 2], values, Vec3::new(-1.0, 0.0, 0.0), Vec3::new(2.0, 1.0, 2.0), m)
    }

    /// An `rgbgrid` over the same box: σa per colour from the samples, σs
    /// constant 0.5, so that each channel's integral differs.
    fn rgb_grid() -> DensityGrid {
        let values = (0..36).map(|i| ((i * 5) % 7) as f32 * 0.3).collect();
        DensityGrid::new(&GridMedium {
            resolution: [3, 2, 2],
            channels: 3,
            values,
            sigma_a: GridField { scale: Vec3::splat(2.0), source: FieldSource::Rgb(0) },
            sigma_s: GridField::constant(Vec3::splat(0.5)),
            le: GridField::constant(Vec3::ZERO),
            g: 0.0,
            lo: Vec3::new(-1.0, 0.0, 0.0),
            hi: Vec3::new(2.0, 1.0, 2.0),
            world_to_medium: Affine3A::from_rotation_x(-0.2),
        })
    }

    /// The walked integral equals fine midpoint quadrature of the lookups.
    #[test]
    fn integrals_match_fine_quadrature() {
        for g in [grid(), rgb_grid()] {
            integrals_match_fine_quadrature_of(&g);
        }
    }

    fn integrals_match_fine_quadrature_of(g: &DensityGrid) {
        for (o, d) in [
            (Vec3::new(-3.0, 0.4, 0.7), Vec3::new(1.0, 0.05, 0.1)),
            (Vec3::new(0.2, -1.0, 0.3), Vec3::new(0.1, 1.0, 0.35)),
            (Vec3::new(3.0, 2.0, 3.0), Vec3::new(-1.0, -0.6, -0.9) * 2.5),
            (Vec3::new(0.5, 0.5, 1.0), Vec3::new(0.0, 0.0, 1.0)),
        ] {
            let (t0, t1) = (0.0, 6.0);
            let n = 200_000;
            let h = (t1 - t0) / n as f32;
            let fine = (0..n)
                .map(|i| g.extinction(o + d * (t0 + (i as f32 + 0.5) * h)).as_dvec3() * h as f64)
                .sum::<glam::DVec3>();
            let exact = g.integral(o, d, t0, t1);
            for k in 0..3 {
                let (exact, fine) = (exact[k], fine[k]);
                assert!(fine > 0.1, "the ray {o} {d} misses the grid");
                assert!((exact as f64 - fine).abs() < 1e-3 * fine, "{exact} vs {fine} for {o} {d}");
            }
            // Inverting gives back the distance to half the depth, channel by channel.
            for k in 0..3 {
                let (t, at) = g.invert(o, d, t0, t1, k, exact[k] * 0.5).unwrap();
                let to_t = g.integral(o, d, t0, t);
                assert!((to_t[k] - 0.5 * exact[k]).abs() < 1e-4 * exact[k], "{t}");
                assert!((to_t - at).abs().max_element() < 1e-4 * exact.max_element(), "{to_t} vs {at}");
                assert_eq!(g.invert(o, d, t0, t1, k, exact[k] * 1.01), None);
            }
        }
    }

    #[test]
    fn lookups_follow_pbrts_sample_placement() {
        let g =
            density_grid([2, 1, 1], vec![1.0, 3.0], Vec3::ZERO, Vec3::new(2.0, 1.0, 1.0), Affine3A::IDENTITY);
        // Samples at x = 0.5 and 1.5; halfway between them, their mean;
        // towards the edges, a ramp down to the missing neighbours.
        let density = |x: f32| g.extinction(Vec3::new(x, 0.5, 0.5)).x;
        assert_eq!(density(0.5), 1.0);
        assert_eq!(density(1.0), 2.0);
        assert_eq!(density(1.5), 3.0);
        assert_eq!(density(1.75), 2.25);
        assert_eq!(density(2.5), 0.0);
        let p = g.point(Vec3::new(1.0, 0.5, 0.5));
        assert_eq!((p.sigma_a, p.sigma_s), (Vec3::splat(0.5), Vec3::splat(1.5)));
    }
}
