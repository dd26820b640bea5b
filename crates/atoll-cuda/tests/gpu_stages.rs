//! GPU equality tests of the wavefront stages (`kernels/wavefront.cu`) and
//! of the device functions they are built from (`kernels/test_bsdf.cu`):
//! every output is compared with the Rust function it mirrors, record by
//! record and value by value.
//!
//! The kernels are compiled with `--fmad=false` here, so that the GPU
//! evaluates exactly the CPU's operations (only `sinf`/`cosf` may differ by
//! an ulp or two) and a random decision never flips on a rounding
//! difference; [`shade_with_production_options_mostly_agrees`] checks the
//! default options too, allowing a few flipped decisions.
//!
//! Ignored unless asked for (`--include-ignored`, as scripts/gpu-check
//! does); then, without a GPU (no driver, no NVRTC, no device) every test
//! skips, and `ATOLL_REQUIRE_GPU=1` turns a skip into a failure.

use std::sync::Arc;

use atoll_bvh::ScenePart;
use atoll_cuda::compile::{compile_with_cache, Output};
use atoll_cuda::gpu::{launch_1d, Gpu};
use atoll_cuda::layout::{GpuRecord, HitRef, HIT_NONE};
use atoll_cuda::params::{FrameParamsHost, SceneView};
use atoll_cuda::scene::{GpuScene, SceneTables};
use atoll_cuda::work::{WorkFifo, WorkStatus};
use atoll_render::lights::Emitter;
use atoll_render::material_coeffs::{bsdf_from_record, store_hair_offset, store_tangent, PackedMaterial};
use atoll_render::record::{flags, MaterialKind, NO_LIGHT};
use atoll_render::rng::{pcg_hash, SampleStream};
use atoll_render::sampling::sample_uniform_sphere;
use atoll_render::stages::{generate::camera_record, shade::shade};
use atoll_render::{CpuDevice, Device, FrameContext, Queue, RayRecord, RenderOptions};
use atoll_scene::camera::tile_order_pixel;
use atoll_scene::{
    AreaEmission, CoatedConductorParams, CoatedDiffuseParams, Coating, EnvLayout, EnvironmentImage,
    FieldSource, GridField, GridMedium, HairParams, HomogeneousMedium, Instance, IntegratorSettings, Light,
    Material, MeasuredBrdf, Medium, MediumInterface, Object, PrincipledParams, Rgb, Scene, TriangleMesh,
};
use bytemuck::Zeroable;
use cudarc::driver::{CudaModule, CudaSlice, PushKernelArg};
use cudarc::nvrtc::Ptx;
use glam::{Affine3A, Quat, UVec2, Vec2, Vec3};

const BLOCK: u32 = 128;

/// The GPU, or `None` (test skipped) when there is none.
fn gpu() -> Option<Arc<Gpu>> {
    let require = std::env::var("ATOLL_REQUIRE_GPU").is_ok_and(|v| v == "1");
    let skip = |why: String| {
        assert!(!require, "ATOLL_REQUIRE_GPU=1 but {why}");
        eprintln!("skipping GPU test: {why}");
        None
    };
    // cudarc panics without the libraries: check before any call into them.
    if !atoll_cuda::error::driver_present() {
        return skip("no CUDA driver library".into());
    }
    if !atoll_cuda::error::nvrtc_present() {
        return skip("no NVRTC library".into());
    }
    match Gpu::open(0) {
        Ok(gpu) => Some(gpu),
        Err(e) => skip(e.to_string()),
    }
}

/// Kernel file `file` compiled for this GPU, with `--fmad=false` unless
/// `production` (then exactly the options the device uses).
fn module(gpu: &Gpu, file: &str, production: bool) -> Arc<CudaModule> {
    module_with(gpu, file, production, &[])
}

/// [`module`] with extra NVRTC options (a specialisation's defines).
fn module_with(gpu: &Gpu, file: &str, production: bool, extra: &[&str]) -> Arc<CudaModule> {
    let mut options = gpu.compile_options().clone();
    options.extra.extend(extra.iter().map(|s| s.to_string()));
    if !production {
        options.extra.push("--fmad=false".into());
    }
    let compiled = compile_with_cache(file, &options, None).unwrap_or_else(|e| panic!("{e}"));
    let image = match options.output {
        Output::Cubin => Ptx::from_binary(compiled.image),
        Output::Ptx => Ptx::from_src(String::from_utf8(compiled.image).unwrap()),
    };
    gpu.ctx.load_module(image).unwrap()
}

fn upload<T: cudarc::driver::DeviceRepr + Copy>(gpu: &Gpu, data: &[T]) -> CudaSlice<T> {
    gpu.stream.clone_htod(data).unwrap()
}

fn download<T: cudarc::driver::DeviceRepr + Copy>(gpu: &Gpu, data: &CudaSlice<T>) -> Vec<T> {
    gpu.stream.clone_dtoh(data).unwrap()
}

fn records_of(v: Vec<GpuRecord>) -> Vec<RayRecord> {
    v.into_iter().map(|r| r.0).collect()
}

fn gpu_records(v: &[RayRecord]) -> Vec<GpuRecord> {
    v.iter().map(|&r| GpuRecord(r)).collect()
}

/// Equal within the float tolerance of these tests (1e-4 relative, 1e-6
/// absolute for values near 0); infinities and NaNs must match exactly.
fn close(a: f32, b: f32) -> bool {
    a == b || (a.is_nan() && b.is_nan()) || (a - b).abs() <= 1e-4 * a.abs().max(b.abs()) + 1e-6
}

fn close_all(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| close(*x, *y))
}

/// f16 fields: one f16 rounding step apart at most (computed fields such as
/// the hit normals round two nearly equal f32s).
fn close_f16(a: &[half::f16], b: &[half::f16]) -> bool {
    a.iter().zip(b).all(|(x, y)| {
        let (x, y) = (x.to_f32(), y.to_f32());
        x == y || (x - y).abs() <= 1e-3 * x.abs().max(y.abs()) + 1e-4
    })
}

/// `Err` naming the first field of `gpu` that differs from `cpu`.
fn compare_records(cpu: &RayRecord, gpu: &RayRecord) -> Result<(), String> {
    let mut bad = Vec::new();
    let mut f = |name: &str, ok: bool| {
        if !ok {
            bad.push(name.to_string());
        }
    };
    f("origin", close_all(&cpu.origin, &gpu.origin));
    f("t_max", close(cpu.t_max, gpu.t_max));
    f("direction", close_all(&cpu.direction, &gpu.direction));
    f("pixel", cpu.pixel == gpu.pixel);
    f("throughput", close_all(&cpu.throughput, &gpu.throughput));
    f("sample", cpu.sample == gpu.sample);
    f("bsdf_pdf", close(cpu.bsdf_pdf, gpu.bsdf_pdf));
    f("depth", cpu.depth == gpu.depth);
    f("flags", cpu.flags == gpu.flags);
    f("light", cpu.light == gpu.light);
    f("instance", cpu.instance == gpu.instance);
    f("eta_scale", cpu.eta_scale == gpu.eta_scale);
    if cpu.flags & flags::SHADOW != 0 {
        f("optical depth", close_all(&cpu.position, &gpu.position));
    }
    // The hit half is defined only for hits (record.rs).
    if cpu.flags & flags::HIT != 0 {
        f("position", close_all(&cpu.position, &gpu.position));
        f("emission_scale", cpu.emission_scale == gpu.emission_scale);
        f("position_error", (cpu.position_error as i32 - gpu.position_error as i32).abs() <= 1);
        f("geometric_normal", close_f16(&cpu.geometric_normal, &gpu.geometric_normal));
        f("material", cpu.material == gpu.material);
        f("shading_normal", close_f16(&cpu.shading_normal, &gpu.shading_normal));
        f("coeffs", cpu.coeffs == gpu.coeffs);
    }
    if bad.is_empty() {
        Ok(())
    } else {
        Err(format!("fields {bad:?} differ:\n  cpu {cpu:?}\n  gpu {gpu:?}"))
    }
}

/// Deterministic numbers in [0, 1) for the synthetic inputs.
fn rnd(i: u32, k: u32) -> f32 {
    SampleStream::new(0x5eed, i, 0).get(k)
}

fn unit(i: u32, k: u32) -> Vec3 {
    sample_uniform_sphere(Vec2::new(rnd(i, k), rnd(i, k + 1)))
}

