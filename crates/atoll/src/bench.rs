//! `atoll bench`: BVH build and traversal speed on a generated scene, and
//! path-tracing speed on the Cornell box; or traversal speed on any scene
//! atoll loads (`atoll bench SCENE`), its rays written out for other ray
//! tracers on request (`--export`, read by scripts/bench-embree.py and
//! scripts/bench-mitsuba.py).

use std::path::PathBuf;
use std::sync::Arc;

use atoll_dist::Layout;
use atoll_render::{render, RenderOptions};
use atoll_scene::IntegratorSettings;
use clap::Args;
use glam::UVec2;

use crate::device::{select, DeviceArgs};
use crate::render::WaveArgs;
use crate::CliError;

#[derive(Args)]
pub struct BenchArgs {
    /// Measure traversal on this scene (a file, or a built-in scene such as
    /// `landscape:100`, as `atoll render` takes it) instead of the
    /// generated one: primary rays through its camera, and from every
    /// primary hit a shadow and a diffuse ray. The Cornell-box path-tracing
    /// run is left out.
    pub scene: Option<PathBuf>,
    /// Primary rays, WxH. Default: the scene's film resolution (2048x2048
    /// on the GPU for the generated scene).
    #[arg(long, value_parser = crate::render::parse_resolution)]
    pub res: Option<UVec2>,
    /// Write the traversal scene's triangles (world space) and its three
    /// ray batches to DIR as little-endian f32 (`triangles.f32`: N × 9;
    /// `primary.f32`, `shadow.f32`, `diffuse.f32`: M × 7 of origin,
    /// direction, t_max), for other ray tracers to trace the same rays.
    /// Instances are expanded (36 bytes a triangle), as with `--flat`:
    /// refused up front where that would not fit the memory available.
    #[arg(long, value_name = "DIR")]
    pub export: Option<PathBuf>,
    /// Triangles in the generated traversal scene (at most 2^28: some
    /// 20 GiB with its BVH).
    #[arg(long, default_value_t = 2_000_000,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=1 << 28))]
    pub triangles: usize,
    /// Samples per pixel for the Cornell-box path-tracing run.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..))]
    pub spp: u32,
    /// Skip the traversal benchmark (on a GPU the BVH builds are still
    /// timed).
    #[arg(long)]
    pub no_traversal: bool,
    /// Trace the flattened scene (every triangle unique) instead of the
    /// instanced one (on the CPU the generated scene is always flattened;
    /// with SCENE, the scene's instances are expanded into world space, as
    /// `--export` writes them).
    #[arg(long)]
    pub flat: bool,
    /// Path-tracing runs after an untimed 1-spp warm-up; the median is reported.
    #[arg(long, default_value_t = 1,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub runs: usize,
    /// Measure queue copy speed between GPUs 0 and 1 (peer copies vs
    /// through the host) instead of everything else.
    #[arg(long)]
    pub peer: bool,
    /// Measure how fast a queue of ray records goes from the device to the
    /// host and back (`read_queue`/`write_queue`: a ring's host transport,
    /// and rings of processes) instead of everything else.
    #[arg(long, conflicts_with = "peer")]
    pub queue_copy: bool,
    /// Under mpirun, one GPU per process (`--device cuda:N`): measure NCCL
    /// send/recv between ranks 0 and 1, at the queue sizes of `--peer`,
    /// instead of everything else (needs a build with `--features mpi`).
    #[arg(long, conflicts_with_all = ["peer", "queue_copy"])]
    pub nccl_ranks: bool,
    /// GPU quality builds timed beside the plain LBVH, as ROUNDS:GAMMA
    /// pairs (treelet rounds; the first round's primitive threshold,
    /// doubled each round), e.g. `3:7,2:14,1:7`. Default: the renderer's.
    #[arg(long, value_delimiter = ',', value_parser = parse_treelets, value_name = "ROUNDS:GAMMA")]
    pub treelets: Vec<(u32, u32)>,
    /// No progress lines on stderr (results only).
    #[arg(short, long)]
    pub quiet: bool,
    #[command(flatten)]
    pub device: DeviceArgs,
    #[command(flatten)]
    pub waves: WaveArgs,
}

