//! Rendering one frame on many devices, whatever the strategy: checking
//! the layout, preparing the devices (sharing scenes where they share
//! hardware), choosing the ring transport, the warm-up, cutting the frame
//! into waves, one thread per device running its strategy
//! ([`crate::replicate`], [`crate::ring`]), and summing the films.
//!
//! Waves are handed out from one counter shared by all devices
//! (replicate) or all rings (ring), so faster devices or islands take more
//! of them. Devices accumulate only the pixels they shade; films are
//! summed once at the end.

use std::cell::Cell;
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use atoll_bvh::ScenePart;
use atoll_render::camera::CameraRays;
use atoll_render::device::{DeviceStats, PrepareStats};
use atoll_render::integrator::warm_up_waves;
use atoll_render::{Device, DeviceError, DirectRing, Film, FrameContext, RenderOptions, Wave};
use atoll_scene::Scene;

use crate::handout::{Joining, LocalHandout, Pacing, Speed, WaveHandout};
use crate::layout::{Layout, RingOrder};
use crate::replicate;
use crate::ring::{ring_loop, run_members, RingLink, RingPeers};
use crate::shared::{hardware_of, prepare_shared, SharedReport};
use crate::stripes::StripeHandout;
use crate::transport::{choose_transport, connect_rings, Handover, Transport};
use crate::vote::Vote;

/// What one device did over a frame.
#[derive(Clone, Debug, Default)]
pub struct DeviceReport {
    /// The device's name (`cpu:0`, `cuda:1`).
    pub name: String,
    /// Ring and member within it (0, 0 for replicate).
    pub island: usize,
    /// Position in its ring (the scene part it holds).
    pub member: usize,
    /// What preparing (upload, BVH build) cost and holds.
    pub prepare: PrepareStats,
    /// The device's own counters (rays traced, busy time).
    pub stats: DeviceStats,
    /// Waves this device generated (its share of the pixels).
    pub waves: usize,
    /// Seconds from the start of rendering until this device finished.
    pub wall_seconds: f64,
    /// Seconds spent blocked on the other devices of its ring (queue
    /// hand-overs, end-of-wave votes).
    pub wait_seconds: f64,
    /// Ray-record bytes this device sent to the next device of its ring.
    pub bytes_sent: u64,
    /// Seconds spent sending queues: waiting for the trace before the send
    /// to finish, then the copy (peer) or the read-back (host).
    pub send_seconds: f64,
    /// The device's first failure (a stage, or moving queues): the frame
    /// is then wrong and refused. Shared so that reports stay cloneable.
    pub error: Option<Arc<DeviceError>>,
}

impl DeviceReport {
    /// Keeps `e` unless an earlier failure is kept.
    pub fn fail(&mut self, e: DeviceError) {
        self.error.get_or_insert_with(|| Arc::new(e));
    }

    /// `result`'s value, or after keeping its error, `fallback`.
    pub fn keep<T>(&mut self, result: Result<T, DeviceError>, fallback: T) -> T {
        result.unwrap_or_else(|e| {
            self.fail(e);
            fallback
        })
    }

    /// The first failure, owned, for returning it.
    pub(crate) fn take_error(&mut self) -> Option<DeviceError> {
        let shared = self.error.take()?;
        let device = self.name.clone();
        Some(
            Arc::try_unwrap(shared).unwrap_or_else(|e| DeviceError::Other { device, message: e.to_string() }),
        )
    }
}

/// A frame rendered on many devices.
#[derive(Clone, Debug)]
pub struct MultiOutput {
    /// The merged film of every device.
    pub film: Film,
    /// Per device, in device order.
    pub devices: Vec<DeviceReport>,
    /// Seconds to prepare every device (they prepare at once).
    pub prepare_seconds: f64,
    /// Seconds from the first wave to the last.
    pub render_seconds: f64,
    /// Under the shared strategy: the prepass and where the chunks went.
    pub shared: Option<SharedReport>,
}

impl MultiOutput {
    /// Camera samples per second.
    pub fn samples_per_second(&self) -> f64 {
        self.film.pixel_count() as f64 * self.film.spp as f64 / self.render_seconds.max(1e-9)
    }

