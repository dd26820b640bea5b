//! Shapes pbrt defines by refinement, turned into triangles at load time:
//! `loopsubdiv` (Loop subdivision surfaces) and `bilinearmesh` (bilinear
//! patches).

use std::collections::HashMap;

use glam::{Vec2, Vec3};

use super::shapes::ShapeMesh;

/// Loop subdivision of the triangle mesh (`positions`, `indices`) `levels`
/// times, then every vertex moved to its limit position; smooth normals from
/// the final triangles (area-weighted). Rules as pbrt's `LoopSubdivide`:
/// interior edges `3/8 (a + b) + 1/8 (c + d)`, boundary edges `(a + b) / 2`;
/// interior vertices `(1 - nβ) v + β Σ ring` with `β = 3/16` for valence 3
/// and `3 / (8n)` otherwise, boundary vertices `3/4 v + 1/8 (b0 + b1)`;
/// limits `(1 - nγ) v + γ Σ ring` with `γ = 1 / (n + 3 / (8β))`, and
/// `3/5 v + 1/5 (b0 + b1)` on the boundary. Edges shared by more than two
/// triangles are treated as boundaries.
pub fn loop_subdivide(positions: &[Vec3], indices: &[[u32; 3]], levels: u32) -> ShapeMesh {
    let mut p = positions.to_vec();
    let mut faces = indices.to_vec();
    for _ in 0..levels {
        let topo = Topology::new(p.len(), &faces);
        let mut next: Vec<Vec3> = (0..p.len()).map(|v| topo.even(&p, v)).collect();
        let mut edge_vertex = HashMap::with_capacity(topo.edges.len());
        for (&(a, b), opposite) in &topo.edges {
            let (pa, pb) = (p[a as usize], p[b as usize]);
            let q = match opposite.as_slice() {
                [c, d] => (pa + pb) * 0.375 + (p[*c as usize] + p[*d as usize]) * 0.125,
                _ => (pa + pb) * 0.5,
            };
            edge_vertex.insert((a, b), next.len() as u32);
            next.push(q);
        }
        let mid = |a: u32, b: u32| edge_vertex[&(a.min(b), a.max(b))];
        faces = faces
            .iter()
            .flat_map(|&[a, b, c]| {
                let (ab, bc, ca) = (mid(a, b), mid(b, c), mid(c, a));
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
        p = next;
    }
    let topo = Topology::new(p.len(), &faces);
    let limit: Vec<Vec3> = (0..p.len()).map(|v| topo.limit(&p, v)).collect();
    let normals = vertex_normals(&limit, &faces);
    ShapeMesh { name: "loopsubdiv".into(), positions: limit, normals, indices: faces, ..Default::default() }
}

/// Edges (sorted vertex pairs) with the vertices opposite them, and each
/// vertex's neighbours and boundary neighbours.
struct Topology {
    edges: HashMap<(u32, u32), Vec<u32>>,
    ring: Vec<Vec<u32>>,
    boundary: Vec<Vec<u32>>,
}

impl Topology {
    fn new(vertices: usize, faces: &[[u32; 3]]) -> Self {
        let mut edges: HashMap<(u32, u32), Vec<u32>> = HashMap::with_capacity(faces.len() * 3 / 2 + 1);
        for &[a, b, c] in faces {
            for (x, y, opposite) in [(a, b, c), (b, c, a), (c, a, b)] {
                edges.entry((x.min(y), x.max(y))).or_default().push(opposite);
            }
        }
        let mut ring = vec![Vec::new(); vertices];
        let mut boundary = vec![Vec::new(); vertices];
        for (&(a, b), opposite) in &edges {
            ring[a as usize].push(b);
            ring[b as usize].push(a);
            if opposite.len() != 2 {
                boundary[a as usize].push(b);
                boundary[b as usize].push(a);
            }
        }
        Topology { edges, ring, boundary }
    }

    /// The new position of an existing vertex.
    fn even(&self, p: &[Vec3], v: usize) -> Vec3 {
        self.smooth(p, v, loop_beta, 0.125)
    }

    /// The limit-surface position of a vertex.
    fn limit(&self, p: &[Vec3], v: usize) -> Vec3 {
        self.smooth(p, v, |n| 1.0 / (n + 3.0 / (8.0 * loop_beta(n))), 0.2)
    }

    /// `(1 - n w) v + w Σ ring` inside (`w = interior(n)` for valence `n`),
    /// `(1 - 2 b) v + b (b0 + b1)` on a boundary; corners where several
    /// boundaries meet, and isolated vertices, stay put.
    fn smooth(&self, p: &[Vec3], v: usize, interior: impl Fn(f32) -> f32, b: f32) -> Vec3 {
        match self.boundary[v].as_slice() {
            [] if !self.ring[v].is_empty() => {
                let n = self.ring[v].len() as f32;
                let w = interior(n);
                p[v] * (1.0 - n * w) + self.ring_sum(p, v) * w
            }
            [b0, b1] => p[v] * (1.0 - 2.0 * b) + (p[*b0 as usize] + p[*b1 as usize]) * b,
            _ => p[v],
        }
    }

    fn ring_sum(&self, p: &[Vec3], v: usize) -> Vec3 {
        self.ring[v].iter().map(|&u| p[u as usize]).sum()
    }
}

/// Loop's vertex weight `β` for valence `n`: 3/16 for 3, else 3 / (8n).
fn loop_beta(n: f32) -> f32 {
    if n == 3.0 {
        3.0 / 16.0
    } else {
        3.0 / (8.0 * n)
    }
}

/// Area-weighted vertex normals of a triangle mesh (counter-clockwise fronts).
fn vertex_normals(p: &[Vec3], faces: &[[u32; 3]]) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; p.len()];
    for &[a, b, c] in faces {
        let face = (p[b as usize] - p[a as usize]).cross(p[c as usize] - p[a as usize]);
        for v in [a, b, c] {
            n[v as usize] += face;
        }
    }
    n.into_iter().map(|v| v.normalize_or_zero()).collect()
}

