//! White-furnace tests: scenes whose radiance is known in closed form.

mod common;

use std::sync::Arc;

use atoll_render::RenderOptions;
use atoll_scene::{
    AreaEmission, Camera, Instance, IntegratorSettings, Light, Material, Object, PrincipledParams, Rgb,
    Scene, TriangleMesh,
};
use common::{assert_finite, mean_and_stderr, render_with};
use glam::{Affine3A, UVec2, Vec3};

/// An axis-aligned cube [-1,1]³ as 12 triangles.
fn cube(material: u32, emission: Option<AreaEmission>) -> TriangleMesh {
    let positions: Vec<Vec3> = (0..8)
        .map(|i| {
            Vec3::new(
                (i & 1) as f32 * 2.0 - 1.0,
                (i >> 1 & 1) as f32 * 2.0 - 1.0,
                (i >> 2) as f32 * 2.0 - 1.0,
            )
        })
        .collect();
    let quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]];
    let indices = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
    TriangleMesh { name: "cube".into(), positions, indices, material, emission, ..Default::default() }
}

/// A UV sphere of radius 1 with smooth normals.
fn sphere(material: u32) -> TriangleMesh {
    common::uv_sphere(material, 48, 96)
}

fn scene_with(meshes: Vec<TriangleMesh>, materials: Vec<Material>, eye: Vec3, target: Vec3) -> Scene {
    let mut scene = Scene { materials, ..Default::default() };
    let ids = meshes.into_iter().map(|m| scene.add_mesh(m)).collect();
    let object = scene.add_object(Object { name: "world".into(), meshes: ids });
    scene.instances.push(Instance::new(object, Affine3A::IDENTITY));
    scene.settings.camera = Camera {
        camera_to_world: glam::camera::lh::view::look_at_mat4(eye, target, Vec3::Y).inverse(),
        fov_degrees: 60.0,
        ..Camera::default()
    };
    scene
}

fn options(spp: u32, max_depth: u32) -> RenderOptions {
    RenderOptions {
        resolution: UVec2::new(32, 32),
        spp,
        integrator: IntegratorSettings::Path { max_depth },
        seed: 3,
        russian_roulette: true,
        light_sampler: Default::default(),
        wave_size: 1 << 16,
        merge_waves: true,
        crop: None,
        film_response: glam::Mat3::IDENTITY,
        filter: atoll_scene::PixelFilter::PIXEL,
    }
}

/// A white (albedo 1) diffuse sphere under a uniform environment of
/// radiance 1 looks exactly as bright as the sky: every pixel is 1.
/// Exercises environment NEE, BSDF sampling and their MIS weights.
#[test]
fn white_sphere_under_uniform_sky_is_invisible() {
    let mut scene = scene_with(
        vec![sphere(0)],
        vec![Material::Diffuse { reflectance: Rgb::ONE }],
        Vec3::new(0.0, 0.0, -3.0),
        Vec3::ZERO,
    );
    scene.lights.push(Light::Infinite { radiance: Rgb::ONE, portal: None });
    let film = render_with(&Arc::new(scene), options(64, 8), None);
    assert_finite(&film);
    let pixels = film.pixels();
    for c in 0..3 {
        let (mean, err) = mean_and_stderr(pixels.iter().map(|p| p[c]));
        assert!((mean - 1.0).abs() < 4.0 * err + 2e-3, "channel {c}: mean {mean} ± {err}");
    }
}

/// The same furnace lit by uniform environment images (equal-area and
/// lat-long, rotated): image sampling, its density on escaped rays (MIS)
/// and the lookups must give the same 1 everywhere.
#[test]
fn white_sphere_under_a_uniform_environment_image_is_invisible() {
    use atoll_scene::{EnvLayout, EnvironmentImage};
    for (w, h, layout) in [(16, 16, EnvLayout::EqualArea), (32, 16, EnvLayout::LatLong)] {
        let mut scene = scene_with(
            vec![sphere(0)],
            vec![Material::Diffuse { reflectance: Rgb::ONE }],
            Vec3::new(0.0, 0.0, -3.0),
            Vec3::ZERO,
        );
        let image = EnvironmentImage::new(w, h, vec![Rgb::splat(0.5); (w * h) as usize], layout);
        scene.lights.push(Light::Environment {
            image: Arc::new(image),
            scale: Rgb::splat(2.0),
            light_to_world: glam::Mat3::from_rotation_x(0.4),
            portal: None,
        });
        let film = render_with(&Arc::new(scene), options(64, 8), None);
        assert_finite(&film);
        let pixels = film.pixels();
        for c in 0..3 {
            let (mean, err) = mean_and_stderr(pixels.iter().map(|p| p[c]));
            assert!((mean - 1.0).abs() < 4.0 * err + 2e-3, "{layout:?} channel {c}: mean {mean} ± {err}");
        }
    }
}

