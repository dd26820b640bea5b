//! The CUDA device: [`atoll_render::Device`] on one GPU, stage for stage
//! what [`atoll_render::CpuDevice`] does on the host.
//!
//! | stage            | CPU device                        | here                                         |
//! |------------------|-----------------------------------|----------------------------------------------|
//! | prepare          | `SceneBvh::build`                 | memory plan, table upload, GPU BVH build, frame tables |
//! | queue_work       | pending waves on the host         | `push_work` into a FIFO on the GPU ([`crate::work`]) |
//! | refill           | `camera_record` per free slot     | `refill_claim` + `refill_generate`           |
//! | trace_paths      | `bvh.intersect` + `write_hit`     | `trace::trace_closest_queued` (`write_surface` folded in) |
//! | shade            | `shade` + film / queue appends    | `shade` (appends with atomics)               |
//! | trace_shadows    | `bvh.occluded`                    | `trace::trace_any`                           |
//! | resolve_shadows  | film adds                         | `resolve_shadows`                            |
//!
//! The trait's stage methods cannot fail, but a GPU can (a driver error, a
//! kernel fault). The first error is kept in an [`ErrorSlot`]: it is logged
//! at once, every later stage does nothing and the queues read as empty, so
//! the integrator's loop ends; callers check the slot after rendering (the
//! CLI does) instead of getting a silently wrong image.

use std::mem::ManuallyDrop;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use atoll_bvh::{ByteModel, ScenePart};
use atoll_render::camera::CameraRays;
use atoll_render::device::{DeviceStats, PrepareStats};
use atoll_render::material_coeffs::wants_tangent;
use atoll_render::material_layout::tangent_slot;
use atoll_render::record::MaterialKind;
use atoll_render::{
    Device, DeviceError, DirectTransport, Film, FrameContext, Queue, RayRecord, RenderOptions, Wave,
};
use atoll_scene::Scene;
use cudarc::driver::{CudaFunction, CudaSlice, DevicePtr, PushKernelArg};

use crate::error::CudaError;
use crate::gpu::{launch_1d, Gpu, Timer};
use crate::params::{FrameParams, FrameParamsHost, FrameTables, SceneView};
use crate::queues::{queue_bytes, Queues};
use crate::scene::{GpuScene, HEADROOM};
use crate::trace::{DeviceQueueLength, SurfaceTables, TraceFeatures};
use crate::window::ChunkWindow;
use crate::work::{WorkFeed, FEED_BYTES};
use crate::{bvh, trace};

/// Threads per block of the wavefront kernels.
const BLOCK: u32 = 128;

/// What [`Device::frame_bytes`] allows for the frame parameters (light
/// and material tables) before they are built: a generous allowance.
const PARAMS_ALLOWANCE: u64 = 16 << 20;

/// Bytes a GPU device allocates for a frame of `options` besides the
/// scene ([`Device::frame_bytes`]): queues, wave feed, film, an allowance
/// for the frame parameters (lights, materials: known only once the frame
/// is built) and the headroom.
pub fn frame_bytes(options: &RenderOptions) -> u64 {
    queues_and_film_bytes(options) + PARAMS_ALLOWANCE + HEADROOM
}

/// A frame's queues, wave feed and film: what a device allocates for a
/// frame besides the scene and the frame parameters.
fn queues_and_film_bytes(options: &RenderOptions) -> u64 {
    queue_bytes(options.queue_capacity()) + FEED_BYTES + options.pixel_count() as u64 * 12
}
/// The kernel file of the wavefront stages.
const WAVEFRONT: &str = "wavefront.cu";

/// The first error a device met, shared with whoever needs to check it.
#[derive(Clone, Debug, Default)]
pub struct ErrorSlot(Arc<Mutex<Option<String>>>);

impl ErrorSlot {
    /// The error message, if any.
    pub fn get(&self) -> Option<String> {
        self.0.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }

    /// Keeps `message` unless an earlier error is already kept.
    fn set(&self, message: String) {
        let mut slot = self.0.lock().unwrap_or_else(|p| p.into_inner());
        if slot.is_none() {
            tracing::error!("{message}");
            *slot = Some(message);
        }
    }
}

/// The wavefront kernels, loaded once per prepare.
struct Kernels {
    shade: CudaFunction,
    resolve_shadows: CudaFunction,
}

impl Kernels {
    fn load(gpu: &Gpu, frame: &FrameContext) -> Result<Self, CudaError> {
        Ok(Kernels {
            shade: gpu.function_with(WAVEFRONT, "shade", &shading_options(frame))?,
            resolve_shadows: gpu.function_with(WAVEFRONT, "resolve_shadows", &bookkeeping_options())?,
        })
    }
}

/// The wavefront module of the shading kernels, specialised to `frame`.
fn shading_options(frame: &FrameContext) -> Vec<String> {
    let mut options = vec!["-DATOLL_WAVEFRONT_KERNELS=1".to_string()];
    options.extend(shade_features(frame));
    options
}

/// The wavefront module of the queue bookkeeping (the same for every frame).
fn bookkeeping_options() -> Vec<String> {
    vec!["-DATOLL_WAVEFRONT_KERNELS=2".to_string()]
}

/// Every kernel module a frame loads on a GPU (file, extra options), to be
/// compiled at once ([`Gpu::compile_ahead`]) when preparing starts.
fn frame_modules(frame: &FrameContext) -> Vec<(&'static str, Vec<String>)> {
    let trace = TraceFeatures::of(frame).defines(trace::TraversalVariant::default());
    let mut modules =
        vec![(WAVEFRONT, shading_options(frame)), ("trace.cu", trace), (WAVEFRONT, bookkeeping_options())];
    modules.extend(bvh::BUILD_FILES.iter().map(|&file| (file, Vec::new())));
    modules
}

