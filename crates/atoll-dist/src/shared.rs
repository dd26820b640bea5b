//! The shared strategy (Jaroš et al. 2021): the scene in fixed-size
//! chunks over the devices' memories, each device rendering its share of
//! the waves as in replicate, reading every chunk where it lies.
//!
//! Preparing is the paper's steps 1–4: the chunks start dealt round robin
//! ([`initial_placement`]); every device renders its share of the frame's
//! first sample counting reads per chunk (the prepass); the counts place
//! the chunks ([`place_chunks`]: hot ones replicated, the rest on their
//! main reader, the coldest in host memory when the devices are full);
//! the devices move their chunks there. Rendering is then replicate's.

use std::sync::Arc;
use std::time::Instant;

use atoll_render::device::PrepareStats;
use atoll_render::{
    ChunkLayout, ChunkPlacement, Device, DeviceError, FrameContext, RenderOptions, Residency, Wave,
};
use atoll_scene::Scene;

use crate::chunk_placement::{
    access_concentration, initial_placement, local_read_share, place_chunks, ChunkBudget, Replication,
};
use crate::layout::RingOrder;
use crate::placement::host_memory_available;
use crate::render::{run_waves, RunShape};
use crate::stripes::StripeHandout;

/// Default chunk size: the paper's optimum for scenes under 30 GB.
pub const DEFAULT_CHUNK_BYTES: u64 = 2 << 20;

/// Most chunks a shared scene is cut into: every device keeps a counter
/// per chunk, and a chunk size far below the scene's would make those
/// counters outgrow the scene.
pub const MAX_CHUNKS: usize = 1 << 24;

/// How a shared scene is cut and placed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SharedSpec {
    /// Bytes per chunk.
    pub chunk_bytes: u64,
    /// How many chunks to replicate.
    pub replication: Replication,
    /// Memory budget per device (`None`: what each has).
    pub budget: Option<u64>,
    /// Whether chunks may stay in host memory when the devices are full.
    pub host_tier: bool,
}

impl Default for SharedSpec {
    fn default() -> Self {
        SharedSpec {
            chunk_bytes: DEFAULT_CHUNK_BYTES,
            replication: Replication::Auto,
            budget: None,
            host_tier: true,
        }
    }
}

/// What the prepass found and where it put the chunks.
#[derive(Clone, Debug)]
pub struct SharedReport {
    /// The scene's tables and chunks.
    pub layout: ChunkLayout,
    /// Reads per device and chunk during the prepass.
    pub counts: Vec<Vec<u64>>,
    /// Where the chunks went.
    pub placement: ChunkPlacement,
    /// Per device, what it holds and reads elsewhere under `placement`.
    pub residency: Vec<Residency>,
    /// Per device, the share of its prepass reads its own memory serves
    /// under `placement`.
    pub local_reads: Vec<f64>,
    /// Seconds of the counting render.
    pub prepass_seconds: f64,
}

impl SharedReport {
    /// Chunks replicated on every device.
    pub fn replicated_chunks(&self) -> usize {
        self.placement.homes.iter().filter(|h| **h == atoll_render::ChunkHome::Replicated).count()
    }

    /// Share of reads the hottest `fractions` of the scene's bytes take.
    pub fn concentration(&self, fractions: &[f64]) -> Vec<f64> {
        access_concentration(&self.layout, &self.counts, fractions)
    }
}

/// Per device, the bytes of chunks it may hold: for a device with memory
/// of its own, the budget or its free memory, whichever is less, less
/// what it allocates for the frame itself; for a device on host memory
/// the budget (which counts scene bytes alone).
fn chunk_budgets(
    devices: &[Box<dyn Device>],
    hardware: &[usize],
    spec: &SharedSpec,
    options: &RenderOptions,
) -> ChunkBudget {
    let devices = devices[..leader_count(hardware)]
        .iter()
        .enumerate()
        .map(|(l, d)| match d.free_memory() {
            // Memory of its own: the frames of every device on it come
            // out of the budget too.
            Some(free) => {
                let frames = hardware.iter().filter(|&&h| h == l).count() as u64 * d.frame_bytes(options);
                Some(spec.budget.map_or(free, |b| b.min(free)).saturating_sub(frames))
            }
            // Host memory: a budget counts scene bytes alone.
            None => spec.budget,
        })
        .collect();
    // Three quarters of what the OS has available: the rest is kept for
    // the scene itself, the renderer and others.
    let host = spec.host_tier.then(|| host_memory_available().map_or(u64::MAX, |a| a / 4 * 3));
    ChunkBudget { devices, host }
}

/// Per device, the index of the first device on its hardware: the
/// leaders, each on hardware of its own, come first (more wavefronts on a
/// GPU are added after the devices listed), the others share a leader's
/// chunks. `Err` when a device listed later shares an earlier one's
/// hardware before every leader is listed.
pub(crate) fn hardware_of(devices: &[Box<dyn Device>]) -> Result<Vec<usize>, DeviceError> {
    let shares = |d: usize, e: usize| devices[d].shares_memory_with(devices[e].as_ref());
    let leaders = (0..devices.len()).take_while(|&d| !(0..d).any(|e| shares(d, e))).count();
    (0..devices.len())
        .map(|d| match d < leaders {
            true => Ok(d),
            false => (0..leaders).find(|&l| shares(d, l)).ok_or_else(|| {
                error(format!(
                    "{} follows a device on shared hardware: list each piece of hardware once (--streams adds wavefronts)",
                    devices[d].name()
                ))
            }),
        })
        .collect()
}

