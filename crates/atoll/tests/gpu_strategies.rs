//! Two GPU devices render the same image as one: replicate, ring with peer
//! copies and ring through the host, over memory-balanced parts and over
//! work-balanced chunks. With one GPU both devices are made on it (the
//! ring's copies are then copies within that GPU); `ATOLL_REQUIRE_GPUS=2`
//! makes a machine with fewer than two GPUs a failure. Skipped (with a
//! message) without a GPU.

use std::sync::Arc;

use atoll_cuda::CudaDevice;
use atoll_dist::work::partition_work_balanced;
use atoll_dist::{
    partition, render_multi, render_multi_warmed, Layout, PartitionOptions, RingOrder, Transport,
};
use atoll_render::{render, Device, Film, RenderOptions};
use atoll_scene::{IntegratorSettings, Scene};
use glam::UVec2;

/// The ordinals of two devices: two GPUs where there are, else both on
/// GPU 0; `None` (skip) without a GPU.
fn two_devices_or_skip(test: &str) -> Option<[usize; 2]> {
    let count = atoll_cuda::device_count().unwrap_or(0);
    let required = std::env::var("ATOLL_REQUIRE_GPUS").map_or(0, |v| v.parse::<usize>().unwrap_or(0));
    if count < required {
        panic!("{test}: ATOLL_REQUIRE_GPUS={required} but {count} GPUs found");
    }
    match count {
        0 => {
            eprintln!("{test}: skipped, no GPU");
            None
        }
        1 => {
            eprintln!("{test}: one GPU, both devices on it");
            Some([0, 0])
        }
        _ => Some([0, 1]),
    }
}

fn gpus(ordinals: [usize; 2]) -> Vec<Box<dyn Device>> {
    ordinals.iter().map(|&i| Box::new(CudaDevice::new(i).unwrap()) as Box<dyn Device>).collect()
}

fn options(scene: &Scene) -> RenderOptions {
    let mut o = RenderOptions::from_scene(scene);
    o.resolution = UVec2::new(128, 128);
    o.spp = 8;
    o.integrator = IntegratorSettings::Path { max_depth: 8 };
    o
}

/// Per-pixel relative error within 1e-3 except for rare hit ties, equal
/// means; `Err` says how they differ.
fn same_image(a: &Film, b: &Film, what: &str) -> Result<(), String> {
    let (pa, pb) = (a.pixels(), b.pixels());
    let differing = pa
        .iter()
        .zip(&pb)
        .filter(|(x, y)| {
            (**x - **y).abs().max_element() > 1e-3 * x.abs().max_element().max(y.abs().max_element()) + 1e-5
        })
        .count();
    eprintln!("{what}: {differing} of {} pixels differ beyond rounding", pa.len());
    let (ma, mb) = (a.mean(), b.mean());
    if differing * 200 > pa.len() || (ma - mb).abs().max_element() > 1e-3 * ma.max_element() {
        return Err(format!("{what}: {differing} of {} pixels differ, means {ma} vs {mb}", pa.len()));
    }
    Ok(())
}

fn scenes() -> Vec<(&'static str, Arc<Scene>)> {
    let mut landscape = atoll_scene::landscape::Landscape::new(1).build();
    landscape.settings.film.resolution = UVec2::new(128, 72);
    vec![
        ("cornell", Arc::new(atoll_scene::cornell::builtin_cornell_box())),
        ("landscape:1", Arc::new(landscape)),
    ]
}

