//! One opened GPU: its context, the stream all of atoll's work goes on, its
//! properties, and the kernel modules loaded into it.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use cudarc::driver::sys::{CUdevice_attribute, CUevent_flags};
use cudarc::driver::{CudaContext, CudaEvent, CudaFunction, CudaModule, CudaStream, LaunchConfig};
use cudarc::nvrtc::Ptx;

use crate::compile::{compile, CompileOptions, Output};
use crate::error::{require_driver, require_nvrtc, CudaError};
use crate::scene::rows::RowTable;

/// Number of CUDA GPUs, `Err(NoDriver)` without a driver library. A driver
/// that loads but finds no GPU (or is not initialisable) counts as 0.
pub fn device_count() -> Result<usize, CudaError> {
    require_driver()?;
    match CudaContext::device_count() {
        Ok(n) => Ok(n.max(0) as usize),
        // cuInit fails with NO_DEVICE on a machine without GPUs.
        Err(e) if e.0 == cudarc::driver::sys::CUresult::CUDA_ERROR_NO_DEVICE => Ok(0),
        Err(e) => Err(CudaError::Driver { context: "counting CUDA GPUs".into(), source: e }),
    }
}

/// One compiled image, filled by the first caller asking for it.
type CompiledSlot = Arc<Mutex<Option<Arc<Vec<u8>>>>>;

/// The process's slot for `file` compiled with `options`, and whether this
/// call made it (no one asked for that image before).
fn compiled_slot(file: &str, options: &CompileOptions) -> (CompiledSlot, bool) {
    static COMPILED: std::sync::OnceLock<Mutex<HashMap<String, CompiledSlot>>> = std::sync::OnceLock::new();
    let key = format!("{file} {:?} {}", options.nvrtc_options(), options.extension());
    let mut compiled = COMPILED.get_or_init(Default::default).lock().unwrap_or_else(|p| p.into_inner());
    let made = !compiled.contains_key(&key);
    (compiled.entry(key).or_default().clone(), made)
}

/// Kernel file `file` compiled with `options`, once per process: every
/// opened [`Gpu`] (several per GPU with `--streams`, one per device of a
/// ring) loads its own modules, but they all ask for the same images at
/// once while preparing. Without this each compiled its own copy on a cold
/// disk cache (a ring's devices compiled the same kernels side by side,
/// which made preparing slow); now the first compiles and the others wait
/// for its image. Failures are not kept: a later caller tries again and
/// gets its own error.
fn compile_once(file: &str, options: &CompileOptions) -> Result<Arc<Vec<u8>>, CudaError> {
    let (slot, _) = compiled_slot(file, options);
    let mut slot = slot.lock().unwrap_or_else(|p| p.into_inner());
    if let Some(image) = slot.as_ref() {
        return Ok(image.clone());
    }
    let compiled = compile(file, options)?;
    if !compiled.log.trim().is_empty() {
        tracing::debug!("{file}: NVRTC log:\n{}", compiled.log);
    }
    let image = Arc::new(compiled.image);
    *slot = Some(image.clone());
    Ok(image)
}

/// An opened GPU. Cheap to share (`Arc<Gpu>`); everything atoll does on it
/// is queued on [`Gpu::stream`], in order.
pub struct Gpu {
    pub ordinal: usize,
    /// Unique per opened `Gpu` (several may be opened on one ordinal, each
    /// with its own stream): keys per-stream state such as tracers.
    pub id: u64,
    pub ctx: Arc<CudaContext>,
    /// atoll's one stream on this GPU: every allocation, copy and kernel
    /// goes here, in order. A dedicated (non-null) stream, so that work on
    /// other streams (copies, NCCL) can overlap with it later; cudarc's
    /// event tracking is off, so such streams must be ordered with events
    /// explicitly.
    pub stream: Arc<CudaStream>,
    /// The green context of a GPU part ([`Gpu::open_partition`]).
    green: Option<GreenContext>,
    /// (index, parts) of a GPU part.
    pub part: Option<(usize, usize)>,
    /// e.g. "NVIDIA H200".
    pub name: String,
    /// (major, minor), e.g. (9, 0).
    pub compute_capability: (u32, u32),
    pub total_memory: u64,
    pub multiprocessors: u32,
    /// Loaded modules by kernel file name: each file is compiled and loaded
    /// once per GPU, on first use.
    modules: Mutex<HashMap<String, Arc<CudaModule>>>,
    /// Extra NVRTC options for every kernel of this GPU (e.g. fast math).
    compile_options: CompileOptions,
}