    /// Rays (path segments and shadow rays) traced by every device together, per second.
    pub fn rays_per_second(&self) -> f64 {
        let rays: u64 = self.devices.iter().map(|d| d.stats.rays_traced + d.stats.shadow_rays_traced).sum();
        rays as f64 / self.render_seconds.max(1e-9)
    }
}

/// The waves of a frame for `workers` devices or rings taking them
/// dynamically: waves are made smaller (down to 4096 pixels) until there
/// are at least 8 per worker, and the last `2 × workers` are cut in four
/// (guided scheduling), so that the last ones to finish do not keep the
/// others waiting long.
pub fn work_units(options: &RenderOptions, workers: usize) -> Vec<Wave> {
    const MIN_PIXELS: u32 = 4096;
    let pixels = options.pixel_count().max(1) as u64;
    let wanted = 8 * workers.max(1) as u64;
    let per_unit = (pixels * options.spp.max(1) as u64).div_ceil(wanted).max(MIN_PIXELS as u64).min(pixels);
    let mut opts = options.clone();
    opts.wave_size = opts.wave_size.min(per_unit as u32).max(1);
    let mut waves = Wave::all(&opts);
    let tail = waves.len().saturating_sub(2 * workers.max(1));
    let split: Vec<Wave> = waves[tail..]
        .iter()
        .flat_map(|w| {
            let piece = w.pixel_count.div_ceil(4).max(MIN_PIXELS);
            (w.first_pixel..w.first_pixel + w.pixel_count).step_by(piece as usize).map(move |first| Wave {
                sample: w.sample,
                first_pixel: first,
                pixel_count: piece.min(w.first_pixel + w.pixel_count - first),
            })
        })
        .collect();
    waves.truncate(tail);
    waves.extend(split);
    waves
}

/// Prepares every device with its part, all at once (uploads and BVH builds
/// of different devices overlap). Devices on one piece of hardware holding
/// the same part share one copy of it: the first of them prepares it, then
/// the others borrow it ([`Device::prepare_sharing`]).
fn prepare_all(
    devices: &mut [Box<dyn Device>],
    scene: &Arc<Scene>,
    frame: &Arc<FrameContext>,
    layout: &Layout,
) -> Result<Vec<PrepareStats>, DeviceError> {
    let whole = ScenePart::whole(scene);
    let part_index = |d: usize| match layout {
        Layout::Replicate | Layout::Shared(_) => 0,
        Layout::Ring { parts, .. } => d % parts.len(),
    };
    let part_of = |d: usize| match layout {
        Layout::Replicate | Layout::Shared(_) => &whole,
        Layout::Ring { parts, .. } => &parts[d % parts.len()],
    };
    // Per device, the earlier device whose scene it borrows.
    let leader: Vec<Option<usize>> = (0..devices.len())
        .map(|d| {
            (0..d).find(|&e| {
                part_index(e) == part_index(d) && devices[d].shares_memory_with(devices[e].as_ref())
            })
        })
        .collect();
    let mut stats: Vec<Option<Result<PrepareStats, DeviceError>>> = std::thread::scope(|scope| {
        let handles: Vec<_> = devices
            .iter_mut()
            .enumerate()
            .map(|(d, device)| {
                let part = part_of(d);
                let leads = leader[d].is_none();
                scope.spawn(move || leads.then(|| device.prepare(scene, part, frame)))
            })
            .collect();
        handles.into_iter().map(|h| h.join().expect("device prepare panicked")).collect()
    });
    for d in 0..devices.len() {
        let Some(l) = leader[d] else { continue };
        let (before, rest) = devices.split_at_mut(d);
        stats[d] = Some(rest[0].prepare_sharing(before[l].as_ref(), frame));
    }
    stats.into_iter().map(|s| s.expect("every device prepared")).collect()
}

