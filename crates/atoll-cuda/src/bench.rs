//! The GPU BVH benchmark (BENCHMARKS.md's GPU BVH figures in one run): LBVH
//! build speed per phase and quality against the CPU's binned-SAH builder,
//! then rays/s for primary, shadow (AO) and diffuse batches per traversal
//! variant and triangle test. Rays are `atoll_bvh::bench`'s (same views,
//! same hashes), hit counts are checked against the CPU; times are CUDA
//! events around each launch, after a warm-up, median of `runs`.
//!
//! `cargo run --release -p atoll-cuda --example gpu_bench` runs it; the
//! [`std::fmt::Display`] of [`GpuBenchReport`] is the table to record in BENCHMARKS.md.

use std::fmt;
use std::sync::Arc;
use std::time::Instant;

use atoll_bvh::bench::{generate_rays, BenchOptions};
use atoll_bvh::{Bvh2, Ray, SceneBvh, ScenePart};
use atoll_render::record::flags;
use atoll_scene::Scene;
use cudarc::driver::sys::CUevent_flags;
use cudarc::driver::CudaSlice;
use glam::UVec2;

use crate::bvh::{BuildOptions, GpuSceneBvh, TriangleTest};
use crate::error::CudaError;
use crate::gpu::Gpu;
use crate::layout::{GpuRecord, HitRef, HIT_NONE};
use crate::scene::{GpuScene, SceneTables};
use crate::trace::{Tracer, TraversalVariant};

/// What to measure.
#[derive(Clone, Debug, PartialEq)]
pub struct GpuBenchOptions {
    /// Primary rays per axis.
    pub resolution: UVec2,
    /// Timed runs per measurement (after one warm-up); the median is reported.
    pub runs: usize,
    pub variants: Vec<TraversalVariant>,
    pub tests: Vec<TriangleTest>,
    /// Also time builds of `atoll_scene::procedural::bench_scene_flat(n)`
    /// (every triangle unique, none instanced) for each `n` here (the
    /// 10M-triangle build target); empty: none.
    pub build_scenes: Vec<usize>,
    /// Shadow-ray length as a fraction of the scene diagonal (as the CPU bench).
    pub shadow_fraction: f32,
    /// The quality builds timed beside the plain LBVH, as (treelet rounds,
    /// first round's gamma): the default's, or a sweep of them.
    pub quality_builds: Vec<(u32, u32)>,
    /// Time traversal too (else the builds only).
    pub traversal: bool,
}

impl Default for GpuBenchOptions {
    fn default() -> Self {
        GpuBenchOptions {
            resolution: UVec2::new(2048, 2048),
            runs: 5,
            variants: TraversalVariant::ALL.to_vec(),
            tests: vec![TriangleTest::Exact, TriangleTest::Woop],
            build_scenes: vec![10_000_000],
            shadow_fraction: 0.05,
            quality_builds: vec![(
                BuildOptions::default().treelet_rounds,
                BuildOptions::default().treelet_gamma,
            )],
            traversal: true,
        }
    }
}

/// One timed build configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildRow {
    pub scene: String,
    pub builder: String,
    pub triangles: u32,
    pub instances: u32,
    /// Median device milliseconds per phase, and in total.
    pub phases: Vec<(&'static str, f32)>,
    pub device_ms: f32,
    pub mtris_per_s: f64,
    /// SAH of the BLASes and TLAS, recomputed on the host from the download.
    pub blas_sah: f32,
    pub tlas_sah: f32,
    /// The CPU binned-SAH builder's (`SceneBvh<Bvh2>`), when it was built.
    pub cpu_blas_sah: Option<f32>,
    pub nodes: u32,
    pub bytes: u64,
}

/// One ray batch with every (variant, test) measurement.
#[derive(Clone, Debug, PartialEq)]
pub struct BatchRow {
    pub name: &'static str,
    pub any: bool,
    pub rays: usize,
    pub cpu_hits: usize,
    /// (variant, test, Mrays/s, hits).
    pub results: Vec<(TraversalVariant, TriangleTest, f64, usize)>,
}

/// Everything [`run`] measured.
#[derive(Clone, Debug, PartialEq)]
pub struct GpuBenchReport {
    pub device: String,
    pub scene_triangles: u64,
    pub resolution: UVec2,
    pub builds: Vec<BuildRow>,
    pub batches: Vec<BatchRow>,
}

