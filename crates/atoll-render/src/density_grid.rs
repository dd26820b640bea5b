//! Integrals of a voxel density grid along rays, exactly: pbrt-v4's
//! `SampledGrid` interpolates its samples trilinearly (sample `i` sits at
//! `(i + 0.5) / n` of the bounds, missing neighbours count as 0), so along
//! a ray, inside one cell of the sample lattice, the density is a product
//! of three linear functions of `t`: a cubic, which two-point
//! Gauss–Legendre quadrature integrates exactly. Walking the cells the ray
//! crosses (Amanatides & Woo's DDA) gives the optical depth of any segment
//! without noise, and inverting it gives exact distance sampling (regular
//! tracking), so grid media need neither delta nor ratio tracking's
//! majorants. The CUDA kernels (`kernels/media.cuh`) walk the same cells.

use glam::{Affine3A, Vec3};

/// A density grid placed in the world.
#[derive(Clone, Debug, PartialEq)]
pub struct DensityGrid {
    /// Samples per axis.
    pub resolution: [u32; 3],
    /// `resolution[0] * resolution[1] * resolution[2]` samples, x fastest.
    pub values: Vec<f32>,
    /// World space to the grid's sample lattice: sample `i` at integer `i`,
    /// the bounds from -0.5 to `n - 0.5`.
    pub world_to_lattice: Affine3A,
}

/// Abscissa of two-point Gauss–Legendre quadrature on [-1, 1]: 1/√3.
const GAUSS: f32 = 0.577_350_26;

impl DensityGrid {
    /// A grid of `values` filling the medium-space box `lo`..`hi`, placed
    /// by `world_to_medium`.
    pub fn new(
        resolution: [u32; 3],
        values: Vec<f32>,
        lo: Vec3,
        hi: Vec3,
        world_to_medium: Affine3A,
    ) -> Self {
        let n = Vec3::new(resolution[0] as f32, resolution[1] as f32, resolution[2] as f32);
        let scale = n / (hi - lo);
        let to_lattice = Affine3A::from_translation(Vec3::splat(-0.5))
            * Affine3A::from_scale(scale)
            * Affine3A::from_translation(-lo);
        DensityGrid { resolution, values, world_to_lattice: to_lattice * world_to_medium }
    }

    /// Sample `(x, y, z)`, 0 outside the grid.
    fn sample(&self, x: i32, y: i32, z: i32) -> f32 {
        let [nx, ny, nz] = self.resolution.map(|n| n as i32);
        if x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz {
            return 0.0;
        }
        self.values[((z * ny + y) * nx + x) as usize]
    }

