//! Curves: pbrt-v4's `curve` shape as a primitive of its own. A curve is
//! a chain of cubic Bézier segments, each cut into pieces (pbrt's
//! `splitdepth`); every piece is one BVH primitive, intersected exactly by
//! traversal (`atoll_bvh::curve`, and the GPU's `curve.cuh`).
//!
//! A mesh with curves ([`crate::TriangleMesh::curves`]) holds one
//! triangle per piece: the degenerate triangle `(lo, hi, hi)` spanning
//! the piece's bounding box ([`Curves::proxy_triangles`]). BVH builders,
//! partitioners, chunk tables and memory plans then handle curves as they
//! handle triangles, with the right bounds; traversal tests the piece
//! instead of the triangle, which never hits.
//!
//! The geometry follows pbrt-v4's `Curve`: flat curves are ribbons that
//! turn to face each ray, cylinder curves the same ribbon with a normal
//! turned across it as a tube's would be, ribbons lie across normals
//! given at the segment's ends. A piece's parameter `u` runs along its
//! segment (0 to 1 over the segment, as in pbrt), `v` across the curve.

use glam::{Vec3, Vec3A};

/// How a curve meets rays (pbrt's `type`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CurveKind {
    /// A ribbon turned to face every ray.
    #[default]
    Flat,
    /// A flat curve whose normal turns across it like a tube's.
    Cylinder,
    /// A ribbon lying across the normals given at its segment's ends.
    Ribbon,
}

impl CurveKind {
    /// The kind's number in device records (`CURVE_*` in the kernels).
    pub fn code(self) -> u32 {
        match self {
            CurveKind::Flat => 0,
            CurveKind::Cylinder => 1,
            CurveKind::Ribbon => 2,
        }
    }
}

/// One BVH primitive of a curve: the part `u[0]..u[1]` of a cubic Bézier
/// segment.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CurvePiece {
    /// The piece's own control points (the segment's, restricted to `u`).
    pub points: [Vec3; 4],
    /// The segment's width at its start and its end; it varies linearly
    /// with the segment's `u`.
    pub widths: [f32; 2],
    /// The range of the segment's parameter the piece covers.
    pub u: [f32; 2],
    /// Ribbons: the segment's unit normals at its ends (zero otherwise).
    pub normals: [Vec3; 2],
}

/// The pieces of one `curve` shape.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Curves {
    pub kind: CurveKind,
    pub pieces: Vec<CurvePiece>,
}

/// Where a ray meets a curve piece, as shading wants it ([`CurvePiece::surface`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurveSurface {
    /// ∂p/∂u along the segment.
    pub dpdu: Vec3,
    /// ∂p/∂v across the curve (its length the width there).
    pub dpdv: Vec3,
    /// `normalize(dpdu × dpdv)` (zero where that is degenerate).
    pub normal: Vec3,
    /// The curve's width at the hit (a ribbon's as the ray sees it).
    pub width: f32,
}

/// `a + (b - a) t`, as pbrt's `Lerp` (`(1 - t) a + t b`).
#[inline]
pub fn lerp(t: f32, a: f32, b: f32) -> f32 {
    (1.0 - t) * a + t * b
}

#[inline]
fn lerp3(t: f32, a: Vec3A, b: Vec3A) -> Vec3A {
    a * (1.0 - t) + b * t
}

/// The blossom `p(a, b, c)` of a cubic Bézier curve (de Casteljau with
/// three parameters): `p(u, u, u)` is the point at `u`, and the control
/// points of the part `[s, t]` are `p(s,s,s), p(s,s,t), p(s,t,t), p(t,t,t)`.
#[inline]
pub fn blossom(p: &[Vec3A; 4], a: f32, b: f32, c: f32) -> Vec3A {
    let q = [lerp3(a, p[0], p[1]), lerp3(a, p[1], p[2]), lerp3(a, p[2], p[3])];
    let r = [lerp3(b, q[0], q[1]), lerp3(b, q[1], q[2])];
    lerp3(c, r[0], r[1])
}

/// The control points of the part `[s, t]` of the curve `p`.
#[inline]
pub fn restrict(p: &[Vec3A; 4], s: f32, t: f32) -> [Vec3A; 4] {
    [blossom(p, s, s, s), blossom(p, s, s, t), blossom(p, s, t, t), blossom(p, t, t, t)]
}

