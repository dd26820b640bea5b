//! `atoll render`.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use atoll_dist::{RingOrder, Strategy, Transport};
use atoll_render::integrator::render_warmed;
use atoll_render::{render, RenderOptions};
use atoll_scene::progress::Prepared;
use atoll_scene::Scene;
use atoll_scene::{FilmSettings, IntegratorSettings, LightSampler};
use clap::Args;
use glam::UVec2;
use indicatif::{ProgressBar, ProgressState, ProgressStyle};

use crate::device::{select, DeviceArgs};
use crate::load::{load_scene_reporting, LoadReport};
use crate::multi::{
    self, parse_devices, parse_partitioning, parse_ring_order, parse_transport, DeviceList, DeviceSpec,
    MultiArgs, Partitioning,
};
use crate::preflight::Room;
use crate::CliError;
use atoll_scene::input::SizeCheck;

/// How the wavefront loop is fed (shared by `render` and `bench`).
#[derive(Args, Clone, Default)]
pub struct WaveArgs {
    /// Render one wave at a time instead of starting the next wave's paths
    /// in the slots finished paths free (wave-front merging).
    #[arg(long)]
    pub no_merge: bool,
    /// Paths in flight per device (default 1048576 on GPUs, 262144 on the
    /// CPU; queues take about 4 x 128 B each).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub wave_size: Option<u32>,
    /// Wavefronts per GPU: devices on it sharing one copy of the scene (or,
    /// on a ring, of their parts: more islands), each with its own queues
    /// and film (default 3, fewer when memory is short; 1 with --no-merge,
    /// whose reruns are then bit-identical).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=8))]
    pub streams: Option<u32>,
}

impl WaveArgs {
    /// Wavefronts wanted per GPU (see `--streams`).
    pub fn streams(&self) -> usize {
        match (self.no_merge, self.streams) {
            (_, Some(n)) => n as usize,
            (true, None) => 1,
            (false, None) => atoll_cuda::DEFAULT_STREAMS,
        }
    }

    /// Sets the options' wave settings; `gpu`: a CUDA device renders (its
    /// default wave is larger).
    pub fn apply(&self, options: &mut RenderOptions, gpu: bool) {
        options.merge_waves = !self.no_merge;
        match self.wave_size {
            Some(size) => options.wave_size = size,
            None if gpu => options.wave_size = atoll_cuda::DEFAULT_WAVE_SIZE,
            None => {}
        }
    }
}

