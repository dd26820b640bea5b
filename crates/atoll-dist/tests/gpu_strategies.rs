//! Two GPUs render the same image as one: replicate, ring with peer copies
//! and ring through the host. Skipped (with a message) on machines with
//! fewer than two GPUs, unless `ATOLL_REQUIRE_GPUS=2` asks for them.

use std::sync::Arc;

use atoll_cuda::CudaDevice;
use atoll_dist::{partition, render_multi, Layout, PartitionOptions, Transport};
use atoll_render::{render, Device, Film, RenderOptions};
use atoll_scene::{IntegratorSettings, Scene};
use glam::UVec2;

fn two_gpus_or_skip(test: &str) -> bool {
    let count = atoll_cuda::device_count().unwrap_or(0);
    if count >= 2 {
        return true;
    }
    if std::env::var("ATOLL_REQUIRE_GPUS").is_ok_and(|v| v.parse::<usize>().unwrap_or(0) >= 2) {
        panic!("{test}: ATOLL_REQUIRE_GPUS=2 but {count} GPUs found");
    }
    eprintln!("{test}: skipped, {count} GPU(s) (needs 2)");
    false
}

fn gpus() -> Vec<Box<dyn Device>> {
    (0..2).map(|i| Box::new(CudaDevice::new(i).unwrap()) as Box<dyn Device>).collect()
}

fn options(scene: &Scene) -> RenderOptions {
    let mut o = RenderOptions::from_scene(scene);
    o.resolution = UVec2::new(128, 128);
    o.spp = 8;
    o.integrator = IntegratorSettings::Path { max_depth: 8 };
    o
}

/// Per-pixel relative error within 1e-3 except for rare hit ties, equal means.
fn assert_same_image(a: &Film, b: &Film, what: &str) {
    let (pa, pb) = (a.pixels(), b.pixels());
    let differing = pa
        .iter()
        .zip(&pb)
        .filter(|(x, y)| {
            (**x - **y).abs().max_element() > 1e-3 * x.abs().max_element().max(y.abs().max_element()) + 1e-5
        })
        .count();
    eprintln!("{what}: {differing} of {} pixels differ beyond rounding", pa.len());
    assert!(differing * 200 <= pa.len(), "{what}: {differing} of {} pixels differ", pa.len());
    let (ma, mb) = (a.mean(), b.mean());
    assert!((ma - mb).abs().max_element() <= 1e-3 * ma.max_element(), "{what}: means {ma} vs {mb}");
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
    if !two_gpus_or_skip("replicate_and_ring_on_two_gpus_are_one_gpu") {
        return;
    }
    for (name, scene) in scenes() {
        let opts = options(&scene);
        let mut one = CudaDevice::new(0).unwrap();
        let mut reference = render(&mut one, &scene, opts.clone(), &mut |_, _| {}).unwrap().film;
        reference.spp = opts.spp;
        assert!(one.error().is_none());

        let out = render_multi(&mut gpus(), &scene, opts.clone(), &Layout::Replicate, None, &mut |_, _| {})
            .unwrap();
        assert_same_image(&reference, &out.film, &format!("{name} replicate"));

        let p = partition(&scene, 2, &atoll_cuda::scene::byte_model(), &PartitionOptions::default()).unwrap();
        let layout = Layout::Ring { parts: p.parts, islands: 1 };
        for transport in [Transport::Peer, Transport::Host] {
            let out =
                render_multi(&mut gpus(), &scene, opts.clone(), &layout, Some(transport), &mut |_, _| {})
                    .unwrap();
            assert_same_image(&reference, &out.film, &format!("{name} ring ({transport:?})"));
            assert!(out.devices.iter().all(|d| d.bytes_sent > 0));
        }
    }
}
