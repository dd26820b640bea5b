//! Bump and normal maps: the shading normal bent by a material's
//! displacement texture or normal-map image, as pbrt-v4's `BumpMap` and
//! `NormalMap` bend it (the surface itself stays where it is). The CUDA
//! port (`kernels/bump.cuh`) does the same arithmetic.
//!
//! Both work in the triangle's (u, v) parameterisation: its partial
//! derivatives dp/du, dp/dv (pbrt's `Triangle` rules, a frame about the
//! normal where the uvs are degenerate), turned into pbrt's shading
//! partials where the mesh has normals. Departures from pbrt: the bump's
//! finite-difference step is pbrt's fallback of 0.0005 in (u, v) (pbrt
//! shrinks it with the pixel's footprint, from ray differentials atoll
//! does not track), and the normal's own change over the surface (pbrt's
//! `dndu`, `dndv` times the displacement) is left out.

use glam::{Vec2, Vec3};

/// How a material bends its shading normal ([`ShadingNormalProgram::kind`]).
pub mod kind {
    /// Not at all.
    pub const NONE: u32 = 0;
    /// A float texture of displacement along the normal (its first channel).
    pub const BUMP: u32 = 1;
    /// An RGB texture of tangent-space normals.
    pub const NORMAL_MAP: u32 = 2;
}

/// pbrt's finite-difference step in (u, v) where the pixel's footprint is unknown.
pub const BUMP_STEP: f32 = 0.0005;

/// pbrt's `CoordinateSystem`: two unit vectors completing unit `v` to a
/// frame (the BSDF's frame, which is the same construction).
fn coordinate_system(v: Vec3) -> (Vec3, Vec3) {
    let frame = crate::bsdf::Frame::from_z(v);
    (frame.x, frame.y)
}

/// A triangle's dp/du and dp/dv from its corners `p` and their `uv`s
/// (pbrt's `Triangle::InteractionFromIntersection`); a frame about the unit
/// normal `ng` where the uvs give none.
pub fn triangle_partials(p: [Vec3; 3], uv: [Vec2; 3], ng: Vec3) -> (Vec3, Vec3) {
    let (duv02, duv12) = (uv[0] - uv[2], uv[1] - uv[2]);
    let (dp02, dp12) = (p[0] - p[2], p[1] - p[2]);
    let det = duv02.x * duv12.y - duv02.y * duv12.x;
    if det.abs() >= 1e-9 {
        let inv = 1.0 / det;
        let dpdu = (dp02 * duv12.y - dp12 * duv02.y) * inv;
        let dpdv = (dp12 * duv02.x - dp02 * duv12.x) * inv;
        if dpdu.cross(dpdv).length_squared() > 0.0 && dpdu.is_finite() && dpdv.is_finite() {
            return (dpdu, dpdv);
        }
    }
    coordinate_system(ng)
}

/// The surface at a hit, as bump and normal mapping see it.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceAt {
    pub position: Vec3,
    pub uv: Vec2,
    /// Unit geometric normal, on the side of the shading normal.
    pub ng: Vec3,
    /// Unit shading normal.
    pub ns: Vec3,
    /// The triangle's partial derivatives ([`triangle_partials`]).
    pub dpdu: Vec3,
    pub dpdv: Vec3,
    /// Whether the shading normal is the mesh's (interpolated normals):
    /// pbrt's shading partials are then turned about it.
    pub interpolated: bool,
}

impl SurfaceAt {
    /// pbrt's shading dp/du, dp/dv: the triangle's where the shading normal
    /// is the geometric one, else dp/du made perpendicular to it and its
    /// cross product with the normal.
    pub fn shading_partials(&self) -> (Vec3, Vec3) {
        if !self.interpolated {
            return (self.dpdu, self.dpdv);
        }
        let ts = self.ns.cross(self.dpdu);
        if ts.length_squared() > 0.0 {
            (ts.cross(self.ns), ts)
        } else {
            coordinate_system(self.ns)
        }
    }
}

/// A surface's shading geometry after bump or normal mapping: pbrt's
/// shading normal and `dpdu`, the BSDF frame's z and x axes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bent {
    /// Unit; on the geometric normal's side.
    pub normal: Vec3,
    /// Not unit, not necessarily perpendicular to `normal`: the frame makes
    /// it so ([`crate::bsdf::Frame::from_xz`]), which for bump maps leaves
    /// it as pbrt has it (perpendicular already) and for normal maps is
    /// pbrt's Gram–Schmidt step.
    pub dpdu: Vec3,
}

