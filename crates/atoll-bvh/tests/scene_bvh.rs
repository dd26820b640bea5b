//! Queries of both layouts against brute force over every instanced triangle.

use atoll_bvh::{
    Aabb, BuildOptions, Bvh2, Bvh4Cpu, BvhLayout, MeshRange, Ray, SceneBvh, ScenePart, TriAccel,
};
use atoll_scene::{Instance, Object, Scene, TriangleMesh};
use glam::{Affine3A, Quat, Vec3};

/// PCG-style LCG: small and deterministic.
struct Rng(u64);

impl Rng {
    fn f32(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32) / (1u64 << 24) as f32
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }
    fn vec3(&mut self, lo: f32, hi: f32) -> Vec3 {
        Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }
    fn below(&mut self, n: usize) -> usize {
        ((self.f32() * n as f32) as usize).min(n - 1)
    }
    fn direction(&mut self) -> Vec3 {
        loop {
            let v = self.vec3(-1.0, 1.0);
            if (0.01..=1.0).contains(&v.length_squared()) {
                return v.normalize();
            }
        }
    }
}

/// A soup of `n` random triangles in [-1, 1]^3, with degenerate ones
/// (repeated and collinear vertices) and shared vertices mixed in.
fn soup(rng: &mut Rng, n: usize) -> TriangleMesh {
    let mut mesh = TriangleMesh { name: "soup".into(), ..Default::default() };
    for t in 0..n {
        let c = rng.vec3(-1.0, 1.0);
        let size = rng.range(0.02, 0.4);
        let (a, b) = (c + rng.vec3(-size, size), c + rng.vec3(-size, size));
        let third = match t % 11 {
            0 => a,                 // repeated vertex
            1 => a + 2.0 * (b - a), // collinear
            _ => c + rng.vec3(-size, size),
        };
        let base = mesh.positions.len() as u32;
        mesh.positions.extend([a, b, third]);
        // Every fifth triangle reuses the previous triangle's last vertex.
        let first = if t % 5 == 4 { base - 1 } else { base };
        mesh.indices.push([first, base + 1, base + 2]);
    }
    mesh
}

/// Several objects (one of them empty), instanced with random rotations,
/// non-uniform scales and translations, plus a world object.
fn random_scene(seed: u64, tris: usize) -> Scene {
    let mut rng = Rng(seed);
    let mut scene = Scene::default();
    let mut objects = Vec::new();
    for o in 0..4 {
        let meshes = (0..1 + o % 2).map(|_| scene.add_mesh(soup(&mut rng, tris / 6))).collect();
        objects.push(scene.add_object(Object { name: format!("o{o}"), meshes }));
    }
    let empty = scene.add_mesh(TriangleMesh::default());
    let empty = scene.add_object(Object { name: "empty".into(), meshes: vec![empty] });
    for i in 0..9 {
        let rotation = Quat::from_axis_angle(rng.direction(), rng.range(0.0, 6.3));
        let scale = rng.vec3(0.3, 2.0);
        let object = if i == 4 { empty } else { objects[i % objects.len()] };
        let m = Affine3A::from_scale_rotation_translation(scale, rotation, rng.vec3(-4.0, 4.0));
        scene.instances.push(Instance::new(object, m));
    }
    let world = scene.add_mesh(soup(&mut rng, tris / 6));
    let world = scene.add_object(Object { name: "world".into(), meshes: vec![world] });
    scene.instances.push(Instance::new(world, Affine3A::IDENTITY));
    scene
}

