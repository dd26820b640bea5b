//! Noise and the tessellated shapes the landscape is built from: geodesic
//! spheres (rocks, canopies, orbs), surfaces of revolution (trunks, conifer
//! canopies), a torus and faceted crystals. Every closed shape has its
//! geometric normals pointing outwards (pbrt's rule, see
//! [`TriangleMesh::geometric_normal`]), which dielectrics need to tell
//! entering from leaving rays.

use std::collections::HashMap;

use glam::Vec3;

use crate::TriangleMesh;

/// A 32-bit integer hash with good avalanche (Wellons' `lowbias32`).
pub fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^ (x >> 16)
}

/// Uniform in [0, 1) from a hash value (24 bits, exact in f32).
pub fn unit(h: u32) -> f32 {
    (h >> 8) as f32 / (1u32 << 24) as f32
}

/// Quintic fade: C2-continuous, so the heightfield's normals have no creases
/// at lattice lines (smoothstep would leave visible grid seams in the shading).
fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + (b - a) * t
}

/// Smooth 2D value noise in [0, 1) with lattice values hashed from `seed`.
pub fn value_noise2(x: f32, z: f32, seed: u32) -> f32 {
    let (fx, fz) = (x.floor(), z.floor());
    let (ix, iz) = (fx as i32, fz as i32);
    let (tx, tz) = (fade(x - fx), fade(z - fz));
    let at = |dx: i32, dz: i32| unit(hash((ix + dx) as u32 ^ hash((iz + dz) as u32 ^ seed)));
    lerp(lerp(at(0, 0), at(1, 0), tx), lerp(at(0, 1), at(1, 1), tx), tz)
}

/// Smooth 3D value noise in [0, 1) (for displacing shapes).
pub fn value_noise3(p: Vec3, seed: u32) -> f32 {
    let f = p.floor();
    let i = f.as_ivec3();
    let t = (p - f).to_array().map(fade);
    let at = |dx: i32, dy: i32, dz: i32| {
        unit(hash((i.x + dx) as u32 ^ hash((i.y + dy) as u32 ^ hash((i.z + dz) as u32 ^ seed))))
    };
    let plane =
        |dz| lerp(lerp(at(0, 0, dz), at(1, 0, dz), t[0]), lerp(at(0, 1, dz), at(1, 1, dz), t[0]), t[1]);
    lerp(plane(0), plane(1), t[2])
}

/// Fractal sum of `octaves` of 3D value noise (frequency x2, amplitude x0.5),
/// normalised back to [0, 1).
pub fn fbm3(p: Vec3, octaves: u32, seed: u32) -> f32 {
    let (mut sum, mut norm, mut amplitude, mut q) = (0.0, 0.0, 1.0, p);
    for octave in 0..octaves {
        sum += amplitude * value_noise3(q, hash(seed ^ octave));
        norm += amplitude;
        amplitude *= 0.5;
        q *= 2.03;
    }
    sum / norm
}

/// Adds area-weighted vertex normals (for smooth shading of displaced shapes).
pub fn with_normals(mut mesh: TriangleMesh) -> TriangleMesh {
    let mut normals = vec![Vec3::ZERO; mesh.positions.len()];
    for t in 0..mesh.triangle_count() {
        let n = mesh.geometric_normal(t);
        for &i in &mesh.indices[t] {
            normals[i as usize] += n;
        }
    }
    mesh.normals = normals.into_iter().map(Vec3::normalize_or_zero).collect();
    mesh
}

/// A geodesic sphere of radius 1: an icosahedron whose faces are split into
/// `frequency²` triangles each, projected onto the sphere (`20 f²` triangles,
/// `10 f² + 2` vertices, all about the same size, unlike a UV sphere), then
/// moved by `shape(direction)` (which returns the vertex position).
pub fn geodesic(name: &str, frequency: u32, shape: impl Fn(Vec3) -> Vec3) -> TriangleMesh {
    let f = frequency.max(1);
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let corners = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .map(Vec3::from_array);
    const FACES: [[u32; 3]; 20] = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let mut positions = Vec::with_capacity((10 * f * f + 2) as usize);
    let mut indices = Vec::with_capacity((20 * f * f) as usize);
    // A vertex is keyed by its integer weights on the icosahedron's corners,
    // sorted, so vertices on shared edges are found again exactly (a key on
    // float positions could split them by rounding and open cracks).
    let mut ids: HashMap<[(u32, u32); 3], u32> = HashMap::new();
    for face in FACES {
        let [c0, c1, c2] = face.map(|c| corners[c as usize]);
        // Wind each face outwards whatever order the table lists it in.
        let face = if (c1 - c0).cross(c2 - c0).dot(c0) < 0.0 { [face[0], face[2], face[1]] } else { face };
        let [c0, c1, c2] = face.map(|c| corners[c as usize]);
        let mut vertex = |a: u32, b: u32| -> u32 {
            let mut key = [(face[0], f - a - b), (face[1], a), (face[2], b)].map(|(c, w)| match w {
                0 => (u32::MAX, 0),
                _ => (c, w),
            });
            key.sort_unstable();
            *ids.entry(key).or_insert_with(|| {
                let p = c0 * (f - a - b) as f32 + c1 * a as f32 + c2 * b as f32;
                positions.push(shape(p.normalize()));
                (positions.len() - 1) as u32
            })
        };
        for a in 0..f {
            for b in 0..f - a {
                let (p, q, r) = (vertex(a, b), vertex(a + 1, b), vertex(a, b + 1));
                indices.push([p, q, r]);
                if b + 1 < f - a {
                    indices.push([q, vertex(a + 1, b + 1), r]);
                }
            }
        }
    }
    TriangleMesh { name: name.into(), positions, indices, ..Default::default() }
}

