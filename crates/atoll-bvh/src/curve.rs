//! The ray/curve test: pbrt-v4's `Curve::IntersectRay` and
//! `RecursiveIntersect` (after Nakamaru & Ohno 2002). The piece is moved
//! into a frame where the ray runs along +z from the origin, cut in halves
//! until each part is nearly straight, and each part is tested as a
//! segment of the width the curve has there. The GPU's `curve.cuh` does
//! the same operations in the same order (but for the CPU's early
//! bounding-sphere test, which changes no hit).
//!
//! pbrt recurses; here the halves are visited depth first over the
//! implicit binary tree of parameter ranges, each part's control points
//! made from the piece's by blossoming, so the GPU needs no stack.

use atoll_scene::curve::{lerp, restrict, CurveKind, CurvePiece};
use glam::Vec3A;

/// The deepest subdivision (pbrt's cap: 1024 parts).
pub const MAX_CURVE_DEPTH: i32 = 10;

/// `(t, u, v)` of a hit: `u` the segment's parameter, `v` across the curve.
pub type CurveHit = (f32, f32, f32);

/// pbrt's `Log2Int` for a float ≥ 1: the exponent, plus one where the
/// significand passes √2 (log2 rounded to the nearest integer). Bits, not
/// `log2`, so the GPU finds the same depth.
fn log2_int(v: f32) -> i32 {
    const MID_SIGNIFICAND: u32 = 0b0000_0000_0011_0101_0000_0100_1111_0011;
    let bits = v.to_bits();
    let exponent = ((bits >> 23) & 0xff) as i32 - 127;
    exponent + i32::from(bits & 0x7f_ffff >= MID_SIGNIFICAND)
}

/// How many times the piece is halved (pbrt's `maxDepth`): enough that
/// each part departs from its chord by about a twentieth of the width.
/// `cp` are the control points in the ray's frame.
fn refinement_depth(cp: &[Vec3A; 4], widths: [f32; 2]) -> i32 {
    let mut l0 = 0.0f32;
    for i in 0..2 {
        let d = (cp[i] - 2.0 * cp[i + 1] + cp[i + 2]).abs();
        l0 = l0.max(d.x.max(d.y).max(d.z));
    }
    if l0 <= 0.0 {
        return 0;
    }
    let eps = widths[0].max(widths[1]) * 0.05;
    let v = std::f32::consts::SQRT_2 * 6.0 * l0 / (8.0 * eps);
    if v.is_nan() || v < 1.0 {
        return 0;
    }
    (log2_int(v) / 2).clamp(0, MAX_CURVE_DEPTH)
}

/// The ray's frame (pbrt's `LookAt(o, o + d, dx)`): rows x, y, z with z
/// along the ray; `None` for a zero direction.
fn ray_frame(dir: Vec3A, p0: Vec3A, p3: Vec3A) -> Option<[Vec3A; 3]> {
    let len = dir.length();
    if len == 0.0 {
        return None;
    }
    let z = dir / len;
    let mut up = dir.cross(p3 - p0);
    if up.length_squared() == 0.0 {
        up = z.any_orthonormal_vector();
    }
    let x = up.normalize().cross(z).normalize();
    let y = z.cross(x);
    Some([x, y, z])
}

/// Whether the box of `cp` grown by `half_width` meets the ray's segment
/// `(0, 0, 0)..(0, 0, z_max)`.
fn overlaps_ray(cp: &[Vec3A; 4], half_width: f32, z_max: f32) -> bool {
    let lo = cp[0].min(cp[1]).min(cp[2].min(cp[3])) - Vec3A::splat(half_width);
    let hi = cp[0].max(cp[1]).max(cp[2].max(cp[3])) + Vec3A::splat(half_width);
    lo.x <= 0.0 && hi.x >= 0.0 && lo.y <= 0.0 && hi.y >= 0.0 && lo.z <= z_max && hi.z >= 0.0
}

