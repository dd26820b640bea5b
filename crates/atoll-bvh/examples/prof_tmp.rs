// Scratch driver for profiling (not part of the deliverable).
use atoll_bvh::*;
fn main() {
    let tris: usize = std::env::args().nth(1).map_or(200_000, |s| s.parse().unwrap());
    let res: u32 = std::env::args().nth(2).map_or(256, |s| s.parse().unwrap());
    let wide = std::env::args().nth(3).is_none_or(|s| s == "4");
    let scene = atoll_scene::procedural::bench_scene_flat(tris);
    let opts = bench::BenchOptions { resolution: Some(glam::UVec2::splat(res)), ..Default::default() };
    if wide {
        run::<Bvh4Cpu>(&scene, &opts)
    } else {
        run::<Bvh2>(&scene, &opts)
    }
}
#[inline(never)]
fn primary<L: BvhLayout>(bvh: &SceneBvh<L>, rays: &[Ray]) -> usize {
    rays.iter().filter(|r| bvh.intersect(r).is_some()).count()
}
#[inline(never)]
fn shadow<L: BvhLayout>(bvh: &SceneBvh<L>, rays: &[Ray]) -> usize {
    rays.iter().filter(|r| bvh.occluded(r)).count()
}
#[inline(never)]
fn diffuse<L: BvhLayout>(bvh: &SceneBvh<L>, rays: &[Ray]) -> usize {
    rays.iter().filter(|r| bvh.intersect(r).is_some()).count()
}
fn run<L: BvhLayout>(scene: &atoll_scene::Scene, opts: &bench::BenchOptions) {
    let bvh = SceneBvh::<L>::build(scene);
    let rays = bench::generate_rays(scene, &SceneBvh::<Bvh4Cpu>::build(scene), opts);
    let t = std::time::Instant::now();
    let a = primary(&bvh, &rays.primary);
    let t1 = t.elapsed();
    let b = shadow(&bvh, &rays.shadow);
    let t2 = t.elapsed();
    let c = diffuse(&bvh, &rays.diffuse);
    let t3 = t.elapsed();
    println!(
        "{} hits {a} {b} {c}; Mrays/s {:.2} {:.2} {:.2}",
        L::NAME,
        rays.primary.len() as f64 / t1.as_secs_f64() / 1e6,
        rays.shadow.len() as f64 / (t2 - t1).as_secs_f64() / 1e6,
        rays.diffuse.len() as f64 / (t3 - t2).as_secs_f64() / 1e6
    );
}
