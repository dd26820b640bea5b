//! Wave-front merging on the GPU: the device-side FIFO of waves that
//! `refill` starts camera paths from, and the status the host reads one
//! bounce late.
//!
//! The host cannot decide how many paths to start without knowing how many
//! finished, and reading that back each bounce would leave the GPU idle for
//! a round trip. So the host pushes whole waves into a FIFO on the device
//! (`push_work`), and each bounce a one-thread kernel (`refill_claim`) fills
//! the path queue's free slots from the FIFO's front, then
//! `refill_generate` writes the camera records. `refill_claim` also writes a
//! [`WorkStatus`], copied to pinned host memory in stream order: the host
//! reads it [`STATUS_LAG`] refills late (waiting only for that refill,
//! while the bounces queued after it run) to learn whether work remains and
//! when to push the next wave.

use bytemuck::{Pod, Zeroable};
use cudarc::driver::sys::CUevent_flags;
use cudarc::driver::{CudaEvent, CudaSlice, PinnedHostSlice, PushKernelArg};

use crate::error::CudaError;
use crate::gpu::{launch_1d, Gpu};
#[cfg(test)]
use crate::layout::{field_layout, FieldLayout};
use crate::queues::Queues;
use atoll_render::Queue;

/// Waves the device FIFO holds (pushed and not yet fully started).
pub(crate) const WORK_SLOTS: u32 = 64;
/// Most FIFO waves one refill starts paths from.
pub(crate) const WORK_CLAIMS: u32 = 8;

/// A run of camera paths: one sample over `pixel_count` pixels from
/// `first_pixel`. In a claim, `queue_offset` is where its records go.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuWave {
    pub sample: u32,
    pub first_pixel: u32,
    pub pixel_count: u32,
    pub queue_offset: u32,
}

/// What the host learns of the work a bounce late (16 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct WorkStatus {
    /// Camera paths started since `prepare`.
    pub paths_started: u64,
    /// Path queue length after the last refill.
    pub queue_len: u32,
    /// FIFO waves whose paths have all started (the FIFO's front index).
    pub waves_started: u32,
}

/// The device-side FIFO (its front index is `WorkStatus::waves_started`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct WorkFifo {
    /// Wave `i` is in slot `i % WORK_SLOTS`.
    pub waves: [GpuWave; WORK_SLOTS as usize],
    /// What the last refill started, for `refill_generate`.
    pub claims: [GpuWave; WORK_CLAIMS as usize],
    /// Waves pushed so far.
    pub pushed: u32,
    /// Paths of the front wave already started.
    pub taken: u32,
    pub claim_count: u32,
    pub pad: u32,
}

impl GpuWave {
    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(GpuWave { sample, first_pixel, pixel_count, queue_offset })
    }
}

impl WorkStatus {
    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(WorkStatus { paths_started, queue_len, waves_started })
    }
}

impl WorkFifo {
    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(WorkFifo { waves, claims, pushed, taken, claim_count, pad })
    }
}

// SAFETY: plain-old-data `#[repr(C)]` structs (Pod): any bit pattern,
// zeros included, is a valid value, copied to and from the device bytewise.
unsafe impl cudarc::driver::DeviceRepr for WorkFifo {}
unsafe impl cudarc::driver::ValidAsZeroBits for WorkFifo {}
unsafe impl cudarc::driver::DeviceRepr for WorkStatus {}
unsafe impl cudarc::driver::ValidAsZeroBits for WorkStatus {}

/// The kernels of `wavefront.cu` that feed the path queue.
struct WorkKernels {
    push: cudarc::driver::CudaFunction,
    claim: cudarc::driver::CudaFunction,
    generate: cudarc::driver::CudaFunction,
}

impl WorkKernels {
    fn load(gpu: &Gpu, (file, extra): (&str, &[String])) -> Result<Self, CudaError> {
        Ok(WorkKernels {
            push: gpu.function_with(file, "push_work", extra)?,
            claim: gpu.function_with(file, "refill_claim", extra)?,
            generate: gpu.function_with(file, "refill_generate", extra)?,
        })
    }
}

