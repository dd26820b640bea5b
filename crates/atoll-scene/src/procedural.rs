//! Procedural scenes: the benchmark landscape (a noise terrain with many
//! instanced spheres and rocks), and [`flatten`] to bake instances into
//! world-space meshes.

use glam::{Affine3A, Mat3, Quat, UVec2, Vec3};

use crate::{Instance, Material, Object, Scene, TriangleMesh};

/// Half the side of the square terrain, in scene units.
const HALF_SIZE: f32 = 50.0;
/// Share of the triangle budget that goes to the terrain; instances get the rest.
const TERRAIN_SHARE: usize = 4;

/// A landscape of about `target_triangles` instanced triangles (never fewer):
/// a quarter in a heightfield terrain (the world object), the rest in
/// instances of three tessellated objects (a sphere and two rocks) scattered
/// over it. Deterministic; one diffuse material; a 1024x1024, 60 degree camera
/// looking down at the terrain at an angle.
pub fn bench_scene(target_triangles: usize) -> Scene {
    let mut scene = Scene::default();
    let material = scene.add_material(Material::default_diffuse());

    let terrain_quads = (target_triangles / TERRAIN_SHARE / 2).max(4);
    let terrain = scene.add_mesh(TriangleMesh { material, ..terrain_mesh(terrain_quads) });
    let world = scene.add_object(Object { name: "world".into(), meshes: vec![terrain] });
    scene.instances.push(Instance::new(world, Affine3A::IDENTITY));

    // Object detail grows with the budget, so the instance count stays in the hundreds.
    let stacks = ((target_triangles as f32 / 2048.0).sqrt() as u32).clamp(4, 64);
    let shapes = [("sphere", 0.0, 0), ("rock_a", 0.35, 1), ("rock_b", 0.5, 2)];
    let mut objects = Vec::new();
    for (name, roughness, seed) in shapes {
        let mesh = TriangleMesh { material, ..blob_mesh(name, stacks, roughness, seed) };
        let tris = mesh.triangle_count();
        let mesh = scene.add_mesh(mesh);
        objects.push((scene.add_object(Object { name: name.into(), meshes: vec![mesh] }), tris));
    }
    let per_instance = objects.iter().map(|o| o.1).sum::<usize>() / objects.len();
    let terrain_tris = scene.meshes[terrain as usize].triangle_count();
    let instances = target_triangles.saturating_sub(terrain_tris).div_ceil(per_instance);
    // Cycling through the objects (rather than drawing them) keeps the total
    // predictable: at least the target.
    let mut rng = Rng(0x5eed);
    for i in 0..instances {
        let (object, _) = objects[i % objects.len()];
        let x = (rng.next() * 2.0 - 1.0) * HALF_SIZE * 0.95;
        let z = (rng.next() * 2.0 - 1.0) * HALF_SIZE * 0.95;
        let scale = 0.4 + 1.6 * rng.next() * rng.next();
        let tilt = Quat::from_rotation_x((rng.next() - 0.5) * 0.6);
        let rotation = Quat::from_rotation_y(rng.next() * std::f32::consts::TAU) * tilt;
        // Half sunk into the ground, like boulders.
        let position = Vec3::new(x, height(x, z) + 0.3 * scale, z);
        scene.instances.push(Instance::new(
            object,
            Affine3A::from_scale_rotation_translation(Vec3::splat(scale), rotation, position),
        ));
    }

    let eye = Vec3::new(0.0, 38.0, -72.0);
    let target = Vec3::new(0.0, 0.0, 6.0);
    let settings = &mut scene.settings;
    // glam 0.34's replacement for `Mat4::look_at_lh` (world to left-handed view space).
    settings.camera.camera_to_world = glam::camera::lh::view::look_at_mat4(eye, target, Vec3::Y).inverse();
    settings.camera.fov_degrees = 60.0;
    settings.film.resolution = UVec2::new(1024, 1024);
    settings.spp = 16;
    scene
}

/// [`bench_scene`] with every instance baked into world space: the same
/// triangles as rays see them, without instancing (for fair comparisons
/// with single-level ray tracers).
pub fn bench_scene_flat(target_triangles: usize) -> Scene {
    flatten(&bench_scene(target_triangles))
}

