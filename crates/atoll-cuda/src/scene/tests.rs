//! Scene table construction and the memory plan, without a GPU.

use atoll_scene::{AreaEmission, Instance, Object, Scene, TriangleMesh};
use glam::{Affine3A, Quat, Vec3};

use super::*;
use crate::layout::mesh_flags;

fn quad(material: u32) -> TriangleMesh {
    TriangleMesh {
        name: "quad".into(),
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
        indices: vec![[0, 1, 2], [0, 2, 3]],
        material,
        ..Default::default()
    }
}

/// Every table entry must reproduce the scene's own data.
fn assert_tables_match(scene: &Scene, t: &SceneTables) {
    assert_eq!(t.objects.len(), scene.objects.len());
    assert_eq!(t.instances.len(), scene.instances.len());
    assert_eq!(t.triangles.len(), t.triangle_mesh.len() * 3);
    assert_eq!(t.counts(), TableCounts::of(scene), "counts without building agree");
    let mut next_triangle = 0;
    for (o, object) in scene.objects.iter().enumerate() {
        let go = t.objects[o];
        assert_eq!(go.first_triangle, next_triangle, "objects are contiguous and in order");
        assert_eq!(go.mesh_count as usize, object.meshes.len());
        assert_eq!(go.triangle_count as u64, scene.object_triangles(o as u32));
        next_triangle += go.triangle_count;
        for (k, &mesh_id) in object.meshes.iter().enumerate() {
            let gm = t.meshes[go.first_mesh as usize + k];
            let mesh = &scene.meshes[mesh_id as usize];
            assert_eq!(gm.scene_mesh, mesh_id);
            assert_eq!(gm.material, mesh.material);
            assert_eq!(gm.triangle_count as usize, mesh.indices.len());
            assert_eq!(gm.flags & mesh_flags::EMISSIVE != 0, mesh.emission.is_some());
            assert_eq!(gm.flags & mesh_flags::FLIP_NORMALS != 0, mesh.flip_normals);
            assert_eq!(gm.flags & mesh_flags::HAS_NORMALS != 0, !mesh.normals.is_empty());
            for (local, tri) in mesh.indices.iter().enumerate() {
                let global = gm.first_triangle as usize + local;
                assert_eq!(t.triangle_mesh[global] as usize, go.first_mesh as usize + k);
                for (c, &local_vertex) in tri.iter().enumerate() {
                    let v = t.triangles[global * 3 + c] as usize;
                    let p = Vec3::from_slice(&t.vertices[v * 3..v * 3 + 3]);
                    assert_eq!(p, mesh.positions[local_vertex as usize], "absolute index of {global}/{c}");
                    if !mesh.normals.is_empty() {
                        let n = Vec3::from_slice(&t.normals[v * 3..v * 3 + 3]);
                        assert_eq!(n, mesh.normals[local_vertex as usize]);
                    }
                }
            }
        }
    }
    assert_eq!(next_triangle as usize, t.triangle_mesh.len());
    for (i, inst) in scene.instances.iter().enumerate() {
        let g = t.instances[i];
        assert_eq!(g.object, inst.object);
        let p = Vec3::new(0.3, -1.2, 2.5);
        let m = &g.object_to_world;
        let q = Vec3::new(
            m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3],
            m[4] * p.x + m[5] * p.y + m[6] * p.z + m[7],
            m[8] * p.x + m[9] * p.y + m[10] * p.z + m[11],
        );
        assert!(q.abs_diff_eq(inst.object_to_world.transform_point3(p), 1e-5), "row-major 3x4");
        let w = &g.world_to_object;
        let back = Vec3::new(
            w[0] * q.x + w[1] * q.y + w[2] * q.z + w[3],
            w[4] * q.x + w[5] * q.y + w[6] * q.z + w[7],
            w[8] * q.x + w[9] * q.y + w[10] * q.z + w[11],
        );
        assert!(back.abs_diff_eq(p, 1e-4), "inverse");
    }
}