/// A green context handle (kept for making more streams on it; never
/// destroyed: parts live as long as the process).
#[derive(Clone, Copy)]
struct GreenContext(cudarc::driver::sys::CUgreenCtx);

// SAFETY: a green context handle may be used from any thread.
unsafe impl Send for GreenContext {}
unsafe impl Sync for GreenContext {}

/// What sets a GPU part apart from the whole GPU.
#[derive(Clone, Copy)]
struct GpuPart {
    green: GreenContext,
    /// Which part, of how many.
    index: usize,
    parts: usize,
    multiprocessors: u32,
}

/// A non-blocking stream of green context `green` (which `ctx` wraps).
///
/// # Safety
/// `green` must be the live green context `ctx` was made from.
unsafe fn green_stream(
    ctx: &Arc<CudaContext>,
    green: cudarc::driver::sys::CUgreenCtx,
    label: &str,
) -> Result<Arc<CudaStream>, CudaError> {
    use cudarc::driver::sys;
    let mut stream: sys::CUstream = std::ptr::null_mut();
    let flags = sys::CUstream_flags::CU_STREAM_NON_BLOCKING as u32;
    match sys::cuGreenCtxStreamCreate(&mut stream, green, flags, 0) {
        sys::CUresult::CUDA_SUCCESS => Ok(ctx.wrap_borrowed_stream(stream)),
        r => Err(CudaError::Usage(format!("{label}: creating a stream: {r:?}"))),
    }
}

impl std::fmt::Debug for Gpu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Gpu")
            .field("ordinal", &self.ordinal)
            .field("name", &self.name)
            .field("compute_capability", &self.compute_capability)
            .field("total_memory", &self.total_memory)
            .finish_non_exhaustive()
    }
}

impl Gpu {
    /// Opens GPU `ordinal` (its primary context) and a stream on it. Fails
    /// cleanly without a driver, without NVRTC (every kernel needs it), or
    /// for an ordinal the machine does not have.
    pub fn open(ordinal: usize) -> Result<Arc<Gpu>, CudaError> {
        let count = device_count()?;
        if count == 0 {
            return Err(CudaError::NoGpu);
        }
        if ordinal >= count {
            return Err(CudaError::BadOrdinal { ordinal, count });
        }
        require_nvrtc()?;
        let what = |w: &str| format!("cuda:{ordinal}: {w}");
        let ctx = CudaContext::new(ordinal).map_err(CudaError::driver(what("creating the context")))?;
        // SAFETY: atoll queues all of its work on `stream`, in order, so no
        // buffer is ever used on two streams and cudarc's per-buffer events
        // (a record and a wait per kernel argument: a measurable share of a
        // small bounce) are not needed. Code that adds streams must order
        // them itself.
        unsafe { ctx.disable_event_tracking() };
        let stream = ctx.new_stream().map_err(CudaError::driver(what("creating a stream")))?;
        Self::with_context(ordinal, ctx, stream, None)
    }