/// The `shade` kernel is specialised to the frame: material kinds no
/// material has and emission textures when no emitter has one are compiled
/// out (kernels/bsdf.cuh, lights.cuh `ATOLL_WITH_*`), so their registers do
/// not lower every scene's occupancy (the Cornell box's shade kernel needs
/// far fewer registers without them).
fn shade_features(frame: &FrameContext) -> Vec<String> {
    let has = |kinds: &[MaterialKind]| frame.materials.iter().any(|m| kinds.contains(&m.kind));
    let emission_textures = frame.lights.emission_ops.is_empty().then_some("ATOLL_WITH_EMISSION_TEXTURES");
    let coated: &[MaterialKind] = &[MaterialKind::CoatedDiffuse, MaterialKind::CoatedConductor];
    [
        ("ATOLL_WITH_COATED", coated),
        ("ATOLL_WITH_COATED_CONDUCTOR", &[MaterialKind::CoatedConductor]),
        ("ATOLL_WITH_PRINCIPLED", &[MaterialKind::Principled]),
        ("ATOLL_WITH_HAIR", &[MaterialKind::Hair]),
        ("ATOLL_WITH_MEASURED", &[MaterialKind::Measured]),
    ]
    .into_iter()
    .filter(|&(_, kinds)| !has(kinds))
    .map(|(name, _)| name)
    .chain(emission_textures)
    .chain((!may_carry_tangents(frame)).then_some("ATOLL_WITH_TANGENTS"))
    .chain((!frame.media.any()).then_some("ATOLL_WITH_MEDIA"))
    .chain((frame.media.any() && !frame.media.has_rgb_grids()).then_some("ATOLL_WITH_RGB_MEDIA"))
    .map(|name| format!("-D{name}=0"))
    .collect()
}

/// Whether some hit of `frame` may carry a tangent for its BSDF frame
/// (`material_coeffs::wants_tangent`): a material of a kind with a tangent
/// slot that wants one as packed, or whose textures may make it want one.
fn may_carry_tangents(frame: &FrameContext) -> bool {
    frame.materials.iter().zip(&frame.textures.materials).any(|(m, textures)| {
        tangent_slot(m.kind).is_some() && (wants_tangent(m.kind, &m.coeffs) || !textures.is_empty())
    })
}

/// A frame's scene on one GPU: tables, BVH and frame parameters. Read-only
/// once prepared, so devices on the same GPU holding the same part share
/// one ([`CudaDevice::prepare_sharing`]).
struct SceneOnGpu {
    /// Its own arrays, or views into `window` (never freed: leaked on drop).
    scene: ManuallyDrop<GpuScene>,
    bvh: ManuallyDrop<bvh::GpuSceneBvh>,
    params: FrameParamsHost,
    /// One [`SceneView`] on the device (what `write_surface` reads).
    scene_view: CudaSlice<SceneView>,
    /// The shared scene's window the arrays are views into (kept alive
    /// until they are let go), and this device's index among its GPUs.
    window: Option<(Arc<Mutex<ChunkWindow>>, usize)>,
}

impl SceneOnGpu {
    fn own(
        scene: GpuScene,
        bvh: bvh::GpuSceneBvh,
        params: FrameParamsHost,
        scene_view: CudaSlice<SceneView>,
    ) -> Self {
        SceneOnGpu {
            scene: ManuallyDrop::new(scene),
            bvh: ManuallyDrop::new(bvh),
            params,
            scene_view,
            window: None,
        }
    }
}

impl Drop for SceneOnGpu {
    fn drop(&mut self) {
        // SAFETY: the fields are taken once, here, and not used after.
        let (scene, bvh) =
            unsafe { (ManuallyDrop::take(&mut self.scene), ManuallyDrop::take(&mut self.bvh)) };
        match self.window {
            // The window owns the memory (and is dropped after this, with the field).
            Some(_) => crate::sharing::leak_views(scene, bvh),
            None => drop((scene, bvh)),
        }
    }
}

/// Per-chunk read counters of a shared scene on this GPU (the prepass).
struct AccessCounters {
    counts: CudaSlice<u64>,
    /// Whether the trace kernels count now.
    on: bool,
}

/// A device's hold on a [`SceneOnGpu`]. Its buffers are freed on the
/// stream of the device that built it, which does not wait for the
/// others' kernels: each holder finishes its own work before letting go.
struct SceneHold {
    shared: Arc<SceneOnGpu>,
    gpu: Arc<Gpu>,
}

impl Drop for SceneHold {
    fn drop(&mut self) {
        if let Err(e) = self.gpu.synchronize() {
            tracing::error!("{}: finishing before releasing the scene: {e}", self.gpu.label());
        }
    }
}

impl std::ops::Deref for SceneHold {
    type Target = SceneOnGpu;
    fn deref(&self) -> &SceneOnGpu {
        &self.shared
    }
}

/// What `prepare` made resident.
struct Resident {
    frame: Arc<FrameContext>,
    scene: SceneHold,
    kernels: Kernels,
    /// What the trace kernels are specialised for.
    trace_features: TraceFeatures,
    queues: Queues,
    /// RGB f32 radiance sums per pixel.
    film: CudaSlice<f32>,
    /// Rays traced (path segments, shadow rays), counted by the trace
    /// kernels themselves: the host does not know queue lengths mid-wave.
    traced_paths: CudaSlice<u64>,
    traced_shadows: CudaSlice<u64>,
    /// Waves queued on the device and what the host knows of them.
    work: WorkFeed,
    /// Under the shared strategy: the per-chunk read counters.
    access: Option<AccessCounters>,
    /// This device's own frame parameters once its camera moved
    /// ([`Device::set_camera`]); until then the scene's, shared with the
    /// other devices on the GPU.
    moved_camera: Option<CudaSlice<FrameParams>>,
}

