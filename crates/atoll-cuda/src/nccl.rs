//! NCCL between processes: each process (an MPI rank, say) joins one
//! communicator with its GPU, made from a unique id that rank 0 creates and
//! the caller carries to the others over its own channel (MPI broadcasts
//! it). NCCL is loaded at run time like the driver: without libnccl,
//! [`nccl_present`] says so and callers keep their host transport.

use std::sync::Arc;

use cudarc::driver::sys as sys_driver;
use cudarc::driver::CudaSlice;
use cudarc::nccl::safe::Id;
use cudarc::nccl::{result, sys};

use atoll_render::{Device, DeviceError, Film, ProcessLink, ProcessTransport, Queue};

use crate::error::CudaError;
use crate::gpu::Gpu;
use crate::layout::GpuRecord;
use crate::peer::cuda;

/// Whether libnccl can be loaded.
pub fn nccl_present() -> bool {
    // SAFETY: only probes whether the shared library loads.
    unsafe { cudarc::nccl::sys::is_culib_present() }
}

/// Maps an NCCL failure to an error saying what was being done.
pub(crate) fn nccl(what: &'static str) -> impl Fn(cudarc::nccl::result::NcclError) -> CudaError {
    move |e| {
        // NCCL's own account of the last failure (say, two ranks of one
        // communicator on one GPU), where it has one.
        // SAFETY: NCCL is loaded (an NCCL call just failed); a null
        // communicator asks for the process's last error, a string NCCL
        // owns and keeps.
        let last = unsafe { sys::ncclGetLastError(std::ptr::null_mut()) };
        let detail = match last.is_null() {
            true => String::new(),
            // SAFETY: non-null, NUL-terminated (as above).
            false => unsafe { std::ffi::CStr::from_ptr(last) }.to_string_lossy().trim().to_string(),
        };
        match detail.is_empty() {
            true => CudaError::Usage(format!("NCCL {what}: {:?}", e.0)),
            false => CudaError::Usage(format!("NCCL {what}: {:?}: {detail}", e.0)),
        }
    }
}

/// The bytes of a communicator's unique id, as they travel between
/// processes.
pub type NcclIdBytes = [u8; 128];

/// A new unique id (rank 0 makes it; every rank connects with it).
pub fn new_id() -> Result<NcclIdBytes, CudaError> {
    if !nccl_present() {
        return Err(CudaError::Usage("NCCL: libnccl.so.2 cannot be loaded".into()));
    }
    let id = Id::new().map_err(nccl("unique id"))?;
    Ok(id.internal().map(|c| c as u8))
}

/// One process's place in a communicator over the processes' GPUs (the
/// raw communicator: ring steps send from and receive into buffers the
/// device's queues own, by address).
pub struct NcclLink {
    comm: sys::ncclComm_t,
    gpu: Arc<Gpu>,
    /// This process's rank in the communicator.
    rank: usize,
}

// SAFETY: the communicator is used by one thread at a time (`&self` calls
// come from the device's thread; NCCL communicators may move threads).
unsafe impl Send for NcclLink {}

impl NcclLink {
    /// Joins the communicator of `size` processes that `id` names, as
    /// `rank`, with `gpu`. Every process must call it (NCCL waits for all).
    pub fn connect(
        gpu: &Arc<Gpu>,
        id: &NcclIdBytes,
        rank: usize,
        size: usize,
    ) -> Result<NcclLink, CudaError> {
        if !nccl_present() {
            return Err(CudaError::Usage("NCCL: libnccl.so.2 cannot be loaded".into()));
        }
        let bad = |what| CudaError::Usage(format!("NCCL: {what} out of range"));
        let me = rank;
        let (rank, size) =
            (i32::try_from(rank).map_err(|_| bad("rank"))?, i32::try_from(size).map_err(|_| bad("size"))?);
        gpu.ctx
            .bind_to_thread()
            .map_err(CudaError::driver(format!("{}: binding the context", gpu.label())))?;
        let id = sys::ncclUniqueId { internal: id.map(|b| b as std::ffi::c_char) };
        let mut comm = std::mem::MaybeUninit::uninit();
        // SAFETY: `comm` is written by NCCL before it is read.
        let comm = unsafe {
            result::comm_init_rank(comm.as_mut_ptr(), size, id, rank).map_err(nccl("joining"))?;
            comm.assume_init()
        };
        Ok(NcclLink { comm, gpu: gpu.clone(), rank: me })
    }

