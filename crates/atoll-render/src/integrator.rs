//! The wavefront loop: generate → (trace → shade → trace shadows → resolve)*
//! per wave, on one device. Strategies over many devices reuse the same
//! stage order with queues moving between devices.

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

/// Runs one wave to completion on `device`.
pub fn render_wave(device: &mut dyn Device, wave: &Wave) {
    device.generate(wave);
    // No queue lengths are asked for here beyond `has_paths`: on a GPU each
    // one is a round trip that leaves the device idle.
    while device.has_paths() {
        device.trace_paths();
        device.shade();
        device.trace_shadows();
        device.resolve_shadows();
    }
}

/// Renders a frame of `scene` on one device. `progress` is called after each
/// wave with (waves done, waves total).
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
    for (i, wave) in waves.iter().enumerate() {
        render_wave(device, wave);
        progress(i + 1, waves.len());
    }
    let render_seconds = start.elapsed().as_secs_f64();
    let mut film = device.film();
    film.spp = frame.options.spp;
    Ok(RenderOutput { film, prepare, device: device.stats(), render_seconds, prepare_seconds })
}
