//! Ray queues moved straight from GPU to GPU, for the ring strategy (ray
//! queue cycling): the sender copies its queue into the receiver's idle
//! incoming buffer with `cuMemcpyPeerAsync` (over NVLink where the GPUs
//! have peer access, staged by the driver otherwise), then the receiver
//! makes that buffer its queue. No record passes through the host.
//!
//! The protocol, per ring step (the strategy orders it with a barrier):
//! 1. every member calls [`CudaDevice::incoming_slot`] and publishes it;
//! 2. every member calls [`CudaDevice::send_queue`] with its successor's
//!    slot (returns when the copy has landed) and hands over the length;
//! 3. every member calls [`CudaDevice::accept_incoming`] with that length.
//!
//! Slots change from step to step (buffers swap), so they are published
//! anew each time.

use std::sync::Arc;

use atoll_render::Queue;
use cudarc::driver::sys;
use cudarc::driver::DevicePtr;

use crate::device::CudaDevice;
use crate::error::CudaError;
use crate::gpu::Gpu;
use crate::layout::GpuRecord;

/// Where a neighbour may copy a queue into this device (valid until the
/// next [`CudaDevice::accept_incoming`]).
#[derive(Clone, Copy, Debug)]
pub struct IncomingSlot {
    ctx: sys::CUcontext,
    records: sys::CUdeviceptr,
    capacity: u32,
}

// SAFETY: a CUcontext handle and a device address are plain values; the
// driver accepts them from any thread, and the protocol above keeps the
// buffer alive and unused by its owner while a neighbour writes it.
unsafe impl Send for IncomingSlot {}
unsafe impl Sync for IncomingSlot {}

/// Lets each GPU of `gpus` read and write the others' memory directly
/// where the hardware allows it. Returns, per ordered pair (i, j), whether
/// direct access from i to j is on; copies between pairs without it still
/// work, staged through the host by the driver.
pub fn enable_peer_access(gpus: &[Arc<Gpu>]) -> Result<Vec<Vec<bool>>, CudaError> {
    let mut access = vec![vec![false; gpus.len()]; gpus.len()];
    for (i, a) in gpus.iter().enumerate() {
        a.ctx.bind_to_thread().map_err(CudaError::driver(format!("{}: binding the context", a.label())))?;
        for (j, b) in gpus.iter().enumerate() {
            if i == j || a.ordinal == b.ordinal {
                continue;
            }
            let mut can = 0;
            // SAFETY: plain queries and a context flag on live contexts.
            let result = unsafe {
                sys::cuDeviceCanAccessPeer(&mut can, a.ordinal as i32, b.ordinal as i32);
                if can == 0 {
                    continue;
                }
                sys::cuCtxEnablePeerAccess(b.ctx.cu_ctx(), 0)
            };
            match result {
                sys::CUresult::CUDA_SUCCESS | sys::CUresult::CUDA_ERROR_PEER_ACCESS_ALREADY_ENABLED => {}
                e => {
                    return Err(CudaError::Driver {
                        context: format!("{}: enabling peer access to {}", a.label(), b.label()),
                        source: cudarc::driver::DriverError(e),
                    })
                }
            }
            // Buffers come from `b`'s stream-ordered memory pool
            // (cuMemAllocAsync), which context peer access does not cover:
            // without this grant, peer copies silently fall back to staging
            // through the host (measured: 38 GB/s instead of NVLink's ~400).
            grant_pool_access(b, a)?;
            access[i][j] = true;
        }
    }
    Ok(access)
}

/// Lets `reader` access memory allocated from `owner`'s current memory pool.
fn grant_pool_access(owner: &Gpu, reader: &Gpu) -> Result<(), CudaError> {
    let context = || format!("{}: granting {} access to its memory pool", owner.label(), reader.label());
    let mut pool: sys::CUmemoryPool = std::ptr::null_mut();
    let desc = sys::CUmemAccessDesc {
        location: sys::CUmemLocation {
            type_: sys::CUmemLocationType::CU_MEM_LOCATION_TYPE_DEVICE,
            id: reader.ordinal as i32,
        },
        flags: sys::CUmemAccess_flags::CU_MEM_ACCESS_FLAGS_PROT_READWRITE,
    };
    // SAFETY: a query of the device's current pool and an access grant on
    // it; `desc` lives across the call.
    unsafe {
        sys::cuDeviceGetMemPool(&mut pool, owner.ordinal as sys::CUdevice)
            .result()
            .map_err(CudaError::driver(context()))?;
        sys::cuMemPoolSetAccess(pool, &desc, 1).result().map_err(CudaError::driver(context()))?;
    }
    Ok(())
}

impl CudaDevice {
    /// This device's buffer for an incoming `queue` (see the module docs).
    pub fn incoming_slot(&mut self, queue: Queue) -> Result<IncomingSlot, CudaError> {
        let gpu = self.gpu().clone();
        let queues = self.queues_mut()?;
        let capacity = queues.capacity;
        let buffer = queues.incoming(&gpu, queue)?;
        let (records, _sync) = buffer.device_ptr(&gpu.stream);
        Ok(IncomingSlot { ctx: gpu.ctx.cu_ctx(), records, capacity })
    }