#[derive(Args, Default)]
#[command(group(clap::ArgGroup::new("placement").args(["devices", "mpi"]).multiple(true)))]
pub struct RenderArgs {
    /// Scene file (.pbrt, .obj, .gltf/.glb, .ply, .off) or a generated `landscape:GROWTH[:SEED]`;
    /// the built-in Cornell box when omitted.
    pub scene: Option<PathBuf>,
    /// Output image (.exr linear, .png sRGB); default: the scene's Film filename, else atoll.png.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Samples per pixel (overrides the scene).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub spp: Option<u32>,
    /// Resolution WxH (overrides the scene).
    #[arg(long, value_parser = parse_resolution)]
    pub res: Option<UVec2>,
    /// Maximum number of bounces (overrides the scene's path integrator).
    #[arg(long)]
    pub max_depth: Option<u32>,
    /// Worker threads of the CPU device (default: all cores; at most 16
    /// per core).
    #[arg(long, value_parser = parse_threads)]
    pub threads: Option<usize>,
    #[command(flatten)]
    pub device: DeviceArgs,
    #[command(flatten)]
    pub waves: WaveArgs,
    /// Render on several devices: comma-separated cpu, cpu:N (N CPU devices
    /// sharing the cores), cuda:I, or cuda:I/P (the next of P parts of GPU
    /// I's multiprocessors: a stand-in for P GPUs; cuda:I[J/P] is part J);
    /// `--device-memory` is then per device. With --mpi, one device listed
    /// is this rank's one device.
    #[arg(long, value_parser = parse_devices, conflicts_with = "device")]
    pub devices: Option<DeviceList>,
    /// How several devices share the work: auto (replicate when the scene
    /// fits every device, else shared on GPUs that can read each other's
    /// memory, else rings of as few devices as fit), replicate, ring, or shared (the scene in chunks over the devices' memories, hot
    /// chunks replicated, placed by a counting 1-spp prepass).
    #[arg(long, default_value = "auto", value_parser = parse_strategy, requires = "devices")]
    pub strategy: Strategy,
    /// Chunk size of `--strategy shared`, e.g. 2M or 64M.
    #[arg(long, value_parser = crate::device::parse_size, value_name = "SIZE", requires = "devices")]
    pub chunk_size: Option<u64>,
    /// Share of the chunks `--strategy shared` replicates on every device
    /// (0 to 1; at most what the budgets allow). Default: as many as leave
    /// room for an even share of the rest (Jaroš et al.'s N_dup).
    #[arg(long, value_parser = parse_fraction, requires = "devices")]
    pub replicate_fraction: Option<f64>,
    /// How ring queues move between devices: peer (GPU to GPU copies, the
    /// default for GPUs) or host (through host memory, any device). Rings
    /// of GPU ranks (`--mpi`) use NCCL unless this says host.
    #[arg(long, value_parser = parse_transport, requires = "devices")]
    pub ring_transport: Option<Transport>,
    /// Where a ring's queues are made and shaded: spread (every member
    /// makes queues from its share of the pixels; shading where a queue's
    /// cycle ends: the least traffic) or home (member 0, holding the
    /// largest piece, makes and shades every queue, so every ray is traced
    /// there first: the other parts skip what lies behind its hits).
    #[arg(long, default_value = "spread", value_parser = parse_ring_order, requires = "placement")]
    pub ring_order: RingOrder,
    /// Devices per ring with `--strategy ring` (the scene split into this
    /// many parts; the devices beyond form more islands). Default: the
    /// fewest that fit `--device-memory`, or all devices without one. With
    /// `--mpi --ring-ranks`: how many of a rank's devices split its share
    /// (default: the fewest that fit).
    #[arg(long, requires = "devices")]
    pub ring_size: Option<usize>,
    /// How a ring's scene parts are made: auto (measured for rings of 2,
    /// memory for scenes of more than 50M unique triangles; cost for longer
    /// rings: what measured fastest), memory (objects balanced
    /// by bytes), cost or cost=BYTES (by bytes plus 9 KiB, or BYTES, per
    /// instance: instanced objects spread over the parts), work (compact
    /// chunks balanced by bytes and by the frame's estimated ray work),
    /// measured (the same, the work measured: where a 128-pixel-wide sample
    /// of the frame's paths hits, rendered on the CPU), or spatial (one
    /// compact region per part).
    #[arg(long = "partition", default_value = "auto", value_parser = parse_partitioning, requires = "placement")]
    pub partitioning: Partitioning,
    /// Also write a false-colour image of which device holds which surface.
    #[arg(long, value_name = "IMAGE", requires = "placement")]
    pub ownership: Option<PathBuf>,
    /// Random seed; different seeds give independent images.
    #[arg(long, default_value_t = 0)]
    pub seed: u32,
    /// Disable Russian roulette (fixed-length paths).
    #[arg(long)]
    pub no_rr: bool,
    /// How next-event estimation picks a light: `bvh` (by what each light
    /// can contribute at the shading point) or `power`. Default: the
    /// scene's `Integrator "string lightsampler"`, else `bvh`.
    #[arg(long, value_parser = parse_light_sampler)]
    pub light_sampler: Option<LightSampler>,
    /// Render ambient occlusion instead of the scene's integrator, with this max distance.
    #[arg(long, value_parser = parse_distance)]
    pub ao: Option<f32>,
    /// Render the frame's first sample untimed on the prepared devices,
    /// then clear it (benchmarks: kernel loading, clocks and first-touch
    /// costs stay out of the reported speed).
    #[arg(long)]
    pub warmup: bool,
    /// Hide the progress bar.
    #[arg(long, short)]
    pub quiet: bool,
    /// Render with every process `mpirun` started (one per node or per
    /// GPU, each on its own `--device`/`--devices` with its own copy of the
    /// scene): waves handed out by rank 0 as devices free up, films summed
    /// there; rank 0 writes the image and prints every rank's devices.
    /// Needs an atoll built with `--features mpi`.
    #[arg(long)]
    pub mpi: bool,
    /// With --mpi: ranks per ring, each holding one share of the scene,
    /// queues cycling between ranks (over NCCL between GPUs, else as MPI
    /// messages; it must divide the ranks; the rings share the waves). A
    /// rank's `--devices` each hold its share, or split it (`--ring-size`,
    /// or where a share would not fit one device): a queue then visits the
    /// rank's devices before the next rank's. Devices beyond form more
    /// rings. Default: 1 (every rank holds the whole scene) when the scene
    /// fits the smallest rank's device, else the fewest ranks whose parts
    /// fit (one device per rank).
    #[arg(long, requires = "mpi", value_parser = clap::value_parser!(u32).range(1..))]
    pub ring_ranks: Option<u32>,
    /// With --mpi: how the ranks' films are summed on rank 0: peer (NCCL
    /// between each rank's first GPU, the default where every rank has
    /// one) or host (MPI through host memory).
    #[arg(long, requires = "mpi", value_parser = crate::multi::parse_transport)]
    pub film_transport: Option<Transport>,
}

