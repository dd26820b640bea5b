//! The strategy test bodies shared with CPU devices
//! (`atoll-dist/tests/common/strategy_bodies.rs`) run on CUDA devices, and
//! what only GPUs have (devices on parts of one GPU). Device `i` of a
//! render is on GPU `i` modulo the GPU count: two devices on two GPUs
//! where there are, all on GPU 0 with one GPU (a ring's copies are then
//! copies within that GPU); `ATOLL_REQUIRE_GPUS=N` makes fewer than N GPUs
//! a failure. Ignored unless asked for (`--include-ignored`, as
//! scripts/gpu-check and scripts/gpu-multi pass), so that a machine
//! without a GPU reports them as ignored rather than passed; asked for
//! there, they fail.

#[path = "../../atoll-dist/tests/common/strategy_bodies.rs"]
mod strategy_bodies;

use std::sync::Once;

use atoll_cuda::CudaDevice;
use atoll_dist::{partition, render_multi, Layout, PartitionOptions, RingOrder};
use atoll_render::{Device, RenderOptions};
use atoll_scene::IntegratorSettings;
use glam::UVec2;
use strategy_bodies::{Kind, Tolerance};

/// The GPUs to place devices on; panics without one, or with fewer than
/// `ATOLL_REQUIRE_GPUS`.
fn gpu_count() -> usize {
    let count = atoll_cuda::device_count().unwrap_or(0);
    let required = std::env::var("ATOLL_REQUIRE_GPUS").map_or(0, |v| v.parse::<usize>().unwrap_or(0));
    assert!(count >= required, "ATOLL_REQUIRE_GPUS={required} but {count} GPUs found");
    assert!(count > 0, "no CUDA GPU found");
    count
}

fn gpus(n: usize) -> Vec<Box<dyn Device>> {
    let count = gpu_count();
    static ONE_GPU: Once = Once::new();
    if count == 1 && n > 1 {
        ONE_GPU.call_once(|| eprintln!("one GPU: every device on it"));
    }
    (0..n).map(|i| Box::new(CudaDevice::new(i % count).unwrap()) as Box<dyn Device>).collect()
}

/// Larger images than the CPU's, spanning several GPU-sized waves; a GPU's
/// film sums atomically, in no fixed order, so pixels match more loosely.
const CUDA: Kind = Kind {
    devices: gpus,
    resolution: UVec2::new(128, 128),
    tolerance: Tolerance { relative: 1e-3, absolute: 1e-5, one_in: 200 },
    part_budgets: false,
    shared_chunk: 2 << 20,
    shared_growth: 16,
    distinct_memories: gpu_count,
};

strategy_bodies::strategy_tests!(
    CUDA,
    #[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
);
strategy_bodies::shared_strategy_tests!(
    CUDA,
    #[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
);

