//! How many bytes a device needs for a [`ScenePart`]: the weight estimate
//! that partitioning balances and that devices check against their budget
//! before building (Wald, Jaroš, Zellmann 2023, "content weight estimate").
//!
//! Geometry is counted exactly from the mesh arrays; acceleration structures
//! are estimated with per-triangle, per-instance and per-object constants of
//! a [`ByteModel`], fitted to what a device's BVH really allocates.
//!
//! A mesh the part includes only some triangles of is charged its whole
//! vertex arrays (the devices keep a mesh's vertices as they are, so that
//! triangle indices stay valid) but only the index entries of the included
//! triangles (a range of the index array, addressed with an offset). Vertex
//! bytes of a mesh are charged once per part however many objects, ranges or
//! instances use it.

use atoll_scene::{MeshId, ObjectId, Scene, SceneSizes};

use crate::ScenePart;

/// Bytes per stored index triple (`[u32; 3]`).
const INDEX_BYTES: u64 = 12;

/// Per-element constants of a device's memory use beyond the mesh arrays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ByteModel {
    /// BVH bytes per triangle stored in a bottom-level BVH: leaf triangle
    /// data, padding and the triangle's share of the nodes.
    pub per_triangle: u64,
    /// Bytes per vertex beyond the mesh's own arrays (for a device that
    /// converts or pads vertex data; 0 where meshes are used as stored).
    pub per_vertex: u64,
    /// Bytes per instance in the part: its top-level record and share of the
    /// top-level nodes.
    pub per_instance: u64,
    /// Fixed bytes per object with a bottom-level BVH (allocations, root).
    pub per_object: u64,
    /// Build scratch per triangle, charged for the part's largest object:
    /// freed once its bottom-level BVH is built, but needed at the peak.
    pub scratch_per_triangle: u64,
}

impl ByteModel {
    /// The CPU device's [`crate::SceneBvh`] with [`crate::Bvh4Cpu`] nodes,
    /// fitted to its allocations (counted with a global allocator on the
    /// procedural scenes, see atoll-dist's `tests/byte_model.rs`).
    ///
    /// - Per triangle, 68: a [`crate::Tri4`] lane (144 / 4 = 36 bytes) and
    ///   an 8-byte primitive id make 44 bytes a slot; leaves (up to 8
    ///   triangles) are padded to whole blocks of 4 and the 128-byte nodes
    ///   add their share: `SceneBvhStats::blas.bytes` measured 56 to 57 a
    ///   triangle, the allocations (growth slack of the node vector
    ///   included) 62 to 67.
    /// - Per instance, 144: an 80-byte top-level record and about half a
    ///   128-byte node (leaves of one instance); measured 132 to 142.
    /// - Per object, 256: a bottom-level BVH's allocations and a root node
    ///   that small objects barely fill.
    /// - Build scratch per triangle, 112: primitive boxes (32) and builder
    ///   references (32), binary nodes (about 32), primitive order and
    ///   unpadded ids (12); the measured peak was 102 to 105 above what
    ///   stays allocated.
    ///
    /// Geometry is shared with the host scene on the CPU, but it is counted
    /// anyway: the budget is meant to model a device that holds its part.
    pub const CPU: ByteModel = ByteModel {
        per_triangle: 68,
        per_vertex: 0,
        per_instance: 144,
        per_object: 256,
        scratch_per_triangle: 112,
    };
}

impl ByteModel {
    /// Bytes a device with this model needs for a scene of `sizes`,
    /// textures aside. Saturating: sizes known before a scene is built
    /// come from its files, which may claim anything.
    pub fn bytes(&self, sizes: &SceneSizes) -> u64 {
        let c = sizes;
        [
            (c.geometry_bytes, 1),
            (c.vertices, self.per_vertex),
            (c.triangles, self.per_triangle),
            (c.objects, self.per_object),
            (c.instances, self.per_instance),
            (c.largest_object_triangles, self.scratch_per_triangle),
        ]
        .iter()
        .fold(0u64, |sum, &(n, each)| sum.saturating_add(n.saturating_mul(each)))
    }
}

/// Bytes of one mesh's vertex arrays (positions, normals, uvs) as
/// stored, with its curve pieces.
fn vertex_bytes(scene: &Scene, mesh: MeshId) -> u64 {
    let m = &scene.meshes[mesh as usize];
    (m.positions.len() * 12 + m.normals.len() * 12 + m.uvs.len() * 8) as u64
        + m.curves.as_ref().map_or(0, |c| c.bytes())
}

