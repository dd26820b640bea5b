//! Host-side checks of the kernel parameters (no GPU needed).

use atoll_render::lights::Emitter;
use atoll_render::record::MaterialKind;
use atoll_render::{FrameContext, RenderOptions};
use atoll_scene::{IntegratorSettings, Light, Rgb, Scene};
use glam::{Vec2, Vec3, Vec4};

use super::*;

fn cornell_frame(integrator: IntegratorSettings) -> (Scene, FrameContext) {
    let mut scene = atoll_scene::cornell::builtin_cornell_box();
    scene.lights.push(Light::Point { position: Vec3::new(0.1, 0.5, 0.2), intensity: Rgb::splat(2.0) });
    scene.lights.push(Light::Infinite { radiance: Rgb::new(0.1, 0.2, 0.3), portal: None });
    scene.lights.push(Light::spot(Vec3::new(0.0, 1.9, 0.0), -Vec3::Y, Rgb::splat(3.0), 40.0, 5.0));
    scene.lights.push(Light::Goniometric {
        position: Vec3::new(0.2, 1.5, -0.1),
        world_to_light: glam::Mat3::from_rotation_x(0.3),
        intensity: Rgb::new(1.0, 2.0, 3.0),
        map: std::sync::Arc::new(atoll_scene::IntensityMap {
            resolution: 2,
            values: vec![0.5, 1.0, 0.0, 2.0],
        }),
    });
    scene.lights.push(Light::Projection {
        position: Vec3::new(-0.2, 1.0, 0.3),
        world_to_light: glam::Mat3::from_rotation_y(0.2),
        scale: 3.0,
        image: std::sync::Arc::new(atoll_scene::ProjectionImage {
            width: 3,
            height: 2,
            pixels: (0..6).map(|i| Rgb::new(i as f32, 0.5, 1.0)).collect(),
            tan_half_fov: 0.5,
        }),
    });
    let pixels = (0..12).map(|i| Rgb::new(i as f32, 1.0, 0.5)).collect();
    scene.lights.push(Light::Environment {
        image: std::sync::Arc::new(atoll_scene::EnvironmentImage::new(
            4,
            3,
            pixels,
            atoll_scene::EnvLayout::LatLong,
        )),
        scale: Rgb::splat(2.0),
        light_to_world: glam::Mat3::from_rotation_y(0.5),
        portal: None,
    });
    let mut options = RenderOptions::from_scene(&scene);
    options.resolution = glam::UVec2::new(64, 48);
    options.integrator = integrator;
    options.seed = 7;
    let frame = FrameContext::new(&scene, options);
    (scene, frame)
}

/// The camera ray computed from the parameter block the way camera.cuh
/// does must be the CPU's `CameraRays::ray`, bit for bit (both evaluate the
/// same f32 operations in the same order on the host).
fn ray_from_params(p: &FrameParams, raster: Vec2) -> (Vec3, Vec3) {
    let t = raster / Vec2::from(p.raster_size);
    let x = p.window_min[0] + t.x * (p.window_max[0] - p.window_min[0]);
    let y = p.window_max[1] - t.y * (p.window_max[1] - p.window_min[1]);
    let m = &p.camera_to_world;
    let row = |r: usize, v: Vec3, w: f32| {
        m[r * 4] * v.x + m[r * 4 + 1] * v.y + m[r * 4 + 2] * v.z + m[r * 4 + 3] * w
    };
    let (origin, dir) = if p.projection == projection_kind::ORTHOGRAPHIC {
        (Vec3::new(x, y, 0.0), Vec3::Z)
    } else {
        (Vec3::ZERO, Vec3::new(x, y, 1.0))
    };
    let o = Vec3::new(row(0, origin, 1.0), row(1, origin, 1.0), row(2, origin, 1.0));
    let d = Vec3::new(row(0, dir, 0.0), row(1, dir, 0.0), row(2, dir, 0.0)).normalize();
    (o, d)
}

