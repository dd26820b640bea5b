//! Wave-front merging: starting the next wave's paths in freed queue slots
//! renders the same paths (same rays, same image up to the order of film
//! additions) in fewer, fuller bounces.

use std::sync::Arc;

use atoll_bvh::ScenePart;
use atoll_render::device::{DeviceStats, PrepareStats};
use atoll_render::Wave;
use atoll_render::{
    render, CpuDevice, Device, DeviceError, Film, FrameContext, Queue, RayRecord, RenderOptions,
};
use atoll_scene::{IntegratorSettings, Scene};
use glam::UVec2;

/// A CPU device that counts bounces and the fullest and emptiest path
/// queue it traced.
struct Counting {
    inner: CpuDevice,
    bounces: usize,
    queue_lengths: Vec<usize>,
}

impl Device for Counting {
    fn name(&self) -> String {
        self.inner.name()
    }
    fn prepare(
        &mut self,
        scene: &Arc<Scene>,
        part: &ScenePart,
        frame: &Arc<FrameContext>,
    ) -> Result<PrepareStats, DeviceError> {
        self.inner.prepare(scene, part, frame)
    }
    fn reset_frame(&mut self) -> Result<(), DeviceError> {
        self.inner.reset_frame()
    }
    fn set_camera(&mut self, camera: &atoll_render::camera::CameraRays) -> Result<(), DeviceError> {
        self.inner.set_camera(camera)
    }
    fn queue_work(&mut self, wave: &Wave) -> Result<(), DeviceError> {
        self.inner.queue_work(wave)
    }
    fn wants_work(&self) -> Result<bool, DeviceError> {
        self.inner.wants_work()
    }
    fn refill(&mut self) -> Result<(), DeviceError> {
        self.inner.refill()
    }
    fn trace_paths(&mut self) -> Result<(), DeviceError> {
        self.bounces += 1;
        self.queue_lengths.push(self.inner.queue_len(Queue::Paths)?);
        self.inner.trace_paths()
    }
    fn shade(&mut self) -> Result<(), DeviceError> {
        self.inner.shade()
    }
    fn trace_shadows(&mut self) -> Result<(), DeviceError> {
        self.inner.trace_shadows()
    }
    fn resolve_shadows(&mut self) -> Result<(), DeviceError> {
        self.inner.resolve_shadows()
    }
    fn has_paths(&self) -> Result<bool, DeviceError> {
        self.inner.has_paths()
    }
    fn queue_len(&self, queue: Queue) -> Result<usize, DeviceError> {
        self.inner.queue_len(queue)
    }
    fn read_queue_into(&self, queue: Queue, into: &mut Vec<RayRecord>) -> Result<(), DeviceError> {
        self.inner.read_queue_into(queue, into)
    }
    fn write_queue(&mut self, queue: Queue, records: &[RayRecord]) -> Result<(), DeviceError> {
        self.inner.write_queue(queue, records)
    }
    fn film(&self) -> Result<Film, DeviceError> {
        self.inner.film()
    }
    fn stats(&self) -> Result<DeviceStats, DeviceError> {
        self.inner.stats()
    }
    fn frame_bytes(&self, options: &atoll_render::RenderOptions) -> u64 {
        self.inner.frame_bytes(options)
    }
    fn set_memory_budget(&mut self, bytes: Option<u64>) {
        self.inner.set_memory_budget(bytes)
    }
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }
}

fn render_counting(scene: &Arc<Scene>, merge: bool) -> (Film, DeviceStats, Counting) {
    let mut options = RenderOptions::from_scene(scene);
    // 61 x 47 pixels in waves of 1000: waves end mid-row and mid-sample.
    options.resolution = UVec2::new(61, 47);
    options.spp = 5;
    options.wave_size = 1000;
    options.integrator = IntegratorSettings::Path { max_depth: 8 };
    options.merge_waves = merge;
    let mut device = Counting { inner: CpuDevice::new(), bounces: 0, queue_lengths: Vec::new() };
    let out = render(&mut device, scene, options, &mut |_, _| {}).expect("render");
    (out.film, out.device, device)
}

#[test]
fn merged_waves_trace_the_same_paths_in_fewer_fuller_bounces() {
    let scene = Arc::new(atoll_scene::cornell::builtin_cornell_box());
    let (one_at_a_time, stats_a, a) = render_counting(&scene, false);
    let (merged, stats_b, b) = render_counting(&scene, true);

    // Same rays: paths and shadow rays depend only on (pixel, sample).
    assert_eq!(stats_a.rays_traced, stats_b.rays_traced, "path segments traced");
    assert_eq!(stats_a.shadow_rays_traced, stats_b.shadow_rays_traced, "shadow rays traced");
    // Same image up to the order of additions into each pixel.
    let mut worst = 0.0f32;
    for (p, q) in one_at_a_time.sum.iter().zip(&merged.sum) {
        worst = worst.max(((*p - *q).abs() / p.abs().max(glam::Vec3::splat(1e-3))).max_element());
    }
    assert!(worst < 1e-5, "largest per-pixel relative difference {worst}");
    assert!(one_at_a_time.mean().max_element() > 0.0, "a black image proves nothing");

    eprintln!("bounces: {} one wave at a time, {} merged", a.bounces, b.bounces);
    // Fewer bounces: 15 waves of up to 9 bounces each one at a time; merged,
    // the queue stays full until the last wave has started.
    assert!(b.bounces * 3 < a.bounces * 2, "merged {} bounces vs {} one at a time", b.bounces, a.bounces);
    let full = b.queue_lengths.iter().take_while(|&&n| n == 1000).count();
    assert!(full * 2 > b.bounces, "queue full in only {full} of {} merged bounces", b.bounces);
    // Without merging no queue is fuller than a wave; with it, none overflows.
    assert!(a.queue_lengths.iter().chain(&b.queue_lengths).all(|&n| n <= 1000));
}

/// `render_warmed` prepares once, renders the first sample untimed and
/// clears it: the frame after is the cold frame, counters included.
#[test]
fn a_warmed_frame_is_the_cold_frame() {
    let scene = Arc::new(atoll_scene::cornell::builtin_cornell_box());
    let mut options = RenderOptions::from_scene(&scene);
    options.resolution = UVec2::new(32, 32);
    options.spp = 3;
    let cold = render(&mut CpuDevice::new(), &scene, options.clone(), &mut |_, _| {}).unwrap();
    let mut device = Counting { inner: CpuDevice::new(), bounces: 0, queue_lengths: Vec::new() };
    let warm = atoll_render::integrator::render_warmed(&mut device, &scene, options, &mut |_, _| {}).unwrap();
    assert_eq!(cold.device.rays_traced, warm.device.rays_traced);
    assert_eq!(cold.device.shadow_rays_traced, warm.device.shadow_rays_traced);
    assert_eq!(cold.film.sum, warm.film.sum, "one device, one order: the same sums");
    assert!(device.bounces > 0);
}