/// A progress line on stderr: each step takes seconds (kernels compile on
/// first use, scenes are generated), which would otherwise pass in silence.
fn step(args: &BenchArgs, what: std::fmt::Arguments) {
    if !args.quiet {
        eprintln!("bench: {what}");
    }
}

pub fn run(args: BenchArgs) -> Result<(), CliError> {
    if args.peer {
        return peer_copies();
    }
    if args.nccl_ranks {
        return nccl_ranks(&args);
    }
    let selected = select(&args.device, None)?;
    if args.queue_copy {
        return queue_copies(&args, selected);
    }
    if let Some(path) = &args.scene {
        return scene_traversal(&args, path, &selected);
    }
    match (&selected.gpu, args.no_traversal) {
        (Some(gpu), _) => {
            let what = if args.no_traversal { "BVH builds" } else { "BVH builds and traversal" };
            step(&args, format_args!("{what} on {} triangles ({})", args.triangles, selected.description));
            gpu_traversal(&args, gpu)?;
        }
        (None, false) => {
            step(
                &args,
                format_args!(
                    "BVH builds and traversal on {} triangles ({})",
                    args.triangles, selected.description
                ),
            );
            traversal(&args)?;
        }
        (None, true) => {}
    }
    // Path tracing: the diffuse Cornell box at 512², 15 bounces, no Russian
    // roulette (the settings of the GPU speed target in BENCHMARKS.md).
    let scene = Arc::new(atoll_scene::cornell::builtin_cornell_box());
    let mut options = RenderOptions::from_scene(&scene);
    options.resolution = UVec2::new(512, 512);
    options.spp = args.spp;
    options.integrator = IntegratorSettings::Path { max_depth: 15 };
    options.russian_roulette = false;
    args.waves.apply(&mut options, selected.gpu.is_some());
    // Wavefronts sharing the GPU (`--streams`), as `atoll render` uses them.
    let more = atoll_dist::placement::more_wavefronts(
        selected.device.as_ref(),
        args.waves.streams(),
        &scene,
        &options,
        None,
    )
    .map_err(|e| CliError::Runtime(e.to_string()))?;
    let streams = more.len() + 1;
    let mut devices = vec![selected.device];
    devices.extend(more);
    // (seconds, samples/s, rays/s) of one frame.
    let mut run_once = |spp: u32| {
        let options = RenderOptions { spp, ..options.clone() };
        if devices.len() == 1 {
            let out = render(devices[0].as_mut(), &scene, options, &mut |_, _| {})
                .map_err(|e| CliError::Runtime(e.to_string()))?;
            return Ok::<_, CliError>((out.render_seconds, out.samples_per_second(), out.rays_per_second()));
        }
        let out =
            atoll_dist::render_multi(&mut devices, &scene, options, &Layout::Replicate, None, &mut |_, _| {})
                .map_err(|e| CliError::Runtime(e.to_string()))?;
        Ok((out.render_seconds, out.samples_per_second(), out.rays_per_second()))
    };
    // Warm-up: kernel compilation, caches, clocks.
    step(&args, format_args!("path tracing the Cornell box: warming up (kernels compile on first use)"));
    run_once(1)?;
    let runs = args.runs.max(1);
    let mut runs = (0..runs)
        .map(|k| {
            step(&args, format_args!("path tracing the Cornell box: run {} of {runs}", k + 1));
            run_once(args.spp)
        })
        .collect::<Result<Vec<_>, _>>()?;
    runs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (seconds, samples, rays) = runs[runs.len() / 2];
    println!(
        "path tracing  cornell box 512x512, {} spp, depth 15, no RR, waves of {}{}{}: {:.3} M samples/s, {:.2} M rays/s ({:.3} s median of {}, on {})",
        args.spp,
        options.wave_size,
        if options.merge_waves { " merged" } else { "" },
        if streams > 1 { format!(", {streams} wavefronts") } else { String::new() },
        samples / 1e6,
        rays / 1e6,
        seconds,
        runs.len(),
        selected.description
    );
    Ok(())
}

