//! The CUDA device's ray queues: device buffers of ray records with their
//! lengths in device memory.
//!
//! Kernels read a queue's length from its device counter and append with
//! atomics, so the host need not know lengths between stages (pbrt-v4's
//! habit). The host caches a length when it learns it (generate, a
//! read-back, a write) and forgets it when a kernel may change it; a
//! read-back happens only when the integrator asks ([`Queues::len`]).

use std::cell::{Cell, RefCell};

use atoll_render::{Queue, RayRecord};
use cudarc::driver::{CudaSlice, DevicePtr, DevicePtrMut, PinnedHostSlice};

use crate::error::CudaError;
use crate::gpu::Gpu;
use crate::layout::{GpuRecord, HitRef};

/// Bytes the queues of `capacity` records take on the device.
pub(crate) fn queue_bytes(capacity: u32) -> u64 {
    let record = std::mem::size_of::<GpuRecord>() as u64;
    // paths + next (the path queue's ping-pong partner) + shadows + the
    // spare shadow queue a ring needs (counted always: the plan is checked
    // before the strategy is known to the device), the hit references of
    // closest-hit tracing, three counters and the sent-bytes counter.
    capacity.max(1) as u64 * (4 * record + std::mem::size_of::<HitRef>() as u64) + 3 * 4 + 8
}

/// `staging`, grown to hold at least `records` records.
fn staged<'a>(
    staging: &'a mut Option<PinnedHostSlice<GpuRecord>>,
    gpu: &Gpu,
    records: usize,
) -> Result<&'a mut PinnedHostSlice<GpuRecord>, CudaError> {
    if staging.as_ref().is_none_or(|s| s.len() < records) {
        // Room for half as much again: queues grow in waves.
        let len = records + records / 2;
        // SAFETY: only the first records copied in are ever read. Not
        // write-combined (cudarc's `alloc_pinned`): the host reads it.
        let pinned = unsafe { gpu.ctx.alloc_pinned_with_flags::<GpuRecord>(len, 0) }.map_err(
            CudaError::driver(format!("{}: allocating {len} records of page-locked memory", gpu.label())),
        )?;
        *staging = Some(pinned);
    }
    Ok(staging.as_mut().expect("allocated above"))
}

/// The path and shadow queues of one device.
pub struct Queues {
    pub capacity: u32,
    /// The path queue traced and shaded now.
    pub paths: CudaSlice<GpuRecord>,
    /// Where `shade` appends continuing paths; swapped with `paths` after.
    pub next: CudaSlice<GpuRecord>,
    pub shadows: CudaSlice<GpuRecord>,
    /// Closest-hit results, one per path record.
    pub hits: CudaSlice<HitRef>,
    pub path_count: CudaSlice<u32>,
    pub next_count: CudaSlice<u32>,
    pub shadow_count: CudaSlice<u32>,
    /// Where a ring neighbour copies a shadow queue in (allocated by the
    /// first [`Queues::incoming`] for shadows: only rings need it).
    pub spare_shadows: Option<CudaSlice<GpuRecord>>,
    pub spare_shadow_count: Option<CudaSlice<u32>>,
    /// Bytes sent to ring neighbours so far (the send kernel adds).
    pub sent_bytes: CudaSlice<u64>,
    /// Host copies of the counters when known (`None`: only the device knows).
    path_len: Cell<Option<u32>>,
    shadow_len: Cell<Option<u32>>,
    /// Page-locked host memory that queues read back or written go
    /// through (allocated on first use: only rings through the host and
    /// rings of processes need it). Copies from pageable memory are staged
    /// by the driver at a fraction of the bus speed.
    staging: RefCell<Option<PinnedHostSlice<GpuRecord>>>,
}

impl Queues {
    /// Empty queues of `capacity` records each.
    pub fn new(gpu: &Gpu, capacity: u32) -> Result<Self, CudaError> {
        let capacity = capacity.max(1);
        let what = |w: &str| format!("{}: allocating the {w} ({capacity} entries)", gpu.label());
        let records = |w: &str| {
            gpu.stream.alloc_zeros::<GpuRecord>(capacity as usize).map_err(CudaError::driver(what(w)))
        };
        let counter = |w: &str| gpu.stream.alloc_zeros::<u32>(1).map_err(CudaError::driver(what(w)));
        Ok(Queues {
            capacity,
            paths: records("path queue")?,
            next: records("next path queue")?,
            shadows: records("shadow queue")?,
            hits: gpu
                .stream
                .alloc_zeros(capacity as usize)
                .map_err(CudaError::driver(what("hit references")))?,
            path_count: counter("path counter")?,
            next_count: counter("next path counter")?,
            shadow_count: counter("shadow counter")?,
            spare_shadows: None,
            spare_shadow_count: None,
            sent_bytes: gpu.stream.alloc_zeros(1).map_err(CudaError::driver(what("sent counter")))?,
            path_len: Cell::new(Some(0)),
            shadow_len: Cell::new(Some(0)),
            staging: RefCell::new(None),
        })
    }