/// The shading geometry `surface` gets from a material that bends it by
/// `kind`, its texture evaluated by `eval` at (uv, point); the unbent
/// normal where the result is no direction. Faces the geometric normal's
/// side (pbrt's `SetShadingGeometry`, orientation not authoritative).
///
/// A bump map's finite differences step half the footprint's uv change
/// (`duv`: its `(dudx, dvdx)` and `(dudy, dvdy)`), [`BUMP_STEP`] where that
/// is 0, as pbrt-v4's `BumpMap` steps.
pub fn bent_normal(
    kind: u32,
    surface: &SurfaceAt,
    duv: [Vec2; 2],
    mut eval: impl FnMut(Vec2, Vec3) -> Vec3,
) -> Bent {
    let (ss, ts) = surface.shading_partials();
    let (n, dpdu) = match kind {
        kind::BUMP => {
            let d = eval(surface.uv, surface.position).x;
            let step = |a: f32, b: f32| match 0.5 * (a.abs() + b.abs()) {
                0.0 => BUMP_STEP,
                s => s,
            };
            let (step_u, step_v) = (step(duv[0].x, duv[1].x), step(duv[0].y, duv[1].y));
            let du = eval(surface.uv + Vec2::new(step_u, 0.0), surface.position + ss * step_u).x;
            let dv = eval(surface.uv + Vec2::new(0.0, step_v), surface.position + ts * step_v).x;
            let dpdu = ss + surface.ns * ((du - d) / step_u);
            let dpdv = ts + surface.ns * ((dv - d) / step_v);
            (dpdu.cross(dpdv).normalize_or_zero(), dpdu)
        }
        kind::NORMAL_MAP => {
            let c = eval(surface.uv, surface.position);
            let local = (c * 2.0 - Vec3::ONE).normalize_or_zero();
            let x = ss.normalize_or_zero();
            let y = surface.ns.cross(x);
            ((x * local.x + y * local.y + surface.ns * local.z).normalize_or_zero(), ss)
        }
        _ => (Vec3::ZERO, ss),
    };
    if n == Vec3::ZERO || !n.is_finite() {
        return Bent { normal: surface.ns, dpdu: ss };
    }
    Bent { normal: if n.dot(surface.ng) < 0.0 { -n } else { n }, dpdu }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat(interpolated: bool) -> SurfaceAt {
        SurfaceAt {
            position: Vec3::new(0.3, 0.4, 0.0),
            uv: Vec2::new(0.3, 0.4),
            ng: Vec3::Z,
            ns: Vec3::Z,
            dpdu: Vec3::X,
            dpdv: Vec3::Y,
            interpolated,
        }
    }

    #[test]
    fn partials_follow_the_uvs() {
        let p = [Vec3::ZERO, Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 4.0, 0.0)];
        let uv = [Vec2::ZERO, Vec2::X, Vec2::Y];
        assert_eq!(triangle_partials(p, uv, Vec3::Z), (Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 4.0, 0.0)));
        // Degenerate uvs: a frame about the normal.
        let (a, b) = triangle_partials(p, [Vec2::ZERO; 3], Vec3::Z);
        assert!(a.dot(Vec3::Z).abs() < 1e-6 && b.dot(Vec3::Z).abs() < 1e-6 && a.cross(b).length() > 0.99);
    }

    /// A height field d = a·u tilts the normal by atan(a) against +u, as the
    /// surface z = a·u would; a constant one bends nothing.
    #[test]
    fn bumps_tilt_the_normal_as_the_displaced_surface() {
        for interpolated in [false, true] {
            let s = flat(interpolated);
            let tilted = bent_normal(kind::BUMP, &s, [Vec2::ZERO; 2], |uv, _| Vec3::splat(0.5 * uv.x));
            let expected = Vec3::new(-0.5, 0.0, 1.0).normalize();
            assert!((tilted.normal - expected).length() < 1e-3, "{tilted:?}");
            // dp/du climbs the slope, perpendicular to the bent normal.
            assert!((tilted.dpdu - Vec3::new(1.0, 0.0, 0.5)).length() < 1e-3, "{tilted:?}");
            assert_eq!(bent_normal(kind::BUMP, &s, [Vec2::ZERO; 2], |_, _| Vec3::splat(0.7)).normal, Vec3::Z);
        }
        // Read at the point as well as the uv: the same slope from p.
        let by_point =
            bent_normal(kind::BUMP, &flat(false), [Vec2::ZERO; 2], |_, p| Vec3::splat(0.5 * p.x)).normal;
        assert!((by_point - Vec3::new(-0.5, 0.0, 1.0).normalize()).length() < 1e-3, "{by_point}");
    }

    #[test]
    fn normal_maps_are_tangent_space_normals() {
        let s = flat(true);
        // (0.5, 0.5, 1) is the unbent normal; (1, 0.5, 0.5) points along +u.
        assert!(
            (bent_normal(kind::NORMAL_MAP, &s, [Vec2::ZERO; 2], |_, _| Vec3::new(0.5, 0.5, 1.0)).normal
                - Vec3::Z)
                .length()
                < 1e-6
        );
        let along_u =
            bent_normal(kind::NORMAL_MAP, &s, [Vec2::ZERO; 2], |_, _| Vec3::new(1.0, 0.5, 0.75)).normal;
        assert!((along_u - Vec3::new(1.0, 0.0, 0.5).normalize()).length() < 1e-5, "{along_u}");
        // Never below the surface: flipped to the geometric normal's side.
        let under =
            bent_normal(kind::NORMAL_MAP, &s, [Vec2::ZERO; 2], |_, _| Vec3::new(0.5, 0.5, 0.0)).normal;
        assert!(under.dot(Vec3::Z) >= 0.0, "{under}");
    }
}