/// Traversal speed on the scene at `path` (CPU or GPU, as selected), its
/// rays first written out with `--export`.
fn scene_traversal(
    args: &BenchArgs,
    path: &std::path::Path,
    selected: &crate::device::Selected,
) -> Result<(), CliError> {
    let start = std::time::Instant::now();
    let mut scene = crate::load::load_scene(Some(path))?;
    let expands = args.flat || args.export.is_some();
    let available = atoll_render::device::host_memory_available();
    check_expansion_fits(expands, path, scene.stats().instanced_triangles, available)?;
    if args.flat {
        scene = atoll_scene::procedural::flatten(&scene);
    }
    let stats = scene.stats();
    step(
        args,
        format_args!(
            "{}: {} unique triangles, {} instanced, loaded in {:.2} s; traversal on {}",
            path.display(),
            stats.unique_triangles,
            stats.instanced_triangles,
            start.elapsed().as_secs_f64(),
            selected.description
        ),
    );
    let resolution = args.res.unwrap_or(scene.settings.film.resolution);
    // The rays of the export and of the CPU measurement.
    let cpu_options = atoll_bvh::bench::BenchOptions { resolution: Some(resolution), ..Default::default() };
    if let Some(dir) = &args.export {
        atoll_bvh::bench::export_bench_data(&scene, &cpu_options, dir)
            .map_err(|e| CliError::Runtime(format!("{}: {e}", dir.display())))?;
        step(args, format_args!("triangles and rays written to {}", dir.display()));
        let pieces = scene.stats().curve_pieces;
        if pieces > 0 {
            tracing::warn!(
                "{}: the scene's {pieces} curve pieces are not triangles and are left out of triangles.f32; \
                 its rays were traced with them",
                dir.display()
            );
        }
    }
    match &selected.gpu {
        Some(gpu) => {
            let options = atoll_cuda::bench::GpuBenchOptions {
                resolution,
                build_scenes: Vec::new(),
                ..Default::default()
            };
            let report = atoll_cuda::bench::run(gpu, &scene, &options)
                .map_err(|e| CliError::Runtime(e.to_string()))?;
            println!("{report}");
        }
        None => println!("{}", atoll_bvh::bench::run_traversal_bench(&scene, &cpu_options)),
    }
    Ok(())
}

/// Expanding instances (`--flat`, `--export`) keeps every instanced
/// triangle in world space in host memory: refused up front when that
/// alone would take more than the memory `available` (`None`: unknown).
fn check_expansion_fits(
    expands: bool,
    path: &std::path::Path,
    instanced_triangles: u64,
    available: Option<u64>,
) -> Result<(), CliError> {
    if !expands {
        return Ok(());
    }
    // Three world-space vertices of three f32 each.
    let needed = instanced_triangles.saturating_mul(36);
    match available {
        Some(free) if needed > free => Err(CliError::Runtime(format!(
            "{}: expanding its {instanced_triangles} instanced triangles (--flat, --export) needs {}, more than the {} of memory available",
            path.display(),
            atoll_cuda::error::fmt_bytes(needed),
            atoll_cuda::error::fmt_bytes(free)
        ))),
        _ => Ok(()),
    }
}

/// `--treelets`' ROUNDS:GAMMA (gamma at least 7: a treelet has 7 leaves).
fn parse_treelets(s: &str) -> Result<(u32, u32), String> {
    let (rounds, gamma) =
        s.split_once(':').ok_or_else(|| format!("{s:?}: expected ROUNDS:GAMMA, e.g. 3:7"))?;
    let number = |v: &str| v.trim().parse::<u32>().map_err(|e| format!("{v:?}: {e}"));
    match (number(rounds)?, number(gamma)?) {
        (rounds @ 0..=16, gamma @ 7..) => Ok((rounds, gamma)),
        _ => Err(format!("{s:?}: rounds must be 0 to 16 and gamma at least 7")),
    }
}