    /// Makes room for `records` per queue, keeping both queues' contents.
    pub(crate) fn ensure_capacity(&mut self, gpu: &Gpu, records: u32) -> Result<(), CudaError> {
        if records <= self.capacity {
            return Ok(());
        }
        tracing::debug!("{}: growing queues from {} to {records} records", gpu.label(), self.capacity);
        let mut grown = Queues::new(gpu, records)?;
        let context = || format!("{}: growing the queues", gpu.label());
        let old = self.capacity as usize;
        let copy = |src: &CudaSlice<GpuRecord>, dst: &mut CudaSlice<GpuRecord>| {
            gpu.stream.memcpy_dtod(src, &mut dst.slice_mut(0..old)).map_err(CudaError::driver(context()))
        };
        copy(&self.paths, &mut grown.paths)?;
        copy(&self.shadows, &mut grown.shadows)?;
        gpu.stream
            .memcpy_dtod(&self.path_count, &mut grown.path_count)
            .map_err(CudaError::driver(context()))?;
        gpu.stream
            .memcpy_dtod(&self.shadow_count, &mut grown.shadow_count)
            .map_err(CudaError::driver(context()))?;
        if self.spare_shadows.is_some() {
            grown.incoming(gpu, Queue::Shadows)?;
        }
        gpu.stream
            .memcpy_dtod(&self.sent_bytes, &mut grown.sent_bytes)
            .map_err(CudaError::driver(context()))?;
        grown.path_len.set(self.path_len.get());
        grown.shadow_len.set(self.shadow_len.get());
        grown.staging = self.staging.take().into();
        *self = grown;
        Ok(())
    }

    fn cache(&self, queue: Queue) -> &Cell<Option<u32>> {
        match queue {
            Queue::Paths => &self.path_len,
            Queue::Shadows => &self.shadow_len,
        }
    }

    fn counter(&self, queue: Queue) -> &CudaSlice<u32> {
        match queue {
            Queue::Paths => &self.path_count,
            Queue::Shadows => &self.shadow_count,
        }
    }

    /// The host's copy of a length, if it has one.
    pub(crate) fn known_len(&self, queue: Queue) -> Option<u32> {
        self.cache(queue).get()
    }

    /// Records the length a kernel or copy just set on the device (`None`: unknown now).
    pub fn set_known_len(&self, queue: Queue, len: Option<u32>) {
        self.cache(queue).set(len);
    }

    /// The queue's length, read back from the device (waiting for the
    /// stream) when the host does not know it.
    pub fn len(&self, gpu: &Gpu, queue: Queue) -> Result<u32, CudaError> {
        if let Some(n) = self.known_len(queue) {
            return Ok(n);
        }
        let n = gpu
            .stream
            .clone_dtoh(self.counter(queue))
            .map_err(CudaError::driver(format!("{}: reading a queue length", gpu.label())))?[0];
        if n > self.capacity {
            return Err(CudaError::Usage(format!(
                "{}: queue {queue:?} claims {n} records but holds at most {} (kernel bug)",
                gpu.label(),
                self.capacity
            )));
        }
        self.set_known_len(queue, Some(n));
        Ok(n)
    }

    /// Threads to launch for a kernel over `queue`: its length when known,
    /// else its capacity (the kernel reads the length on the device).
    pub(crate) fn launch_len(&self, queue: Queue) -> u32 {
        self.known_len(queue).unwrap_or(self.capacity)
    }

    /// Zeroes a queue's device counter.
    pub fn clear(&mut self, gpu: &Gpu, queue: Queue) -> Result<(), CudaError> {
        let counter = match queue {
            Queue::Paths => &mut self.path_count,
            Queue::Shadows => &mut self.shadow_count,
        };
        gpu.stream
            .memset_zeros(counter)
            .map_err(CudaError::driver(format!("{}: clearing a queue", gpu.label())))?;
        self.set_known_len(queue, Some(0));
        Ok(())
    }

    /// After `shade` appended to `next`: it becomes the path queue.
    pub(crate) fn swap_paths(&mut self) {
        std::mem::swap(&mut self.paths, &mut self.next);
        std::mem::swap(&mut self.path_count, &mut self.next_count);
        self.path_len.set(None);
    }