#[test]
fn replicate_and_ring_on_two_gpus_are_one_gpu() {
    let Some(ordinals) = two_devices_or_skip("replicate_and_ring_on_two_gpus_are_one_gpu") else {
        return;
    };
    // Every combination runs before the test fails: which ones differ says
    // more than the first.
    let mut failures = Vec::new();
    for (name, scene) in scenes() {
        let opts = options(&scene);
        let mut one = CudaDevice::new(0).unwrap();
        let single = render(&mut one, &scene, opts.clone(), &mut |_, _| {}).unwrap();
        let mut reference = single.film;
        reference.spp = opts.spp;

        let out =
            render_multi(&mut gpus(ordinals), &scene, opts.clone(), &Layout::Replicate, None, &mut |_, _| {})
                .unwrap();
        failures.extend(same_image(&reference, &out.film, &format!("{name} replicate")).err());
        if ordinals[0] == ordinals[1] {
            // Replicas on one GPU share one copy of the scene.
            let held: Vec<u64> = out.devices.iter().map(|d| d.prepare.scene_bytes).collect();
            assert!(held[0] > 0 && held[1] == 0, "{name}: scene bytes per replica {held:?}");
        }

        let model = atoll_cuda::scene::byte_model();
        let none = PartitionOptions::default();
        let memory = partition(&scene, 2, &model, &none).unwrap();
        let work = partition_work_balanced(&scene, 2, opts.resolution, &model, &none).unwrap();
        for (parts, p) in [("memory", memory), ("work", work)] {
            let orders = [
                (Transport::Peer, RingOrder::Spread),
                (Transport::Host, RingOrder::Spread),
                (Transport::Peer, RingOrder::Home),
            ];
            for (transport, order) in orders {
                let layout = Layout::Ring { parts: p.parts.clone(), islands: 1, order };
                // Peer rings warmed (first sample, then cleared): the
                // reset must leave no warm-up rays in film or counters.
                let render = if transport == Transport::Peer { render_multi_warmed } else { render_multi };
                let out = render(
                    &mut gpus(ordinals),
                    &scene,
                    opts.clone(),
                    &layout,
                    Some(transport),
                    &mut |_, _| {},
                )
                .unwrap();
                failures.extend(
                    same_image(
                        &reference,
                        &out.film,
                        &format!("{name} ring ({parts}, {transport:?}, {order:?})"),
                    )
                    .err(),
                );
                assert!(out.devices.iter().all(|d| d.bytes_sent > 0));
                for d in &out.devices {
                    // Stages timed on the GPU: within the frame (its last
                    // kernels may end just after the host's clock stops).
                    let busy = d.stats.busy_seconds;
                    if !(busy > 0.0 && busy <= out.render_seconds * 1.1 + 0.01) {
                        failures.push(format!(
                            "{name} ring ({parts}, {transport:?}, {order:?}): {} busy {busy:.4} s of {:.4} s",
                            d.name, out.render_seconds
                        ));
                    }
                    if d.stats.rays_traced != single.device.rays_traced {
                        failures.push(format!(
                            "{name} ring ({parts}, {transport:?}, {order:?}): {} traced {} path rays, one device {}",
                            d.name, d.stats.rays_traced, single.device.rays_traced
                        ));
                    }
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Devices on two parts of GPU 0 (green contexts: multiprocessors apart,
/// memory shared, standing in for two GPUs): replicate and both ring
/// orders render the one-device image, and each part has its share of the
/// multiprocessors.
#[test]
fn replicate_and_ring_on_two_gpu_parts_are_one_gpu() {
    if two_devices_or_skip("replicate_and_ring_on_two_gpu_parts_are_one_gpu").is_none() {
        return;
    }
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
    for (name, scene) in scenes() {
        let opts = options(&scene);
        let mut reference =
            render(&mut CudaDevice::new(0).unwrap(), &scene, opts.clone(), &mut |_, _| {}).unwrap().film;
        reference.spp = opts.spp;
        let mut devices = parts();
        for d in devices.iter_mut() {
            let gpu = d.as_any_mut().downcast_mut::<CudaDevice>().unwrap().gpu().clone();
            assert!(gpu.multiprocessors * 2 <= whole && gpu.multiprocessors * 4 > whole, "{}", gpu.label());
        }
        let out = render_multi(&mut devices, &scene, opts.clone(), &Layout::Replicate, None, &mut |_, _| {})
            .unwrap();
        failures.extend(same_image(&reference, &out.film, &format!("{name} replicate on parts")).err());
        let p = partition(&scene, 2, &atoll_cuda::scene::byte_model(), &PartitionOptions::default()).unwrap();
        for order in [RingOrder::Spread, RingOrder::Home] {
            let layout = Layout::Ring { parts: p.parts.clone(), islands: 1, order };
            let out =
                render_multi(&mut parts(), &scene, opts.clone(), &layout, None, &mut |_, _| {}).unwrap();
            failures.extend(
                same_image(&reference, &out.film, &format!("{name} ring on parts ({order:?})")).err(),
            );
            assert!(out.devices.iter().all(|d| d.bytes_sent > 0));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
