//! pbrt-v4's `curve` shape: its control points become cubic Bézier
//! segments, each cut into `2^splitdepth` pieces (as pbrt's
//! `CreateCurves` does), which traversal intersects exactly
//! ([`crate::curve`]).
//!
//! Parameters as in pbrt-v4: `P` (4 + 3k points for the `bezier` basis,
//! at least 4 for `bspline`, converted to Bézier segments), `degree` (3,
//! or 2), `type` (`flat`, `cylinder`, `ribbon`), `width` (1) or
//! `width0`/`width1` along the whole curve, `N` for ribbons (one per
//! segment end), `splitdepth` (3).

use glam::Vec3;

use crate::curve::{CurveKind, Curves};

use crate::error::{FileLoc, SceneError};

use super::params::ParamList;
use super::shapes::ShapeMesh;

/// The deepest `splitdepth` taken (256 pieces a segment); deeper ones are
/// clamped to it.
const MAX_SPLIT_DEPTH: i64 = 8;

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

/// The curve's pieces and their proxy triangles (`Shape "curve" params`).
pub fn curve(p: &ParamList, loc: &FileLoc) -> Result<ShapeMesh, SceneError> {
    let points = p.point3s("P").unwrap_or_default();
    let basis = p.string("basis")?.unwrap_or_else(|| "bezier".into());
    let degree = p.int("degree")?.unwrap_or(3);
    let segments = bezier_segments(&points, &basis, degree, loc)?;
    let kind = match p.string("type")?.as_deref().unwrap_or("flat") {
        "flat" => CurveKind::Flat,
        "cylinder" => CurveKind::Cylinder,
        "ribbon" => CurveKind::Ribbon,
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
    if kind == CurveKind::Ribbon && normals.len() != segments.len() + 1 {
        return Err(SceneError::at(
            loc,
            format!(
                "curve: a ribbon needs one normal \"N\" per segment end ({}), got {}",
                segments.len() + 1,
                normals.len()
            ),
        ));
    }
    let split = p.int("splitdepth")?.unwrap_or(3).clamp(0, MAX_SPLIT_DEPTH);
    // Drawn from the scene's budget before they are made (a piece is a primitive).
    let pieces = (segments.len() as u64).checked_mul(1 << split);
    super::shapes::generate("curve", pieces, loc)?;
    let curves = Curves::from_segments(kind, &segments, (w0, w1), &normals, 1 << split);
    let (positions, indices) = curves.proxy_triangles();
    Ok(ShapeMesh { name: "curve".into(), positions, indices, curves: Some(curves), ..Default::default() })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(n: usize) -> Vec<Vec3> {
        (0..n).map(|i| Vec3::new(0.0, 0.0, i as f32)).collect()
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
}