/// Random rays: half aimed at triangles, some axis-parallel, some with
/// unnormalised directions, some with a finite `t_max`.
fn random_rays(rng: &mut Rng, scene: &Scene, n: usize) -> Vec<Ray> {
    let (lo, hi) = scene.world_bounds().unwrap();
    (0..n)
        .map(|i| {
            let origin = lo + (hi - lo) * rng.vec3(-0.2, 1.2);
            let mut direction = match i % 4 {
                0 => {
                    let inst = &scene.instances[rng.below(scene.instances.len())];
                    let meshes = &scene.objects[inst.object as usize].meshes;
                    let mesh = &scene.meshes[meshes[rng.below(meshes.len())] as usize];
                    if mesh.indices.is_empty() {
                        rng.direction()
                    } else {
                        let [a, b, c] = mesh.triangle(rng.below(mesh.indices.len()));
                        inst.object_to_world.transform_point3((a + b + c) / 3.0) - origin
                    }
                }
                1 => [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z][rng.below(6)],
                _ => rng.direction(),
            };
            if i % 3 == 0 {
                direction *= rng.range(0.1, 10.0);
            }
            let t_max = if i % 2 == 0 { f32::INFINITY } else { rng.range(0.0, 2.0) * (hi - lo).length() };
            Ray { origin, direction, t_max, time: 0.0 }
        })
        .collect()
}

/// Every hit `(t, instance, mesh, triangle)` with `0 < t < t_max`, tested in
/// object space like the BVH does (so `t` agrees to the last bit), sorted by `t`.
fn brute_force(scene: &Scene, part: &ScenePart, ray: &Ray) -> Vec<(f32, u32, u32, u32)> {
    let mut hits = Vec::new();
    for &i in &part.instances {
        let inst = &scene.instances[i as usize];
        let m = inst.object_to_world.inverse();
        let (o, d) = (m.transform_point3a(ray.origin.into()), m.transform_vector3a(ray.direction.into()));
        for r in part.object_ranges(scene, inst.object) {
            let mesh = &scene.meshes[r.mesh as usize];
            for t in r.triangles {
                if let Some((th, ..)) = TriAccel::new(mesh.triangle(t as usize)).intersect(o, d, ray.t_max) {
                    hits.push((th, i, r.mesh, t));
                }
            }
        }
    }
    hits.sort_by(|a, b| a.0.total_cmp(&b.0));
    hits
}

/// Checks both queries of `bvh` on `rays`; returns how many rays hit.
fn check<L: BvhLayout>(scene: &Scene, part: &ScenePart, bvh: &SceneBvh<L>, rays: &[Ray]) -> usize {
    let mut hits = 0;
    for (i, ray) in rays.iter().enumerate() {
        let expected = brute_force(scene, part, ray);
        let got = bvh.intersect(ray);
        assert_eq!(bvh.occluded(ray), !expected.is_empty(), "ray {i} {ray:?}");
        let (Some(hit), Some(&(t, instance, mesh, triangle))) = (got, expected.first()) else {
            assert_eq!(got.is_none(), expected.is_empty(), "ray {i} {ray:?}: {got:?} vs {expected:?}");
            continue;
        };
        hits += 1;
        assert!((hit.t - t).abs() <= 1e-4 * t, "ray {i}: t {} vs {t}", hit.t);
        let near_tie = expected.get(1).is_some_and(|second| second.0 - t <= 1e-4 * t);
        if !near_tie {
            assert_eq!((hit.instance, hit.mesh, hit.triangle), (instance, mesh, triangle), "ray {i}");
        }
        // The barycentrics locate the hit on the world-space triangle (where
        // that is well conditioned: not on slivers, not at grazing angles).
        let m = scene.instances[hit.instance as usize].object_to_world;
        let [p0, p1, p2] =
            scene.meshes[hit.mesh as usize].triangle(hit.triangle as usize).map(|p| m.transform_point3(p));
        let n = (p1 - p0).cross(p2 - p0);
        let sine = n.length() / ((p1 - p0).length() * (p2 - p0).length());
        let cosine = n.normalize().dot(ray.direction.normalize()).abs();
        if sine > 0.05 && cosine > 0.05 {
            let p = (1.0 - hit.u - hit.v) * p0 + hit.u * p1 + hit.v * p2;
            let q = ray.origin + hit.t * ray.direction;
            assert!((p - q).length() <= 1e-4 * (1.0 + q.length()), "ray {i}: {p} vs {q}");
        }
    }
    hits
}

