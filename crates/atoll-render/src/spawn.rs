//! Robust ray spawning (pbrt-v4's approach, *Physically Based Rendering*
//! 4th ed., §6.8): every computed point carries a conservative bound on its
//! floating-point error, and a ray leaves from a point pushed along the
//! geometric normal just past that bound; a ray towards another point (a
//! shadow ray to a light sample) also stops short of the target's own bound.
//! No scene-scale epsilon is involved: the offsets follow the error of each
//! point's arithmetic, so a scene renders the same anywhere in space.
//!
//! A hit carries its bound as one scalar, `dot(|n|, error)` along its
//! geometric normal, which is all the offset needs
//! ([`crate::RayRecord::position_error`]). `kernels/spawn.cuh` mirrors
//! every function here operation by operation.

use glam::{Affine3A, Vec3};

/// Half the spacing of floats at 1 (the unit roundoff).
const UNIT_ROUNDOFF: f32 = f32::EPSILON * 0.5;

/// The part of a shadow ray's length left untested before its target
/// (pbrt-v4's `ShadowEpsilon`, relative to the ray's length).
pub const SHADOW_EPSILON: f32 = 1e-4;

/// Bound on the relative error of `n` chained float operations (pbrt's γₙ).
/// The kernels take the values they need as constants (`GAMMA_3`, ...).
pub const fn gamma(n: u32) -> f32 {
    let e = n as f32 * UNIT_ROUNDOFF;
    e / (1.0 - e)
}

/// Σ |bᵢ pᵢ| for triangle corners `p` and barycentrics `b`: the point
/// `Σ bᵢ pᵢ` is off by at most γ₇ times this where an intersection
/// computed it, γ₆ where a light sample did (pbrt's bounds).
pub fn barycentric_magnitude(p: [Vec3; 3], b: [f32; 3]) -> Vec3 {
    (p[0] * b[0]).abs() + (p[1] * b[1]).abs() + (p[2] * b[2]).abs()
}

/// Error bound of `m` applied to a point `p` that had error `e` (pbrt's
/// transform of a `Point3fi`): the transform's own rounding, γ₃ (|M| |p| +
/// |t|), plus the old error carried through |M|, widened by (1 + γ₃).
pub fn transformed_error(m: &Affine3A, p: Vec3, e: Vec3) -> Vec3 {
    let abs = |v: glam::Vec3A| Vec3::from(v.abs());
    let (x, y, z) = (abs(m.matrix3.x_axis), abs(m.matrix3.y_axis), abs(m.matrix3.z_axis));
    let pa = p.abs();
    let rounding = x * pa.x + y * pa.y + z * pa.z + abs(m.translation);
    let carried = x * e.x + y * e.y + z * e.z;
    gamma(3) * rounding + (gamma(3) + 1.0) * carried
}

/// The error bound along unit normal `n` of a point with per-axis error
/// `e`: how far the point may lie off its surface.
pub fn error_along(n: Vec3, e: Vec3) -> f32 {
    n.abs().dot(e)
}

/// A non-negative error bound as bfloat16 bits, rounded up so the stored
/// bound is never smaller (bf16 keeps f32's range: bounds from tiny scenes
/// to planet-sized ones fit).
pub fn pack_error(bound: f32) -> u16 {
    if bound.is_nan() || bound <= 0.0 {
        return 0;
    }
    let bits = bound.to_bits();
    let high = bits >> 16;
    // Any discarded bit means the truncated value is smaller: step up one
    // bf16 (an infinity stays infinite).
    let rounded = if bits & 0xffff != 0 && high < 0x7f80 { high + 1 } else { high };
    rounded as u16
}

/// The bound [`pack_error`] stored.
pub fn unpack_error(bits: u16) -> f32 {
    f32::from_bits((bits as u32) << 16)
}

/// `f32::next_up` for finite `v` by one integer step on the bits (the
/// library version also handles NaN and infinities, which no ray origin
/// is, at several times the cost; `kernels/spawn.cuh` does the same).
fn next_float_up(v: f32) -> f32 {
    let bits = v.to_bits();
    if bits & 0x7fff_ffff == 0 {
        return f32::from_bits(1);
    }
    f32::from_bits(if v > 0.0 { bits + 1 } else { bits - 1 })
}

/// The next float away from `v` in the direction of `offset`'s sign.
fn round_away(v: f32, offset: f32) -> f32 {
    if offset > 0.0 {
        next_float_up(v)
    } else if offset < 0.0 {
        -next_float_up(-v)
    } else {
        v
    }
}

/// pbrt's `OffsetRayOrigin`: `p` (off its surface by at most `error` along
/// geometric normal `n`) pushed along `n` to the side `w` leaves from,
/// just past the error bound. Each coordinate is then rounded one more
/// float away from `p`, since rounding the sum could land back inside.
pub fn offset_ray_origin(p: Vec3, error: f32, n: Vec3, w: Vec3) -> Vec3 {
    let mut offset = n * error;
    if n.dot(w) < 0.0 {
        offset = -offset;
    }
    let po = p + offset;
    Vec3::new(round_away(po.x, offset.x), round_away(po.y, offset.y), round_away(po.z, offset.z))
}