/// Refills whose status copies are in flight at once: the host reads the
/// status of the refill before the last one, so the GPU holds more than a
/// bounce of queued work while the host waits and decides. The price: a
/// device runs `STATUS_LAG` empty bounces after its last paths finish.
pub(crate) const STATUS_LAG: usize = 2;

/// One refill's status, copied to pinned host memory.
struct StatusCopy {
    host: PinnedHostSlice<WorkStatus>,
    /// Recorded after the copy. Waited on by polling: the pinned buffer's
    /// own event blocks the thread in the driver, and waking it took longer
    /// than the GPU's queued work (measured several times slower on the
    /// Cornell bench).
    copied: CudaEvent,
}

/// One device's work feed: the FIFO, its status, and what the host pushed.
pub(crate) struct WorkFeed {
    kernels: WorkKernels,
    fifo: CudaSlice<WorkFifo>,
    status: CudaSlice<WorkStatus>,
    /// Refill `n`'s status goes to `copies[n % STATUS_LAG]`.
    copies: Vec<StatusCopy>,
    refills: usize,
    pushed_waves: u32,
    pushed_paths: u64,
}

/// Bytes a feed takes on the device.
pub(crate) const FEED_BYTES: u64 =
    (std::mem::size_of::<WorkFifo>() + std::mem::size_of::<WorkStatus>()) as u64;

impl WorkFeed {
    /// A feed whose kernels come from `file` (the wavefront kernels).
    /// The feed, its kernels from kernel file `module.0` compiled with the
    /// options `module.1`.
    pub(crate) fn new(gpu: &Gpu, module: (&str, &[String])) -> Result<Self, CudaError> {
        let kernels = WorkKernels::load(gpu, module)?;
        let what = |w: &str| format!("{}: allocating the work {w}", gpu.label());
        let fifo = gpu.stream.alloc_zeros(1).map_err(CudaError::driver(what("FIFO")))?;
        let status = gpu.stream.alloc_zeros(1).map_err(CudaError::driver(what("status")))?;
        let copies = (0..STATUS_LAG)
            .map(|_| {
                // Flags 0: cached host memory (cudarc's default, write-combined,
                // is slow for the host to read).
                // SAFETY: the allocation is initialised just below, before any read.
                let mut host = unsafe { gpu.ctx.alloc_pinned_with_flags::<WorkStatus>(1, 0) }
                    .map_err(CudaError::driver(what("status copy")))?;
                host.as_mut_slice().map_err(CudaError::driver(what("status copy")))?[0] =
                    WorkStatus::default();
                let copied = gpu
                    .ctx
                    .new_event(Some(CUevent_flags::CU_EVENT_DISABLE_TIMING))
                    .map_err(CudaError::driver(what("status event")))?;
                Ok(StatusCopy { host, copied })
            })
            .collect::<Result<_, CudaError>>()?;
        Ok(WorkFeed { kernels, fifo, status, copies, refills: 0, pushed_waves: 0, pushed_paths: 0 })
    }

    /// The status of the refill before the last one (zeros before any):
    /// waits, polling, for that refill only.
    fn seen(&self) -> Result<WorkStatus, CudaError> {
        let copy = &self.copies[self.refills % STATUS_LAG];
        while !copy.copied.is_complete() {
            std::hint::spin_loop();
        }
        Ok(copy.host.as_slice().map_err(CudaError::driver("reading the work status"))?[0])
    }

    /// Paths pushed and not started, as of the status seen (an upper bound now).
    fn pending(&self) -> Result<u64, CudaError> {
        Ok(self.pushed_paths - self.seen()?.paths_started)
    }

