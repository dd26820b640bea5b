//! pbrt-v4's quadrics (`sphere`, `disk`, `cylinder`) as triangle meshes in
//! object space, with pbrt's parameters and defaults, its (u, v)
//! parameterisation and its surface normal (which side an area light
//! emits from). Tessellating keeps one primitive, the triangle, in every
//! BVH, traversal and device; the steps below keep a disk's or cylinder's
//! area within 0.04% of the analytic one (1 − sin(2π/n)/(2π/n)).
//!
//! Each is a grid over (u, v) in [0, 1]², u along φ: vertices are made by
//! the shape's closure, and triangles that collapse (a pole, a disk's
//! centre) are left out. Triangles wind so that their geometric normal
//! ([`crate::TriangleMesh::geometric_normal`]) agrees with pbrt's surface
//! normal, which the vertex normals also carry.

use std::f32::consts::{PI, TAU};

use glam::{Vec2, Vec3};

use super::shapes::ShapeMesh;

/// Steps around a full circle (φ from 0 to 2π) of a disk or a cylinder;
/// a partial sweep takes its share, and at least four.
pub const PHI_STEPS: u32 = 128;
/// Steps around and from pole to pole of a full sphere: fewer than a
/// disk's, as a sphere has many more triangles per step (its area is
/// 0.3% short).
pub const SPHERE_STEPS: (u32, u32) = (64, 32);
/// The fewest steps of any partial sweep.
const MIN_PHI_STEPS: u32 = 4;

/// pbrt's `phimax` in degrees (clamped to 0–360) as radians, and the steps
/// to sweep it when a full turn takes `full_steps`.
fn phi_sweep(phimax_degrees: f32, full_steps: u32) -> (f32, u32) {
    let phimax = phimax_degrees.clamp(0.0, 360.0).to_radians();
    let steps = ((full_steps as f32 * phimax / TAU).ceil() as u32).max(MIN_PHI_STEPS);
    (phimax, steps)
}

/// `(sin, cos)` of `phi`, exact at the ends of a full turn so that a closed
/// sweep meets itself without a crack.
fn sin_cos_turn(phi: f32, full_turn: bool) -> (f32, f32) {
    if phi == 0.0 || (full_turn && phi >= TAU) {
        (0.0, 1.0)
    } else {
        phi.sin_cos()
    }
}

/// The grid of `u_steps` × `v_steps` quads of a shape whose vertex at
/// (u, v) is `at(u, v) = (position, normal)`.
fn grid(name: &str, u_steps: u32, v_steps: u32, at: impl Fn(f32, f32) -> (Vec3, Vec3)) -> ShapeMesh {
    let mut m = ShapeMesh { name: name.into(), ..Default::default() };
    for i in 0..=v_steps {
        let v = i as f32 / v_steps as f32;
        for j in 0..=u_steps {
            let u = j as f32 / u_steps as f32;
            let (p, n) = at(u, v);
            m.positions.push(p);
            m.normals.push(n);
            m.uvs.push(Vec2::new(u, v));
        }
    }
    let idx = |i: u32, j: u32| i * (u_steps + 1) + j;
    for i in 0..v_steps {
        for j in 0..u_steps {
            let (a, b, c, d) = (idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1));
            for t in [[a, b, c], [a, c, d]] {
                let [p0, p1, p2] = t.map(|k| m.positions[k as usize]);
                let n = (p0 - p2).cross(p1 - p2);
                if n == Vec3::ZERO {
                    continue;
                }
                let shading: Vec3 = t.iter().map(|&k| m.normals[k as usize]).sum();
                m.indices.push(if n.dot(shading) < 0.0 { [t[0], t[2], t[1]] } else { t });
            }
        }
    }
    m
}

