//! The `Device` trait: what every device (CPU, CUDA GPU) does, shaped like
//! the integrator's stages, and the capabilities distribution strategies
//! and placement build on (memory facts, scene sharing on one piece of
//! hardware, direct queue transport). Strategies see devices only through
//! this trait: queues move through [`Device::read_queue`] /
//! [`Device::write_queue`], or through a [`DirectTransport`] a device kind
//! offers.

use std::any::Any;
use std::sync::Arc;

use atoll_bvh::{ByteModel, ScenePart};
use atoll_scene::Scene;

use crate::camera::CameraRays;
use crate::chunks::{Residency, SceneSharing};
use crate::film::Film;
use crate::frame::{FrameContext, RenderOptions, Wave, DEFAULT_WAVE_SIZE};
use crate::record::RayRecord;
use crate::transport::{DirectTransport, ProcessTransport};

/// The two queues of ray records a device holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Queue {
    /// Path segments: traced for closest hits, then shaded.
    Paths,
    /// Shadow/AO rays: traced for any hit, then resolved into the film.
    Shadows,
}

/// Errors a device reports. A device's own error type (a GPU driver's)
/// stays the [`DeviceError::Backend`] source, so callers can walk the chain.
#[derive(Debug, thiserror::Error)]
pub enum DeviceError {
    #[error("{device}: scene needs {needed} bytes but the memory budget is {budget} bytes")]
    OutOfMemory { device: String, needed: u64, budget: u64 },
    #[error("{device}: {what} is not something this device can do")]
    Unsupported { device: String, what: String },
    /// A stage called after an earlier one failed: the device does no
    /// more work this frame (its queues read as empty), so that loops and
    /// ring neighbours finish.
    #[error("{device}: stopped after an earlier failure: {first}")]
    Stopped { device: String, first: String },
    /// What the device's back-end reported, as its own error.
    #[error("{device}: {what}")]
    Backend {
        device: String,
        what: String,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    #[error("{device}: {message}")]
    Other { device: String, message: String },
}

/// What preparing a device cost.
#[derive(Clone, Debug, Default)]
pub struct PrepareStats {
    /// Bytes of scene data (geometry + BVH) resident on the device.
    pub scene_bytes: u64,
    /// Bytes of queues and film.
    pub frame_bytes: u64,
    /// Seconds copying the scene's tables to the device (0 where it reads
    /// them in place).
    pub upload_seconds: f64,
    pub bvh_build_seconds: f64,
    pub bvh_sah_cost: f32,
    /// Under the shared strategy, what of the chunked scene the device
    /// holds and what it reads elsewhere (`scene_bytes` is then the bytes
    /// it holds).
    pub shared: Option<Residency>,
}

/// Counters a device keeps over a frame.
#[derive(Clone, Debug, Default)]
pub struct DeviceStats {
    pub rays_traced: u64,
    pub shadow_rays_traced: u64,
    /// Seconds spent inside stage calls.
    pub busy_seconds: f64,
}

/// One renderer back-end. Stages return errors: after one, a device may
/// answer every later call with [`DeviceError::Stopped`] (a GPU whose
/// stream failed), its queues reading as empty, so that the loops driving
/// it, and a ring's other members, still finish.
pub trait Device: Send {
    /// A short name such as `cpu` or `cuda:0`.
    fn name(&self) -> String;

    /// Makes `part` of the scene resident (upload, BVH build over that part
    /// only; [`ScenePart::whole`] for all of it) and allocates queues and
    /// film for `frame`. Materials and lights are always whole: a device
    /// shades any hit, wherever it was found. Fails before allocating when
    /// the memory budget cannot hold it.
    fn prepare(
        &mut self,
        scene: &Arc<Scene>,
        part: &ScenePart,
        frame: &Arc<FrameContext>,
    ) -> Result<PrepareStats, DeviceError>;