/// Renders a frame on `devices` placed by `layout`, ring queues moving by
/// `transport` (`None`: the fastest the devices allow). `progress` gets
/// (waves done, waves total) as waves finish.
pub fn render_multi(
    devices: &mut [Box<dyn Device>],
    scene: &Arc<Scene>,
    options: RenderOptions,
    layout: &Layout,
    transport: Option<Transport>,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<MultiOutput, DeviceError> {
    let frame = MultiFrame { layout, transport, warmup: false, shared: None };
    render_multi_with(devices, scene, options, &frame, progress)
}

/// [`render_multi`] after an untimed pass over the frame's first sample on
/// the prepared devices, cleared after ([`Device::reset_frame`]): kernel
/// loading, clocks and first-touch costs stay out of the timed frame, and
/// every device is prepared once.
pub fn render_multi_warmed(
    devices: &mut [Box<dyn Device>],
    scene: &Arc<Scene>,
    options: RenderOptions,
    layout: &Layout,
    transport: Option<Transport>,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<MultiOutput, DeviceError> {
    let frame = MultiFrame { layout, transport, warmup: true, shared: None };
    render_multi_with(devices, scene, options, &frame, progress)
}

/// What other processes share of a frame (MPI ranks, `crate::ranks`).
#[derive(Clone, Copy)]
pub struct Shared<'a> {
    /// Hands out the frame's waves to every process.
    pub handout: &'a dyn WaveHandout,
    /// Set when this process's devices are members of rings whose other
    /// members are other processes: per device, its ring's links. The
    /// layout is then a ring of this process's parts, device `i * K + j`
    /// (K parts) holding part j as a member of island i's ring.
    pub rings: &'a [&'a (dyn RingPeers + Sync)],
}

/// How one frame is spread: over this process's devices, and with
/// `shared` over other processes'.
#[derive(Clone, Copy)]
pub struct MultiFrame<'a> {
    /// Where the scene goes on this process's devices.
    pub layout: &'a Layout,
    /// How ring queues move (`None`: the fastest the devices allow).
    pub transport: Option<Transport>,
    /// Render the frame's first sample untimed first ([`render_multi_warmed`]).
    pub warmup: bool,
    /// What other processes share of the frame (`None`: this process
    /// renders it alone).
    pub shared: Option<Shared<'a>>,
}

/// [`render_multi`] as `frame` says (warm-up, other processes). Each
/// process then returns its devices' part of the film. The handout is
/// joined even when this process fails to prepare, so that the others
/// learn of it instead of waiting.
pub fn render_multi_with(
    devices: &mut [Box<dyn Device>],
    scene: &Arc<Scene>,
    options: RenderOptions,
    frame: &MultiFrame<'_>,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<MultiOutput, DeviceError> {
    let MultiFrame { layout, transport, warmup, shared } = *frame;
    let alone = LocalHandout::default();
    let handout = shared.map_or(&alone as &dyn WaveHandout, |s| s.handout);
    let remote: &[&(dyn RingPeers + Sync)] = shared.map_or(&[], |s| s.rings);
    // A ring of processes counts once, at its member 0.
    let islands = match remote.is_empty() {
        false => remote.iter().filter(|link| link.place().member == 0).count(),
        true => workers(layout, devices.len()),
    };
    let frame = Arc::new(FrameContext::new(scene, options));
    let wave_size = wave_size_for(devices, &frame.options);
    let warmup = warmup.then_some(WarmUp { workers: islands, wave_size });
    let ready = ready_frame(devices, scene, &frame, layout, transport, warmup, remote);
    let joined = handout.join(Joining {
        ready: ready.is_ok(),
        workers: islands,
        wave_size,
        samples: frame.options.pixel_count() as u64 * frame.options.spp as u64,
    });
    let Ready { prepared, prepare_seconds, shape, warmed, direct, shared: shared_scene } = ready?;
    let joined = joined?;
    // Every process cuts the same waves (only their sizes may differ from
    // what this process's devices would take alone).
    let cut = RenderOptions { wave_size: joined.wave_size, ..frame.options.clone() };
    let mut waves = work_units(&cut, joined.workers);
    // Devices sharing a scene's memory keep to their own region of the image.
    let stripes;
    let handout: &dyn WaveHandout = match (layout, shared) {
        (Layout::Shared(_), None) => {
            let (pixels, hardware) = (frame.options.pixel_count(), hardware_of(devices)?);
            (waves, stripes) = StripeHandout::cut(&waves, pixels, &hardware);
            &stripes
        }
        _ => handout,
    };
    handout.begin(waves.len(), pacing(&frame.options, &waves, islands, &warmed));
    let start = Instant::now();
    let reports = match remote.is_empty() {
        false => run_members(devices, &waves, shape, remote, handout, progress),
        true => run_waves(devices, &waves, shape, &direct, handout, progress),
    };
    let render_seconds = start.elapsed().as_secs_f64();
    handout.end();
    let mut reports = reports?;
    let film = finish_reports(devices, &mut reports, &direct, shape.ring, frame.options.spp)?;
    for (report, prepare) in reports.iter_mut().zip(prepared) {
        report.prepare = prepare;
    }
    Ok(MultiOutput { film, devices: reports, prepare_seconds, render_seconds, shared: shared_scene })
}