pub(crate) fn parse_resolution(s: &str) -> Result<UVec2, String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or("expected WxH, e.g. 512x512")?;
    let parse = |v: &str| v.trim().parse::<u32>().map_err(|e| format!("{v:?}: {e}"));
    FilmSettings::check_resolution(parse(w)? as u64, parse(h)? as u64)
}

/// `--threads`: at least 1, at most 16 per core (more only costs memory
/// and scheduling; hundreds of thousands hang the pool's start).
fn parse_threads(s: &str) -> Result<usize, String> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    match s.trim().parse::<usize>() {
        Ok(n) if (1..=16 * cores).contains(&n) => Ok(n),
        _ => Err(format!("{s:?}: expected a thread count from 1 to {} (16 per core)", 16 * cores)),
    }
}

/// A distance: finite and above 0.
fn parse_distance(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(d) if d.is_finite() && d > 0.0 => Ok(d),
        _ => Err(format!("{s:?}: expected a distance above 0")),
    }
}

/// The folder of `output`, refused when it does not exist, or when `output`
/// exists and is not a regular file (a folder, a pipe, a device: replacing
/// one with an image is never what the user meant).
pub(crate) fn check_folder(output: &Path) -> Result<&Path, CliError> {
    let dir = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(CliError::Input(format!(
            "{}: the folder {} does not exist",
            output.display(),
            dir.display()
        )));
    }
    match std::fs::metadata(output) {
        Ok(m) if m.is_dir() => Err(CliError::Input(format!("{}: is a folder", output.display()))),
        Ok(m) if !m.is_file() => {
            Err(CliError::Input(format!("{}: is not a regular file (a pipe or a device)", output.display())))
        }
        _ => Ok(dir),
    }
}

/// Refuses an output that cannot be written, before anything is loaded or
/// rendered: an extension other than .exr or .png, a folder that does not
/// exist, or one this user cannot write in (tried with a temporary file,
/// removed at once).
pub(crate) fn check_output(output: &Path) -> Result<(), CliError> {
    match output.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).as_deref() {
        Some("exr") | Some("png") => {}
        _ => return Err(CliError::Input(format!("{}: output must end in .exr or .png", output.display()))),
    }
    let dir = check_folder(output)?;
    tempfile::tempfile_in(dir)
        .map(drop)
        .map_err(|e| CliError::Input(format!("{}: cannot write in {}: {e}", output.display(), dir.display())))
}