/// Whether the ray `origin + t dir`, `0 < t < t_max`, passes clear of the
/// sphere around the piece's control points grown by half its width (the
/// curve lies in their convex hull): a few operations that spare most
/// candidate pieces the ray frame and the refinement depth. Conservative:
/// its margin covers the rounding of the test, so it changes no hit. The
/// GPU's `curve.cuh` goes without it: there it measured slower
/// (BENCHMARKS.md).
fn misses_bounding_sphere(piece: &CurvePiece, p: &[Vec3A; 4], origin: Vec3A, dir: Vec3A, t_max: f32) -> bool {
    let centre = (p[0] + p[1] + p[2] + p[3]) * 0.25;
    let r2 = p.iter().map(|q| (*q - centre).length_squared()).fold(0.0f32, f32::max);
    let half = 0.5 * piece.width_at(piece.u[0]).max(piece.width_at(piece.u[1]));
    let to_centre = centre - origin;
    let radius = (r2.sqrt() + half) * (1.0 + 1e-4) + 1e-5 * to_centre.length();
    let dd = dir.length_squared();
    let t_centre = to_centre.dot(dir) / dd;
    let off_axis = (to_centre - dir * t_centre).length_squared();
    let dt = radius / dd.sqrt();
    off_axis > radius * radius || t_centre + dt < 0.0 || t_centre - dt > t_max
}

/// The closest hit (with `ANY`, the first found) of the ray `origin + t
/// dir`, `0 < t < t_max`, on the piece (in the piece's space).
pub fn intersect_curve<const ANY: bool>(
    kind: CurveKind,
    piece: &CurvePiece,
    origin: Vec3A,
    dir: Vec3A,
    t_max: f32,
) -> Option<CurveHit> {
    let points = piece.points_a();
    if misses_bounding_sphere(piece, &points, origin, dir, t_max) {
        return None;
    }
    subdivide::<ANY>(kind, piece, &points, origin, dir, t_max)
}

/// pbrt's test proper (what [`intersect_curve`] runs on rays the bounding
/// sphere does not rule out).
fn subdivide<const ANY: bool>(
    kind: CurveKind,
    piece: &CurvePiece,
    points: &[Vec3A; 4],
    origin: Vec3A,
    dir: Vec3A,
    t_max: f32,
) -> Option<CurveHit> {
    let frame = ray_frame(dir, points[0], points[3])?;
    let to_ray = |p: Vec3A| {
        let q = p - origin;
        Vec3A::new(frame[0].dot(q), frame[1].dot(q), frame[2].dot(q))
    };
    let cp = points.map(to_ray);
    let ray_length = dir.length();
    let depth = refinement_depth(&cp, piece.widths);
    // A ribbon's width is foreshortened by its normal's angle to the ray.
    let ribbon_scale = |u: f32| piece.ribbon_normal(u).dot(dir).abs() / ray_length;
    let mut z_max = ray_length * t_max;
    let mut best: Option<CurveHit> = None;
    let (mut level, mut index) = (0i32, 0u32);
    loop {
        let scale = 1.0 / (1u32 << level) as f32;
        let (a, b) = (index as f32 * scale, (index + 1) as f32 * scale);
        let part = restrict(&cp, a, b);
        let (u0, u1) = (lerp(a, piece.u[0], piece.u[1]), lerp(b, piece.u[0], piece.u[1]));
        let max_width = piece.width_at(u0).max(piece.width_at(u1));
        if overlaps_ray(&part, 0.5 * max_width, z_max) {
            if level < depth {
                level += 1;
                index *= 2;
                continue;
            }
            if let Some(hit) = segment_hit(kind, piece, &part, (u0, u1), ray_length, z_max, &ribbon_scale) {
                if ANY {
                    return Some(hit);
                }
                z_max = hit.0 * ray_length;
                best = Some(hit);
            }
        }
        // The next range in depth-first order: up past right halves, then across.
        while index & 1 == 1 {
            index >>= 1;
            level -= 1;
        }
        if level == 0 {
            return best;
        }
        index += 1;
    }
}

/// pbrt's leaf test: the part `cp` (in the ray's frame), nearly straight,
/// covering the segment's parameters `u0..u1`.
fn segment_hit(
    kind: CurveKind,
    piece: &CurvePiece,
    cp: &[Vec3A; 4],
    (u0, u1): (f32, f32),
    ray_length: f32,
    z_max: f32,
    ribbon_scale: &impl Fn(f32) -> f32,
) -> Option<CurveHit> {
    // The ray must pass between the perpendiculars to the tangents at the ends.
    let edge = (cp[1].y - cp[0].y) * -cp[0].y + cp[0].x * (cp[0].x - cp[1].x);
    if edge < 0.0 {
        return None;
    }
    let edge = (cp[2].y - cp[3].y) * -cp[3].y + cp[3].x * (cp[3].x - cp[2].x);
    if edge < 0.0 {
        return None;
    }
    // The parameter of the chord's point nearest the ray.
    let (sx, sy) = (cp[3].x - cp[0].x, cp[3].y - cp[0].y);
    let denom = sx * sx + sy * sy;
    if denom == 0.0 {
        return None;
    }
    let w = (-cp[0].x * sx + -cp[0].y * sy) / denom;
    let u = lerp(w, u0, u1).clamp(u0, u1);
    let mut hit_width = piece.width_at(u);
    if kind == CurveKind::Ribbon {
        hit_width *= ribbon_scale(u);
    }
    let (pc, dpcdw) = atoll_scene::curve::evaluate(cp, w.clamp(0.0, 1.0));
    let dist2 = pc.x * pc.x + pc.y * pc.y;
    if dist2 > hit_width * hit_width * 0.25 || pc.z < 0.0 || pc.z > z_max {
        return None;
    }
    let t = pc.z / ray_length;
    if t.is_nan() || t <= 0.0 {
        return None;
    }
    // Which side of the curve the ray passes, for v across it.
    let dist = dist2.sqrt();
    let edge = dpcdw.x * -pc.y + pc.x * dpcdw.y;
    let v = if edge > 0.0 { 0.5 + dist / hit_width } else { 0.5 - dist / hit_width };
    Some((t, u, v))
}