/// A point with its error bound along its normal, as [`spawn_ray_to`]
/// takes both ends. `normal` is zero for points on no surface (a point
/// light), which are then not offset.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    pub p: Vec3,
    pub normal: Vec3,
    pub error: f32,
}

/// A spawned ray: origin, unit direction and extent.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpawnedRay {
    pub origin: Vec3,
    pub direction: Vec3,
    pub t_max: f32,
}

/// pbrt's `SpawnRayTo` for two points with error bounds: leaves `from` on
/// the side facing `to`, aims at `to` moved off its own surface towards the
/// origin, and stops [`SHADOW_EPSILON`] of the length short of it, so
/// neither surface can occlude the ray between them. `None` when the two
/// points coincide.
pub fn spawn_ray_to(from: SurfacePoint, to: SurfacePoint) -> Option<SpawnedRay> {
    let origin = offset_ray_origin(from.p, from.error, from.normal, to.p - from.p);
    let target = offset_ray_origin(to.p, to.error, to.normal, origin - to.p);
    let d = target - origin;
    let length = d.length();
    if !(length > 0.0 && length.is_finite()) {
        return None;
    }
    Some(SpawnedRay { origin, direction: d * (1.0 / length), t_max: length * (1.0 - SHADOW_EPSILON) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn next_float_matches_the_library() {
        for v in [0.0f32, -0.0, 1.0, -1.0, 1e-40, -1e-40, 3.5e5, -7.25e-3, f32::MAX / 2.0] {
            assert_eq!(next_float_up(v).to_bits(), v.next_up().to_bits(), "{v}");
            assert_eq!(round_away(v, -1.0).to_bits(), v.next_down().to_bits(), "{v}");
        }
    }

    #[test]
    fn packed_error_is_never_smaller() {
        for v in [1e-12f32, 3.7e-7, 0.04, 1.0, 123.456, 6.5e4, 3e30] {
            let back = unpack_error(pack_error(v));
            assert!(back >= v && back <= v * 1.01, "{v} -> {back}");
        }
        assert_eq!(unpack_error(pack_error(0.0)), 0.0);
        assert_eq!(unpack_error(pack_error(-1.0)), 0.0);
        assert_eq!(unpack_error(pack_error(0.5)), 0.5);
        assert_eq!(unpack_error(pack_error(f32::INFINITY)), f32::INFINITY);
    }

    #[test]
    fn offset_origin_leaves_the_error_box_on_the_side_of_w() {
        let n = Vec3::Y;
        for scale in [1.0f32, 1e3, 1e5, 1e7] {
            let p = Vec3::new(scale, 0.25 * scale, -scale);
            let error = gamma(7) * p.abs().max_element();
            let up = offset_ray_origin(p, error, n, Vec3::new(0.3, 1.0, 0.0));
            let down = offset_ray_origin(p, error, n, Vec3::new(0.3, -1.0, 0.0));
            assert!(up.y - p.y > error && p.y - down.y > error, "{scale}: {up} {down}");
            assert_eq!((up.x, up.z), (p.x, p.z));
        }
    }

    /// A shadow ray between two parallel surfaces far from the origin
    /// starts above the lower one's error box and ends below the upper one's.
    #[test]
    fn spawn_ray_to_stays_between_both_error_boxes() {
        let base = Vec3::new(1e5, 3.0, -2e5);
        let from = SurfacePoint { p: base, normal: Vec3::Y, error: gamma(7) * 2e5 };
        let to =
            SurfacePoint { p: base + Vec3::new(0.5, 1.5, 0.25), normal: -Vec3::Y, error: gamma(7) * 2e5 };
        let ray = spawn_ray_to(from, to).unwrap();
        assert!(ray.origin.y - from.p.y > from.error);
        let end = ray.origin + ray.direction * ray.t_max;
        assert!(to.p.y - end.y > to.error, "end {end}, target {}", to.p);
        assert!((ray.direction.length() - 1.0).abs() < 1e-6);
        assert!(spawn_ray_to(from, from).is_none());
    }

    #[test]
    fn transformed_error_includes_the_transform_rounding() {
        let m = Affine3A::from_translation(Vec3::new(1e5, 0.0, 0.0));
        let e = transformed_error(&m, Vec3::new(1.0, 2.0, 3.0), Vec3::ZERO);
        assert!(e.x > 1e5 * gamma(3) && e.y > 0.0);
        let identity = transformed_error(&Affine3A::IDENTITY, Vec3::ONE, Vec3::splat(1e-3));
        assert!(identity.x >= 1e-3 && identity.x < 1.01e-3);
    }
}