pub fn run(args: RenderArgs) -> Result<(), CliError> {
    if args.mpi {
        return run_ranked(args);
    }
    let (opened, size_check) = open_before_loading(&args)?;
    let Frame { scene, mut options, output, load } = load_frame(&args, size_check)?;
    if let Some(DeviceList(specs)) = &args.devices {
        set_waves_for_devices(&args, specs, &mut options);
        let devices = match opened {
            Some(Opened::Many(devices)) => devices,
            _ => multi::open_devices(specs, args.device.device_memory, args.threads)?,
        };
        return render_on_devices(&scene, options, &args, specs, devices, &output, load);
    }
    let mut selected = match opened {
        Some(Opened::One(selected)) => fit_device_waves(&args, selected, &scene, &mut options),
        _ => open_device(&args, &scene, &mut options)?,
    };
    let more = gpu_wavefronts(selected.device.as_ref(), &args, &scene, &options)?;
    if !more.is_empty() {
        return render_streams(&scene, options, &args, selected, more, &output, load);
    }
    let render = if args.warmup { render_warmed } else { render };
    let mut bar = progress_bar(args.quiet);
    let out =
        render(selected.device.as_mut(), &scene, options.clone(), &mut |done, total| bar.update(done, total))
            .map_err(|e| CliError::Runtime(format!("rendering failed: {e}")))?;
    bar.finish_and_clear();
    write_image(&out.film, &options, &output)?;
    let run = Run {
        load,
        prepare_seconds: out.prepare_seconds,
        upload_seconds: out.prepare.upload_seconds,
        bvh_build_seconds: out.prepare.bvh_build_seconds,
        render_seconds: out.render_seconds,
        samples_per_second: out.samples_per_second(),
        rays_per_second: out.rays_per_second(),
    };
    print_summary(&output, &options, &selected.description, run);
    Ok(())
}

#[cfg(feature = "mpi")]
fn run_ranked(args: RenderArgs) -> Result<(), CliError> {
    crate::ranked::run(args)
}

#[cfg(not(feature = "mpi"))]
fn run_ranked(_args: RenderArgs) -> Result<(), CliError> {
    Err(CliError::Input(
        "--mpi: this atoll was built without MPI (build it with `cargo build --release --features mpi`)"
            .into(),
    ))
}

/// The scene and what to render of it, as the command line says.
pub(crate) struct Frame {
    pub scene: Arc<Scene>,
    pub options: RenderOptions,
    pub output: PathBuf,
    pub load: LoadReport,
}

/// Loads the scene and applies the command line's overrides; refuses a bad
/// output name before any render time is spent.
/// A file scene's sizes pass `size_check` before its meshes are read.
pub(crate) fn load_frame(args: &RenderArgs, size_check: Option<SizeCheck>) -> Result<Frame, CliError> {
    if let Some(output) = &args.output {
        check_output(output)?;
    }
    let (scene, load) = load_scene_reporting(args.scene.as_deref(), args.quiet, size_check)?;
    let mut options = RenderOptions::from_scene(&scene);
    if let Some(spp) = args.spp {
        options.spp = spp;
    }
    if let Some(res) = args.res {
        options.set_image(&FilmSettings { resolution: res, ..scene.settings.film.clone() });
    }
    // A scene's own resolution gets the same limits as --res (loaders other
    // than PBRT's derive it, e.g. from a glTF camera's aspect ratio).
    if args.res.is_none() {
        let res = options.resolution;
        FilmSettings::check_resolution(res.x as u64, res.y as u64).map_err(|e| {
            let scene =
                args.scene.as_deref().map_or("the built-in scene".into(), |p| p.display().to_string());
            CliError::Input(format!("{scene}: {e}"))
        })?;
    }
    if let Some(depth) = args.max_depth {
        options.integrator = IntegratorSettings::Path { max_depth: depth };
    }
    if let Some(distance) = args.ao {
        options.integrator = IntegratorSettings::AmbientOcclusion { max_distance: distance };
    }
    options.seed = args.seed;
    options.russian_roulette = !args.no_rr;
    if let Some(sampler) = args.light_sampler {
        options.light_sampler = sampler;
    }
    let output = match (&args.output, &scene.settings.film.filename) {
        (Some(output), _) => output.clone(),
        // A scene from elsewhere must not choose where images land: no
        // absolute paths or `..` (as for the files it reads).
        (None, Some(name)) => atoll_scene::input::beside(Path::new(""), name).map_err(|e| {
            let scene = args.scene.as_deref().map_or(String::new(), |p| p.display().to_string());
            CliError::Input(format!("{scene}: Film \"filename\": {e}"))
        })?,
        (None, None) => PathBuf::from("atoll.png"),
    };
    if args.output.is_none() {
        check_output(&output)?;
    }
    Ok(Frame { scene: Arc::new(scene), options, output, load })
}

