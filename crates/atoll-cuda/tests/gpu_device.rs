//! `CudaDevice` against `CpuDevice`: the same stages on the same scene must
//! give the same queues and (up to float rounding) the same image. Ignored
//! unless asked for (`--include-ignored`); see tests/common.

mod common;

use std::sync::Arc;

use atoll_bvh::ScenePart;
use atoll_cuda::CudaDevice;
use atoll_render::integrator::render_warmed;
use atoll_render::record::flags;
use atoll_render::{render, CpuDevice, Device, DeviceError, FrameContext, Queue, RenderOptions, Wave};
use atoll_scene::{IntegratorSettings, Scene};
use glam::{UVec2, Vec3};

use common::gpu_or_skip;

fn options(scene: &Scene, res: u32, spp: u32) -> RenderOptions {
    let mut o = RenderOptions::from_scene(scene);
    o.resolution = UVec2::splat(res);
    o.spp = spp;
    o
}

fn cornell() -> Arc<Scene> {
    Arc::new(atoll_scene::cornell::builtin_cornell_box())
}

/// Largest relative difference of the channel means.
fn mean_diff(a: Vec3, b: Vec3) -> f32 {
    ((a - b).abs() / a.abs().max(Vec3::splat(1e-6))).max_element()
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn camera_rays_and_hits_match_the_cpu_device() {
    let Some(gpu) = gpu_or_skip("stages") else { return };
    // An orthographic camera with a thin lens and an off-centre screen
    // window, and spherical ones, make their rays as the CPU does, too.
    let mut orthographic = atoll_scene::cornell::builtin_cornell_box();
    orthographic.settings.camera = atoll_scene::Camera {
        projection: atoll_scene::Projection::Orthographic,
        screen_window: Some([-1.2, 0.8, -0.9, 1.1]),
        lens_radius: 0.05,
        focal_distance: 4.0,
        ..orthographic.settings.camera.clone()
    };
    // Spherical cameras in both mappings.
    let spherical = |mapping| {
        let mut s = atoll_scene::cornell::builtin_cornell_box();
        s.settings.camera.projection = atoll_scene::Projection::Spherical { mapping };
        Arc::new(s)
    };
    let cameras = [
        Arc::new(orthographic),
        spherical(atoll_scene::EnvLayout::EqualArea),
        spherical(atoll_scene::EnvLayout::LatLong),
        cornell(),
    ];
    for scene in cameras {
        let frame = Arc::new(FrameContext::new(&scene, options(&scene, 32, 1)));
        let mut cpu = CpuDevice::new();
        let mut cuda = CudaDevice::on(gpu.clone());
        cpu.prepare(&scene, &ScenePart::whole(&scene), &frame).unwrap();
        cuda.prepare(&scene, &ScenePart::whole(&scene), &frame).unwrap();
        let wave = Wave { sample: 0, first_pixel: 0, pixel_count: 32 * 32 };
        for device in [&mut cpu as &mut dyn Device, &mut cuda] {
            device.queue_work(&wave).unwrap();
            device.refill().unwrap();
        }
        let (c, g) = (cpu.read_queue(Queue::Paths).unwrap(), cuda.read_queue(Queue::Paths).unwrap());
        assert_eq!(c.len(), g.len());
        for (a, b) in c.iter().zip(&g) {
            assert_eq!((a.pixel, a.sample, a.flags, a.depth), (b.pixel, b.sample, b.flags, b.depth));
            assert!(
                a.origin().abs_diff_eq(b.origin(), 1e-4) && a.direction().abs_diff_eq(b.direction(), 1e-4)
            );
        }
        if scene.settings.camera.projection != atoll_scene::Projection::Perspective {
            continue;
        }
        // Trace the CPU's rays on both, so that only traversal and hit attributes differ.
        cuda.write_queue(Queue::Paths, &c).unwrap();
        cpu.trace_paths().unwrap();
        cuda.trace_paths().unwrap();
        let (c, g) = (cpu.read_queue(Queue::Paths).unwrap(), cuda.read_queue(Queue::Paths).unwrap());
        let mut mismatched = 0;
        for (a, b) in c.iter().zip(&g) {
            if a.has(flags::HIT) != b.has(flags::HIT) || a.instance != b.instance {
                mismatched += 1;
                continue;
            }
            if a.has(flags::HIT) {
                assert!((a.t_max - b.t_max).abs() <= 1e-4 * a.t_max.max(1.0), "{} vs {}", a.t_max, b.t_max);
                assert!(Vec3::from(a.position).abs_diff_eq(Vec3::from(b.position), 1e-4));
                assert!(a.geometric_normal().abs_diff_eq(b.geometric_normal(), 1e-3));
                assert_eq!((a.material, a.coeffs, a.light), (b.material, b.coeffs, b.light));
            }
        }
        // Rays through triangle edges may legitimately disagree.
        assert!(mismatched <= c.len() / 200, "{mismatched} of {} hits differ", c.len());
    }
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn cornell_box_matches_the_cpu_device_and_is_deterministic() {
    let Some(gpu) = gpu_or_skip("cornell") else { return };
    let scene = cornell();
    let mut o = options(&scene, 64, 16);
    o.russian_roulette = false;
    o.integrator = IntegratorSettings::Path { max_depth: 8 };
    let cpu = render(&mut CpuDevice::new(), &scene, o.clone(), &mut |_, _| {}).unwrap();
    let mut cuda = CudaDevice::on(gpu);
    let errors = cuda.errors();
    let a = render(&mut cuda, &scene, o.clone(), &mut |_, _| {}).unwrap();
    let b = render(&mut cuda, &scene, o.clone(), &mut |_, _| {}).unwrap();
    // One wave at a time no two records of a queue share a pixel, so film
    // atomics never race: reruns are identical bit for bit.
    let one_at_a_time = RenderOptions { merge_waves: false, ..o };
    let c = render(&mut cuda, &scene, one_at_a_time.clone(), &mut |_, _| {}).unwrap();
    let d = render(&mut cuda, &scene, one_at_a_time.clone(), &mut |_, _| {}).unwrap();
    // A warmed frame: the first sample rendered on the prepared device,
    // then film and counters cleared; the frame after is the cold one.
    let warmed = render_warmed(&mut cuda, &scene, one_at_a_time, &mut |_, _| {}).unwrap();
    assert_eq!(errors.get(), None);
    assert_eq!(warmed.film.sum, d.film.sum, "a warmed frame is the cold frame");
    assert_eq!(warmed.device.rays_traced, d.device.rays_traced);
    assert_eq!(warmed.device.shadow_rays_traced, d.device.shadow_rays_traced);
    assert!(warmed.device.busy_seconds <= warmed.render_seconds * 1.5, "the warm-up's busy time is cleared");
    let (mc, mg) = (cpu.film.mean(), a.film.mean());
    println!("mean cpu {mc}, gpu {mg}; gpu {:.2} M rays/s", a.rays_per_second() / 1e6);
    assert!(mean_diff(mc, mg) < 0.02, "means differ: cpu {mc}, gpu {mg}");
    assert_eq!(c.film.sum, d.film.sum, "two GPU renders of one frame, one wave at a time, are identical");
    // Merged waves trace the same paths; samples of one pixel may meet in
    // a queue and add to the film in either order.
    for (i, (p, q)) in
        a.film.sum.iter().zip(&b.film.sum).chain(a.film.sum.iter().zip(&c.film.sum)).enumerate()
    {
        assert!(p.abs_diff_eq(*q, 1e-5 * p.abs().max_element().max(1.0)), "pixel {i}: {p} vs {q}");
    }
    assert_eq!(a.device.rays_traced, b.device.rays_traced);
    assert_eq!(a.device.rays_traced, c.device.rays_traced);
    assert!(a.device.rays_traced >= 64 * 64 * 16);
    assert!(a.device.busy_seconds > 0.0 && a.device.busy_seconds <= a.render_seconds * 1.5);
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn ambient_occlusion_on_an_instanced_scene_matches_the_cpu_device() {
    let Some(gpu) = gpu_or_skip("ao instanced") else { return };
    let scene = Arc::new(atoll_scene::procedural::bench_scene(100_000));
    let mut o = options(&scene, 96, 4);
    o.integrator = IntegratorSettings::AmbientOcclusion { max_distance: 5.0 };
    let cpu = render(&mut CpuDevice::new(), &scene, o.clone(), &mut |_, _| {}).unwrap();
    let gpu = render(&mut CudaDevice::on(gpu), &scene, o, &mut |_, _| {}).unwrap();
    let (mc, mg) = (cpu.film.mean(), gpu.film.mean());
    assert!(mean_diff(mc, mg) < 0.01, "AO means differ: cpu {mc}, gpu {mg}");
    let (sc, sg) = (cpu.device.shadow_rays_traced as f64, gpu.device.shadow_rays_traced as f64);
    assert!((sc - sg).abs() <= 0.005 * sc, "shadow rays: cpu {sc}, gpu {sg}");
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn memory_budget_is_refused_before_allocating() {
    let Some(gpu) = gpu_or_skip("budget") else { return };
    let scene = cornell();
    let frame = Arc::new(FrameContext::new(&scene, options(&scene, 512, 1)));
    let mut cuda = CudaDevice::on(gpu).with_memory_budget(1 << 20);
    match cuda.prepare(&scene, &ScenePart::whole(&scene), &frame) {
        Err(DeviceError::OutOfMemory { needed, budget, .. }) => assert!(needed > budget && budget == 1 << 20),
        other => panic!("expected OutOfMemory, got {other:?}"),
    }
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn stages_before_prepare_are_errors_not_panics() {
    let Some(gpu) = gpu_or_skip("usage") else { return };
    let mut cuda = CudaDevice::on(gpu);
    let first = cuda.queue_work(&Wave { sample: 0, first_pixel: 0, pixel_count: 4 }).unwrap_err();
    assert!(first.to_string().contains("before prepare"), "{first}");
    // Once failed, every later stage says so, and queues read as empty.
    match cuda.trace_paths() {
        Err(DeviceError::Stopped { first, .. }) => assert!(first.contains("before prepare"), "{first}"),
        other => panic!("expected Stopped, got {other:?}"),
    }
    assert_eq!(cuda.queue_len(Queue::Paths).unwrap_or(0), 0);
    assert!(cuda.errors().get().unwrap().contains("before prepare"));
}

/// Renders `scene` one wave at a time on the CPU and on `cuda` and checks
/// the images agree: channel means within 0.1%, fewer than 0.5% of pixels
/// off by more than 0.1% (`what` names the case in failures).
fn assert_renders_match(cuda: &mut CudaDevice, scene: &Arc<Scene>, what: &str) {
    let errors = cuda.errors();
    let o = RenderOptions { merge_waves: false, ..RenderOptions::from_scene(scene) };
    let cpu = render(&mut CpuDevice::new(), scene, o.clone(), &mut |_, _| {}).unwrap();
    let gpu = render(cuda, scene, o, &mut |_, _| {}).unwrap();
    assert_eq!(errors.get(), None);
    assert_films_close(&cpu.film, &gpu.film, what, 1e-3, 200);
}

/// Renders `scene` on the CPU and on `cuda` and checks the films agree
/// ([`assert_films_close`] with `mean_tolerance` and `one_in`).
fn assert_devices_agree(cuda: &mut CudaDevice, scene: Scene, what: &str, mean_tolerance: f32, one_in: usize) {
    let scene = Arc::new(scene);
    let o = RenderOptions::from_scene(&scene);
    let cpu = render(&mut CpuDevice::new(), &scene, o.clone(), &mut |_, _| {}).unwrap();
    let gpu = render(cuda, &scene, o, &mut |_, _| {}).unwrap();
    assert_films_close(&cpu.film, &gpu.film, what, mean_tolerance, one_in);
}

/// The films' channel means agree within `mean_tolerance` (relative), and
/// fewer than one pixel in `one_in` differs by more than 0.1% of its
/// brightest channel.
fn assert_films_close(
    cpu: &atoll_render::Film,
    gpu: &atoll_render::Film,
    what: &str,
    mean_tolerance: f32,
    one_in: usize,
) {
    let (mc, mg) = (cpu.mean(), gpu.mean());
    assert!(mean_diff(mc, mg) < mean_tolerance, "{what}: means cpu {mc}, gpu {mg}");
    let differ = cpu
        .sum
        .iter()
        .zip(&gpu.sum)
        .filter(|(p, q)| !p.abs_diff_eq(**q, 1e-3 * p.abs().max_element().max(0.05)))
        .count();
    assert!(differ * one_in < cpu.sum.len(), "{what}: {differ} of {} pixels differ", cpu.sum.len());
}

/// A realistic camera's rays (traced through its lens on the GPU from the
/// packed lens table) render the image the CPU renders: vignetting, focus
/// and all.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn realistic_cameras_match_the_cpu_device() {
    let Some(gpu) = gpu_or_skip("realistic camera") else { return };
    let mut cuda = CudaDevice::on(gpu);
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/realistic.pbrt");
    let mut scene = atoll_scene::load_any(std::path::Path::new(path)).unwrap().scene;
    scene.settings.film.resolution = UVec2::new(96, 64);
    scene.settings.spp = 16;
    assert_renders_match(&mut cuda, &Arc::new(scene.clone()), "realistic.pbrt");
    // The same lens wide open with pbrt's star-shaped stop.
    use atoll_scene::lens::{parse_lens_file, ApertureImage, LensSystem};
    let lens_file = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/singlet-50mm.dat");
    let values = parse_lens_file(&std::fs::read_to_string(lens_file).unwrap()).unwrap();
    let star = ApertureImage::builtin("star");
    let (lens, _) = LensSystem::new(&values, 12.0, star, 3.04, scene.settings.film.diagonal).unwrap();
    scene.settings.camera.lens = Some(Arc::new(lens));
    assert_renders_match(&mut cuda, &Arc::new(scene), "realistic.pbrt with a star-shaped stop");
}

/// Curve pieces (flat, cylinder and ribbon curves, bent, tapered, under
/// diffuse and hair materials, in the world and instanced) are intersected
/// and shaded on the GPU as on the CPU: the same hits but for fused
/// multiply-adds at their edges, so the images agree in their means and
/// nearly every pixel; `scenes/hair.pbrt` too.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn curves_match_the_cpu_device() {
    let Some(gpu) = gpu_or_skip("curves") else { return };
    let mut cuda = CudaDevice::on(gpu);
    let source = r#"
LookAt 0 0.5 5  0 0.5 0  0 1 0
Camera "perspective" "float fov" [ 40 ]
Sampler "independent" "integer pixelsamples" [ 64 ]
Integrator "path" "integer maxdepth" [ 8 ]
Film "rgb" "integer xresolution" [ 64 ] "integer yresolution" [ 48 ]
WorldBegin
LightSource "infinite" "rgb L" [ 0.4 0.45 0.5 ]
LightSource "distant" "point3 from" [ -1 3 2 ] "point3 to" [ 0 0 0 ] "rgb L" [ 3 3 3 ]
Material "diffuse" "rgb reflectance" [ 0.5 0.5 0.5 ]
Shape "trianglemesh" "point3 P" [ -4 -1 -4  4 -1 -4  4 -1 4  -4 -1 4 ] "integer indices" [ 0 1 2 0 2 3 ]
Material "diffuse" "rgb reflectance" [ 0.8 0.3 0.2 ]
Shape "curve" "string type" "flat" "point3 P" [ -2 -1 0  -1.5 1 0.5  -1 0 -0.5  -0.8 2 0 ] "float width0" [ 0.3 ] "float width1" [ 0.05 ]
Material "hair" "float eumelanin" [ 0.8 ]
Shape "curve" "string type" "cylinder" "point3 P" [ -0.5 -1 0  0 0.5 1  0.2 1 -1  0.5 2 0 ] "float width" [ 0.25 ]
Material "conductor"
Shape "curve" "string type" "ribbon" "point3 P" [ 1 -1 0  1.2 0 0  1.4 1 0  1.3 2 0 ] "normal N" [ 0 0 1  1 0 1 ] "float width" [ 0.4 ]
ObjectBegin "tuft"
Material "hair" "rgb sigma_a" [ 0.3 0.6 1.2 ]
Shape "curve" "string type" "cylinder" "point3 P" [ 0 0 0  0.1 0.3 0  -0.1 0.6 0.1  0 1 0 ] "float width0" [ 0.08 ] "float width1" [ 0.02 ] "integer splitdepth" [ 1 ]
ObjectEnd
AttributeBegin
Translate 2 -1 1
Rotate 30 0 0 1
ObjectInstance "tuft"
AttributeEnd
AttributeBegin
Translate -2.5 -1 1
Scale 1.5 1.5 1.5
ObjectInstance "tuft"
AttributeEnd
"#;
    let loaded = atoll_scene::pbrt::load_str(source, "curves.pbrt", std::path::Path::new(".")).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let hair = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/hair.pbrt");
    let mut hair = atoll_scene::load_any(std::path::Path::new(hair)).unwrap().scene;
    hair.settings.spp = 16;
    for (scene, what) in [(loaded.scene, "curves"), (hair, "hair.pbrt")] {
        assert_devices_agree(&mut cuda, scene, what, 5e-3, 20);
    }
}

/// Subsurface scattering (`scenes/subsurface.pbrt`: measured, coloured,
/// rough and reflectance-given interiors, a backlit slab): the images
/// agree in the mean. A walk's numbers come from where its segments start,
/// which the devices round apart in the last bit after a step or two (the
/// stage test holds each step to the CPU's): past that the walks differ,
/// so pixels are not compared, and the means within the noise of 64
/// samples.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn subsurface_matches_the_cpu_device() {
    let Some(gpu) = gpu_or_skip("subsurface") else { return };
    let mut cuda = CudaDevice::on(gpu);
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/subsurface.pbrt");
    let mut scene = atoll_scene::load_any(std::path::Path::new(path)).unwrap().scene;
    scene.settings.spp = 64;
    assert_devices_agree(&mut cuda, scene, "subsurface.pbrt", 1.5e-2, 1);
}

/// Moving instances (`scenes/motion.pbrt`: a sliding ball, a box turning
/// and rising, a spinning ring of instances) and a moving camera are where
/// the CPU puts them at each path's time: rays take the same times on both
/// devices, and the TLAS bounds instances over their motion.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn motion_blur_matches_the_cpu_device() {
    let Some(gpu) = gpu_or_skip("motion blur") else { return };
    let mut cuda = CudaDevice::on(gpu);
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/motion.pbrt");
    let mut scene = atoll_scene::load_any(std::path::Path::new(path)).unwrap().scene;
    scene.settings.spp = 32;
    assert!(scene.motions.len() >= 3);
    // And with the camera turning and stepping aside while the shutter is open.
    let mut moving_camera = scene.clone();
    let start = moving_camera.settings.camera.camera_to_world.as_dmat4();
    let end = glam::DMat4::from_translation(glam::DVec3::new(0.3, 0.1, 0.0))
        * start
        * glam::DMat4::from_rotation_y(0.05);
    moving_camera.settings.camera.motion = atoll_scene::Motion::new(&start, &end, [0.0, 1.0]);
    assert!(moving_camera.settings.camera.motion.is_some());
    for (scene, what) in [(scene, "motion.pbrt"), (moving_camera, "motion.pbrt, moving camera")] {
        assert_devices_agree(&mut cuda, scene, what, 5e-3, 20);
    }
}

/// Anisotropic lobes (conductor, dielectric, coated diffuse, measured)
/// turn with the surface's dp/du on the GPU as on the CPU, bump-mapped or
/// not (the frame's tangent written with the hit, read when shading).
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn anisotropic_frames_match_the_cpu_device() {
    use atoll_scene::texture_scenes::anisotropic_plane_scene;
    use atoll_scene::{CoatedDiffuseParams, Coating, Material, MeasuredBrdf, Rgb};
    let Some(gpu) = gpu_or_skip("anisotropy") else { return };
    let mut cuda = CudaDevice::on(gpu);
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/measured-ggx-aniso.bsdf");
    let table = MeasuredBrdf::from_bytes(&std::fs::read(path).unwrap(), "measured-ggx-aniso.bsdf").unwrap();
    let coating = Coating { alpha_x: 0.1, alpha_y: 0.4, ..Coating::PBRT_DEFAULT };
    let materials = [
        Material::Conductor {
            eta: Rgb::new(0.2, 0.9, 1.1),
            k: Rgb::new(3.9, 2.4, 2.2),
            alpha_x: 0.1,
            alpha_y: 0.4,
        },
        Material::Dielectric { eta: 1.5, alpha_x: 0.1, alpha_y: 0.4 },
        Material::CoatedDiffuse(CoatedDiffuseParams { reflectance: Rgb::splat(0.5), coating }),
        Material::Measured { brdf: 0 },
    ];
    for material in materials {
        for (angle, slopes) in [(30.0, glam::Vec2::ZERO), (120.0, glam::Vec2::new(0.4, -0.3))] {
            let mut scene = anisotropic_plane_scene(material.clone(), angle, slopes);
            scene.measured = vec![Arc::new(table.clone())];
            let what = format!("{material:?} at {angle}°, bumps {slopes}");
            if !matches!(material, Material::CoatedDiffuse(_)) {
                scene.settings.spp = 64;
                assert_renders_match(&mut cuda, &Arc::new(scene), &what);
                continue;
            }
            // The coating's random walks are seeded by the directions'
            // bits, and the bumped frame may differ by an ulp (fused
            // multiply-adds): other walks, the same distribution. 1024
            // samples on 64 pixels put the means' noise near 0.2%.
            scene.settings.spp = 1024;
            let scene = Arc::new(scene);
            let o = RenderOptions::from_scene(&scene);
            let cpu = render(&mut CpuDevice::new(), &scene, o.clone(), &mut |_, _| {}).unwrap();
            let gpu = render(&mut cuda, &scene, o, &mut |_, _| {}).unwrap();
            let (mc, mg) = (cpu.film.mean(), gpu.film.mean());
            assert!(mean_diff(mc, mg) < 1e-2, "{what}: means cpu {mc}, gpu {mg}");
        }
    }
}

/// Textured parameters (a checkerboard ground, a screen that is a mix
/// chosen by a texture) and alpha cut-outs (the screen's stripes, seen from
/// above and casting their shadow below) render alike on CPU and GPU: same
/// texture programs, same alpha decisions.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn textures_and_alpha_cut_outs_match_the_cpu_device() {
    use atoll_scene::texture_scenes::{cutout_scene, Screen};
    let Some(gpu) = gpu_or_skip("textures") else { return };
    let mut cuda = CudaDevice::on(gpu);
    for eye in [Vec3::new(0.0, 0.0, 3.0), Vec3::new(0.0, 0.0, 0.6)] {
        for screen in [Screen::AlphaMask, Screen::Strips] {
            let scene = Arc::new(cutout_scene(screen, eye));
            assert_renders_match(&mut cuda, &scene, &format!("{screen:?} from {eye}"));
        }
    }
}

