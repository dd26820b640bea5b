//! Scenes, rays and a brute-force reference for testing and benchmarking
//! the GPU BVH (used by the host tests, `tests/gpu_bvh.rs` and the bench).

use atoll_bvh::{Ray, TriAccel};
use atoll_scene::{Instance, Material, Object, Scene, TriangleMesh};
use glam::{Affine3A, Quat, Vec3, Vec3A};

use super::host::{HostHit, ScenePlan};
use crate::scene::SceneTables;

/// A small deterministic generator (PCG-style LCG), uniform in [0, 1).
pub struct Rng(pub u64);

impl Rng {
    pub(crate) fn uniform(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32) / (1u64 << 24) as f32
    }

    pub(crate) fn vec3(&mut self) -> Vec3 {
        Vec3::new(self.uniform(), self.uniform(), self.uniform())
    }

    pub fn below(&mut self, n: u32) -> u32 {
        ((self.uniform() * n as f32) as u32).min(n.saturating_sub(1))
    }
}

/// Random little triangles in the unit cube around the origin; every 9th
/// duplicates the previous one and every 13th is degenerate (a line).
fn random_mesh(rng: &mut Rng, triangles: usize, material: u32) -> TriangleMesh {
    let mut positions = Vec::with_capacity(3 * triangles);
    for t in 0..triangles {
        if t % 9 == 8 {
            let n = positions.len();
            positions.extend_from_within(n - 3..n);
            continue;
        }
        let c = rng.vec3() * 2.0 - Vec3::ONE;
        let (a, b) = ((rng.vec3() - 0.5) * 0.6, (rng.vec3() - 0.5) * 0.6);
        let b = if t % 13 == 12 { a * 2.0 } else { b };
        positions.extend([c, c + a, c + b]);
    }
    let indices = (0..triangles as u32).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
    TriangleMesh { name: "random".into(), positions, indices, material, ..Default::default() }
}

/// A scene of `objects` random objects (sizes from 1 to `max_triangles`,
/// one with two meshes, one with none) and `instances` instances with
/// random transforms, plus one identity and one singular instance.
pub fn random_scene(seed: u64, objects: usize, max_triangles: usize, instances: usize) -> Scene {
    let mut rng = Rng(seed);
    let mut scene = Scene::default();
    let material = scene.add_material(Material::default_diffuse());
    let mut ids = Vec::new();
    for o in 0..objects {
        let meshes = if o == 1 {
            Vec::new()
        } else {
            let n = if o == 0 { 1 } else { 1 + rng.below(max_triangles as u32) as usize };
            let mut m = vec![scene.add_mesh(random_mesh(&mut rng, n, material))];
            if o == 2 {
                m.push(scene.add_mesh(random_mesh(&mut rng, n / 2 + 1, material)));
            }
            m
        };
        ids.push(scene.add_object(Object { name: format!("object {o}"), meshes }));
    }
    scene.instances.push(Instance::new(ids[objects - 1], Affine3A::IDENTITY));
    scene.instances.push(Instance::new(ids[0], Affine3A::from_scale(Vec3::new(1.0, 0.0, 1.0))));
    for _ in 0..instances {
        let axis = (rng.vec3() - 0.5).normalize_or(Vec3::Y);
        let m = Affine3A::from_scale_rotation_translation(
            Vec3::splat(0.3 + rng.uniform() * 2.0) * Vec3::new(1.0, 0.5 + rng.uniform(), 1.0),
            Quat::from_axis_angle(axis, rng.uniform() * 6.0),
            (rng.vec3() - 0.5) * 10.0,
        );
        scene.instances.push(Instance::new(ids[rng.below(objects as u32) as usize], m));
    }
    scene
}

/// Rays from random points of `[-12, 12]^3` (half of them aimed at the
/// middle, where [`random_scene`] puts its instances) in directions not
/// normalised; some with short `t_max`, some axis-aligned.
pub fn random_rays(seed: u64, n: usize) -> Vec<Ray> {
    let mut rng = Rng(seed);
    (0..n)
        .map(|i| {
            let origin = (rng.vec3() - 0.5) * 24.0;
            let mut direction = (rng.vec3() - 0.5) * (0.5 + 3.0 * rng.uniform());
            if i % 17 == 0 {
                direction = Vec3::new(0.0, 0.0, if i % 2 == 0 { 1.0 } else { -1.0 });
            }
            if i % 2 == 0 {
                // Aimed at the middle, where most geometry is.
                direction = (rng.vec3() - 0.5) * 2.0 - origin;
            }
            let t_max = if i % 3 == 0 { 0.5 + 10.0 * rng.uniform() } else { f32::INFINITY };
            Ray { origin, direction, t_max, time: 0.0 }
        })
        .collect()
}

/// The closest hit over every triangle of every instance in `plan`, with
/// the CPU's transform and triangle test (the ground truth for traversals).
pub fn brute_force(tables: &SceneTables, plan: &ScenePlan, ray: &Ray) -> Option<HostHit> {
    let mut best: Option<HostHit> = None;
    let mut t_max = ray.t_max;
    for &i in &plan.valid_instances {
        let inst = &tables.instances[i as usize];
        let (o, d) = (Vec3A::from(ray.origin), Vec3A::from(ray.direction));
        let identity = (0..12).all(|k| inst.object_to_world[k] == if k % 5 == 0 { 1.0 } else { 0.0 });
        let (o, d) = if identity {
            (o, d)
        } else {
            let m = &inst.world_to_object;
            let row = |r: usize, v: Vec3A| m[r * 4] * v.x + m[r * 4 + 1] * v.y + m[r * 4 + 2] * v.z;
            (
                Vec3A::new(row(0, o) + m[3], row(1, o) + m[7], row(2, o) + m[11]),
                Vec3A::new(row(0, d), row(1, d), row(2, d)),
            )
        };
        let object = &tables.objects[inst.object as usize];
        for tri in object.first_triangle..object.first_triangle + object.triangle_count {
            let corner = |k: usize| {
                let v = tables.triangles[3 * tri as usize + k] as usize;
                Vec3::new(tables.vertices[3 * v], tables.vertices[3 * v + 1], tables.vertices[3 * v + 2])
            };
            if let Some((t, u, v)) = TriAccel::new([corner(0), corner(1), corner(2)]).intersect(o, d, t_max) {
                t_max = t;
                best = Some(HostHit { t, u, v, instance: i, triangle: tri });
            }
        }
    }
    best
}