fn median(mut v: Vec<f32>) -> f32 {
    v.sort_by(f32::total_cmp);
    v[v.len() / 2]
}

fn event_err(gpu: &Gpu) -> impl Fn(cudarc::driver::DriverError) -> CudaError + '_ {
    move |e| CudaError::Driver { context: format!("{}: benchmark event", gpu.label()), source: e }
}

/// Builds `runs + 1` times (the first untimed) and reports medians.
fn time_build(
    gpu: &Gpu,
    scene: &GpuScene,
    name: &str,
    builder: String,
    options: &BuildOptions,
    runs: usize,
    cpu_blas_sah: Option<f32>,
) -> Result<BuildRow, CudaError> {
    let mut bvh = GpuSceneBvh::build_with(gpu, scene, options)?;
    let mut stats = Vec::new();
    for _ in 0..runs.max(1) {
        drop(bvh);
        bvh = GpuSceneBvh::build_with(gpu, scene, options)?;
        stats.push(bvh.stats().clone());
    }
    let phases = stats[0]
        .phases
        .iter()
        .enumerate()
        .map(|(i, (name, _))| (*name, median(stats.iter().map(|s| s.phases[i].1).collect())))
        .collect();
    let device_ms = median(stats.iter().map(|s| s.device_ms).collect());
    let s = bvh.stats();
    let (blas_sah, tlas_sah) = bvh.download(gpu)?.sah(options.intersection_cost, options.traversal_cost);
    Ok(BuildRow {
        scene: name.to_string(),
        builder,
        triangles: s.triangles,
        instances: s.instances,
        phases,
        device_ms,
        mtris_per_s: s.triangles as f64 / device_ms.max(1e-6) as f64 / 1e3,
        blas_sah,
        tlas_sah,
        cpu_blas_sah,
        nodes: s.blas_nodes + s.tlas_nodes,
        bytes: s.bytes,
    })
}

fn to_records(rays: &[Ray], shadow: bool) -> Vec<GpuRecord> {
    rays.iter()
        .enumerate()
        .map(|(i, r)| {
            let mut rec = GpuRecord::from_ray(r, i as u32);
            rec.0.flags = if shadow { flags::SHADOW } else { 0 };
            rec
        })
        .collect()
}

