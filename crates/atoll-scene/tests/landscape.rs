//! The benchmark landscape: determinism, growth scaling, the estimate,
//! placement on the terrain, object kinds and the view. Kept to growth ≤ 4
//! and reduced detail so debug builds run them in well under a second each.

use std::collections::HashMap;

use atoll_scene::landscape::Landscape;
use atoll_scene::{IntegratorSettings, Light, Material, Scene, TriangleMesh};
use glam::{UVec2, Vec3};

fn landscape(growth: u32, seed: u32, detail: f32) -> Landscape {
    Landscape { growth, seed, detail }
}

/// Object id by name.
fn objects(scene: &Scene) -> HashMap<&str, u32> {
    scene.objects.iter().enumerate().map(|(i, o)| (o.name.as_str(), i as u32)).collect()
}

/// Height of the terrain mesh (mesh 0, a row-major `(n+1)²` grid whose
/// cells are split along the `(i+1, j)`–`(i, j+1)` diagonal) at `(x, z)`,
/// found from the mesh alone.
fn mesh_height(terrain: &TriangleMesh, x: f32, z: f32) -> f32 {
    let row = (terrain.positions.len() as f64).sqrt() as usize;
    assert_eq!(row * row, terrain.positions.len());
    let p = |i: usize, j: usize| terrain.positions[j * row + i];
    let (x0, step) = (p(0, 0).x, p(1, 0).x - p(0, 0).x);
    let cell = |v: f32| {
        let u = ((v - x0) / step).clamp(0.0, (row - 1) as f32);
        let i = (u.floor() as usize).min(row - 2);
        (i, u - i as f32)
    };
    let ((i, _), (j, _)) = (cell(x), cell(z));
    // Fractions from the cell's own corners: what the triangles interpolate.
    let (a, d) = (p(i, j), p(i + 1, j + 1));
    let (fu, fv) = ((x - a.x) / (d.x - a.x), (z - a.z) / (d.z - a.z));
    let h = |di, dj| p(i + di, j + dj).y;
    if fu + fv <= 1.0 {
        h(0, 0) + fu * (h(1, 0) - h(0, 0)) + fv * (h(0, 1) - h(0, 0))
    } else {
        h(1, 1) + (1.0 - fu) * (h(0, 1) - h(1, 1)) + (1.0 - fv) * (h(1, 0) - h(1, 1))
    }
}

#[test]
fn same_seed_gives_the_same_scene_and_another_seed_does_not() {
    let (a, b) = (landscape(1, 7, 0.5).build(), landscape(1, 7, 0.5).build());
    assert_eq!(a.meshes.len(), b.meshes.len());
    for (m, n) in a.meshes.iter().zip(&b.meshes) {
        assert_eq!(
            (&m.positions, &m.normals, &m.indices, m.material),
            (&n.positions, &n.normals, &n.indices, n.material)
        );
    }
    assert_eq!(a.instances.len(), b.instances.len());
    for (i, j) in a.instances.iter().zip(&b.instances) {
        assert_eq!((i.object, i.object_to_world), (j.object, j.object_to_world));
    }
    assert_eq!((&a.materials, &a.lights, &a.settings), (&b.materials, &b.lights, &b.settings));

    let c = landscape(1, 8, 0.5).build();
    assert_ne!(a.meshes[0].positions, c.meshes[0].positions, "the terrain depends on the seed");
    assert_ne!(a.instances[5].object_to_world, c.instances[5].object_to_world, "so does placement");
    // Sizes do not: the estimate knows nothing of the seed's effects.
    assert_eq!(a.stats().instanced_triangles, c.stats().instanced_triangles);
}

#[test]
fn instances_and_instanced_triangles_grow_linearly() {
    let ratio = |a: u64, b: u64| a as f64 / b as f64;
    for detail in [1.0, 0.25] {
        let (one, four) = (landscape(1, 0, detail).estimate(), landscape(4, 0, detail).estimate());
        let r = ratio(four.instances - 1, one.instances - 1);
        assert!((3.6..=4.4).contains(&r), "instances x{r} at detail {detail}");
        let r = ratio(four.instanced_triangles, one.instanced_triangles);
        assert!((3.6..=4.4).contains(&r), "instanced triangles x{r} at detail {detail}");
    }
    // The documented sizes: growth g is about g million instanced triangles.
    for (growth, target) in [(1, 1e6), (10, 1e7), (100, 1e8), (1000, 1e9)] {
        let e = Landscape::new(growth).estimate();
        let r = e.instanced_triangles as f64 / target;
        assert!((0.99..1.01).contains(&r), "growth {growth}: {e:?}");
        assert!(e.unique_triangles * 20 < e.instanced_triangles, "instancing keeps memory small: {e:?}");
    }
    // Built scenes scale the same way (reduced detail keeps this quick).
    let (one, four) = (landscape(1, 3, 0.25).build().stats(), landscape(4, 3, 0.25).build().stats());
    let r = ratio(four.instanced_triangles, one.instanced_triangles);
    assert!((3.6..=4.4).contains(&r), "built: x{r}");
    // Objects get finer with growth (mildly), on top of the terrain's 2 × (128 √g)² triangles.
    let object_triangles = |g: u32| {
        let terrain = 2 * ((128.0 * (g as f64).sqrt()).round() as u64).pow(2);
        Landscape::new(g).estimate().unique_triangles - terrain
    };
    let r = ratio(object_triangles(1000), object_triangles(1));
    assert!((1.15..1.6).contains(&r), "object detail x{r}");
}