/// 3D texture mappings (pbrt's planar, spherical and cylindrical) give the
/// GPU the same textured materials and mix choices as the CPU: both
/// checkerboards of the cut-out scene (the ground's reflectance, the
/// screen's mix amount) mapped from the hit point.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn projected_textures_match_the_cpu_device() {
    use atoll_scene::texture_scenes::{cutout_scene, Screen};
    use atoll_scene::{TexMapping, Texture};
    let Some(gpu) = gpu_or_skip("projected textures") else { return };
    let mut cuda = CudaDevice::on(gpu);
    let texture_from_world = glam::Affine3A::from_translation(Vec3::new(0.3, -0.2, 0.1));
    let (vs, vt) = (Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 1.5, 0.5));
    for mapping in [
        TexMapping::Planar { texture_from_world, vs, vt, ds: 0.25, dt: 0.0 },
        TexMapping::Spherical { texture_from_world },
        TexMapping::Cylindrical { texture_from_world },
    ] {
        let mut scene = cutout_scene(Screen::Strips, Vec3::new(0.0, 0.0, 3.0));
        for t in &mut scene.textures.textures {
            if let Texture::Checkerboard { mapping: m, .. } = t {
                *m = mapping;
            }
        }
        assert_renders_match(&mut cuda, &Arc::new(scene), &format!("{mapping:?}"));
    }
    // directionmix: the screen faces +z, the ground too; a tilted direction
    // gives both a share of each texture.
    let mut scene = cutout_scene(Screen::Strips, Vec3::new(0.0, 0.0, 3.0));
    let facing = scene.textures.add(Texture::Facing { direction: Vec3::new(0.6, 0.0, 0.8) });
    for t in &mut scene.textures.textures {
        if let Texture::Checkerboard { tex, .. } = t {
            *t = Texture::Mix { tex: *tex, amount: atoll_scene::TexInput::Texture(facing) };
        }
    }
    assert_renders_match(&mut cuda, &Arc::new(scene), "directionmix");
}