    /// The density at lattice point `s` inside cell `c` (trilinear).
    fn density_in(&self, c: [i32; 3], s: Vec3) -> f32 {
        let d = s - Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32);
        let v = |i, j, k| self.sample(c[0] + i, c[1] + j, c[2] + k);
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let x00 = lerp(v(0, 0, 0), v(1, 0, 0), d.x);
        let x10 = lerp(v(0, 1, 0), v(1, 1, 0), d.x);
        let x01 = lerp(v(0, 0, 1), v(1, 0, 1), d.x);
        let x11 = lerp(v(0, 1, 1), v(1, 1, 1), d.x);
        lerp(lerp(x00, x10, d.y), lerp(x01, x11, d.y), d.z)
    }

    /// The density at world point `p` (pbrt's `SampledGrid::Lookup`; 0
    /// outside the bounds).
    pub fn density(&self, p: Vec3) -> f32 {
        let s = self.world_to_lattice.transform_point3(p);
        let n = Vec3::new(self.resolution[0] as f32, self.resolution[1] as f32, self.resolution[2] as f32);
        if s.cmplt(Vec3::splat(-0.5)).any() || s.cmpgt(n - 0.5).any() {
            return 0.0;
        }
        let c = s.floor();
        self.density_in([c.x as i32, c.y as i32, c.z as i32], s)
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

    /// ∫ density dt over `ta..tb` inside cell `c` (exact: a cubic).
    fn cell_integral(&self, c: [i32; 3], s0: Vec3, ds: Vec3, ta: f32, tb: f32) -> f32 {
        let (mid, half) = (0.5 * (ta + tb), 0.5 * (tb - ta));
        let at = |t: f32| self.density_in(c, s0 + ds * t);
        half * (at(mid - half * GAUSS) + at(mid + half * GAUSS))
    }

    /// ∫ density dt along `origin + t · dir` for `t0 <= t < t1` (in units
    /// of `t`: times `|dir|` for world distance).
    pub fn integral(&self, origin: Vec3, dir: Vec3, t0: f32, t1: f32) -> f32 {
        let mut sum = 0.0;
        self.walk(origin, dir, t0, t1, |c, s0, ds, ta, tb| {
            sum += self.cell_integral(c, s0, ds, ta, tb);
            true
        });
        sum
    }

    /// The `t` in `t0..t1` where [`DensityGrid::integral`] from `t0`
    /// reaches `target`, or `None` when the whole segment holds less.
    pub fn invert(&self, origin: Vec3, dir: Vec3, t0: f32, t1: f32, target: f32) -> Option<f32> {
        let mut sum = 0.0;
        let mut found = None;
        self.walk(origin, dir, t0, t1, |c, s0, ds, ta, tb| {
            let here = self.cell_integral(c, s0, ds, ta, tb);
            if sum + here < target {
                sum += here;
                return true;
            }
            // Bisection on the exact partial integral, which grows with t.
            let (mut lo, mut hi) = (ta, tb);
            for _ in 0..30 {
                let t = 0.5 * (lo + hi);
                if sum + self.cell_integral(c, s0, ds, ta, t) < target {
                    lo = t;
                } else {
                    hi = t;
                }
            }
            found = Some(0.5 * (lo + hi));
            false
        });
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> DensityGrid {
        // 3 × 2 × 2 samples with varied values over [-1, 2] × [0, 1] × [0, 2].
        let values = (0..12).map(|i| ((i * 7) % 5) as f32 * 0.5 + 0.25).collect();
        let m = Affine3A::from_rotation_y(0.3).inverse();
        DensityGrid::new([3, 2, 2], values, Vec3::new(-1.0, 0.0, 0.0), Vec3::new(2.0, 1.0, 2.0), m)
    }

    /// The walked integral equals fine midpoint quadrature of the lookups.
    #[test]
    fn integrals_match_fine_quadrature() {
        let g = grid();
        for (o, d) in [
            (Vec3::new(-3.0, 0.4, 0.7), Vec3::new(1.0, 0.05, 0.1)),
            (Vec3::new(0.2, -1.0, 0.3), Vec3::new(0.1, 1.0, 0.35)),
            (Vec3::new(3.0, 2.0, 3.0), Vec3::new(-1.0, -0.6, -0.9) * 2.5),
            (Vec3::new(0.5, 0.5, 1.0), Vec3::new(0.0, 0.0, 1.0)),
        ] {
            let (t0, t1) = (0.0, 6.0);
            let n = 200_000;
            let h = (t1 - t0) / n as f32;
            let fine: f64 =
                (0..n).map(|i| g.density(o + d * (t0 + (i as f32 + 0.5) * h)) as f64 * h as f64).sum();
            let exact = g.integral(o, d, t0, t1);
            assert!(fine > 0.1, "the ray {o} {d} misses the grid");
            assert!((exact as f64 - fine).abs() < 1e-3 * fine, "{exact} vs {fine} for {o} {d}");
            // Inverting gives back the distance to half the depth.
            let t = g.invert(o, d, t0, t1, exact * 0.5).unwrap();
            assert!((g.integral(o, d, t0, t) - 0.5 * exact).abs() < 1e-4 * exact, "{t}");
            assert_eq!(g.invert(o, d, t0, t1, exact * 1.01), None);
        }
    }

    #[test]
    fn lookups_follow_pbrts_sample_placement() {
        let g = DensityGrid::new(
            [2, 1, 1],
            vec![1.0, 3.0],
            Vec3::ZERO,
            Vec3::new(2.0, 1.0, 1.0),
            Affine3A::IDENTITY,
        );
        // Samples at x = 0.5 and 1.5; halfway between them, their mean;
        // towards the edges, a ramp down to the missing neighbours.
        assert_eq!(g.density(Vec3::new(0.5, 0.5, 0.5)), 1.0);
        assert_eq!(g.density(Vec3::new(1.0, 0.5, 0.5)), 2.0);
        assert_eq!(g.density(Vec3::new(1.5, 0.5, 0.5)), 3.0);
        assert_eq!(g.density(Vec3::new(1.75, 0.5, 0.5)), 2.25);
        assert_eq!(g.density(Vec3::new(2.5, 0.5, 0.5)), 0.0);
    }
}
