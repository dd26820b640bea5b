//! Ray queues moved straight from GPU to GPU, for the ring strategy (ray
//! queue cycling): the CUDA [`DirectTransport`]. The sender's
//! `send_records` kernel (kernels/peer.cu) reads its queue length on the
//! device and writes records and length into the receiver's idle incoming
//! buffer over NVLink (peer access); the receiver then makes that buffer
//! its queue. Nothing passes through the host and the host never waits:
//! each step is queued on the two GPUs' streams and ordered with events.
//!
//! A step (`atoll_render::transport` orders the host side):
//! 1. `open`: every member records its `ready` event and publishes its
//!    [`IncomingSlot`] (a barrier follows);
//! 2. `send`: every member copies into its successor's slot, after the
//!    successor's `ready` (so all the successor's earlier work on that
//!    buffer is done), recording its `sent` event;
//! 3. `accept`: every member takes in the slot after its predecessor's `sent`.
//!
//! Slots change from step to step (buffers swap), so they are published
//! anew each time. Events alternate by step parity: a member re-records a
//! step's events only after a barrier its neighbours pass after waiting
//! on them.

use std::sync::{Arc, Mutex};

use atoll_render::{Device, DeviceError, DirectRing, DirectTransport, Queue};
use cudarc::driver::sys;
use cudarc::driver::{CudaEvent, CudaSlice, DevicePtr, PushKernelArg};

use crate::device::CudaDevice;
use crate::error::CudaError;
use crate::gpu::Gpu;

/// Where a neighbour may write a queue into this device (valid until the
/// device accepts what came in).
#[derive(Clone, Copy, Debug)]
pub(crate) struct IncomingSlot {
    pub(crate) records: sys::CUdeviceptr,
    pub(crate) count: sys::CUdeviceptr,
    pub(crate) capacity: u32,
}

/// Lets each GPU of `gpus` read and write the others' memory directly
/// where the hardware allows it. Returns, per ordered pair (i, j), whether
/// direct access from i to j is on; copies between pairs without it still
/// work, staged through the host by the driver.
pub(crate) fn enable_peer_access(gpus: &[Arc<Gpu>]) -> Result<Vec<Vec<bool>>, CudaError> {
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
            // through the host (measured: a small fraction of NVLink's speed).
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
    /// This device's buffer and counter for an incoming `queue` (see the module docs).
    pub(crate) fn incoming_slot(&mut self, queue: Queue) -> Result<IncomingSlot, CudaError> {
        let gpu = self.gpu().clone();
        let queues = self.queues_mut()?;
        let capacity = queues.capacity;
        let (records, count) = queues.incoming(&gpu, queue)?;
        let (records, _sync) = records.device_ptr(&gpu.stream);
        let (count, _sync) = count.device_ptr(&gpu.stream);
        Ok(IncomingSlot { records, count, capacity })
    }

    /// Loads (compiling on a cold cache) the send kernel now, so that the
    /// first ring step does not pay for it.
    fn load_peer_kernels(&self) -> Result<(), CudaError> {
        self.gpu().function("peer.cu", "send_records").map(|_| ())
    }

    /// Bytes this device has sent to ring neighbours (read back: waits for
    /// the device).
    fn bytes_sent(&mut self) -> Result<u64, CudaError> {
        let gpu = self.gpu().clone();
        let queues = self.queues_mut()?;
        let n = gpu
            .stream
            .clone_dtoh(&queues.sent_bytes)
            .map_err(CudaError::driver(format!("{}: reading the sent counter", gpu.label())))?;
        Ok(n[0])
    }

    /// Records `event` on this device's stream: everything queued so far.
    fn record(&self, event: &CudaEvent) -> Result<(), CudaError> {
        event
            .record(&self.gpu().stream)
            .map_err(CudaError::driver(format!("{}: recording an event", self.gpu().label())))
    }

    /// Queues, after `after` (an event of the receiver), the copy of
    /// `queue` into a neighbour's incoming slot, then records `sent`.
    fn send_queue(
        &mut self,
        queue: Queue,
        to: &IncomingSlot,
        after: &CudaEvent,
        sent: &CudaEvent,
    ) -> Result<(), CudaError> {
        let gpu = self.gpu().clone();
        let what = |w: &str| format!("{}: sending the {queue:?} queue: {w}", gpu.label());
        let kernel = gpu.function("peer.cu", "send_records")?;
        let media = self.frame_has_media()?;
        let queues = self.queues_mut()?;
        if queues.capacity > to.capacity {
            return Err(CudaError::Usage(what(&format!(
                "a queue of {} records does not fit the receiver's {}",
                queues.capacity, to.capacity
            ))));
        }
        gpu.stream.wait(after).map_err(CudaError::driver(what("waiting for the receiver")))?;
        let (src, src_count) = match queue {
            Queue::Paths => (&queues.paths, &queues.path_count),
            Queue::Shadows => (&queues.shadows, &queues.shadow_count),
        };
        let mut launch = gpu.stream.launch_builder(&kernel);
        // Shadow rays: the first 4 of 8 words (see peer.cu), and through
        // media all of them (their optical depth is in the hit half's
        // position); paths: all of them.
        let word_shift: u32 = match queue {
            Queue::Shadows if !media => 2,
            _ => 3,
        };
        launch
            .arg(src)
            .arg(src_count)
            .arg(&to.records)
            .arg(&to.count)
            .arg(&to.capacity)
            .arg(&word_shift)
            .arg(&mut queues.sent_bytes);
        // Enough blocks to keep NVLink busy; the kernel strides over the rest.
        let config = cudarc::driver::LaunchConfig {
            grid_dim: (gpu.multiprocessors * 4, 1, 1),
            block_dim: (256, 1, 1),
            shared_mem_bytes: 0,
        };
        // SAFETY: matches `send_records(const uint4* src, const unsigned* src_count, uint4* dst,
        // unsigned* dst_count, unsigned capacity, unsigned word_shift, unsigned long long*
        // sent_bytes)` in peer.cu (`sent_bytes` is this GPU's one counter; word_shift <= 3
        // keeps every copied word inside its record). `src` holds `capacity` records
        // and its counter never exceeds that; `to` names a live buffer of `to.capacity` records
        // and its counter on a GPU with peer access (enabled by `enable_peer_access`), which
        // its owner leaves alone until `accept_incoming`, ordered after `sent` below; the
        // kernel writes at most `to.capacity` records.
        unsafe { launch.launch(config) }.map_err(CudaError::driver(what("launch")))?;
        self.record(sent)
    }

    /// Makes the incoming buffer, being filled by a neighbour's `send_queue`
    /// that records `sent`, this device's `queue`; later work waits for it.
    fn accept_incoming(&mut self, queue: Queue, sent: &CudaEvent) -> Result<(), CudaError> {
        let gpu = self.gpu().clone();
        gpu.stream.wait(sent).map_err(CudaError::driver(format!(
            "{}: waiting for the incoming {queue:?} queue",
            gpu.label()
        )))?;
        self.queues_mut()?.accept_incoming(&gpu, queue)
    }
}