    /// Opens part `index` of GPU `ordinal` split into `parts` equal groups
    /// of multiprocessors (a CUDA green context), with a stream of its own.
    /// Devices on the parts of one GPU stand in for separate GPUs: their
    /// kernels run apart, while memory, its bandwidth and the L2 cache stay
    /// shared. A ring's lock-step and hand-overs can so be measured against
    /// replication without a second GPU.
    pub fn open_partition(ordinal: usize, parts: usize, index: usize) -> Result<Arc<Gpu>, CudaError> {
        use cudarc::driver::sys;
        let count = device_count()?;
        if ordinal >= count {
            return Err(if count == 0 { CudaError::NoGpu } else { CudaError::BadOrdinal { ordinal, count } });
        }
        require_nvrtc()?;
        let label = format!("cuda:{ordinal}/{parts}");
        let failed = |what: &str, r: sys::CUresult| CudaError::Usage(format!("{label}: {what}: {r:?}"));
        let check = |what: &str, r: sys::CUresult| match r {
            sys::CUresult::CUDA_SUCCESS => Ok(()),
            r => Err(failed(what, r)),
        };
        // SAFETY: plain driver calls on out-parameters sized for them; the
        // resources and descriptor live until the green context is made.
        unsafe {
            let mut device: sys::CUdevice = 0;
            check("getting the device", sys::cuDeviceGet(&mut device, ordinal as i32))?;
            let mut all: sys::CUdevResource = std::mem::zeroed();
            check(
                "reading its multiprocessors",
                sys::cuDeviceGetDevResource(
                    device,
                    &mut all,
                    sys::CUdevResourceType::CU_DEV_RESOURCE_TYPE_SM,
                ),
            )?;
            let total = all.__bindgen_anon_1.sm.smCount;
            // Groups of a multiple of 8 (Hopper's granularity), as many as asked.
            let per_part = (total / parts.max(1) as u32) / 8 * 8;
            if per_part == 0 || index >= parts {
                return Err(CudaError::Usage(format!(
                    "{label}: {total} multiprocessors make no {parts} parts"
                )));
            }
            let mut groups: Vec<sys::CUdevResource> = vec![std::mem::zeroed(); parts];
            let mut made = parts as u32;
            let mut rest: sys::CUdevResource = std::mem::zeroed();
            check(
                "splitting its multiprocessors",
                sys::cuDevSmResourceSplitByCount(
                    groups.as_mut_ptr(),
                    &mut made,
                    &all,
                    &mut rest,
                    0,
                    per_part,
                ),
            )?;
            if (made as usize) < parts {
                return Err(CudaError::Usage(format!(
                    "{label}: only {made} groups of {per_part} multiprocessors"
                )));
            }
            let mut desc: sys::CUdevResourceDesc = std::ptr::null_mut();
            check("describing a group", sys::cuDevResourceGenerateDesc(&mut desc, &mut groups[index], 1))?;
            let mut green: sys::CUgreenCtx = std::ptr::null_mut();
            let flags = sys::CUgreenCtxCreate_flags::CU_GREEN_CTX_DEFAULT_STREAM as u32;
            check("creating a green context", sys::cuGreenCtxCreate(&mut green, desc, device, flags))?;
            let mut raw: sys::CUcontext = std::ptr::null_mut();
            check("its context", sys::cuCtxFromGreenCtx(&mut raw, green))?;
            let ctx = CudaContext::from_raw_context(ordinal, device, raw)
                .map_err(CudaError::driver(format!("{label}: wrapping the context")))?;
            // A green context is destroyed by cuGreenCtxDestroy, not by the
            // cuCtxDestroy cudarc calls when its last handle drops: keep one
            // handle for the process's life (parts are opened a few times).
            std::mem::forget(ctx.clone());
            ctx.disable_event_tracking();
            let stream = green_stream(&ctx, green, &label)?;
            let multiprocessors = groups[index].__bindgen_anon_1.sm.smCount;
            let part = GpuPart { green: GreenContext(green), index, parts, multiprocessors };
            Self::with_context(ordinal, ctx, stream, Some(part))
        }
    }

