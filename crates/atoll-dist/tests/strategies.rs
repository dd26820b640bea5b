//! Many CPU devices render the same image as one: replicate, ring (ray
//! queue cycling over scene parts, big objects split) and islands of rings.
//!
//! Random numbers depend only on (pixel, sample, dimension), so the only
//! differences allowed are float summation order (a pixel's samples may be
//! summed on different devices before the films are merged) and hit ties
//! between parts (equal distances on two devices' triangles).

use std::sync::Arc;

use atoll_bvh::{ByteModel, ScenePart};
use atoll_dist::{partition, render_multi, Layout, PartitionOptions, RingOrder};
use atoll_render::{render, CpuDevice, Device, Film, RenderOptions};
use atoll_scene::Scene;
use glam::UVec2;

fn options(scene: &Scene, spp: u32) -> RenderOptions {
    let mut o = RenderOptions::from_scene(scene);
    o.resolution = UVec2::new(40, 40);
    o.spp = spp;
    o
}

fn single(scene: &Arc<Scene>, options: &RenderOptions) -> Film {
    let mut device = CpuDevice::new();
    let mut film = render(&mut device, scene, options.clone(), &mut |_, _| {}).unwrap().film;
    film.spp = options.spp;
    film
}

fn cpus(n: usize, budget: Option<u64>) -> Vec<Box<dyn Device>> {
    (0..n)
        .map(|i| {
            let mut d = CpuDevice::new().with_name(format!("cpu:{i}"));
            if let Some(b) = budget {
                d = d.with_memory_budget(b);
            }
            Box::new(d) as Box<dyn Device>
        })
        .collect()
}

/// Same image up to float rounding: every pixel within a relative 1e-4
/// (absolute 1e-6 near black) except hit-tie pixels, which must be rare.
fn assert_same_image(a: &Film, b: &Film, what: &str) {
    let (pa, pb) = (a.pixels(), b.pixels());
    assert_eq!(pa.len(), pb.len());
    let differing = pa
        .iter()
        .zip(&pb)
        .filter(|(x, y)| {
            ((**x - **y).abs().max_element()) > 1e-4 * x.abs().max_element().max(y.abs().max_element()) + 1e-6
        })
        .count();
    eprintln!("{what}: {differing} of {} pixels differ beyond rounding", pa.len());
    assert!(differing * 500 <= pa.len(), "{what}: {differing} of {} pixels differ", pa.len());
    let (ma, mb) = (a.mean(), b.mean());
    assert!((ma - mb).abs().max_element() <= 1e-3 * ma.max_element(), "{what}: means {ma} vs {mb}");
    assert!(ma.max_element() > 0.0, "{what}: a black image proves nothing");
}

/// The Cornell box and a few extra objects: several objects and meshes to
/// spread over parts, an area light that must be sampled from every part.
fn scene() -> Arc<Scene> {
    Arc::new(atoll_scene::cornell::builtin_cornell_box())
}

#[test]
fn replicate_on_three_devices_is_one_device() {
    let scene = scene();
    let opts = options(&scene, 4);
    let reference = single(&scene, &opts);
    let mut devices = cpus(3, None);
    let out = render_multi(&mut devices, &scene, opts, &Layout::Replicate, None, &mut |_, _| {}).unwrap();
    assert_same_image(&reference, &out.film, "replicate");
    // Every device took a share of the waves, and together all of them.
    let waves: usize = out.devices.iter().map(|d| d.waves).sum();
    assert_eq!(waves, atoll_dist::render::work_units(&options(&scene, 4), 3).len());
    assert!(out.devices.iter().all(|d| d.bytes_sent == 0), "replicas exchange no rays");
}

#[test]
fn ring_of_three_parts_is_one_device() {
    let scene = scene();
    let opts = options(&scene, 4);
    let reference = single(&scene, &opts);
    let p = partition(&scene, 3, &ByteModel::CPU, &PartitionOptions::default()).unwrap();
    assert!(p.parts.iter().all(|part| !part.instances.is_empty()), "every device holds something");
    let budget = *p.bytes.iter().max().unwrap();
    let whole = atoll_bvh::part_bytes(&scene, &ScenePart::whole(&scene), &ByteModel::CPU);
    assert!(budget < whole, "the parts are smaller than the scene");
    // Budgets below the whole scene: a device could not hold it alone.
    let mut devices = cpus(3, Some(budget));
    assert!(devices[0]
        .prepare(
            &scene,
            &ScenePart::whole(&scene),
            &Arc::new(atoll_render::FrameContext::new(&scene, opts.clone()))
        )
        .is_err());
    let layout = Layout::Ring { parts: p.parts.clone(), islands: 1, order: RingOrder::Spread };
    // Queues of 500 paths: waves end mid-image, so merging has work to merge.
    for merge in [true, false] {
        let opts = RenderOptions { merge_waves: merge, wave_size: 500, ..opts.clone() };
        let out = render_multi(&mut devices, &scene, opts, &layout, None, &mut |_, _| {}).unwrap();
        assert_same_image(&reference, &out.film, &format!("ring of 3 (merging {merge})"));
        for d in &out.devices {
            assert!(d.bytes_sent > 0, "{}: queues cycle", d.name);
            assert!(d.prepare.scene_bytes <= budget);
        }
    }
}