/// An environment image with a bright patch on a graded background, rotated.
fn environment_light(layout: EnvLayout) -> Light {
    let (w, h) = if layout == EnvLayout::LatLong { (16u32, 8u32) } else { (12, 12) };
    let pixels = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if (2..5).contains(&x) && (2..4).contains(&y) {
                Rgb::new(20.0, 15.0, 10.0)
            } else {
                Rgb::new(0.1 + 0.02 * x as f32, 0.2, 0.1 + 0.03 * y as f32)
            }
        })
        .collect();
    Light::Environment {
        image: Arc::new(EnvironmentImage::new(w, h, pixels, layout)),
        scale: Rgb::new(1.0, 0.8, 1.2),
        light_to_world: glam::Mat3::from_rotation_x(0.3) * glam::Mat3::from_rotation_z(0.2),
        portal: None,
    }
}

/// The Cornell box with every kind of light and a small image.
fn test_frame(integrator: IntegratorSettings, lens: bool) -> (Scene, FrameContext) {
    let mut scene = atoll_scene::cornell::builtin_cornell_box();
    scene
        .lights
        .push(Light::Point { position: Vec3::new(0.2, 1.5, 0.1), intensity: Rgb::new(1.0, 2.0, 0.5) });
    scene.lights.push(Light::Distant { direction: Vec3::new(0.3, -1.0, 0.2), radiance: Rgb::splat(0.7) });
    scene.lights.push(Light::Infinite { radiance: Rgb::new(0.1, 0.2, 0.3), portal: None });
    scene.lights.push(Light::spot(Vec3::new(0.0, 1.9, 0.0), -Vec3::Y, Rgb::splat(2.0), 35.0, 10.0));
    scene.lights.push(environment_light(EnvLayout::EqualArea));
    // Portals in the box's open front (facing out, -z): a constant sky and
    // an image seen only through them.
    let window = |x0: f32, x1: f32| {
        let corners = [
            Vec3::new(x0, 0.2, -1.0),
            Vec3::new(x0, 1.6, -1.0),
            Vec3::new(x1, 1.6, -1.0),
            Vec3::new(x1, 0.2, -1.0),
        ];
        Some(atoll_scene::Portal::new(corners).unwrap())
    };
    scene.lights.push(Light::Infinite { radiance: Rgb::new(0.3, 0.2, 0.1), portal: window(0.5, -0.5) });
    let Light::Environment { image, scale, light_to_world, .. } = environment_light(EnvLayout::LatLong)
    else {
        unreachable!()
    };
    scene.lights.push(Light::Environment { image, scale, light_to_world, portal: window(0.9, 0.1) });
    if lens {
        scene.settings.camera.lens_radius = 0.05;
        scene.settings.camera.focal_distance = 3.5;
    }
    let mut options = RenderOptions::from_scene(&scene);
    options.resolution = UVec2::new(64, 48);
    options.integrator = integrator;
    options.seed = 11;
    let frame = FrameContext::new(&scene, options);
    (scene, frame)
}

/// Every material the record can carry, pass-through included.
fn test_materials() -> Vec<PackedMaterial> {
    [
        Material::Diffuse { reflectance: Rgb::new(0.7, 0.5, 0.3) },
        Material::Conductor {
            eta: Rgb::new(0.2, 0.9, 1.1),
            k: Rgb::new(3.9, 2.4, 2.1),
            alpha_x: 0.0,
            alpha_y: 0.0,
        },
        Material::Conductor {
            eta: Rgb::new(0.2, 0.9, 1.1),
            k: Rgb::new(3.9, 2.4, 2.1),
            alpha_x: 0.3,
            alpha_y: 0.08,
        },
        Material::Dielectric { eta: 1.5, alpha_x: 0.0, alpha_y: 0.0 },
        Material::Dielectric { eta: 1.5, alpha_x: 0.3, alpha_y: 0.2 },
        Material::Dielectric { eta: 1.33, alpha_x: 0.1, alpha_y: 0.1 },
        Material::Dielectric { eta: 1.0, alpha_x: 0.3, alpha_y: 0.3 },
        Material::DiffuseTransmission {
            reflectance: Rgb::new(0.3, 0.5, 0.1),
            transmittance: Rgb::new(0.6, 0.2, 0.4),
        },
        Material::DiffuseTransmission { reflectance: Rgb::ZERO, transmittance: Rgb::splat(0.5) },
        Material::ThinDielectric { eta: 1.5 },
        Material::ThinDielectric { eta: 1.0 },
        Material::Interface,
    ]
    .iter()
    .map(PackedMaterial::pack)
    .collect()
}

/// `n` path records with hand-filled hits (one per pixel): misses, every
/// material kind, emissive hits, depths around the maximum, both flag states.
fn synthetic_paths(frame: &FrameContext, n: u32) -> Vec<RayRecord> {
    let materials = test_materials();
    let triangle_lights: Vec<u32> = (0..frame.lights.emitters.len() as u32)
        .filter(|&i| matches!(frame.lights.emitters[i as usize], Emitter::Triangle { .. }))
        .collect();
    assert!(!triangle_lights.is_empty());
    (0..n)
        .map(|i| {
            let mut r = camera_record(frame, i, i % 3);
            r.direction = unit(i, 0).to_array();
            r.throughput = [0.2 + rnd(i, 2), 0.3 + rnd(i, 3), 0.1 + rnd(i, 4)];
            r.bsdf_pdf = 0.1 + 4.0 * rnd(i, 5);
            r.depth = (i / 7 % 7) as u16;
            r.flags = if rnd(i, 6) < 0.3 { flags::SPECULAR } else { 0 };
            r.t_max = 0.3 + 3.0 * rnd(i, 7);
            if i % 9 == 0 {
                r.t_max = f32::INFINITY;
                return r; // a miss
            }
            r.flags |= flags::HIT;
            r.position = [2.0 * rnd(i, 8) - 1.0, 2.0 * rnd(i, 9), 2.0 * rnd(i, 10) - 1.0];
            let ng = unit(i, 11);
            // Shading normals near the geometric one, sometimes on the other side.
            let mut ns = (ng + 0.3 * unit(i, 13)).normalize();
            if i % 11 == 0 {
                ns = -ns;
            }
            r.geometric_normal = ng.to_array().map(half::f16::from_f32);
            r.shading_normal = ns.to_array().map(half::f16::from_f32);
            r.instance = i % 5;
            materials[(i as usize / 2) % materials.len()].store(&mut r);
            r.light = if i % 4 == 1 { triangle_lights[i as usize % triangle_lights.len()] } else { NO_LIGHT };
            r
        })
        .collect()
}

/// Outputs of one `shade` launch (or its CPU reference).
struct Shaded {
    next: Vec<RayRecord>,
    shadows: Vec<RayRecord>,
    film: Vec<f32>,
}

fn shade_on_cpu(frame: &FrameContext, paths: &[RayRecord]) -> Shaded {
    let pixels = frame.options.pixel_count() as usize;
    let mut out = Shaded { next: Vec::new(), shadows: Vec::new(), film: vec![0.0; 3 * pixels] };
    for r in paths {
        let o = shade(frame, r);
        if o.emitted != Vec3::ZERO {
            for c in 0..3 {
                out.film[3 * r.pixel as usize + c] += o.emitted[c];
            }
        }
        out.shadows.extend(o.shadow);
        out.next.extend(o.next);
    }
    out
}