/// Every pixel filter places and weights the GPU's camera samples as the
/// CPU's: the cut-out scene under pbrt-v4's filters (Mitchell and Lanczos
/// with their negative weights).
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn pixel_filters_match_the_cpu_device() {
    use atoll_scene::texture_scenes::{cutout_scene, Screen};
    use atoll_scene::PixelFilter;
    let Some(gpu) = gpu_or_skip("pixel filters") else { return };
    let mut cuda = CudaDevice::on(gpu);
    let radius = glam::Vec2::new(2.0, 1.5);
    for filter in [
        PixelFilter::Box { radius: glam::Vec2::new(1.0, 0.75) },
        PixelFilter::PBRT_DEFAULT,
        PixelFilter::Mitchell { radius, b: 1.0 / 3.0, c: 1.0 / 3.0 },
        PixelFilter::LanczosSinc { radius, tau: 3.0 },
        PixelFilter::Triangle { radius },
    ] {
        let mut scene = cutout_scene(Screen::Strips, Vec3::new(0.0, 0.0, 3.0));
        scene.settings.film.filter = filter;
        assert_renders_match(&mut cuda, &Arc::new(scene), &format!("{filter:?}"));
    }
}

/// pbrt-v4's procedural textures give the GPU's hits the CPU's
/// coefficients: the cut-out scene's checkerboards become dots, 3D
/// checkerboards and bilinear blends, and mixes whose amount is each noise
/// texture of the hit point.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn procedural_textures_match_the_cpu_device() {
    use atoll_scene::texture_scenes::{cutout_scene, Screen};
    use atoll_scene::{Noise, TexInput, TexMapping, Texture};
    let Some(gpu) = gpu_or_skip("noise textures") else { return };
    let mut cuda = CudaDevice::on(gpu);
    let dots = |t: &Texture| match t {
        Texture::Checkerboard { tex, .. } => Some(Texture::Dots {
            mapping: TexMapping::Uv(atoll_scene::UvMapping { su: 6.0, sv: 6.0, du: 0.0, dv: 0.0 }),
            tex: *tex,
        }),
        _ => None,
    };
    let mut scene = cutout_scene(Screen::Strips, Vec3::new(0.0, 0.0, 3.0));
    for t in &mut scene.textures.textures {
        if let Some(d) = dots(t) {
            *t = d;
        }
    }
    assert_renders_match(&mut cuda, &Arc::new(scene), "dots");
    let texture_from_world = glam::Affine3A::from_scale(Vec3::splat(3.0));
    // 3D checkerboards and bilinear blends in place of the checkerboards.
    // The cells are shifted off the ground (z = 0) and the screen (z = 1):
    // a surface lying on a cell boundary takes either cell by rounding.
    let solid = texture_from_world * glam::Affine3A::from_translation(Vec3::new(0.0, 0.0, 0.15));
    let mut scene = cutout_scene(Screen::Strips, Vec3::new(0.0, 0.0, 3.0));
    for t in &mut scene.textures.textures {
        if let Texture::Checkerboard { tex, .. } = t {
            *t = Texture::SolidCheckerboard { texture_from_world: solid, tex: *tex };
        }
    }
    assert_renders_match(&mut cuda, &Arc::new(scene), "solid checkerboard");
    let mut scene = cutout_scene(Screen::Strips, Vec3::new(0.0, 0.0, 3.0));
    for t in &mut scene.textures.textures {
        if let Texture::Checkerboard { mapping, tex } = t {
            *t = Texture::Bilerp { mapping: *mapping, corners: [tex[0], tex[1], tex[1], tex[0]] };
        }
    }
    assert_renders_match(&mut cuda, &Arc::new(scene), "bilerp");
    for noise in [
        Noise::Fbm { octaves: 6, omega: 0.6 },
        Noise::Wrinkled { octaves: 8, omega: 0.5 },
        Noise::Windy,
        Noise::Marble { octaves: 8, omega: 0.5, scale: 2.0, variation: 0.4 },
    ] {
        let mut scene = cutout_scene(Screen::Strips, Vec3::new(0.0, 0.0, 3.0));
        let amount = scene.textures.add(Texture::Noise { noise, texture_from_world });
        for t in &mut scene.textures.textures {
            if let Texture::Checkerboard { tex, .. } = t {
                *t = Texture::Mix { tex: *tex, amount: TexInput::Texture(amount) };
            }
        }
        assert_renders_match(&mut cuda, &Arc::new(scene), &format!("{noise:?}"));
    }
}