/// Devices on two parts of GPU 0 (green contexts: multiprocessors apart,
/// memory shared, standing in for two GPUs): replicate and both ring
/// orders render the one-device image, and each part has its share of the
/// multiprocessors.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn replicate_and_ring_on_two_gpu_parts_are_one_gpu() {
    gpu_count();
    let parts = || -> Vec<Box<dyn Device>> {
        (0..2)
            .map(|i| {
                let gpu = atoll_cuda::Gpu::open_partition(0, 2, i).unwrap();
                Box::new(CudaDevice::on(gpu)) as Box<dyn Device>
            })
            .collect()
    };
    let whole = atoll_cuda::Gpu::open(0).unwrap().multiprocessors;
    let mut failures = Vec::new();
    for (name, scene) in strategy_bodies::scenes() {
        let opts = RenderOptions {
            integrator: IntegratorSettings::Path { max_depth: 8 },
            ..CUDA.options(&scene, 8)
        };
        let (reference, _) = CUDA.single(&scene, &opts);
        let mut devices = parts();
        for d in devices.iter_mut() {
            let gpu = d.as_any_mut().downcast_mut::<CudaDevice>().unwrap().gpu().clone();
            assert!(gpu.multiprocessors * 2 <= whole && gpu.multiprocessors * 4 > whole, "{}", gpu.label());
        }
        let out = render_multi(&mut devices, &scene, opts.clone(), &Layout::Replicate, None, &mut |_, _| {})
            .unwrap();
        failures.extend(CUDA.same_image(&reference, &out.film, &format!("{name} replicate on parts")).err());
        let p = partition(&scene, 2, &atoll_cuda::scene::byte_model(), &PartitionOptions::default()).unwrap();
        for order in [RingOrder::Spread, RingOrder::Home] {
            let layout = Layout::Ring { parts: p.parts.clone(), islands: 1, order };
            let out =
                render_multi(&mut parts(), &scene, opts.clone(), &layout, None, &mut |_, _| {}).unwrap();
            failures.extend(
                CUDA.same_image(&reference, &out.film, &format!("{name} ring on parts ({order:?})")).err(),
            );
            assert!(out.devices.iter().all(|d| d.bytes_sent > 0));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// More wavefronts on each GPU of a shared scene (another stream each,
/// as `--streams` adds) read their GPU's chunks: the prepass and the
/// placement are the two GPUs', the image the one-GPU image.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn more_wavefronts_share_their_gpus_chunks() {
    if gpu_count() < 2 {
        eprintln!("more wavefronts share their GPU's chunks: skipped, needs 2 GPUs");
        return;
    }
    let mut devices = gpus(2);
    let more: Vec<Box<dyn Device>> = devices
        .iter()
        .map(|d| d.another_on_same_hardware().expect("a GPU takes more streams").unwrap())
        .collect();
    devices.extend(more);
    let scene = std::sync::Arc::new(atoll_scene::landscape::Landscape::new(16).build());
    let opts = CUDA.options(&scene, 4);
    let (reference, _) = CUDA.single(&scene, &opts);
    let spec = atoll_dist::SharedSpec {
        replication: atoll_dist::chunk_placement::Replication::Fraction(0.1),
        ..Default::default()
    };
    let out = render_multi(&mut devices, &scene, opts, &Layout::Shared(spec), None, &mut |_, _| {}).unwrap();
    CUDA.assert_same_image(&reference, &out.film, "landscape:16 shared, two wavefronts per GPU");
    let report = out.shared.unwrap();
    assert_eq!(report.residency.len(), 2, "the chunks are placed over the GPUs, not the wavefronts");
    assert!(
        out.devices[2..].iter().all(|d| d.prepare.scene_bytes == 0),
        "the extra wavefronts hold no chunks"
    );
}

/// The split-ground body's budget search finds a partition under the CUDA
/// byte model too (no GPU needed: the model is arithmetic), so the GPU
/// run of that body is not the first to learn that it cannot.
#[test]
fn the_split_ground_partition_fits_the_cuda_byte_model() {
    let scene = strategy_bodies::ground_scene();
    strategy_bodies::split_ground_partition(&scene, &atoll_cuda::scene::byte_model());
}

/// `auto` on GPUs whose budget holds neither the whole scene nor room to
/// build its BVH whole on one of them: the BVH is built in pieces, so it
/// shares the scene's memory (faster than the ring); with room it
/// replicates.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn auto_shares_a_scene_no_gpu_has_room_to_build_whole() {
    use atoll_dist::placement::{place, PlacementRequest};
    use atoll_dist::{Plan, Strategy};
    let scene = std::sync::Arc::new(atoll_scene::landscape::Landscape::new(16).build());
    let mut options = CUDA.options(&scene, 1);
    // Small queues, so that the scene decides what fits.
    options.wave_size = 1 << 14;
    let whole = atoll_bvh::ScenePart::whole(&scene);
    let build = atoll_cuda::scene::part_plan(&scene, &whole).total();
    let scene_bytes = atoll_bvh::part_bytes(&scene, &whole, &atoll_cuda::scene::byte_model());
    let request = |budget: Option<u64>| PlacementRequest {
        strategy: Strategy::Auto,
        ring_size: None,
        budget,
        partitioning: Default::default(),
        ring_order: RingOrder::Spread,
        streams: 1,
        shared: Default::default(),
        may_add_wavefronts: vec![false; 2],
    };
    let devices = |budget: Option<u64>| -> Vec<Box<dyn Device>> {
        let count = gpu_count();
        (0..2)
            .map(|i| {
                let mut d = CudaDevice::new(i % count).unwrap();
                if let Some(b) = budget {
                    d = d.with_memory_budget(b);
                }
                Box::new(d) as Box<dyn Device>
            })
            .collect()
    };
    let placed = place(&mut devices(None), &scene, &options, &request(None)).unwrap();
    assert_eq!(placed.plan, Plan::Replicate, "room for everything");
    // A frame beside 65% of the scene: half of it fits, all of it does
    // not, and building its BVH needs all of it and more.
    let probe = devices(None).pop().unwrap();
    let frame = probe.frame_bytes(&options) + probe.scene_wide_bytes(&scene);
    let budget = frame + scene_bytes * 65 / 100;
    assert!(budget < build, "the budget {budget} B leaves room to build ({build} B)");
    let placed = place(&mut devices(Some(budget)), &scene, &options, &request(Some(budget))).unwrap();
    assert_eq!(placed.plan, Plan::Shared, "scene {scene_bytes} B, budget {budget} B");
}