/// The frame parameters a device's kernels read ([`Resident::moved_camera`]).
fn frame_params<'a>(
    moved_camera: &'a Option<CudaSlice<FrameParams>>,
    scene: &'a SceneOnGpu,
) -> &'a CudaSlice<FrameParams> {
    moved_camera.as_ref().unwrap_or(&scene.params.device)
}

/// Device time of the stages: timers are collected as stages are queued
/// and summed once their work has finished (no waiting per stage).
#[derive(Default)]
struct BusyTime {
    finished_ms: f64,
    pending: Vec<Timer>,
    /// Timers already read, for reuse.
    spare: Vec<Timer>,
}

impl BusyTime {
    /// Adds the timers whose work has finished (all of them when `wait`).
    fn collect(&mut self, wait: bool) -> Result<(), CudaError> {
        let mut still = Vec::new();
        for timer in self.pending.drain(..) {
            if wait || timer.is_done() {
                self.finished_ms += timer.elapsed_ms()? as f64;
                self.spare.push(timer);
            } else {
                still.push(timer);
            }
        }
        self.pending = still;
        Ok(())
    }

    /// A timer started now on `gpu`'s stream (a spare one when there is).
    fn start(&mut self, gpu: &Gpu) -> Result<Timer, CudaError> {
        match self.spare.pop() {
            Some(mut timer) => timer.restart(gpu).map(|()| timer),
            None => gpu.start_timer(),
        }
    }

    /// Clears the time, keeping the timers for reuse.
    fn reset(&mut self) -> Result<(), CudaError> {
        self.collect(true)?;
        self.finished_ms = 0.0;
        Ok(())
    }
}

/// Whether `ATOLL_SERIAL_STAGES=1` asks timed stages to run one at a time
/// ([`Device::time_stages`]).
fn serial_stages() -> bool {
    static SERIAL: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *SERIAL.get_or_init(|| std::env::var("ATOLL_SERIAL_STAGES").is_ok_and(|v| v == "1"))
}

/// A device that runs every stage on one CUDA GPU.
pub struct CudaDevice {
    gpu: Arc<Gpu>,
    memory_budget: Option<u64>,
    resident: Option<Resident>,
    errors: ErrorSlot,
    stats: DeviceStats,
    busy: Mutex<BusyTime>,
    /// Times the wave in flight, from `generate` to the `has_paths` that
    /// finds the path queue empty.
    wave_timer: Mutex<Option<Timer>>,
    /// Time each stage rather than whole waves ([`Device::time_stages`]).
    stage_timing: bool,
}

impl CudaDevice {
    /// A device on GPU `ordinal` (opened now: fails without a driver, GPU or NVRTC).
    pub fn new(ordinal: usize) -> Result<Self, CudaError> {
        Ok(Self::on(Gpu::open(ordinal)?))
    }

    /// A device on an already opened GPU.
    pub fn on(gpu: Arc<Gpu>) -> Self {
        CudaDevice {
            gpu,
            memory_budget: None,
            resident: None,
            errors: ErrorSlot::default(),
            stats: DeviceStats::default(),
            busy: Mutex::new(BusyTime::default()),
            wave_timer: Mutex::new(None),
            stage_timing: false,
        }
    }

    /// Limits the bytes this device may allocate (scene, BVH, queues, film).
    pub fn with_memory_budget(mut self, bytes: u64) -> Self {
        self.memory_budget = Some(bytes);
        self
    }

    pub fn gpu(&self) -> &Arc<Gpu> {
        &self.gpu
    }

    /// Where the first failure of a stage is kept (see the module docs).
    pub fn errors(&self) -> ErrorSlot {
        self.errors.clone()
    }

    /// [`DeviceError::Stopped`] once a call has failed.
    fn stopped(&self) -> Result<(), DeviceError> {
        match self.errors.get() {
            Some(first) => Err(DeviceError::Stopped { device: self.gpu.label(), first }),
            None => Ok(()),
        }
    }

    /// Keeps `e`, met doing `name` (later calls stop), and returns it with
    /// `name` as its context.
    fn failed(&self, name: &str, e: CudaError) -> DeviceError {
        let device = self.gpu.label();
        self.errors.set(format!("{device} {name}: {e}"));
        DeviceError::Backend { what: format!("{name}: {e}"), device, source: Box::new(e) }
    }

    /// Runs `f`, what `name` does on this device: after an earlier
    /// failure not at all; a failure is kept and returned.
    fn checked<R>(&self, name: &str, f: impl FnOnce() -> Result<R, CudaError>) -> Result<R, DeviceError> {
        self.stopped()?;
        f().map_err(|e| self.failed(name, e))
    }

    /// [`CudaDevice::checked`] for a stage that needs the device mutably.
    fn stage(
        &mut self,
        name: &str,
        f: impl FnOnce(&mut Self) -> Result<(), CudaError>,
    ) -> Result<(), DeviceError> {
        self.stopped()?;
        f(self).map_err(|e| self.failed(name, e))
    }

    /// [`CudaDevice::stage`] between a pair of timing events when stages are timed.
    fn timed_stage(
        &mut self,
        name: &str,
        f: impl FnOnce(&mut Self) -> Result<(), CudaError>,
    ) -> Result<(), DeviceError> {
        if !self.stage_timing {
            return self.stage(name, f);
        }
        // Measurement aid (`ATOLL_SERIAL_STAGES=1`): every timed stage runs
        // alone in the process, finished before the next starts, so each
        // device's busy time is what its stages take without the others
        // sharing its GPU: with a ring's members on one GPU, what each
        // would take on a GPU of its own (BENCHMARKS.md).
        static SERIAL: Mutex<()> = Mutex::new(());
        let serial = serial_stages().then(|| SERIAL.lock().unwrap_or_else(|p| p.into_inner()));
        if serial.is_some() {
            self.stage("synchronize", |d| d.gpu.synchronize())?;
        }
        self.stage(name, |d| {
            let mut busy = d.busy.lock().unwrap_or_else(|p| p.into_inner());
            if busy.pending.len() >= 32 {
                // Read the finished ones (never waits), so timers get reused.
                busy.collect(false)?;
            }
            let mut timer = busy.start(&d.gpu)?;
            drop(busy);
            let done = f(d);
            timer.stop(&d.gpu)?;
            d.busy.lock().unwrap_or_else(|p| p.into_inner()).pending.push(timer);
            done
        })?;
        if serial.is_some() {
            self.stage("synchronize", |d| d.gpu.synchronize())?;
        }
        Ok(())
    }