/// A copy of `scene` whose only object is the world object, holding every
/// instanced mesh transformed into world space, with one identity instance.
pub fn flatten(scene: &Scene) -> Scene {
    let mut flat = Scene {
        settings: scene.settings.clone(),
        materials: scene.materials.clone(),
        lights: scene.lights.clone(),
        measured: scene.measured.clone(),
        ..Scene::default()
    };
    for inst in &scene.instances {
        let m = inst.object_to_world;
        let normal_matrix = Mat3::from(m.matrix3).inverse().transpose();
        let mirrored = m.matrix3.determinant() < 0.0;
        for &mesh_id in &scene.objects[inst.object as usize].meshes {
            let mesh = &scene.meshes[mesh_id as usize];
            let mut moved = TriangleMesh {
                positions: mesh.positions.iter().map(|&p| m.transform_point3(p)).collect(),
                normals: mesh.normals.iter().map(|&n| (normal_matrix * n).normalize_or_zero()).collect(),
                // The transform swapping handedness flips pbrt's geometric normal.
                flip_normals: mesh.flip_normals ^ mirrored,
                ..mesh.clone()
            };
            if let Some(curves) = &mut moved.curves {
                // Pieces move themselves; their proxies are remade, not moved.
                let scale = m.matrix3.determinant().abs().cbrt();
                curves.transform(|p| m.transform_point3(p), |n| normal_matrix * n, scale);
                (moved.positions, moved.indices) = curves.proxy_triangles();
            }
            flat.meshes.push(moved);
        }
    }
    let meshes = (0..flat.meshes.len() as u32).collect();
    let world = flat.add_object(Object { name: "world".into(), meshes });
    flat.instances.push(Instance::new(world, Affine3A::IDENTITY));
    flat
}

/// Terrain height at `(x, z)`: a few octaves of smooth value noise.
fn height(x: f32, z: f32) -> f32 {
    let (mut sum, mut amplitude, mut frequency) = (0.0, 9.0, 1.0 / 28.0);
    for octave in 0..5 {
        sum += amplitude * (value_noise([x * frequency, z * frequency, octave as f32 * 7.1]) - 0.5);
        amplitude *= 0.45;
        frequency *= 2.1;
    }
    sum
}

/// A square grid of about `quads` quads over the terrain, two triangles each.
fn terrain_mesh(quads: usize) -> TriangleMesh {
    let n = (quads as f32).sqrt().ceil().max(2.0) as u32;
    let step = 2.0 * HALF_SIZE / n as f32;
    let mut positions = Vec::with_capacity(((n + 1) * (n + 1)) as usize);
    for j in 0..=n {
        for i in 0..=n {
            let (x, z) = (-HALF_SIZE + i as f32 * step, -HALF_SIZE + j as f32 * step);
            positions.push(Vec3::new(x, height(x, z), z));
        }
    }
    let mut indices = Vec::with_capacity((2 * n * n) as usize);
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            let (b, c, d) = (a + 1, a + n + 1, a + n + 2);
            indices.extend([[a, c, b], [b, c, d]]);
        }
    }
    with_normals(TriangleMesh { name: "terrain".into(), positions, indices, ..Default::default() })
}

/// A unit sphere of `stacks` rings and `2 * stacks` segments, its radius
/// displaced by up to `roughness` with 3D noise (0 gives a smooth sphere).
fn blob_mesh(name: &str, stacks: u32, roughness: f32, seed: u32) -> TriangleMesh {
    let slices = 2 * stacks;
    let mut positions = vec![Vec3::Y];
    for s in 1..stacks {
        let theta = std::f32::consts::PI * s as f32 / stacks as f32;
        for k in 0..slices {
            let phi = std::f32::consts::TAU * k as f32 / slices as f32;
            let dir = Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin());
            let p = dir * 2.3 + Vec3::splat(seed as f32 * 17.0);
            let bumps = value_noise(p.into()) + 0.5 * value_noise((p * 2.7).into());
            positions.push(dir * (1.0 + roughness * (bumps - 0.75)));
        }
    }
    positions.push(-Vec3::Y);
    let ring = |s: u32, k: u32| 1 + (s - 1) * slices + k % slices;
    let bottom = positions.len() as u32 - 1;
    let mut indices = Vec::new();
    for k in 0..slices {
        indices.push([0, ring(1, k + 1), ring(1, k)]);
        indices.push([bottom, ring(stacks - 1, k), ring(stacks - 1, k + 1)]);
        for s in 1..stacks - 1 {
            let (a, b, c, d) = (ring(s, k), ring(s, k + 1), ring(s + 1, k), ring(s + 1, k + 1));
            indices.extend([[a, b, c], [b, d, c]]);
        }
    }
    with_normals(TriangleMesh { name: name.into(), positions, indices, ..Default::default() })
}