/// pbrt-v4's `sphere`: `radius` (1), `zmin` (−radius), `zmax` (radius),
/// `phimax` (360). (u, v) = (φ / φmax, (θ − θ(zmin)) / (θ(zmax) − θ(zmin))),
/// θ measured from +z: v = 0 at `zmin`. The normal points out (in for a
/// negative radius, as pbrt's).
pub fn sphere(radius: f32, zmin: f32, zmax: f32, phimax_degrees: f32) -> ShapeMesh {
    let r = radius.abs();
    let (lo, hi) = (zmin.min(zmax).clamp(-r, r), zmin.max(zmax).clamp(-r, r));
    let ratio = |z: f32| if r > 0.0 { (z / r).clamp(-1.0, 1.0) } else { 0.0 };
    let (theta_lo, theta_hi) = (ratio(lo).acos(), ratio(hi).acos());
    let (phimax, u_steps) = phi_sweep(phimax_degrees, SPHERE_STEPS.0);
    let span = (theta_lo - theta_hi).abs();
    let v_steps = ((SPHERE_STEPS.1 as f32 * span / PI).ceil() as u32).max(1);
    let full = phimax >= TAU;
    grid("sphere", u_steps, v_steps, |u, v| {
        let theta = theta_lo + v * (theta_hi - theta_lo);
        // Exact poles, so the triangles that meet there collapse and go.
        let (sin_t, cos_t) = if v == 0.0 && lo <= -r {
            (0.0, -1.0)
        } else if v == 1.0 && hi >= r {
            (0.0, 1.0)
        } else {
            theta.sin_cos()
        };
        let (sin_p, cos_p) = sin_cos_turn(u * phimax, full);
        let n = Vec3::new(sin_t * cos_p, sin_t * sin_p, cos_t);
        (n * r, if radius < 0.0 { -n } else { n })
    })
}

/// pbrt-v4's `disk`: `height` (0), `radius` (1), `innerradius` (0),
/// `phimax` (360), in the plane z = height. (u, v) = (φ / φmax,
/// (radius − ρ) / (radius − innerradius)); the normal is +z.
pub fn disk(height: f32, radius: f32, inner_radius: f32, phimax_degrees: f32) -> ShapeMesh {
    let (phimax, u_steps) = phi_sweep(phimax_degrees, PHI_STEPS);
    let full = phimax >= TAU;
    grid("disk", u_steps, 1, |u, v| {
        let rho = radius + v * (inner_radius - radius);
        let (sin_p, cos_p) = sin_cos_turn(u * phimax, full);
        (Vec3::new(rho * cos_p, rho * sin_p, height), Vec3::Z)
    })
}