    fn resident(&mut self) -> Result<&mut Resident, CudaError> {
        self.resident.as_mut().ok_or_else(|| CudaError::Usage("CudaDevice used before prepare()".into()))
    }

    /// Whether the frame has media: shadow rays then carry their optical
    /// depth in the record's hit half (an error before `prepare`).
    pub(crate) fn frame_has_media(&mut self) -> Result<bool, CudaError> {
        Ok(self.resident()?.frame.media.any())
    }

    /// The frame's queues (an error before `prepare`).
    pub(crate) fn queues_mut(&mut self) -> Result<&mut Queues, CudaError> {
        Ok(&mut self.resident()?.queues)
    }

    /// Runs `f` on the frame's resident state (an error before `prepare`).
    /// Stages are not timed one by one: device time is measured per wave
    /// (`start_wave_timer`), because creating and recording an event pair
    /// around every stage cost more host time than the small stages take on
    /// the GPU, which then waited for its next launch.
    fn with_resident<R>(
        &mut self,
        f: impl FnOnce(&mut Resident) -> Result<R, CudaError>,
    ) -> Result<R, CudaError> {
        f(self.resident()?)
    }

    fn start_wave_timer(&self) -> Result<(), CudaError> {
        self.stop_wave_timer()?;
        if self.stage_timing {
            return Ok(());
        }
        *self.wave_timer.lock().unwrap_or_else(|p| p.into_inner()) = Some(self.gpu.start_timer()?);
        Ok(())
    }

    /// Ends the wave's timer (queued; never waits) and files it for `stats`.
    fn stop_wave_timer(&self) -> Result<(), CudaError> {
        if let Some(mut timer) = self.wave_timer.lock().unwrap_or_else(|p| p.into_inner()).take() {
            timer.stop(&self.gpu)?;
            self.busy.lock().unwrap_or_else(|p| p.into_inner()).pending.push(timer);
        }
        Ok(())
    }

    /// Frees the previous frame's buffers (before planning the new one)
    /// and clears the counters.
    fn release(&mut self) {
        self.resident = None;
        self.stats = DeviceStats::default();
        *self.busy.lock().unwrap_or_else(|p| p.into_inner()) = BusyTime::default();
    }

    fn try_prepare(
        &mut self,
        scene: &Arc<Scene>,
        part: &ScenePart,
        frame: &Arc<FrameContext>,
    ) -> Result<PrepareStats, CudaError> {
        self.release();
        let gpu = self.gpu.clone();
        let options = &frame.options;
        let capacity = options.queue_capacity();
        let params_bytes = FrameTables::build(frame).bytes() + std::mem::size_of::<SceneView>() as u64;
        let frame_bytes = queues_and_film_bytes(options) + params_bytes;

        // Compiled (or loaded from the cache) while the scene goes up and
        // its BVH is built, and before the clock of the first wave starts.
        gpu.compile_ahead(frame_modules(frame));
        let start = Instant::now();
        let gpu_scene = GpuScene::upload_part(&gpu, scene, part, self.memory_budget, frame_bytes)?;
        gpu.synchronize()?;
        let upload_seconds = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let bvh = bvh::GpuSceneBvh::build(&gpu, &gpu_scene)?;
        gpu.synchronize()?;
        let bvh_build_seconds = start.elapsed().as_secs_f64();
        let params = FrameParamsHost::for_scene(&gpu, frame, Some(&gpu_scene))?;
        let view = [SceneView::of(&gpu_scene)];
        let scene_view =
            gpu.stream.clone_htod(&view).map_err(CudaError::driver("uploading the scene view"))?;
        let shared = Arc::new(SceneOnGpu::own(gpu_scene, bvh, params, scene_view));
        let kernels = Kernels::load(&gpu, frame)?;
        let mut stats = self.make_resident(frame, shared, kernels, capacity)?;
        stats.scene_bytes = {
            let s = &self.resident()?.scene;
            s.scene.bytes() + s.bvh.bytes()
        };
        stats.bvh_build_seconds = bvh_build_seconds;
        stats.upload_seconds = upload_seconds;
        stats.bvh_sah_cost = self.resident()?.scene.bvh.sah_cost();
        Ok(stats)
    }

    /// The per-device state over a prepared scene: trace kernels, queues,
    /// film, counters, wave feed. Stats count the frame's bytes only.
    fn make_resident(
        &mut self,
        frame: &Arc<FrameContext>,
        shared: Arc<SceneOnGpu>,
        kernels: Kernels,
        capacity: u32,
    ) -> Result<PrepareStats, CudaError> {
        let gpu = self.gpu.clone();
        let options = &frame.options;
        // The BVH's own features too: the counting prepass sets its
        // counters in the module these name, which must be the one traced with.
        let trace_features = TraceFeatures::of(frame).for_bvh(&shared.bvh);
        trace::load_default_kernels(&gpu, &shared.bvh, trace_features)?;
        let queues = Queues::new(&gpu, capacity)?;
        let film = gpu
            .stream
            .alloc_zeros::<f32>(options.pixel_count().max(1) as usize * 3)
            .map_err(CudaError::driver(format!("{}: allocating the film", gpu.label())))?;
        let counter = |what: &str| {
            gpu.stream
                .alloc_zeros::<u64>(1)
                .map_err(CudaError::driver(format!("{}: allocating the {what} counter", gpu.label())))
        };
        let (traced_paths, traced_shadows) = (counter("traced paths")?, counter("traced shadows")?);
        let work = WorkFeed::new(&gpu, (WAVEFRONT, &bookkeeping_options()))?;
        gpu.synchronize()?;
        let stats = PrepareStats {
            frame_bytes: queues_and_film_bytes(options) + shared.params.bytes(),
            ..Default::default()
        };
        self.resident = Some(Resident {
            frame: frame.clone(),
            scene: SceneHold { shared, gpu: gpu.clone() },
            kernels,
            trace_features,
            queues,
            film,
            traced_paths,
            traced_shadows,
            work,
            access: None,
            moved_camera: None,
        });
        Ok(stats)
    }

