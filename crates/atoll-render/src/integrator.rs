//! The wavefront loop: (refill → trace → shade → trace shadows → resolve)*
//! on one device, fed waves of camera paths. Strategies over many devices
//! reuse the same stage order with queues moving between devices.

use std::sync::Arc;
use std::time::Instant;

use atoll_bvh::ScenePart;
use atoll_scene::Scene;

use crate::device::{Device, DeviceError, DeviceStats, PrepareStats};
use crate::film::Film;
use crate::frame::{FrameContext, RenderOptions, Wave};

/// The result of rendering a frame.
#[derive(Clone, Debug)]
pub struct RenderOutput {
    pub film: Film,
    pub prepare: PrepareStats,
    pub device: DeviceStats,
    /// Seconds from the first generated wave to the last resolved one.
    pub render_seconds: f64,
    pub prepare_seconds: f64,
}

impl RenderOutput {
    /// Camera samples per second.
    pub fn samples_per_second(&self) -> f64 {
        self.film.pixel_count() as f64 * self.film.spp as f64 / self.render_seconds.max(1e-9)
    }

    /// All rays (path segments and shadow rays) per second.
    pub fn rays_per_second(&self) -> f64 {
        (self.device.rays_traced + self.device.shadow_rays_traced) as f64 / self.render_seconds.max(1e-9)
    }
}

/// One bounce of the wavefront loop: top the path queue up with pending
/// camera paths, trace, shade, trace and resolve shadow rays.
pub fn bounce(device: &mut dyn Device) {
    device.refill();
    device.trace_paths();
    device.shade();
    device.trace_shadows();
    device.resolve_shadows();
}

/// Renders waves from `take` on `device` until `take` has none left and
/// every path has finished. With `merge` the next wave is queued while the
/// current one's paths still run (wave-front merging), else only once the
/// device is idle.
pub fn render_waves(device: &mut dyn Device, merge: bool, take: &mut dyn FnMut() -> Option<Wave>) {
    loop {
        // No queue lengths are asked for here beyond `has_paths` and
        // `wants_work`: on a GPU these read a status the device copies back
        // a bounce ahead, so the GPU never waits for the host.
        let busy = device.has_paths();
        if !busy || (merge && device.wants_work()) {
            match take() {
                Some(wave) => device.queue_work(&wave),
                None if !busy => return,
                None => {}
            }
        }
        bounce(device);
    }
}

/// Renders a frame of `scene` on one device. `progress` is called as each
/// wave starts with (waves started, waves total).
pub fn render(
    device: &mut dyn Device,
    scene: &Arc<Scene>,
    options: RenderOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<RenderOutput, DeviceError> {
    let start = Instant::now();
    let frame = Arc::new(FrameContext::new(scene, options));
    let prepare = device.prepare(scene, &ScenePart::whole(scene), &frame)?;
    let prepare_seconds = start.elapsed().as_secs_f64();
    let waves = Wave::all(&frame.options);
    let start = Instant::now();
    let mut taken = 0;
    render_waves(device, frame.options.merge_waves, &mut || {
        let wave = waves.get(taken).copied();
        if wave.is_some() {
            taken += 1;
            progress(taken, waves.len());
        }
        wave
    });
    let render_seconds = start.elapsed().as_secs_f64();
    let mut film = device.film();
    film.spp = frame.options.spp;
    Ok(RenderOutput { film, prepare, device: device.stats(), render_seconds, prepare_seconds })
}