#[cfg(test)]
mod tests {
    use super::*;
    use atoll_scene::curve::Curves;
    use glam::Vec3;

    fn piece_kind(piece: &CurvePiece) -> CurveKind {
        if piece.normals[0] == Vec3::ZERO {
            CurveKind::Flat
        } else {
            CurveKind::Ribbon
        }
    }

    fn straight(kind: CurveKind, width: f32) -> CurvePiece {
        let line = [Vec3::ZERO, Vec3::Z, Vec3::Z * 2.0, Vec3::Z * 3.0];
        Curves::from_segments(kind, &[line], (width, width), &[Vec3::Y, Vec3::Y], 1).pieces[0]
    }

    #[test]
    fn a_straight_curve_is_hit_within_its_width() {
        let piece = straight(CurveKind::Flat, 0.5);
        let dir = Vec3A::new(0.0, 1.0, 0.0);
        for x in [-0.3f32, -0.24, -0.1, 0.0, 0.1, 0.24, 0.3] {
            let origin = Vec3A::new(x, -2.0, 1.5);
            let hit = intersect_curve::<false>(CurveKind::Flat, &piece, origin, dir, f32::INFINITY);
            assert_eq!(hit.is_some(), x.abs() < 0.25, "x {x}");
            if let Some((t, u, v)) = hit {
                assert!((t - 2.0).abs() < 1e-5, "t {t}");
                assert!((u - 0.5).abs() < 1e-5, "u {u}");
                // v runs across the width, 0.5 on the axis.
                assert!((v - (0.5 + x.abs() / 0.5)).abs() < 1e-5 || (v - (0.5 - x.abs() / 0.5)).abs() < 1e-5);
            }
        }
        // Past t_max, behind the origin, or past the ends: no hit.
        let origin = Vec3A::new(0.0, -2.0, 1.5);
        assert!(intersect_curve::<false>(CurveKind::Flat, &piece, origin, dir, 1.9).is_none());
        assert!(intersect_curve::<false>(CurveKind::Flat, &piece, -origin, dir, 10.0).is_none());
        let past = Vec3A::new(0.0, -2.0, 3.2);
        assert!(intersect_curve::<false>(CurveKind::Flat, &piece, past, dir, 10.0).is_none());
        // The two sides of the axis give v below and above one half.
        let left = intersect_curve::<false>(CurveKind::Flat, &piece, Vec3A::new(-0.1, -2.0, 1.5), dir, 9.0);
        let right = intersect_curve::<false>(CurveKind::Flat, &piece, Vec3A::new(0.1, -2.0, 1.5), dir, 9.0);
        assert!((left.unwrap().2 - 0.5) * (right.unwrap().2 - 0.5) < 0.0);
    }

    /// A bent curve: hits lie on the curve's centre line within half its
    /// width, whatever the ray's direction, and a ray along a hit's
    /// direction from far away finds the same point.
    #[test]
    fn hits_of_a_bent_curve_lie_on_it() {
        let c = [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::new(2.0, -1.0, 1.0), Vec3::new(3.0, 0.0, 0.0)];
        let curves = Curves::from_segments(CurveKind::Flat, &[c], (0.1, 0.05), &[], 4);
        let mut hits = 0;
        for (k, piece) in curves.pieces.iter().enumerate() {
            for j in 0..16 {
                let s = (j as f32 + 0.5) / 16.0;
                let (on, _) = atoll_scene::curve::evaluate(&piece.points_a(), s);
                let dir = Vec3A::new((j as f32).sin(), 0.3, (k as f32 + j as f32).cos()).normalize();
                let origin = on - dir * 5.0;
                let Some((t, u, _)) = intersect_curve::<false>(curves.kind, piece, origin, dir, 100.0) else {
                    continue;
                };
                hits += 1;
                let p = origin + dir * t;
                let (centre, _) = atoll_scene::curve::evaluate(&c.map(Vec3A::from), u);
                assert!((p - centre).length() <= 0.5 * piece.width_at(u) * 1.01 + 2e-3, "piece {k}, {j}");
                // The aimed-at point, or a nearer part of the curve.
                assert!(t < 5.0 + 0.1, "t {t}");
                assert!(intersect_curve::<true>(curves.kind, piece, origin, dir, 100.0).is_some());
            }
        }
        assert!(hits >= 60, "{hits} of 64 rays aimed at the centre line hit");
    }