/// pbrt-v4's `cylinder`: `radius` (1), `zmin` (−1), `zmax` (1), `phimax`
/// (360), about the z axis, open at both ends. (u, v) = (φ / φmax,
/// (z − zmin) / (zmax − zmin)); the normal points out.
pub fn cylinder(radius: f32, zmin: f32, zmax: f32, phimax_degrees: f32) -> ShapeMesh {
    let (lo, hi) = (zmin.min(zmax), zmin.max(zmax));
    let (phimax, u_steps) = phi_sweep(phimax_degrees, PHI_STEPS);
    let full = phimax >= TAU;
    grid("cylinder", u_steps, 1, |u, v| {
        let (sin_p, cos_p) = sin_cos_turn(u * phimax, full);
        let out = Vec3::new(cos_p, sin_p, 0.0);
        let n = if radius < 0.0 { -out } else { out };
        (Vec3::new(radius * cos_p, radius * sin_p, lo + v * (hi - lo)), n)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area(m: &ShapeMesh) -> f32 {
        m.indices
            .iter()
            .map(|t| {
                let [p0, p1, p2] = t.map(|i| m.positions[i as usize]);
                0.5 * (p0 - p2).cross(p1 - p2).length()
            })
            .sum()
    }

    /// Every triangle's geometric normal agrees with its vertices' normals.
    fn faces_its_normals(m: &ShapeMesh) {
        assert!(!m.indices.is_empty());
        for t in &m.indices {
            let [p0, p1, p2] = t.map(|i| m.positions[i as usize]);
            let n = (p0 - p2).cross(p1 - p2);
            assert!(n.length() > 0.0, "{t:?} collapsed");
            for &k in t {
                assert!(n.dot(m.normals[k as usize]) > 0.0, "triangle {t:?} faces away from its normals");
            }
        }
    }

    fn relative(a: f32, b: f32) -> f32 {
        (a - b).abs() / b
    }

    #[test]
    fn a_full_sphere_is_closed_faces_out_and_has_pbrts_parameterisation() {
        let s = sphere(2.0, -2.0, 2.0, 360.0);
        faces_its_normals(&s);
        let (n_phi, n_theta) = SPHERE_STEPS;
        assert_eq!(s.indices.len() as u32, 2 * n_phi * (n_theta - 1), "one triangle per step at each pole");
        for (t, n) in s.indices.iter().flat_map(|t| t.map(|i| (t, s.normals[i as usize]))) {
            let c: Vec3 = t.iter().map(|&i| s.positions[i as usize]).sum();
            assert!(c.dot(n) > 0.0, "normals point out");
        }
        assert!(s.positions.iter().all(|p| (p.length() - 2.0).abs() < 1e-5));
        assert!(relative(area(&s), 4.0 * PI * 4.0) < 4e-3, "{}", area(&s));
        // pbrt: v = 0 at zmin (the -z pole), 1 at zmax; u = 1/4 at +y.
        for (p, uv) in s.positions.iter().zip(&s.uvs) {
            assert!((p.z + 2.0 * (PI * uv.y).cos()).abs() < 1e-4, "{p} {uv}");
            if uv.x == 0.25 && uv.y > 0.0 && uv.y < 1.0 {
                assert!(p.y > 0.0 && p.x.abs() < 1e-5, "{p}");
            }
        }
        // Closed: every edge is shared by two triangles.
        let mut edges = std::collections::HashMap::new();
        let key = |p: Vec3| (p * 1e4).round().as_ivec3().to_array();
        for t in &s.indices {
            for k in 0..3 {
                let (a, b) = (key(s.positions[t[k] as usize]), key(s.positions[t[(k + 1) % 3] as usize]));
                *edges.entry(if a < b { (a, b) } else { (b, a) }).or_insert(0) += 1;
            }
        }
        assert!(edges.values().all(|&c| c == 2), "open edges");
    }

    #[test]
    fn partial_spheres_keep_to_their_bounds() {
        let s = sphere(1.0, -0.5, 0.8, 90.0);
        faces_its_normals(&s);
        for p in &s.positions {
            assert!(p.z >= -0.5 - 1e-6 && p.z <= 0.8 + 1e-6 && p.x >= -1e-6 && p.y >= -1e-6, "{p}");
        }
        // A zone of height h has area 2π r h; a quarter of it here.
        assert!(relative(area(&s), 2.0 * PI * 1.3 / 4.0) < 4e-3, "{}", area(&s));
        // Reversed bounds are sorted, as in pbrt.
        assert_eq!(sphere(1.0, 0.8, -0.5, 90.0), s);
        // Negative radius: the same surface, normals in.
        let inner = sphere(-1.0, -1.0, 1.0, 360.0);
        faces_its_normals(&inner);
        assert!(inner.normals.iter().zip(&inner.positions).all(|(n, p)| n.dot(*p) < 0.0));
    }

    #[test]
    fn disks_face_up_with_pbrts_parameterisation() {
        let d = disk(0.5, 2.0, 0.0, 360.0);
        faces_its_normals(&d);
        assert!(d.normals.iter().all(|&n| n == Vec3::Z));
        assert!(d.positions.iter().all(|p| p.z == 0.5));
        assert!(relative(area(&d), PI * 4.0) < 1e-3, "{}", area(&d));
        // v = 0 at the rim, 1 at the centre (or the inner radius).
        for (p, uv) in d.positions.iter().zip(&d.uvs) {
            assert!((p.truncate().length() - 2.0 * (1.0 - uv.y)).abs() < 1e-5);
        }
        let annulus = disk(0.0, 2.0, 1.0, 180.0);
        faces_its_normals(&annulus);
        assert!(relative(area(&annulus), PI * 3.0 / 2.0) < 1e-3, "{}", area(&annulus));
        assert!(annulus.positions.iter().all(|p| p.y >= -1e-6));
    }

    #[test]
    fn cylinders_face_out_with_pbrts_parameterisation() {
        let c = cylinder(0.5, 1.0, 3.0, 360.0);
        faces_its_normals(&c);
        assert!(relative(area(&c), TAU * 0.5 * 2.0) < 1e-3, "{}", area(&c));
        for ((p, n), uv) in c.positions.iter().zip(&c.normals).zip(&c.uvs) {
            assert!((p.z - (1.0 + 2.0 * uv.y)).abs() < 1e-6);
            assert!((p.truncate().length() - 0.5).abs() < 1e-6 && n.dot(*p) > 0.0);
        }
        assert_eq!(cylinder(0.5, 3.0, 1.0, 360.0), c);
    }
}