#[test]
fn islands_of_two_rings_of_two_are_one_device() {
    let scene = scene();
    let opts = options(&scene, 6);
    let reference = single(&scene, &opts);
    let p = partition(&scene, 2, &ByteModel::CPU, &PartitionOptions::default()).unwrap();
    let layout = Layout::Ring { parts: p.parts, islands: 2, order: RingOrder::Spread };
    let mut devices = cpus(4, None);
    let out = render_multi(&mut devices, &scene, opts, &layout, None, &mut |_, _| {}).unwrap();
    assert_same_image(&reference, &out.film, "2 islands of 2");
    // Both islands generated pixels.
    let per_island = |i: usize| out.devices.iter().filter(|d| d.island == i).map(|d| d.waves).sum::<usize>();
    assert!(per_island(0) > 0 && per_island(1) > 0);
}

/// A ground mesh heavier than any device's budget, split by triangle
/// ranges over the parts, plus boxes standing on it, lit by the sky and sun.
fn ground_scene() -> Arc<Scene> {
    let mut scene = atoll_scene::procedural::bench_scene(20_000);
    atoll_scene::framing::frame_scene(&mut scene, false);
    Arc::new(scene)
}

#[test]
fn a_ground_object_too_big_for_one_device_is_split() {
    let scene = ground_scene();
    let opts = options(&scene, 2);
    let reference = single(&scene, &opts);
    let model = ByteModel::CPU;
    let whole = atoll_bvh::part_bytes(&scene, &ScenePart::whole(&scene), &model);
    let budget = whole * 2 / 5;
    let p = partition(&scene, 3, &model, &PartitionOptions { budget: Some(budget), ..Default::default() })
        .unwrap();
    assert!(p.parts.iter().any(|part| !part.object_subsets.is_empty()), "an object was split");
    let mut devices = cpus(3, Some(budget));
    let layout = Layout::Ring { parts: p.parts, islands: 1, order: RingOrder::Spread };
    let out = render_multi(&mut devices, &scene, opts, &layout, None, &mut |_, _| {}).unwrap();
    assert_same_image(&reference, &out.film, "ring with a split ground");
}

#[test]
fn a_ring_over_spatial_slabs_is_one_device() {
    let scene = ground_scene();
    let opts = options(&scene, 2);
    let reference = single(&scene, &opts);
    let p = atoll_dist::spatial::partition_spatial(&scene, 3, &ByteModel::CPU, &PartitionOptions::default())
        .unwrap();
    let layout = Layout::Ring { parts: p.parts, islands: 1, order: RingOrder::Spread };
    let out = render_multi(&mut cpus(3, None), &scene, opts, &layout, None, &mut |_, _| {}).unwrap();
    assert_same_image(&reference, &out.film, "ring over spatial slabs");
}

/// The default ring partition: chunks balanced by bytes and by where the
/// camera's rays will work; interleaved, the ground is cut into many
/// triangle runs per part.
#[test]
fn a_ring_over_work_balanced_chunks_is_one_device() {
    let scene = ground_scene();
    let opts = options(&scene, 2);
    let reference = single(&scene, &opts);
    let p = atoll_dist::work::partition_work_balanced(
        &scene,
        3,
        opts.resolution,
        &ByteModel::CPU,
        &PartitionOptions::default(),
    )
    .unwrap();
    let ground_runs: usize =
        p.parts.iter().flat_map(|part| &part.object_subsets).filter(|s| s.0 == 0).map(|s| s.1.len()).sum();
    assert!(ground_runs > 3, "the ground is cut into {ground_runs} runs");
    let layout = Layout::Ring { parts: p.parts, islands: 1, order: RingOrder::Spread };
    let out = render_multi(&mut cpus(3, None), &scene, opts, &layout, None, &mut |_, _| {}).unwrap();
    assert_same_image(&reference, &out.film, "ring over work-balanced chunks");
}

/// Textures and alpha masks on a ring: the striped screen (alpha cut-outs,
/// a textured mix) and the checkerboard ground split over two devices; the
/// cut-out test runs on whichever part holds the screen, closest hits and
/// shadow rays alike, and the image equals one device's.
#[test]
fn a_ring_over_textured_and_alpha_masked_parts_is_one_device() {
    use atoll_scene::texture_scenes::{cutout_scene, Screen};
    for eye in [glam::Vec3::new(0.0, 0.0, 3.0), glam::Vec3::new(0.0, 0.0, 0.6)] {
        let scene = Arc::new(cutout_scene(Screen::AlphaMask, eye));
        let opts = options(&scene, 4);
        let reference = single(&scene, &opts);
        let p = partition(&scene, 2, &ByteModel::CPU, &PartitionOptions::default()).unwrap();
        assert!(p.parts.iter().all(|part| !part.instances.is_empty() || !part.object_subsets.is_empty()));
        let mut devices = cpus(2, None);
        let layout = Layout::Ring { parts: p.parts.clone(), islands: 1, order: RingOrder::Spread };
        let out = render_multi(&mut devices, &scene, opts, &layout, None, &mut |_, _| {}).unwrap();
        assert_same_image(&reference, &out.film, &format!("textured ring from {eye}"));
    }
}