/// The point at `t` of the cubic Bézier curve `p` and the derivative there.
#[inline]
pub fn evaluate(p: &[Vec3A; 4], t: f32) -> (Vec3A, Vec3A) {
    let q = [lerp3(t, p[0], p[1]), lerp3(t, p[1], p[2]), lerp3(t, p[2], p[3])];
    let r = [lerp3(t, q[0], q[1]), lerp3(t, q[1], q[2])];
    // The derivative of a cubic Bézier curve is 3 (r1 - r0) (for t in
    // (0, 1); pbrt's special case for an end where two points coincide
    // follows).
    let d = if (r[1] - r[0]).length_squared() > 0.0 {
        3.0 * (r[1] - r[0])
    } else if t < 0.5 {
        p[2] - p[0]
    } else {
        p[3] - p[1]
    };
    (lerp3(t, r[0], r[1]), d)
}

/// The angle between unit vectors `a` and `b`, accurate near 0 and π
/// (pbrt's `AngleBetween`).
pub fn angle_between(a: Vec3A, b: Vec3A) -> f32 {
    if a.dot(b) < 0.0 {
        std::f32::consts::PI - 2.0 * ((a + b).length() / 2.0).clamp(-1.0, 1.0).asin()
    } else {
        2.0 * ((b - a).length() / 2.0).clamp(-1.0, 1.0).asin()
    }
}

impl CurvePiece {
    /// The segment's width at its parameter `u`.
    #[inline]
    pub fn width_at(&self, u: f32) -> f32 {
        lerp(u, self.widths[0], self.widths[1])
    }

    /// The control points as `Vec3A`s.
    #[inline]
    pub fn points_a(&self) -> [Vec3A; 4] {
        self.points.map(Vec3A::from)
    }

    /// The box holding the piece: its control points' box grown by half
    /// the wider of its end widths (pbrt's `Curve::Bounds`).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let half = 0.5 * self.width_at(self.u[0]).max(self.width_at(self.u[1]));
        let lo = self.points.iter().fold(Vec3::INFINITY, |a, &p| a.min(p)) - Vec3::splat(half);
        let hi = self.points.iter().fold(Vec3::NEG_INFINITY, |a, &p| a.max(p)) + Vec3::splat(half);
        (lo, hi)
    }

    /// A ribbon's normal at the segment's `u`: its end normals turned into
    /// each other by angle (pbrt's spherical interpolation).
    pub fn ribbon_normal(&self, u: f32) -> Vec3A {
        let (n0, n1) = (Vec3A::from(self.normals[0]), Vec3A::from(self.normals[1]));
        let angle = angle_between(n0, n1);
        if angle == 0.0 {
            return n0;
        }
        let inv_sin = 1.0 / angle.sin();
        n0 * (((1.0 - u) * angle).sin() * inv_sin) + n1 * ((u * angle).sin() * inv_sin)
    }

    /// ∂p/∂u (along the segment) at the segment's parameter `u`.
    pub fn dpdu(&self, u: f32) -> Vec3A {
        let span = self.u[1] - self.u[0];
        let local = if span > 0.0 { (u - self.u[0]) / span } else { 0.0 };
        let (_, d) = evaluate(&self.points_a(), local.clamp(0.0, 1.0));
        if span > 0.0 {
            d / span
        } else {
            d
        }
    }

    /// The surface at a hit `(u, v)` of a ray along `dir` (in the piece's
    /// space), as pbrt-v4's `Curve::RecursiveIntersect` makes it.
    pub fn surface(&self, kind: CurveKind, u: f32, v: f32, dir: Vec3A) -> CurveSurface {
        let dpdu = self.dpdu(u);
        let mut width = self.width_at(u);
        let dpdv = match kind {
            CurveKind::Ribbon => {
                let n = self.ribbon_normal(u);
                width *= n.dot(dir).abs() / dir.length();
                n.cross(dpdu).normalize_or_zero() * width
            }
            CurveKind::Flat | CurveKind::Cylinder => {
                // Across the curve in the plane facing the ray.
                let across = dir.cross(dpdu).normalize_or_zero() * width;
                if kind == CurveKind::Flat {
                    across
                } else {
                    // Turned about dpdu by -θ, θ from -90° to 90° across
                    // the curve: the normal of a tube seen side on.
                    let theta = lerp(v, -90.0, 90.0).to_radians();
                    let axis = dpdu.normalize_or_zero();
                    across * theta.cos() - axis.cross(across) * theta.sin()
                }
            }
        };
        let normal = dpdu.cross(dpdv).normalize_or_zero();
        CurveSurface { dpdu: dpdu.into(), dpdv: dpdv.into(), normal: normal.into(), width }
    }
}

