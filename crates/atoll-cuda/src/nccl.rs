//! NCCL between processes: each process (an MPI rank, say) joins one
//! communicator with its GPU, made from a unique id that rank 0 creates and
//! the caller carries to the others over its own channel (MPI broadcasts
//! it). NCCL is loaded at run time like the driver: without libnccl,
//! [`nccl_present`] says so and callers keep their host transport.

use std::sync::Arc;

use cudarc::driver::CudaSlice;
use cudarc::nccl::safe::{group_end, group_start, Comm, Id};

use crate::error::CudaError;
use crate::gpu::Gpu;

/// Whether libnccl can be loaded.
pub fn nccl_present() -> bool {
    // SAFETY: only probes whether the shared library loads.
    unsafe { cudarc::nccl::sys::is_culib_present() }
}

/// Maps an NCCL failure to an error saying what was being done.
pub(crate) fn nccl(what: &'static str) -> impl Fn(cudarc::nccl::result::NcclError) -> CudaError {
    move |e| CudaError::Usage(format!("NCCL {what}: {e:?}"))
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

/// One process's place in a communicator over the processes' GPUs.
pub struct NcclLink {
    comm: Comm,
    gpu: Arc<Gpu>,
}

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
        let id = Id::uninit(id.map(|b| b as std::ffi::c_char));
        let comm = Comm::from_rank(gpu.stream.clone(), rank, size, id).map_err(nccl("joining"))?;
        Ok(NcclLink { comm, gpu: gpu.clone() })
    }

    pub fn rank(&self) -> usize {
        self.comm.rank()
    }

    pub fn size(&self) -> usize {
        self.comm.world_size()
    }

    /// Sends `outgoing` to rank `to` and receives `incoming` (its whole
    /// length) from rank `from` at once, on the GPU's stream, then waits:
    /// a ring step. Either may be `None` (a one-way copy).
    pub fn exchange(
        &self,
        outgoing: Option<(&CudaSlice<u8>, usize)>,
        incoming: Option<(&mut CudaSlice<u8>, usize)>,
    ) -> Result<(), CudaError> {
        group_start().map_err(nccl("group start"))?;
        if let Some((data, to)) = outgoing {
            self.comm.send(data, to as i32).map_err(nccl("send"))?;
        }
        if let Some((data, from)) = incoming {
            self.comm.recv(data, from as i32).map_err(nccl("recv"))?;
        }
        group_end().map_err(nccl("group end"))?;
        self.gpu.synchronize()
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
