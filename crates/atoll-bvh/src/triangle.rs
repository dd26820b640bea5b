//! The ray/triangle test shared by every layout (and, later, by the GPU
//! kernels): Möller–Trumbore, written once over a lane type so that the
//! scalar reference [`TriAccel`] and the 4-wide [`Tri4`] do the same
//! arithmetic in the same order and so agree to the bit.

use std::ops::{Add, Div, Mul, Sub};

use glam::{Vec3, Vec3A, Vec4};

/// A triangle prepared for the intersection test: a corner and the two edges
/// leaving it (36 bytes). The reference form of the test, and what [`Tri4`]
/// blocks are made of.
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

/// What the test needs of a number: `f32` for one triangle, `Vec4` for four.
trait Lane: Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self> {
    const ONE: Self;
}

impl Lane for f32 {
    const ONE: f32 = 1.0;
}

impl Lane for Vec4 {
    const ONE: Vec4 = Vec4::ONE;
}

fn cross<T: Lane>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn dot<T: Lane>(a: [T; 3], b: [T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Möller–Trumbore (1997), two-sided, without epsilons: `(det, t, u, v)` of
/// the ray `origin + t * dir` against the triangle `v0, v0 + e1, v0 + e2`.
/// The hit point is `(1-u-v)*p0 + u*p1 + v*p2`. A hit needs `det != 0`
/// (`det == 0`: the ray lies in the triangle's plane, or the triangle is
/// degenerate), `u >= 0, v >= 0, u + v <= 1` and `0 < t < t_max`; NaNs (from
/// a `det` so small that `1/det` overflows) fail those comparisons. Not
/// watertight: a ray through a shared edge may, rarely, miss both
/// triangles. The GPU kernels must do exactly these operations in this order
/// (no fused multiply-adds) for hits to agree across devices.
#[inline(always)]
fn moller_trumbore<T: Lane>(origin: [T; 3], dir: [T; 3], v0: [T; 3], e1: [T; 3], e2: [T; 3]) -> (T, T, T, T) {
    let p = cross(dir, e2);
    let det = dot(e1, p);
    let inv_det = T::ONE / det;
    let s = [origin[0] - v0[0], origin[1] - v0[1], origin[2] - v0[2]];
    let u = dot(s, p) * inv_det;
    let q = cross(s, e1);
    let v = dot(dir, q) * inv_det;
    let t = dot(e2, q) * inv_det;
    (det, t, u, v)
}

impl TriAccel {
    /// Prepares triangle `(p0, p1, p2)` in index order (the order barycentrics refer to).
    #[inline]
    pub fn new([p0, p1, p2]: [Vec3; 3]) -> Self {
        TriAccel { v0: p0, e1: p1 - p0, e2: p2 - p0 }
    }

    /// `(t, u, v)` of a hit with `0 < t < t_max` (see [`Tri4`] for the rules).
    #[inline(always)]
    pub fn intersect(&self, origin: Vec3A, dir: Vec3A, t_max: f32) -> Option<(f32, f32, f32)> {
        let (det, t, u, v) =
            moller_trumbore(origin.into(), dir.into(), self.v0.into(), self.e1.into(), self.e2.into());
        // Written so that NaN fails every comparison: all must be true to hit.
        let hit = det != 0.0 && u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0 && t < t_max;
        hit.then_some((t, u, v))
    }
}

/// A ray as [`Tri4`] wants it: each component splatted over four lanes.
#[derive(Clone, Copy, Debug)]
pub struct Ray4 {
    origin: [Vec4; 3],
    dir: [Vec4; 3],
}

impl Ray4 {
    /// Splats a ray's origin and direction.
    #[inline(always)]
    pub fn new(origin: Vec3A, dir: Vec3A) -> Self {
        Ray4 { origin: origin.to_array().map(Vec4::splat), dir: dir.to_array().map(Vec4::splat) }
    }
}

/// Four [`TriAccel`]s as structure of arrays (144 bytes): one test of a ray
/// against all four costs about as much as a scalar test against one. Leaf
/// primitive ranges start at multiples of 4, so every leaf is a run of whole
/// blocks; unused lanes hold degenerate (all-zero) triangles, which never hit.
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Tri4 {
    /// x, y and z of `p0` (3 x 16 bytes).
    pub v0: [Vec4; 3],
    /// x, y and z of `p1 - p0` (3 x 16 bytes).
    pub e1: [Vec4; 3],
    /// x, y and z of `p2 - p0` (3 x 16 bytes).
    pub e2: [Vec4; 3],
}

const _: () = assert!(std::mem::size_of::<Tri4>() == 144);

impl Tri4 {
    /// Triangles per block.
    pub const LANES: usize = 4;

    /// Packs up to four triangles; missing lanes stay degenerate.
    pub fn new(tris: &[TriAccel]) -> Self {
        assert!(tris.len() <= Self::LANES);
        let mut block = Tri4::default();
        for (lane, tri) in tris.iter().enumerate() {
            for axis in 0..3 {
                block.v0[axis][lane] = tri.v0[axis];
                block.e1[axis][lane] = tri.e1[axis];
                block.e2[axis][lane] = tri.e2[axis];
            }
        }
        block
    }

    /// Lanes hit with `0 < t < t_max` as bits of the returned mask, with
    /// every lane's `t`, `u` and `v`.
    #[inline(always)]
    pub fn test(&self, ray: &Ray4, t_max: f32) -> (u32, Vec4, Vec4, Vec4) {
        let (det, t, u, v) = moller_trumbore(ray.origin, ray.dir, self.v0, self.e1, self.e2);
        let hit = det.cmpne(Vec4::ZERO)
            & u.cmpge(Vec4::ZERO)
            & v.cmpge(Vec4::ZERO)
            & (u + v).cmple(Vec4::ONE)
            & t.cmpgt(Vec4::ZERO)
            & t.cmplt(Vec4::splat(t_max));
        (hit.bitmask(), t, u, v)
    }

    /// The closest hit with `0 < t < t_max`: `(lane, t, u, v)`.
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray4, t_max: f32) -> Option<(usize, f32, f32, f32)> {
        let (mask, t, u, v) = self.test(ray, t_max);
        if mask == 0 {
            return None;
        }
        let t = t.to_array();
        let mut best = mask.trailing_zeros() as usize;
        let mut rest = mask & (mask - 1);
        while rest != 0 {
            let lane = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            if t[lane] < t[best] {
                best = lane;
            }
        }
        Some((best, t[best], u[best], v[best]))
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

    #[test]
    fn blocks_agree_with_the_reference_to_the_bit() {
        let mut s = 1u32;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            (s >> 8) as f32 / (1 << 24) as f32 * 2.0 - 1.0
        };
        let mut vec = move || Vec3::new(next(), next(), next());
        for _ in 0..2000 {
            let tris: Vec<TriAccel> = (0..3).map(|_| TriAccel::new([vec(), vec(), vec()])).collect();
            let block = Tri4::new(&tris);
            let (o, d) = (Vec3A::from(vec() * 2.0), Vec3A::from(vec()));
            let t_max = 1.0 + vec().x;
            let (mask, t, u, v) = block.test(&Ray4::new(o, d), t_max);
            assert_eq!(mask & 8, 0, "the empty lane never hits");
            for (lane, tri) in tris.iter().enumerate() {
                let expected = tri.intersect(o, d, t_max);
                assert_eq!(expected.is_some(), mask >> lane & 1 == 1);
                if let Some(hit) = expected {
                    assert_eq!(hit, (t[lane], u[lane], v[lane]));
                }
            }
            let closest =
                tris.iter().enumerate().filter_map(|(l, tri)| Some((l, tri.intersect(o, d, t_max)?)));
            let closest = closest.min_by(|a, b| a.1 .0.total_cmp(&b.1 .0)).map(|(l, (t, u, v))| (l, t, u, v));
            assert_eq!(block.intersect(&Ray4::new(o, d), t_max), closest);
        }
    }
}