    /// Copies `queue` into a neighbour's incoming slot and waits until the
    /// copy has landed. Returns the number of records sent.
    pub fn send_queue(&mut self, queue: Queue, to: &IncomingSlot) -> Result<u32, CudaError> {
        let gpu = self.gpu().clone();
        let queues = self.queues_mut()?;
        let len = queues.len(&gpu, queue)?;
        if len > to.capacity {
            return Err(CudaError::Usage(format!(
                "{}: sending {len} records to a queue of {}",
                gpu.label(),
                to.capacity
            )));
        }
        if len > 0 {
            let buffer = match queue {
                Queue::Paths => &queues.paths,
                Queue::Shadows => &queues.shadows,
            };
            let (src, _sync) = buffer.device_ptr(&gpu.stream);
            let bytes = len as usize * std::mem::size_of::<GpuRecord>();
            gpu.ctx
                .bind_to_thread()
                .map_err(CudaError::driver(format!("{}: binding the context", gpu.label())))?;
            // SAFETY: `src` holds `len` records on this GPU (the queue's
            // length, checked against its capacity by `len`); `to` names a
            // live buffer of at least `len` records that its owner leaves
            // alone until `accept_incoming`, which happens only after this
            // function's synchronisation below. The copy is queued after
            // this device's earlier work on the same stream (its trace).
            unsafe {
                cudarc::driver::result::memcpy_peer_async(
                    to.ctx,
                    to.records,
                    gpu.ctx.cu_ctx(),
                    src,
                    bytes,
                    gpu.stream.cu_stream(),
                )
            }
            .map_err(CudaError::driver(format!("{}: sending the {queue:?} queue", gpu.label())))?;
        }
        gpu.synchronize()?;
        Ok(len)
    }

    /// Makes the incoming buffer, filled by a neighbour's `send_queue` with
    /// `len` records, this device's `queue`.
    pub fn accept_incoming(&mut self, queue: Queue, len: u32) -> Result<(), CudaError> {
        let gpu = self.gpu().clone();
        self.queues_mut()?.accept_incoming(&gpu, queue, len)
    }
}

/// Measured copy speed between two GPUs.
#[derive(Clone, Debug)]
pub struct CopyBandwidth {
    pub bytes: u64,
    /// Whether the first GPU has direct (peer) access to the second.
    pub direct: bool,
    /// `cuMemcpyPeerAsync` from the first GPU to the second, GB/s.
    pub peer_gbps: f64,
    /// Device to host to device through pageable memory (what the host
    /// transport's `read_queue` / `write_queue` do), GB/s.
    pub host_gbps: f64,
}

/// Copies `bytes` from `a` to `b` `repeats` times each way (after one
/// untimed copy) and reports the speeds.
pub fn measure_copy(
    a: &Arc<Gpu>,
    b: &Arc<Gpu>,
    bytes: usize,
    repeats: u32,
) -> Result<CopyBandwidth, CudaError> {
    let access = enable_peer_access(&[a.clone(), b.clone()])?;
    let what = |w: &str| format!("copy benchmark: {w}");
    let src = a.stream.alloc_zeros::<u8>(bytes).map_err(CudaError::driver(what("allocating")))?;
    let mut dst = b.stream.alloc_zeros::<u8>(bytes).map_err(CudaError::driver(what("allocating")))?;
    a.synchronize()?;
    b.synchronize()?;
    let peer_copy = || -> Result<(), CudaError> {
        let (s, _s) = src.device_ptr(&a.stream);
        let (d, _d) = dst.device_ptr(&b.stream);
        a.ctx.bind_to_thread().map_err(CudaError::driver(what("binding")))?;
        // SAFETY: both buffers are live and `bytes` long; nothing else uses them.
        unsafe {
            cudarc::driver::result::memcpy_peer_async(
                b.ctx.cu_ctx(),
                d,
                a.ctx.cu_ctx(),
                s,
                bytes,
                a.stream.cu_stream(),
            )
        }
        .map_err(CudaError::driver(what("peer copy")))?;
        a.synchronize()
    };
    let timed = |f: &mut dyn FnMut() -> Result<(), CudaError>| -> Result<f64, CudaError> {
        f()?;
        let start = std::time::Instant::now();
        for _ in 0..repeats.max(1) {
            f()?;
        }
        Ok(bytes as f64 * repeats.max(1) as f64 / start.elapsed().as_secs_f64() / 1e9)
    };
    let peer_gbps = timed(&mut || peer_copy())?;
    let host_gbps = timed(&mut || {
        let host = a.stream.clone_dtoh(&src).map_err(CudaError::driver(what("download")))?;
        b.stream.memcpy_htod(&host, &mut dst).map_err(CudaError::driver(what("upload")))?;
        b.synchronize()
    })?;
    Ok(CopyBandwidth { bytes: bytes as u64, direct: access[0][1], peer_gbps, host_gbps })
}