#[test]
fn frame_params_reproduce_the_camera_and_options() {
    let (_, frame) = cornell_frame(IntegratorSettings::Path { max_depth: 6 });
    let p = FrameParams::from_frame(&frame);
    assert_eq!(p.resolution, [64, 48]);
    assert_eq!(p.raster_size, [64.0, 48.0]);
    assert_eq!((p.seed, p.integrator, p.max_depth), (7, integrator_kind::PATH, 6));
    assert_eq!(p.russian_roulette, 1);
    assert_eq!(p.lens_radius, 0.0, "the Cornell camera is a pinhole");
    for raster in [Vec2::new(0.5, 0.5), Vec2::new(63.2, 1.7), Vec2::new(20.0, 47.9)] {
        let cpu = frame.camera.ray(raster, Vec2::new(0.3, 0.6));
        let gpu = ray_from_params(&p, raster);
        assert_eq!(cpu, gpu, "raster {raster}");
    }
    // An orthographic camera's rays, too.
    let (mut scene, _) = cornell_frame(IntegratorSettings::Path { max_depth: 6 });
    scene.settings.camera.projection = atoll_scene::Projection::Orthographic;
    scene.settings.camera.screen_window = Some([-1.5, 0.5, -0.25, 2.0]);
    let ortho = FrameContext::new(&scene, RenderOptions::from_scene(&scene));
    let q = FrameParams::from_frame(&ortho);
    assert_eq!(
        (q.projection, q.window_min, q.window_max),
        (projection_kind::ORTHOGRAPHIC, [-1.5, -0.25], [0.5, 2.0])
    );
    for raster in [Vec2::new(0.5, 0.5), Vec2::new(63.2, 1.7), Vec2::new(20.0, 47.9)] {
        assert_eq!(
            ortho.camera.ray(raster, Vec2::new(0.3, 0.6)),
            ray_from_params(&q, raster),
            "raster {raster}"
        );
    }
    // Row 3 of the camera matrix is (0, 0, 0, 1): dropping it loses nothing.
    assert_eq!(frame.camera.camera_to_world().row(3), Vec4::W);
    assert_eq!(p.light_count as usize, frame.lights.emitters.len());
    assert_eq!(p.infinite_count, 2, "the constant sky and the environment image");
    assert_eq!(p.material_count as usize, frame.materials.len());
    assert_eq!(p.emitters, 0, "pointers are set by FrameParamsHost");

    let (_, ao) = cornell_frame(IntegratorSettings::AmbientOcclusion { max_distance: 0.25 });
    let p = FrameParams::from_frame(&ao);
    assert_eq!((p.integrator, p.max_depth, p.ao_max_distance), (integrator_kind::AMBIENT_OCCLUSION, 0, 0.25));
}

#[test]
fn frame_tables_mirror_the_light_set_and_materials() {
    let (_, frame) = cornell_frame(IntegratorSettings::Path { max_depth: 5 });
    let t = FrameTables::build(&frame);
    let lights = &frame.lights;
    assert_eq!(t.emitters.len(), lights.emitters.len());
    assert_eq!(t.light_pmf.len(), t.emitters.len());
    assert_eq!(t.light_cdf.len(), t.emitters.len() + 1);
    assert_eq!(*t.light_cdf.last().unwrap(), 1.0);
    assert!(!t.triangle_keys.is_empty(), "the Cornell light is a mesh");
    assert!(t.triangle_keys.windows(2).all(|w| w[0] < w[1]), "keys sorted for binary search");
    for (g, e) in t.emitters.iter().zip(&lights.emitters) {
        match *e {
            Emitter::Point { position, intensity } => {
                assert_eq!(g.kind, emitter_kind::POINT);
                assert_eq!(&g.p[..3], &position.to_array());
                assert_eq!(g.radiance, intensity.to_array());
            }
            Emitter::Infinite { radiance, portal } => {
                assert_eq!(g.kind, emitter_kind::INFINITE);
                assert_eq!(g.radiance, radiance.to_array());
                assert_eq!(portal, None);
                assert_eq!(g.portal, 0);
            }
            Emitter::Distant { .. } => unreachable!("no distant light in this scene"),
            Emitter::Environment { index, .. } => {
                let env = &lights.environments[index as usize];
                assert_eq!(g.kind, emitter_kind::ENVIRONMENT);
                assert_eq!(g.p, env.light_to_world.to_cols_array());
                assert_eq!((g.normal, g.area), ([4.0, 3.0, 1.0], env.func_sum));
                // Pixels (scaled), weights, marginal and conditional CDFs.
                let t0 = g.table as usize;
                assert_eq!(t.environment_tables.len() - t0, 3 * 12 + 12 + 4 + 3 * 5);
                assert_eq!(t.environment_tables[t0 + 3 * 5], 10.0, "pixel 5, red, scale 2");
                assert_eq!(&t.environment_tables[t0 + 48..t0 + 52], env.marginal_cdf.as_slice());
            }
            Emitter::Goniometric { position, world_to_light, intensity, map } => {
                assert_eq!(g.kind, emitter_kind::GONIOMETRIC);
                assert_eq!((g.p, g.normal), (world_to_light.to_cols_array(), position.to_array()));
                assert_eq!((g.radiance, g.area), (intensity.to_array(), 2.0));
                let t0 = g.table as usize;
                assert_eq!(
                    &t.environment_tables[t0..t0 + 4],
                    &lights.intensity_maps[map as usize].values[..]
                );
            }
            Emitter::Projection { position, world_to_light, scale, image } => {
                let image = &lights.projection_images[image as usize];
                assert_eq!(g.kind, emitter_kind::PROJECTION);
                assert_eq!((g.p, g.normal), (world_to_light.to_cols_array(), position.to_array()));
                assert_eq!(g.radiance, [scale, image.tan_half_fov, 0.0]);
                // Width, height, then r, g, b by rows.
                let t0 = g.table as usize;
                assert_eq!(&t.environment_tables[t0..t0 + 2], &[3.0, 2.0]);
                assert_eq!(&t.environment_tables[t0 + 2 + 3 * 4..t0 + 2 + 3 * 5], &[4.0, 0.5, 1.0]);
            }
            Emitter::Spot { position, direction, intensity, cos_falloff_start, cos_falloff_end } => {
                assert_eq!(g.kind, emitter_kind::SPOT);
                assert_eq!(&g.p[..3], &position.to_array());
                assert_eq!(&g.p[3..6], &direction.to_array());
                assert_eq!((g.p[6], g.p[7]), (cos_falloff_start, cos_falloff_end));
                assert_eq!(g.radiance, intensity.to_array());
            }
            Emitter::Triangle { p, normal, area, radiance, two_sided, texture, corner_error } => {
                assert_eq!(g.kind, emitter_kind::TRIANGLE);
                assert_eq!(&g.p[6..9], &p[2].to_array());
                assert_eq!((g.normal, g.area, g.radiance), (normal.to_array(), area, radiance.to_array()));
                assert_eq!(g.two_sided, two_sided as u32);
                assert_eq!(g.error, corner_error);
                assert_eq!(texture.is_none(), g.table == crate::params::NO_EMISSION_TEXTURE);
            }
        }
    }
    // Every (key, base) finds the same light index as the CPU lookup.
    for (&key, &base) in t.triangle_keys.iter().zip(&t.triangle_bases) {
        let (instance, mesh) = ((key >> 32) as u32, key as u32);
        assert_eq!(lights.triangle_light(instance, mesh, 1), Some(base + 1));
    }
    assert_eq!(t.materials.len(), frame.materials.len());
    for (g, m) in t.materials.iter().zip(&frame.materials) {
        assert_eq!(g.kind, m.kind as u32);
        assert_eq!(g.coeffs, m.coeffs.map(|c| c.to_bits()));
    }
    assert!(t.materials.iter().any(|m| m.kind == MaterialKind::Diffuse as u32));
    assert!(t.bytes() >= 184 + 80 * t.emitters.len() as u64);
}