fn counts(scene: &Scene, part: &ScenePart) -> SceneSizes {
    // Counted per object rather than sorted: parts of big scenes hold
    // millions of instances of a few objects.
    let mut instances_of = vec![0u64; scene.objects.len()];
    for &i in &part.instances {
        instances_of[scene.instances[i as usize].object as usize] += 1;
    }
    let objects: Vec<ObjectId> =
        (0..scene.objects.len() as ObjectId).filter(|&o| instances_of[o as usize] > 0).collect();
    let mut c = SceneSizes::default();
    // Per mesh, the triangle ranges any object of the part includes.
    let mut ranges: Vec<(MeshId, u32, u32)> = Vec::new();
    for &o in &objects {
        let mut tris = 0;
        for r in part.object_ranges(scene, o) {
            tris += r.triangles.len() as u64;
            if !r.triangles.is_empty() {
                ranges.push((r.mesh, r.triangles.start, r.triangles.end));
            }
        }
        if tris > 0 {
            c.triangles += tris;
            c.largest_object_triangles = c.largest_object_triangles.max(tris);
            c.objects += 1;
            c.instances += instances_of[o as usize];
        }
    }
    // Index entries of the union of ranges per mesh; vertex arrays once per mesh.
    ranges.sort_unstable();
    let mut i = 0;
    while i < ranges.len() {
        let mesh = ranges[i].0;
        c.vertices += scene.meshes[mesh as usize].positions.len() as u64;
        c.geometry_bytes += vertex_bytes(scene, mesh);
        let (mut start, mut end) = (ranges[i].1, ranges[i].2);
        let mut covered = 0u64;
        while i < ranges.len() && ranges[i].0 == mesh {
            let (s, e) = (ranges[i].1, ranges[i].2);
            if s > end {
                covered += (end - start) as u64;
                start = s;
            }
            end = end.max(e);
            i += 1;
        }
        covered += (end - start) as u64;
        c.geometry_bytes += covered * INDEX_BYTES;
    }
    c
}

/// Mesh bytes a device holds for `part`: the whole vertex arrays of every
/// mesh with a triangle in the part, and the index entries of the included
/// triangles. Meshes of objects the part has no instance of do not count.
pub fn part_geometry_bytes(scene: &Scene, part: &ScenePart) -> u64 {
    counts(scene, part).geometry_bytes
}