    /// Another handle on this GPU (or GPU part) with a stream of its own:
    /// a further wavefront sharing its context, modules and memory.
    pub(crate) fn another_stream(&self) -> Result<Arc<Gpu>, CudaError> {
        let label = self.label();
        let stream = match self.green {
            // SAFETY: `green` is the live green context `ctx` was made from.
            Some(green) => unsafe { green_stream(&self.ctx, green.0, &label)? },
            None => {
                self.ctx.new_stream().map_err(CudaError::driver(format!("{label}: creating a stream")))?
            }
        };
        let part = self.green.zip(self.part).map(|(green, (index, parts))| GpuPart {
            green,
            index,
            parts,
            multiprocessors: self.multiprocessors,
        });
        Self::with_context(self.ordinal, self.ctx.clone(), stream, part)
    }

    fn with_context(
        ordinal: usize,
        ctx: Arc<CudaContext>,
        stream: Arc<CudaStream>,
        part: Option<GpuPart>,
    ) -> Result<Arc<Gpu>, CudaError> {
        let what = |w: &str| format!("cuda:{ordinal}: {w}");
        let name = ctx.name().map_err(CudaError::driver(what("reading the name")))?;
        let (major, minor) =
            ctx.compute_capability().map_err(CudaError::driver(what("reading the compute capability")))?;
        let total_memory =
            ctx.total_mem().map_err(CudaError::driver(what("reading the memory size")))? as u64;
        let multiprocessors = match part {
            Some(p) => p.multiprocessors as i32,
            None => ctx
                .attribute(CUdevice_attribute::CU_DEVICE_ATTRIBUTE_MULTIPROCESSOR_COUNT)
                .map_err(CudaError::driver(what("reading the multiprocessor count")))?,
        };
        let compute_capability = (major as u32, minor as u32);
        static OPENED: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        Ok(Arc::new(Gpu {
            ordinal,
            id: OPENED.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            ctx,
            stream,
            green: part.map(|p| p.green),
            part: part.map(|p| (p.index, p.parts)),
            name,
            compute_capability,
            total_memory,
            multiprocessors: multiprocessors.max(1) as u32,
            modules: Mutex::new(HashMap::new()),
            // Machine code for exactly this GPU: nothing left for the
            // driver to JIT, and no dependency on the driver's PTX version.
            compile_options: CompileOptions::cubin(compute_capability),
        }))
    }

    /// `cuda:N`, or `cuda:N[I/P]` for part I of P ([`Gpu::open_partition`]).
    pub fn label(&self) -> String {
        match self.part {
            Some((index, parts)) => format!("cuda:{}[{index}/{parts}]", self.ordinal),
            None => format!("cuda:{}", self.ordinal),
        }
    }

    /// Bytes currently free on the GPU (all processes).
    pub fn free_memory(&self) -> Result<u64, CudaError> {
        let (free, _total) = self
            .ctx
            .mem_get_info()
            .map_err(CudaError::driver(format!("{}: reading free memory", self.label())))?;
        Ok(free as u64)
    }

    /// The options kernels are compiled with on this GPU.
    pub fn compile_options(&self) -> &CompileOptions {
        &self.compile_options
    }

    /// The module of kernel file `file`, compiled (or taken from the disk
    /// cache) and loaded on first use.
    pub fn module(&self, file: &str) -> Result<Arc<CudaModule>, CudaError> {
        self.module_with(file, &[])
    }

    /// [`Gpu::module`] compiled with extra NVRTC options (`-DNAME=VALUE`
    /// specialisations); one module per file and option list.
    pub(crate) fn module_with(&self, file: &str, extra: &[String]) -> Result<Arc<CudaModule>, CudaError> {
        let key =
            std::iter::once(file.to_string()).chain(extra.iter().cloned()).collect::<Vec<_>>().join(" ");
        let mut modules = self.modules.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        if let Some(module) = modules.get(&key) {
            return Ok(module.clone());
        }
        let mut options = self.compile_options.clone();
        options.extra.extend(extra.iter().cloned());
        let compiled = compile_once(file, &options)?;
        let image = match self.compile_options.output {
            Output::Cubin => Ptx::from_binary(compiled.to_vec()),
            Output::Ptx => Ptx::from_src(String::from_utf8_lossy(&compiled).into_owned()),
        };
        let module = self
            .ctx
            .load_module(image)
            .map_err(CudaError::driver(format!("{}: loading kernel module {file}", self.label())))?;
        modules.insert(key, module.clone());
        Ok(module)
    }