fn check_random_scenes<L: BvhLayout>() {
    for seed in 1..=3 {
        let scene = random_scene(seed, 600);
        let bvh = SceneBvh::<L>::build_layout(&scene, &ScenePart::whole(&scene));
        let stats = bvh.stats();
        assert_eq!((stats.instances, stats.blas_count), (9, 5), "the empty object is left out");
        assert_eq!(stats.instanced_triangles, scene.stats().instanced_triangles);
        let rays = random_rays(&mut Rng(seed + 100), &scene, 1500);
        let hits = check(&scene, &ScenePart::whole(&scene), &bvh, &rays);
        assert!(hits > rays.len() / 5, "only {hits} hits: the test would prove little");
    }
}

#[test]
fn bvh4cpu_matches_brute_force() {
    check_random_scenes::<Bvh4Cpu>();
}

#[test]
fn bvh2_matches_brute_force() {
    check_random_scenes::<Bvh2>();
}

#[test]
fn parts_match_brute_force_over_the_part() {
    let scene = random_scene(7, 600);
    let o0 = &scene.objects[0];
    let m = o0.meshes[0];
    let part = ScenePart {
        instances: vec![0, 1, 4, 6, 9],
        object_subsets: vec![(0, vec![MeshRange { mesh: m, triangles: 10..60 }])],
    };
    let bvh = SceneBvh::build_part(&scene, &part);
    assert_eq!(bvh.stats().instances, 4, "instance 4 is of the empty object");
    let rays = random_rays(&mut Rng(8), &scene, 1500);
    assert!(check(&scene, &part, &bvh, &rays) > 100);
}

#[test]
fn coincident_centroids_fill_multi_block_leaves() {
    // Triangles sharing one centroid cannot be told apart by binning: they
    // end up in leaves of up to 8, two Tri4 blocks each.
    let mut rng = Rng(21);
    let mut mesh = TriangleMesh::default();
    for t in 0..40u32 {
        let (a, b) = (rng.vec3(-1.0, 1.0), rng.vec3(-1.0, 1.0));
        mesh.positions.extend([a, b, -(a + b)]);
        mesh.indices.push([3 * t, 3 * t + 1, 3 * t + 2]);
    }
    let mut scene = Scene::default();
    let mesh = scene.add_mesh(mesh);
    let object = scene.add_object(Object { name: "star".into(), meshes: vec![mesh] });
    scene.instances.push(Instance::new(object, Affine3A::IDENTITY));
    let bvh = SceneBvh::build(&scene);
    assert!(bvh.stats().blas.leaves >= 5, "{:?}", bvh.stats());
    let rays: Vec<Ray> = (0..500)
        .map(|_| {
            let origin = rng.direction() * 3.0;
            Ray { origin, direction: rng.vec3(-0.4, 0.4) - origin, t_max: f32::INFINITY, time: 0.0 }
        })
        .collect();
    assert!(check(&scene, &ScenePart::whole(&scene), &bvh, &rays) > 200);
}

#[test]
fn empty_scenes_hit_nothing() {
    let mut scene = Scene::default();
    let ray = Ray { origin: Vec3::ZERO, direction: Vec3::Z, t_max: f32::INFINITY, time: 0.0 };
    let bvh = SceneBvh::build(&scene);
    assert!(bvh.intersect(&ray).is_none() && !bvh.occluded(&ray));
    assert_eq!((bvh.stats().instances, bvh.stats().triangles), (0, 0));
    // Objects without triangles, with and without instances.
    let mesh = scene.add_mesh(TriangleMesh::default());
    let object = scene.add_object(Object { name: "nothing".into(), meshes: vec![mesh] });
    scene.add_object(Object::default());
    scene.instances.push(Instance::new(object, Affine3A::IDENTITY));
    let bvh = SceneBvh::<Bvh2>::build_layout(&scene, &ScenePart::whole(&scene));
    assert!(bvh.intersect(&ray).is_none() && !bvh.occluded(&ray));
    assert_eq!(bvh.stats().blas_count, 0);
}