/// What takes waves on this process's devices under `layout`: each device
/// replicating (or sharing scene memory), or each ring (island).
fn workers(layout: &Layout, devices: usize) -> usize {
    match layout {
        Layout::Replicate | Layout::Shared(_) => devices,
        Layout::Ring { islands, .. } => *islands,
    }
}

/// The wave size of a frame on `devices`: devices of different kinds (the
/// CPU beside GPUs) take waves of the smallest kind's size: one GPU-sized
/// wave kept a CPU busy longer than the GPUs took for the whole frame.
fn wave_size_for(devices: &[Box<dyn Device>], options: &RenderOptions) -> u32 {
    let smallest = devices.iter().map(|d| d.default_wave_size()).min().unwrap_or(u32::MAX);
    let largest = devices.iter().map(|d| d.default_wave_size()).max().unwrap_or(u32::MAX);
    match smallest < largest {
        true => options.wave_size.min(smallest),
        false => options.wave_size,
    }
}

/// After the waves: the first failure any device kept, or else the
/// devices' films summed (as `spp` samples per pixel), with each report's
/// counters and bytes sent filled in.
fn finish_reports(
    devices: &mut [Box<dyn Device>],
    reports: &mut [DeviceReport],
    direct: &[Box<dyn DirectRing>],
    ring: usize,
    spp: u32,
) -> Result<Film, DeviceError> {
    if let Some(e) = reports.iter_mut().find_map(|r| r.take_error()) {
        return Err(e);
    }
    let film = summed_film(devices, spp)?;
    for (d, (device, report)) in devices.iter_mut().zip(reports.iter_mut()).enumerate() {
        report.stats = device.stats()?;
        if let Some(ring) = direct.get(d / ring) {
            // Counted where the records are sent: the host never learns the lengths.
            report.bytes_sent = ring.bytes_sent(device.as_mut())?;
        }
    }
    Ok(film)
}

/// The devices' films summed, as `spp` samples per pixel: read back at
/// once (several GPUs, or a GPU's wavefronts, each a copy over PCIe),
/// summed in device order (the same sums every time).
fn summed_film(devices: &mut [Box<dyn Device>], spp: u32) -> Result<Film, DeviceError> {
    let films: Vec<Result<Film, DeviceError>> = std::thread::scope(|scope| {
        let reading: Vec<_> = devices.iter_mut().map(|d| scope.spawn(move || d.film())).collect();
        reading.into_iter().map(|h| h.join().expect("reading a film panicked")).collect()
    });
    let mut film: Option<Film> = None;
    for mine in films {
        let mine = mine?;
        match &mut film {
            Some(film) => film.merge(&mine),
            None => film = Some(mine),
        }
    }
    let mut film = film.ok_or_else(|| DeviceError::Other {
        device: "devices".into(),
        message: "no devices rendered".into(),
    })?;
    film.spp = spp;
    Ok(film)
}

/// Devices prepared once for many passes over one scene (an interactive
/// view): each pass renders a range of samples of every pixel, adding to
/// the devices' films; the camera may move between passes, the films then
/// cleared. Samples `a..b` then `b..c` give the film one frame of `c`
/// samples from 0 gives (a path's random numbers depend only on its pixel
/// and sample). One process; any layout.
pub struct Session<'d> {
    devices: &'d mut [Box<dyn Device>],
    frame: Arc<FrameContext>,
    layout: Layout,
    ready: Ready,
    workers: usize,
    wave_size: u32,
    /// Samples per pixel in the films since they were last cleared.
    samples: u32,
    /// Sharing scene memory: per device, its piece of hardware (devices
    /// keep to their hardware's stripe of the image).
    hardware: Vec<usize>,
}