#[test]
fn estimate_matches_the_built_scene() {
    for (growth, seed, detail) in [(1, 0, 1.0), (3, 5, 0.3), (2, 1, 0.7)] {
        let l = landscape(growth, seed, detail);
        let (e, scene) = (l.estimate(), l.build());
        let s = scene.stats();
        assert_eq!(e.meshes, s.meshes as u64);
        assert_eq!(e.objects, s.objects as u64);
        assert_eq!(e.instances, s.instances as u64);
        assert_eq!(e.unique_triangles, s.unique_triangles);
        assert_eq!(e.instanced_triangles, s.instanced_triangles);
        assert_eq!(e.geometry_bytes, s.geometry_bytes);
        let vertices: usize = scene.meshes.iter().map(|m| m.positions.len()).sum();
        assert_eq!(e.vertices, vertices as u64);
        let object_triangles = |o: &atoll_scene::Object| -> u64 {
            o.meshes.iter().map(|&m| scene.meshes[m as usize].triangle_count() as u64).sum()
        };
        assert_eq!(e.largest_object_triangles, scene.objects.iter().map(object_triangles).max().unwrap());
        let instance_bytes = (s.instances * std::mem::size_of::<atoll_scene::Instance>()) as u64;
        assert_eq!(e.bytes, s.geometry_bytes + instance_bytes);
    }
}

#[test]
fn every_instance_stands_on_the_terrain() {
    let l = landscape(2, 11, 0.5);
    let scene = l.build();
    let terrain = &scene.meshes[0];
    let half = l.half_size();
    for inst in &scene.instances[1..] {
        let t = Vec3::from(inst.object_to_world.translation);
        assert!(t.x.abs() <= half && t.z.abs() <= half, "{t} outside the terrain");
        let h = mesh_height(terrain, t.x, t.z);
        assert!(t.y >= h - 1e-3, "instance at {t} is below the terrain ({h})");
        assert!(t.y <= h + 1e-3, "instance at {t} floats above the terrain ({h})");
        assert!((l.terrain_height(t.x, t.z) - h).abs() < 1e-3);
        // Rotation about the up axis and uniform scale only: up stays up.
        let up = inst.object_to_world.transform_vector3(Vec3::Y);
        assert!(up.x.abs() < 1e-5 && up.z.abs() < 1e-5 && up.y > 0.3, "{up}");
    }
}

#[test]
fn object_kinds_have_their_materials_and_are_all_used() {
    let scene = Landscape::new(1).build();
    let ids = objects(&scene);
    let materials = |name: &str| -> Vec<&Material> {
        let o = &scene.objects[ids[name] as usize];
        o.meshes.iter().map(|&m| &scene.materials[scene.meshes[m as usize].material as usize]).collect()
    };
    let is = |m: &Material, kind: &str| match (m, kind) {
        (Material::Diffuse { .. }, "diffuse") => true,
        (Material::Dielectric { eta, .. }, "dielectric") => *eta == 1.5,
        (Material::Conductor { .. }, "conductor") => true,
        _ => false,
    };
    assert_eq!(scene.objects[0].name, "world");
    assert_eq!(scene.objects[0].meshes, [0]);
    for (name, kind, meshes) in [
        ("world", "diffuse", 1),
        ("rock_round", "diffuse", 1),
        ("rock_flat", "diffuse", 1),
        ("rock_tall", "diffuse", 1),
        ("conifer", "diffuse", 2),
        ("broadleaf", "diffuse", 2),
        ("crystals", "dielectric", 1),
        ("glass_orb", "dielectric", 1),
        ("gold_torus", "conductor", 1),
    ] {
        let m = materials(name);
        assert_eq!(m.len(), meshes, "{name}");
        assert!(m.iter().all(|m| is(m, kind)), "{name}: {m:?}");
        let uses = scene.instances.iter().filter(|i| i.object == ids[name]).count();
        assert!(
            uses >= 1 && (name == "world") == (uses == 1) || name != "world" && uses >= 40,
            "{name}: {uses}"
        );
    }
    // Trees: bark and foliage are different materials.
    for tree in ["conifer", "broadleaf"] {
        let o = &scene.objects[ids[tree] as usize];
        let [trunk, crown] = [0, 1].map(|i| scene.meshes[o.meshes[i] as usize].material);
        assert_ne!(trunk, crown, "{tree}");
    }
}