/// GPU BVH build (on the traversal scene and a 10M-triangle one) and GPU
/// traversal throughput per variant, on the instanced bench scene.
fn gpu_traversal(args: &BenchArgs, gpu: &std::sync::Arc<atoll_cuda::Gpu>) -> Result<(), CliError> {
    let scene = if args.flat {
        atoll_scene::procedural::bench_scene_flat(args.triangles)
    } else {
        atoll_scene::procedural::bench_scene(args.triangles)
    };
    let defaults = atoll_cuda::bench::GpuBenchOptions::default();
    let options = atoll_cuda::bench::GpuBenchOptions {
        build_scenes: vec![10_000_000, 20_000_000],
        quality_builds: match args.treelets.is_empty() {
            true => defaults.quality_builds.clone(),
            false => args.treelets.clone(),
        },
        traversal: !args.no_traversal,
        ..defaults
    };
    let report =
        atoll_cuda::bench::run(gpu, &scene, &options).map_err(|e| CliError::Runtime(e.to_string()))?;
    println!("{report}");
    Ok(())
}

/// BVH build and CPU traversal throughput (primary, shadow, diffuse rays) on
/// a generated terrain-and-rocks scene with every triangle in world space
/// (the same data `scripts/bench-cpu.sh` hands to Embree).
fn traversal(args: &BenchArgs) -> Result<(), CliError> {
    let start = std::time::Instant::now();
    let scene = atoll_scene::procedural::bench_scene_flat(args.triangles);
    eprintln!(
        "generated {} triangles in {:.2} s",
        scene.stats().unique_triangles,
        start.elapsed().as_secs_f64()
    );
    let report = atoll_bvh::bench::run_traversal_bench(&scene, &atoll_bvh::bench::BenchOptions::default());
    println!("{report}");
    Ok(())
}

/// Device-to-host and host-to-device speed of the selected device's path
/// queue holding queues of a few sizes, through the `Device` API: 10
/// timed copies each way after an untimed one.
fn queue_copies(args: &BenchArgs, mut selected: crate::device::Selected) -> Result<(), CliError> {
    let scene = Arc::new(atoll_scene::cornell::builtin_cornell_box());
    let mut options = RenderOptions::from_scene(&scene);
    args.waves.apply(&mut options, selected.gpu.is_some());
    let frame = Arc::new(atoll_render::FrameContext::new(&scene, options.clone()));
    let device = selected.device.as_mut();
    let runtime = |e: atoll_render::DeviceError| CliError::Runtime(e.to_string());
    device.prepare(&scene, &atoll_bvh::ScenePart::whole(&scene), &frame).map_err(runtime)?;
    let queue = atoll_render::Queue::Paths;
    for records in [65_536usize, 262_144, 1_048_576].into_iter().filter(|&n| n <= options.wave_size as usize)
    {
        let wave = vec![<atoll_render::RayRecord as bytemuck::Zeroable>::zeroed(); records];
        let failed = |e: atoll_render::DeviceError| CliError::Runtime(e.to_string());
        device.write_queue(queue, &wave).map_err(failed)?;
        device.read_queue(queue).map_err(failed)?;
        let timed = |copy: &mut dyn FnMut() -> Result<(), atoll_render::DeviceError>| {
            let start = std::time::Instant::now();
            (0..10).try_for_each(|_| copy()).map_err(failed)?;
            Ok::<_, CliError>(
                (10 * std::mem::size_of_val(wave.as_slice())) as f64 / start.elapsed().as_secs_f64() / 1e9,
            )
        };
        // Into one vector, as a ring's hand-overs do.
        let mut back = Vec::new();
        let down = timed(&mut || device.read_queue_into(queue, &mut back))?;
        let up = timed(&mut || device.write_queue(queue, &wave))?;
        println!(
            "queue through the host  {records:>8} records ({:>4} MiB): to the host {down:.1} GB/s, to the device {up:.1} GB/s ({})",
            std::mem::size_of_val(wave.as_slice()) >> 20,
            selected.description
        );
    }
    Ok(())
}