#[test]
fn cornell_box_tables() {
    let scene = atoll_scene::cornell::builtin_cornell_box();
    let t = SceneTables::build(&scene);
    assert_tables_match(&scene, &t);
    assert_eq!(t.triangle_mesh.len(), 36);
    assert!(t.normals.is_empty(), "flat-shaded: no normals table");
    let emissive: Vec<_> = t.meshes.iter().filter(|m| m.flags & mesh_flags::EMISSIVE != 0).collect();
    assert_eq!(emissive.len(), 1);
    assert_eq!(emissive[0].triangle_count, 2);
    assert_eq!(t.counts().bytes(), TableCounts::of(&scene).bytes());
}

/// Two objects (one with two meshes, one sharing a mesh with the first),
/// three instances with rotations, scales and a mirror.
fn instanced_scene() -> Scene {
    let mut scene = Scene::default();
    let m0 = scene.add_mesh(quad(0));
    let mut lit = quad(1);
    lit.emission = Some(AreaEmission { radiance: Vec3::ONE, two_sided: false });
    lit.flip_normals = true;
    lit.normals = vec![Vec3::Z; 4];
    let m1 = scene.add_mesh(lit);
    let mut big = quad(2);
    big.positions.push(Vec3::new(2.0, 0.0, 0.0));
    big.indices.push([1, 4, 2]);
    let m2 = scene.add_mesh(big);
    let a = scene.add_object(Object { name: "a".into(), meshes: vec![m0, m1] });
    let b = scene.add_object(Object { name: "b".into(), meshes: vec![m2, m0] });
    scene.instances.push(Instance::new(b, Affine3A::IDENTITY));
    scene.instances.push(Instance::new(
        a,
        Affine3A::from_scale_rotation_translation(
            Vec3::new(2.0, 0.5, 1.0),
            Quat::from_rotation_y(0.7),
            Vec3::new(1.0, 2.0, 3.0),
        ),
    ));
    scene.instances.push(Instance::new(
        b,
        Affine3A::from_scale_rotation_translation(Vec3::new(-1.0, 1.0, 1.0), Quat::IDENTITY, Vec3::X),
    ));
    scene
}