#[test]
fn geometry_is_valid_closed_and_outward() {
    let scene = Landscape::new(1).build();
    for (id, mesh) in scene.meshes.iter().enumerate() {
        mesh.validate().unwrap();
        let normals = (0..mesh.triangle_count()).map(|t| mesh.geometric_normal(t));
        assert!(normals.clone().all(|n| n.length() > 0.0), "{}: degenerate triangle", mesh.name);
        if id == 0 {
            assert!(normals.clone().all(|n| n.y > 0.0), "terrain faces up");
        } else if mesh.name != "trunk" {
            // Closed and wound outwards: a positive signed volume.
            let volume: f32 = (0..mesh.triangle_count())
                .map(|t| {
                    let [a, b, c] = mesh.triangle(t);
                    a.dot(b.cross(c)) / 6.0
                })
                .sum();
            assert!(volume > 0.05, "{}: volume {volume}", mesh.name);
        }
        // Shading normals agree with the surface they smooth.
        if !mesh.normals.is_empty() {
            let agree = (0..mesh.triangle_count())
                .filter(|&t| {
                    let g = mesh.geometric_normal(t);
                    mesh.indices[t].iter().all(|&i| g.dot(mesh.normals[i as usize]) > 0.0)
                })
                .count();
            assert!(agree * 100 >= mesh.triangle_count() * 97, "{}: {agree}", mesh.name);
        }
    }
}

#[test]
fn the_camera_looks_across_the_land_under_sun_and_sky() {
    let l = Landscape::new(1);
    let scene = l.build();
    let s = &scene.settings;
    assert_eq!((s.film.resolution, s.spp), (UVec2::new(1280, 720), 16));
    assert_eq!(s.integrator, IntegratorSettings::Path { max_depth: 5 });
    let cam = s.camera.camera_to_world;
    let eye = cam.transform_point3(Vec3::ZERO);
    let forward = cam.transform_vector3(Vec3::Z).normalize();
    assert!(eye.x.abs() < l.half_size() && eye.z.abs() < l.half_size());
    assert!(eye.y > l.terrain_height(eye.x, eye.z) + 10.0, "above the ground");
    assert!(forward.y < -0.2 && forward.x > 0.5 && forward.z > 0.5, "down along the diagonal: {forward}");
    assert!(cam.transform_vector3(Vec3::Y).y > 0.5, "+y is up");
    // The centre of the image is land, not sky.
    let hit = (1..400).map(|i| eye + forward * i as f32).find(|p| p.y < l.terrain_height(p.x, p.z));
    assert!(hit.is_some_and(|p| p.x.abs() < l.half_size() && p.z.abs() < l.half_size()));
    match scene.lights.as_slice() {
        [Light::Distant { direction, radiance }, Light::Infinite { radiance: sky, portal: None }] => {
            assert!(direction.y < -0.3 && (direction.length() - 1.0).abs() < 1e-5);
            assert!(radiance.min_element() > 1.0 && sky.min_element() > 0.1 && sky.z > sky.x);
        }
        other => panic!("expected sun and sky, got {other:?}"),
    }
}

/// Sizes that would wrap the terrain's 32-bit vertex indices or tessellate
/// objects without end are refused before anything is made or estimated.
#[test]
fn sizes_past_the_scene_model_are_refused() {
    assert_eq!(Landscape::new(1000).check(), Ok(()));
    assert_eq!(landscape(262_000, 0, 1.0).check(), Ok(()));
    for (l, why) in [
        (Landscape::new(u32::MAX), "32-bit indices"),
        (landscape(262_200, 0, 1.0), "32-bit indices"),
        (landscape(1, 0, 150.0), "tessellates objects"),
        (landscape(1, 0, f32::NAN), "positive number"),
        (landscape(1, 0, 0.0), "positive number"),
        (landscape(1, 0, f32::INFINITY), "positive number"),
    ] {
        let e = l.check().unwrap_err();
        assert!(e.contains(why), "{l:?}: {e}");
    }
}

/// FNV-1a over the bytes of every mesh array and instance transform, in
/// scene order.
fn fingerprint(scene: &Scene) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h = (h ^ b as u64).wrapping_mul(0x100_0000_01b3);
        }
    };
    for m in &scene.meshes {
        eat(bytemuck::cast_slice(&m.positions));
        eat(bytemuck::cast_slice(&m.normals));
        eat(bytemuck::cast_slice(&m.indices));
    }
    for i in &scene.instances {
        eat(&i.object.to_le_bytes());
        eat(bytemuck::cast_slice(&i.object_to_world.to_cols_array()));
    }
    h
}

/// The landscape is a benchmark: the same fields must give the same
/// scene from one version to the next (and whatever the thread count), or
/// numbers measured before would stop being comparable.
#[test]
fn the_scene_is_the_same_bit_for_bit_as_it_was() {
    let scene = landscape(3, 5, 0.5).build();
    assert_eq!(fingerprint(&scene), 16569200931050012473, "growth 3, seed 5, detail 0.5");
    let scene = Landscape::new(1).build();
    assert_eq!(fingerprint(&scene), 7820661534689539574, "growth 1");
}
