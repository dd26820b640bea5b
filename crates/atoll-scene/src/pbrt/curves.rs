//! pbrt-v4's `curve` shape as triangles: each cubic segment is cut into as
//! few pieces as keep their chords within an eighth of the curve's width of
//! it ([`pieces_for`]), at most 2^`splitdepth` (pbrt splits it as many times
//! before intersecting the pieces exactly), and the pieces are swept into
//! - a tube of [`TUBE_SIDES`] sides for `cylinder` and `flat` curves (pbrt
//!   turns a flat curve to face each ray; a tube shows the same width from
//!   every side), with normals pointing away from the curve;
//! - a strip for `ribbon` curves, turned about the curve to lie across the
//!   normals `N` given at the segments' ends (pbrt's orientation).
//!
//! Parameters as in pbrt-v4's `CreateCurves`: `P` (4 + 3k points for the
//! `bezier` basis, at least 4 for `bspline`, converted to Bézier segments),
//! `degree` (3, or 2), `width` (1) or `width0`/`width1` along the whole
//! curve, `N` for ribbons, `splitdepth` (3). (u, v) run along the whole
//! curve and across it.

use glam::{Vec2, Vec3};

use crate::error::{FileLoc, SceneError};

use super::params::ParamList;
use super::shapes::ShapeMesh;

/// Sides of the tube a `cylinder` or `flat` curve becomes.
pub const TUBE_SIDES: u32 = 4;

/// The most pieces a segment is cut into (pbrt's `splitdepth` above 4 only
/// refines its exact intersection, which tessellation cannot follow).
const MAX_PIECES: u32 = 16;

/// How a curve is swept.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Sweep {
    Tube,
    Ribbon,
}

/// The cubic Bézier segments of `P` in the `basis` and `degree` given.
fn bezier_segments(
    p: &[Vec3],
    basis: &str,
    degree: i64,
    loc: &FileLoc,
) -> Result<Vec<[Vec3; 4]>, SceneError> {
    let bad = |msg: String| Err(SceneError::at(loc, format!("curve: {msg}")));
    let d = degree as usize;
    match (basis, degree) {
        ("bezier", 2 | 3) => {
            if p.len() < d + 1 || !(p.len() - 1).is_multiple_of(d) {
                return bad(format!(
                    "a degree {d} Bézier curve needs {d}k + 1 points \"P\", got {}",
                    p.len()
                ));
            }
            Ok(p.windows(d + 1).step_by(d).map(cubic).collect())
        }
        ("bspline", 2 | 3) => {
            if p.len() < d + 1 {
                return bad(format!("a degree {d} B-spline curve needs at least {} points \"P\"", d + 1));
            }
            Ok(p.windows(d + 1).map(bspline_to_bezier).collect())
        }
        ("bezier" | "bspline", _) => bad(format!("\"degree\" {degree} is not 2 or 3")),
        _ => bad(format!("unknown \"basis\" \"{basis}\" (expected bezier or bspline)")),
    }
}

/// A Bézier segment of degree 2 or 3 as a cubic one (degree elevation).
fn cubic(w: &[Vec3]) -> [Vec3; 4] {
    match w {
        [a, b, c] => [*a, *a + (*b - *a) * (2.0 / 3.0), *c + (*b - *c) * (2.0 / 3.0), *c],
        [a, b, c, d] => [*a, *b, *c, *d],
        _ => unreachable!("degree 2 or 3"),
    }
}

/// The Bézier form of one uniform B-spline segment of degree 2 or 3.
fn bspline_to_bezier(w: &[Vec3]) -> [Vec3; 4] {
    match w {
        [a, b, c] => cubic(&[(*a + *b) * 0.5, *b, (*b + *c) * 0.5]),
        [a, b, c, d] => [
            (*a + *b * 4.0 + *c) / 6.0,
            (*b * 2.0 + *c) / 3.0,
            (*b + *c * 2.0) / 3.0,
            (*b + *c * 4.0 + *d) / 6.0,
        ],
        _ => unreachable!("degree 2 or 3"),
    }
}

fn bezier_point(c: &[Vec3; 4], t: f32) -> Vec3 {
    let s = 1.0 - t;
    c[0] * (s * s * s) + c[1] * (3.0 * s * s * t) + c[2] * (3.0 * s * t * t) + c[3] * (t * t * t)
}