/// Wave settings for `--devices`: GPU-sized waves when any is a GPU, fitted
/// to `--device-memory`.
pub(crate) fn set_waves_for_devices(args: &RenderArgs, specs: &[DeviceSpec], options: &mut RenderOptions) {
    let gpus = specs.iter().any(|s| s.ordinal().is_some());
    args.waves.apply(options, gpus);
    if let (true, None, Some(budget)) = (gpus, args.waves.wave_size, args.device.device_memory) {
        crate::streams::fit_wave_to_budget(options, budget);
    }
}

/// `--device`: the selected device, with its wave settings.
pub(crate) fn open_device(
    args: &RenderArgs,
    scene: &Arc<Scene>,
    options: &mut RenderOptions,
) -> Result<crate::device::Selected, CliError> {
    let selected = select(&args.device, args.threads)?;
    Ok(fit_device_waves(args, selected, scene, options))
}

/// The wave settings for `selected` rendering `scene`.
fn fit_device_waves(
    args: &RenderArgs,
    selected: crate::device::Selected,
    scene: &Arc<Scene>,
    options: &mut RenderOptions,
) -> crate::device::Selected {
    args.waves.apply(options, selected.gpu.is_some());
    if let (Some(gpu), None) = (&selected.gpu, args.waves.wave_size) {
        let whole = atoll_bvh::ScenePart::whole(scene);
        crate::streams::fit_wave_size(gpu, scene, &whole, options, args.device.device_memory);
    }
    selected
}

/// Devices opened before the scene is loaded.
enum Opened {
    /// `--device`.
    One(crate::device::Selected),
    /// `--devices`.
    Many(Vec<Box<dyn atoll_render::Device>>),
}

/// `--device` or `--devices` opened before the scene is loaded, so that a
/// scene that cannot fit them is refused before it is built
/// ([`crate::preflight`]): a generated scene's sizes are known now; a file
/// scene's are checked by the loader once its text is read, before its
/// meshes are (the check returned). Devices that together cannot hold the
/// scene, however it is split, refuse it the same way.
fn open_before_loading(args: &RenderArgs) -> Result<(Option<Opened>, Option<SizeCheck>), CliError> {
    let Some(source) = args.scene.as_deref() else { return Ok((None, None)) };
    if let Some(output) = &args.output {
        check_output(output)?;
    }
    let known = crate::preflight::known_sizes(Some(source))?;
    let budget = args.device.device_memory;
    let (opened, room) = match &args.devices {
        None => {
            let selected = select(&args.device, args.threads)?;
            let room = Room::of(selected.device.as_ref(), budget);
            (Opened::One(selected), room)
        }
        Some(DeviceList(specs)) => {
            let devices = multi::open_devices(specs, budget, args.threads)?;
            // Scene memory shared over the devices may leave chunks on the host.
            let host_tier = matches!(args.strategy, Strategy::Shared | Strategy::Auto);
            let room = Room::of_devices(&devices, budget, host_tier);
            (Opened::Many(devices), room)
        }
    };
    let Some(counts) = known else { return Ok((Some(opened), room.map(Room::size_check))) };
    crate::preflight::check_fits(source, &counts, room.as_ref())?;
    Ok((Some(opened), None))
}

/// The further wavefronts `--streams` asks for beside `device` (on a GPU:
/// more streams), sharing its scene; none for a CPU.
pub(crate) fn gpu_wavefronts(
    device: &dyn atoll_render::Device,
    args: &RenderArgs,
    scene: &Arc<Scene>,
    options: &RenderOptions,
) -> Result<Vec<Box<dyn atoll_render::Device>>, CliError> {
    atoll_dist::placement::more_wavefronts(
        device,
        args.waves.streams(),
        scene,
        options,
        args.device.device_memory,
    )
    .map_err(|e| CliError::Runtime(e.to_string()))
}