/// Devices holding chunks of their own: the leaders of [`hardware_of`].
fn leader_count(hardware: &[usize]) -> usize {
    hardware.iter().max().map_or(0, |&h| h + 1)
}

/// A device-neutral error about the shared scene as a whole.
fn error(message: impl Into<String>) -> DeviceError {
    DeviceError::Other { device: "shared scene".into(), message: message.into() }
}

/// The prepass alone, for reports (`atoll info --prepass`): prepares
/// `devices` over `scene` shared as `spec` says, counts the reads of the
/// first sample of a frame of `options` and places the chunks.
pub fn prepass(
    devices: &mut [Box<dyn Device>],
    scene: &Arc<Scene>,
    options: RenderOptions,
    spec: &SharedSpec,
) -> Result<SharedReport, DeviceError> {
    let frame = Arc::new(FrameContext::new(scene, options));
    Ok(prepare_shared(devices, scene, &frame, spec)?.1)
}

/// Prepares `devices` over one shared scene: lays it out, deals the
/// chunks, runs the counting prepass and places the chunks by it.
pub(crate) fn prepare_shared(
    devices: &mut [Box<dyn Device>],
    scene: &Arc<Scene>,
    frame: &Arc<FrameContext>,
    spec: &SharedSpec,
) -> Result<(Vec<PrepareStats>, SharedReport), DeviceError> {
    let sharing = devices
        .first()
        .and_then(|d| d.scene_sharing())
        .ok_or_else(|| error("the devices cannot share a scene's memory"))?;
    let hardware = hardware_of(devices)?;
    let leaders = leader_count(&hardware);
    let budget = chunk_budgets(devices, &hardware, spec, &frame.options);
    let layout = sharing.layout(scene, frame, spec.chunk_bytes)?;
    if layout.chunk_count() > MAX_CHUNKS {
        let smallest = layout.bytes().div_ceil(MAX_CHUNKS as u64);
        return Err(error(format!(
            "chunks of {} bytes cut the scene's {} bytes into {} chunks, more than {MAX_CHUNKS}: use a chunk size of at least {smallest} bytes",
            layout.chunk_bytes,
            layout.bytes(),
            layout.chunk_count()
        )));
    }
    let start = initial_placement(&layout, &budget).map_err(|e| error(e.to_string()))?;
    let (lead, follow) = devices.split_at_mut(leaders);
    let mut prepared = sharing.prepare(lead, scene, frame, &layout, &start)?;

    let begin = Instant::now();
    let counts = count_first_sample(lead, frame)?;
    let prepass_seconds = begin.elapsed().as_secs_f64();

    let placement =
        place_chunks(&layout, &counts, &budget, spec.replication).map_err(|e| error(e.to_string()))?;
    sharing.replace(lead, &placement)?;
    let residency: Vec<Residency> = (0..leaders).map(|d| placement.residency(&layout, d)).collect();
    for (stats, residency) in prepared.iter_mut().zip(&residency) {
        stats.scene_bytes = residency.local();
        stats.shared = Some(*residency);
    }
    // More wavefronts on a leader's hardware read its chunks.
    for (f, device) in follow.iter_mut().enumerate() {
        let leader = lead[hardware[leaders + f]].as_ref();
        prepared.push(device.prepare_sharing(leader, frame)?);
    }
    let local_reads = local_read_share(&placement, &counts);
    let report = SharedReport { layout, counts, placement, residency, local_reads, prepass_seconds };
    Ok((prepared, report))
}

/// The prepass: every device renders its stripe of the frame's first
/// sample (as it will the frame's) and no other, one wave at a time,
/// counting chunk reads; then it is cleared for the frame.
fn count_first_sample(
    devices: &mut [Box<dyn Device>],
    frame: &Arc<FrameContext>,
) -> Result<Vec<Vec<u64>>, DeviceError> {
    for device in devices.iter_mut() {
        device.count_accesses(true)?;
    }
    // Four waves per device at least, however small the image.
    let pixels = frame.options.pixel_count();
    let per_wave = pixels.div_ceil(4 * devices.len().max(1) as u32).clamp(1, frame.options.wave_size.max(1));
    let waves = Wave::all(&RenderOptions { spp: 1, wave_size: per_wave, ..frame.options.clone() });
    let stripes: Vec<usize> = (0..devices.len()).collect();
    let (waves, handout) = StripeHandout::cut(&waves, pixels, &stripes);
    let handout = handout.without_stealing();
    let shape = RunShape { ring: 1, order: RingOrder::Spread, merge: false };
    let mut reports = run_waves(devices, &waves, shape, &[], &handout, &mut |_, _| {})?;
    if let Some(e) = reports.iter_mut().find_map(|r| r.take_error()) {
        return Err(e);
    }
    let mut counts = Vec::with_capacity(devices.len());
    for device in devices.iter_mut() {
        device.count_accesses(false)?;
        counts.push(device.access_counts()?);
        device.reset_frame()?;
    }
    Ok(counts)
}