fn shade_on_gpu(
    gpu: &Gpu,
    m: &Arc<CudaModule>,
    params: &FrameParamsHost,
    frame: &FrameContext,
    paths: &[RayRecord],
) -> Shaded {
    let n = paths.len() as u32;
    let pixels = frame.options.pixel_count() as usize;
    let input = upload(gpu, &gpu_records(paths));
    let path_count = upload(gpu, &[n]);
    let mut next = gpu.stream.alloc_zeros::<GpuRecord>(paths.len()).unwrap();
    let mut shadows = gpu.stream.alloc_zeros::<GpuRecord>(paths.len()).unwrap();
    let mut next_count = gpu.stream.alloc_zeros::<u32>(1).unwrap();
    let mut shadow_count = gpu.stream.alloc_zeros::<u32>(1).unwrap();
    let mut film = gpu.stream.alloc_zeros::<f32>(3 * pixels).unwrap();
    let f = m.load_function("shade").unwrap();
    let mut b = gpu.stream.launch_builder(&f);
    b.arg(&params.device).arg(&input).arg(&path_count).arg(&mut next).arg(&mut next_count);
    b.arg(&mut shadows).arg(&mut shadow_count).arg(&mut film);
    // SAFETY: the arguments match `shade` in wavefront.cu; next and shadows
    // hold `n` records each (at most one of each per input record).
    unsafe { b.launch(launch_1d(n, BLOCK)) }.unwrap();
    let next_n = download(gpu, &next_count)[0] as usize;
    let shadow_n = download(gpu, &shadow_count)[0] as usize;
    let mut next = records_of(download(gpu, &next));
    let mut shadows = records_of(download(gpu, &shadows));
    next.truncate(next_n);
    shadows.truncate(shadow_n);
    // Appended in any order; every pixel appears once.
    next.sort_by_key(|r| r.pixel);
    shadows.sort_by_key(|r| r.pixel);
    Shaded { next, shadows, film: download(gpu, &film) }
}

/// Mismatches between two shade results (records matched by pixel).
fn shade_mismatches(cpu: &Shaded, gpu: &Shaded) -> Vec<String> {
    let mut bad = Vec::new();
    for (what, c, g) in [("next", &cpu.next, &gpu.next), ("shadow", &cpu.shadows, &gpu.shadows)] {
        let mut gi = g.iter().peekable();
        for r in c.iter() {
            while gi.peek().is_some_and(|x| x.pixel < r.pixel) {
                bad.push(format!("{what}: pixel {} only on the GPU", gi.next().unwrap().pixel));
            }
            match gi.peek() {
                Some(x) if x.pixel == r.pixel => {
                    if let Err(e) = compare_records(r, gi.next().unwrap()) {
                        bad.push(format!("{what} of pixel {}: {e}", r.pixel));
                    }
                }
                _ => bad.push(format!("{what}: pixel {} only on the CPU", r.pixel)),
            }
        }
        bad.extend(gi.map(|x| format!("{what}: pixel {} only on the GPU", x.pixel)));
    }
    for (i, (a, b)) in cpu.film.iter().zip(&gpu.film).enumerate() {
        if !close(*a, *b) {
            bad.push(format!("film[{}] channel {}: cpu {a} gpu {b}", i / 3, i % 3));
        }
    }
    bad
}

fn assert_no_mismatches(what: &str, bad: &[String]) {
    assert!(
        bad.is_empty(),
        "{what}: {} mismatches, first ones:\n{}",
        bad.len(),
        bad[..bad.len().min(8)].join("\n")
    );
}

/// The work FIFO's refill appends camera records after the paths already
/// queued, across wave boundaries, exactly as `CpuDevice::refill` does.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn refill_matches_camera_record() {
    let Some(gpu) = gpu() else { return };
    let m = module(&gpu, "wavefront.cu", false);
    for lens in [false, true] {
        let (_, frame) = test_frame(IntegratorSettings::Path { max_depth: 5 }, lens);
        let params = FrameParamsHost::new(&gpu, &frame).unwrap();
        let (capacity, queued) = (2048u32, 48u32);
        // (sample, first pixel, count): the first fits, the second only in part.
        let waves = [(5u32, 37u32, 1500u32), (6, 0, 1000)];
        let mut paths = gpu.stream.alloc_zeros::<GpuRecord>(capacity as usize).unwrap();
        let mut path_count = upload(&gpu, &[queued]);
        let mut fifo = gpu.stream.alloc_zeros::<WorkFifo>(1).unwrap();
        let mut status = gpu.stream.alloc_zeros::<WorkStatus>(1).unwrap();
        let push = m.load_function("push_work").unwrap();
        for (sample, first, count) in waves {
            let mut b = gpu.stream.launch_builder(&push);
            b.arg(&mut fifo).arg(&sample).arg(&first).arg(&count);
            // SAFETY: matches `push_work(WorkFifo*, unsigned, unsigned, unsigned)`.
            unsafe { b.launch(launch_1d(1, 1)) }.unwrap();
        }
        let claim = m.load_function("refill_claim").unwrap();
        let mut b = gpu.stream.launch_builder(&claim);
        b.arg(&mut fifo).arg(&mut status).arg(&mut path_count).arg(&capacity);
        // SAFETY: matches `refill_claim(WorkFifo*, WorkStatus*, unsigned*, unsigned)`.
        unsafe { b.launch(launch_1d(1, 1)) }.unwrap();
        let generate = m.load_function("refill_generate").unwrap();
        let mut b = gpu.stream.launch_builder(&generate);
        b.arg(&params.device).arg(&fifo).arg(&mut paths);
        // SAFETY: matches `refill_generate(const FrameParams*, const WorkFifo*, RayRecord*)`;
        // claims end at `capacity`, the length of `paths`.
        unsafe { b.launch(launch_1d(capacity, BLOCK)) }.unwrap();
        assert_eq!(download(&gpu, &path_count), [capacity]);
        let s = download(&gpu, &status)[0];
        let started = capacity - queued;
        assert_eq!((s.paths_started, s.queue_len, s.waves_started), (started as u64, capacity, 1));
        assert_eq!(download(&gpu, &fifo)[0].taken, started - waves[0].2);
        let got = records_of(download(&gpu, &paths));
        let mut bad = Vec::new();
        // Waves count places in tile order.
        let pixel = |ordinal| tile_order_pixel(ordinal, frame.options.resolution);
        for (i, g) in got.iter().enumerate() {
            let i = i as u32;
            let expected = if i < queued {
                RayRecord::zeroed()
            } else if i < queued + waves[0].2 {
                camera_record(&frame, pixel(waves[0].1 + i - queued), waves[0].0)
            } else {
                camera_record(&frame, pixel(waves[1].1 + i - queued - waves[0].2), waves[1].0)
            };
            if let Err(e) = compare_records(&expected, g) {
                bad.push(format!("record {i}: {e}"));
            }
        }
        assert_no_mismatches(&format!("refill (lens {lens})"), &bad);
    }
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn shade_matches_the_cpu_stage() {
    let Some(gpu) = gpu() else { return };
    let m = module(&gpu, "wavefront.cu", false);
    let integrators = [
        IntegratorSettings::Path { max_depth: 5 },
        IntegratorSettings::AmbientOcclusion { max_distance: 0.5 },
        IntegratorSettings::AmbientOcclusion { max_distance: f32::INFINITY },
    ];
    for integrator in integrators {
        for russian_roulette in [true, false] {
            let (_, mut frame) = test_frame(integrator.clone(), false);
            frame.options.russian_roulette = russian_roulette;
            let params = FrameParamsHost::new(&gpu, &frame).unwrap();
            let paths = synthetic_paths(&frame, 3000);
            let cpu = shade_on_cpu(&frame, &paths);
            let got = shade_on_gpu(&gpu, &m, &params, &frame, &paths);
            // The synthetic batch must exercise every output.
            assert!(!cpu.shadows.is_empty() && !cpu.next.is_empty(), "{integrator:?}");
            if matches!(integrator, IntegratorSettings::Path { .. }) {
                assert!(cpu.film.iter().any(|&v| v > 0.0), "no emission in the batch");
            }
            assert_no_mismatches(
                &format!("shade {integrator:?} rr {russian_roulette}"),
                &shade_mismatches(&cpu, &got),
            );
        }
    }
}