/// Bytes a device with `model` needs for `part`: geometry (see
/// [`part_geometry_bytes`]) plus the modelled acceleration structures and
/// build scratch, plus every texture image and medium of the scene: a
/// device shades the hits it finds and the paths it spawns, on any
/// material and in any medium, so each holds them all.
pub fn part_bytes(scene: &Scene, part: &ScenePart, model: &ByteModel) -> u64 {
    scene.replicated_bytes() + model.bytes(&counts(scene, part))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{MeshRange, SceneBvh};
    use atoll_scene::{procedural::bench_scene, Instance, Object, TriangleMesh};
    use glam::{Affine3A, Vec2, Vec3};

    /// A strip of `quads` quads (2 triangles each) with normals and uvs.
    fn strip(quads: u32) -> TriangleMesh {
        let mut m = TriangleMesh::default();
        for i in 0..=quads {
            for y in 0..2 {
                m.positions.push(Vec3::new(i as f32, y as f32, 0.0));
                m.normals.push(Vec3::Z);
                m.uvs.push(Vec2::ZERO);
            }
        }
        for i in 0..quads {
            let a = 2 * i;
            m.indices.push([a, a + 2, a + 1]);
            m.indices.push([a + 1, a + 2, a + 3]);
        }
        m
    }

    fn placed(scene: &mut Scene, object: ObjectId, x: f32) {
        scene.instances.push(Instance::new(object, Affine3A::from_translation(Vec3::X * x)));
    }

    const NO_SCRATCH: ByteModel = ByteModel { scratch_per_triangle: 0, ..ByteModel::CPU };

    #[test]
    fn whole_scene_estimate_tracks_the_cpu_bvh() {
        let scene = bench_scene(20_000);
        let whole = ScenePart::whole(&scene);
        let real = SceneBvh::build(&scene).stats().bytes as u64 + scene.stats().geometry_bytes;
        assert_eq!(part_geometry_bytes(&scene, &whole), scene.stats().geometry_bytes);
        // What stays allocated: above the reported node and leaf bytes by
        // the allocation slack, not by more.
        let resident = part_bytes(&scene, &whole, &NO_SCRATCH) as f64 / real as f64;
        assert!((1.0..1.3).contains(&resident), "resident estimate / real = {resident:.3}");
        // With the build peak of the terrain (most of the triangles) on top.
        let peak = part_bytes(&scene, &whole, &ByteModel::CPU) as f64 / real as f64;
        assert!((1.5..3.0).contains(&peak), "peak estimate / real = {peak:.3}");
    }

    #[test]
    fn ranges_charge_whole_vertices_and_only_their_indices() {
        let mut scene = Scene::default();
        let mesh = scene.add_mesh(strip(50)); // 102 vertices, 100 triangles
        let object = scene.add_object(Object { name: "strip".into(), meshes: vec![mesh] });
        placed(&mut scene, object, 0.0);
        let half = ScenePart {
            instances: vec![0],
            object_subsets: vec![(object, vec![MeshRange { mesh, triangles: 10..60 }])],
        };
        assert_eq!(part_geometry_bytes(&scene, &half), 102 * 32 + 50 * 12);
        let m = ByteModel::CPU;
        let expected = 102 * 32
            + 50 * 12
            + 50 * m.per_triangle
            + m.per_object
            + m.per_instance
            + 50 * m.scratch_per_triangle;
        assert_eq!(part_bytes(&scene, &half, &m), expected);
        // The whole mesh: every index entry.
        let whole = ScenePart::whole(&scene);
        assert_eq!(part_geometry_bytes(&scene, &whole), scene.meshes[0].memory_bytes());
    }

    #[test]
    fn instances_share_one_blas_and_shared_meshes_count_once() {
        let mut scene = Scene::default();
        let mesh = scene.add_mesh(strip(10)); // 22 vertices, 20 triangles
        let a = scene.add_object(Object { name: "a".into(), meshes: vec![mesh] });
        let b = scene.add_object(Object { name: "b".into(), meshes: vec![mesh] });
        for x in 0..3 {
            placed(&mut scene, a, x as f32);
        }
        placed(&mut scene, b, 9.0);
        let m = ByteModel::CPU;
        // Object b keeps triangles 5..15, overlapping a's whole mesh: the
        // vertices and the index entries are held once.
        let part = ScenePart {
            instances: vec![0, 1, 2, 3],
            object_subsets: vec![(b, vec![MeshRange { mesh, triangles: 5..15 }])],
        };
        let geometry = 22 * 32 + 20 * 12;
        assert_eq!(part_geometry_bytes(&scene, &part), geometry);
        let blas = (20 + 10) * m.per_triangle + 2 * m.per_object;
        assert_eq!(
            part_bytes(&scene, &part, &m),
            geometry + blas + 4 * m.per_instance + 20 * m.scratch_per_triangle
        );
    }

    #[test]
    fn empty_parts_and_objects_without_instances_cost_nothing() {
        let mut scene = Scene::default();
        let mesh = scene.add_mesh(strip(4));
        let object = scene.add_object(Object { name: "unplaced".into(), meshes: vec![mesh] });
        let empty = ScenePart::default();
        assert_eq!(part_bytes(&scene, &empty, &ByteModel::CPU), 0);
        // Subsets of objects the part has no instance of are ignored.
        let listed = ScenePart {
            instances: vec![],
            object_subsets: vec![(object, vec![MeshRange { mesh, triangles: 0..8 }])],
        };
        assert_eq!(part_bytes(&scene, &listed, &ByteModel::CPU), 0);
        // An instance whose object keeps no triangle is left out of the BVH.
        placed(&mut scene, object, 0.0);
        let none = ScenePart { instances: vec![0], object_subsets: vec![(object, vec![])] };
        assert_eq!(part_bytes(&scene, &none, &ByteModel::CPU), 0);
    }

    #[test]
    fn every_part_holds_all_texture_images() {
        let mut scene = Scene::default();
        let mesh = scene.add_mesh(strip(4)); // 10 vertices, 8 triangles
        let object = scene.add_object(Object { name: "strip".into(), meshes: vec![mesh] });
        placed(&mut scene, object, 0.0);
        let image = atoll_scene::TextureImage::from_linear("t", 4, 2, vec![[0.5; 4]; 8]);
        scene.textures.add_image(image); // 8 float texels: 128 bytes
        let m = ByteModel::CPU;
        let whole = ScenePart::whole(&scene);
        let geometry = 10 * 32 + 8 * 12;
        assert_eq!(part_geometry_bytes(&scene, &whole), geometry);
        let bvh = 8 * m.per_triangle + m.per_object + m.per_instance + 8 * m.scratch_per_triangle;
        assert_eq!(part_bytes(&scene, &whole, &m), 128 + geometry + bvh);
        assert_eq!(part_bytes(&scene, &ScenePart::default(), &m), 128);
    }
}
