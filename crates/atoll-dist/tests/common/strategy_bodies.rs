//! The strategy tests, written once for every device kind: many devices
//! render the same image as one (replicate, rings over every kind of
//! partition, islands of rings, both ring orders and both transports,
//! warmed frames). `strategy_tests!` makes a `#[test]` of each body for
//! one [`Kind`]: `atoll-dist/tests/strategies.rs` for CPU devices (run in
//! CI) and `atoll/tests/gpu_strategies.rs` for CUDA devices (ignored
//! without `--include-ignored`, which `scripts/gpu-check` passes). Kept
//! out of `atoll-dist`'s dependencies, the CUDA crate is named only by the
//! file that includes this one for GPUs.
//!
//! Random numbers depend only on (pixel, sample, dimension), so the only
//! differences allowed are float summation order (a pixel's samples may be
//! summed on different devices before the films are merged) and hit ties
//! between parts (equal distances on two devices' triangles).

use std::sync::Arc;

use atoll_bvh::{ByteModel, ScenePart};
use atoll_dist::chunk_placement::Replication;
use atoll_dist::work::{partition_work_balanced, partition_work_measured};
use atoll_dist::{
    partition, render_multi, render_multi_warmed, Layout, MultiOutput, PartitionOptions, RingOrder, Session,
    SharedSpec, Transport,
};
use atoll_render::device::DeviceStats;
use atoll_render::{render, Device, Film, RenderOptions};
use atoll_scene::{IntegratorSettings, Scene};
use glam::UVec2;

/// How far one kind's multi-device images may stray from its one-device
/// image: a pixel differs when beyond `relative` of its brightest channel
/// plus `absolute`; at most one pixel in `one_in` may differ (hit ties).
pub struct Tolerance {
    pub relative: f32,
    pub absolute: f32,
    pub one_in: usize,
}

/// One device kind under test.
pub struct Kind {
    /// `n` fresh devices of this kind, for one render.
    pub devices: fn(usize) -> Vec<Box<dyn Device>>,
    /// Every test's image size: a GPU's frame should span several of its
    /// (larger) waves, a debug-built CPU's stay quick.
    pub resolution: UVec2,
    pub tolerance: Tolerance,
    /// Whether a memory budget of a part's bytes (the byte model's charge)
    /// holds that part and not the whole scene: a CPU device's budget
    /// counts scene bytes alone, a GPU's its queues, film and headroom too,
    /// so only the CPU's can be checked against a partition's bytes.
    pub part_budgets: bool,
    /// Chunk size of shared scenes: at least what the device kind maps at once.
    pub shared_chunk: u64,
    /// Growth of the landscape the shared-scene tests render: enough
    /// chunks of `shared_chunk` to spread.
    pub shared_growth: u32,
    /// How many devices of this kind hold memory of their own (GPUs on the
    /// machine; CPU devices: any number). Devices beyond share it.
    pub distinct_memories: fn() -> usize,
}

