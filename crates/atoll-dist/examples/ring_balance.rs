//! Temporary: parts by instance cost.
use atoll_dist::{partition, PartitionOptions, partition::GPU_INSTANCE_COST};
use atoll_scene::landscape::Landscape;
fn main() {
    let growth: u32 = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(100);
    let scene = Landscape::new(growth).build();
    let model = atoll_cuda::scene::byte_model();
    for cost in [0, GPU_INSTANCE_COST] {
        let p = partition(&scene, 2, &model, &PartitionOptions { instance_cost: cost, ..Default::default() }).unwrap();
        let inst: Vec<usize> = p.parts.iter().map(|p| p.instances.len()).collect();
        let load: Vec<f64> = p.bytes.iter().zip(&inst).map(|(&b, &i)| (b + cost.max(GPU_INSTANCE_COST) * i as u64) as f64 / 1e6).collect();
        println!("cost {cost}: bytes {:?} instances {inst:?} modelled load (MB) {load:?}", p.bytes);
    }
}