    /// Prepares for `frame` over a shared scene: `scene` and `bvh` are
    /// views into `window` (this GPU's range, tables as `layout` puts
    /// them), the frame's light and material tables this GPU's own.
    pub(crate) fn prepare_on_window(
        &mut self,
        frame: &Arc<FrameContext>,
        scene: GpuScene,
        bvh: bvh::GpuSceneBvh,
        window: (Arc<Mutex<ChunkWindow>>, usize),
        layout: &atoll_render::ChunkLayout,
    ) -> Result<PrepareStats, DeviceError> {
        let label = self.gpu.label();
        let attempt = |d: &mut Self| -> Result<PrepareStats, CudaError> {
            d.release();
            let gpu = d.gpu.clone();
            let params = FrameParamsHost::for_scene(&gpu, frame, Some(&scene));
            let view = [SceneView::of(&scene)];
            let scene_view =
                gpu.stream.clone_htod(&view).map_err(CudaError::driver("uploading the scene view"));
            let (params, scene_view) = match (params, scene_view) {
                (Ok(p), Ok(v)) => (p, v),
                (Err(e), _) | (_, Err(e)) => {
                    // The views are the window's memory: let go, never free.
                    crate::sharing::leak_views(scene, bvh);
                    return Err(e);
                }
            };
            let shared = Arc::new(SceneOnGpu {
                scene: ManuallyDrop::new(scene),
                bvh: ManuallyDrop::new(bvh),
                params,
                scene_view,
                window: Some(window),
            });
            gpu.compile_ahead(frame_modules(frame));
            let kernels = Kernels::load(&gpu, frame)?;
            let mut stats = d.make_resident(frame, shared, kernels, frame.options.queue_capacity())?;
            let counts = gpu
                .stream
                .alloc_zeros::<u64>(layout.chunk_count().max(1))
                .map_err(CudaError::driver(format!("{label}: allocating access counters")))?;
            d.resident()?.access = Some(AccessCounters { counts, on: false });
            stats.bvh_sah_cost = d.resident()?.scene.bvh.sah_cost();
            Ok(stats)
        };
        attempt(self).map_err(|e| {
            self.resident = None;
            e.into_device_error(&label)
        })
    }

    /// Bytes of shared-scene chunks this device may hold for a frame of
    /// `options`: its budget less the frame's own allocations (`None`
    /// without a budget: the window checks free memory itself).
    pub(crate) fn chunk_budget(&self, options: &RenderOptions) -> Option<u64> {
        self.memory_budget.map(|b| b.saturating_sub(frame_bytes(options)))
    }

    /// The options of the frame prepared.
    pub(crate) fn frame_options(&mut self) -> Result<RenderOptions, CudaError> {
        Ok(self.resident()?.frame.options.clone())
    }

    /// Zeroes the shared scene's read counters.
    pub(crate) fn clear_access_counts(&mut self) -> Result<(), CudaError> {
        let gpu = self.gpu.clone();
        if let Some(a) = self.resident()?.access.as_mut() {
            gpu.stream.memset_zeros(&mut a.counts).map_err(CudaError::driver("clearing access counters"))?;
        }
        Ok(())
    }

    /// Switches the trace kernels to (or from) the counting variant, and
    /// points the counting module's globals at this GPU's counters and window.
    fn try_count_accesses(&mut self, on: bool) -> Result<(), CudaError> {
        let gpu = self.gpu.clone();
        let r = self.resident()?;
        let Some(access) = r.access.as_mut() else {
            return Err(CudaError::Usage("counting accesses needs a shared scene".into()));
        };
        access.on = on;
        r.trace_features.count_accesses = on;
        if !on {
            return Ok(());
        }
        let (window, d) = r.scene.window.as_ref().expect("a shared scene has a window");
        let (base, bytes, chunk) = {
            let w = window.lock().unwrap_or_else(|p| p.into_inner());
            (w.base(*d), w.bytes(), w.chunk_bytes())
        };
        let counts = access.counts.device_ptr(&gpu.stream).0;
        let module =
            gpu.module_with("trace.cu", &r.trace_features.defines(trace::TraversalVariant::default()))?;
        for (name, value) in [
            ("atoll_access_counts", counts),
            ("atoll_window_base", base),
            ("atoll_window_bytes", bytes),
            ("atoll_chunk_bytes", chunk),
        ] {
            let mut global = module
                .get_global(name, &gpu.stream)
                .map_err(CudaError::driver(format!("{}: finding {name}", gpu.label())))?;
            gpu.stream
                .memcpy_htod(&value.to_ne_bytes(), &mut global)
                .map_err(CudaError::driver(format!("{}: setting {name}", gpu.label())))?;
        }
        trace::load_default_kernels(&gpu, &r.scene.bvh, r.trace_features)
    }