/// Samples per side of a curved bilinear patch (planar ones become two triangles).
pub const BILINEAR_GRID: u32 = 8;

/// Samples per side of `patch` in [`bilinear_mesh`]: 1 for a planar patch,
/// [`BILINEAR_GRID`] for a curved one.
fn patch_grid(positions: &[Vec3], patch: [u32; 4]) -> u32 {
    let [p00, p10, p01, p11] = patch.map(|i| positions[i as usize]);
    let extent = (p11 - p00).length().max((p10 - p01).length()).max(f32::MIN_POSITIVE);
    let normal = (p10 - p00).cross(p01 - p00).normalize_or_zero();
    let planar = (p11 - p00).dot(normal).abs() <= 1e-6 * extent;
    if planar {
        1
    } else {
        BILINEAR_GRID
    }
}

/// The triangles [`bilinear_mesh`] makes of `patches`, without making them.
pub fn bilinear_triangles(positions: &[Vec3], patches: &[[u32; 4]]) -> u64 {
    patches.iter().map(|&patch| 2 * (patch_grid(positions, patch) as u64).pow(2)).sum()
}

/// pbrt-v4's `bilinearmesh`: patches of four vertices (`p00, p10, p01,
/// p11`), with optional per-vertex normals and uvs interpolated over them.
/// A planar patch is two triangles, exactly; a curved one is sampled on a
/// [`BILINEAR_GRID`]² grid of its parameter square.
pub fn bilinear_mesh(positions: &[Vec3], normals: &[Vec3], uvs: &[Vec2], patches: &[[u32; 4]]) -> ShapeMesh {
    let mut m = ShapeMesh { name: "bilinearmesh".into(), ..Default::default() };
    for &patch in patches {
        let [p00, p10, p01, p11] = patch.map(|i| positions[i as usize]);
        let grid = patch_grid(positions, patch);
        let base = m.positions.len() as u32;
        for j in 0..=grid {
            for i in 0..=grid {
                let (u, v) = (i as f32 / grid as f32, j as f32 / grid as f32);
                let lerp = |a: Vec3, b: Vec3, c: Vec3, d: Vec3| {
                    (a * (1.0 - u) + b * u) * (1.0 - v) + (c * (1.0 - u) + d * u) * v
                };
                m.positions.push(lerp(p00, p10, p01, p11));
                if !normals.is_empty() {
                    let [n00, n10, n01, n11] = patch.map(|k| normals[k as usize]);
                    m.normals.push(lerp(n00, n10, n01, n11).normalize_or_zero());
                }
                if !uvs.is_empty() {
                    let [t00, t10, t01, t11] = patch.map(|k| uvs[k as usize]);
                    m.uvs.push((t00 * (1.0 - u) + t10 * u) * (1.0 - v) + (t01 * (1.0 - u) + t11 * u) * v);
                }
            }
        }
        let at = |i: u32, j: u32| base + j * (grid + 1) + i;
        for j in 0..grid {
            for i in 0..grid {
                // (u, v) counter-clockwise, as pbrt's patch normal dp/du × dp/dv.
                m.indices.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                m.indices.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetrahedron() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let p = vec![
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(1.0, -1.0, -1.0),
            Vec3::new(-1.0, 1.0, -1.0),
            Vec3::new(-1.0, -1.0, 1.0),
        ];
        (p, vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
    }

    #[test]
    fn closed_meshes_quadruple_faces_and_shrink_smoothly() {
        let (p, f) = tetrahedron();
        for levels in 0..4 {
            let m = loop_subdivide(&p, &f, levels);
            assert_eq!(m.indices.len(), 4 * 4usize.pow(levels));
            // Euler: V - E + F = 2 with E = 3F/2.
            assert_eq!(m.positions.len() + m.indices.len() - 3 * m.indices.len() / 2, 2);
            assert_eq!(m.normals.len(), m.positions.len());
        }
        let m = loop_subdivide(&p, &f, 3);
        // Inside the control tetrahedron's circumsphere and symmetric about the origin.
        let centre: Vec3 = m.positions.iter().sum::<Vec3>() / m.positions.len() as f32;
        assert!(centre.length() < 1e-4, "{centre}");
        assert!(m.positions.iter().all(|q| q.length() < 3f32.sqrt()));
        // Smooth: normals point outwards, away from the centre.
        assert!(m.positions.iter().zip(&m.normals).all(|(q, n)| q.dot(*n) > 0.0));
        // Triangles keep the control mesh's outward orientation.
        let [a, b, c] = m.indices[0].map(|i| m.positions[i as usize]);
        assert!((b - a).cross(c - a).dot(a + b + c) > 0.0);
    }

    #[test]
    fn planes_stay_planar_and_boundaries_stay_on_their_lines() {
        // A 4x4 grid of unit squares in z = 0, each split in two.
        let n = 5u32;
        let p: Vec<Vec3> = (0..n * n).map(|i| Vec3::new((i % n) as f32, (i / n) as f32, 0.0)).collect();
        let mut f = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let v = j * n + i;
                f.push([v, v + 1, v + n + 1]);
                f.push([v, v + n + 1, v + n]);
            }
        }
        let m = loop_subdivide(&p, &f, 2);
        assert!(m.positions.iter().all(|q| q.z == 0.0));
        assert!(m.normals.iter().all(|n| (*n - Vec3::Z).length() < 1e-5));
        // The boundary is smoothed like a cubic B-spline (corners round off,
        // as in pbrt): a straight stretch keeps its middle point in place.
        assert!(m.positions.iter().any(|q| (*q - Vec3::new(2.0, 0.0, 0.0)).length() < 1e-6));
        assert!(m
            .positions
            .iter()
            .all(|q| q.x >= -1e-6 && q.x <= 4.0 + 1e-6 && q.y >= -1e-6 && q.y <= 4.0 + 1e-6));
    }

    #[test]
    fn bilinear_patches_planar_and_curved() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0)];
        let uv = [Vec2::ZERO, Vec2::X, Vec2::Y, Vec2::ONE];
        let flat = bilinear_mesh(&p, &[], &uv, &[[0, 1, 2, 3]]);
        assert_eq!((flat.positions.len(), flat.indices.len()), (4, 2));
        assert_eq!(bilinear_triangles(&p, &[[0, 1, 2, 3]]), 2);
        let [a, b, c] = flat.indices[0].map(|i| flat.positions[i as usize]);
        assert!((b - a).cross(c - a).z > 0.0, "faces +z like dp/du × dp/dv");
        assert_eq!(flat.uvs[3], Vec2::ONE);
        // A saddle: every sample lies on the patch z = u v.
        let saddle = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 1.0)];
        let curved = bilinear_mesh(&saddle, &[], &[], &[[0, 1, 2, 3]]);
        let g = BILINEAR_GRID as usize;
        assert_eq!((curved.positions.len(), curved.indices.len()), ((g + 1) * (g + 1), 2 * g * g));
        assert_eq!(bilinear_triangles(&saddle, &[[0, 1, 2, 3]]), 2 * (g * g) as u64);
        assert!(curved.positions.iter().all(|q| (q.z - q.x * q.y).abs() < 1e-6));
    }
}