/// Peer copies between the GPUs of a ring ([`CudaDevice::direct_transport`]).
pub(crate) struct PeerTransport;

/// Per ring member, its GPU's events by step parity.
struct MemberEvents {
    /// Recorded when the member opens a step: all its earlier work is queued before it.
    ready: [CudaEvent; 2],
    /// Recorded after the member's send: its records have landed.
    sent: [CudaEvent; 2],
}

/// A connected ring of CUDA devices.
struct PeerRing {
    events: Vec<MemberEvents>,
    /// The members' published incoming slots (`None` where opening failed).
    slots: Vec<Mutex<Option<IncomingSlot>>>,
}

/// The CUDA device behind a ring member.
pub(crate) fn cuda(device: &mut dyn Device) -> Result<&mut CudaDevice, DeviceError> {
    let name = device.name();
    device.as_any_mut().downcast_mut::<CudaDevice>().ok_or(DeviceError::Unsupported {
        device: name,
        what: "CUDA peer copies (every member of the ring must be a CUDA GPU)".into(),
    })
}

impl DirectTransport for PeerTransport {
    fn name(&self) -> &'static str {
        "CUDA peer copies"
    }

    fn connect(&self, ring: &mut [Box<dyn Device>]) -> Result<Box<dyn DirectRing>, DeviceError> {
        let mut gpus = Vec::new();
        for device in ring.iter_mut() {
            let d = cuda(device.as_mut())?;
            let label = d.gpu().label();
            d.load_peer_kernels().map_err(|e| e.into_device_error(&label))?;
            gpus.push(d.gpu().clone());
        }
        let access = enable_peer_access(&gpus).map_err(|e| e.into_device_error("peer access"))?;
        for (i, row) in access.iter().enumerate() {
            for (j, &direct) in row.iter().enumerate() {
                // Devices sharing a GPU copy within its memory.
                if gpus[i].ordinal != gpus[j].ordinal && !direct {
                    tracing::warn!(
                        "{} cannot access {} directly: ring copies between them go through the host",
                        gpus[i].label(),
                        gpus[j].label()
                    );
                }
            }
        }
        let events = gpus
            .iter()
            .map(|gpu| {
                let event = || {
                    gpu.ctx.new_event(None).map_err(|e| {
                        CudaError::driver("creating an event")(e).into_device_error(&gpu.label())
                    })
                };
                Ok(MemberEvents { ready: [event()?, event()?], sent: [event()?, event()?] })
            })
            .collect::<Result<Vec<_>, DeviceError>>()?;
        let slots = gpus.iter().map(|_| Mutex::new(None)).collect();
        Ok(Box::new(PeerRing { events, slots }))
    }
}

