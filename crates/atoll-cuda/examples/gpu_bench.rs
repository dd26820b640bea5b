//! The GPU BVH benchmark: `cargo run --release -p atoll-cuda --example
//! gpu_bench -- [triangles] [build-triangles...]` on a GPU machine (build it
//! here with `cargo build --release -p atoll-cuda --example gpu_bench` and
//! copy `target/release/examples/gpu_bench`). Traces the procedural bench
//! scene of `triangles` (default 1M); times builds of the others (default 10M).
//! Environment: ATOLL_BENCH_RES=WxH (default 2048x2048), ATOLL_BENCH_RUNS.

use atoll_cuda::bench::{run, GpuBenchOptions};
use atoll_cuda::Gpu;
use glam::UVec2;

fn main() {
    let args: Vec<usize> = std::env::args().skip(1).map(|a| a.parse().expect("triangle counts")).collect();
    let triangles = args.first().copied().unwrap_or(1_000_000);
    let mut opts = GpuBenchOptions::default();
    if args.len() > 1 {
        opts.build_scenes = args[1..].to_vec();
    }
    if let Ok(res) = std::env::var("ATOLL_BENCH_RES") {
        let (w, h) = res.split_once('x').expect("ATOLL_BENCH_RES=WxH");
        opts.resolution = UVec2::new(w.parse().expect("width"), h.parse().expect("height"));
    }
    if let Ok(runs) = std::env::var("ATOLL_BENCH_RUNS") {
        opts.runs = runs.parse().expect("ATOLL_BENCH_RUNS");
    }
    let gpu = match Gpu::open(0) {
        Ok(gpu) => gpu,
        Err(e) => {
            eprintln!("gpu_bench: {e}");
            std::process::exit(2);
        }
    };
    let scene = atoll_scene::procedural::bench_scene(triangles);
    match run(&gpu, &scene, &opts) {
        Ok(report) => print!("{report}"),
        Err(e) => {
            eprintln!("gpu_bench: {e}");
            std::process::exit(1);
        }
    }
}