    /// Queues on the GPU's stream the send of `outgoing` (an address on
    /// this GPU and a byte count) to rank `to` and the receipt of
    /// `incoming` bytes from rank `from`, at once: a ring step. Either may
    /// be `None` (a one-way copy). Returns without waiting: later work on
    /// the stream comes after.
    ///
    /// # Safety
    /// The addresses must hold the byte counts given, on this link's GPU,
    /// and nothing but later work on the GPU's stream may use them.
    pub unsafe fn exchange_raw(
        &self,
        outgoing: Option<(sys_driver::CUdeviceptr, usize, usize)>,
        incoming: Option<(sys_driver::CUdeviceptr, usize, usize)>,
    ) -> Result<(), CudaError> {
        let stream = self.gpu.stream.cu_stream() as sys::cudaStream_t;
        result::group_start().map_err(nccl("group start"))?;
        if let Some((data, bytes, to)) = outgoing.filter(|o| o.1 > 0) {
            let data = data as *const std::ffi::c_void;
            result::send(data, bytes, sys::ncclDataType_t::ncclUint8, to as i32, self.comm, stream)
                .map_err(nccl("send"))?;
        }
        if let Some((data, bytes, from)) = incoming.filter(|i| i.1 > 0) {
            let data = data as *mut std::ffi::c_void;
            result::recv(data, bytes, sys::ncclDataType_t::ncclUint8, from as i32, self.comm, stream)
                .map_err(nccl("recv"))?;
        }
        result::group_end().map(drop).map_err(nccl("group end"))
    }

    /// [`NcclLink::exchange_raw`] of whole buffers, waited for.
    pub fn exchange(
        &self,
        outgoing: Option<(&CudaSlice<u8>, usize)>,
        incoming: Option<(&mut CudaSlice<u8>, usize)>,
    ) -> Result<(), CudaError> {
        use cudarc::driver::{DevicePtr, DevicePtrMut};
        let stream = &self.gpu.stream;
        let out = outgoing.map(|(d, to)| (d.device_ptr(stream).0, d.len(), to));
        let inc = incoming.map(|(d, from)| {
            let len = d.len();
            (d.device_ptr_mut(stream).0, len, from)
        });
        // SAFETY: whole buffers of this GPU, borrowed until the copies are
        // done (waited for below).
        unsafe { self.exchange_raw(out, inc) }?;
        self.gpu.synchronize()
    }
}

impl NcclLink {
    /// Sums every process's `values` into those of the process at rank
    /// `root`, on the GPUs (`ncclReduce`, in place on each GPU's copy);
    /// the others' are left as they were. Collective, waited for.
    pub fn sum_to_root(&self, values: &mut [f32], root: usize) -> Result<(), CudaError> {
        use cudarc::driver::DevicePtrMut;
        let stream = &self.gpu.stream;
        let label = self.gpu.label();
        let mut on_gpu = stream
            .clone_htod(values)
            .map_err(CudaError::driver(format!("{label}: uploading a film to sum")))?;
        let root = i32::try_from(root).map_err(|_| CudaError::Usage("NCCL: root out of range".into()))?;
        {
            let (data, _sync) = on_gpu.device_ptr_mut(stream);
            let data = data as *mut std::ffi::c_void;
            // SAFETY: `values.len()` floats on this GPU, summed in place
            // (send and receive buffers equal) on its stream, which the
            // read-back below waits for.
            unsafe {
                result::reduce(
                    data,
                    data,
                    values.len(),
                    sys::ncclDataType_t::ncclFloat32,
                    sys::ncclRedOp_t::ncclSum,
                    root,
                    self.comm,
                    stream.cu_stream() as sys::cudaStream_t,
                )
            }
            .map_err(nccl("film sum"))?;
        }
        if self.rank == root as usize {
            stream
                .memcpy_dtoh(&on_gpu, values)
                .map_err(CudaError::driver(format!("{label}: reading the summed film back")))?;
        }
        self.gpu.synchronize()
    }
}

impl Drop for NcclLink {
    fn drop(&mut self) {
        // SAFETY: the communicator is this link's own, used no more.
        let _ = unsafe { result::comm_destroy(self.comm) };
    }
}