    /// Zeroes the film and the kernels' counters (queued on the stream).
    fn try_reset_frame(&mut self) -> Result<(), CudaError> {
        self.stop_wave_timer()?;
        let gpu = self.gpu.clone();
        let r = self.resident()?;
        let what = || format!("{}: clearing the film and counters", gpu.label());
        gpu.stream.memset_zeros(&mut r.film).map_err(CudaError::driver(what()))?;
        gpu.stream.memset_zeros(&mut r.traced_paths).map_err(CudaError::driver(what()))?;
        gpu.stream.memset_zeros(&mut r.traced_shadows).map_err(CudaError::driver(what()))?;
        gpu.stream.memset_zeros(&mut r.queues.sent_bytes).map_err(CudaError::driver(what()))?;
        self.stats = DeviceStats::default();
        self.busy.lock().unwrap_or_else(|p| p.into_inner()).reset()
    }

    fn try_set_camera(&mut self, camera: &CameraRays) -> Result<(), CudaError> {
        let gpu = self.gpu.clone();
        let r = self.resident()?;
        let mut params = r.scene.params.params;
        params.set_camera(camera);
        // Uploaded in stream order: later kernels read it, earlier ones the
        // old block (freed in stream order too).
        let block = gpu
            .stream
            .clone_htod(&[params])
            .map_err(CudaError::driver(format!("{}: uploading the moved camera", gpu.label())))?;
        r.moved_camera = Some(block);
        r.frame = Arc::new(FrameContext { camera: camera.clone(), ..(*r.frame).clone() });
        Ok(())
    }

    fn try_queue_work(&mut self, wave: &Wave) -> Result<(), CudaError> {
        let gpu = self.gpu.clone();
        if self.wave_timer.lock().unwrap_or_else(|p| p.into_inner()).is_none() {
            self.start_wave_timer()?;
        }
        let r = self.resident()?;
        r.work.push(&gpu, wave.sample, wave.first_pixel, wave.pixel_count)
    }

    fn try_refill(&mut self) -> Result<(), CudaError> {
        let gpu = self.gpu.clone();
        self.with_resident(|r| {
            r.work.refill(&gpu, frame_params(&r.moved_camera, &r.scene), &mut r.queues, BLOCK)
        })
    }

    fn try_trace_paths(&mut self) -> Result<(), CudaError> {
        let gpu = self.gpu.clone();
        if self.resident()?.queues.known_len(Queue::Paths) == Some(0) {
            return Ok(());
        }
        self.with_resident(|r| {
            let q = &mut r.queues;
            // The kernels read the path count on the device: no read-back.
            let max = q.launch_len(Queue::Paths);
            let length = DeviceQueueLength { length: &q.path_count, traced: &mut r.traced_paths };
            // Hit attributes are written by the traversal kernel itself (the
            // `surface` stage folded in): one pass over the records fewer.
            let surface =
                SurfaceTables { params: frame_params(&r.moved_camera, &r.scene), scene: &r.scene.scene_view };
            let features = r.trace_features;
            trace::trace_closest_queued(
                &gpu,
                &r.scene.scene,
                &r.scene.bvh,
                &mut q.paths,
                max,
                &mut q.hits,
                length,
                surface,
                features,
            )
        })
    }

    fn try_shade(&mut self) -> Result<(), CudaError> {
        let gpu = self.gpu.clone();
        self.with_resident(|r| {
            let q = &mut r.queues;
            let threads = q.launch_len(Queue::Paths);
            let context = || format!("{}: clearing queue counters", gpu.label());
            gpu.stream.memset_zeros(&mut q.next_count).map_err(CudaError::driver(context()))?;
            gpu.stream.memset_zeros(&mut q.shadow_count).map_err(CudaError::driver(context()))?;
            let mut launch = gpu.stream.launch_builder(&r.kernels.shade);
            launch
                .arg(frame_params(&r.moved_camera, &r.scene))
                .arg(&q.paths)
                .arg(&q.path_count)
                .arg(&mut q.next)
                .arg(&mut q.next_count)
                .arg(&mut q.shadows)
                .arg(&mut q.shadow_count)
                .arg(&mut r.film);
            // SAFETY: matches `shade(const FrameParams*, const RayRecord* paths, const unsigned*
            // path_count, RayRecord* next, unsigned* next_count, RayRecord* shadows, unsigned*
            // shadow_count, float* film)`. Each path appends at most one record to `next` and
            // one to `shadows`, which have the same capacity as `paths`, so appends stay in
            // bounds; both counters were zeroed just above on the same stream; `film` holds
            // 3 floats per pixel and records only name pixels of this frame.
            unsafe { launch.launch(launch_1d(threads, BLOCK)) }
                .map_err(CudaError::driver("launching shade"))?;
            q.swap_paths();
            q.set_known_len(Queue::Shadows, None);
            Ok(())
        })
    }

    fn try_trace_shadows(&mut self) -> Result<(), CudaError> {
        let gpu = self.gpu.clone();
        if self.resident()?.queues.known_len(Queue::Shadows) == Some(0) {
            return Ok(());
        }
        self.with_resident(|r| {
            let q = &mut r.queues;
            let max = q.launch_len(Queue::Shadows);
            let length = DeviceQueueLength { length: &q.shadow_count, traced: &mut r.traced_shadows };
            let tables =
                SurfaceTables { params: frame_params(&r.moved_camera, &r.scene), scene: &r.scene.scene_view };
            trace::trace_any_queued(
                &gpu,
                &r.scene.scene,
                &r.scene.bvh,
                &mut q.shadows,
                max,
                length,
                tables,
                r.trace_features,
            )
        })
    }

    fn try_resolve_shadows(&mut self) -> Result<(), CudaError> {
        let gpu = self.gpu.clone();
        self.with_resident(|r| {
            let q = &mut r.queues;
            if q.known_len(Queue::Shadows) != Some(0) {
                let threads = q.launch_len(Queue::Shadows);
                let media = r.frame.media.any() as u32;
                let mut launch = gpu.stream.launch_builder(&r.kernels.resolve_shadows);
                launch.arg(&q.shadows).arg(&q.shadow_count).arg(&mut r.film).arg(&media);
                // SAFETY: matches `resolve_shadows(const RayRecord* shadows, const unsigned*
                // shadow_count, float* film, unsigned int media)`; the kernel stops at
                // `*shadow_count <= capacity` and records only name pixels of this frame's film.
                unsafe { launch.launch(launch_1d(threads, BLOCK)) }
                    .map_err(CudaError::driver("launching resolve_shadows"))?;
            }
            // Like the CPU device, resolving empties the shadow queue.
            q.clear(&gpu, Queue::Shadows)
        })
    }