/// CPU hit count of a batch, on every core (the check of the GPU's counts).
fn cpu_hits(bvh: &SceneBvh<Bvh2>, rays: &[Ray], any: bool) -> usize {
    let threads = std::thread::available_parallelism().map_or(4, |n| n.get());
    let chunk = rays.len().div_ceil(threads).max(1);
    std::thread::scope(|s| {
        let handles: Vec<_> = rays
            .chunks(chunk)
            .map(|c| {
                s.spawn(move || {
                    c.iter()
                        .filter(|r| if any { bvh.occluded(r) } else { bvh.intersect(r).is_some() })
                        .count()
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().expect("CPU tracing thread")).sum()
    })
}

/// A batch on the device: the records as generated, a copy to trace, hits.
struct DeviceBatch {
    pristine: CudaSlice<GpuRecord>,
    work: CudaSlice<GpuRecord>,
    hits: CudaSlice<HitRef>,
    any: bool,
}

/// Times one batch for one BVH and variant: (Mrays/s, hits). Each run
/// traces a fresh copy of the records (closest-hit tracing shortens t_max,
/// any-hit tracing marks them).
fn time_batch(
    gpu: &Gpu,
    tracer: &mut Tracer,
    bvh: &GpuSceneBvh,
    b: &mut DeviceBatch,
    variant: TraversalVariant,
    runs: usize,
) -> Result<(f64, usize), CudaError> {
    let (pristine, work, hits, any) = (&b.pristine, &mut b.work, &mut b.hits, b.any);
    let count = pristine.len() as u32;
    let mut times = Vec::new();
    for run in 0..=runs.max(1) {
        gpu.stream.memcpy_dtod(pristine, work).map_err(event_err(gpu))?;
        let start = gpu.ctx.new_event(Some(CUevent_flags::CU_EVENT_DEFAULT)).map_err(event_err(gpu))?;
        let end = gpu.ctx.new_event(Some(CUevent_flags::CU_EVENT_DEFAULT)).map_err(event_err(gpu))?;
        start.record(&gpu.stream).map_err(event_err(gpu))?;
        tracer.launch(
            gpu,
            bvh,
            work,
            count,
            if any { None } else { Some(&mut *hits) },
            variant,
            None,
            None,
            None,
            None,
            crate::trace::TraceFeatures::default(),
        )?;
        end.record(&gpu.stream).map_err(event_err(gpu))?;
        let ms = start.elapsed_ms(&end).map_err(event_err(gpu))?;
        if run > 0 {
            times.push(ms);
        }
    }
    let hit_count = if any {
        let recs = gpu.stream.clone_dtoh(&*work).map_err(event_err(gpu))?;
        recs.iter().filter(|r| r.0.has(flags::OCCLUDED)).count()
    } else {
        gpu.stream
            .clone_dtoh(&*hits)
            .map_err(event_err(gpu))?
            .iter()
            .filter(|h| h.instance != HIT_NONE)
            .count()
    };
    Ok((count as f64 / (median(times) as f64 * 1e-3) / 1e6, hit_count))
}

/// The builds a benchmark times: the plain LBVH, then each of `quality`
/// (treelet rounds, first gamma), named by them where not the default.
fn builders(quality: &[(u32, u32)]) -> Vec<(String, BuildOptions)> {
    let default = BuildOptions::default();
    let named = |&(rounds, gamma): &(u32, u32)| {
        let options = BuildOptions { treelet_rounds: rounds, treelet_gamma: gamma, ..default };
        match (rounds, gamma) == (default.treelet_rounds, default.treelet_gamma) {
            true => ("lbvh+treelet".to_string(), options),
            false => (format!("treelet {rounds}:{gamma}"), options),
        }
    };
    std::iter::once(("lbvh".to_string(), BuildOptions::lbvh())).chain(quality.iter().map(named)).collect()
}

/// Runs the benchmark on `scene` (and the build-only scenes of `opts`).
pub fn run(gpu: &Arc<Gpu>, scene: &Scene, opts: &GpuBenchOptions) -> Result<GpuBenchReport, CudaError> {
    let tables = SceneTables::build(scene);
    let scene_triangles = tables.counts().triangles;
    let gpu_scene = GpuScene::upload_tables(gpu, tables)?;
    let cpu_start = Instant::now();
    let cpu_bvh = SceneBvh::<Bvh2>::build_layout(scene, &ScenePart::whole(scene));
    let cpu_sah = cpu_bvh.stats().blas.sah_cost;
    tracing::info!("CPU BVH built in {:.1} s", cpu_start.elapsed().as_secs_f64());

    let mut builds = Vec::new();
    let builders = builders(&opts.quality_builds);
    for (builder, options) in &builders {
        builds.push(time_build(
            gpu,
            &gpu_scene,
            "bench",
            builder.clone(),
            options,
            opts.runs,
            Some(cpu_sah),
        )?);
    }
    for &n in &opts.build_scenes {
        let big = atoll_scene::procedural::bench_scene_flat(n);
        let big_scene = GpuScene::upload_tables(gpu, SceneTables::build(&big))?;
        for (builder, options) in &builders {
            builds.push(time_build(
                gpu,
                &big_scene,
                &format!("flat {n}"),
                builder.clone(),
                options,
                opts.runs,
                None,
            )?);
        }
    }

    if !opts.traversal {
        let (device, resolution) = (gpu.name.clone(), opts.resolution);
        return Ok(GpuBenchReport { device, scene_triangles, resolution, builds, batches: Vec::new() });
    }
    let bench_opts = BenchOptions {
        resolution: Some(opts.resolution),
        shadow_fraction: opts.shadow_fraction,
        ..Default::default()
    };
    let rays = generate_rays(scene, &cpu_bvh, &bench_opts);
    let mut tracer = Tracer::new(gpu)?;
    let bvhs: Vec<(TriangleTest, GpuSceneBvh)> = opts
        .tests
        .iter()
        .map(|&t| {
            GpuSceneBvh::build_with(gpu, &gpu_scene, &BuildOptions { triangle_test: t, ..Default::default() })
                .map(|b| (t, b))
        })
        .collect::<Result<_, _>>()?;
    let mut batches = Vec::new();
    for (name, any, batch) in
        [("primary", false, &rays.primary), ("shadow", true, &rays.shadow), ("diffuse", false, &rays.diffuse)]
    {
        let mut row = BatchRow {
            name,
            any,
            rays: batch.len(),
            cpu_hits: cpu_hits(&cpu_bvh, batch, any),
            results: Vec::new(),
        };
        if batch.is_empty() {
            batches.push(row);
            continue;
        }
        let err = |what: &str| CudaError::driver(format!("{}: {what} for the {name} batch", gpu.label()));
        let mut device = DeviceBatch {
            pristine: gpu.stream.clone_htod(&to_records(batch, any)).map_err(err("uploading rays"))?,
            work: gpu.stream.alloc_zeros(batch.len()).map_err(err("allocating rays"))?,
            hits: gpu.stream.alloc_zeros(batch.len()).map_err(err("allocating hits"))?,
            any,
        };
        for (test, bvh) in &bvhs {
            for &variant in &opts.variants {
                let (mrays, hit_count) = time_batch(gpu, &mut tracer, bvh, &mut device, variant, opts.runs)?;
                row.results.push((variant, *test, mrays, hit_count));
            }
        }
        batches.push(row);
    }
    Ok(GpuBenchReport {
        device: gpu.name.clone(),
        scene_triangles,
        resolution: opts.resolution,
        builds,
        batches,
    })
}

impl fmt::Display for GpuBenchReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "GPU BVH benchmark on {} ({} triangles as uploaded)", self.device, self.scene_triangles)?;
        writeln!(
            f,
            "\nBuild (device ms, median; SAH recomputed on the host, CPU = binned SAH of atoll_bvh):"
        )?;
        let phase_names: Vec<&str> =
            self.builds.first().map_or(Vec::new(), |b| b.phases.iter().map(|p| p.0).collect());
        write!(f, "{:<14} {:<12} {:>10} {:>8}", "scene", "builder", "triangles", "Mtris/s")?;
        for p in &phase_names {
            write!(f, " {p:>8}")?;
        }
        writeln!(f, " {:>8} {:>9} {:>9} {:>8} {:>8}", "total", "BLAS SAH", "vs CPU", "TLAS SAH", "MiB")?;
        for b in &self.builds {
            write!(f, "{:<14} {:<12} {:>10} {:>8.0}", b.scene, b.builder, b.triangles, b.mtris_per_s)?;
            for (_, ms) in &b.phases {
                write!(f, " {ms:>8.3}")?;
            }
            let vs = b
                .cpu_blas_sah
                .map_or("-".to_string(), |c| format!("{:+.1}%", 100.0 * (b.blas_sah / c - 1.0)));
            writeln!(
                f,
                " {:>8.3} {:>9.2} {:>9} {:>8.2} {:>8.1}",
                b.device_ms,
                b.blas_sah,
                vs,
                b.tlas_sah,
                b.bytes as f64 / (1 << 20) as f64
            )?;
        }
        let r = self.resolution;
        writeln!(
            f,
            "\nTraversal (Mrays/s, median; {}x{} primary rays; hits checked against the CPU):",
            r.x, r.y
        )?;
        let columns: Vec<(TraversalVariant, TriangleTest)> =
            self.batches.first().map_or(Vec::new(), |b| b.results.iter().map(|r| (r.0, r.1)).collect());
        write!(f, "{:<8} {:<8} {:>9} {:>9}", "batch", "query", "rays", "CPU hits")?;
        for (v, t) in &columns {
            write!(f, " {:>11}", format!("{}/{}", v.name(), t.suffix()))?;
        }
        writeln!(f)?;
        for b in &self.batches {
            let query = if b.any { "any" } else { "closest" };
            write!(f, "{:<8} {:<8} {:>9} {:>9}", b.name, query, b.rays, b.cpu_hits)?;
            let mut mismatches = Vec::new();
            for (v, t, mrays, hits) in &b.results {
                write!(f, " {mrays:>11.1}")?;
                // Exact tests find the CPU's hits bit for bit; Woop's test
                // rounds differently, so grazing hits may come and go (the
                // equality tests bound that at 0.2% of rays; here 0.01%).
                let tolerance = if *t == TriangleTest::Exact { 0 } else { b.cpu_hits / 10_000 };
                if hits.abs_diff(b.cpu_hits) > tolerance {
                    mismatches.push(format!("{}/{}: {hits}", v.name(), t.suffix()));
                }
            }
            if mismatches.is_empty() {
                writeln!(f)?;
            } else {
                writeln!(f, "   HITS DIFFER ({})", mismatches.join(", "))?;
            }
        }
        Ok(())
    }
}
