//! The CUDA plumbing on a real GPU: opening, compiling and loading kernels,
//! launches, copies, timers, scene upload and the ray queues. Ignored
//! unless asked for (`--include-ignored`, as scripts/gpu-check does); then
//! skipped without a GPU unless `ATOLL_REQUIRE_GPU=1` (see tests/common).

mod common;

use std::sync::Arc;

use atoll_cuda::gpu::launch_1d;
use atoll_cuda::queues::Queues;
use atoll_cuda::scene::{SceneTables, HEADROOM};
use atoll_cuda::{device_count, CudaError, Gpu, GpuScene};
use atoll_render::{Queue, RayRecord};
use bytemuck::Zeroable;
use cudarc::driver::PushKernelArg;

use common::gpu_or_skip;

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn opens_and_describes_the_gpu() {
    let Some(gpu) = gpu_or_skip("open") else { return };
    println!("{gpu:?}, {} SMs", gpu.multiprocessors);
    assert!(gpu.compute_capability >= (7, 5), "CUDA 13 needs sm_75 or newer");
    assert!(gpu.total_memory > 1 << 30);
    let free = gpu.free_memory().unwrap();
    assert!(free > 0 && free <= gpu.total_memory);
    let count = device_count().unwrap();
    assert!(matches!(Gpu::open(count), Err(CudaError::BadOrdinal { .. })));
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn compiles_loads_and_launches_a_kernel() {
    let Some(gpu) = gpu_or_skip("launch") else { return };
    let f = gpu.function("selftest.cu", "selftest_affine").unwrap();
    // The module is loaded once per GPU.
    assert!(Arc::ptr_eq(&gpu.module("selftest.cu").unwrap(), &gpu.module("selftest.cu").unwrap()));
    let n = 100_003u32;
    let mut out = gpu.stream.alloc_zeros::<u32>(n as usize).unwrap();
    let (scale, offset) = (3u32, 7u32);
    let mut timer = gpu.start_timer().unwrap();
    let mut launch = gpu.stream.launch_builder(&f);
    launch.arg(&mut out).arg(&n).arg(&scale).arg(&offset);
    // SAFETY: matches selftest_affine(unsigned*, unsigned n, unsigned, unsigned); `out` holds n.
    unsafe { launch.launch(launch_1d(n, 256)) }.unwrap();
    timer.stop(&gpu).unwrap();
    let host = gpu.stream.clone_dtoh(&out).unwrap();
    assert!(host.iter().enumerate().all(|(i, &v)| v == i as u32 * 3 + 7));
    let ms = timer.elapsed_ms().unwrap();
    assert!((0.0..1000.0).contains(&ms), "{ms} ms");
    assert!(gpu.function("selftest.cu", "no_such_kernel").is_err());
    assert!(matches!(gpu.function("nope.cu", "k"), Err(CudaError::UnknownKernelFile { .. })));
}

/// The queue protocol every stage kernel follows: launched over the
/// capacity, the length read on the device, appends through an atomic.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn queue_kernels_read_their_length_on_the_device() {
    let Some(gpu) = gpu_or_skip("queue protocol") else { return };
    let f = gpu.function("selftest.cu", "selftest_compact_even").unwrap();
    let capacity = 4096u32;
    let input: Vec<u32> = (0..capacity).collect();
    let input = gpu.stream.clone_htod(&input).unwrap();
    let count = gpu.stream.clone_htod(&[1000u32]).unwrap();
    let mut out = gpu.stream.alloc_zeros::<u32>(capacity as usize).unwrap();
    let mut out_count = gpu.stream.alloc_zeros::<u32>(1).unwrap();
    let mut launch = gpu.stream.launch_builder(&f);
    launch.arg(&input).arg(&count).arg(&capacity).arg(&mut out).arg(&mut out_count);
    // SAFETY: matches selftest_compact_even(const unsigned*, const unsigned*, unsigned,
    // unsigned*, unsigned*); every buffer holds `capacity` entries.
    unsafe { launch.launch(launch_1d(capacity, 128)) }.unwrap();
    let n = gpu.stream.clone_dtoh(&out_count).unwrap()[0] as usize;
    assert_eq!(n, 500);
    let mut got = gpu.stream.clone_dtoh(&out).unwrap()[..n].to_vec();
    got.sort_unstable();
    assert_eq!(got, (0..1000).step_by(2).collect::<Vec<u32>>());
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn scene_tables_round_trip_and_budget_refusal() {
    let Some(gpu) = gpu_or_skip("scene upload") else { return };
    let scene = atoll_scene::procedural::bench_scene(50_000);
    let tables = SceneTables::build(&scene);
    let uploaded = GpuScene::upload(&gpu, &scene, None, 0).unwrap();
    assert_eq!(gpu.stream.clone_dtoh(&uploaded.vertices).unwrap(), tables.vertices);
    assert_eq!(gpu.stream.clone_dtoh(&uploaded.triangles).unwrap(), tables.triangles);
    assert_eq!(gpu.stream.clone_dtoh(&uploaded.triangle_mesh).unwrap(), tables.triangle_mesh);
    assert_eq!(gpu.stream.clone_dtoh(&uploaded.meshes).unwrap(), tables.meshes);
    assert_eq!(gpu.stream.clone_dtoh(&uploaded.objects).unwrap(), tables.objects);
    assert_eq!(gpu.stream.clone_dtoh(&uploaded.instances).unwrap(), tables.instances);
    assert_eq!(uploaded.bytes(), tables.counts().bytes());
    // A budget below the plan is refused before anything is allocated.
    match GpuScene::upload(&gpu, &scene, Some(HEADROOM + 1024), 0) {
        Err(CudaError::OutOfMemory { needed, budget, .. }) => assert!(needed > budget),
        Err(e) => panic!("expected OutOfMemory, got {e}"),
        Ok(_) => panic!("expected OutOfMemory, got a scene"),
    }
}

fn record(i: u32) -> RayRecord {
    let mut r = RayRecord::zeroed();
    r.pixel = i;
    r.origin = [i as f32, 1.0, 2.0];
    r.t_max = f32::INFINITY;
    r
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn queues_round_trip_and_grow_keeping_contents() {
    let Some(gpu) = gpu_or_skip("queues") else { return };
    let mut q = Queues::new(&gpu, 64).unwrap();
    assert_eq!(q.len(&gpu, Queue::Paths).unwrap(), 0);
    let paths: Vec<RayRecord> = (0..50).map(record).collect();
    let shadows: Vec<RayRecord> = (100..110).map(record).collect();
    q.write(&gpu, Queue::Paths, &paths).unwrap();
    q.write(&gpu, Queue::Shadows, &shadows).unwrap();
    // Forget the host's copies: lengths must come back from the device.
    q.set_known_len(Queue::Paths, None);
    q.set_known_len(Queue::Shadows, None);
    assert_eq!(q.len(&gpu, Queue::Paths).unwrap(), 50);
    assert_eq!(
        {
            let mut read = Vec::new();
            q.read(&gpu, Queue::Paths, &mut read).unwrap();
            read
        },
        paths
    );
    // Writing more than the capacity grows every queue and keeps the other one.
    let many: Vec<RayRecord> = (0..1000).map(record).collect();
    q.write(&gpu, Queue::Paths, &many).unwrap();
    assert!(q.capacity >= 1000);
    assert_eq!(
        {
            let mut read = Vec::new();
            q.read(&gpu, Queue::Paths, &mut read).unwrap();
            read
        },
        many
    );
    assert_eq!(
        {
            let mut read = Vec::new();
            q.read(&gpu, Queue::Shadows, &mut read).unwrap();
            read
        },
        shadows
    );
    q.clear(&gpu, Queue::Shadows).unwrap();
    q.set_known_len(Queue::Shadows, None);
    assert_eq!(q.len(&gpu, Queue::Shadows).unwrap(), 0);
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn large_uploads_through_page_locked_staging_arrive_whole() {
    let Some(gpu) = gpu_or_skip("staged upload") else { return };
    // Past the staging threshold, over two and a half staging buffers, and
    // not a whole number of them: every chunk and the tail must land.
    let n = (160 << 20) / 4 + 12_345;
    let data: Vec<u32> = (0..n as u32).map(|i| i.wrapping_mul(2_654_435_761)).collect();
    let device = atoll_cuda::gpu::upload(&gpu, &data, "test data").unwrap();
    let back = gpu.stream.clone_dtoh(&device).unwrap();
    assert_eq!(back.len(), data.len());
    assert!(back == data, "first difference at {:?}", back.iter().zip(&data).position(|(a, b)| a != b));
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn large_tables_written_into_staging_equal_the_host_tables() {
    let Some(gpu) = gpu_or_skip("staged tables") else { return };
    // Over 64 MiB of vertices in three meshes, the middle one without
    // normals and uvs: the tables are written chunk by chunk straight into
    // the staging buffers, chunks ending inside meshes.
    let mut scene = atoll_scene::Scene::default();
    let material = scene.add_material(atoll_scene::Material::default_diffuse());
    let mut meshes = Vec::new();
    for (k, vertices) in [2_500_001usize, 3_000_000, 1_700_003].into_iter().enumerate() {
        let f = |i: usize, c: f32| ((i * 7 + k) % 1009) as f32 * 0.01 + c;
        let positions: Vec<glam::Vec3> =
            (0..vertices).map(|i| glam::Vec3::new(f(i, 0.0), f(i, 0.5), k as f32)).collect();
        let indices = (0..vertices as u32 - 2).map(|t| [t, t + 1, t + 2]).collect();
        let with_attributes = k != 1;
        let normals = if with_attributes {
            positions.iter().map(|p| p.normalize_or_zero()).collect()
        } else {
            Vec::new()
        };
        let uvs = if with_attributes { positions.iter().map(|p| p.truncate()).collect() } else { Vec::new() };
        let mesh = atoll_scene::TriangleMesh {
            name: format!("m{k}"),
            positions,
            normals,
            uvs,
            indices,
            material,
            ..Default::default()
        };
        meshes.push(scene.add_mesh(mesh));
    }
    let object = scene.add_object(atoll_scene::Object { name: "all".into(), meshes });
    scene.instances.push(atoll_scene::Instance::new(object, glam::Affine3A::IDENTITY));
    let host = SceneTables::build(&scene);
    assert!(host.vertices.len() * 4 > 64 << 20);
    let tables = GpuScene::upload(&gpu, &scene, None, 0).unwrap();
    let back = |s: &cudarc::driver::CudaSlice<f32>| gpu.stream.clone_dtoh(s).unwrap();
    assert!(back(&tables.vertices) == host.vertices, "vertices differ");
    assert!(back(&tables.normals) == host.normals, "normals differ");
    assert!(back(&tables.uvs) == host.uvs, "uvs differ");
    let back = |s: &cudarc::driver::CudaSlice<u32>| gpu.stream.clone_dtoh(s).unwrap();
    assert!(back(&tables.triangles) == host.triangles, "triangles differ");
    assert!(back(&tables.triangle_mesh) == host.triangle_mesh, "triangle meshes differ");
}