impl PeerRing {
    fn slot(&self, member: usize) -> std::sync::MutexGuard<'_, Option<IncomingSlot>> {
        self.slots[member].lock().unwrap_or_else(|p| p.into_inner())
    }
}

impl DirectRing for PeerRing {
    fn open(
        &self,
        member: usize,
        device: &mut dyn Device,
        queue: Queue,
        step: usize,
    ) -> Result<(), DeviceError> {
        let d = cuda(device)?;
        // The slot first: its first use allocates and zero-fills it on this
        // device's stream, which must come before `ready` (the sender waits
        // only for that). Recorded the other way round, a sender on the same
        // GPU could write into the slot before the fill wiped it (seen as
        // lost shadow rays with two devices on one GPU; invisible across
        // two GPUs, where the send always lands later).
        let slot = d
            .incoming_slot(queue)
            .and_then(|slot| d.record(&self.events[member].ready[step % 2]).map(|()| slot));
        *self.slot(member) = slot.as_ref().ok().copied();
        slot.map(|_| ()).map_err(|e| e.into_device_error(&d.gpu().label()))
    }

    fn send(
        &self,
        member: usize,
        device: &mut dyn Device,
        queue: Queue,
        step: usize,
    ) -> Result<(), DeviceError> {
        let d = cuda(device)?;
        let label = d.gpu().label();
        let next = (member + 1) % self.slots.len();
        let Some(target) = *self.slot(next) else {
            return Err(DeviceError::Other {
                device: label,
                message: "the next device has no incoming slot".into(),
            });
        };
        d.send_queue(queue, &target, &self.events[next].ready[step % 2], &self.events[member].sent[step % 2])
            .map_err(|e| e.into_device_error(&label))
    }

    fn accept(
        &self,
        member: usize,
        device: &mut dyn Device,
        queue: Queue,
        step: usize,
    ) -> Result<(), DeviceError> {
        let d = cuda(device)?;
        let prev = (member + self.slots.len() - 1) % self.slots.len();
        d.accept_incoming(queue, &self.events[prev].sent[step % 2])
            .map_err(|e| e.into_device_error(&d.gpu().label()))
    }

    fn bytes_sent(&self, device: &mut dyn Device) -> Result<u64, DeviceError> {
        let d = cuda(device)?;
        d.bytes_sent().map_err(|e| e.into_device_error(&d.gpu().label()))
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
    /// NCCL `send`/`recv` (grouped) from the first GPU to the second, GB/s;
    /// `None` without the NCCL library.
    pub nccl_gbps: Option<f64>,
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
    let timed = move |f: &mut dyn FnMut() -> Result<(), CudaError>| -> Result<f64, CudaError> {
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
    let nccl_gbps = nccl_copy(a, b, &src, &mut dst, &timed)?;
    Ok(CopyBandwidth { bytes: bytes as u64, direct: access[0][1], peer_gbps, host_gbps, nccl_gbps })
}

/// Runs a copy once untimed, then times repeats of it: GB/s.
type Timed = dyn Fn(&mut dyn FnMut() -> Result<(), CudaError>) -> Result<f64, CudaError>;

/// NCCL point-to-point from `a` to `b` (a communicator over both), timed
/// like the other copies; `None` when libnccl cannot be loaded.
fn nccl_copy(
    a: &Arc<Gpu>,
    b: &Arc<Gpu>,
    src: &CudaSlice<u8>,
    dst: &mut CudaSlice<u8>,
    timed: &Timed,
) -> Result<Option<f64>, CudaError> {
    use crate::nccl::{nccl, nccl_present};
    use cudarc::nccl::safe::{group_end, group_start, Comm};
    if !nccl_present() {
        return Ok(None);
    }
    let comms = Comm::from_devices(vec![a.stream.clone(), b.stream.clone()]).map_err(nccl("init"))?;
    let gbps = timed(&mut || {
        group_start().map_err(nccl("group start"))?;
        comms[0].send(src, 1).map_err(nccl("send"))?;
        comms[1].recv(dst, 0).map_err(nccl("recv"))?;
        group_end().map_err(nccl("group end"))?;
        a.synchronize()?;
        b.synchronize()
    })?;
    Ok(Some(gbps))
}