/// One GPU rendering with several wavefronts (`--streams`): the selected
/// device and `more` on its GPU replicate the frame, sharing one copy of
/// the scene; reported like a single device.
fn render_streams(
    scene: &Arc<Scene>,
    options: RenderOptions,
    args: &RenderArgs,
    selected: crate::device::Selected,
    more: Vec<Box<dyn atoll_render::Device>>,
    output: &Path,
    load: LoadReport,
) -> Result<(), CliError> {
    let description = selected.description.clone();
    let mut devices = vec![selected.device];
    devices.extend(more);
    let render = if args.warmup { atoll_dist::render_multi_warmed } else { atoll_dist::render_multi };
    let mut bar = progress_bar(args.quiet);
    let out = render(
        &mut devices,
        scene,
        options.clone(),
        &atoll_dist::Layout::Replicate,
        None,
        &mut |done, total| bar.update(done, total),
    )
    .map_err(|e| CliError::Runtime(e.to_string()))?;
    bar.finish_and_clear();
    write_image(&out.film, &options, output)?;
    let on = format!("{description} x {} wavefronts", devices.len());
    print_summary(output, &options, &on, Run::of(&out, load));
    Ok(())
}

/// Writes the rendered image to `output`; when that fails after the render
/// (the folder removed or full since it was checked), the image is saved
/// under another name ([`atoll_render::Film::write_fallback`]) and the error
/// says where.
/// Writes `film` as its sensor records it (`options.film_response`).
pub(crate) fn write_image(
    film: &atoll_render::Film,
    options: &RenderOptions,
    output: &Path,
) -> Result<(), CliError> {
    let responded;
    let film = if options.film_response == glam::Mat3::IDENTITY {
        film
    } else {
        responded = film.responded(options.film_response);
        &responded
    };
    let Err(e) = film.write(output) else { return Ok(()) };
    Err(CliError::Runtime(match film.write_fallback(output) {
        Ok(saved) => format!("{e}; the image was saved as {} instead", saved.display()),
        Err(again) => format!("{e}; saving it elsewhere failed too: {again}"),
    }))
}

/// How a render went, for the line it ends with.
pub(crate) struct Run {
    pub load: LoadReport,
    pub prepare_seconds: f64,
    /// Of the preparing (the slowest device's, several rendering): scene
    /// uploads and BVH builds; 0 where a device does not report them.
    pub upload_seconds: f64,
    pub bvh_build_seconds: f64,
    pub render_seconds: f64,
    pub samples_per_second: f64,
    pub rays_per_second: f64,
}

impl Run {
    fn of(out: &atoll_dist::MultiOutput, load: LoadReport) -> Self {
        let slowest = |f: fn(&atoll_render::device::PrepareStats) -> f64| {
            out.devices.iter().map(|d| f(&d.prepare)).fold(0.0, f64::max)
        };
        Run {
            load,
            prepare_seconds: out.prepare_seconds,
            upload_seconds: slowest(|p| p.upload_seconds),
            bvh_build_seconds: slowest(|p| p.bvh_build_seconds),
            render_seconds: out.render_seconds,
            samples_per_second: out.samples_per_second(),
            rays_per_second: out.rays_per_second(),
        }
    }
}

/// The line every render ends with: the image, its size, what rendered it,
/// the times and the speed (scripts read the `M samples/s`).
pub(crate) fn print_summary(output: &Path, options: &RenderOptions, on: &str, run: Run) {
    let parts: Vec<String> = [("upload", run.upload_seconds), ("BVH build", run.bvh_build_seconds)]
        .iter()
        .filter(|(_, seconds)| *seconds > 0.0)
        .map(|(what, seconds)| format!("{what} {seconds:.2} s"))
        .collect();
    let mut prepare = format!("prepare {:.2} s", run.prepare_seconds);
    if !parts.is_empty() {
        prepare += &format!(": {}", parts.join(", "));
    }
    println!(
        "{}: {}x{} {} spp on {on} in {:.2} s ({}; {prepare}): {:.2} M samples/s, {:.2} M rays/s",
        output.display(),
        options.resolution.x,
        options.resolution.y,
        options.spp,
        run.render_seconds,
        run.load,
        run.samples_per_second / 1e6,
        run.rays_per_second / 1e6,
    );
}

fn parse_fraction(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(f) if (0.0..=1.0).contains(&f) => Ok(f),
        _ => Err(format!("{s:?}: expected a fraction from 0 to 1")),
    }
}