    /// Zeroes the film and the counters (rays, busy time) for another
    /// frame over what `prepare` made resident: the scene stays, and so do
    /// the queues, which a finished frame leaves empty. Warm-up passes use
    /// it, so that the timed frame needs no second upload and BVH build.
    fn reset_frame(&mut self) -> Result<(), DeviceError>;

    /// Points the prepared frame's camera elsewhere (an interactive view
    /// moving): camera paths started later leave from `camera`. The scene
    /// stays resident and the film keeps its sums ([`Device::reset_frame`]
    /// clears them). Call it between frames, with nothing in flight.
    fn set_camera(&mut self, camera: &CameraRays) -> Result<(), DeviceError>;

    /// Adds the camera paths of `wave` to this device's pending work, after
    /// what is already pending; [`Device::refill`] starts them as the path
    /// queue has room. Waves pass through in order, so a device that is
    /// given waves one at a time and refilled until empty renders exactly
    /// what a wave-at-a-time loop renders.
    fn queue_work(&mut self, wave: &Wave) -> Result<(), DeviceError>;

    /// Whether pending work may run out at the next refill (at most one
    /// queue's worth of paths not yet started, as far as the device knows):
    /// a caller merging waves queues the next one now, so the path queue
    /// stays full while long paths finish.
    fn wants_work(&self) -> Result<bool, DeviceError>;

    /// Appends pending camera paths to the path queue, up to its capacity
    /// (the frame's wave size). A no-op when nothing is pending or the
    /// queue is full.
    fn refill(&mut self) -> Result<(), DeviceError>;

    /// Closest-hit tracing of the path queue. Hits farther than a record's
    /// `t_max` (e.g. found earlier on another device) are left alone.
    fn trace_paths(&mut self) -> Result<(), DeviceError>;

    /// Shades the path queue: emission goes to the film, next-event rays to
    /// the shadow queue, and continuing paths replace the path queue.
    fn shade(&mut self) -> Result<(), DeviceError>;

    /// Any-hit tracing of the shadow queue (records already occluded are skipped).
    fn trace_shadows(&mut self) -> Result<(), DeviceError>;

    /// Adds unoccluded shadow contributions to the film; empties the shadow queue.
    fn resolve_shadows(&mut self) -> Result<(), DeviceError>;

    /// Whether the path queue may still hold paths or work is pending. A
    /// device for which reading the length back is expensive may answer
    /// `true` for an empty queue (one bounce late): every stage on an empty
    /// queue does nothing.
    fn has_paths(&self) -> Result<bool, DeviceError>;

    fn queue_len(&self, queue: Queue) -> Result<usize, DeviceError>;
    /// `queue`'s records, copied into `into` (its contents replaced, its
    /// allocation reused: a ring through the host moves a queue at every
    /// step, and a fresh allocation of a wave's records costs more in page
    /// faults than the copy itself).
    fn read_queue_into(&self, queue: Queue, into: &mut Vec<RayRecord>) -> Result<(), DeviceError>;
    /// `queue`'s records, in a new vector.
    fn read_queue(&self, queue: Queue) -> Result<Vec<RayRecord>, DeviceError> {
        let mut records = Vec::new();
        self.read_queue_into(queue, &mut records)?;
        Ok(records)
    }
    fn write_queue(&mut self, queue: Queue, records: &[RayRecord]) -> Result<(), DeviceError>;

    /// The radiance sums this device accumulated.
    fn film(&self) -> Result<Film, DeviceError>;

    fn stats(&self) -> Result<DeviceStats, DeviceError>;

    // --- Memory facts: what placement plans with ---

    /// What scene parts cost this device ([`atoll_bvh::part_bytes`]).
    fn byte_model(&self) -> ByteModel {
        ByteModel::CPU
    }

    /// What a scene costs this device held in shared chunks
    /// ([`Device::scene_sharing`]): what stays resident, where its BVH may
    /// be built a piece at a time rather than whole ([`Device::byte_model`]
    /// where it is not).
    fn shared_byte_model(&self) -> ByteModel {
        self.byte_model()
    }