    /// Whether the path queue may hold paths or work may be pending. After
    /// a refill seen with an empty queue and nothing pending, every later
    /// bounce found nothing either (only pushes add paths, and the host
    /// counts those).
    pub(crate) fn busy(&self) -> Result<bool, CudaError> {
        let seen = self.seen()?;
        Ok(self.pushed_paths > seen.paths_started || seen.queue_len > 0)
    }

    /// Whether pending work may run out before the host sees the status
    /// again (and the FIFO has room).
    pub(crate) fn wants_work(&self, capacity: u32) -> Result<bool, CudaError> {
        let seen = self.seen()?;
        let fifo_room = self.pushed_waves - seen.waves_started < WORK_SLOTS / 2;
        Ok(fifo_room && self.pending()? <= STATUS_LAG as u64 * capacity as u64)
    }

    /// Appends a wave to the FIFO (in stream order; never waits).
    pub(crate) fn push(&mut self, gpu: &Gpu, sample: u32, first: u32, count: u32) -> Result<(), CudaError> {
        if count == 0 {
            return Ok(());
        }
        let seen = self.seen()?;
        if self.pushed_waves - seen.waves_started >= WORK_SLOTS {
            return Err(CudaError::Usage(format!(
                "{}: more than {WORK_SLOTS} waves queued; call wants_work first",
                gpu.label()
            )));
        }
        let mut launch = gpu.stream.launch_builder(&self.kernels.push);
        launch.arg(&mut self.fifo).arg(&sample).arg(&first).arg(&count);
        // SAFETY: matches `push_work(WorkFifo*, unsigned sample, unsigned first_pixel,
        // unsigned count)` in wavefront.cu; the FIFO lives as long as `self`, and the
        // check above keeps the slot written free (the device's front index only grows).
        unsafe { launch.launch(launch_1d(1, 1)) }.map_err(CudaError::driver("launching push_work"))?;
        self.pushed_waves += 1;
        self.pushed_paths += count as u64;
        Ok(())
    }

    /// Fills the free slots of the path queue from the FIFO (camera rays in
    /// blocks of `block` threads) and queues the status copy.
    pub(crate) fn refill(
        &mut self,
        gpu: &Gpu,
        params: &CudaSlice<crate::params::FrameParams>,
        queues: &mut Queues,
        block: u32,
    ) -> Result<(), CudaError> {
        // Pending work as of the last refill is an upper bound of what is
        // pending now: with none, only the status needs updating.
        let pending = self.pending()? > 0;
        let capacity = queues.capacity;
        let mut launch = gpu.stream.launch_builder(&self.kernels.claim);
        launch.arg(&mut self.fifo).arg(&mut self.status).arg(&mut queues.path_count).arg(&capacity);
        // SAFETY: matches `refill_claim(WorkFifo*, WorkStatus*, unsigned* path_count,
        // unsigned capacity)`; one thread; all buffers live in `self` or the caller's queues.
        unsafe { launch.launch(launch_1d(1, 1)) }.map_err(CudaError::driver("launching refill_claim"))?;
        if pending {
            let mut launch = gpu.stream.launch_builder(&self.kernels.generate);
            launch.arg(params).arg(&self.fifo).arg(&mut queues.paths);
            // SAFETY: matches `refill_generate(const FrameParams*, const WorkFifo*,
            // RayRecord* paths)`; claims written by `refill_claim` just before (same
            // stream) end at most at `capacity`, the length of `paths`.
            unsafe { launch.launch(launch_1d(capacity, block)) }
                .map_err(CudaError::driver("launching refill_generate"))?;
        }
        let copy = &mut self.copies[self.refills % STATUS_LAG];
        gpu.stream
            .memcpy_dtoh(&self.status, &mut copy.host)
            .map_err(CudaError::driver("copying the work status"))?;
        copy.copied.record(&gpu.stream).map_err(CudaError::driver("recording the work status copy"))?;
        self.refills += 1;
        queues.set_known_len(Queue::Paths, None);
        Ok(())
    }
}
