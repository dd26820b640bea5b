//! Many CPU devices render the same image as one: the strategy test bodies
//! shared with the GPUs (`tests/common/strategy_bodies.rs`), run here on
//! CPU devices.

#[path = "common/strategy_bodies.rs"]
mod strategy_bodies;

use atoll_render::{CpuDevice, Device};
use glam::UVec2;
use strategy_bodies::{Kind, Tolerance};

fn cpus(n: usize) -> Vec<Box<dyn Device>> {
    (0..n).map(|i| Box::new(CpuDevice::new().with_name(format!("cpu:{i}"))) as Box<dyn Device>).collect()
}

/// Small images (debug builds render them in CI), matched within float
/// rounding: the CPU's sums differ only in order.
const CPU: Kind = Kind {
    devices: cpus,
    resolution: UVec2::new(40, 40),
    tolerance: Tolerance { relative: 1e-4, absolute: 1e-6, one_in: 500 },
    part_budgets: true,
    shared_chunk: 512,
    shared_growth: 1,
    distinct_memories: || usize::MAX,
};

strategy_bodies::strategy_tests!(CPU);
strategy_bodies::shared_strategy_tests!(CPU);
