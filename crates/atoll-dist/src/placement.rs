//! Placement policy: which strategy a frame's devices use ([`place`]),
//! how the scene is cut for a ring, how much scene each device may hold,
//! and how many more devices (wavefronts: on a GPU, streams) each piece of
//! hardware takes beside the listed ones, within its memory. Decided from
//! the devices' own memory facts ([`Device::free_memory`],
//! [`Device::frame_bytes`], [`Device::byte_model`]), for any device kind.

use std::sync::Arc;

use atoll_bvh::{part_bytes, ByteModel, ScenePart};
use atoll_render::{Device, DeviceError, RenderOptions};
use atoll_scene::Scene;

use crate::partition::{
    partition, plan_partitioned, PartitionError, PartitionOptions, Plan, Strategy, GPU_INSTANCE_COST,
};
use crate::shared::SharedSpec;
use crate::spatial::partition_spatial;
use crate::work::{partition_work_balanced, partition_work_measured};
use crate::{Layout, Partition, RingOrder};

/// How a ring's parts are made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Partitioning {
    /// `Measured` for rings of 2 (`Memory` for scenes too large to
    /// measure on the host), `Cost` for longer rings (what measured
    /// fastest; see [`partition_ring`]).
    #[default]
    Auto,
    /// Compact chunks balanced by bytes and by the frame's estimated ray
    /// work ([`partition_work_balanced`]).
    Work,
    /// As `Work`, the ray work measured: where a low-resolution sample of
    /// the frame's paths hits ([`crate::work::partition_work_measured`]).
    Measured,
    /// Spatial slabs, one region per part ([`partition_spatial`]).
    Spatial,
    /// Objects greedily onto the least-loaded part ([`partition()`]).
    Memory,
    /// As `Memory`, a part's load being its bytes plus this many per
    /// instance it holds: the GPU's ray work ([`GPU_INSTANCE_COST`]).
    Cost(u64),
}

/// Parts for rings of `k` as `partitioning` says, and what they are.
pub fn partition_ring(
    scene: &Arc<Scene>,
    k: usize,
    model: &ByteModel,
    budget: Option<u64>,
    resolution: glam::UVec2,
    partitioning: Partitioning,
    memory_balanced: Option<Partition>,
) -> Result<(Partition, &'static str), PartitionError> {
    let options = PartitionOptions { budget, ..Default::default() };
    // `memory_balanced` was made with these options where it has K parts.
    let memory = || match memory_balanced.filter(|p| p.parts.len() == k) {
        Some(p) => Ok((p, "memory-balanced")),
        None => partition(scene, k, model, &options).map(|p| (p, "memory-balanced")),
    };
    let spatial = || partition_spatial(scene, k, model, &options).map(|p| (p, "spatial slabs"));
    let work = || {
        partition_work_balanced(scene, k, resolution, model, &options).map(|p| (p, "work-balanced chunks"))
    };
    let measured = || {
        partition_work_measured(scene, k, resolution, model, &options)
            .map(|(p, _)| (p, "measured-work chunks"))
    };
    let cost = |per_instance: u64| {
        let options = PartitionOptions { instance_cost: per_instance, ..options };
        partition(scene, k, model, &options).map(|p| (p, "balanced by bytes and instances"))
    };
    match partitioning {
        Partitioning::Memory => memory(),
        Partitioning::Cost(per_instance) => cost(per_instance),
        Partitioning::Spatial => spatial(),
        Partitioning::Work => work(),
        Partitioning::Measured => measured(),
        // Longer rings: bytes and instances, or one part gets every
        // instanced object; bytes alone where that does not fit the budget.
        // Rings of 2: chunks balanced by measured work where measuring is
        // cheap (it builds a BVH over the whole scene on the host), else
        // memory-balanced parts, the least total work; both measured the
        // fastest of their kind (BENCHMARKS.md).
        Partitioning::Auto if k >= 3 => cost(GPU_INSTANCE_COST).or_else(|_| memory()),
        Partitioning::Auto if measuring_is_cheap(scene) => measured().or_else(|_| memory()),
        Partitioning::Auto => memory(),
    }
}

/// Most unique triangles a scene may have for `auto` to measure its
/// rings' work: the measuring render builds a BVH over all of them on the
/// host first.
pub const MEASURE_MAX_TRIANGLES: u64 = 50_000_000;

fn measuring_is_cheap(scene: &Scene) -> bool {
    scene.meshes.iter().map(|m| m.indices.len() as u64).sum::<u64>() <= MEASURE_MAX_TRIANGLES
}

