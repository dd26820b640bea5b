//! The shared Cornell-box scenes load with the expected content, and the
//! built-in Cornell box is the same scene as `cbox/diffuse`.

mod common;

use atoll_scene::cornell::builtin_cornell_box;
use atoll_scene::pbrt::load_file;
use atoll_scene::{AreaEmission, IntegratorSettings, Material, Rgb, Scene};
use common::{assert_close, shared_scene};
use glam::{UVec2, Vec3};

fn check_common(s: &Scene) {
    assert_eq!(s.settings.film.resolution, UVec2::new(512, 512));
    assert_eq!(s.settings.spp, 4096);
    assert_eq!(s.settings.integrator, IntegratorSettings::Path { max_depth: 15 });
    let cam = &s.settings.camera;
    assert!((cam.fov_degrees - 39.3077).abs() < 1e-5);
    assert_eq!(cam.lens_radius, 0.0);
    assert_close(cam.camera_to_world.transform_point3(Vec3::ZERO), Vec3::new(0.0, 1.0, -3.9), 1e-6);
    assert_close(cam.camera_to_world.transform_vector3(Vec3::Z), Vec3::Z, 1e-6);
    // `Scale -1 1 1` before LookAt mirrors the camera's x axis.
    assert_close(cam.camera_to_world.transform_vector3(Vec3::X), -Vec3::X, 1e-6);
    assert!(s.lights.is_empty());

    // World geometry only: one world object with one identity instance.
    assert_eq!(s.objects.len(), 1);
    assert_eq!(s.instances.len(), 1);
    assert_eq!(s.instances[0].object, 0);
    assert_eq!(s.instances[0].object_to_world, glam::Affine3A::IDENTITY);
    assert_eq!(s.objects[0].meshes.len(), s.meshes.len());

    // The light: a one-sided quad facing down, emitting (17, 12, 4), black diffuse.
    let lights: Vec<_> = s.meshes.iter().filter(|m| m.emission.is_some()).collect();
    assert_eq!(lights.len(), 1);
    let light = lights[0];
    assert_eq!(light.name, "light.ply");
    assert_eq!(light.emission, Some(AreaEmission { radiance: Rgb::new(17.0, 12.0, 4.0), two_sided: false }));
    assert_eq!(s.materials[light.material as usize], Material::Diffuse { reflectance: Rgb::ZERO });
    assert!(!light.flip_normals);
    for t in 0..light.triangle_count() {
        assert_close(light.geometric_normal(t).normalize(), -Vec3::Y, 1e-6);
    }
    assert!(light.positions.iter().all(|p| (p.y - 1.999).abs() < 1e-6));

    let by_name = |n: &str| s.meshes.iter().find(|m| m.name == n).unwrap();
    let white = Material::Diffuse { reflectance: Rgb::new(0.725, 0.71, 0.68) };
    assert_eq!(s.materials[by_name("floor.ply").material as usize], white);
    assert_eq!(
        s.materials[by_name("left.ply").material as usize],
        Material::Diffuse { reflectance: Rgb::new(0.63, 0.065, 0.05) }
    );
    assert_eq!(
        s.materials[by_name("right.ply").material as usize],
        Material::Diffuse { reflectance: Rgb::new(0.14, 0.45, 0.091) }
    );
    assert_eq!(by_name("floor.ply").positions[1], Vec3::new(-1.0, 0.0, 1.0));
}

#[test]
fn diffuse_cornell_box() {
    let loaded = load_file(&shared_scene("cbox/diffuse/scene.pbrt")).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let s = &loaded.scene;
    check_common(s);
    assert_eq!(s.settings.film.filename.as_deref(), Some("diffuse.exr"));
    assert_eq!(s.meshes.len(), 8);
    let stats = s.stats();
    assert_eq!(stats.unique_triangles, 2 * 6 + 12 * 2);
    assert_eq!(stats.instanced_triangles, 36);
    assert_eq!(stats.emissive_triangles, 2);
    // white, red, green and the light's black: unused named materials are not stored.
    assert_eq!(s.materials.len(), 4);
    assert!(s.meshes.iter().all(|m| m.normals.is_empty() && m.uvs.is_empty() && !m.flip_normals));
    assert_close(stats.bounds_min, Vec3::new(-1.0, 0.0, -1.0), 1e-6);
    assert_close(stats.bounds_max, Vec3::new(1.0, 2.0, 1.0), 1e-6);
}

#[test]
fn specular_cornell_box() {
    let loaded = load_file(&shared_scene("cbox/spec/scene.pbrt")).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let s = &loaded.scene;
    check_common(s);
    let sphere = s.meshes.iter().find(|m| m.name == "sphere.ply").unwrap();
    assert_eq!(sphere.triangle_count(), 20480);
    assert_eq!(sphere.positions.len(), 10242);
    assert_eq!(
        s.materials[sphere.material as usize],
        Material::Dielectric { eta: 1.5, alpha_x: 0.0, alpha_y: 0.0 }
    );
    let mirror = s.meshes.iter().find(|m| m.name == "mirror.ply").unwrap();
    assert_eq!(mirror.triangle_count(), 12);
    let Material::Conductor { eta, k, alpha_x, alpha_y } = s.materials[mirror.material as usize] else {
        panic!("mirror is not a conductor")
    };
    assert_eq!((eta, alpha_x, alpha_y), (Rgb::ONE, 0.0, 0.0));
    assert_eq!(k, Material::conductor_k_from_reflectance(Rgb::ONE));
    assert_eq!(s.stats().unique_triangles, 2 * 6 + 20480 + 12);
}

#[test]
fn builtin_cornell_box_equals_the_shared_diffuse_scene() {
    let builtin = builtin_cornell_box();
    let shared = load_file(&shared_scene("cbox/diffuse/scene.pbrt")).unwrap().scene;
    let mut settings = shared.settings.clone();
    settings.film.filename = None;
    settings.spp = 64;
    assert_eq!(builtin.settings, settings);
    assert_eq!(builtin.meshes.len(), shared.meshes.len());
    for (b, s) in builtin.meshes.iter().zip(&shared.meshes) {
        assert_eq!(b.positions, s.positions, "{}", s.name);
        assert_eq!(b.indices, s.indices, "{}", s.name);
        assert_eq!(
            builtin.materials[b.material as usize], shared.materials[s.material as usize],
            "{}",
            s.name
        );
        assert_eq!((b.emission, b.flip_normals), (s.emission, s.flip_normals), "{}", s.name);
    }
    assert_eq!(builtin.materials, shared.materials);
    assert_eq!(builtin.objects.len(), shared.objects.len());
    assert_eq!(builtin.instances.len(), shared.instances.len());
}