impl<'d> Session<'d> {
    /// Prepares `devices` (placed by `layout`, ring queues moving by
    /// `transport`) for passes over frames of `options` (its `spp` does
    /// not matter: passes say which samples they render).
    pub fn prepare(
        devices: &'d mut [Box<dyn Device>],
        scene: &Arc<Scene>,
        options: RenderOptions,
        layout: &Layout,
        transport: Option<Transport>,
    ) -> Result<Session<'d>, DeviceError> {
        let frame = Arc::new(FrameContext::new(scene, options));
        let ready = ready_frame(devices, scene, &frame, layout, transport, None, &[])?;
        Ok(Session {
            hardware: match layout {
                Layout::Shared(_) => hardware_of(devices)?,
                _ => Vec::new(),
            },
            workers: workers(layout, devices.len()),
            wave_size: wave_size_for(devices, &frame.options),
            devices,
            frame,
            layout: layout.clone(),
            ready,
            samples: 0,
        })
    }

    /// What preparing cost each device.
    pub fn prepared(&self) -> &[PrepareStats] {
        &self.ready.prepared
    }

    /// The frame's options (resolution, integrator, …).
    pub fn options(&self) -> &RenderOptions {
        &self.frame.options
    }

    /// Samples per pixel accumulated since the films were last cleared.
    pub fn samples(&self) -> u32 {
        self.samples
    }

    /// Renders `count` more samples of every pixel (samples
    /// `self.samples()..+count`), adding to the films; the pass's seconds.
    pub fn render_samples(&mut self, count: u32) -> Result<f64, DeviceError> {
        let first = self.samples;
        let cut =
            RenderOptions { wave_size: self.wave_size, spp: count.max(1), ..self.frame.options.clone() };
        let mut waves = work_units(&cut, self.workers);
        for wave in &mut waves {
            wave.sample += first;
        }
        let local = LocalHandout::default();
        let stripes;
        let handout: &dyn WaveHandout = match self.layout {
            Layout::Shared(_) => {
                (waves, stripes) = StripeHandout::cut(&waves, cut.pixel_count(), &self.hardware);
                &stripes
            }
            _ => &local,
        };
        handout.begin(waves.len(), pacing(&cut, &waves, self.workers, &[]));
        let start = Instant::now();
        let reports =
            run_waves(self.devices, &waves, self.ready.shape, &self.ready.direct, handout, &mut |_, _| {});
        let seconds = start.elapsed().as_secs_f64();
        handout.end();
        let mut reports = reports?;
        if let Some(e) = reports.iter_mut().find_map(|r| r.take_error()) {
            return Err(e);
        }
        self.samples = first + count.max(1);
        Ok(seconds)
    }

    /// Each device's counters since the films were last cleared.
    pub fn stats(&self) -> Result<Vec<DeviceStats>, DeviceError> {
        self.devices.iter().map(|d| d.stats()).collect()
    }

    /// The devices' films summed: `samples()` samples per pixel.
    pub fn film(&mut self) -> Result<Film, DeviceError> {
        summed_film(self.devices, self.samples)
    }

    /// Clears the films for a new accumulation, the camera moved to
    /// `camera` when given (from sample 0 again).
    pub fn restart(&mut self, camera: Option<&CameraRays>) -> Result<(), DeviceError> {
        for device in self.devices.iter_mut() {
            if let Some(camera) = camera {
                device.set_camera(camera)?;
            }
            device.reset_frame()?;
        }
        if let Some(camera) = camera {
            self.frame = Arc::new(FrameContext { camera: camera.clone(), ..(*self.frame).clone() });
        }
        self.samples = 0;
        Ok(())
    }

    /// The devices, for their names and memory figures.
    pub fn devices(&self) -> &[Box<dyn Device>] {
        self.devices
    }
}