fn parse_strategy(s: &str) -> Result<Strategy, String> {
    s.parse().map_err(|e: atoll_dist::ParseStrategyError| e.to_string())
}

pub(crate) fn progress_bar(quiet: bool) -> RenderProgress {
    let bar = if quiet { ProgressBar::hidden() } else { ProgressBar::new_spinner() };
    let start = Prepared::now();
    bar.set_style(
        ProgressStyle::with_template("{spinner} preparing [{elapsed_precise}]{prepared}")
            .expect("valid template")
            .with_key("prepared", move |state: &ProgressState, w: &mut dyn std::fmt::Write| {
                let _ =
                    w.write_str(&preparing_text(Prepared::now().since(start), state.elapsed().as_secs_f64()));
            }),
    );
    bar.enable_steady_tick(std::time::Duration::from_millis(100));
    RenderProgress { bar, rendering: false }
}

/// What the preparing spinner adds after its time: the bytes copied to
/// the devices and the triangles their BVHs were built over so far, with
/// rates over `seconds` (nothing before there is anything).
fn preparing_text(done: Prepared, seconds: f64) -> String {
    let seconds = seconds.max(1e-3);
    let mut parts = Vec::new();
    if done.bytes_copied > 0 {
        let gb = done.bytes_copied as f64 / 1e9;
        parts.push(format!("copied {gb:.2} GB ({:.2} GB/s)", gb / seconds));
    }
    if done.triangles_built > 0 {
        let m = done.triangles_built as f64 / 1e6;
        parts.push(format!("BVH over {m:.1} M triangles ({:.1} M/s)", m / seconds));
    }
    match parts.is_empty() {
        true => String::new(),
        false => format!(" {}", parts.join(", ")),
    }
}

/// A render's progress: a spinner while the devices prepare (uploads, BVH
/// builds: no wave is handed out yet), then a bar over the frame's waves.
pub(crate) struct RenderProgress {
    bar: ProgressBar,
    rendering: bool,
}

impl RenderProgress {
    /// `done` of `total` waves handed out.
    pub fn update(&mut self, done: usize, total: usize) {
        if !self.rendering {
            self.rendering = true;
            self.bar.disable_steady_tick();
            self.bar.set_style(
                ProgressStyle::with_template(
                    "{spinner} [{elapsed_precise}] {wide_bar} {percent:>3}% eta {eta}",
                )
                .expect("valid template"),
            );
            self.bar.reset_elapsed();
            self.bar.reset_eta();
        }
        self.bar.set_length(total as u64);
        self.bar.set_position(done as u64);
    }

    pub fn finish_and_clear(&self) {
        self.bar.finish_and_clear();
    }
}

/// `--devices`: plan, render on every device, write, print the per-device table.
fn render_on_devices(
    scene: &Arc<Scene>,
    options: RenderOptions,
    args: &RenderArgs,
    specs: &[DeviceSpec],
    devices: Vec<Box<dyn atoll_render::Device>>,
    output: &Path,
    load: LoadReport,
) -> Result<(), CliError> {
    let mut bar = progress_bar(args.quiet);
    let out =
        multi::render(devices, scene, options.clone(), &multi_args(args, specs), &mut |done, total| {
            bar.update(done, total)
        })?;
    bar.finish_and_clear();
    write_image(&out.film, &options, output)?;
    print!("{}", multi::device_table(&out));
    print!("{}", multi::shared_table(&out));
    let on = format!("{} devices", out.devices.len());
    print_summary(output, &options, &on, Run::of(&out, load));
    Ok(())
}

/// What `--devices` renders with, from the command line.
pub(crate) fn multi_args<'a>(args: &'a RenderArgs, specs: &'a [DeviceSpec]) -> MultiArgs<'a> {
    MultiArgs {
        specs,
        strategy: args.strategy,
        budget: args.device.device_memory,
        ownership: args.ownership.as_deref(),
        transport: args.ring_transport,
        partitioning: args.partitioning,
        streams: args.waves.streams(),
        warmup: args.warmup,
        ring_order: args.ring_order,
        ring_size: args.ring_size,
        shared: shared_spec(args),
    }
}