#[test]
fn single_triangle_hits_and_t_max_limits() {
    let mut scene = Scene::default();
    let mesh = scene.add_mesh(TriangleMesh {
        positions: vec![Vec3::new(0.0, 0.0, 5.0), Vec3::new(4.0, 0.0, 5.0), Vec3::new(0.0, 2.0, 5.0)],
        indices: vec![[0, 1, 2]],
        ..Default::default()
    });
    let object = scene.add_object(Object { name: "one".into(), meshes: vec![mesh] });
    let object_to_world = Affine3A::from_translation(Vec3::new(0.0, 0.0, 1.0));
    scene.instances.push(Instance::new(object, object_to_world));
    let bvh = SceneBvh::build(&scene);
    let ray = |t_max| Ray {
        origin: Vec3::new(1.0, 0.5, 0.0),
        direction: Vec3::new(0.0, 0.0, 2.0),
        t_max,
        time: 0.0,
    };
    let hit = bvh.intersect(&ray(10.0)).unwrap();
    assert_eq!((hit.t, hit.u, hit.v), (3.0, 0.25, 0.25));
    assert_eq!((hit.instance, hit.mesh, hit.triangle), (0, 0, 0));
    assert!(bvh.occluded(&ray(3.001)) && bvh.intersect(&ray(3.001)).is_some());
    assert!(!bvh.occluded(&ray(3.0)) && bvh.intersect(&ray(3.0)).is_none(), "t_max is exclusive");
    let beside = Ray { origin: Vec3::new(3.0, 1.5, 0.0), ..ray(10.0) };
    assert!(bvh.intersect(&beside).is_none() && !bvh.occluded(&beside));
    let behind = Ray { origin: Vec3::new(1.0, 0.5, 7.0), ..ray(10.0) };
    assert!(bvh.intersect(&behind).is_none());
    let stats = bvh.stats();
    assert_eq!((stats.tlas.nodes, stats.blas.nodes, stats.blas.leaves, stats.triangles), (1, 1, 1, 1));
}

#[test]
fn binned_sah_beats_median_splits() {
    let scene = atoll_scene::procedural::bench_scene_flat(20_000);
    let mut rng = Rng(3);
    let soup = soup(&mut rng, 20_000);
    for meshes in [&scene.meshes[..], std::slice::from_ref(&soup)] {
        let boxes: Vec<Aabb> = meshes
            .iter()
            .flat_map(|m| (0..m.triangle_count()).map(|t| Aabb::from_points(m.triangle(t))))
            .collect();
        let o = BuildOptions::TRIANGLES;
        let sah = Bvh2::build(&boxes, &o).sah_cost(&o);
        let median = Bvh2::build(&boxes, &BuildOptions::QUICK).sah_cost(&o);
        assert!(sah < 0.9 * median, "binned SAH {sah} vs median {median}");
        // The wide layout is converted from the same tree: one node a level less.
        let wide = Bvh4Cpu::from_bvh2(Bvh2::build(&boxes, &o)).stats(&o);
        assert!(wide.max_depth < Bvh2::build(&boxes, &o).stats(&o).max_depth);
    }
}

#[test]
fn queries_are_thread_safe() {
    fn send_sync<T: Send + Sync>() {}
    send_sync::<SceneBvh>();
    let scene = random_scene(11, 300);
    let bvh = SceneBvh::build(&scene);
    let rays = random_rays(&mut Rng(12), &scene, 400);
    let serial: Vec<_> = rays.iter().map(|r| bvh.intersect(r)).collect();
    let parallel: Vec<_> = std::thread::scope(|s| {
        let handles: Vec<_> = rays
            .chunks(100)
            .map(|c| s.spawn(|| c.iter().map(|r| bvh.intersect(r)).collect::<Vec<_>>()))
            .collect();
        handles.into_iter().flat_map(|h| h.join().unwrap()).collect()
    });
    assert_eq!(serial, parallel);
}