/// NCCL between the GPUs of processes ([`crate::device::CudaDevice`]'s
/// process transport): rings of ranks step device to device.
pub(crate) struct NcclTransport;

impl ProcessTransport for NcclTransport {
    fn name(&self) -> &'static str {
        "NCCL"
    }

    fn new_id(&self) -> Result<Vec<u8>, DeviceError> {
        new_id().map(|id| id.to_vec()).map_err(|e| e.into_device_error("NCCL"))
    }

    fn connect(
        &self,
        device: &mut dyn Device,
        id: &[u8],
        rank: usize,
        size: usize,
    ) -> Result<Box<dyn ProcessLink>, DeviceError> {
        let d = cuda(device)?;
        let label = d.gpu().label();
        let id: &NcclIdBytes = id.try_into().map_err(|_| DeviceError::Other {
            device: label.clone(),
            message: "an NCCL id has 128 bytes".into(),
        })?;
        let link = NcclLink::connect(d.gpu(), id, rank, size).map_err(|e| e.into_device_error(&label))?;
        Ok(Box::new(DeviceLink(link)))
    }
}

/// A ring step's queues, or the ranks' films, over an [`NcclLink`].
struct DeviceLink(NcclLink);

impl ProcessLink for DeviceLink {
    fn exchange(
        &self,
        device: &mut dyn Device,
        queue: Queue,
        sending: (usize, usize),
        receiving: (usize, usize),
    ) -> Result<(), DeviceError> {
        let d = cuda(device)?;
        let label = d.gpu().label();
        d.nccl_exchange(&self.0, queue, sending, receiving).map_err(|e| e.into_device_error(&label))
    }

    fn sum_film(&self, device: &mut dyn Device, film: &mut Film, root: usize) -> Result<(), DeviceError> {
        let label = cuda(device)?.gpu().label();
        let values: &mut [f32] = bytemuck::cast_slice_mut(&mut film.sum);
        self.0.sum_to_root(values, root).map_err(|e| e.into_device_error(&label))
    }
}

impl crate::device::CudaDevice {
    /// Queues the send of the first `sending.0` records of `queue` to rank
    /// `sending.1` and the receipt of `receiving.0` from rank `receiving.1`
    /// into the incoming buffer the peer ring uses, which then becomes the
    /// queue. Nothing waits: the device's later work comes after on its
    /// stream.
    fn nccl_exchange(
        &mut self,
        link: &NcclLink,
        queue: Queue,
        (sending, next): (usize, usize),
        (receiving, prev): (usize, usize),
    ) -> Result<(), CudaError> {
        use cudarc::driver::DevicePtr;
        let gpu = self.gpu().clone();
        let slot = self.incoming_slot(queue)?;
        let queues = self.queues_mut()?;
        if sending.max(receiving) > slot.capacity as usize {
            return Err(CudaError::Usage(format!(
                "{}: a ring step of {sending} and {receiving} records passes the queues' {}",
                gpu.label(),
                slot.capacity
            )));
        }
        let records = match queue {
            Queue::Paths => &queues.paths,
            Queue::Shadows => &queues.shadows,
        };
        let record = std::mem::size_of::<GpuRecord>();
        {
            let (source, _sync) = records.device_ptr(&gpu.stream);
            let (outgoing, incoming) =
                ((source, sending * record, next), (slot.records, receiving * record, prev));
            // SAFETY: both buffers hold a queue's capacity of records on
            // this GPU, at least the counts checked above, and the queues
            // touch them only on this GPU's stream (the incoming buffer
            // becomes the queue below; the sent one the next incoming).
            unsafe { link.exchange_raw(Some(outgoing), Some(incoming)) }?;
        }
        // SAFETY: the slot's counter is one u32 on this GPU, set in stream order.
        unsafe { sys_driver::cuMemsetD32Async(slot.count, receiving as u32, 1, gpu.stream.cu_stream()) }
            .result()
            .map_err(CudaError::driver(format!("{}: writing the received count", gpu.label())))?;
        self.queues_mut()?.accept_incoming(&gpu, queue)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn without_libnccl_an_id_is_an_error_not_a_panic() {
        match nccl_present() {
            // Making an id needs no GPU; joining is for the GPU machine.
            true => assert!(new_id().is_ok()),
            false => {
                let e = new_id().unwrap_err().to_string();
                assert!(e.contains("libnccl.so.2 cannot be loaded"), "{e}");
            }
        }
    }
}