/// A frame's devices, prepared (and warmed up) and ready for its waves.
struct Ready {
    prepared: Vec<PrepareStats>,
    prepare_seconds: f64,
    shape: RunShape,
    /// Per worker, camera samples and seconds of the warm-up (empty
    /// without one).
    warmed: Vec<(u64, f64)>,
    /// Per ring, its direct transport (empty when queues go through the host).
    direct: Vec<Box<dyn DirectRing>>,
    /// The shared strategy's prepass and placement.
    shared: Option<SharedReport>,
}

/// How this process's `workers` take `waves` ([`Pacing`]): devices
/// merging wave-fronts hold up to a queue's worth of them at once; each
/// worker's speed on the warm-up, if any.
fn pacing(options: &RenderOptions, waves: &[Wave], workers: usize, warmed: &[(u64, f64)]) -> Pacing {
    let samples: u64 = waves.iter().map(|w| w.pixel_count as u64).sum();
    let per_wave = (samples as f64 / waves.len().max(1) as f64).max(1.0);
    let held = match options.merge_waves {
        true => (options.wave_size as f64 / per_wave).ceil() as usize + 1,
        false => 1,
    };
    let speed = |w: usize| {
        let &(samples, seconds) = warmed.get(w)?;
        (samples > 0).then(|| Speed { seconds_per_wave: seconds * per_wave / samples as f64, workers: 1 })
    };
    Pacing { in_flight: held, warmed: (0..workers).map(speed).collect() }
}

/// How a process warms its devices up: the frame's first sample, cut for
/// its `workers` (at least one) in waves of `wave_size` as the frame's
/// will be, and at least one per worker, so that every worker is timed on
/// waves like the frame's.
#[derive(Clone, Copy, Debug)]
struct WarmUp {
    workers: usize,
    wave_size: u32,
}

/// Checks `layout` against `devices`, prepares them, picks the ring
/// transport and, with `warmup`, renders the frame's first sample and
/// clears it (on rings of processes, `remote`, with their members),
/// timing each worker.
fn ready_frame(
    devices: &mut [Box<dyn Device>],
    scene: &Arc<Scene>,
    frame: &Arc<FrameContext>,
    layout: &Layout,
    transport: Option<Transport>,
    warmup: Option<WarmUp>,
    remote: &[&(dyn RingPeers + Sync)],
) -> Result<Ready, DeviceError> {
    if devices.is_empty() {
        return Err(DeviceError::Other {
            device: "devices".into(),
            message: "no devices to render on".into(),
        });
    }
    if !remote.is_empty() && (devices.len() != remote.len() || !matches!(layout, Layout::Ring { .. })) {
        return Err(DeviceError::Other {
            device: "devices".into(),
            message: "members of rings of processes render one device per member, each holding its part"
                .into(),
        });
    }
    if let Some(needed) = layout.devices() {
        if needed != devices.len() {
            return Err(DeviceError::Other {
                device: "devices".into(),
                message: format!("the ring layout needs {needed} devices, {} given", devices.len()),
            });
        }
    }
    let start = Instant::now();
    let (prepared, shared) = match layout {
        Layout::Shared(spec) => {
            let (prepared, report) = prepare_shared(devices, scene, frame, spec)?;
            (prepared, Some(report))
        }
        _ => (prepare_all(devices, scene, frame, layout)?, None),
    };
    let prepare_seconds = start.elapsed().as_secs_f64();

    let (ring, order) = match layout {
        Layout::Replicate | Layout::Shared(_) => (1, RingOrder::Spread),
        Layout::Ring { parts, order, .. } => (parts.len(), *order),
    };
    // (Rings of processes link their members themselves.)
    let transport = match ring > 1 && remote.is_empty() {
        true => choose_transport(devices, transport)?,
        false => Transport::Host,
    };
    let shape = RunShape { ring, order, merge: frame.options.merge_waves };
    let direct = match transport {
        Transport::Peer => connect_rings(devices, ring)?,
        Transport::Host => Vec::new(),
    };
    for device in devices.iter_mut() {
        // A ring member waits for its neighbours between stages: time the
        // stages, not the waves, for its busy time.
        device.time_stages(ring > 1 || !remote.is_empty());
    }
    let mut warmed = Vec::new();
    if let Some(WarmUp { workers, wave_size }) = warmup {
        // This process's own share of the first sample: warming up needs
        // no other process.
        let cutting_for = workers.max(1);
        let per_worker = frame.options.pixel_count().div_ceil(cutting_for as u32);
        let cut = RenderOptions { wave_size: wave_size.min(per_worker.max(1)), ..frame.options.clone() };
        let first: Vec<Wave> = warm_up_waves(&work_units(&cut, cutting_for)).collect();
        let handout = LocalHandout::default();
        // Member 0 alone makes a ring of processes' warm-up queues.
        let mine = match remote.first() {
            Some(link) if link.place().member != 0 => &first[..0],
            _ => &first[..],
        };
        handout.begin(mine.len(), Pacing::default());
        let mut reports = match remote.is_empty() {
            false => run_members(devices, mine, shape, remote, &handout, &mut |_, _| {})?,
            true => run_waves(devices, mine, shape, &direct, &handout, &mut |_, _| {})?,
        };
        if let Some(e) = reports.iter_mut().find_map(|r| r.take_error()) {
            return Err(e);
        }
        // Per worker (a device replicating, a ring), the samples it took
        // and the busy time of its busiest device: a GPU's warm-up is a few
        // milliseconds of kernels in several times as long of start-up, and
        // its wall time made it look several times slower than it is.
        let per_wave = mine.iter().map(|w| w.pixel_count as u64).sum::<u64>() / mine.len().max(1) as u64;
        warmed = vec![(0u64, 0f64); workers];
        for (d, (report, device)) in reports.iter().zip(devices.iter()).enumerate() {
            // (A process's members of rings of processes take waves as
            // workers 0, 1, … island by island.)
            let worker = if remote.is_empty() { report.island } else { d / ring };
            if let Some((samples, seconds)) = warmed.get_mut(worker) {
                *samples += report.waves as u64 * per_wave;
                *seconds = seconds.max(device.stats()?.busy_seconds);
            }
        }
        for device in devices.iter_mut() {
            device.reset_frame()?;
        }
    }
    Ok(Ready { prepared, prepare_seconds, shape, warmed, direct, shared })
}