/// A warmed frame (the first sample rendered untimed on the prepared
/// devices, then cleared) is the cold frame: same image, same ray counts,
/// and no ray of the warm-up left in the counters or the bytes sent.
#[test]
fn warmed_ring_renders_the_cold_frame() {
    let scene = scene();
    let opts = RenderOptions { wave_size: 500, ..options(&scene, 3) };
    let p = partition(&scene, 2, &ByteModel::CPU, &PartitionOptions::default()).unwrap();
    let layout = Layout::Ring { parts: p.parts, islands: 1, order: RingOrder::Spread };
    let cold = render_multi(&mut cpus(2, None), &scene, opts.clone(), &layout, None, &mut |_, _| {}).unwrap();
    let mut progress = 0;
    let warm =
        atoll_dist::render_multi_warmed(&mut cpus(2, None), &scene, opts, &layout, None, &mut |done, _| {
            progress = done
        })
        .unwrap();
    assert_same_image(&cold.film, &warm.film, "warmed ring");
    assert_eq!(warm.film.spp, cold.film.spp);
    assert_eq!(
        progress,
        warm.devices.iter().map(|d| d.waves).sum::<usize>(),
        "progress counts the timed frame"
    );
    // Every ray visits every member; which member generates (and so
    // sends) a wave depends on timing, so bytes are compared in all.
    for (c, w) in cold.devices.iter().zip(&warm.devices) {
        assert_eq!(c.stats.rays_traced, w.stats.rays_traced, "{}", c.name);
        assert_eq!(c.stats.shadow_rays_traced, w.stats.shadow_rays_traced, "{}", c.name);
    }
    let one = render(
        &mut CpuDevice::new(),
        &scene,
        RenderOptions { wave_size: 500, ..options(&scene, 3) },
        &mut |_, _| {},
    )
    .unwrap();
    assert!(
        warm.devices.iter().all(|d| d.stats.rays_traced == one.device.rays_traced),
        "every member traces every path ray"
    );
    let sent = |out: &atoll_dist::MultiOutput| out.devices.iter().map(|d| d.bytes_sent).sum::<u64>();
    assert_eq!(sent(&cold), sent(&warm));
}

/// With [`RingOrder::Home`] member 0 makes and shades every queue (every
/// ray is traced there first): the same image, every wave taken by member
/// 0, every ray on every member, and every record sent K times per cycle
/// (round the ring and home) against K − 1.
#[test]
fn a_ring_with_one_home_renders_the_same_image() {
    let scene = scene();
    let opts = RenderOptions { wave_size: 500, ..options(&scene, 3) };
    let reference = single(&scene, &opts);
    for k in [2, 3] {
        let p = partition(&scene, k, &ByteModel::CPU, &PartitionOptions::default()).unwrap();
        let ring = |order| {
            let layout = Layout::Ring { parts: p.parts.clone(), islands: 1, order };
            render_multi(&mut cpus(k, None), &scene, opts.clone(), &layout, None, &mut |_, _| {}).unwrap()
        };
        let (spread, home) = (ring(RingOrder::Spread), ring(RingOrder::Home));
        assert_same_image(&reference, &home.film, &format!("ring of {k} with one home"));
        assert!(home.devices[0].waves > 0, "member 0 takes the waves");
        assert!(home.devices[1..].iter().all(|d| d.waves == 0), "only member 0 takes waves");
        let sent = |out: &atoll_dist::MultiOutput| out.devices.iter().map(|d| d.bytes_sent).sum::<u64>();
        assert_eq!(sent(&home) * (k as u64 - 1), sent(&spread) * k as u64, "ring of {k}");
        for d in &home.devices {
            let rays = spread.devices[0].stats.rays_traced;
            assert_eq!(d.stats.rays_traced, rays, "{}: every ray on every member", d.name);
        }
    }
}

/// A ring of 3 over parts balanced by bytes and instances renders the
/// one-device image.
#[test]
fn ring_over_instance_cost_parts_is_one_device() {
    let scene = scene();
    let opts = options(&scene, 3);
    let reference = single(&scene, &opts);
    let costed =
        PartitionOptions { instance_cost: atoll_dist::partition::GPU_INSTANCE_COST, ..Default::default() };
    let p = partition(&scene, 3, &ByteModel::CPU, &costed).unwrap();
    let layout = Layout::Ring { parts: p.parts, islands: 1, order: RingOrder::Spread };
    let out = render_multi(&mut cpus(3, None), &scene, opts, &layout, None, &mut |_, _| {}).unwrap();
    assert_same_image(&reference, &out.film, "ring over instance-cost parts");
}