/// GPU-to-GPU copy speed for ray queues of a few sizes (32 MiB is one wave
/// of 262144 records).
/// NCCL send/recv between the GPUs of ranks 0 and 1 (one each), both
/// ways, timed like [`peer_copies`] (one untimed copy, then 20); the time
/// of a copy is the slower rank's. Rank 0 prints.
#[cfg(feature = "mpi")]
fn nccl_ranks(args: &BenchArgs) -> Result<(), CliError> {
    use atoll_cuda::nccl::{new_id, NcclIdBytes, NcclLink};
    let runtime = |e: atoll_cuda::CudaError| CliError::Runtime(e.to_string());
    let ranks =
        atoll_dist::ranks::Ranks::init().map_err(|e| CliError::Runtime(format!("--nccl-ranks: {e}")))?;
    if ranks.size() < 2 {
        return Err(CliError::Input("--nccl-ranks: start two or more processes with mpirun".into()));
    }
    let selected = select(&args.device, None)?;
    let Some(gpu) = selected.gpu else {
        return Err(CliError::Input("--nccl-ranks: every rank needs a GPU (--device cuda:N)".into()));
    };
    let mut id: NcclIdBytes = [0; 128];
    if ranks.is_root() {
        id = new_id().map_err(runtime)?;
    }
    ranks.broadcast(&mut id);
    let link = NcclLink::connect(&gpu, &id, ranks.rank(), ranks.size()).map_err(runtime)?;
    let me = ranks.rank();
    let names = ranks.gather_text(&selected.description);
    const REPEATS: usize = 20;
    for mib in [4usize, 32, 256] {
        let bytes = mib << 20;
        let alloc = || gpu.stream.alloc_zeros::<u8>(bytes).map_err(|e| CliError::Runtime(e.to_string()));
        let (outgoing, mut incoming) = (alloc()?, alloc()?);
        for (from, to) in [(0, 1), (1, 0)] {
            let mut copy = || {
                link.exchange(
                    (me == from).then_some((&outgoing, to)),
                    (me == to).then_some((&mut incoming, from)),
                )
            };
            copy().map_err(runtime)?;
            ranks.wait_for_all();
            let start = std::time::Instant::now();
            for _ in 0..REPEATS {
                copy().map_err(runtime)?;
            }
            let seconds = ranks.max(start.elapsed().as_secs_f64());
            if ranks.is_root() {
                let gbps = (bytes * REPEATS) as f64 / seconds / 1e9;
                let name = |r: usize| names.get(r).map_or("?", String::as_str);
                println!(
                    "NCCL send/recv  rank {from} ({}) -> rank {to} ({})  {mib:>4} MiB: {gbps:.1} GB/s",
                    name(from),
                    name(to)
                );
            }
        }
    }
    Ok(())
}

#[cfg(not(feature = "mpi"))]
fn nccl_ranks(_args: &BenchArgs) -> Result<(), CliError> {
    Err(CliError::Input(
        "--nccl-ranks: this atoll was built without MPI (build it with `cargo build --release --features mpi`)".into(),
    ))
}

fn peer_copies() -> Result<(), CliError> {
    let open = |i| atoll_cuda::Gpu::open(i).map_err(|e| CliError::Runtime(e.to_string()));
    let (a, b) = (open(0)?, open(1)?);
    for (x, y) in [(&a, &b), (&b, &a)] {
        for mib in [4usize, 32, 256] {
            let r = atoll_cuda::peer::measure_copy(x, y, mib << 20, 20)
                .map_err(|e| CliError::Runtime(e.to_string()))?;
            println!(
                "queue copy  {} -> {}  {:>4} MiB: peer {:.1} GB/s ({}), NCCL send/recv {}, through the host {:.1} GB/s",
                x.label(),
                y.label(),
                mib,
                r.peer_gbps,
                if r.direct { "direct" } else { "no peer access: staged by the driver" },
                r.nccl_gbps.map_or("unavailable (no libnccl)".to_string(), |g| format!("{g:.1} GB/s")),
                r.host_gbps
            );
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Expanding instances is refused when the world-space triangles alone
    /// exceed the memory available, and only then.
    #[test]
    fn expanding_instances_is_refused_beyond_the_memory_available() {
        let path = std::path::Path::new("big.pbrt");
        assert!(check_expansion_fits(true, path, 1000, Some(36_000)).is_ok());
        let refused = check_expansion_fits(true, path, 1001, Some(36_000));
        let Err(CliError::Runtime(message)) = refused else { panic!("not refused: {refused:?}") };
        assert!(message.starts_with("big.pbrt: expanding its 1001 instanced triangles"), "{message}");
        assert!(check_expansion_fits(false, path, u64::MAX, Some(0)).is_ok(), "nothing expanded");
        assert!(check_expansion_fits(true, path, u64::MAX, None).is_ok(), "memory unknown");
    }
}
