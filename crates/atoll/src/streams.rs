//! The GPU wave size, chosen before devices are opened: how many paths a
//! GPU keeps in flight within its memory. (How many devices share one
//! GPU is `atoll_dist::placement`'s.)

use std::sync::Arc;

use atoll_bvh::{part_bytes, ScenePart};
use atoll_cuda::device::frame_bytes as gpu_frame_bytes;
use atoll_cuda::Gpu;
use atoll_render::RenderOptions;
use atoll_scene::Scene;

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
