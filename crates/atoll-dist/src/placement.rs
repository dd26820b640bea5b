//! Placement policy: how much scene each device may hold, and how many
//! more devices (wavefronts: on a GPU, streams) each piece of hardware
//! takes beside the listed ones, within its memory. Decided from the
//! devices' own memory facts ([`Device::free_memory`],
//! [`Device::frame_bytes`], [`Device::byte_model`]), for any device kind.

use atoll_bvh::{part_bytes, ScenePart};
use atoll_render::{Device, DeviceError, RenderOptions};
use atoll_scene::Scene;

use crate::Partition;

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
    let Some(free) = device.free_memory().filter(|_| wanted > 1) else { return Ok(Vec::new()) };
    let available = budget.map_or(free, |b| b.min(free));
    let scene_bytes = part_bytes(scene, &ScenePart::whole(scene), &device.byte_model());
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