/// Runs each body once, for `$kind` (an expression making a [`Kind`]),
/// as a `#[test]` of the body's name; attributes after it (an `#[ignore]`)
/// go on every test. The file including this one names it
/// `strategy_bodies` at its crate root.
macro_rules! strategy_tests {
    ($kind:expr $(, #[$attr:meta])* $(,)?) => {
        $crate::strategy_bodies::strategy_tests!(@each [$(#[$attr])*] $kind;
            replicate_is_one_device
            ring_of_three_parts_is_one_device
            ring_transports_and_orders_are_one_device
            islands_of_two_rings_of_two_are_one_device
            a_ground_object_too_big_for_one_device_is_split
            a_ring_over_spatial_slabs_is_one_device
            a_ring_over_work_balanced_chunks_is_one_device
            a_ring_over_textured_and_alpha_masked_parts_is_one_device
            warmed_ring_renders_the_cold_frame
            a_ring_with_one_home_renders_the_same_image
            ring_over_instance_cost_parts_is_one_device
            passes_of_a_session_add_up_to_one_frame
            media_on_rings_and_replicas_are_one_device
            curves_on_rings_and_replicas_are_one_device
            moving_instances_on_rings_and_replicas_are_one_device
        );
    };
    // The attributes travel as one token tree: a list repeated inside the
    // bodies' repetition would have to repeat as often as it.
    (@each $attrs:tt $kind:expr; $($body:ident)*) => {
        $($crate::strategy_bodies::strategy_tests!(@one $attrs $kind; $body);)*
    };
    (@one [$(#[$attr:meta])*] $kind:expr; $body:ident) => {
        #[test]
        $(#[$attr])*
        fn $body() {
            $crate::strategy_bodies::$body(&$kind);
        }
    };
}
pub(crate) use strategy_tests;

/// As [`strategy_tests!`], for the shared strategy's bodies: device kinds
/// that can share a scene's memory ([`Device::scene_sharing`]) run them.
macro_rules! shared_strategy_tests {
    ($kind:expr $(, #[$attr:meta])* $(,)?) => {
        $crate::strategy_bodies::strategy_tests!(@each [$(#[$attr])*] $kind;
            shared_memory_is_one_device
            shared_memory_with_a_host_tier_is_one_device
            replicated_fractions_are_one_device
        );
    };
}
pub(crate) use shared_strategy_tests;

impl Kind {
    /// What scene parts cost this kind's devices.
    pub fn byte_model(&self) -> ByteModel {
        (self.devices)(1)[0].byte_model()
    }

    pub fn options(&self, scene: &Scene, spp: u32) -> RenderOptions {
        let mut o = RenderOptions::from_scene(scene);
        o.resolution = self.resolution;
        o.spp = spp;
        o
    }

    /// One device's image (its `spp` set, as a merged film's is) and
    /// counters (a failed stage fails the render).
    pub fn single(&self, scene: &Arc<Scene>, options: &RenderOptions) -> (Film, DeviceStats) {
        let mut device = (self.devices)(1).pop().unwrap();
        let out = render(device.as_mut(), scene, options.clone(), &mut |_, _| {})
            .unwrap_or_else(|e| panic!("{}: {e}", device.name()));
        let mut film = out.film;
        film.spp = options.spp;
        (film, out.device)
    }

    fn render(
        &self,
        n: usize,
        scene: &Arc<Scene>,
        options: &RenderOptions,
        layout: &Layout,
        transport: Option<Transport>,
    ) -> MultiOutput {
        render_multi(&mut (self.devices)(n), scene, options.clone(), layout, transport, &mut |_, _| {})
            .unwrap()
    }

    /// Same image up to float rounding; `Err` says how they differ.
    pub fn same_image(&self, a: &Film, b: &Film, what: &str) -> Result<(), String> {
        let Tolerance { relative, absolute, one_in } = self.tolerance;
        let (pa, pb) = (a.pixels(), b.pixels());
        assert_eq!(pa.len(), pb.len(), "{what}");
        let differing = pa
            .iter()
            .zip(&pb)
            .filter(|(x, y)| {
                (**x - **y).abs().max_element()
                    > relative * x.abs().max_element().max(y.abs().max_element()) + absolute
            })
            .count();
        eprintln!("{what}: {differing} of {} pixels differ beyond rounding", pa.len());
        let (ma, mb) = (a.mean(), b.mean());
        if differing * one_in > pa.len() || (ma - mb).abs().max_element() > 1e-3 * ma.max_element() {
            return Err(format!("{what}: {differing} of {} pixels differ, means {ma} vs {mb}", pa.len()));
        }
        if ma.max_element() <= 0.0 {
            return Err(format!("{what}: a black image proves nothing"));
        }
        Ok(())
    }

    pub fn assert_same_image(&self, a: &Film, b: &Film, what: &str) {
        if let Err(e) = self.same_image(a, b, what) {
            panic!("{e}");
        }
    }
}

/// The direct transport where every device offers one (GPU peer copies),
/// else through the host: rings of either kind run the same bodies.
fn direct_or_host(devices: &[Box<dyn Device>]) -> Transport {
    if devices.iter().all(|d| d.direct_transport().is_some()) {
        Transport::Peer
    } else {
        Transport::Host
    }
}

/// The Cornell box and a few extra objects: several objects and meshes to
/// spread over parts, an area light that must be sampled from every part.
pub fn cornell() -> Arc<Scene> {
    Arc::new(atoll_scene::cornell::builtin_cornell_box())
}

/// The Cornell box and a small generated landscape (instancing, glass,
/// metal, sun and sky).
pub fn scenes() -> Vec<(&'static str, Arc<Scene>)> {
    let mut landscape = atoll_scene::landscape::Landscape::new(1).build();
    landscape.settings.film.resolution = UVec2::new(128, 72);
    vec![("cornell", cornell()), ("landscape:1", Arc::new(landscape))]
}

/// A ground mesh heavier than any device's budget, split by triangle
/// ranges over the parts, plus boxes standing on it, lit by the sky and sun.
pub fn ground_scene() -> Arc<Scene> {
    let mut scene = atoll_scene::procedural::bench_scene(20_000);
    atoll_scene::framing::frame_scene(&mut scene, false);
    Arc::new(scene)
}

fn bytes_sent(out: &MultiOutput) -> u64 {
    out.devices.iter().map(|d| d.bytes_sent).sum()
}

/// Replicas render the one-device image, sharing the waves and sending no
/// rays; replicas on one piece of hardware hold one copy of the scene.
pub fn replicate_is_one_device(kind: &Kind) {
    for (name, scene) in scenes() {
        let opts = kind.options(&scene, 4);
        let (reference, _) = kind.single(&scene, &opts);
        let mut devices = (kind.devices)(3);
        let sharing: Vec<bool> = (0..devices.len())
            .map(|d| (0..d).any(|e| devices[d].shares_memory_with(devices[e].as_ref())))
            .collect();
        let out = render_multi(&mut devices, &scene, opts.clone(), &Layout::Replicate, None, &mut |_, _| {})
            .unwrap();
        kind.assert_same_image(&reference, &out.film, &format!("{name} replicate"));
        // Every device took a share of the waves, and together all of them.
        let waves: usize = out.devices.iter().map(|d| d.waves).sum();
        assert_eq!(waves, atoll_dist::render::work_units(&opts, 3).len(), "{name}");
        assert!(out.devices.iter().all(|d| d.bytes_sent == 0), "{name}: replicas exchange no rays");
        let held: Vec<u64> = out.devices.iter().map(|d| d.prepare.scene_bytes).collect();
        for (d, &shares) in sharing.iter().enumerate() {
            assert_eq!(held[d] == 0, shares, "{name}: scene bytes per replica {held:?}, sharing {sharing:?}");
        }
    }
}

pub fn ring_of_three_parts_is_one_device(kind: &Kind) {
    let scene = cornell();
    let opts = kind.options(&scene, 4);
    let (reference, _) = kind.single(&scene, &opts);
    let mut devices = (kind.devices)(3);
    let model = devices[0].byte_model();
    let p = partition(&scene, 3, &model, &PartitionOptions::default()).unwrap();
    assert!(p.parts.iter().all(|part| !part.instances.is_empty()), "every device holds something");
    let budget = *p.bytes.iter().max().unwrap();
    let whole = atoll_bvh::part_bytes(&scene, &ScenePart::whole(&scene), &model);
    assert!(budget < whole, "the parts are smaller than the scene");
    if kind.part_budgets {
        // Budgets below the whole scene: a device could not hold it alone.
        for d in devices.iter_mut() {
            d.set_memory_budget(Some(budget));
        }
        let frame = Arc::new(atoll_render::FrameContext::new(&scene, opts.clone()));
        assert!(devices[0].prepare(&scene, &ScenePart::whole(&scene), &frame).is_err());
    }
    let layout = Layout::Ring { parts: p.parts.clone(), islands: 1, order: RingOrder::Spread };
    // Queues of 500 paths: waves end mid-image, so merging has work to merge.
    for merge in [true, false] {
        let opts = RenderOptions { merge_waves: merge, wave_size: 500, ..opts.clone() };
        let out = render_multi(&mut devices, &scene, opts, &layout, None, &mut |_, _| {}).unwrap();
        kind.assert_same_image(&reference, &out.film, &format!("ring of 3 (merging {merge})"));
        for d in &out.devices {
            assert!(d.bytes_sent > 0, "{}: queues cycle", d.name);
            assert!(!kind.part_budgets || d.prepare.scene_bytes <= budget, "{}: over its budget", d.name);
        }
    }
}

/// Rings of two over memory-balanced parts and over work-balanced chunks,
/// queues moving directly (where the devices can; through the host
/// otherwise) and through the host, spread and with one home: the
/// one-device image, every member tracing every path ray, busy within the
/// frame.
pub fn ring_transports_and_orders_are_one_device(kind: &Kind) {
    // Every combination runs before the test fails: which ones differ says
    // more than the first.
    let mut failures = Vec::new();
    for (name, scene) in scenes() {
        let opts = RenderOptions {
            integrator: IntegratorSettings::Path { max_depth: 8 },
            ..kind.options(&scene, 8)
        };
        let (reference, single) = kind.single(&scene, &opts);
        let model = kind.byte_model();
        let none = PartitionOptions::default();
        let memory = partition(&scene, 2, &model, &none).unwrap();
        let work = partition_work_balanced(&scene, 2, opts.resolution, &model, &none).unwrap();
        for (parts, p) in [("memory", memory), ("work", work)] {
            for (direct, order) in
                [(true, RingOrder::Spread), (false, RingOrder::Spread), (true, RingOrder::Home)]
            {
                let layout = Layout::Ring { parts: p.parts.clone(), islands: 1, order };
                let mut devices = (kind.devices)(2);
                let transport = if direct { direct_or_host(&devices) } else { Transport::Host };
                // Direct rings warmed (first sample, then cleared): the
                // reset must leave no warm-up rays in film or counters.
                let render = if direct { render_multi_warmed } else { render_multi };
                let out =
                    render(&mut devices, &scene, opts.clone(), &layout, Some(transport), &mut |_, _| {})
                        .unwrap();
                let what = format!("{name} ring ({parts}, {transport:?}, {order:?})");
                failures.extend(kind.same_image(&reference, &out.film, &what).err());
                assert!(out.devices.iter().all(|d| d.bytes_sent > 0), "{what}: queues cycle");
                for d in &out.devices {
                    // Stages timed on the device: within the frame (a GPU's
                    // last kernels may end just after the host's clock stops).
                    let busy = d.stats.busy_seconds;
                    if !(busy > 0.0 && busy <= out.render_seconds * 1.1 + 0.01) {
                        failures.push(format!(
                            "{what}: {} busy {busy:.4} s of {:.4} s",
                            d.name, out.render_seconds
                        ));
                    }
                    if d.stats.rays_traced != single.rays_traced {
                        failures.push(format!(
                            "{what}: {} traced {} path rays, one device {}",
                            d.name, d.stats.rays_traced, single.rays_traced
                        ));
                    }
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

pub fn islands_of_two_rings_of_two_are_one_device(kind: &Kind) {
    let scene = cornell();
    let opts = kind.options(&scene, 6);
    let (reference, _) = kind.single(&scene, &opts);
    let mut devices = (kind.devices)(4);
    let p = partition(&scene, 2, &devices[0].byte_model(), &PartitionOptions::default()).unwrap();
    let layout = Layout::Ring { parts: p.parts, islands: 2, order: RingOrder::Spread };
    let out = render_multi(&mut devices, &scene, opts, &layout, None, &mut |_, _| {}).unwrap();
    kind.assert_same_image(&reference, &out.film, "2 islands of 2");
    // Both islands generated pixels.
    let per_island = |i: usize| out.devices.iter().filter(|d| d.island == i).map(|d| d.waves).sum::<usize>();
    assert!(per_island(0) > 0 && per_island(1) > 0);
}

/// An interactive view's passes (prepared once, samples rendered a few at
/// a time) add up to one frame of all their samples, replicating, on a
/// ring and sharing scene memory; after the camera moves, the films start
/// again and give the frame of the moved camera.
pub fn passes_of_a_session_add_up_to_one_frame(kind: &Kind) {
    let scene = cornell();
    let opts = kind.options(&scene, 4);
    let (reference, _) = kind.single(&scene, &opts);
    let mut moved = (*scene).clone();
    let camera = &mut moved.settings.camera;
    camera.camera_to_world = glam::Mat4::from_rotation_y(0.2) * camera.camera_to_world;
    let moved = Arc::new(moved);
    let (moved_reference, _) = kind.single(&moved, &opts);
    assert!(kind.same_image(&reference, &moved_reference, "moved").is_err(), "the camera moved");
    let rays = atoll_render::camera::CameraRays::new(&moved.settings.camera, opts.resolution);
    let p = partition(&scene, 2, &kind.byte_model(), &PartitionOptions::default()).unwrap();
    let mut layouts =
        vec![Layout::Replicate, Layout::Ring { parts: p.parts, islands: 1, order: RingOrder::Spread }];
    if on_hardware_of_their_own(kind, 2) {
        let spec = SharedSpec { chunk_bytes: kind.shared_chunk, host_tier: false, ..Default::default() };
        layouts.push(Layout::Shared(spec));
    }
    for layout in layouts {
        let mut devices = (kind.devices)(2);
        let mut session = Session::prepare(&mut devices, &scene, opts.clone(), &layout, None).unwrap();
        for count in [1, 2, 1] {
            session.render_samples(count).unwrap();
        }
        assert_eq!(session.samples(), 4);
        let what = format!("{layout:?} passes of 1, 2 and 1 samples");
        kind.assert_same_image(&reference, &session.film().unwrap(), &what);
        session.restart(Some(&rays)).unwrap();
        assert_eq!(session.samples(), 0);
        assert!(session.film().unwrap().sum.iter().all(|p| *p == glam::Vec3::ZERO), "{what}: cleared");
        for count in [3, 1] {
            session.render_samples(count).unwrap();
        }
        kind.assert_same_image(&moved_reference, &session.film().unwrap(), &format!("{what}, camera moved"));
    }
}

/// Three parts of `scene` (the ground scene) under the smallest budget
/// from 40% of the scene up that `model` can meet, and that budget. The
/// fixed costs per instance and object differ between device kinds, so the
/// tightest budget that fits does too. The ground must have been split.
pub fn split_ground_partition(scene: &Scene, model: &ByteModel) -> (atoll_dist::Partition, u64) {
    let whole = atoll_bvh::part_bytes(scene, &ScenePart::whole(scene), model);
    let (p, budget) = (40..=60)
        .step_by(5)
        .map(|percent| whole * percent / 100)
        .find_map(|budget| {
            let options = PartitionOptions { budget: Some(budget), ..Default::default() };
            partition(scene, 3, model, &options).ok().map(|p| (p, budget))
        })
        .expect("three parts of at most 60% of the scene each");
    assert!(p.parts.iter().any(|part| !part.object_subsets.is_empty()), "an object was split");
    (p, budget)
}

pub fn a_ground_object_too_big_for_one_device_is_split(kind: &Kind) {
    let scene = ground_scene();
    let opts = kind.options(&scene, 2);
    let (reference, _) = kind.single(&scene, &opts);
    let mut devices = (kind.devices)(3);
    let (p, budget) = split_ground_partition(&scene, &devices[0].byte_model());
    if kind.part_budgets {
        for d in devices.iter_mut() {
            d.set_memory_budget(Some(budget));
        }
    }
    let layout = Layout::Ring { parts: p.parts, islands: 1, order: RingOrder::Spread };
    let out = render_multi(&mut devices, &scene, opts, &layout, None, &mut |_, _| {}).unwrap();
    kind.assert_same_image(&reference, &out.film, "ring with a split ground");
}

pub fn a_ring_over_spatial_slabs_is_one_device(kind: &Kind) {
    let scene = ground_scene();
    let opts = kind.options(&scene, 2);
    let (reference, _) = kind.single(&scene, &opts);
    let model = kind.byte_model();
    let p = atoll_dist::spatial::partition_spatial(&scene, 3, &model, &PartitionOptions::default()).unwrap();
    let layout = Layout::Ring { parts: p.parts, islands: 1, order: RingOrder::Spread };
    let out = kind.render(3, &scene, &opts, &layout, None);
    kind.assert_same_image(&reference, &out.film, "ring over spatial slabs");
}

/// The default ring partition: chunks balanced by bytes and by where the
/// camera's rays will work; interleaved, the ground is cut into many
/// triangle runs per part.
pub fn a_ring_over_work_balanced_chunks_is_one_device(kind: &Kind) {
    let scene = ground_scene();
    let opts = kind.options(&scene, 2);
    let (reference, _) = kind.single(&scene, &opts);
    let model = kind.byte_model();
    let estimated =
        partition_work_balanced(&scene, 3, opts.resolution, &model, &PartitionOptions::default()).unwrap();
    let (measured, hits) =
        partition_work_measured(&scene, 3, opts.resolution, &model, &PartitionOptions::default()).unwrap();
    assert!(hits > 0, "the measuring render hit nothing");
    for (what, p) in [("estimated", estimated), ("measured", measured)] {
        let ground_runs: usize = p
            .parts
            .iter()
            .flat_map(|part| &part.object_subsets)
            .filter(|s| s.0 == 0)
            .map(|s| s.1.len())
            .sum();
        assert!(ground_runs > 3, "{what}: the ground is cut into {ground_runs} runs");
        let layout = Layout::Ring { parts: p.parts, islands: 1, order: RingOrder::Spread };
        let out = kind.render(3, &scene, &opts, &layout, None);
        kind.assert_same_image(&reference, &out.film, &format!("ring over {what}-work chunks"));
    }
}

/// Textures and alpha masks on a ring: the striped screen (alpha cut-outs,
/// a textured mix) and the checkerboard ground split over two devices; the
/// cut-out test runs on whichever part holds the screen, closest hits and
/// shadow rays alike, and the image equals one device's.
pub fn a_ring_over_textured_and_alpha_masked_parts_is_one_device(kind: &Kind) {
    use atoll_scene::texture_scenes::{cutout_scene, Screen};
    for eye in [glam::Vec3::new(0.0, 0.0, 3.0), glam::Vec3::new(0.0, 0.0, 0.6)] {
        let scene = Arc::new(cutout_scene(Screen::AlphaMask, eye));
        let opts = kind.options(&scene, 4);
        let (reference, _) = kind.single(&scene, &opts);
        let model = kind.byte_model();
        let p = partition(&scene, 2, &model, &PartitionOptions::default()).unwrap();
        assert!(p.parts.iter().all(|part| !part.instances.is_empty() || !part.object_subsets.is_empty()));
        let layout = Layout::Ring { parts: p.parts.clone(), islands: 1, order: RingOrder::Spread };
        let out = kind.render(2, &scene, &opts, &layout, None);
        kind.assert_same_image(&reference, &out.film, &format!("textured ring from {eye}"));
    }
}

/// `scenes/media.pbrt`: fog the camera sits in, a sphere bounding
/// scattering ink, glass holding a tint. Replicas and a ring of three
/// render one device's image: shadow rays gather their optical depth on
/// every member (boundaries of media are on different parts), and paths
/// keep their medium across the hand-overs.
pub fn media_on_rings_and_replicas_are_one_device(kind: &Kind) {
    // Beside the sources where they are, else from the repository root
    // (test binaries run elsewhere, as on the GPU machine).
    let beside = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/media.pbrt");
    let path = if beside.exists() { beside } else { "scenes/media.pbrt".into() };
    let scene = Arc::new(atoll_scene::load_any(&path).unwrap().scene);
    assert!(scene.media.len() == 4 && scene.meshes.iter().filter(|m| m.media.is_some()).count() == 3);
    let opts = kind.options(&scene, 4);
    let (reference, _) = kind.single(&scene, &opts);
    let out = kind.render(2, &scene, &opts, &Layout::Replicate, None);
    kind.assert_same_image(&reference, &out.film, "media, replicate");
    let p = partition(&scene, 3, &kind.byte_model(), &PartitionOptions::default()).unwrap();
    let layout = Layout::Ring { parts: p.parts, islands: 1, order: RingOrder::Spread };
    let out = kind.render(3, &scene, &opts, &layout, None);
    kind.assert_same_image(&reference, &out.film, "media, ring of 3");
}

/// `scenes/<name>` of the repository, loaded.
fn repository_scene(name: &str) -> Arc<Scene> {
    let beside = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes").join(name);
    let path = if beside.exists() { beside } else { std::path::Path::new("scenes").join(name) };
    Arc::new(atoll_scene::load_any(&path).unwrap().scene)
}

/// Replicas and a ring of two render one device's image of `scene`.
fn replicas_and_a_ring_of_two_are_one_device(kind: &Kind, scene: &Arc<Scene>, what: &str) {
    let opts = kind.options(scene, 4);
    let (reference, _) = kind.single(scene, &opts);
    let out = kind.render(2, scene, &opts, &Layout::Replicate, None);
    kind.assert_same_image(&reference, &out.film, &format!("{what}, replicate"));
    let p = partition(scene, 2, &kind.byte_model(), &PartitionOptions::default()).unwrap();
    assert!(p.parts.iter().all(|part| !part.instances.is_empty() || !part.object_subsets.is_empty()));
    let layout = Layout::Ring { parts: p.parts, islands: 1, order: RingOrder::Spread };
    let out = kind.render(2, scene, &opts, &layout, None);
    kind.assert_same_image(&reference, &out.film, &format!("{what}, ring of 2"));
}

/// `scenes/hair.pbrt`: curve pieces under the hair material. Curves are
/// cut between parts by their proxy triangles like any mesh, and each
/// part's curve hits travel with their shading data.
pub fn curves_on_rings_and_replicas_are_one_device(kind: &Kind) {
    let scene = repository_scene("hair.pbrt");
    assert!(scene.meshes.iter().filter(|m| m.curves.is_some()).count() > 100);
    replicas_and_a_ring_of_two_are_one_device(kind, &scene, "curves");
}

/// `scenes/motion.pbrt`: moving shapes and instances. Every member sees
/// each path at the same time of the shutter, and a part's moving
/// instances are bounded over their motion.
pub fn moving_instances_on_rings_and_replicas_are_one_device(kind: &Kind) {
    let scene = repository_scene("motion.pbrt");
    assert!(scene.motions.len() >= 3);
    replicas_and_a_ring_of_two_are_one_device(kind, &scene, "motion blur");
}

/// A warmed frame (the first sample rendered untimed on the prepared
/// devices, then cleared) is the cold frame: same image, same ray counts,
/// and no ray of the warm-up left in the counters or the bytes sent.
pub fn warmed_ring_renders_the_cold_frame(kind: &Kind) {
    let scene = cornell();
    let opts = RenderOptions { wave_size: 500, ..kind.options(&scene, 3) };
    let model = kind.byte_model();
    let p = partition(&scene, 2, &model, &PartitionOptions::default()).unwrap();
    let layout = Layout::Ring { parts: p.parts, islands: 1, order: RingOrder::Spread };
    let cold = kind.render(2, &scene, &opts, &layout, None);
    let mut progress = 0;
    let warm =
        render_multi_warmed(&mut (kind.devices)(2), &scene, opts.clone(), &layout, None, &mut |done, _| {
            progress = done
        })
        .unwrap();
    kind.assert_same_image(&cold.film, &warm.film, "warmed ring");
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
    let (_, one) = kind.single(&scene, &opts);
    assert!(
        warm.devices.iter().all(|d| d.stats.rays_traced == one.rays_traced),
        "every member traces every path ray"
    );
    assert_eq!(bytes_sent(&cold), bytes_sent(&warm));
}

/// With [`RingOrder::Home`] member 0 makes and shades every queue (every
/// ray is traced there first): the same image, every wave taken by member
/// 0, every ray on every member, and every record sent K times per cycle
/// (round the ring and home) against K − 1.
pub fn a_ring_with_one_home_renders_the_same_image(kind: &Kind) {
    let scene = cornell();
    let opts = RenderOptions { wave_size: 500, ..kind.options(&scene, 3) };
    let (reference, _) = kind.single(&scene, &opts);
    let model = kind.byte_model();
    for k in [2, 3] {
        let p = partition(&scene, k, &model, &PartitionOptions::default()).unwrap();
        let ring = |order| {
            let layout = Layout::Ring { parts: p.parts.clone(), islands: 1, order };
            kind.render(k, &scene, &opts, &layout, None)
        };
        let (spread, home) = (ring(RingOrder::Spread), ring(RingOrder::Home));
        kind.assert_same_image(&reference, &home.film, &format!("ring of {k} with one home"));
        assert!(home.devices[0].waves > 0, "member 0 takes the waves");
        assert!(home.devices[1..].iter().all(|d| d.waves == 0), "only member 0 takes waves");
        assert_eq!(bytes_sent(&home) * (k as u64 - 1), bytes_sent(&spread) * k as u64, "ring of {k}");
        for d in &home.devices {
            let rays = spread.devices[0].stats.rays_traced;
            assert_eq!(d.stats.rays_traced, rays, "{}: every ray on every member", d.name);
        }
    }
}

/// A ring of 3 over parts balanced by bytes and instances renders the
/// one-device image.
pub fn ring_over_instance_cost_parts_is_one_device(kind: &Kind) {
    let scene = cornell();
    let opts = kind.options(&scene, 3);
    let (reference, _) = kind.single(&scene, &opts);
    let model = kind.byte_model();
    let costed =
        PartitionOptions { instance_cost: atoll_dist::partition::GPU_INSTANCE_COST, ..Default::default() };
    let p = partition(&scene, 3, &model, &costed).unwrap();
    let layout = Layout::Ring { parts: p.parts, islands: 1, order: RingOrder::Spread };
    let out = kind.render(3, &scene, &opts, &layout, None);
    kind.assert_same_image(&reference, &out.film, "ring over instance-cost parts");
}

/// The Cornell box, a landscape of `kind.shared_growth`, the hair scene
/// (curve pieces, whose tables are chunks like the triangles') and the
/// motion-blur scene (moving instances).
fn shared_scenes(kind: &Kind) -> Vec<(String, Arc<Scene>)> {
    let mut landscape = atoll_scene::landscape::Landscape::new(kind.shared_growth).build();
    landscape.settings.film.resolution = UVec2::new(128, 72);
    let name = format!("landscape:{}", kind.shared_growth);
    // The landscape last: the host tier's test takes the last, largest.
    vec![
        ("cornell".to_string(), cornell()),
        ("hair".to_string(), repository_scene("hair.pbrt")),
        ("motion".to_string(), repository_scene("motion.pbrt")),
        (name, Arc::new(landscape)),
    ]
}

/// Bytes of `scene`'s chunks on this kind's devices, and the budget that
/// leaves a device room for `fraction` of them beside its frame.
fn shared_budget(kind: &Kind, scene: &Arc<Scene>, options: &RenderOptions, fraction: f64) -> (u64, u64) {
    let devices = (kind.devices)(1);
    let sharing = devices[0].scene_sharing().expect("a device kind that shares scene memory");
    let frame = Arc::new(atoll_render::FrameContext::new(scene, options.clone()));
    let bytes = sharing.layout(scene, &frame, kind.shared_chunk).unwrap().bytes();
    let own_memory = devices[0].free_memory().is_some();
    let frame_bytes = if own_memory { devices[0].frame_bytes(options) } else { 0 };
    (bytes, (fraction * bytes as f64) as u64 + frame_bytes)
}

/// Whether `n` fresh devices of `kind` each have hardware of their own
/// (three GPU devices on a two-GPU machine do not).
fn on_hardware_of_their_own(kind: &Kind, n: usize) -> bool {
    let devices = (kind.devices)(n);
    (0..n).all(|d| (0..d).all(|e| !devices[d].shares_memory_with(devices[e].as_ref())))
}

/// Renders `scene` on `n` devices sharing its memory as `spec` says.
fn render_shared(
    kind: &Kind,
    n: usize,
    scene: &Arc<Scene>,
    options: &RenderOptions,
    spec: SharedSpec,
) -> MultiOutput {
    let layout = Layout::Shared(spec);
    render_multi(&mut (kind.devices)(n), scene, options.clone(), &layout, None, &mut |_, _| {})
        .unwrap_or_else(|e| panic!("shared on {n} devices: {e}"))
}

/// Two and three devices, each with room for only part of the scene,
/// render the one-device image: the prepass counted reads on every device,
/// every chunk is placed once, no device holds more than its budget, and
/// each reads some chunks from the others.
pub fn shared_memory_is_one_device(kind: &Kind) {
    let mut spread = 0;
    for (name, scene) in shared_scenes(kind) {
        let opts = kind.options(&scene, 4);
        if shared_budget(kind, &scene, &opts, 1.0).0 < 8 * kind.shared_chunk {
            // Budgets of a fraction of a few chunks cannot hold whole chunks.
            eprintln!("{name}: too few chunks of {} to spread", kind.shared_chunk);
            continue;
        }
        spread += 1;
        let (reference, _) = kind.single(&scene, &opts);
        for (n, fraction) in [(2, 0.7), (3, 0.5)] {
            if !on_hardware_of_their_own(kind, n) {
                // A device sharing another's hardware reads that one's chunks.
                eprintln!("{name}: {n} devices are not on {n} pieces of hardware");
                continue;
            }
            let (bytes, budget) = shared_budget(kind, &scene, &opts, fraction);
            let spec = SharedSpec {
                chunk_bytes: kind.shared_chunk,
                budget: Some(budget),
                host_tier: false,
                ..Default::default()
            };
            let out = render_shared(kind, n, &scene, &opts, spec);
            kind.assert_same_image(&reference, &out.film, &format!("{name} shared on {n}"));
            let report = out.shared.as_ref().expect("a shared report");
            // A GPU with no room to build the BVH whole builds it in pieces,
            // cutting large objects: a few more nodes than the whole build's.
            let whole_bytes = bytes;
            let bytes = report.layout.bytes();
            assert!(bytes.abs_diff(whole_bytes) <= whole_bytes / 20, "{bytes} against {whole_bytes} B");
            assert_eq!(report.counts.len(), n);
            // Every device renders its stripe of the prepass, counting.
            for (d, counts) in report.counts.iter().enumerate() {
                assert!(counts.iter().sum::<u64>() > 0, "{name}: device {d} counted no reads");
            }
            let owned: u64 = report.residency.iter().map(|r| r.owned).sum();
            for (d, r) in report.residency.iter().enumerate() {
                assert_eq!(r.replicated + owned + r.host, bytes, "{name}: every byte placed once");
                assert_eq!(r.local() + r.remote + r.host, bytes, "{name}: device {d} sees every byte");
                assert!(r.local() < bytes && r.remote > 0, "{name}: device {d} holds {r:?} of {bytes}");
                assert!(r.local() <= budget, "{name}: device {d} holds {r:?}, budget {budget}");
                assert_eq!(r.host, 0, "{name}: the devices hold it all");
                assert_eq!(out.devices[d].prepare.shared, Some(*r));
            }
            assert!(report.replicated_chunks() > 0, "{name}: room to replicate the hottest chunks");
            assert!(report.local_reads.iter().all(|&l| l > 0.0 && l <= 1.0), "{:?}", report.local_reads);
        }
    }
    assert!(spread > 0, "no test scene spans enough chunks");
}

/// Devices that together cannot hold the scene leave its coldest chunks
/// in host memory and still render the one-device image; without the
/// host tier the same budgets are refused before rendering.
pub fn shared_memory_with_a_host_tier_is_one_device(kind: &Kind) {
    // Two devices sharing one memory take its budget once: the test's
    // budgets then leave everything in host memory.
    if (kind.distinct_memories)() < 2 {
        eprintln!("shared memory with a host tier: skipped, needs 2 devices with memories of their own");
        return;
    }
    let (name, scene) = shared_scenes(kind).pop().unwrap();
    let opts = kind.options(&scene, 2);
    let (reference, _) = kind.single(&scene, &opts);
    let (bytes, budget) = shared_budget(kind, &scene, &opts, 0.3);
    let spec = SharedSpec {
        chunk_bytes: kind.shared_chunk,
        budget: Some(budget),
        host_tier: true,
        ..Default::default()
    };
    let out = render_shared(kind, 2, &scene, &opts, spec);
    kind.assert_same_image(&reference, &out.film, &format!("{name} shared with a host tier"));
    let report = out.shared.unwrap();
    let host = report.residency[0].host;
    assert!(host > 0 && host < bytes, "{name}: {host} of {bytes} bytes in host memory");
    let layout = Layout::Shared(SharedSpec { host_tier: false, ..spec });
    let refused = render_multi(&mut (kind.devices)(2), &scene, opts, &layout, None, &mut |_, _| {});
    let message = refused.expect_err("refused without a host tier").to_string();
    assert!(message.contains("do not fit"), "{message}");
}

/// The paper's sweep: 0%, half and all of the chunks replicated (no
/// budget) render the same image, replicating as many as asked.
pub fn replicated_fractions_are_one_device(kind: &Kind) {
    let scene = cornell();
    let opts = kind.options(&scene, 2);
    let (reference, _) = kind.single(&scene, &opts);
    for fraction in [0.0, 0.5, 1.0] {
        let spec = SharedSpec {
            chunk_bytes: kind.shared_chunk,
            replication: Replication::Fraction(fraction),
            ..Default::default()
        };
        let out = render_shared(kind, 2, &scene, &opts, spec);
        kind.assert_same_image(&reference, &out.film, &format!("cornell, {fraction} replicated"));
        let report = out.shared.unwrap();
        let chunks = report.layout.chunk_count();
        let read = (0..chunks).filter(|&c| report.counts.iter().any(|d| d[c] > 0)).count();
        let wanted = ((fraction * chunks as f64).round() as usize).min(read);
        assert_eq!(report.replicated_chunks(), wanted, "{fraction} of {chunks} chunks, {read} read");
    }
}
