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
pub fn bounce(device: &mut dyn Device) -> Result<(), DeviceError> {
    bounce_observed(device, &mut |_| Ok(()))
}

/// [`bounce`], showing the traced path queue (closest hits written) to
/// `traced` before it is shaded.
pub fn bounce_observed(device: &mut dyn Device, traced: &mut Observer<'_>) -> Result<(), DeviceError> {
    device.refill()?;
    device.trace_paths()?;
    traced(device)?;
    device.shade()?;
    device.trace_shadows()?;
    device.resolve_shadows()
}

/// Renders waves from `take` on `device` until `take` has none left and
/// every path has finished. With `merge` the next wave is queued while the
/// current one's paths still run (wave-front merging), else only once the
/// device is idle. Stops at the first error.
pub fn render_waves(
    device: &mut dyn Device,
    merge: bool,
    take: &mut dyn FnMut() -> Option<Wave>,
) -> Result<(), DeviceError> {
    render_waves_observed(device, merge, take, &mut |_| Ok(()))
}

/// What sees a device's traced path queue each bounce ([`bounce_observed`]).
pub type Observer<'a> = dyn FnMut(&dyn Device) -> Result<(), DeviceError> + 'a;

/// [`render_waves`], showing every bounce's traced path queue to `traced`
/// (where a frame's rays hit: the ring's measured work).
pub fn render_waves_observed(
    device: &mut dyn Device,
    merge: bool,
    take: &mut dyn FnMut() -> Option<Wave>,
    traced: &mut Observer<'_>,
) -> Result<(), DeviceError> {
    loop {
        // No queue lengths are asked for here beyond `has_paths` and
        // `wants_work`: on a GPU these read a status the device copies back
        // a bounce ahead, so the GPU never waits for the host.
        let busy = device.has_paths()?;
        if !busy || (merge && device.wants_work()?) {
            match take() {
                Some(wave) => device.queue_work(&wave)?,
                None if !busy => return Ok(()),
                None => {}
            }
        }
        bounce_observed(device, traced)?;
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
    render_frame(device, scene, options, false, progress)
}

/// [`render`] after an untimed [`warm_up`] on the prepared device
/// (benchmarks: kernel loading, clocks and first-touch costs stay out of
/// the reported speed, and the scene is prepared once).
pub fn render_warmed(
    device: &mut dyn Device,
    scene: &Arc<Scene>,
    options: RenderOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<RenderOutput, DeviceError> {
    render_frame(device, scene, options, true, progress)
}

/// The waves of a warm-up pass: those of the frame's first sample.
pub fn warm_up_waves(waves: &[Wave]) -> impl Iterator<Item = Wave> + '_ {
    waves.iter().copied().filter(|w| w.sample == 0)
}

/// Renders the first sample of `frame` on a prepared `device`, then clears
/// its film and counters ([`Device::reset_frame`]).
pub fn warm_up(device: &mut dyn Device, frame: &FrameContext) -> Result<(), DeviceError> {
    let waves = Wave::all(&frame.options);
    let mut first = warm_up_waves(&waves);
    render_waves(device, frame.options.merge_waves, &mut || first.next())?;
    device.reset_frame()
}

fn render_frame(
    device: &mut dyn Device,
    scene: &Arc<Scene>,
    options: RenderOptions,
    warmup: bool,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<RenderOutput, DeviceError> {
    let start = Instant::now();
    let frame = Arc::new(FrameContext::new(scene, options));
    let prepare = device.prepare(scene, &ScenePart::whole(scene), &frame)?;
    let prepare_seconds = start.elapsed().as_secs_f64();
    if warmup {
        warm_up(device, &frame)?;
    }
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
    })?;
    let render_seconds = start.elapsed().as_secs_f64();
    let mut film = device.film()?;
    film.spp = frame.options.spp;
    Ok(RenderOutput { film, prepare, device: device.stats()?, render_seconds, prepare_seconds })
}