/// The widest of `models`, element by element: what partitioning charges
/// so that every device kind present can hold any part.
pub fn widest_model(models: impl IntoIterator<Item = ByteModel>) -> ByteModel {
    models
        .into_iter()
        .reduce(|a, b| ByteModel {
            per_triangle: a.per_triangle.max(b.per_triangle),
            per_vertex: a.per_vertex.max(b.per_vertex),
            per_instance: a.per_instance.max(b.per_instance),
            per_object: a.per_object.max(b.per_object),
            scratch_per_triangle: a.scratch_per_triangle.max(b.scratch_per_triangle),
        })
        .unwrap_or(ByteModel::CPU)
}

/// What the caller asks of [`place`].
#[derive(Clone, Debug)]
pub struct PlacementRequest {
    /// Replicate, ring or let the scene's size decide.
    pub strategy: Strategy,
    /// Devices per ring; `None`: the fewest the budget allows.
    pub ring_size: Option<usize>,
    /// Memory budget per device (`None`: what each has).
    pub budget: Option<u64>,
    /// How a ring's parts are made.
    pub partitioning: Partitioning,
    /// Where a ring's queues start and end their cycles.
    pub ring_order: RingOrder,
    /// Wavefronts per piece of hardware wanted: more devices beside the
    /// listed ones (on a GPU, streams) sharing their scene or parts.
    pub streams: usize,
    /// How a shared scene is cut and placed (its budget is `budget`).
    pub shared: SharedSpec,
    /// Per listed device, whether it may take more wavefronts beside it
    /// when replicating (not when the same GPU is listed twice: those
    /// devices already share it).
    pub may_add_wavefronts: Vec<bool>,
}