    /// Starts compiling `modules` (kernel file, extra options as for
    /// [`Gpu::module_with`]) at once, each on a thread of its own, and
    /// returns: NVRTC compiles one program per thread, and a frame's
    /// modules compiled one after the other took several times as long as
    /// the longest of them. A later [`Gpu::module_with`] of one of them
    /// waits for its compilation to finish; one that failed is compiled
    /// again there, which reports the error. Modules the process asked for
    /// before (another device's, an earlier frame's) start no thread.
    pub(crate) fn compile_ahead(&self, modules: Vec<(&'static str, Vec<String>)>) {
        for (file, extra) in modules {
            let mut options = self.compile_options.clone();
            options.extra.extend(extra);
            // (Another device, or an earlier frame, already asked for it.)
            if !compiled_slot(file, &options).1 {
                continue;
            }
            std::thread::spawn(move || {
                if let Err(e) = compile_once(file, &options) {
                    tracing::debug!("compiling {file} ahead: {e}");
                }
            });
        }
    }

    /// Kernel `name` of kernel file `file` (an `extern "C" __global__` function).
    pub fn function(&self, file: &str, name: &str) -> Result<CudaFunction, CudaError> {
        self.function_with(file, name, &[])
    }

    /// [`Gpu::function`] of the module compiled with `extra` options.
    pub(crate) fn function_with(
        &self,
        file: &str,
        name: &str,
        extra: &[String],
    ) -> Result<CudaFunction, CudaError> {
        self.module_with(file, extra)?
            .load_function(name)
            .map_err(CudaError::driver(format!("{}: kernel {name} in {file}", self.label())))
    }

    /// Waits for all work queued on the stream.
    pub(crate) fn synchronize(&self) -> Result<(), CudaError> {
        self.stream.synchronize().map_err(CudaError::driver(format!("{}: synchronizing", self.label())))
    }

    /// A timing event pair recording from now on the stream; call
    /// [`Timer::stop`] after queuing the work to time.
    pub fn start_timer(&self) -> Result<Timer, CudaError> {
        let timing = Some(CUevent_flags::CU_EVENT_DEFAULT);
        let context = || format!("{}: timing event", self.label());
        let start = self.ctx.new_event(timing).map_err(CudaError::driver(context()))?;
        let end = self.ctx.new_event(timing).map_err(CudaError::driver(context()))?;
        start.record(&self.stream).map_err(CudaError::driver(context()))?;
        Ok(Timer { start, end, stopped: false })
    }
}

/// A pair of CUDA events around work on a stream: device time, not host time.
#[derive(Debug)]
pub struct Timer {
    start: CudaEvent,
    end: CudaEvent,
    stopped: bool,
}

impl Timer {
    /// Marks the end of the timed work (queued; does not wait).
    pub fn stop(&mut self, gpu: &Gpu) -> Result<(), CudaError> {
        self.end.record(&gpu.stream).map_err(CudaError::driver(format!("{}: timing event", gpu.label())))?;
        self.stopped = true;
        Ok(())
    }

    /// Starts timing again from now on the stream, reusing the events
    /// (creating a pair costs more host time than recording one).
    pub(crate) fn restart(&mut self, gpu: &Gpu) -> Result<(), CudaError> {
        self.start
            .record(&gpu.stream)
            .map_err(CudaError::driver(format!("{}: timing event", gpu.label())))?;
        self.stopped = false;
        Ok(())
    }

    /// Whether the timed work has finished (never blocks).
    pub(crate) fn is_done(&self) -> bool {
        self.stopped && self.end.is_complete()
    }