/// How the devices of a frame work together.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RunShape {
    /// Devices per ring (1: replicate).
    pub(crate) ring: usize,
    pub(crate) order: RingOrder,
    /// Wave-front merging.
    pub(crate) merge: bool,
}

/// Renders `waves` on the prepared `devices`, one thread each, waves taken
/// dynamically by the devices (replicate) or rings (ring); every device's
/// report, in device order (counters and film are read by the caller).
pub(crate) fn run_waves(
    devices: &mut [Box<dyn Device>],
    waves: &[Wave],
    shape: RunShape,
    direct: &[Box<dyn DirectRing>],
    handout: &dyn WaveHandout,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Vec<DeviceReport>, DeviceError> {
    let RunShape { ring, order, merge, .. } = shape;
    let islands = devices.len() / ring;
    // Workers are devices replicating, or rings: the island.
    let take = |worker: usize| handout.next(worker).and_then(|i| waves.get(i));
    let votes: Vec<Vote> = (0..islands).map(|_| Vote::new(ring)).collect();
    // Device d sends to d + 1 of its ring and receives from d - 1.
    let (senders, receivers): (Vec<_>, Vec<_>) = (0..devices.len()).map(|_| mpsc::channel()).unzip();
    let inboxes: Vec<Mutex<Option<mpsc::Receiver<Handover>>>> =
        receivers.into_iter().map(|r| Mutex::new(Some(r))).collect();
    let reports = on_device_threads(devices, handout, waves.len(), progress, &|d, device, taken| {
        let (island, member) = (d / ring, d % ring);
        let mut report = DeviceReport { name: device.name(), island, member, ..Default::default() };
        if ring == 1 {
            replicate::run_device(device, merge, &|| take(island), taken, &mut report);
            return report;
        }
        let link = RingLink {
            size: ring,
            member,
            direct: direct.get(island).map(|r| r.as_ref()),
            to_next: senders[island * ring + (member + 1) % ring].clone(),
            from_prev: inboxes[d]
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .take()
                .expect("one inbox per device"),
            steps: Cell::new(0),
            spare: Cell::default(),
            vote: &votes[island],
            order,
        };
        ring_loop(device, &link, merge, &|| take(island), taken, &mut report);
        report
    });
    Ok(reports)
}

/// What a device's thread does over a frame: given the device's index, the
/// device and what to call when it takes a wave, its report.
pub(crate) type DeviceWork<'a> = dyn Fn(usize, &mut dyn Device, &dyn Fn()) -> DeviceReport + Sync + 'a;

/// Runs `work` (device index, device, "a wave was taken") on every device,
/// one thread each, and returns their reports in device order with the
/// seconds each took; `progress` hears of every wave taken, from this
/// thread.
pub(crate) fn on_device_threads(
    devices: &mut [Box<dyn Device>],
    handout: &dyn WaveHandout,
    waves: usize,
    progress: &mut dyn FnMut(usize, usize),
    work: &DeviceWork<'_>,
) -> Vec<DeviceReport> {
    let (done_tx, done_rx) = mpsc::channel::<()>();
    let start = Instant::now();
    std::thread::scope(|scope| {
        let handles: Vec<_> = devices
            .iter_mut()
            .enumerate()
            .map(|(d, device)| {
                let done = done_tx.clone();
                scope.spawn(move || {
                    let taken = || {
                        let _ = done.send(());
                    };
                    let mut report = work(d, device.as_mut(), &taken);
                    report.wall_seconds = start.elapsed().as_secs_f64();
                    report
                })
            })
            .collect();
        drop(done_tx);
        for () in done_rx {
            progress(handout.taken(), waves);
        }
        handles.into_iter().map(|h| h.join().expect("device thread panicked")).collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::UVec2;

    /// Waves in flight per worker and warm-up speeds per wave of the frame.
    #[test]
    fn pacing_counts_waves_held_and_scales_warm_up_speeds() {
        let scene = atoll_scene::cornell::builtin_cornell_box();
        let mut options = RenderOptions::from_scene(&scene);
        options.resolution = UVec2::new(256, 256);
        options.spp = 4;
        options.wave_size = 1 << 16;
        let waves: Vec<Wave> = (0..16)
            .map(|i| Wave { sample: i / 4, first_pixel: (i % 4) * 16384, pixel_count: 16384 })
            .collect();
        // Two workers: one rendered 32768 warm-up samples in 0.1 s, the other none.
        let pacing = pacing(&options, &waves, 2, &[(32768, 0.1), (0, 0.2)]);
        // A queue of 65536 holds 4 waves of 16384, and takes the next one early.
        assert_eq!(pacing.in_flight, 5);
        let first = pacing.warmed[0].expect("measured");
        assert!((first.seconds_per_wave - 0.05).abs() < 1e-12, "{first:?}");
        assert_eq!(pacing.warmed[1], None);
        options.merge_waves = false;
        assert_eq!(super::pacing(&options, &waves, 2, &[]).in_flight, 1);
    }

    /// Every (pixel, sample) exactly once, whatever the split.
    #[test]
    fn work_units_cover_the_frame_once_with_a_finer_tail() {
        let scene = atoll_scene::cornell::builtin_cornell_box();
        for (w, h, spp, workers) in [(640, 360, 8, 2), (64, 64, 3, 4), (1, 1, 1, 1), (1280, 720, 32, 3)] {
            let mut options = RenderOptions::from_scene(&scene);
            options.resolution = UVec2::new(w, h);
            options.spp = spp;
            let waves = work_units(&options, workers);
            let mut seen = vec![0u32; (w * h * spp) as usize];
            for wave in &waves {
                assert!(wave.pixel_count > 0 && wave.pixel_count <= options.wave_size);
                for p in wave.first_pixel..wave.first_pixel + wave.pixel_count {
                    seen[(wave.sample * w * h + p) as usize] += 1;
                }
            }
            assert!(seen.iter().all(|&n| n == 1), "{w}x{h} {spp} spp {workers} workers");
            assert!(waves.len() >= 8 * workers || (w * h) as usize * spp as usize <= 8 * 4096 * workers);
        }
    }
}