/// The test frame with four media (a coloured, scattering, glowing one,
/// an absorbing one, a density grid, and a glowing RGB grid or, without
/// `rgb`, a density grid glowing by an `Lescale` grid) and the camera in
/// the first.
fn media_frame(rgb: bool) -> FrameContext {
    let (mut scene, frame) = test_frame(IntegratorSettings::Path { max_depth: 5 }, false);
    scene.media.push(Medium::Homogeneous(HomogeneousMedium {
        sigma_a: Rgb::new(0.3, 0.8, 1.5),
        sigma_s: Rgb::new(1.2, 0.7, 0.2),
        g: 0.6,
        le: Rgb::new(0.5, 0.2, 0.1),
    }));
    scene.media.push(Medium::Homogeneous(HomogeneousMedium {
        sigma_a: Rgb::new(2.0, 0.5, 0.0),
        sigma_s: Rgb::ZERO,
        g: 0.0,
        le: Rgb::ZERO,
    }));
    // A grid of smoke about the box's middle, turned and shifted.
    let place = Affine3A::from_rotation_translation(Quat::from_rotation_y(0.4), Vec3::new(0.1, 0.2, 0.0));
    let density_field = |scale| GridField { scale, source: FieldSource::Scalar(0) };
    scene.media.push(Medium::Grid(GridMedium {
        resolution: [4, 3, 5],
        channels: 1,
        values: (0..60).map(|i| (i * 13 % 7) as f32 * 0.4).collect(),
        sigma_a: density_field(Rgb::new(0.2, 0.1, 0.3)),
        sigma_s: density_field(Rgb::new(2.0, 3.0, 1.0)),
        le: GridField::constant(Rgb::ZERO),
        g: -0.3,
        lo: Vec3::new(-0.8, 0.0, -0.6),
        hi: Vec3::new(0.7, 1.5, 0.9),
        world_to_medium: place,
    }));
    // A glowing RGB grid over the same box: σa and Le per colour, σs 1.
    let glowing = if rgb {
        GridMedium {
            resolution: [3, 4, 2],
            channels: 6,
            values: (0..24 * 6).map(|i| (i * 5 % 9) as f32 * 0.3).collect(),
            sigma_a: GridField { scale: Rgb::splat(1.5), source: FieldSource::Rgb(0) },
            sigma_s: GridField::constant(Rgb::splat(1.5)),
            le: GridField { scale: Rgb::splat(2.0), source: FieldSource::Rgb(3) },
            g: 0.2,
            lo: Vec3::new(-0.8, 0.0, -0.6),
            hi: Vec3::new(0.7, 1.5, 0.9),
            world_to_medium: place,
        }
    } else {
        GridMedium {
            resolution: [3, 4, 2],
            channels: 2,
            values: (0..24 * 2).map(|i| (i * 5 % 9) as f32 * 0.3).collect(),
            sigma_a: density_field(Rgb::new(1.0, 0.5, 0.2)),
            sigma_s: density_field(Rgb::new(0.5, 1.0, 2.0)),
            le: GridField { scale: Rgb::new(2.0, 1.0, 0.5), source: FieldSource::Scalar(1) },
            g: 0.2,
            lo: Vec3::new(-0.8, 0.0, -0.6),
            hi: Vec3::new(0.7, 1.5, 0.9),
            world_to_medium: place,
        }
    };
    scene.media.push(Medium::Grid(glowing));
    scene.settings.camera_medium = 1;
    FrameContext::new(&scene, frame.options.clone())
}

/// Paths travelling through media (or none), hitting surfaces that bound
/// media (or none): segments scatter, pass, glow; media change across
/// surfaces; shadow rays start with their medium's optical depth.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn shade_in_media_matches_the_cpu_stage() {
    let Some(gpu) = gpu() else { return };
    // RGB grids, then grey ones only in their own specialisation.
    for (rgb, defines) in [(true, &[][..]), (false, &["-DATOLL_WITH_RGB_MEDIA=0"][..])] {
        let m = module_with(&gpu, "wavefront.cu", false, defines);
        let frame = media_frame(rgb);
        let params = FrameParamsHost::new(&gpu, &frame).unwrap();
        let mut paths = synthetic_paths(&frame, 3000);
        for (i, r) in paths.iter_mut().enumerate() {
            let i = i as u32;
            r.set_medium((i % 5) as u8);
            if r.has(flags::HIT) {
                let boundaries = [
                    None,
                    MediumInterface::transition(1, 0),
                    MediumInterface::transition(2, 1),
                    MediumInterface::transition(3, 1),
                    MediumInterface::transition(4, 0),
                ];
                r.set_hit_media(boundaries[(i / 5 % 5) as usize]);
            }
        }
        let cpu = shade_on_cpu(&frame, &paths);
        let got = shade_on_gpu(&gpu, &m, &params, &frame, &paths);
        // Media scatter some segments, and shadow rays start inside them.
        let scattered = cpu.next.iter().filter(|r| !r.has(flags::HIT) && r.medium() != 0).count();
        assert!(scattered > 100, "{scattered} paths in media");
        for grid in [3, 4] {
            let in_grid = cpu.next.iter().filter(|r| !r.has(flags::HIT) && r.medium() == grid).count();
            assert!(in_grid > 10, "{in_grid} paths going on in grid {grid}");
        }
        assert!(
            cpu.shadows.iter().any(|s| s.optical_depth() != Vec3::ZERO),
            "no shadow ray starts in a medium"
        );
        assert_no_mismatches(&format!("shade in media (rgb {rgb})"), &shade_mismatches(&cpu, &got));
    }
}