/// `--strategy shared`'s cut and placement, from the command line.
fn shared_spec(args: &RenderArgs) -> atoll_dist::SharedSpec {
    use atoll_dist::chunk_placement::Replication;
    let default = atoll_dist::SharedSpec::default();
    atoll_dist::SharedSpec {
        chunk_bytes: args.chunk_size.unwrap_or(default.chunk_bytes),
        replication: args.replicate_fraction.map_or(Replication::Auto, Replication::Fraction),
        budget: args.device.device_memory,
        ..default
    }
}

fn parse_light_sampler(name: &str) -> Result<LightSampler, String> {
    match name {
        "bvh" => Ok(LightSampler::Bvh),
        "power" => Ok(LightSampler::Power),
        other => Err(format!("unknown light sampler \"{other}\" (bvh, power)")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_preparing_line_gives_what_was_copied_and_built_with_rates() {
        assert_eq!(preparing_text(Prepared::default(), 1.0), "");
        let done = Prepared { bytes_copied: 3_000_000_000, triangles_built: 0 };
        assert_eq!(preparing_text(done, 2.0), " copied 3.00 GB (1.50 GB/s)");
        let done = Prepared { bytes_copied: 500_000_000, triangles_built: 12_000_000 };
        assert_eq!(
            preparing_text(done, 0.5),
            " copied 0.50 GB (1.00 GB/s), BVH over 12.0 M triangles (24.0 M/s)"
        );
    }

    /// A device's preparing counts the triangles its BVH is built over
    /// (the spinner's source).
    #[test]
    fn preparing_a_cpu_device_counts_its_bvh_triangles() {
        let scene = Arc::new(atoll_scene::cornell::builtin_cornell_box());
        let triangles = scene.stats().unique_triangles;
        let before = Prepared::now();
        let options = RenderOptions::from_scene(&scene);
        let mut device = atoll_render::CpuDevice::default();
        let frame = Arc::new(atoll_render::FrameContext::new(&scene, options));
        atoll_render::Device::prepare(&mut device, &scene, &atoll_bvh::ScenePart::whole(&scene), &frame)
            .unwrap();
        // (Other tests may build at once: at least this scene's.)
        assert!(Prepared::now().since(before).triangles_built >= triangles);
    }

    #[test]
    fn an_image_that_cannot_be_written_is_saved_elsewhere_and_said_where() {
        let dir = tempfile::tempdir().unwrap();
        let mut film = atoll_render::Film::new(UVec2::new(2, 2));
        film.spp = 1;
        let options = RenderOptions::from_scene(&atoll_scene::cornell::builtin_cornell_box());
        assert!(write_image(&film, &options, &dir.path().join("ok.png")).is_ok());
        // The folder went away during the render.
        let output = dir.path().join("gone").join("frame.png");
        let Err(CliError::Runtime(message)) = write_image(&film, &options, &output) else {
            panic!("no error")
        };
        let saved = message.split("saved as ").nth(1).and_then(|s| s.strip_suffix(" instead")).unwrap();
        assert!(message.starts_with(&output.display().to_string()), "{message}");
        let saved = Path::new(saved);
        assert!(saved.starts_with(std::env::temp_dir()) && saved.is_file(), "{message}");
        std::fs::remove_file(saved).unwrap();
    }

    #[test]
    fn wavefronts_per_gpu() {
        let waves = |no_merge, streams| WaveArgs { no_merge, wave_size: None, streams };
        assert_eq!(waves(false, None).streams(), atoll_cuda::DEFAULT_STREAMS);
        assert_eq!(waves(true, None).streams(), 1, "--no-merge keeps reruns bit-identical");
        assert_eq!(waves(true, Some(2)).streams(), 2);
        let mut options = RenderOptions::from_scene(&atoll_scene::cornell::builtin_cornell_box());
        let cpu_default = options.wave_size;
        waves(false, None).apply(&mut options, false);
        assert_eq!(options.wave_size, cpu_default);
        waves(false, None).apply(&mut options, true);
        assert_eq!(options.wave_size, atoll_cuda::DEFAULT_WAVE_SIZE);
        WaveArgs { wave_size: Some(4096), ..waves(false, None) }.apply(&mut options, true);
        assert_eq!(options.wave_size, 4096);
    }
}