/// A surface of revolution about +y of the profile `(radius, y)` with
/// `segments` slices. Each profile segment gets its own ring of vertices, so
/// the profile's corners stay sharp (the tiers of a conifer) while the
/// surface is smooth around the axis. A profile point of radius 0 is an apex
/// (a fan of triangles, no degenerate ones). The profile runs bottom to top
/// with the outside on its right (outward normal `(dy, -dr)`).
pub fn lathe(name: &str, profile: &[(f32, f32)], segments: u32) -> TriangleMesh {
    let s = segments.max(3);
    let mut mesh = TriangleMesh { name: name.into(), ..Default::default() };
    let angle = |k: u32| std::f32::consts::TAU * (k % s) as f32 / s as f32;
    for pair in profile.windows(2) {
        let [(r0, y0), (r1, y1)] = [pair[0], pair[1]];
        let n2 = glam::Vec2::new(y1 - y0, r0 - r1).normalize_or_zero();
        let base = mesh.positions.len() as u32;
        for (r, y) in [(r0, y0), (r1, y1)] {
            for k in 0..s {
                let (sin, cos) = angle(k).sin_cos();
                mesh.positions.push(Vec3::new(r * cos, y, r * sin));
                mesh.normals.push(Vec3::new(n2.x * cos, n2.y, n2.x * sin));
            }
        }
        // Ring 0 (a, b) at the segment's start, ring 1 (c, d) at its end;
        // [a, c, b] and [b, c, d] face along (dy, -dr) (checked by the tests).
        for k in 0..s {
            let (a, b) = (base + k, base + (k + 1) % s);
            let (c, d) = (a + s, b + s);
            if r1 > 0.0 {
                mesh.indices.push([b, c, d]);
            }
            if r0 > 0.0 {
                mesh.indices.push([a, c, b]);
            }
        }
    }
    drop_unused(mesh)
}

/// Removes vertices no triangle uses (the duplicate apex vertices a fan
/// leaves behind), keeping the order of the rest.
fn drop_unused(mut mesh: TriangleMesh) -> TriangleMesh {
    let mut remap = vec![u32::MAX; mesh.positions.len()];
    for tri in &mesh.indices {
        for &i in tri {
            remap[i as usize] = 0;
        }
    }
    for (next, r) in remap.iter_mut().filter(|r| **r == 0).enumerate() {
        *r = next as u32;
    }
    let keep =
        |v: &Vec<Vec3>| v.iter().zip(&remap).filter(|&(_, &r)| r != u32::MAX).map(|(p, _)| *p).collect();
    mesh.positions = keep(&mesh.positions);
    mesh.normals = keep(&mesh.normals);
    for tri in &mut mesh.indices {
        *tri = tri.map(|i| remap[i as usize]);
    }
    mesh
}

/// A torus standing upright in the xy plane, centred at the origin: major
/// radius `major`, tube radius `minor`, `around × tube` quads, analytic normals.
pub fn torus(name: &str, major: f32, minor: f32, around: u32, tube: u32) -> TriangleMesh {
    let (nu, nv) = (around.max(3), tube.max(3));
    let mut mesh = TriangleMesh { name: name.into(), ..Default::default() };
    for i in 0..nu {
        let (su, cu) = (std::f32::consts::TAU * i as f32 / nu as f32).sin_cos();
        let radial = Vec3::new(cu, su, 0.0);
        for j in 0..nv {
            let (sv, cv) = (std::f32::consts::TAU * j as f32 / nv as f32).sin_cos();
            let n = radial * cv + Vec3::Z * sv;
            mesh.positions.push(radial * major + n * minor);
            mesh.normals.push(n);
        }
    }
    let id = |i: u32, j: u32| (i % nu) * nv + j % nv;
    for i in 0..nu {
        for j in 0..nv {
            // Around the ring is +u, around the tube is +v; u x v points out.
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i, j + 1), id(i + 1, j + 1));
            mesh.indices.extend([[a, b, c], [b, d, c]]);
        }
    }
    mesh
}