/// Paths in and out of subsurface interiors: entering through the rough or
/// smooth boundary, walking (no light sampling, the depth kept), and
/// leaving by the exit lobe into the vacuum or a fog, with coloured
/// interiors whose channels are picked by the throughput.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn shade_in_subsurface_interiors_matches_the_cpu_stage() {
    let Some(gpu) = gpu() else { return };
    let m = module(&gpu, "wavefront.cu", false);
    let (mut scene, frame) = test_frame(IntegratorSettings::Path { max_depth: 5 }, false);
    let interior = |sigma_a, sigma_s, g| HomogeneousMedium { sigma_a, sigma_s, g, le: Rgb::ZERO };
    scene.media.push(Medium::Homogeneous(interior(Rgb::splat(0.1), Rgb::new(0.5, 0.3, 0.2), 0.0)));
    scene.media.push(Medium::Subsurface(interior(Rgb::new(0.1, 0.4, 1.2), Rgb::new(6.0, 4.0, 2.0), 0.3)));
    scene.media.push(Medium::Subsurface(interior(Rgb::ZERO, Rgb::splat(3.0), 0.0)));
    let frame = FrameContext::new(&scene, frame.options.clone());
    let params = FrameParamsHost::new(&gpu, &frame).unwrap();
    let boundaries = [
        Material::Subsurface(atoll_scene::SubsurfaceParams {
            eta: 1.4,
            alpha_x: 0.0,
            alpha_y: 0.0,
            interior: interior(Rgb::ZERO, Rgb::ONE, 0.0),
        }),
        Material::Subsurface(atoll_scene::SubsurfaceParams {
            eta: 1.33,
            alpha_x: 0.2,
            alpha_y: 0.3,
            interior: interior(Rgb::ZERO, Rgb::ONE, 0.0),
        }),
    ]
    .map(|m| PackedMaterial::pack(&m));
    let mut paths = synthetic_paths(&frame, 3000);
    for (i, r) in paths.iter_mut().enumerate() {
        let i = i as u32;
        // Half the paths walk an interior, the others arrive from outside.
        let inside = [2u8, 3][(i % 2) as usize];
        r.set_medium(if i % 4 < 2 { inside } else { i.is_multiple_of(3) as u8 });
        if r.has(flags::HIT) && i % 3 != 2 {
            boundaries[(i / 3 % 2) as usize].store(r);
            let outside = (i / 5 % 2) as u8;
            r.set_hit_media(MediumInterface::transition(inside, outside));
        }
    }
    let cpu = shade_on_cpu(&frame, &paths);
    let got = shade_on_gpu(&gpu, &m, &params, &frame, &paths);
    let walking = cpu.next.iter().filter(|r| !r.has(flags::HIT) && r.medium() >= 2).count();
    assert!(walking > 100, "{walking} paths walking interiors");
    assert_no_mismatches("shade in subsurface interiors", &shade_mismatches(&cpu, &got));
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn shade_with_production_options_mostly_agrees() {
    let Some(gpu) = gpu() else { return };
    let m = module(&gpu, "wavefront.cu", true);
    let (_, frame) = test_frame(IntegratorSettings::Path { max_depth: 5 }, false);
    let params = FrameParamsHost::new(&gpu, &frame).unwrap();
    let paths = synthetic_paths(&frame, 3000);
    let cpu = shade_on_cpu(&frame, &paths);
    let got = shade_on_gpu(&gpu, &m, &params, &frame, &paths);
    let bad = shade_mismatches(&cpu, &got);
    // FMA contraction may flip a decision that sits on a rounding boundary.
    assert!(bad.len() <= 30, "{} mismatches, first ones:\n{}", bad.len(), bad[..bad.len().min(8)].join("\n"));
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn resolve_shadows_adds_unoccluded_rays() {
    let Some(gpu) = gpu() else { return };
    let m = module(&gpu, "wavefront.cu", false);
    let (_, frame) = test_frame(IntegratorSettings::Path { max_depth: 5 }, false);
    let mut shadows = shade_on_cpu(&frame, &synthetic_paths(&frame, 3000)).shadows;
    for (i, s) in shadows.iter_mut().enumerate() {
        if i % 3 == 0 {
            s.flags |= flags::OCCLUDED;
        }
    }
    let pixels = frame.options.pixel_count() as usize;
    let mut expected = vec![0.0f32; 3 * pixels];
    for s in shadows.iter().filter(|s| !s.has(flags::OCCLUDED)) {
        for c in 0..3 {
            expected[3 * s.pixel as usize + c] += s.throughput[c];
        }
    }
    let capacity = shadows.len() as u32 + 100;
    let count = upload(&gpu, &[shadows.len() as u32]);
    let f = m.load_function("resolve_shadows").unwrap();
    let resolve = |shadows: &[RayRecord], media: u32| {
        let mut padded = shadows.to_vec();
        padded.resize(capacity as usize, RayRecord::zeroed());
        let input = upload(&gpu, &gpu_records(&padded));
        let mut film = gpu.stream.alloc_zeros::<f32>(3 * pixels).unwrap();
        let mut b = gpu.stream.launch_builder(&f);
        b.arg(&input).arg(&count).arg(&mut film).arg(&media);
        // SAFETY: the arguments match `resolve_shadows`; records past the count are never read.
        unsafe { b.launch(launch_1d(capacity, BLOCK)) }.unwrap();
        download(&gpu, &film)
    };
    let compare = |what: &str, film: &[f32], expected: &[f32]| {
        let bad: Vec<String> = (0..film.len())
            .filter(|&i| !close(film[i], expected[i]))
            .map(|i| format!("film[{i}]: cpu {} gpu {}", expected[i], film[i]))
            .collect();
        assert_no_mismatches(what, &bad);
    };
    compare("resolve_shadows", &resolve(&shadows, 0), &expected);
    // Through media: each ray's optical depth (in its position) attenuates it.
    for (i, s) in shadows.iter_mut().enumerate() {
        s.position = [rnd(i as u32, 20), 2.0 * rnd(i as u32, 21), 0.5 * rnd(i as u32, 22)];
    }
    let mut expected = vec![0.0f32; 3 * pixels];
    for s in shadows.iter().filter(|s| !s.has(flags::OCCLUDED)) {
        let attenuated = s.throughput() * (-s.optical_depth()).exp();
        for c in 0..3 {
            expected[3 * s.pixel as usize + c] += attenuated[c];
        }
    }
    compare("resolve_shadows through media", &resolve(&shadows, 1), &expected);
}

/// A scene for `surface`: the Cornell box plus an object with per-vertex
/// normals (one of them against its face), a flipped mesh and an emissive
/// mesh, instanced twice under rotations and non-uniform scales.
fn surface_scene() -> Scene {
    let mut scene = atoll_scene::cornell::builtin_cornell_box();
    let metal = scene.add_material(Material::Conductor {
        eta: Rgb::splat(0.2),
        k: Rgb::splat(3.0),
        alpha_x: 0.2,
        alpha_y: 0.2,
    });
    let glass = scene.add_material(Material::Dielectric { eta: 1.5, alpha_x: 0.0, alpha_y: 0.0 });
    // Its hits carry the surface's dpdu as the fibre's axis.
    let hair = scene.add_material(Material::Hair(HairParams::pbrt_default()));
    let tent = TriangleMesh {
        name: "tent".into(),
        positions: vec![
            Vec3::new(-0.3, 0.0, -0.3),
            Vec3::new(0.3, 0.0, -0.3),
            Vec3::new(0.0, 0.4, 0.0),
            Vec3::new(0.0, 0.0, 0.3),
        ],
        normals: vec![
            Vec3::new(-0.5, 0.5, -0.5),
            Vec3::new(0.5, 0.5, -0.5),
            Vec3::Y,
            Vec3::new(0.0, -0.2, -1.0),
        ],
        indices: vec![[0, 1, 2], [1, 3, 2], [3, 0, 2]],
        // A mix of a mix: each hit resolves to metal, glass or metal again.
        material: {
            let inner = scene.add_material(Material::Mix { materials: [metal, glass], amount: 0.4 });
            scene.add_material(Material::Mix { materials: [inner, metal], amount: 0.3 })
        },
        ..Default::default()
    };
    let tent = scene.add_mesh(tent);
    let flipped = scene.add_mesh(TriangleMesh {
        name: "flipped".into(),
        positions: vec![Vec3::new(-0.2, 0.5, -0.2), Vec3::new(0.2, 0.5, -0.2), Vec3::new(0.0, 0.5, 0.2)],
        indices: vec![[0, 1, 2]],
        material: hair,
        flip_normals: true,
        ..Default::default()
    });
    let lamp = scene.add_mesh(TriangleMesh {
        name: "lamp".into(),
        positions: vec![
            Vec3::new(-0.1, 0.6, -0.1),
            Vec3::new(0.1, 0.6, -0.1),
            Vec3::new(0.1, 0.6, 0.1),
            Vec3::new(-0.1, 0.6, 0.1),
        ],
        indices: vec![[0, 1, 2], [0, 2, 3]],
        material: metal,
        emission: Some(AreaEmission { radiance: Rgb::splat(2.0), two_sided: true }),
        ..Default::default()
    });
    let object = scene.add_object(Object { name: "props".into(), meshes: vec![tent, flipped, lamp] });
    for (k, (axis, angle, scale, at)) in [
        (Vec3::Y, 0.7f32, Vec3::new(1.0, 1.5, 0.8), Vec3::new(-0.4, 0.0, 0.2)),
        (Vec3::new(1.0, 0.3, 0.2).normalize(), -0.4, Vec3::new(0.7, 0.9, 1.3), Vec3::new(0.45, 0.3, -0.3)),
    ]
    .into_iter()
    .enumerate()
    {
        let to_world = Affine3A::from_scale_rotation_translation(
            scale,
            Quat::from_axis_angle(axis, angle + k as f32),
            at,
        );
        scene.instances.push(Instance::new(object, to_world));
    }
    scene
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn surface_matches_write_hit() {
    let Some(gpu) = gpu() else { return };
    let m = module(&gpu, "wavefront.cu", false);
    let scene = Arc::new(surface_scene());
    let mut options = RenderOptions::from_scene(&scene);
    options.resolution = UVec2::new(48, 32);
    let frame = Arc::new(FrameContext::new(&scene, options));
    // Camera rays and rays from inside the box in every direction.
    let mut rays: Vec<RayRecord> =
        (0..frame.options.pixel_count()).map(|p| camera_record(&frame, p, 0)).collect();
    for i in 0..4000u32 {
        let mut r = camera_record(&frame, i % frame.options.pixel_count(), 1);
        r.origin = [1.6 * rnd(i, 20) - 0.8, 0.1 + 1.6 * rnd(i, 21), 1.6 * rnd(i, 22) - 0.8];
        r.direction = unit(i, 23).to_array();
        rays.push(r);
    }
    // The CPU device's hits (write_hit) ...
    let mut cpu = CpuDevice::new();
    cpu.prepare(&scene, &ScenePart::whole(&scene), &frame).unwrap();
    cpu.write_queue(Queue::Paths, &rays).unwrap();
    cpu.trace_paths().unwrap();
    let cpu_hits = cpu.read_queue(Queue::Paths).unwrap();
    // ... and the same BVH's raw hits as GPU traversal would report them.
    let bvh = atoll_bvh::SceneBvh::build(&scene);
    let tables = SceneTables::build(&scene);
    let mut hits = Vec::with_capacity(rays.len());
    let mut gpu_input = rays.clone();
    for (r, input) in rays.iter().zip(gpu_input.iter_mut()) {
        let ray = atoll_bvh::Ray { origin: r.origin(), direction: r.direction(), t_max: r.t_max, time: 0.0 };
        hits.push(match bvh.intersect(&ray) {
            Some(h) => {
                let object = tables.objects[scene.instances[h.instance as usize].object as usize];
                let meshes = &tables.meshes
                    [object.first_mesh as usize..(object.first_mesh + object.mesh_count) as usize];
                let mesh =
                    meshes.iter().find(|gm| gm.scene_mesh == h.mesh).expect("hit mesh is in its object");
                input.t_max = h.t; // traversal shrinks t_max
                HitRef { u: h.u, v: h.v, instance: h.instance, triangle: mesh.first_triangle + h.triangle }
            }
            None => HitRef { u: 0.0, v: 0.0, instance: HIT_NONE, triangle: 0 },
        });
    }
    let scene_gpu = GpuScene::upload_tables(&gpu, tables).unwrap();
    let view = upload(&gpu, &[SceneView::of(&scene_gpu)]);
    let params = FrameParamsHost::new(&gpu, &frame).unwrap();
    let n = rays.len() as u32;
    let mut paths = upload(&gpu, &gpu_records(&gpu_input));
    let hits_dev = upload(&gpu, &hits);
    let count = upload(&gpu, &[n]);
    let f = m.load_function("surface").unwrap();
    let mut b = gpu.stream.launch_builder(&f);
    b.arg(&params.device).arg(&view).arg(&mut paths).arg(&hits_dev).arg(&count);
    // SAFETY: the arguments match `surface`; `paths` and `hits` hold `n` entries.
    unsafe { b.launch(launch_1d(n, BLOCK)) }.unwrap();
    let got = records_of(download(&gpu, &paths));
    let (mut compared, mut emissive, mut with_normals, mut hair) = (0, 0, 0, 0);
    let mut bad = Vec::new();
    for (i, (c, g)) in cpu_hits.iter().zip(&got).enumerate() {
        // A tie between two BVH builds could pick another triangle: compare
        // only rays whose CPU hit is the one handed to the kernel.
        if c.has(flags::HIT) != (hits[i].instance != HIT_NONE) || c.t_max != gpu_input[i].t_max {
            continue;
        }
        compared += 1;
        emissive += (c.light != NO_LIGHT) as u32;
        with_normals += (c.shading_normal != c.geometric_normal) as u32;
        hair += (c.material_kind() == MaterialKind::Hair) as u32;
        if let Err(e) = compare_records(c, g) {
            bad.push(format!("ray {i}: {e}"));
        }
    }
    assert!(compared >= rays.len() * 95 / 100, "only {compared} of {} rays comparable", rays.len());
    assert!(
        emissive > 0 && with_normals > 0 && hair > 0,
        "the rays must hit lights ({emissive}), smooth meshes ({with_normals}) and hair ({hair})"
    );
    assert_no_mismatches("surface", &bad);
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn rng_is_bit_identical() {
    let Some(gpu) = gpu() else { return };
    let m = module(&gpu, "test_bsdf.cu", false);
    let seed = 1234u32;
    let queries: Vec<u32> =
        (0..20_000u32).flat_map(|i| [i.wrapping_mul(2_654_435_761), i % 97, i % 61]).collect();
    let n = (queries.len() / 3) as u32;
    let q = upload(&gpu, &queries);
    let mut out = gpu.stream.alloc_zeros::<u32>(2 * n as usize).unwrap();
    let f = m.load_function("test_rng").unwrap();
    let mut b = gpu.stream.launch_builder(&f);
    b.arg(&seed).arg(&q).arg(&n).arg(&mut out);
    // SAFETY: the arguments match `test_rng`; `out` holds 2n words.
    unsafe { b.launch(launch_1d(n, BLOCK)) }.unwrap();
    let out = download(&gpu, &out);
    for (i, q) in queries.chunks(3).enumerate() {
        assert_eq!(out[2 * i], pcg_hash(q[0]), "pcg_hash({})", q[0]);
        let expected = SampleStream::new(seed, q[0], q[1]).get(q[2]);
        assert_eq!(out[2 * i + 1], expected.to_bits(), "get({q:?})");
    }
}

/// The 16 output words of `test_bsdf` for one case, computed on the CPU.
fn bsdf_reference(r: &RayRecord, measured: &[Arc<MeasuredBrdf>], input: &[f32]) -> [f32; 16] {
    let mut out = [0.0f32; 16];
    let Some(b) = bsdf_from_record(r, measured) else { return out };
    let (wo, wi) = (Vec3::from_slice(&input[0..3]), Vec3::from_slice(&input[3..6]));
    out[0..3].copy_from_slice(&b.eval(wo, wi).to_array());
    out[3] = b.pdf(wo, wi);
    if let Some(s) = b.sample(wo, input[6], Vec2::new(input[7], input[8])) {
        out[4] = 1.0;
        out[5..8].copy_from_slice(&s.f.to_array());
        out[8..11].copy_from_slice(&s.wi.to_array());
        out[11] = s.pdf;
        out[12] = s.eta;
        out[13] = s.delta as u32 as f32;
        out[14] = s.transmission as u32 as f32;
    }
    out[15] = b.is_delta() as u32 as f32;
    out
}

/// Runs `test_bsdf` on `cases` cases cycling through `materials` (random
/// directions, half of them reflection pairs) and compares every output
/// with [`bsdf_reference`]; returns the cases that differ.
fn bsdf_mismatches(gpu: &Gpu, materials: &[PackedMaterial], cases: u32) -> Vec<String> {
    bsdf_mismatches_measured(gpu, materials, &[], cases)
}

/// [`bsdf_mismatches`] with the measured BRDFs `measured` materials name.
fn bsdf_mismatches_measured(
    gpu: &Gpu,
    materials: &[PackedMaterial],
    measured: &[Arc<MeasuredBrdf>],
    cases: u32,
) -> Vec<String> {
    let m = module(gpu, "test_bsdf.cu", false);
    let (mut records, mut inputs) = (Vec::new(), Vec::new());
    for i in 0..cases {
        let mut r = RayRecord::zeroed();
        materials[i as usize % materials.len()].store(&mut r);
        let wo = unit(i, 0);
        // Half the cases with wi on wo's side (reflection), half anywhere.
        let mut wi = unit(i, 2);
        if i % 2 == 0 && wi.z * wo.z < 0.0 {
            wi.z = -wi.z;
        }
        records.push(r);
        inputs.extend_from_slice(&[wo.x, wo.y, wo.z, wi.x, wi.y, wi.z, rnd(i, 4), rnd(i, 5), rnd(i, 6)]);
    }
    let n = records.len() as u32;
    let r_dev = upload(gpu, &gpu_records(&records));
    let in_dev = upload(gpu, &inputs);
    // One word more, so that no measured BRDFs still upload.
    let mut tables = atoll_cuda::params::pack_measured(measured);
    tables.push(0.0);
    let tables = upload(gpu, &tables);
    let mut out = gpu.stream.alloc_zeros::<f32>(16 * n as usize).unwrap();
    let f = m.load_function("test_bsdf").unwrap();
    let mut b = gpu.stream.launch_builder(&f);
    b.arg(&r_dev).arg(&tables).arg(&in_dev).arg(&n).arg(&mut out);
    // SAFETY: the arguments match `test_bsdf`; 9 input and 16 output words per case.
    unsafe { b.launch(launch_1d(n, BLOCK)) }.unwrap();
    let out = download(gpu, &out);
    let mut bad = Vec::new();
    for i in 0..n as usize {
        let expected = bsdf_reference(&records[i], measured, &inputs[9 * i..9 * i + 9]);
        let got = &out[16 * i..16 * i + 16];
        if !close_all(&expected, got) {
            bad.push(format!(
                "case {i} (material {}): input {:?}\n  cpu {expected:?}\n  gpu {got:?}",
                records[i].material,
                &inputs[9 * i..9 * i + 9]
            ));
        }
    }
    bad
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn bsdfs_match_value_by_value() {
    let Some(gpu) = gpu() else { return };
    let bad = bsdf_mismatches(&gpu, &test_materials(), 12_000);
    // A sampled decision on a rounding boundary (sinf/cosf differ by an ulp) may flip.
    assert!(
        bad.len() <= 3,
        "{} BSDF cases differ, first ones:\n{}",
        bad.len(),
        bad[..bad.len().min(6)].join("\n")
    );
}

/// Coated diffuse and coated conductor surfaces (smooth and rough coatings
/// and conductors, absorbing and scattering layers, several walks per
/// estimate).
fn coated_materials() -> Vec<PackedMaterial> {
    let coating = |(alpha_x, alpha_y): (f32, f32), thickness: f32, albedo: Rgb, g: f32, n_samples: u32| {
        Coating { alpha_x, alpha_y, thickness, albedo, g, n_samples, ..Coating::PBRT_DEFAULT }
    };
    let diffuse = |reflectance: Rgb, coating: Coating| {
        Material::CoatedDiffuse(CoatedDiffuseParams { reflectance, coating })
    };
    let conductor = |alpha: (f32, f32), coating: Coating| {
        Material::CoatedConductor(CoatedConductorParams {
            eta: Rgb::new(0.2, 0.92, 1.1),
            k: Rgb::new(3.9, 2.45, 2.14),
            alpha_x: alpha.0,
            alpha_y: alpha.1,
            coating,
        })
    };
    [
        diffuse(Rgb::new(0.8, 0.4, 0.1), coating((0.0, 0.0), 0.01, Rgb::ZERO, 0.0, 1)),
        diffuse(Rgb::new(0.8, 0.4, 0.1), coating((0.3, 0.3), 0.01, Rgb::ZERO, 0.0, 1)),
        diffuse(Rgb::splat(0.7), coating((0.1, 0.5), 0.3, Rgb::new(0.9, 0.5, 0.2), 0.5, 2)),
        diffuse(Rgb::splat(0.9), coating((0.0, 0.0), 0.5, Rgb::splat(0.8), -0.3, 1)),
        diffuse(Rgb::ZERO, coating((0.0, 0.0), 0.01, Rgb::ZERO, 0.0, 1)),
        conductor((0.0, 0.0), coating((0.0, 0.0), 0.01, Rgb::ZERO, 0.0, 1)),
        conductor((0.0, 0.0), coating((0.3, 0.3), 0.01, Rgb::ZERO, 0.0, 1)),
        conductor((0.2, 0.4), coating((0.0, 0.0), 0.01, Rgb::ZERO, 0.0, 1)),
        conductor((0.3, 0.3), coating((0.1, 0.2), 0.3, Rgb::new(0.9, 0.5, 0.2), 0.5, 1)),
    ]
    .iter()
    .map(PackedMaterial::pack)
    .collect()
}

/// The layered BSDF's `eval`, `pdf` and `sample` seed their random walks
/// with hashes of their arguments, so the GPU reproduces the CPU's walks
/// value by value. A walk can turn differently where an ulp of `expf`,
/// `logf`, `sinf` or `cosf` decides a comparison: rare, but a walk has many.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn coated_walks_match_value_by_value() {
    let Some(gpu) = gpu() else { return };
    let cases = 10_000;
    let bad = bsdf_mismatches(&gpu, &coated_materials(), cases);
    assert!(
        bad.len() <= cases as usize / 500,
        "{} of {cases} coated cases differ, first ones:\n{}",
        bad.len(),
        bad[..bad.len().min(6)].join("\n")
    );
}

/// `shade` with coated hits: light sampling with the stochastic
/// `eval`/`pdf`, and the next segment's MIS density taken from `pdf`
/// (`bsdf_sampled_pdf_is_proportional`).
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn shade_with_coated_materials_matches_the_cpu_stage() {
    shade_materials_matches_the_cpu_stage(&coated_materials());
}

/// `shade` on 3000 synthetic paths whose hits take `materials` in turn, on
/// CPU and GPU: at most 6 records may differ (an ulp deciding a branch).
fn shade_materials_matches_the_cpu_stage(materials: &[PackedMaterial]) {
    let Some(gpu) = gpu() else { return };
    let m = module(&gpu, "wavefront.cu", false);
    let (_, frame) = test_frame(IntegratorSettings::Path { max_depth: 5 }, false);
    let params = FrameParamsHost::new(&gpu, &frame).unwrap();
    let mut paths = synthetic_paths(&frame, 3000);
    for (i, r) in paths.iter_mut().enumerate().filter(|(_, r)| r.has(flags::HIT)) {
        let m = &materials[i % materials.len()];
        m.store(r);
        // Hair, measured and anisotropic lobes turn their frame about a
        // tangent the hit carries.
        let offset = if i % 3 == 0 { rnd(i as u32, 18) * 2.0 - 1.0 } else { 2.0 };
        store_hair_offset(m.kind, &mut r.coeffs, offset);
        store_tangent(m.kind, &mut r.coeffs, unit(i as u32, 17));
    }
    let cpu = shade_on_cpu(&frame, &paths);
    let got = shade_on_gpu(&gpu, &m, &params, &frame, &paths);
    assert!(!cpu.shadows.is_empty() && !cpu.next.is_empty());
    let bad = shade_mismatches(&cpu, &got);
    assert!(bad.len() <= 6, "{} mismatches, first ones:\n{}", bad.len(), bad[..bad.len().min(8)].join("\n"));
}

/// Principled surfaces: dielectric, metal and glass, rough and smooth
/// (delta lobes), with clearcoat, sheen and tints, and everything at once.
fn principled_materials() -> Vec<PackedMaterial> {
    // (base colour, metallic, roughness, transmission), then (sheen,
    // clearcoat, clearcoat gloss, specular and sheen tint).
    let p = |(base_color, metallic, roughness, transmission): (Rgb, f32, f32, f32),
             (sheen, clearcoat, clearcoat_gloss, tint): (f32, f32, f32, f32)| {
        Material::Principled(PrincipledParams {
            base_color,
            metallic,
            roughness,
            specular: 0.5,
            specular_tint: tint,
            sheen,
            sheen_tint: tint,
            clearcoat,
            clearcoat_gloss,
            transmission,
            eta: 1.5,
        })
    };
    let orange = Rgb::new(0.8, 0.4, 0.1);
    let plain = (0.0, 0.0, 1.0, 0.0);
    [
        p((orange, 0.0, 0.5, 0.0), plain),
        p((orange, 0.0, 0.0, 0.0), plain),
        p((orange, 1.0, 0.3, 0.0), plain),
        p((orange, 1.0, 0.0, 0.0), plain),
        p((Rgb::splat(0.9), 0.0, 0.2, 1.0), plain),
        p((Rgb::new(0.6, 0.9, 0.7), 0.0, 0.0, 1.0), plain),
        p((orange, 0.0, 1.0, 0.0), (1.0, 0.0, 1.0, 0.5)),
        p((orange, 0.3, 0.4, 0.0), (0.0, 1.0, 0.5, 1.0)),
        p((Rgb::new(0.2, 0.5, 0.9), 0.3, 0.4, 0.4), (0.5, 0.7, 0.8, 0.5)),
    ]
    .iter()
    .map(PackedMaterial::pack)
    .collect()
}

/// The principled BSDF's `eval`, `pdf`, `sample` and `is_delta` on the GPU
/// (`principled.cuh`) agree with the CPU's value by value.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn principled_bsdfs_match_value_by_value() {
    let Some(gpu) = gpu() else { return };
    let cases = 12_000;
    let bad = bsdf_mismatches(&gpu, &principled_materials(), cases);
    // `powf`/`logf` in the GTR1 sampler and `sinf`/`cosf` may differ by an
    // ulp and flip a decision on a rounding boundary.
    assert!(
        bad.len() <= 3,
        "{} of {cases} principled cases differ, first ones:\n{}",
        bad.len(),
        bad[..bad.len().min(6)].join("\n")
    );
}

/// `shade` with principled hits: light sampling through the mixture's
/// `eval`/`pdf`, and delta and non-delta samples of its lobes.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn shade_with_principled_matches_the_cpu_stage() {
    shade_materials_matches_the_cpu_stage(&principled_materials());
}

/// Hair fibres: smooth and rough, light and dark, tilted scales or none.
fn hair_materials() -> Vec<PackedMaterial> {
    let hair = |sigma_a: Rgb, beta_m: f32, beta_n: f32, alpha: f32| {
        Material::Hair(HairParams { sigma_a, eta: 1.55, beta_m, beta_n, alpha })
    };
    [
        Material::Hair(HairParams::pbrt_default()),
        hair(Rgb::ZERO, 0.3, 0.3, 2.0),
        hair(Rgb::new(0.1, 0.4, 1.2), 0.05, 0.2, 0.0),
        hair(Rgb::new(3.0, 5.0, 8.0), 0.8, 0.9, 5.0),
    ]
    .iter()
    .map(PackedMaterial::pack)
    .chain([given_offset(hair(Rgb::new(0.4, 0.6, 1.0), 0.3, 0.3, 2.0), -0.35)])
    .collect()
}

/// A hair fibre whose hit gives its offset (`-1 + 2v`) rather than the
/// packed material's `OFFSET_FROM_NORMAL`.
fn given_offset(m: Material, offset: f32) -> PackedMaterial {
    let mut packed = PackedMaterial::pack(&m);
    packed.coeffs[atoll_render::material_layout::hair::OFFSET] = half::f16::from_f32(offset);
    packed
}

/// The hair BSDF's `eval`, `pdf` and `sample` on the GPU (`hair.cuh`)
/// agree with the CPU's value by value.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn hair_bsdfs_match_value_by_value() {
    let Some(gpu) = gpu() else { return };
    let cases = 12_000;
    let bad = bsdf_mismatches(&gpu, &hair_materials(), cases);
    // Narrow lobes are ill-conditioned in f32: `Mp`'s exponent subtracts
    // terms of size 1 / v (thousands for beta_m 0.05), so an ulp of `logf`
    // or `expf` moves `f` and `pdf` by a few parts in 10⁴ (more than
    // `close` allows) in a case in a thousand or so.
    assert!(
        bad.len() <= cases as usize / 500,
        "{} of {cases} hair cases differ, first ones:\n{}",
        bad.len(),
        bad[..bad.len().min(6)].join("\n")
    );
}