    /// Milliseconds between start and stop; waits for the work to finish.
    pub fn elapsed_ms(&self) -> Result<f32, CudaError> {
        if !self.stopped {
            return Err(CudaError::Usage("Timer::elapsed_ms before stop".into()));
        }
        self.start.elapsed_ms(&self.end).map_err(CudaError::driver("reading a timing event"))
    }
}

/// A 1-D launch of `threads` threads in blocks of `block` (at least one
/// block, so kernels that read their count on the device always run).
pub fn launch_1d(threads: u32, block: u32) -> LaunchConfig {
    LaunchConfig {
        grid_dim: (threads.div_ceil(block).max(1), 1, 1),
        block_dim: (block, 1, 1),
        shared_mem_bytes: 0,
    }
}

/// Copies `data` to a new device buffer; an empty table becomes one zeroed
/// element (zero-length allocations fail), never read since its count is 0.
/// For several tables, an [`Uploader`] shares its staging buffers.
pub fn upload<T: cudarc::driver::DeviceRepr + cudarc::driver::ValidAsZeroBits + Copy>(
    gpu: &Gpu,
    data: &[T],
    what: &str,
) -> Result<cudarc::driver::CudaSlice<T>, CudaError> {
    Uploader::new(gpu).upload(data, what)
}

/// Tables at least this large go through page-locked staging buffers of
/// [`STAGING_BYTES`]: from pageable memory the driver copies through a
/// small staging buffer of its own, at a fraction of the link's speed.
const STAGED_UPLOAD_BYTES: usize = 64 << 20;
const STAGING_BYTES: usize = 64 << 20;

/// Copies tables to one GPU, large ones through two page-locked buffers
/// made at the first that needs them and kept for the rest (making
/// page-locked memory costs more than copying through it).
pub struct Uploader<'g> {
    gpu: &'g Gpu,
    staging: Option<Staging>,
}

/// Two page-locked buffers, and for each the event after the copy that
/// last read it.
struct Staging {
    buffers: [cudarc::driver::PinnedHostSlice<u8>; 2],
    done: [cudarc::driver::CudaEvent; 2],
}

impl<'g> Uploader<'g> {
    pub fn new(gpu: &'g Gpu) -> Self {
        Uploader { gpu, staging: None }
    }

    /// [`upload`], staged through the shared buffers.
    pub fn upload<T: cudarc::driver::DeviceRepr + cudarc::driver::ValidAsZeroBits + Copy>(
        &mut self,
        data: &[T],
        what: &str,
    ) -> Result<cudarc::driver::CudaSlice<T>, CudaError> {
        let gpu = self.gpu;
        let context = || format!("{}: uploading {what} ({} entries)", gpu.label(), data.len());
        if data.is_empty() {
            return gpu.stream.alloc_zeros(1).map_err(CudaError::driver(context()));
        }
        if std::mem::size_of_val(data) < STAGED_UPLOAD_BYTES {
            let copy = gpu.stream.clone_htod(data).map_err(CudaError::driver(context()))?;
            atoll_scene::progress::copied(std::mem::size_of_val(data) as u64);
            return Ok(copy);
        }
        use rayon::prelude::*;
        // SAFETY: `T` is plain device data (`DeviceRepr + Copy`): its bytes
        // are what the device reads.
        let bytes =
            unsafe { std::slice::from_raw_parts(data.as_ptr() as *const u8, std::mem::size_of_val(data)) };
        self.staged(data.len(), STAGING_BYTES, &|offset, chunk: &mut [u8]| {
            let source = &bytes[offset..offset + chunk.len()];
            chunk
                .par_chunks_mut(1 << 20)
                .zip(source.par_chunks(1 << 20))
                .for_each(|(h, c)| h.copy_from_slice(c));
        })
        .map_err(CudaError::driver(context()))
    }