    fn try_film(&self) -> Result<Film, CudaError> {
        let r = self
            .resident
            .as_ref()
            .ok_or_else(|| CudaError::Usage("CudaDevice::film before prepare()".into()))?;
        let mut film = Film::new(r.frame.options.resolution);
        // Straight into the film's sums (three f32 a pixel, no padding).
        let sums: &mut [f32] = bytemuck::cast_slice_mut(&mut film.sum);
        self.gpu
            .stream
            .memcpy_dtoh(&r.film, sums)
            .map_err(CudaError::driver(format!("{}: downloading the film", self.gpu.label())))?;
        self.gpu.synchronize()?;
        Ok(film)
    }

    /// Rays traced so far (paths, shadows), from the kernels' counters.
    fn try_traced(&self) -> Result<(u64, u64), CudaError> {
        let Some(r) = &self.resident else { return Ok((0, 0)) };
        let read = |c: &CudaSlice<u64>| {
            self.gpu.stream.clone_dtoh(c).map_err(CudaError::driver("reading the ray counters"))
        };
        Ok((read(&r.traced_paths)?[0], read(&r.traced_shadows)?[0]))
    }

    fn try_busy_seconds(&self) -> Result<f64, CudaError> {
        let mut busy = self.busy.lock().unwrap_or_else(|p| p.into_inner());
        busy.collect(true)?;
        Ok(busy.finished_ms / 1e3)
    }
}

impl Device for CudaDevice {
    fn name(&self) -> String {
        self.gpu.label()
    }

    fn prepare(
        &mut self,
        scene: &Arc<Scene>,
        part: &ScenePart,
        frame: &Arc<FrameContext>,
    ) -> Result<PrepareStats, DeviceError> {
        self.try_prepare(scene, part, frame).map_err(|e| {
            self.resident = None;
            e.into_device_error(&self.gpu.label())
        })
    }

    fn reset_frame(&mut self) -> Result<(), DeviceError> {
        self.stage("reset_frame", |d| d.try_reset_frame())
    }

    fn set_camera(&mut self, camera: &CameraRays) -> Result<(), DeviceError> {
        self.stage("set_camera", |d| d.try_set_camera(camera))
    }

    fn queue_work(&mut self, wave: &Wave) -> Result<(), DeviceError> {
        self.stage("queue_work", |d| d.try_queue_work(wave))
    }

    fn wants_work(&self) -> Result<bool, DeviceError> {
        let Some(r) = &self.resident else { return Ok(false) };
        self.checked("wants_work", || r.work.wants_work(r.queues.capacity))
    }

    fn refill(&mut self) -> Result<(), DeviceError> {
        self.timed_stage("refill", |d| d.try_refill())
    }

    fn trace_paths(&mut self) -> Result<(), DeviceError> {
        self.timed_stage("trace_paths", |d| d.try_trace_paths())
    }

    fn shade(&mut self) -> Result<(), DeviceError> {
        self.timed_stage("shade", |d| d.try_shade())
    }

    fn trace_shadows(&mut self) -> Result<(), DeviceError> {
        self.timed_stage("trace_shadows", |d| d.try_trace_shadows())
    }

    fn resolve_shadows(&mut self) -> Result<(), DeviceError> {
        self.timed_stage("resolve_shadows", |d| d.try_resolve_shadows())
    }

    /// From the status of the last refill (see [`crate::work`]): waits for
    /// that refill, not for the stages queued after it, so the GPU keeps a
    /// bounce of work while the host decides. The answer is a bounce late:
    /// after the last paths finish, one more (empty) bounce runs.
    fn has_paths(&self) -> Result<bool, DeviceError> {
        let Some(r) = &self.resident else { return Ok(false) };
        let more = self.checked("has_paths", || r.work.busy())?;
        if !more {
            self.checked("timing", || self.stop_wave_timer())?;
        }
        Ok(more)
    }

    fn queue_len(&self, queue: Queue) -> Result<usize, DeviceError> {
        let Some(r) = &self.resident else { return Ok(0) };
        let len = self.checked("queue_len", || r.queues.len(&self.gpu, queue))?;
        // Sum the timers that are done (all of them after a read-back),
        // so the pending list stays short; this never waits.
        self.checked("timing", || self.busy.lock().unwrap_or_else(|p| p.into_inner()).collect(false))?;
        Ok(len as usize)
    }

    fn read_queue_into(&self, queue: Queue, into: &mut Vec<RayRecord>) -> Result<(), DeviceError> {
        into.clear();
        let Some(r) = &self.resident else { return Ok(()) };
        self.checked("read_queue", || r.queues.read(&self.gpu, queue, into)).inspect_err(|_| into.clear())
    }

    fn write_queue(&mut self, queue: Queue, records: &[RayRecord]) -> Result<(), DeviceError> {
        let gpu = self.gpu.clone();
        self.stage("write_queue", |d| d.resident()?.queues.write(&gpu, queue, records))
    }

    fn film(&self) -> Result<Film, DeviceError> {
        self.checked("film", || self.try_film())
    }

    fn frame_bytes(&self, options: &RenderOptions) -> u64 {
        frame_bytes(options)
    }

    fn byte_model(&self) -> ByteModel {
        crate::scene::byte_model()
    }

    fn shared_byte_model(&self) -> ByteModel {
        crate::scene::shared_byte_model()
    }

    fn scene_wide_bytes(&self, scene: &Scene) -> u64 {
        crate::scene::scene_wide_rows(scene)
    }