impl Curves {
    /// The pieces of the cubic Bézier `segments` of one curve, each cut
    /// into `pieces_per_segment` equal parameter ranges (pbrt's
    /// `2^splitdepth`); `widths` run linearly along the whole curve, and
    /// `normals` (ribbons: one per segment end) are normalised.
    pub fn from_segments(
        kind: CurveKind,
        segments: &[[Vec3; 4]],
        (w0, w1): (f32, f32),
        normals: &[Vec3],
        pieces_per_segment: u32,
    ) -> Curves {
        let count = segments.len() as f32;
        let n = pieces_per_segment.max(1);
        let mut pieces = Vec::with_capacity(segments.len() * n as usize);
        for (s, segment) in segments.iter().enumerate() {
            let widths = [lerp(s as f32 / count, w0, w1), lerp((s + 1) as f32 / count, w0, w1)];
            let ends = if kind == CurveKind::Ribbon {
                [normals[s].normalize_or_zero(), normals[s + 1].normalize_or_zero()]
            } else {
                [Vec3::ZERO; 2]
            };
            let p = segment.map(Vec3A::from);
            for k in 0..n {
                let u = [k as f32 / n as f32, (k + 1) as f32 / n as f32];
                let points = restrict(&p, u[0], u[1]).map(Vec3::from);
                pieces.push(CurvePiece { points, widths, u, normals: ends });
            }
        }
        Curves { kind, pieces }
    }

    /// The proxy triangles of the pieces (see the module's documentation):
    /// positions `lo, hi` per piece and the triangles `(lo, hi, hi)`.
    pub fn proxy_triangles(&self) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut positions = Vec::with_capacity(2 * self.pieces.len());
        let mut indices = Vec::with_capacity(self.pieces.len());
        for (i, piece) in self.pieces.iter().enumerate() {
            let (lo, hi) = piece.bounds();
            positions.extend([lo, hi]);
            let i = 2 * i as u32;
            indices.push([i, i + 1, i + 1]);
        }
        (positions, indices)
    }

    /// Moves the pieces by a transform given as its action on points and
    /// on normals, and its mean scale (`|det|^(1/3)`, which scales widths:
    /// exact for similarity transforms).
    pub fn transform(&mut self, point: impl Fn(Vec3) -> Vec3, normal: impl Fn(Vec3) -> Vec3, scale: f32) {
        for piece in &mut self.pieces {
            piece.points = piece.points.map(&point);
            piece.normals = piece.normals.map(|n| normal(n).normalize_or_zero());
            piece.widths = piece.widths.map(|w| w * scale);
        }
    }

    /// Bytes the pieces take in memory (device records are this size too).
    pub fn bytes(&self) -> u64 {
        (self.pieces.len() * CURVE_RECORD_BYTES) as u64
    }
}

/// Bytes of one piece's record on a device (control points, widths, the
/// parameter range and a ribbon's normals: six 16-byte words).
pub const CURVE_RECORD_BYTES: usize = 96;

#[cfg(test)]
mod tests {
    use super::*;

    fn bent() -> [Vec3; 4] {
        [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::new(2.0, -1.0, 1.0), Vec3::new(3.0, 0.0, 0.0)]
    }