    /// The queue's records, copied into `into` (on the host).
    pub fn read(&self, gpu: &Gpu, queue: Queue, into: &mut Vec<RayRecord>) -> Result<(), CudaError> {
        into.clear();
        let n = self.len(gpu, queue)? as usize;
        if n == 0 {
            return Ok(());
        }
        let buffer = match queue {
            Queue::Paths => &self.paths,
            Queue::Shadows => &self.shadows,
        };
        let context = || format!("{}: reading the {queue:?} queue", gpu.label());
        let mut staging = self.staging.borrow_mut();
        // (Waits for earlier copies through it.)
        let host = staged(&mut staging, gpu, n)?.as_mut_slice().map_err(CudaError::driver(context()))?;
        let (device, _read) = buffer.device_ptr(&gpu.stream);
        // SAFETY: `host` and the queue both hold at least `n` records
        // (cudarc's own copy would take the staging memory's length), and
        // the stream is synchronised before `host` is read.
        unsafe { cudarc::driver::result::memcpy_dtoh_async(&mut host[..n], device, gpu.stream.cu_stream()) }
            .map_err(CudaError::driver(context()))?;
        gpu.stream.synchronize().map_err(CudaError::driver(context()))?;
        into.extend_from_slice(bytemuck::cast_slice(&host[..n]));
        Ok(())
    }

    /// Replaces the queue's records (growing the queues when needed).
    pub fn write(&mut self, gpu: &Gpu, queue: Queue, records: &[RayRecord]) -> Result<(), CudaError> {
        let n = u32::try_from(records.len())
            .map_err(|_| CudaError::Usage(format!("{} records do not fit a queue", records.len())))?;
        self.ensure_capacity(gpu, n)?;
        let context = || format!("{}: writing the {queue:?} queue", gpu.label());
        let (buffer, counter) = match queue {
            Queue::Paths => (&mut self.paths, &mut self.path_count),
            Queue::Shadows => (&mut self.shadows, &mut self.shadow_count),
        };
        if n > 0 {
            let mut staging = self.staging.borrow_mut();
            let pinned = staged(&mut staging, gpu, n as usize)?;
            // (Waits for earlier copies out of it.)
            let host = pinned.as_mut_slice().map_err(CudaError::driver(context()))?;
            host[..n as usize].copy_from_slice(bytemuck::cast_slice(records));
            let (device, _written) = buffer.device_ptr_mut(&gpu.stream);
            // SAFETY: `device` holds at least `n` records (ensure_capacity),
            // and the pinned memory is not touched again before the stream
            // is synchronised below.
            unsafe {
                cudarc::driver::result::memcpy_htod_async(device, &host[..n as usize], gpu.stream.cu_stream())
            }
            .map_err(CudaError::driver(context()))?;
        }
        gpu.stream.memcpy_htod(&[n], counter).map_err(CudaError::driver(context()))?;
        // The staging memory may be rewritten as soon as this returns.
        gpu.stream.synchronize().map_err(CudaError::driver(context()))?;
        self.set_known_len(queue, Some(n));
        Ok(())
    }

    /// The buffer a ring neighbour copies `queue` into, with its counter:
    /// the path queue's ping-pong partner (idle outside `shade`), or the
    /// spare shadow buffer (allocated on first use: only rings need it).
    pub(crate) fn incoming(
        &mut self,
        gpu: &Gpu,
        queue: Queue,
    ) -> Result<(&mut CudaSlice<GpuRecord>, &mut CudaSlice<u32>), CudaError> {
        match queue {
            Queue::Paths => Ok((&mut self.next, &mut self.next_count)),
            Queue::Shadows => {
                if self.spare_shadows.is_none() {
                    let what = || format!("{}: allocating the spare shadow queue", gpu.label());
                    let spare = gpu
                        .stream
                        .alloc_zeros::<GpuRecord>(self.capacity as usize)
                        .map_err(CudaError::driver(what()))?;
                    let count = gpu.stream.alloc_zeros::<u32>(1).map_err(CudaError::driver(what()))?;
                    self.spare_shadows = Some(spare);
                    self.spare_shadow_count = Some(count);
                }
                match (self.spare_shadows.as_mut(), self.spare_shadow_count.as_mut()) {
                    (Some(records), Some(count)) => Ok((records, count)),
                    _ => unreachable!("allocated together above"),
                }
            }
        }
    }

    /// Makes the incoming buffer and counter (filled by a neighbour) the
    /// queue, and the queue's old ones the next incoming. The length is
    /// known only on the device until read.
    pub(crate) fn accept_incoming(&mut self, gpu: &Gpu, queue: Queue) -> Result<(), CudaError> {
        match queue {
            Queue::Paths => {
                std::mem::swap(&mut self.paths, &mut self.next);
                std::mem::swap(&mut self.path_count, &mut self.next_count);
            }
            Queue::Shadows => {
                let (Some(records), Some(count)) =
                    (self.spare_shadows.as_mut(), self.spare_shadow_count.as_mut())
                else {
                    return Err(CudaError::Usage(format!("{}: no shadow queue was sent here", gpu.label())));
                };
                std::mem::swap(&mut self.shadows, records);
                std::mem::swap(&mut self.shadow_count, count);
            }
        }
        self.set_known_len(queue, None);
        Ok(())
    }
}