/// Inside a closed box whose walls emit Le = 1 and reflect albedo a = 0.5,
/// radiance is Le · Σ_{k=0..D} a^k everywhere. Exercises area-light NEE,
/// MIS on emitter hits, max depth and Russian roulette.
#[test]
fn closed_emissive_box_matches_geometric_series() {
    let albedo = 0.5f32;
    let max_depth = 12;
    let emission = AreaEmission { radiance: Rgb::ONE, two_sided: true };
    let scene = scene_with(
        vec![cube(0, Some(emission))],
        vec![Material::Diffuse { reflectance: Rgb::splat(albedo) }],
        Vec3::new(0.1, -0.2, -0.5),
        Vec3::new(0.3, 0.4, 1.0),
    );
    let expected: f64 = (0..=max_depth).map(|k| (albedo as f64).powi(k)).sum();
    let film = render_with(&Arc::new(scene), options(32, max_depth as u32), None);
    assert_finite(&film);
    let (mean, err) = mean_and_stderr(film.pixels().iter().map(|p| p.y));
    assert!((mean - expected).abs() < 4.0 * err + 2e-3, "mean {mean} ± {err}, expected {expected}");
}

/// Ambient occlusion inside a closed box is 0 everywhere; of a lone sphere
/// under an open sky it is 1 (convex: nothing occludes its hemisphere).
#[test]
fn ambient_occlusion_extremes() {
    let white = vec![Material::Diffuse { reflectance: Rgb::ONE }];
    let mut opts = options(4, 0);
    opts.integrator = IntegratorSettings::AmbientOcclusion { max_distance: f32::INFINITY };
    let inside = scene_with(vec![cube(0, None)], white.clone(), Vec3::ZERO, Vec3::Z);
    let film = render_with(&Arc::new(inside), opts.clone(), None);
    assert!(film.pixels().iter().all(|p| *p == Vec3::ZERO));
    let outside = scene_with(vec![sphere(0)], white, Vec3::new(0.0, 0.0, -2.5), Vec3::ZERO);
    let film = render_with(&Arc::new(outside), opts, None);
    // Every camera sample that hits the sphere contributes exactly 1, so each
    // pixel is (hits / spp): a fractional remainder means self-occlusion.
    let pixels = film.pixels();
    for p in &pixels {
        let hits = p.x * 4.0;
        assert!((hits - hits.round()).abs() < 1e-5, "a convex object occluded itself: {p}");
    }
    assert!(pixels.iter().filter(|p| p.x == 1.0).count() > 100);
}

/// Principled spheres under a uniform sky of radiance 1: smooth white metal
/// is a perfect mirror (every pixel 1, through its delta lobe); a rough
/// white dielectric and a white coated glass, whose lobes mix delta and
/// glossy ones with light sampling, reflect less than they receive but most
/// of it (the single-scattering lobes lose a little).
#[test]
fn white_principled_spheres_under_uniform_sky() {
    let p = |metallic: f32, roughness: f32, transmission: f32, clearcoat: f32| {
        Material::Principled(PrincipledParams {
            base_color: Rgb::ONE,
            metallic,
            roughness,
            specular: 0.5,
            specular_tint: 0.0,
            sheen: 0.0,
            sheen_tint: 0.5,
            clearcoat,
            clearcoat_gloss: 1.0,
            transmission,
            eta: 1.5,
        })
    };
    for (material, lo, hi) in [
        (p(1.0, 0.0, 0.0, 0.0), 1.0, 1.0),
        (p(0.0, 0.5, 0.0, 0.0), 0.9, 1.0),
        (p(0.0, 0.3, 1.0, 1.0), 0.9, 1.0),
    ] {
        let mut scene =
            scene_with(vec![sphere(0)], vec![material.clone()], Vec3::new(0.0, 0.0, -3.0), Vec3::ZERO);
        scene.lights.push(Light::Infinite { radiance: Rgb::ONE, portal: None });
        let film = render_with(&Arc::new(scene), options(64, 16), None);
        assert_finite(&film);
        let pixels = film.pixels();
        for c in 0..3 {
            let (mean, err) = mean_and_stderr(pixels.iter().map(|p| p[c]));
            let slack = 4.0 * err + 2e-3;
            assert!(mean > lo - slack && mean < hi + slack, "{material:?} channel {c}: mean {mean} ± {err}");
        }
    }
}