/// What [`place`] decided.
#[derive(Clone, Debug)]
pub struct Placement {
    /// The strategy and, for rings, their size and number.
    pub plan: Plan,
    /// Where the scene goes on the devices (those `place` kept and added).
    pub layout: Layout,
    /// The ring's partition, and what kind it is.
    pub partition: Option<(Partition, &'static str)>,
    /// Lines worth telling the user (devices left idle, wavefronts added).
    pub notes: Vec<String>,
}

/// Why [`place`] failed.
#[derive(Debug, thiserror::Error)]
pub enum PlacementError {
    /// The request itself is inconsistent (a ring size out of range).
    #[error("{0}")]
    Request(String),
    /// The scene does not fit the devices as asked, or cannot be cut.
    #[error(transparent)]
    Partition(#[from] PartitionError),
    /// A device could not be added beside another.
    #[error(transparent)]
    Device(#[from] DeviceError),
}

/// Chooses the strategy for `devices` rendering `scene` (replicate when the
/// scene fits each device, else shared scene memory where the devices can
/// share it and have memory of their own, else rings of the fewest
/// devices that hold it),
/// partitions the scene for rings, and adds the further devices
/// `request.streams` asks for (more islands over the same hardware, or
/// more replicas sharing a scene). Devices a ring plan cannot use (N not a
/// multiple of K) are dropped.
pub fn place(
    devices: &mut Vec<Box<dyn Device>>,
    scene: &Arc<Scene>,
    options: &RenderOptions,
    request: &PlacementRequest,
) -> Result<Placement, PlacementError> {
    let n = devices.len();
    let start = std::time::Instant::now();
    let model = widest_model(devices.iter().map(|d| d.byte_model()));
    // Replicas on one GPU share one copy of the scene; ring members on one
    // GPU hold different parts, so each has its share of the memory.
    let replica_budget = scene_budget(devices, scene, request.budget, options, Sharing::Scene);
    let budget = scene_budget(devices, scene, request.budget, options, Sharing::Memory);
    // The memory-balanced partition that found a ring's K, for reuse.
    let mut found = None;
    let mut planned = |budget, strategy| {
        plan_partitioned(scene, &model, n, budget, Some(strategy)).map(|(plan, partition)| {
            found = partition;
            plan
        })
    };
    let plan = match (request.strategy, request.ring_size) {
        (Strategy::Ring, Some(k)) if (2..=n).contains(&k) => Plan::Ring { k, islands: n / k },
        (_, Some(k)) => {
            return Err(PlacementError::Request(format!(
                "--ring-size {k}: needs --strategy ring and between 2 and {n} (the devices listed)"
            )))
        }
        (Strategy::Ring, None) => planned(budget, Strategy::Ring)?,
        (Strategy::Replicate, None) => planned(replica_budget, Strategy::Replicate)?,
        (Strategy::Shared, None) => Plan::Shared,
        (Strategy::Auto, None) => match planned(replica_budget, Strategy::Replicate) {
            Ok(p) => p,
            Err(_) if sharing_is_faster(devices, scene) => Plan::Shared,
            Err(_) => planned(budget, Strategy::Auto)?,
        },
    };
    tracing::info!("planned {plan:?} in {:.2} s", start.elapsed().as_secs_f64());
    let start = std::time::Instant::now();
    let mut notes = Vec::new();
    let (layout, partition) = match plan {
        Plan::Replicate => {
            // Replicas on one GPU share one copy of the scene (the first
            // prepares it, the others add only their queues and film, each
            // checked against what is then free): no shared-out budgets.
            for d in devices.iter_mut() {
                d.set_memory_budget(request.budget);
            }
            (Layout::Replicate, None)
        }
        Plan::Ring { k, islands } => {
            let (p, kind) =
                partition_ring(scene, k, &model, budget, options.resolution, request.partitioning, found)?;
            (Layout::Ring { parts: p.parts.clone(), islands, order: request.ring_order }, Some((p, kind)))
        }
        Plan::Shared => {
            for d in devices.iter_mut() {
                d.set_memory_budget(request.budget);
            }
            (Layout::Shared(SharedSpec { budget: request.budget, ..request.shared }), None)
        }
    };
    let used = match plan {
        Plan::Ring { k, islands } => k * islands,
        Plan::Replicate | Plan::Shared => n,
    };
    if used < n {
        notes.push(format!("{} of {n} devices idle (rings of {used} devices in all)", n - used));
    }
    tracing::info!("partitioned the scene in {:.2} s", start.elapsed().as_secs_f64());
    let start = std::time::Instant::now();
    devices.truncate(used);
    let mut layout = layout;
    match (&mut layout, &partition) {
        (Layout::Ring { parts, islands, .. }, Some((p, _))) => {
            // More islands over the same hardware, each member sharing the
            // part of the device it copies: while one ring waits on a
            // hand-over, the others' kernels keep the GPUs busy.
            let copies = ring_copies(devices, request.streams, p, options, request.budget);
            let ring = parts.len();
            for _ in 0..copies {
                for d in 0..ring * *islands {
                    let Some(more) = devices[d].another_on_same_hardware() else { continue };
                    let mut more = more?;
                    more.set_memory_budget(request.budget);
                    devices.push(more);
                }
            }
            if copies > 0 {
                notes
                    .push(format!("{} islands of {ring} sharing their GPUs' parts", *islands * (copies + 1)));
                *islands *= copies + 1;
            }
        }
        _ => {
            // A replica holds the whole scene, a device sharing its memory
            // about an even share of it.
            let whole = ScenePart::whole(scene);
            let (sharing, what) = match plan {
                Plan::Shared => (n.max(1) as u64, "its share of the scene"),
                _ => (1, "its replica"),
            };
            for d in 0..n {
                if !request.may_add_wavefronts.get(d).copied().unwrap_or(false) {
                    continue;
                }
                let held = part_bytes(scene, &whole, &devices[d].byte_model()).div_ceil(sharing);
                let more = more_wavefronts_beside(
                    devices[d].as_ref(),
                    request.streams,
                    held,
                    options,
                    request.budget,
                )?;
                if !more.is_empty() {
                    notes.push(format!(
                        "{}: {} wavefronts sharing {what}",
                        devices[d].name(),
                        more.len() + 1
                    ));
                }
                devices.extend(more);
            }
        }
    }
    tracing::info!("added {} devices in {:.2} s", devices.len() - used, start.elapsed().as_secs_f64());
    Ok(Placement { plan, layout, partition, notes })
}

/// Whether `auto` shares the scene's memory rather than cutting it for
/// rings: on devices with memory of their own (GPUs) that can share it
/// ([`Device::scene_sharing`], direct access between every pair), which
/// measured faster than the ring on the landscape (BENCHMARKS.md, shared
/// scene memory). CPU devices draw on one memory: their rings stay.
fn sharing_is_faster(devices: &[Box<dyn Device>], scene: &Scene) -> bool {
    let own_memory = devices.len() > 1 && devices.iter().all(|d| d.free_memory().is_some());
    let Some(sharing) = devices.first().and_then(|d| d.scene_sharing()).filter(|_| own_memory) else {
        return false;
    };
    match sharing.supports(devices, scene) {
        Ok(()) if sharing.lays_out_slowly(scene) => {
            tracing::info!(
                "not sharing the scene's memory: no device has room to build it, and the host builds slowly"
            );
            false
        }
        Ok(()) => true,
        Err(why) => {
            tracing::info!("not sharing the scene's memory: {why}");
            false
        }
    }
}

pub use atoll_render::device::host_memory_available;

/// What devices listed on one piece of hardware share of it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sharing {
    /// One copy of the scene (replicas): each adds only its frame.
    Scene,
    /// The memory, evenly (ring members holding different parts).
    Memory,
}

/// Devices of `devices` drawing on `device`'s memory, itself included.
fn sharing_memory(devices: &[Box<dyn Device>], device: &dyn Device) -> usize {
    devices.iter().filter(|d| std::ptr::addr_eq(d.as_ref(), device) || d.shares_memory_with(device)).count()
}

/// `device`'s free memory divided among the devices of `devices` on the
/// same hardware; `None` where the device has no figure (host memory).
pub fn free_share(devices: &[Box<dyn Device>], device: &dyn Device) -> Option<u64> {
    device.free_memory().map(|free| free / sharing_memory(devices, device).max(1) as u64)
}

/// Bytes of scene (geometry, BVH) each device may hold: the budget (or,
/// for devices with memory of their own and no budget, their free memory,
/// shared as `sharing` says) less what every device allocates for the
/// frame itself (queues, film, parameters, headroom). `None`: no limit
/// known (devices on host memory without a budget).
pub fn scene_budget(
    devices: &[Box<dyn Device>],
    scene: &Scene,
    budget: Option<u64>,
    options: &RenderOptions,
    sharing: Sharing,
) -> Option<u64> {
    let with_memory: Vec<&dyn Device> =
        devices.iter().map(|d| d.as_ref()).filter(|d| d.free_memory().is_some()).collect();
    let free = with_memory
        .iter()
        .filter_map(|&d| match sharing {
            Sharing::Memory => free_share(devices, d),
            Sharing::Scene => {
                let others = sharing_memory(devices, d).saturating_sub(1) as u64;
                d.free_memory().map(|f| f.saturating_sub(others * d.frame_bytes(options)))
            }
        })
        .min();
    let total = match (budget, free) {
        (Some(b), Some(f)) => Some(b.min(f)),
        (Some(b), None) => Some(b),
        // Every device with memory of its own and no budget: what they have free.
        (None, Some(f)) if with_memory.len() == devices.len() => Some(f),
        (None, _) => None,
    }?;
    if with_memory.is_empty() {
        return Some(total);
    }
    // The rows every device's tables keep for the whole scene are not in
    // the byte model's charge for a part.
    let frame =
        with_memory.iter().map(|d| d.frame_bytes(options) + d.scene_wide_bytes(scene)).max().unwrap_or(0);
    Some(total.saturating_sub(frame))
}

/// How many more copies of a ring's devices (more islands over the same
/// hardware) fit: every device of the ring must hold another frame beside
/// its part (the partition's estimate) within its share of its free memory
/// (or `budget`). 0 unless every device has memory of its own and can have
/// another device beside it.
pub fn ring_copies(
    devices: &[Box<dyn Device>],
    wanted: usize,
    partition: &Partition,
    options: &RenderOptions,
    budget: Option<u64>,
) -> usize {
    if wanted <= 1 {
        return 0;
    }
    let fit = devices.iter().enumerate().map(|(d, device)| {
        let Some(share) = free_share(devices, device.as_ref()) else { return 0 };
        let available = budget.map_or(share, |b| b.min(share));
        let part = partition.bytes[d % partition.parts.len()];
        (available.saturating_sub(part) / device.frame_bytes(options).max(1)).saturating_sub(1) as usize
    });
    fit.min().unwrap_or(0).min(wanted - 1)
}

/// Up to `wanted - 1` more devices beside `device` for replicas sharing
/// its scene (on a GPU, more streams): as many as fit beside the scene
/// (estimated with the device's byte model) and every device's frame in
/// its free memory, or in `budget`. None where the device kind takes no
/// others beside it.
pub fn more_wavefronts(
    device: &dyn Device,
    wanted: usize,
    scene: &Scene,
    options: &RenderOptions,
    budget: Option<u64>,
) -> Result<Vec<Box<dyn Device>>, DeviceError> {
    let scene_bytes = part_bytes(scene, &ScenePart::whole(scene), &device.byte_model());
    more_wavefronts_beside(device, wanted, scene_bytes, options, budget)
}

/// [`more_wavefronts`] beside a device holding `scene_bytes` of scene.
pub fn more_wavefronts_beside(
    device: &dyn Device,
    wanted: usize,
    scene_bytes: u64,
    options: &RenderOptions,
    budget: Option<u64>,
) -> Result<Vec<Box<dyn Device>>, DeviceError> {
    let Some(free) = device.free_memory().filter(|_| wanted > 1) else { return Ok(Vec::new()) };
    let available = budget.map_or(free, |b| b.min(free));
    let fit = (available.saturating_sub(scene_bytes) / device.frame_bytes(options).max(1)) as usize;
    let n = wanted.min(fit).max(1);
    if n < wanted {
        tracing::info!("{}: memory for {n} of {wanted} wavefronts", device.name());
    }
    let mut more = Vec::new();
    for _ in 1..n {
        match device.another_on_same_hardware() {
            Some(d) => {
                let mut d = d?;
                d.set_memory_budget(budget);
                more.push(d);
            }
            None => break,
        }
    }
    Ok(more)
}