    /// A ribbon lies in its plane: a ray through that plane hits it within
    /// half its width of the axis from any side (its width foreshortened
    /// as the ray sees it), where a flat curve, turned to face the ray,
    /// shows its whole width.
    #[test]
    fn ribbons_lie_in_their_plane() {
        let ribbon = straight(CurveKind::Ribbon, 0.5);
        let flat = straight(CurveKind::Flat, 0.5);
        // Through the point (x, 0, 1.5) of the ribbon's plane y = 0.
        let at = |piece: &CurvePiece, x: f32, dir: Vec3A| {
            let origin = Vec3A::new(x, 0.0, 1.5) - dir * 3.0;
            intersect_curve::<false>(piece_kind(piece), piece, origin, dir, 10.0)
        };
        let slanted = Vec3A::new(60f32.to_radians().sin(), 60f32.to_radians().cos(), 0.0);
        for dir in [Vec3A::Y, slanted] {
            assert!(at(&ribbon, 0.24, dir).is_some() && at(&ribbon, 0.26, dir).is_none());
        }
        // The flat curve's axis is 0.5 x from this ray: within 0.25 up to x = 0.5.
        assert!(at(&flat, 0.45, slanted).is_some() && at(&flat, 0.55, slanted).is_none());
    }

    /// The bounding-sphere test only spares work: over random rays near
    /// bent pieces of every kind, the test with it finds exactly the hits
    /// the test without it finds.
    #[test]
    fn the_bounding_sphere_rejects_no_hit() {
        let c = [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::new(2.0, -1.0, 1.0), Vec3::new(3.0, 0.0, 0.0)];
        let mut state = 12345u32;
        let mut rnd = || {
            state = state.wrapping_mul(747796405).wrapping_add(2891336453);
            (state >> 8) as f32 / (1u32 << 24) as f32
        };
        let mut hits = 0;
        for kind in [CurveKind::Flat, CurveKind::Cylinder, CurveKind::Ribbon] {
            let curves = Curves::from_segments(kind, &[c], (0.3, 0.1), &[Vec3::Y, Vec3::Z], 4);
            for piece in &curves.pieces {
                for _ in 0..2000 {
                    let target = Vec3A::new(3.0 * rnd(), 2.0 * rnd() - 1.0, 1.2 * rnd() - 0.1);
                    let dir = Vec3A::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5) * (0.1 + 4.0 * rnd());
                    let origin = target - dir * (0.5 + 3.0 * rnd());
                    let t_max = 1.0 + 4.0 * rnd();
                    let full = subdivide::<false>(kind, piece, &piece.points_a(), origin, dir, t_max);
                    assert_eq!(intersect_curve::<false>(kind, piece, origin, dir, t_max), full);
                    hits += usize::from(full.is_some());
                }
            }
        }
        assert!(hits > 300, "{hits} hits");
    }

    #[test]
    fn depth_grows_with_bend_over_width() {
        let cp =
            [Vec3A::ZERO, Vec3A::new(1.0, 1.0, 0.0), Vec3A::new(2.0, -1.0, 0.0), Vec3A::new(3.0, 0.0, 0.0)];
        assert!(refinement_depth(&cp, [0.01, 0.01]) > refinement_depth(&cp, [0.5, 0.5]));
        assert_eq!(refinement_depth(&cp, [0.0, 0.0]), MAX_CURVE_DEPTH);
        let line = [Vec3A::ZERO, Vec3A::X, Vec3A::X * 2.0, Vec3A::X * 3.0];
        assert_eq!(refinement_depth(&line, [0.01, 0.01]), 0);
        assert_eq!(log2_int(1.0), 0);
        assert_eq!(log2_int(1.5), 1);
        assert_eq!(log2_int(1.4), 0);
        assert_eq!(log2_int(1024.0), 10);
    }
}