/// Adds area-weighted vertex normals.
fn with_normals(mut mesh: TriangleMesh) -> TriangleMesh {
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

/// Smooth value noise in [0, 1): hashed lattice values, trilinear
/// interpolation with smoothstep weights.
fn value_noise(p: [f32; 3]) -> f32 {
    let cell = p.map(f32::floor);
    let w = [0, 1, 2].map(|a| {
        let f = p[a] - cell[a];
        f * f * (3.0 - 2.0 * f)
    });
    let c = cell.map(|v| v as i32);
    let lattice = |dx: i32, dy: i32, dz: i32| {
        let h = [c[0] + dx, c[1] + dy, c[2] + dz]
            .iter()
            .fold(0x9e37_79b9u32, |h, &v| (h ^ v as u32).wrapping_mul(0x0100_0193).rotate_left(13));
        Rng(h as u64).next()
    };
    let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
    let plane = |dz| {
        let y0 = lerp(lattice(0, 0, dz), lattice(1, 0, dz), w[0]);
        let y1 = lerp(lattice(0, 1, dz), lattice(1, 1, dz), w[0]);
        lerp(y0, y1, w[1])
    };
    lerp(plane(0), plane(1), w[2])
}

/// SplitMix64: small, deterministic, good enough for placement and noise.
struct Rng(u64);

impl Rng {
    /// Uniform in [0, 1).
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bench_scene_meets_the_target_deterministically() {
        for target in [1_000, 50_000] {
            let scene = bench_scene(target);
            let stats = scene.stats();
            assert!(stats.instanced_triangles >= target as u64, "{stats:?}");
            assert!(stats.instanced_triangles < target as u64 * 3 / 2, "{stats:?}");
            assert!(stats.instances > 10 && stats.objects == 4 && stats.materials == 1);
            for mesh in &scene.meshes {
                mesh.validate().unwrap();
                assert!((0..mesh.triangle_count()).all(|t| mesh.geometric_normal(t).length() > 0.0));
            }
            let again = bench_scene(target);
            assert_eq!(again.meshes[1].positions, scene.meshes[1].positions);
            assert_eq!(again.instances[7].object_to_world, scene.instances[7].object_to_world);
            assert_eq!(scene.settings.film.resolution, UVec2::new(1024, 1024));
        }
    }

    #[test]
    fn camera_looks_down_at_the_terrain() {
        let cam = bench_scene(1_000).settings.camera.camera_to_world;
        let forward = cam.transform_vector3(Vec3::Z).normalize();
        assert!(forward.y < -0.3 && forward.z > 0.5, "{forward}");
        assert!(cam.transform_vector3(Vec3::Y).y > 0.5);
        assert!(cam.transform_vector3(Vec3::X).x > 0.9, "+x is right when looking along +z");
    }

    #[test]
    fn flatten_keeps_world_space_triangles() {
        let scene = bench_scene(5_000);
        let flat = flatten(&scene);
        assert_eq!((flat.instances.len(), flat.objects.len()), (1, 1));
        assert_eq!(flat.stats().instanced_triangles, scene.stats().instanced_triangles);
        let inst = scene.instances[5];
        let mesh = &scene.meshes[scene.objects[inst.object as usize].meshes[0] as usize];
        let p = inst.object_to_world.transform_point3(mesh.positions[3]);
        assert!((flat.meshes[5].positions[3] - p).length() < 1e-5);
        // Instanced bounds transform object boxes, so they may only be looser.
        let ((lo, hi), (flat_lo, flat_hi)) = (scene.world_bounds().unwrap(), flat.world_bounds().unwrap());
        assert!(lo.cmple(flat_lo + 1e-4).all() && flat_hi.cmple(hi + 1e-4).all());
        assert!((lo - flat_lo).length() < 3.0 && (hi - flat_hi).length() < 3.0);
    }

    /// Flattened curves move their pieces (points, widths, normals) and
    /// remake their proxies around them.
    #[test]
    fn flatten_moves_curve_pieces() {
        use crate::curve::{CurveKind, Curves};
        let line = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0, Vec3::X * 3.0];
        let curves = Curves::from_segments(CurveKind::Ribbon, &[line], (0.1, 0.1), &[Vec3::Y, Vec3::Y], 2);
        let (positions, indices) = curves.proxy_triangles();
        let mut scene = Scene::default();
        let mesh =
            scene.add_mesh(TriangleMesh { positions, indices, curves: Some(curves), ..Default::default() });
        let object = scene.add_object(Object { name: "hair".into(), meshes: vec![mesh] });
        let to_world = Affine3A::from_scale_rotation_translation(
            Vec3::splat(2.0),
            glam::Quat::from_rotation_z(std::f32::consts::FRAC_PI_2),
            Vec3::new(1.0, 0.0, 0.0),
        );
        scene.instances.push(Instance::new(object, to_world));
        let flat = flatten(&scene);
        let moved = &flat.meshes[0];
        let pieces = &moved.curves.as_ref().unwrap().pieces;
        assert!((pieces[1].points[3] - Vec3::new(1.0, 6.0, 0.0)).length() < 1e-5, "{}", pieces[1].points[3]);
        assert!((pieces[0].widths[0] - 0.2).abs() < 1e-6);
        assert!((pieces[0].normals[0] - Vec3::new(-1.0, 0.0, 0.0)).length() < 1e-6);
        for (tri, piece) in moved.indices.iter().zip(pieces) {
            assert_eq!(moved.positions[tri[0] as usize], piece.bounds().0);
            assert_eq!(moved.positions[tri[1] as usize], piece.bounds().1);
        }
    }
}