/// Bump and normal maps bend the GPU's shading normals as the CPU's: a
/// plane bump-mapped by a ramp, normal-mapped, and the tilted plane both
/// stand for (`texture_scenes::bent_plane_scene`).
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn bump_and_normal_maps_match_the_cpu_device() {
    use atoll_scene::texture_scenes::{bent_plane_scene, Bend};
    let Some(gpu) = gpu_or_skip("bump and normal maps") else { return };
    let mut cuda = CudaDevice::on(gpu);
    for bend in [Bend::Tilted, Bend::Bump, Bend::NormalMap] {
        assert_renders_match(&mut cuda, &Arc::new(bent_plane_scene(bend)), &format!("{bend:?}"));
    }
}

/// Emission textures: light sampling and emitter hits on the GPU scale the
/// light exactly as on the CPU (checkerboard emission, seen directly and
/// lighting a floor).
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn emission_textures_match_the_cpu_device() {
    use atoll_scene::texture_scenes::textured_light_scene;
    use atoll_scene::{Rgb, TexInput, Texture, UvMapping};
    let Some(gpu) = gpu_or_skip("emission textures") else { return };
    let mut cuda = CudaDevice::on(gpu);
    let checker = Texture::Checkerboard {
        mapping: UvMapping { su: 4.0, sv: 4.0, du: 0.0, dv: 0.0 }.into(),
        tex: [TexInput::Value(Rgb::new(0.2, 0.5, 1.0)), TexInput::Value(Rgb::splat(2.0))],
    };
    for (eye, target) in
        [(Vec3::new(0.0, -3.0, 0.8), Vec3::ZERO), (Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 0.01, 2.0))]
    {
        let scene = Arc::new(textured_light_scene(Some(checker.clone()), eye, target));
        assert_renders_match(&mut cuda, &scene, &format!("from {eye}"));
    }
}