#[test]
fn empty_frame_tables_still_have_a_distribution() {
    let scene = Scene::default();
    let frame = FrameContext::new(&scene, RenderOptions::from_scene(&scene));
    let t = FrameTables::build(&frame);
    assert!(t.emitters.is_empty() && t.triangle_keys.is_empty());
    assert_eq!(t.light_cdf, [1.0], "one entry: select() never reads it without emitters");
    let p = FrameParams::from_frame(&frame);
    assert_eq!((p.light_count, p.infinite_count, p.triangle_key_count), (0, 0, 0));
}

/// An infinite light's portal travels in the environment tables: the
/// emitter names its words, which are the light set's portal frame.
#[test]
fn portals_travel_in_the_environment_tables() {
    let mut scene = atoll_scene::cornell::builtin_cornell_box();
    let corners = [
        Vec3::new(0.5, 0.2, -1.0),
        Vec3::new(0.5, 1.6, -1.0),
        Vec3::new(-0.5, 1.6, -1.0),
        Vec3::new(-0.5, 0.2, -1.0),
    ];
    let portal = Some(atoll_scene::Portal::new(corners).unwrap());
    scene.lights.push(Light::Infinite { radiance: Rgb::splat(0.5), portal });
    let frame = FrameContext::new(&scene, RenderOptions::from_scene(&scene));
    let t = FrameTables::build(&frame);
    let (g, e) = t
        .emitters
        .iter()
        .zip(&frame.lights.emitters)
        .find(|(g, _)| g.kind == emitter_kind::INFINITE)
        .unwrap();
    let Emitter::Infinite { portal: Some(k), .. } = *e else { panic!("{e:?}") };
    assert!(g.portal > 0);
    let at = g.portal as usize - 1;
    assert_eq!(
        &t.environment_tables[at..at + PORTAL_WORDS],
        &portal_words(&frame.lights.portals[k as usize])
    );
    assert_eq!(frame.lights.portals[k as usize].z, -Vec3::Z, "the frame faces out of the box");
}