fn bezier_tangent(c: &[Vec3; 4], t: f32) -> Vec3 {
    let s = 1.0 - t;
    (c[1] - c[0]) * (3.0 * s * s) + (c[2] - c[1]) * (6.0 * s * t) + (c[3] - c[2]) * (3.0 * t * t)
}

/// Any unit vector perpendicular to unit `t`.
fn perpendicular(t: Vec3) -> Vec3 {
    let axis = if t.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    t.cross(axis).normalize()
}

/// The curve's triangles (`Shape "curve" params`).
pub fn curve(p: &ParamList, loc: &FileLoc) -> Result<ShapeMesh, SceneError> {
    let points = p.point3s("P").unwrap_or_default();
    let basis = p.string("basis")?.unwrap_or_else(|| "bezier".into());
    let degree = p.int("degree")?.unwrap_or(3);
    let segments = bezier_segments(&points, &basis, degree, loc)?;
    let sweep = match p.string("type")?.as_deref().unwrap_or("flat") {
        "flat" | "cylinder" => Sweep::Tube,
        "ribbon" => Sweep::Ribbon,
        other => {
            return Err(SceneError::at(
                loc,
                format!("curve: unknown \"type\" \"{other}\" (expected flat, ribbon or cylinder)"),
            ))
        }
    };
    let width = p.float_or("width", 1.0)?;
    let (w0, w1) = (p.float_or("width0", width)?, p.float_or("width1", width)?);
    if !(w0 >= 0.0 && w1 >= 0.0) {
        return Err(SceneError::at(loc, "curve: widths must not be negative"));
    }
    let normals = p.normals("N").unwrap_or_default();
    if sweep == Sweep::Ribbon && normals.len() != segments.len() + 1 {
        return Err(SceneError::at(
            loc,
            format!(
                "curve: a ribbon needs one normal \"N\" per segment end ({}), got {}",
                segments.len() + 1,
                normals.len()
            ),
        ));
    }
    let split = p.int("splitdepth")?.unwrap_or(3).clamp(0, 8) as u32;
    let pieces = (1u32 << split).min(MAX_PIECES);
    Ok(sweep_segments(&segments, sweep, (w0, w1), &normals, pieces))
}

/// The triangles a curve gets when its segments are cut into `pieces` in all.
#[cfg(test)]
fn triangles_of(pieces: u32, ribbon: bool) -> u64 {
    let per_piece = if ribbon { 2 } else { 2 * TUBE_SIDES as u64 };
    pieces as u64 * per_piece
}

/// Pieces a cubic segment `c` of width `width` is cut into: as few as keep
/// each piece's chord within `width / 8` of the curve (a four-sided tube
/// departs from the round fibre by about that much already), at most
/// `max_pieces`. A chord over a parameter interval `1 / n` departs from the
/// curve by at most `max |B''| / (8 n²)`, and `|B''| ≤ 6 max_i |P_i -
/// 2 P_i+1 + P_i+2|`. Hair strands are short, nearly straight segments: a
/// piece or two each instead of `max_pieces`.
fn pieces_for(c: &[Vec3; 4], width: f32, max_pieces: u32) -> u32 {
    let bend = (c[0] - 2.0 * c[1] + c[2]).length().max((c[1] - 2.0 * c[2] + c[3]).length());
    if width <= 0.0 {
        return max_pieces;
    }
    let n = (6.0 * bend / width).sqrt().ceil();
    if n.is_finite() {
        (n as u32).clamp(1, max_pieces)
    } else {
        max_pieces
    }
}

