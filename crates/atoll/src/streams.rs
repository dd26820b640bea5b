//! Wavefronts per GPU (`--streams`) and the GPU wave size: how many
//! devices share one GPU's copy of the scene (or of a ring's parts), and
//! how many paths each keeps in flight, within its memory.

use std::sync::Arc;

use atoll_bvh::{part_bytes, ScenePart};
use atoll_cuda::device::CudaDevice;
use atoll_cuda::Gpu;
use atoll_dist::Partition;
use atoll_render::{Device, RenderOptions};
use atoll_scene::Scene;

use crate::CliError;

/// Bytes a CUDA device allocates for a frame besides the scene: queues,
/// film, headroom and the frame parameters.
pub fn gpu_frame_bytes(options: &RenderOptions) -> u64 {
    let wave = options.wave_size.min(options.pixel_count()).max(1);
    atoll_cuda::queues::queue_bytes(wave)
        + options.pixel_count() as u64 * 12
        + atoll_cuda::scene::HEADROOM
        // Frame parameters (lights, materials): a generous allowance.
        + (16 << 20)
}

/// Halves the GPU default wave (not one given with `--wave-size`) until
/// the scene (estimated for `part` with the CUDA byte model) and one frame
/// fit `gpu`'s free memory or `budget`, down to 2^16 paths: the larger
/// default must not refuse a scene the smaller one rendered.
pub fn fit_wave_size(
    gpu: &Arc<Gpu>,
    scene: &Scene,
    part: &ScenePart,
    options: &mut RenderOptions,
    budget: Option<u64>,
) {
    let Ok(free) = gpu.free_memory() else { return };
    let available = budget.map_or(free, |b| b.min(free));
    let scene_bytes = part_bytes(scene, part, &atoll_cuda::scene::byte_model());
    while options.wave_size > 1 << 16 && scene_bytes + gpu_frame_bytes(options) > available {
        options.wave_size /= 2;
    }
}

/// For several devices under `--device-memory`: halves the GPU default
/// wave until a frame takes at most an eighth of the budget (down to 2^16
/// paths), so that emulated small memories hold scene parts, not queues.
pub fn fit_wave_to_budget(options: &mut RenderOptions, budget: u64) {
    while options.wave_size > 1 << 16 && gpu_frame_bytes(options) > budget / 8 {
        options.wave_size /= 2;
    }
}

/// How many more copies of a ring's devices (`--streams`) fit: every GPU
/// device of the ring must hold another frame beside its part (the
/// partition's estimate) within its share of its GPU's free memory (or
/// `budget`). 0 unless every device is a GPU.
pub fn ring_stream_copies(
    devices: &mut [Box<dyn Device>],
    streams: usize,
    partition: &Partition,
    options: &RenderOptions,
    budget: Option<u64>,
) -> usize {
    let gpus: Option<Vec<Arc<Gpu>>> = devices
        .iter_mut()
        .map(|d| d.as_any_mut().downcast_mut::<CudaDevice>().map(|c| c.gpu().clone()))
        .collect();
    let (Some(gpus), true) = (gpus, streams > 1) else { return 0 };
    let frame = gpu_frame_bytes(options).max(1);
    let fit = gpus.iter().enumerate().map(|(d, gpu)| {
        let Some(share) = free_share(&gpus, gpu) else { return 0 };
        let available = budget.map_or(share, |b| b.min(share));
        let part = partition.bytes[d % partition.parts.len()];
        (available.saturating_sub(part) / frame).saturating_sub(1) as usize
    });
    fit.min().unwrap_or(0).min(streams - 1)
}

/// `gpu`'s free memory divided among the devices of `gpus` on it (devices
/// listed on one GPU, `cuda:0,cuda:0`, share it); `None` when unreadable.
pub fn free_share(gpus: &[Arc<Gpu>], gpu: &Gpu) -> Option<u64> {
    let sharing = gpus.iter().filter(|g| g.ordinal == gpu.ordinal).count().max(1) as u64;
    gpu.free_memory().ok().map(|free| free / sharing)
}

/// Up to `streams - 1` more devices on `gpu` for replicas sharing the
/// scene of the device already on it (`--streams`): as many as fit beside
/// the scene (estimated with the CUDA byte model) and every device's frame
/// in the GPU's free memory, or in `budget` (the whole GPU's, then).
pub fn extra_streams(
    gpu: &Arc<Gpu>,
    streams: usize,
    scene: &Scene,
    options: &RenderOptions,
    budget: Option<u64>,
) -> Result<Vec<Box<dyn Device>>, CliError> {
    if streams <= 1 {
        return Ok(Vec::new());
    }
    let free = gpu.free_memory().map_err(|e| CliError::Runtime(e.to_string()))?;
    let available = budget.map_or(free, |b| b.min(free));
    let scene_bytes = part_bytes(scene, &ScenePart::whole(scene), &atoll_cuda::scene::byte_model());
    let fit = (available.saturating_sub(scene_bytes) / gpu_frame_bytes(options).max(1)) as usize;
    let n = streams.min(fit).max(1);
    if n < streams {
        tracing::info!("{}: memory for {n} of {streams} wavefronts", gpu.label());
    }
    (1..n)
        .map(|_| {
            let more = gpu.another_stream().map_err(|e| CliError::Runtime(e.to_string()))?;
            let mut d = CudaDevice::on(more);
            d.set_memory_budget(budget);
            Ok(Box::new(d) as Box<dyn Device>)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_budgets_get_smaller_default_waves() {
        let scene = atoll_scene::cornell::builtin_cornell_box();
        let mut options = RenderOptions::from_scene(&scene);
        options.resolution = glam::UVec2::new(1280, 720);
        options.wave_size = atoll_cuda::DEFAULT_WAVE_SIZE;
        let roomy = options.clone();
        fit_wave_to_budget(&mut options, 64 << 30);
        assert_eq!(options.wave_size, roomy.wave_size, "64 GiB holds the default");
        fit_wave_to_budget(&mut options, 2 << 30);
        assert!(options.wave_size < roomy.wave_size && gpu_frame_bytes(&options) <= (2u64 << 30) / 8);
        assert!(
            gpu_frame_bytes(&RenderOptions { wave_size: options.wave_size * 2, ..options.clone() })
                > (2u64 << 30) / 8
        );
        fit_wave_to_budget(&mut options, 1 << 20);
        assert_eq!(options.wave_size, 1 << 16, "never below 2^16 paths");
    }
}