    #[test]
    fn pieces_follow_their_segment() {
        let curves = Curves::from_segments(CurveKind::Flat, &[bent()], (0.2, 0.1), &[], 8);
        assert_eq!(curves.pieces.len(), 8);
        let whole = bent().map(Vec3A::from);
        for piece in &curves.pieces {
            let p = piece.points_a();
            for j in 0..=4 {
                let f = j as f32 / 4.0;
                let u = lerp(f, piece.u[0], piece.u[1]);
                assert!((evaluate(&p, f).0 - evaluate(&whole, u).0).length() < 1e-5);
                // Derivatives in the segment's parameter agree too.
                assert!((piece.dpdu(u) - evaluate(&whole, u).1).length() < 1e-4, "{u}");
            }
            assert_eq!(piece.widths, [0.2, 0.1]);
        }
        // Widths run along the whole curve: a second segment starts where the first ends.
        let two = Curves::from_segments(CurveKind::Flat, &[bent(), bent()], (0.2, 0.1), &[], 1);
        assert_eq!(two.pieces[0].widths, [0.2, 0.15]);
        assert_eq!(two.pieces[1].widths, [0.15, 0.1]);
    }

    #[test]
    fn proxies_bound_their_pieces() {
        let curves = Curves::from_segments(CurveKind::Flat, &[bent()], (0.2, 0.1), &[], 4);
        let (positions, indices) = curves.proxy_triangles();
        for (piece, tri) in curves.pieces.iter().zip(&indices) {
            let (lo, hi) = (positions[tri[0] as usize], positions[tri[1] as usize]);
            assert_eq!(tri[1], tri[2]);
            for j in 0..=16 {
                let (p, _) = evaluate(&piece.points_a(), j as f32 / 16.0);
                let p = Vec3::from(p);
                assert!(p.cmpge(lo + 0.05).all() && p.cmple(hi - 0.05).all(), "{p} in {lo}..{hi}");
            }
        }
    }

    #[test]
    fn ribbon_normals_turn_by_angle() {
        let piece = CurvePiece { normals: [Vec3::X, Vec3::Y], ..Default::default() };
        let mid = piece.ribbon_normal(0.5);
        assert!((mid - Vec3A::new(1.0, 1.0, 0.0).normalize()).length() < 1e-6);
        assert!((piece.ribbon_normal(0.25).length() - 1.0).abs() < 1e-6);
        assert!((angle_between(Vec3A::X, -Vec3A::X) - std::f32::consts::PI).abs() < 1e-6);
    }

    /// A straight curve along z seen along -y: a flat curve's normal faces
    /// along the ray, a cylinder's turns across it like a tube's.
    #[test]
    fn surfaces_face_as_pbrts() {
        let line = [Vec3::ZERO, Vec3::Z, Vec3::Z * 2.0, Vec3::Z * 3.0];
        let piece = Curves::from_segments(CurveKind::Flat, &[line], (0.5, 0.5), &[], 1).pieces[0];
        let dir = Vec3A::new(0.0, -1.0, 0.0);
        let flat = piece.surface(CurveKind::Flat, 0.5, 0.5, dir);
        assert!((flat.dpdu - Vec3::Z * 3.0).length() < 1e-5);
        assert!((flat.dpdv.length() - 0.5).abs() < 1e-6 && flat.dpdv.dot(Vec3::Y).abs() < 1e-6);
        assert!(flat.normal.y.abs() > 0.999);
        for (v, expect) in [(0.0, 1.0f32), (0.5, 0.0), (1.0, 1.0)] {
            let s = piece.surface(CurveKind::Cylinder, 0.5, v, dir);
            assert!((s.normal.x.abs() - expect).abs() < 1e-5, "v {v}: {}", s.normal);
            assert!(s.normal.z.abs() < 1e-5);
        }
        // The two edges of a cylinder curve face opposite ways.
        let (a, b) = (
            piece.surface(CurveKind::Cylinder, 0.5, 0.0, dir),
            piece.surface(CurveKind::Cylinder, 0.5, 1.0, dir),
        );
        assert!(a.normal.dot(b.normal) < -0.999);
        // A ribbon facing the ray shows its full width, one edge on less.
        let ribbon = CurvePiece { normals: [Vec3::Y, Vec3::Y], ..piece };
        assert!((ribbon.surface(CurveKind::Ribbon, 0.5, 0.5, dir).width - 0.5).abs() < 1e-6);
        let slanted = Vec3A::new(1.0, -1.0, 0.0);
        assert!(
            (ribbon.surface(CurveKind::Ribbon, 0.5, 0.5, slanted).width - 0.5 * 0.5f32.sqrt()).abs() < 1e-6
        );
    }
}