    /// Bytes this device allocates for a frame of `options` besides the
    /// scene: queues, film, frame parameters, headroom.
    fn frame_bytes(&self, options: &RenderOptions) -> u64;

    /// Bytes the device keeps for the whole scene whatever part it holds
    /// (rows of per-instance tables), beyond the byte model's charge.
    fn scene_wide_bytes(&self, _scene: &Scene) -> u64 {
        0
    }

    /// Memory free on the device now; `None` where the device draws on
    /// host memory (no figure worth planning with).
    fn free_memory(&self) -> Option<u64> {
        None
    }

    /// Replaces the memory budget (`None`: what the device has).
    fn set_memory_budget(&mut self, bytes: Option<u64>);

    /// The paths in flight this kind of device renders best with.
    fn default_wave_size(&self) -> u32 {
        DEFAULT_WAVE_SIZE
    }

    // --- Sharing one piece of hardware ---

    /// Whether this device and `other` draw on the same memory (two
    /// devices on one GPU): they share its capacity, and one may use a
    /// scene the other prepared ([`Device::prepare_sharing`]).
    fn shares_memory_with(&self, _other: &dyn Device) -> bool {
        false
    }

    /// Prepares for `frame` over the scene `owner` (a device this one
    /// shares memory with, prepared for the same frame) holds: one copy
    /// of the scene serves both, each with its own queues and film.
    fn prepare_sharing(
        &mut self,
        _owner: &dyn Device,
        _frame: &Arc<FrameContext>,
    ) -> Result<PrepareStats, DeviceError> {
        Err(DeviceError::Unsupported { device: self.name(), what: "sharing another device's scene".into() })
    }

    /// Another device on the same hardware (on a GPU, another stream),
    /// with the same memory budget, not prepared: it can share this one's
    /// scene, and its work fills the gaps of this one's. `None` where that
    /// gains nothing (the CPU's threads are already all busy).
    fn another_on_same_hardware(&self) -> Option<Result<Box<dyn Device>, DeviceError>> {
        None
    }

    /// Measures busy time stage by stage instead of wave by wave: a ring
    /// member's stages are separated by waits for its neighbours, which a
    /// wave's time would count as work.
    fn time_stages(&mut self, _per_stage: bool) {}

    // --- Scene memory shared between devices ---

    /// The way devices of this kind share one chunked copy of the scene,
    /// where they can ([`crate::chunks`]).
    fn scene_sharing(&self) -> Option<Arc<dyn SceneSharing>> {
        None
    }

    /// From the next stage on, counts reads of each chunk of a shared
    /// scene (`false`: stops counting, keeping the counts).
    fn count_accesses(&mut self, _on: bool) -> Result<(), DeviceError> {
        Err(DeviceError::Unsupported { device: self.name(), what: "counting scene accesses".into() })
    }

    /// Reads per chunk of a shared scene counted since it was prepared or
    /// placed anew: the prepass's statistics.
    fn access_counts(&self) -> Result<Vec<u64>, DeviceError> {
        Err(DeviceError::Unsupported { device: self.name(), what: "counting scene accesses".into() })
    }

    // --- Moving queues ---

    /// A way to move queues between devices of this kind without the host
    /// (GPU peer copies), where there is one.
    fn direct_transport(&self) -> Option<Arc<dyn DirectTransport>> {
        None
    }

    /// A way to move queues to devices of other processes without the
    /// host (NCCL between GPUs), where there is one.
    fn process_transport(&self) -> Option<Arc<dyn ProcessTransport>> {
        None
    }

    /// The concrete device, for the device crate's own use (a transport or
    /// a scene shared between devices of one kind). Strategies do not cast.
    fn as_any(&self) -> &dyn Any;

    /// See [`Device::as_any`].
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

/// Host memory the OS says is available now (`None` where it does not say).
pub fn host_memory_available() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = meminfo.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}
