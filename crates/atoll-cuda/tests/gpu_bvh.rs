//! The GPU BVH on a real GPU: the radix sort and scan, the LBVH build
//! (compared bit for bit with the host reference, and checked), traversal
//! (every variant and triangle test against brute force) and its SAH
//! against the CPU's binned-SAH builder. Ignored unless asked for
//! (`--include-ignored`); see tests/common.

mod common;

use atoll_bvh::Ray;
use atoll_cuda::bvh::sort::{morton_passes, SortKernels, SortPass, SortScratch};
use atoll_cuda::bvh::testing::{brute_force, random_rays, random_scene, Rng};
use atoll_cuda::bvh::{reference, BuildOptions, GpuSceneBvh, HostSceneBvh, ScenePlan, TriangleTest};
use atoll_cuda::layout::{GpuRecord, HitRef, HIT_NONE};
use atoll_cuda::scene::SceneTables;
use atoll_cuda::trace::{trace_any_with, trace_closest_with, TraversalVariant};
use atoll_cuda::{Gpu, GpuScene};
use atoll_render::record::flags;
use cudarc::driver::CudaSlice;

use common::gpu_or_skip;

fn upload(gpu: &Gpu, v: &[u32]) -> CudaSlice<u32> {
    gpu.stream.clone_htod(v).unwrap()
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn scan_matches_the_host() {
    let Some(gpu) = gpu_or_skip("scan") else { return };
    let k = SortKernels::load(&gpu).unwrap();
    let mut rng = Rng(1);
    for n in [1u32, 2, 2047, 2048, 2049, 100_000, 3_000_001] {
        let data: Vec<u32> = (0..n).map(|_| rng.below(5)).collect();
        let mut scratch = SortScratch::new(&gpu, 1, n).unwrap();
        // In place, then from one buffer into another (the input kept).
        let mut d = upload(&gpu, &data);
        k.scan_in_place(&gpu, &mut d, n, &mut scratch).unwrap();
        let in_place = gpu.stream.clone_dtoh(&d).unwrap();
        let in_place_total = gpu.stream.clone_dtoh(&scratch.total).unwrap()[0];
        let input = upload(&gpu, &data);
        let mut output = upload(&gpu, &vec![7; n as usize]);
        k.scan(&gpu, &input, &mut output, n, &mut scratch).unwrap();
        assert_eq!(gpu.stream.clone_dtoh(&input).unwrap(), data, "n = {n}: the input changed");
        let into = gpu.stream.clone_dtoh(&output).unwrap();
        let into_total = gpu.stream.clone_dtoh(&scratch.total).unwrap()[0];
        for (got, total) in [(in_place, in_place_total), (into, into_total)] {
            let mut sum = 0;
            for (i, &x) in data.iter().enumerate() {
                assert_eq!(got[i], sum, "n = {n}, i = {i}");
                sum += x;
            }
            assert_eq!(total, sum, "n = {n}");
        }
    }
}

/// Sorts on the GPU and checks against a stable host sort by `order`.
fn check_sort(gpu: &Gpu, k: &SortKernels, keys: &[u32], seg_start: &[u32], passes: &[SortPass]) {
    let n = keys.len() as u32;
    let values: Vec<u32> = (0..n).collect();
    let (mut dk, mut dv) = (upload(gpu, keys), upload(gpu, &values));
    let (mut ak, mut av) = (upload(gpu, keys), upload(gpu, &values));
    let seg = upload(gpu, seg_start);
    let mut scratch = SortScratch::new(gpu, n, 1).unwrap();
    let segments = seg_start.len() as u32 - 1;
    k.sort_pairs(gpu, &mut dk, &mut dv, &mut ak, &mut av, n, passes, &seg, segments, &mut scratch).unwrap();
    let (got_k, got_v) = (gpu.stream.clone_dtoh(&dk).unwrap(), gpu.stream.clone_dtoh(&dv).unwrap());
    let mut expected = values.clone();
    expected.sort_by_key(|&p| (reference::segment_of(p, seg_start), keys[p as usize]));
    assert_eq!(got_v, expected, "n = {n}: values (stability)");
    let expected_keys: Vec<u32> = expected.iter().map(|&p| keys[p as usize]).collect();
    assert_eq!(got_k, expected_keys, "n = {n}: keys");
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn radix_sort_is_stable_with_duplicates_and_segments() {
    let Some(gpu) = gpu_or_skip("radix sort") else { return };
    let k = SortKernels::load(&gpu).unwrap();
    let mut rng = Rng(2);
    let all_bits: Vec<SortPass> = (0..4).map(|i| SortPass { shift: 8 * i, from_segment: false }).collect();
    for n in [1u32, 4095, 4096, 4097, 1_000_003] {
        // Full 32-bit keys, and few distinct keys (long runs across tiles).
        let keys: Vec<u32> = (0..n).map(|_| rng.below(u32::MAX)).collect();
        check_sort(&gpu, &k, &keys, &[0, n], &all_bits);
        let keys: Vec<u32> = (0..n).map(|_| rng.below(7) << 20).collect();
        check_sort(&gpu, &k, &keys, &[0, n], &all_bits);
    }
    // 30-bit codes in 300 segments: the Morton passes plus two segment passes.
    let n = 200_000u32;
    let keys: Vec<u32> = (0..n).map(|_| rng.below(1 << 30)).collect();
    let mut seg_start: Vec<u32> = (0..300).map(|s| s * s * 2).collect();
    seg_start.push(n);
    check_sort(&gpu, &k, &keys, &seg_start, &morton_passes(300));
}

/// The index of the first difference of two tables, for messages.
fn first_difference<T: PartialEq + std::fmt::Debug>(what: &str, a: &[T], b: &[T]) -> Option<String> {
    if a.len() != b.len() {
        return Some(format!("{what}: {} vs {} entries", a.len(), b.len()));
    }
    a.iter()
        .zip(b)
        .position(|(x, y)| x != y)
        .map(|i| format!("{what}[{i}]: GPU {:?} vs host {:?}", a[i], b[i]))
}

fn compare_with_reference(gpu_bvh: &HostSceneBvh, host: &HostSceneBvh) {
    let problems: Vec<String> = [
        first_difference("blas_nodes", &gpu_bvh.blas_nodes, &host.blas_nodes),
        first_difference("tlas_nodes", &gpu_bvh.tlas_nodes, &host.tlas_nodes),
        first_difference("tris", &gpu_bvh.tris, &host.tris),
        first_difference("tri_ids", &gpu_bvh.tri_ids, &host.tri_ids),
        first_difference("instances", &gpu_bvh.instances, &host.instances),
        first_difference("blas_roots", &gpu_bvh.blas_roots, &host.blas_roots),
        first_difference("blas_bounds", &gpu_bvh.blas_bounds, &host.blas_bounds),
        first_difference("blas_tri_bases", &gpu_bvh.blas_tri_bases, &host.blas_tri_bases),
        (gpu_bvh.tlas_root != host.tlas_root)
            .then(|| format!("tlas_root {} vs {}", gpu_bvh.tlas_root, host.tlas_root)),
    ]
    .into_iter()
    .flatten()
    .collect();
    assert!(problems.is_empty(), "GPU build differs from the host reference:\n{}", problems.join("\n"));
}

fn scenes() -> Vec<(&'static str, atoll_scene::Scene)> {
    vec![
        ("random", random_scene(21, 8, 2000, 60)),
        ("many small objects", random_scene(22, 300, 20, 400)),
        ("bench", atoll_scene::procedural::bench_scene(100_000)),
    ]
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn gpu_build_equals_the_host_reference_and_is_valid() {
    let Some(gpu) = gpu_or_skip("build") else { return };
    for (name, scene) in scenes() {
        let tables = SceneTables::build(&scene);
        let plan = ScenePlan::new(&tables.objects, &tables.instances);
        let gpu_scene = GpuScene::upload_tables(&gpu, tables.clone()).unwrap();
        for options in [BuildOptions::lbvh(), BuildOptions::default()] {
            let bvh = GpuSceneBvh::build_with(&gpu, &gpu_scene, &options).unwrap();
            let got = bvh.download(&gpu).unwrap();
            got.check(&plan).unwrap_or_else(|e| panic!("{name}, {} rounds: {e}", options.treelet_rounds));
            compare_with_reference(&got, &reference::build_scene(&tables, &options));
            let s = bvh.stats();
            println!("{name}, {} rounds: {:?}", options.treelet_rounds, s);
            assert!(
                s.build_bytes
                    <= atoll_cuda::bvh::build_bytes(s.triangles as u64, s.blases as u64, s.instances as u64)
            );
            let (host_sah, _) = got.sah(options.intersection_cost, options.traversal_cost);
            assert!(
                (host_sah - s.blas_sah).abs() <= 1e-3 * host_sah,
                "SAH {host_sah} vs tracked {}",
                s.blas_sah
            );
        }
    }
}

/// The build in pieces (shared scene memory's, for scenes no GPU builds
/// whole) equals its host reference bit for bit, with objects whole and
/// cut into segments, and is valid.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn gpu_build_in_pieces_equals_the_host_reference() {
    let Some(gpu) = gpu_or_skip("build in pieces") else { return };
    for (name, scene) in scenes() {
        let tables = SceneTables::build(&scene);
        let largest = tables.objects.iter().map(|o| o.triangle_count).max().unwrap();
        let options = BuildOptions::default();
        for capacity in [largest, largest / 5 + 1] {
            let (plan, got) = atoll_cuda::bvh::build_in_pieces(&gpu, &tables, capacity, &options).unwrap();
            got.check(&plan).unwrap_or_else(|e| panic!("{name}, pieces of {capacity}: {e}"));
            let (host_plan, host) = reference::build_in_pieces(&tables, capacity, &options).unwrap();
            assert_eq!(plan, host_plan);
            compare_with_reference(&got, &host);
            println!(
                "{name}, pieces of {capacity}: {} BLASes, {} TLAS records",
                plan.seg_object.len(),
                got.instances.len()
            );
        }
    }
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn empty_and_tiny_scenes_build_and_trace() {
    let Some(gpu) = gpu_or_skip("tiny") else { return };
    // Objects: one triangle (0) and none (1).
    let objects = random_scene(5, 2, 1, 0);
    let one = atoll_scene::Instance::new(0, glam::Affine3A::IDENTITY);
    let tiny = [
        atoll_scene::Scene::default(),
        atoll_scene::Scene { instances: Vec::new(), ..objects.clone() },
        atoll_scene::Scene { instances: vec![one], ..objects.clone() },
        objects,
    ];
    for s in tiny {
        let tables = SceneTables::build(&s);
        let gpu_scene = GpuScene::upload_tables(&gpu, tables.clone()).unwrap();
        let bvh = GpuSceneBvh::build(&gpu, &gpu_scene).unwrap();
        compare_with_reference(
            &bvh.download(&gpu).unwrap(),
            &reference::build_scene(&tables, &BuildOptions::default()),
        );
        let rays = random_rays(3, 1000);
        let (hits, _) = trace_on_gpu(&gpu, &gpu_scene, &bvh, &rays, TraversalVariant::default(), false);
        let plan = ScenePlan::new(&tables.objects, &tables.instances);
        for (ray, hit) in rays.iter().zip(&hits) {
            assert_eq!(hit.instance == HIT_NONE, brute_force(&tables, &plan, ray).is_none());
        }
        // Zero rays is a no-op.
        let mut records = gpu.stream.alloc_zeros::<GpuRecord>(1).unwrap();
        let mut h = gpu.stream.alloc_zeros::<HitRef>(1).unwrap();
        trace_closest_with(&gpu, &gpu_scene, &bvh, &mut records, 0, &mut h, TraversalVariant::Persistent)
            .unwrap();
    }
}

fn records(rays: &[Ray]) -> Vec<GpuRecord> {
    rays.iter()
        .enumerate()
        .map(|(i, r)| {
            let mut rec = GpuRecord::from_ray(r, i as u32);
            // Every 11th shadow ray starts occluded: trace_any must skip it.
            if i % 11 == 0 {
                rec.0.flags = flags::OCCLUDED;
            }
            rec
        })
        .collect()
}

/// Closest hits (and the records after) or any-hit records of `rays`.
fn trace_on_gpu(
    gpu: &Gpu,
    scene: &GpuScene,
    bvh: &GpuSceneBvh,
    rays: &[Ray],
    variant: TraversalVariant,
    any: bool,
) -> (Vec<HitRef>, Vec<GpuRecord>) {
    let mut recs = gpu.stream.clone_htod(&records(rays)).unwrap();
    let mut hits = gpu.stream.alloc_zeros::<HitRef>(rays.len()).unwrap();
    let n = rays.len() as u32;
    if any {
        trace_any_with(gpu, scene, bvh, &mut recs, n, variant).unwrap();
    } else {
        trace_closest_with(gpu, scene, bvh, &mut recs, n, &mut hits, variant).unwrap();
    }
    (gpu.stream.clone_dtoh(&hits).unwrap(), gpu.stream.clone_dtoh(&recs).unwrap())
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn gpu_traversal_matches_brute_force() {
    let Some(gpu) = gpu_or_skip("traversal") else { return };
    let scene = random_scene(31, 10, 3000, 80);
    let tables = SceneTables::build(&scene);
    let plan = ScenePlan::new(&tables.objects, &tables.instances);
    let gpu_scene = GpuScene::upload_tables(&gpu, tables.clone()).unwrap();
    let rays = random_rays(32, 20_000);
    let truth: Vec<_> = rays.iter().map(|r| brute_force(&tables, &plan, r)).collect();
    let hit_count = truth.iter().filter(|h| h.is_some()).count();
    assert!(hit_count > rays.len() / 5, "{hit_count} hits");
    for test in [TriangleTest::Exact, TriangleTest::Woop] {
        let bvh = GpuSceneBvh::build_with(
            &gpu,
            &gpu_scene,
            &BuildOptions { triangle_test: test, ..Default::default() },
        )
        .unwrap();
        for variant in TraversalVariant::ALL {
            let (hits, recs) = trace_on_gpu(&gpu, &gpu_scene, &bvh, &rays, variant, false);
            let mut differ = Vec::new();
            for (i, (want, (hit, rec))) in truth.iter().zip(hits.iter().zip(&recs)).enumerate() {
                let ok = match want {
                    None => hit.instance == HIT_NONE && rec.0.t_max == rays[i].t_max,
                    // Bit-identical t (the triangle may differ where duplicates share it).
                    Some(w) if test == TriangleTest::Exact => rec.0.t_max == w.t && hit.instance != HIT_NONE,
                    Some(w) => hit.instance != HIT_NONE && (rec.0.t_max - w.t).abs() <= 1e-4 * w.t,
                };
                if !ok {
                    differ.push(format!("ray {i}: GPU {hit:?} t {} vs {want:?}", rec.0.t_max));
                }
            }
            let allowed = if test == TriangleTest::Exact { 0 } else { rays.len() / 500 };
            println!("{test:?} {}: {} of {} closest hits differ", variant.name(), differ.len(), rays.len());
            assert!(
                differ.len() <= allowed,
                "{test:?} {}:\n{}",
                variant.name(),
                differ[..differ.len().min(10)].join("\n")
            );

            let (_, recs) = trace_on_gpu(&gpu, &gpu_scene, &bvh, &rays, variant, true);
            let wrong = recs
                .iter()
                .enumerate()
                .filter(|(i, r)| r.0.has(flags::OCCLUDED) != (i % 11 == 0 || truth[*i].is_some()))
                .count();
            assert!(wrong <= allowed, "{test:?} {}: {wrong} any-hit results wrong", variant.name());
        }
    }
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn sah_against_the_cpu_binned_builder() {
    let Some(gpu) = gpu_or_skip("sah") else { return };
    let scene = atoll_scene::procedural::bench_scene(1_000_000);
    let cpu =
        atoll_bvh::SceneBvh::<atoll_bvh::Bvh2>::build_layout(&scene, &atoll_bvh::ScenePart::whole(&scene))
            .stats();
    let gpu_scene = GpuScene::upload_tables(&gpu, SceneTables::build(&scene)).unwrap();
    for options in [BuildOptions::lbvh(), BuildOptions::default()] {
        let bvh = GpuSceneBvh::build_with(&gpu, &gpu_scene, &options).unwrap();
        let (blas, tlas) = bvh.download(&gpu).unwrap().sah(1.0, 1.0);
        println!(
            "{} treelet rounds: BLAS SAH {blas:.2} vs CPU binned {:.2} ({:+.1}%), TLAS {tlas:.2} vs {:.2}; {:.1} Mtris/s",
            options.treelet_rounds,
            cpu.blas.sah_cost,
            100.0 * (blas / cpu.blas.sah_cost - 1.0),
            cpu.tlas.sah_cost,
            bvh.stats().mtris_per_s()
        );
        assert!(blas < 1.3 * cpu.blas.sah_cost);
    }
}