fn sweep_segments(
    segments: &[[Vec3; 4]],
    sweep: Sweep,
    (w0, w1): (f32, f32),
    normals: &[Vec3],
    max_pieces: u32,
) -> ShapeMesh {
    // A tube is one surface, as pbrt's curve is: light leaving through it
    // must not stop at its far wall.
    let tube = sweep == Sweep::Tube;
    let mut m = ShapeMesh { name: "curve".into(), transparent_back_faces: tube, ..Default::default() };
    // The rings' (segment, t): each segment's pieces, then the curve's end.
    let width_at = |u: f32| w0 + (w1 - w0) * u;
    let count = segments.len() as f32;
    let mut at: Vec<(usize, f32)> = Vec::new();
    for (s, c) in segments.iter().enumerate() {
        let width = 0.5 * (width_at(s as f32 / count) + width_at((s + 1) as f32 / count));
        let n = pieces_for(c, width, max_pieces);
        at.extend((0..n).map(|k| (s, k as f32 / n as f32)));
    }
    at.push((segments.len() - 1, 1.0));
    let rings = at.len() as u32;
    // A frame carried along the curve with the least twist (a tube's sides
    // do not spin about it from one ring to the next).
    let mut side = Vec3::ZERO;
    let cross_count = if sweep == Sweep::Tube { TUBE_SIDES + 1 } else { 2 };
    for &(s, t) in &at {
        let c = &segments[s];
        // u runs along the whole curve, a segment's share each.
        let u = (s as f32 + t) / count;
        let (center, tangent) = (bezier_point(c, t), bezier_tangent(c, t).normalize_or_zero());
        let tangent = if tangent == Vec3::ZERO { (c[3] - c[0]).normalize_or(Vec3::Z) } else { tangent };
        let radius = 0.5 * width_at(u);
        match sweep {
            Sweep::Tube => {
                side = if side == Vec3::ZERO { perpendicular(tangent) } else { side };
                side = (side - tangent * side.dot(tangent)).normalize_or(perpendicular(tangent));
                let up = tangent.cross(side);
                for k in 0..cross_count {
                    let phi = std::f32::consts::TAU * (k % TUBE_SIDES) as f32 / TUBE_SIDES as f32;
                    let out = side * phi.cos() + up * phi.sin();
                    m.positions.push(center + out * radius);
                    m.normals.push(out);
                    m.uvs.push(Vec2::new(u, k as f32 / TUBE_SIDES as f32));
                }
            }
            Sweep::Ribbon => {
                // The normal between the segment's end normals (pbrt
                // interpolates them by angle), made perpendicular to the curve.
                let (n0, n1) = (normals[s].normalize_or_zero(), normals[s + 1].normalize_or_zero());
                let n = (n0 * (1.0 - t) + n1 * t).normalize_or(n0);
                let n = (n - tangent * n.dot(tangent)).normalize_or(perpendicular(tangent));
                let across = tangent.cross(n);
                for k in 0..cross_count {
                    m.positions.push(center + across * (radius * (2.0 * k as f32 - 1.0)));
                    m.normals.push(n);
                    m.uvs.push(Vec2::new(u, k as f32));
                }
            }
        }
    }
    for ring in 0..rings - 1 {
        for k in 0..cross_count - 1 {
            let (a, b) = (ring * cross_count + k, (ring + 1) * cross_count + k);
            let (c, d) = (b + 1, a + 1);
            for tri in [[a, b, c], [a, c, d]] {
                let [p0, p1, p2] = tri.map(|i| m.positions[i as usize]);
                let n = (p0 - p2).cross(p1 - p2);
                if n.length_squared() == 0.0 {
                    continue;
                }
                let shading: Vec3 = tri.iter().map(|&i| m.normals[i as usize]).sum();
                m.indices.push(if n.dot(shading) < 0.0 { [tri[0], tri[2], tri[1]] } else { tri });
            }
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(n: usize) -> Vec<Vec3> {
        (0..n).map(|i| Vec3::new(0.0, 0.0, i as f32)).collect()
    }

    /// Tubes are wound outwards (their back faces are their inside) and
    /// say so; ribbons are two-sided surfaces.
    #[test]
    fn tubes_are_wound_outwards() {
        let curve =
            [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::new(2.0, -1.0, 1.0), Vec3::new(3.0, 0.0, 0.0)];
        let m = sweep_segments(&[curve], Sweep::Tube, (0.2, 0.1), &[], 8);
        assert!(m.transparent_back_faces);
        for t in &m.indices {
            let [p0, p1, p2] = t.map(|i| m.positions[i as usize]);
            let outward: Vec3 = t.iter().map(|&i| m.normals[i as usize]).sum();
            assert!((p0 - p2).cross(p1 - p2).dot(outward) > 0.0, "{t:?}");
        }
        let normals = [Vec3::Z, Vec3::Z];
        assert!(!sweep_segments(&[curve], Sweep::Ribbon, (0.2, 0.1), &normals, 8).transparent_back_faces);
    }

    #[test]
    fn a_straight_cylinder_curve_is_a_tube_of_its_width() {
        let seg = bezier_segments(&line(4), "bezier", 3, &FileLoc::whole_file("c")).unwrap();
        let m = sweep_segments(&seg, Sweep::Tube, (0.2, 0.2), &[], 8);
        assert_eq!(m.indices.len() as u64, triangles_of(1, false), "a straight segment is one piece");
        for (p, n) in m.positions.iter().zip(&m.normals) {
            assert!((p.truncate().length() - 0.1).abs() < 1e-5, "{p}");
            assert!(
                (n.truncate().normalize() - p.truncate().normalize()).length() < 1e-4 && n.z.abs() < 1e-5
            );
            assert!((-1e-5..=3.0 + 1e-5).contains(&p.z));
        }
        for t in &m.indices {
            let [p0, p1, p2] = t.map(|i| m.positions[i as usize]);
            let centre = (p0 + p1 + p2) / 3.0;
            assert!((p0 - p2).cross(p1 - p2).dot(centre.truncate().extend(0.0)) > 0.0, "faces out");
        }
        // Tapering: width0 at the start, width1 at the end.
        let m = sweep_segments(&seg, Sweep::Tube, (0.2, 0.0), &[], 2);
        assert!(m.positions.iter().filter(|p| p.z > 3.0 - 1e-5).all(|p| p.truncate().length() < 1e-6));
    }

    /// A bent segment gets as many pieces as keep the swept centre line
    /// within an eighth of the width of the curve, and no more than asked.
    #[test]
    fn bent_segments_get_pieces_by_their_bend_and_width() {
        let c = [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::new(2.0, -1.0, 0.0), Vec3::new(3.0, 0.0, 0.0)];
        for (width, max) in [(0.02, 64), (0.1, 64), (0.5, 64), (0.02, 8)] {
            let n = pieces_for(&c, width, max);
            assert!(n <= max && n >= 1);
            let m = sweep_segments(&[c], Sweep::Ribbon, (width, width), &[Vec3::Z, Vec3::Z], max);
            assert_eq!(m.indices.len() as u64, triangles_of(n, true));
            if n == max && pieces_for(&c, width, 2 * max) > max {
                continue; // capped: coarser than the tolerance by request
            }
            // The centre line of each piece (its ribbon's two edges averaged)
            // against the curve between them.
            let centre: Vec<Vec3> = m.positions.chunks(2).map(|p| 0.5 * (p[0] + p[1])).collect();
            for (k, w) in centre.windows(2).enumerate() {
                for j in 1..8 {
                    let f = j as f32 / 8.0;
                    let on_curve = bezier_point(&c, (k as f32 + f) / n as f32);
                    let chord = w[0] + (w[1] - w[0]) * f;
                    assert!((on_curve - chord).length() <= width / 8.0 + 1e-5, "width {width}, piece {k}");
                }
            }
        }
        assert!(pieces_for(&c, 0.02, 64) > pieces_for(&c, 0.5, 64), "thinner curves need more pieces");
        assert_eq!(pieces_for(&c, 0.0, 16), 16, "a zero width takes the most");
    }

    #[test]
    fn bases_and_degrees_give_the_same_line() {
        let loc = FileLoc::whole_file("c");
        let cubic = bezier_segments(&line(7), "bezier", 3, &loc).unwrap();
        assert_eq!(cubic.len(), 2);
        let quadratic = bezier_segments(&line(5), "bezier", 2, &loc).unwrap();
        assert_eq!(quadratic.len(), 2);
        assert_eq!(bezier_segments(&line(6), "bspline", 3, &loc).unwrap().len(), 3);
        // A uniform B-spline over evenly spaced points on a line is the line.
        for s in bezier_segments(&line(6), "bspline", 3, &loc).unwrap() {
            assert!(s.windows(2).all(|w| (w[1].z - w[0].z - 1.0 / 3.0).abs() < 1e-5), "{s:?}");
        }
        assert!(bezier_segments(&line(5), "bezier", 3, &loc).is_err());
        assert!(bezier_segments(&line(4), "nurbs", 3, &loc).is_err());
        assert!(bezier_segments(&line(4), "bezier", 4, &loc).is_err());
    }

    #[test]
    fn ribbons_lie_across_their_normals() {
        let seg = bezier_segments(&line(4), "bezier", 3, &FileLoc::whole_file("c")).unwrap();
        let m = sweep_segments(&seg, Sweep::Ribbon, (0.5, 0.5), &[Vec3::X, Vec3::X], 4);
        assert_eq!(m.indices.len() as u64, triangles_of(1, true));
        assert!(m.positions.iter().all(|p| p.x.abs() < 1e-6 && (p.y.abs() - 0.25).abs() < 1e-6));
        assert!(m.normals.iter().all(|n| *n == Vec3::X));
    }
}