#[test]
fn instanced_scene_tables() {
    let scene = instanced_scene();
    let t = SceneTables::build(&scene);
    assert_tables_match(&scene, &t);
    // m0 is in both objects: stored twice.
    assert_eq!(t.meshes.iter().filter(|m| m.scene_mesh == 0).count(), 2);
    assert_eq!(
        t.objects[0],
        GpuObject { first_triangle: 0, triangle_count: 4, first_mesh: 0, mesh_count: 2 }
    );
    assert_eq!(
        t.objects[1],
        GpuObject { first_triangle: 4, triangle_count: 5, first_mesh: 2, mesh_count: 2 }
    );
    // Normals table covers every vertex; meshes without normals read zeros.
    assert_eq!(t.normals.len(), t.vertices.len());
    assert_eq!(&t.normals[0..3], &[0.0; 3]);
    // The emissive, flipped mesh with normals.
    assert_eq!(t.meshes[1].flags, mesh_flags::HAS_NORMALS | mesh_flags::FLIP_NORMALS | mesh_flags::EMISSIVE);
    // Normal matrix of the mirror: x negated.
    let n = t.instances[2].normal_to_world;
    assert_eq!(n, [-1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
}

#[test]
fn part_tables_hold_only_the_part_with_scene_wide_indices() {
    let scene = instanced_scene();
    // Instances 0 (object b) and 1 (object a); of b only triangles 1..3 of mesh 2.
    let part = ScenePart {
        instances: vec![0, 1],
        object_subsets: vec![(1, vec![MeshRange { mesh: 2, triangles: 1..3 }])],
    };
    let t = SceneTables::build_part(&scene, &part);
    assert_eq!(t.counts(), TableCounts::of_part(&scene, &part), "counts without building agree");
    assert_eq!(t.objects[0].triangle_count, 4, "object a whole");
    assert_eq!(t.objects[1].triangle_count, 2, "object b: the range only");
    let b_mesh = t.meshes[t.objects[1].first_mesh as usize];
    assert_eq!((b_mesh.scene_mesh, b_mesh.first_scene_triangle, b_mesh.triangle_count), (2, 1, 2));
    // The range's triangles, with the mesh's vertices kept whole.
    let first = b_mesh.first_triangle as usize;
    for (k, local) in (1..3).enumerate() {
        for c in 0..3 {
            let v = t.triangles[(first + k) * 3 + c] - b_mesh.first_vertex;
            assert_eq!(v, scene.meshes[2].indices[local][c]);
        }
    }
    let excluded: Vec<u32> = t.instances.iter().map(|i| i.excluded).collect();
    assert_eq!(excluded, [0, 0, 1], "every instance keeps its row; the third is outside the part");
    let plan = crate::bvh::ScenePlan::new(&t.objects, &t.instances);
    assert_eq!(plan.valid_instances, [0, 1]);
    // The whole scene as a part is the plain build.
    assert_eq!(SceneTables::build_part(&scene, &ScenePart::whole(&scene)), SceneTables::build(&scene));
}

/// Interleaved partitions cut a mesh into many ranges per part: its
/// vertices are stored once, every range indexing the same block.
#[test]
fn ranges_of_one_mesh_share_its_vertices() {
    let scene = instanced_scene();
    let ranges = vec![MeshRange { mesh: 2, triangles: 0..1 }, MeshRange { mesh: 2, triangles: 2..3 }];
    let part = ScenePart { instances: vec![0], object_subsets: vec![(1, ranges)] };
    let t = SceneTables::build_part(&scene, &part);
    assert_eq!(t.counts(), TableCounts::of_part(&scene, &part));
    assert_eq!(t.counts().vertices, scene.meshes[2].positions.len() as u64, "one vertex block");
    let meshes = &t.meshes[t.objects[1].first_mesh as usize..][..2];
    assert_eq!(meshes[0].first_vertex, meshes[1].first_vertex);
    assert_eq!((meshes[0].first_scene_triangle, meshes[1].first_scene_triangle), (0, 2));
    for (k, local) in [0usize, 2].into_iter().enumerate() {
        for c in 0..3 {
            assert_eq!(t.triangles[k * 3 + c] - meshes[0].first_vertex, scene.meshes[2].indices[local][c]);
        }
    }
}

#[test]
fn empty_scene_has_empty_tables_and_positive_size() {
    let t = SceneTables::build(&Scene::default());
    assert_eq!(t, SceneTables::default());
    assert!(t.counts().bytes() > 0, "placeholders of one element are counted");
}

#[test]
fn memory_plan_refuses_before_allocating() {
    let scene = atoll_scene::procedural::bench_scene(200_000);
    let counts = TableCounts::of(&scene);
    let plan = MemoryPlan {
        scene_tables: counts.bytes(),
        bvh: crate::bvh::estimate_bytes(counts.triangles, counts.instances),
        queues: 3 * (1 << 18) * 128,
        film: 1024 * 1024 * 12,
        params: 0,
    };
    assert!(plan.total() > plan.scene_tables + plan.bvh);
    plan.check("cuda:0", None, 80 << 30).unwrap();
    plan.check("cuda:0", Some(plan.total()), 80 << 30).unwrap();
    // The budget binds.
    match plan.check("cuda:0", Some(plan.total() - 1), 80 << 30) {
        Err(CudaError::OutOfMemory { needed, budget, free, what, .. }) => {
            assert_eq!((needed, budget, free), (plan.total(), plan.total() - 1, 80 << 30));
            assert!(what.contains("BVH"), "{what}");
        }
        other => panic!("{other:?}"),
    }
    // Free memory binds when it is the smaller.
    let e = plan.check("cuda:0", Some(u64::MAX), 1 << 20).unwrap_err();
    assert!(e.to_string().contains("only 1.00 MiB"), "{e}");
}