    /// A table made row by row ([`RowTable`]): large ones written straight
    /// into the staging buffers, a chunk of rows at a time.
    pub(crate) fn upload_rows<W>(
        &mut self,
        table: &RowTable<W>,
        what: &str,
    ) -> Result<cudarc::driver::CudaSlice<W>, CudaError>
    where
        W: cudarc::driver::DeviceRepr + cudarc::driver::ValidAsZeroBits + bytemuck::Pod + Send + Sync,
    {
        let row_bytes = table.words * std::mem::size_of::<W>();
        if table.rows * row_bytes < STAGED_UPLOAD_BYTES {
            return self.upload(&table.to_vec(), what);
        }
        let gpu = self.gpu;
        let context = || format!("{}: uploading {what} ({} rows)", gpu.label(), table.rows);
        self.staged(table.len(), STAGING_BYTES - STAGING_BYTES % row_bytes, &|offset, chunk: &mut [u8]| {
            table.fill_par(offset / row_bytes, bytemuck::cast_slice_mut(chunk));
        })
        .map_err(CudaError::driver(context()))
    }

    /// A new device buffer of `len` elements whose bytes `fill(offset,
    /// chunk)` writes, `chunk_bytes` at a time, into the two page-locked
    /// buffers: threads fill one while the copy engine drains the other.
    fn staged<T: cudarc::driver::DeviceRepr>(
        &mut self,
        len: usize,
        chunk_bytes: usize,
        fill: &(dyn Fn(usize, &mut [u8]) + Sync),
    ) -> Result<cudarc::driver::CudaSlice<T>, cudarc::driver::DriverError> {
        use cudarc::driver::DevicePtrMut;
        let gpu = self.gpu;
        // SAFETY: every byte is written by the copies below before the buffer
        // is returned (they cover all `len` elements, and the stream is synchronised).
        let mut device = unsafe { gpu.stream.alloc::<T>(len) }?;
        let total = len * std::mem::size_of::<T>();
        let staging = match &mut self.staging {
            Some(staging) => staging,
            None => self.staging.insert(Staging {
                // SAFETY: written before each copy reads them.
                buffers: [unsafe { gpu.ctx.alloc_pinned::<u8>(STAGING_BYTES) }?, unsafe {
                    gpu.ctx.alloc_pinned::<u8>(STAGING_BYTES)
                }?],
                done: [gpu.ctx.new_event(None)?, gpu.ctx.new_event(None)?],
            }),
        };
        {
            let (base, _written) = device.device_ptr_mut(&gpu.stream);
            for (i, offset) in (0..total).step_by(chunk_bytes).enumerate() {
                let b = i % 2;
                // The copy that last read this buffer is over (no-op at first).
                staging.done[b].synchronize()?;
                let host = &mut staging.buffers[b].as_mut_slice()?[..chunk_bytes.min(total - offset)];
                fill(offset, host);
                // SAFETY: the destination lies inside `device` (bytes
                // `offset..offset + host.len()` of `total`), and `host` is
                // not written again before `done[b]` says this copy is over.
                unsafe {
                    cudarc::driver::result::memcpy_htod_async(
                        base + offset as u64,
                        host,
                        gpu.stream.cu_stream(),
                    )
                }?;
                staging.done[b].record(&gpu.stream)?;
                atoll_scene::progress::copied(host.len() as u64);
            }
        }
        gpu.stream.synchronize()?;
        Ok(device)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn launch_shapes() {
        assert_eq!(launch_1d(0, 256).grid_dim, (1, 1, 1));
        assert_eq!(launch_1d(257, 256).grid_dim, (2, 1, 1));
        assert_eq!(launch_1d(1 << 18, 128).grid_dim, (2048, 1, 1));
    }

    #[test]
    fn without_a_driver_open_is_an_error_not_a_panic() {
        if crate::error::driver_present() {
            return; // a real driver: covered by tests/gpu_basic.rs
        }
        assert!(matches!(device_count(), Err(CudaError::NoDriver)));
        assert!(matches!(Gpu::open(0), Err(CudaError::NoDriver)));
    }
}
