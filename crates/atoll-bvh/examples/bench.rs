//! Runs the traversal benchmark on the procedural landscape and optionally
//! exports its triangles, rays and results for `scripts/bench-embree.py`.
//!
//! ```text
//! cargo run --release -p atoll-bvh --example bench -- \
//!     [--triangles 2000000] [--instanced] [--threads 1,2] [--runs 5] [--builds 3]
//!     [--resolution 1024] [--export DIR]
//! ```
//! Without `--instanced` the scene is flattened to world-space triangles,
//! the fair comparison with a single-level Embree scene.

use std::path::PathBuf;

use atoll_bvh::bench::{export_bench_data, run_traversal_bench, BenchOptions};
use atoll_scene::procedural::{bench_scene, bench_scene_flat};
use glam::UVec2;

fn main() {
    let mut triangles = 2_000_000;
    let mut instanced = false;
    let mut export: Option<PathBuf> = None;
    let mut opts = BenchOptions { threads: vec![1, 0], ..Default::default() };
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = || args.next().unwrap_or_else(|| fail(&format!("{arg} needs a value")));
        match arg.as_str() {
            "--triangles" => triangles = parse(&value()),
            "--instanced" => instanced = true,
            "--threads" => opts.threads = value().split(',').map(parse).collect(),
            "--runs" => opts.runs = parse(&value()),
            "--builds" => opts.builds = parse(&value()),
            "--resolution" => opts.resolution = Some(UVec2::splat(parse(&value()) as u32)),
            "--export" => export = Some(value().into()),
            _ => fail(&format!("unknown argument {arg}")),
        }
    }
    let scene = if instanced { bench_scene(triangles) } else { bench_scene_flat(triangles) };
    let report = run_traversal_bench(&scene, &opts);
    print!("{report}");
    if let Some(dir) = export {
        export_bench_data(&scene, &opts, &dir).unwrap_or_else(|e| fail(&format!("export: {e}")));
        std::fs::write(dir.join("atoll.json"), report.to_json()).unwrap_or_else(|e| fail(&e.to_string()));
        println!("exported to {}", dir.display());
    }
}

fn parse(s: &str) -> usize {
    s.replace('_', "").parse().unwrap_or_else(|_| fail(&format!("not a number: {s}")))
}

fn fail(message: &str) -> ! {
    eprintln!("bench: {message}");
    std::process::exit(2)
}