/// `shade` with hair hits: the frame about the stored axis, light sampling
/// and sampled directions to both sides of the surface.
/// Measured BRDFs (`scenes/measured-ggx.bsdf`, isotropic, and
/// `measured-ggx-aniso.bsdf`, anisotropic): their tables' lookups, warps
/// and the BSDF built on them, value by value, from a table of two.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn measured_bsdf_matches_value_by_value() {
    let Some(gpu) = gpu() else { return };
    let measured = ["measured-ggx.bsdf", "measured-ggx-aniso.bsdf"].map(|name| {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes").join(name);
        Arc::new(MeasuredBrdf::from_bytes(&std::fs::read(path).unwrap(), name).unwrap())
    });
    let materials = [0, 1].map(|brdf| PackedMaterial::pack(&Material::Measured { brdf }));
    let bad = bsdf_mismatches_measured(&gpu, &materials, &measured, 12_000);
    // A sampled direction is a reflection about a normal made from sin and
    // cos of table angles: a component near 0 (a grazing wi.z, and `f`
    // divided by it) is the difference of nearly equal terms, and sincosf
    // rounds apart from Rust's sin_cos. Five such cases in 12,000 were seen.
    assert!(
        bad.len() <= 12,
        "{} measured cases differ, first ones:\n{}",
        bad.len(),
        bad[..bad.len().min(6)].join("\n")
    );
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn shade_with_hair_matches_the_cpu_stage() {
    shade_materials_matches_the_cpu_stage(&hair_materials());
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn light_sampling_and_lookup_match() {
    let Some(gpu) = gpu() else { return };
    let m = module(&gpu, "test_bsdf.cu", false);
    // Area lights (the Cornell light, two lamp instances) and every other kind.
    let mut scene = surface_scene();
    scene.lights.extend([
        Light::Point { position: Vec3::new(0.2, 1.5, 0.1), intensity: Rgb::splat(3.0) },
        Light::Distant { direction: Vec3::new(0.3, -1.0, 0.2), radiance: Rgb::splat(0.7) },
        Light::Infinite { radiance: Rgb::new(0.1, 0.2, 0.3), portal: None },
        // Aimed down into the sampled region, its falloff band crossing it.
        Light::spot(Vec3::new(0.0, 1.8, 0.0), -Vec3::Y, Rgb::new(4.0, 3.0, 2.0), 25.0, 10.0),
        // Above the sampled region, turned, its 8×8 map varying texel by texel.
        Light::Goniometric {
            position: Vec3::new(-0.1, 1.7, 0.2),
            world_to_light: glam::Mat3::from_rotation_z(0.4) * glam::Mat3::from_rotation_x(-0.3),
            intensity: Rgb::new(2.0, 1.0, 0.5),
            map: std::sync::Arc::new(atoll_scene::IntensityMap {
                resolution: 8,
                values: (0..64).map(|i| (i % 7) as f32 * 0.3).collect(),
            }),
        },
        // A projector above the region, aimed down and turned, its 5×4
        // image varying pixel by pixel; its frustum covers part of the region.
        Light::Projection {
            position: Vec3::new(0.1, 1.6, -0.1),
            world_to_light: glam::Mat3::from_rotation_z(0.3) * glam::Mat3::from_rotation_x(-1.5),
            scale: 2.5,
            image: std::sync::Arc::new(atoll_scene::ProjectionImage {
                width: 5,
                height: 4,
                pixels: (0..20).map(|i| Rgb::new((i % 3) as f32, (i % 5) as f32 * 0.5, 1.0)).collect(),
                tan_half_fov: 0.4,
            }),
        },
        environment_light(EnvLayout::LatLong),
        environment_light(EnvLayout::EqualArea),
    ]);
    let mut options = RenderOptions::from_scene(&scene);
    options.resolution = UVec2::new(8, 8);
    let frame = FrameContext::new(&scene, options);
    let params = FrameParamsHost::new(&gpu, &frame).unwrap();
    let inputs: Vec<f32> = (0..8000u32)
        .flat_map(|i| {
            [1.8 * rnd(i, 0) - 0.9, 1.9 * rnd(i, 1), 1.8 * rnd(i, 2) - 0.9, rnd(i, 3), rnd(i, 4), rnd(i, 5)]
        })
        .collect();
    let n = (inputs.len() / 6) as u32;
    let in_dev = upload(&gpu, &inputs);
    let mut out = gpu.stream.alloc_zeros::<f32>(10 * n as usize).unwrap();
    let f = m.load_function("test_lights").unwrap();
    let mut b = gpu.stream.launch_builder(&f);
    b.arg(&params.device).arg(&in_dev).arg(&n).arg(&mut out);
    // SAFETY: the arguments match `test_lights`; 6 input and 10 output words per case.
    unsafe { b.launch(launch_1d(n, BLOCK)) }.unwrap();
    let out = download(&gpu, &out);
    let mut bad = Vec::new();
    for (i, input) in inputs.chunks(6).enumerate() {
        let mut expected = [0.0f32; 10];
        if let Some(ls) =
            frame.lights.sample(Vec3::from_slice(input), input[3], Vec2::new(input[4], input[5]))
        {
            expected[0] = 1.0;
            expected[1..4].copy_from_slice(&ls.wi.to_array());
            expected[4] = ls.distance;
            expected[5..8].copy_from_slice(&ls.radiance.to_array());
            expected[8] = ls.pdf;
            expected[9] = ls.delta as u32 as f32;
        }
        if !close_all(&expected, &out[10 * i..10 * i + 10]) {
            bad.push(format!(
                "case {i} {input:?}:\n  cpu {expected:?}\n  gpu {:?}",
                &out[10 * i..10 * i + 10]
            ));
        }
    }
    assert_no_mismatches("light sampling", &bad);

    // Every (instance, mesh) pair, emissive or not, and some triangles.
    let queries: Vec<u32> = (0..scene.instances.len() as u32 + 1)
        .flat_map(|inst| {
            (0..scene.meshes.len() as u32 + 1).flat_map(move |mesh| [0u32, 1].map(|t| [inst, mesh, t]))
        })
        .flatten()
        .collect();
    let n = (queries.len() / 3) as u32;
    let q_dev = upload(&gpu, &queries);
    let mut out = gpu.stream.alloc_zeros::<u32>(n as usize).unwrap();
    let f = m.load_function("test_light_lookup").unwrap();
    let mut b = gpu.stream.launch_builder(&f);
    b.arg(&params.device).arg(&q_dev).arg(&n).arg(&mut out);
    // SAFETY: the arguments match `test_light_lookup`; one output word per query.
    unsafe { b.launch(launch_1d(n, BLOCK)) }.unwrap();
    let out = download(&gpu, &out);
    let mut found = 0;
    for (q, got) in queries.chunks(3).zip(out) {
        let expected = frame.lights.triangle_light(q[0], q[1], q[2]).unwrap_or(NO_LIGHT);
        assert_eq!(got, expected, "triangle_light{q:?}");
        found += (got != NO_LIGHT) as u32;
    }
    assert!(found >= 6, "the Cornell light and both lamp instances");
}
