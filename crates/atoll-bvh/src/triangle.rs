//! The ray/triangle test shared by every layout (and, later, by the GPU kernels).

use glam::{Vec3, Vec3A};

/// A triangle prepared for the intersection test: a corner and the two edges
/// leaving it (36 bytes). Leaves store these contiguously in leaf order, so a
/// leaf's triangles are one linear read and the edges need no recomputation.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct TriAccel {
    /// `p0` (12 bytes).
    pub v0: Vec3,
    /// `p1 - p0` (12 bytes).
    pub e1: Vec3,
    /// `p2 - p0` (12 bytes).
    pub e2: Vec3,
}

const _: () = assert!(std::mem::size_of::<TriAccel>() == 36);

impl TriAccel {
    /// Prepares triangle `(p0, p1, p2)` in index order (the order barycentrics refer to).
    #[inline]
    pub fn new([p0, p1, p2]: [Vec3; 3]) -> Self {
        TriAccel { v0: p0, e1: p1 - p0, e2: p2 - p0 }
    }

    /// Möller–Trumbore (1997), two-sided, without epsilons: returns `(t, u, v)`
    /// for a hit with `0 < t < t_max`, where the hit point is
    /// `(1-u-v)*p0 + u*p1 + v*p2`. `det == 0` (a ray in the triangle's plane
    /// or a degenerate triangle) is a miss; a `det` so small that `1/det`
    /// overflows gives NaN barycentrics, which fail the comparisons and miss
    /// too. Not watertight: a ray through a shared edge may, rarely, miss both
    /// triangles. The GPU kernels must use this same test (same operation
    /// order) for hits to agree across devices.
    #[inline(always)]
    pub fn intersect(&self, origin: Vec3A, dir: Vec3A, t_max: f32) -> Option<(f32, f32, f32)> {
        let e1 = Vec3A::from(self.e1);
        let e2 = Vec3A::from(self.e2);
        let p = dir.cross(e2);
        let det = e1.dot(p);
        if det == 0.0 {
            return None;
        }
        let inv_det = 1.0 / det;
        let s = origin - Vec3A::from(self.v0);
        let u = s.dot(p) * inv_det;
        let q = s.cross(e1);
        let v = dir.dot(q) * inv_det;
        let t = e2.dot(q) * inv_det;
        // Written so that NaN fails every comparison: all must be true to hit.
        let hit = u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0 && t < t_max;
        hit.then_some((t, u, v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hit_point_matches_barycentrics() {
        let tri = [Vec3::new(0.0, 0.0, 1.0), Vec3::new(2.0, 0.0, 1.0), Vec3::new(0.0, 4.0, 1.0)];
        let acc = TriAccel::new(tri);
        let (o, d) = (Vec3A::new(0.5, 1.0, -1.0), Vec3A::new(0.0, 0.0, 2.0));
        let (t, u, v) = acc.intersect(o, d, f32::INFINITY).unwrap();
        assert_eq!((t, u, v), (1.0, 0.25, 0.25));
        let p = (1.0 - u - v) * tri[0] + u * tri[1] + v * tri[2];
        assert!((Vec3::from(o + t * d) - p).length() < 1e-6);
        // t_max is exclusive, and so is t = 0.
        assert!(acc.intersect(o, d, 1.0).is_none());
        assert!(acc.intersect(o + Vec3A::new(0.0, 0.0, 2.0), d, 10.0).is_none());
        // Outside the triangle, and parallel to it.
        assert!(acc.intersect(Vec3A::new(1.5, 3.0, -1.0), d, 10.0).is_none());
        assert!(acc.intersect(o, Vec3A::X, 10.0).is_none());
        // Degenerate triangles never hit.
        let flat = TriAccel::new([Vec3::ZERO, Vec3::X, Vec3::X * 2.0]);
        assert!(flat.intersect(Vec3A::new(0.5, 0.0, -1.0), Vec3A::Z, 10.0).is_none());
    }
}