    fn free_memory(&self) -> Option<u64> {
        self.gpu.free_memory().ok()
    }

    fn set_memory_budget(&mut self, bytes: Option<u64>) {
        self.memory_budget = bytes;
    }

    fn scene_sharing(&self) -> Option<Arc<dyn atoll_render::SceneSharing>> {
        Some(Arc::new(crate::sharing::CudaSharing::new(self.gpu.clone(), self.memory_budget)))
    }

    fn count_accesses(&mut self, on: bool) -> Result<(), DeviceError> {
        self.stage("count_accesses", |d| d.try_count_accesses(on))
    }

    fn access_counts(&self) -> Result<Vec<u64>, DeviceError> {
        let Some(r) = &self.resident else {
            return Err(self.failed("access_counts", CudaError::Usage("before prepare()".into())));
        };
        let Some(a) = &r.access else {
            return Err(DeviceError::Unsupported {
                device: self.gpu.label(),
                what: "counting without a shared scene".into(),
            });
        };
        self.checked("access_counts", || {
            self.gpu.synchronize()?;
            self.gpu.stream.clone_dtoh(&a.counts).map_err(CudaError::driver("reading access counters"))
        })
    }

    fn default_wave_size(&self) -> u32 {
        crate::DEFAULT_WAVE_SIZE
    }

    fn shares_memory_with(&self, other: &dyn Device) -> bool {
        other.as_any().downcast_ref::<CudaDevice>().is_some_and(|o| o.gpu.ordinal == self.gpu.ordinal)
    }

    /// One copy of the tables and BVH serves both devices, each with its
    /// own queues and film: two devices on one GPU keep it busier than one
    /// (their kernels fill each other's gaps), at no cost in scene memory.
    fn prepare_sharing(
        &mut self,
        owner: &dyn Device,
        frame: &Arc<FrameContext>,
    ) -> Result<PrepareStats, DeviceError> {
        let label = self.gpu.label();
        let owner = owner.as_any().downcast_ref::<CudaDevice>();
        let shared = match owner.and_then(|o| o.resident.as_ref().map(|r| (o, r))) {
            Some((o, r)) if o.gpu.ordinal == self.gpu.ordinal && Arc::ptr_eq(&r.frame, frame) => {
                r.scene.shared.clone()
            }
            _ => {
                return Err(CudaError::Usage(format!(
                    "{label}: can share only the scene of a device on the same GPU prepared for this frame"
                ))
                .into_device_error(&label))
            }
        };
        let attempt = |d: &mut Self| -> Result<PrepareStats, CudaError> {
            d.release();
            let plan = crate::scene::MemoryPlan {
                queues: queues_and_film_bytes(&frame.options),
                ..Default::default()
            };
            plan.check(&label, d.memory_budget, d.gpu.free_memory()?)?;
            let kernels = Kernels::load(&d.gpu, frame)?;
            d.make_resident(frame, shared, kernels, frame.options.queue_capacity())
        };
        attempt(self).map_err(|e| {
            self.resident = None;
            e.into_device_error(&label)
        })
    }

    fn another_on_same_hardware(&self) -> Option<Result<Box<dyn Device>, DeviceError>> {
        let more = self.gpu.another_stream().map(|gpu| {
            let mut d = CudaDevice::on(gpu);
            d.memory_budget = self.memory_budget;
            Box::new(d) as Box<dyn Device>
        });
        Some(more.map_err(|e| e.into_device_error(&self.gpu.label())))
    }

    /// Each stage between a pair of events, kept for reuse: a ring's
    /// bounces are large enough that recording them costs nothing
    /// measurable, unlike the small bounces of one device, which keeps
    /// timing waves.
    fn time_stages(&mut self, per_stage: bool) {
        self.stage_timing = per_stage;
    }

    fn direct_transport(&self) -> Option<Arc<dyn DirectTransport>> {
        Some(Arc::new(crate::peer::PeerTransport))
    }

    fn process_transport(&self) -> Option<Arc<dyn atoll_render::ProcessTransport>> {
        crate::nccl::nccl_present().then(|| Arc::new(crate::nccl::NcclTransport) as Arc<_>)
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }

    fn stats(&self) -> Result<DeviceStats, DeviceError> {
        let mut stats = self.stats.clone();
        (stats.rays_traced, stats.shadow_rays_traced) = self.checked("stats", || self.try_traced())?;
        stats.busy_seconds = self.checked("stats", || self.try_busy_seconds())?;
        Ok(stats)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use atoll_scene::texture_scenes::anisotropic_plane_scene;
    use atoll_scene::{Material, Rgb};
    use glam::Vec2;

    fn features_of(scene: &Scene) -> Vec<String> {
        shade_features(&FrameContext::new(scene, atoll_render::RenderOptions::from_scene(scene)))
    }

    /// Only frames with a material whose hits may carry a tangent compile
    /// the shade kernel's tangent read in.
    #[test]
    fn tangents_are_compiled_in_for_anisotropic_materials_only() {
        let without = "-DATOLL_WITH_TANGENTS=0".to_string();
        let conductor = |alpha_y| Material::Conductor { eta: Rgb::ONE, k: Rgb::ONE, alpha_x: 0.1, alpha_y };
        let cornell = atoll_scene::cornell::builtin_cornell_box();
        assert!(features_of(&cornell).contains(&without));
        let isotropic = anisotropic_plane_scene(conductor(0.1), 0.0, Vec2::ZERO);
        assert!(features_of(&isotropic).contains(&without));
        let anisotropic = anisotropic_plane_scene(conductor(0.4), 0.0, Vec2::ZERO);
        assert!(!features_of(&anisotropic).contains(&without));
        let measured = anisotropic_plane_scene(Material::Measured { brdf: 0 }, 0.0, Vec2::ZERO);
        assert!(!features_of(&measured).contains(&without));
    }
}