/// One hexagonal crystal: a prism of `radius` along `axis` from `base`,
/// pointed at both ends, `length` long; flat-shaded (unshared vertices, no
/// normals), 24 triangles, each wound away from the crystal's centre
/// (it is convex, so that is outwards).
pub fn crystal(mesh: &mut TriangleMesh, base: Vec3, axis: Vec3, radius: f32, length: f32) {
    let axis = axis.normalize();
    let side = axis.any_orthonormal_vector();
    let other = axis.cross(side);
    let ring = |t: f32| -> [Vec3; 6] {
        std::array::from_fn(|k| {
            let (s, c) = (std::f32::consts::TAU * k as f32 / 6.0).sin_cos();
            base + axis * (t * length) + (side * c + other * s) * radius
        })
    };
    let (low, high) = (ring(0.18), ring(0.78));
    let (bottom, top) = (base, base + axis * length);
    let centre = base + axis * (0.5 * length);
    let mut tri = |p: [Vec3; 3]| {
        let outward = (p[1] - p[0]).cross(p[2] - p[0]).dot(p[0] - centre) >= 0.0;
        let p = if outward { p } else { [p[0], p[2], p[1]] };
        let first = mesh.positions.len() as u32;
        mesh.positions.extend(p);
        mesh.indices.push([first, first + 1, first + 2]);
    };
    for k in 0..6 {
        let l = (k + 1) % 6;
        tri([low[k], low[l], high[k]]);
        tri([low[l], high[l], high[k]]);
        tri([high[k], high[l], top]);
        tri([low[l], low[k], bottom]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Six times the signed volume: positive when the closed mesh's geometric
    /// normals point outwards.
    fn volume6(mesh: &TriangleMesh) -> f32 {
        (0..mesh.triangle_count())
            .map(|t| {
                let [a, b, c] = mesh.triangle(t);
                a.dot(b.cross(c))
            })
            .sum()
    }

    /// Every triangle has area and its geometric normal agrees with its
    /// corners' shading normals.
    fn check_normals(mesh: &TriangleMesh) {
        mesh.validate().unwrap();
        for t in 0..mesh.triangle_count() {
            let g = mesh.geometric_normal(t);
            assert!(g.length() > 1e-9, "{}: triangle {t} is degenerate", mesh.name);
            for &i in &mesh.indices[t] {
                if let Some(n) = mesh.normals.get(i as usize) {
                    assert!(g.dot(*n) > 0.0, "{}: triangle {t} faces against its normals", mesh.name);
                }
            }
        }
    }

    #[test]
    fn geodesic_sphere_is_closed_outward_and_counted() {
        for f in [1, 2, 5] {
            let mesh = with_normals(geodesic("s", f, |d| d));
            assert_eq!(mesh.triangle_count() as u32, 20 * f * f);
            assert_eq!(mesh.positions.len() as u32, 10 * f * f + 2, "shared edge vertices are merged");
            check_normals(&mesh);
            let volume = volume6(&mesh) / 6.0;
            assert!(volume > 0.6 * 4.0 / 3.0 * std::f32::consts::PI && volume < 4.2, "{volume}");
        }
    }

    #[test]
    fn lathe_cone_and_cylinder_face_outwards() {
        let closed = lathe("c", &[(0.0, 0.0), (1.0, 0.0), (0.5, 1.0), (0.0, 1.5)], 12);
        assert_eq!(closed.triangle_count(), 12 + 24 + 12);
        check_normals(&closed);
        assert!(volume6(&closed) > 0.0);
        let open = lathe("t", &[(0.2, 0.0), (0.1, 2.0)], 8);
        assert_eq!((open.triangle_count(), open.positions.len()), (16, 16));
        check_normals(&open);
    }

    #[test]
    fn torus_and_crystal_are_outward() {
        let t = torus("t", 1.0, 0.3, 16, 8);
        assert_eq!(t.triangle_count(), 256);
        check_normals(&t);
        assert!(volume6(&t) > 0.0);
        let mut c = TriangleMesh::default();
        crystal(&mut c, Vec3::new(0.3, 0.0, 0.1), Vec3::new(0.2, 1.0, 0.1), 0.2, 1.0);
        assert_eq!(c.triangle_count(), 24);
        check_normals(&c);
        assert!(volume6(&c) > 0.0);
    }

    #[test]
    fn noise_is_smooth_bounded_and_seeded() {
        let mut prev = value_noise2(0.0, 0.3, 1);
        for i in 1..2000 {
            let v = value_noise2(i as f32 * 0.01, 0.3, 1);
            assert!((0.0..1.0).contains(&v));
            assert!((v - prev).abs() < 0.05, "continuous");
            prev = v;
        }
        assert_ne!(value_noise2(0.5, 0.5, 1), value_noise2(0.5, 0.5, 2));
        let f = fbm3(Vec3::new(0.3, 1.7, -2.2), 4, 9);
        assert!((0.0..1.0).contains(&f));
    }
}
