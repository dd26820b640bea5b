//! A chunk window: chunked scene memory that every GPU of a group sees as
//! one plain address range, built with the CUDA virtual memory API (the
//! shared strategy of Jaroš et al. 2021).
//!
//! Each GPU reserves its own virtual range of `chunks × chunk_bytes` and
//! maps every chunk slot to a physical allocation (`cuMemCreate`): its own
//! copy of a replicated chunk, the owner's allocation of an owned chunk
//! (read over NVLink through the peer mapping when the owner is another
//! GPU), or the one host allocation of a host chunk (read over PCIe).
//! Kernels take the range's base as an ordinary pointer and never know
//! where a chunk lives. A range per GPU, rather than one shared range,
//! because replicated chunks map to a different allocation on each GPU.
//!
//! Host chunks are pinned host allocations made by `cuMemCreate` too, not
//! managed memory: oversubscribed managed memory can hang the GPU.
//!
//! Physical allocations are reference counted by the ranges that map them,
//! so [`ChunkWindow::replace`] keeps the allocations of chunks that stay
//! where they are and keeps each GPU's base address: pointers handed to
//! kernels stay valid across a replacement.

use std::collections::{BTreeSet, HashMap, HashSet};
use std::sync::Arc;

use atoll_render::chunks::ChunkTable;
use atoll_render::{ChunkHome, ChunkLayout, ChunkPlacement, Residency};
use cudarc::driver::sys;

use crate::error::{fmt_bytes, CudaError};
use crate::gpu::Gpu;

/// Where one physical copy of a chunk lives.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Holder {
    /// In the memory of the window's GPU `.0` (an index into its GPU list).
    Gpu(usize),
    Host,
}

/// One physical allocation a placement needs: chunk `chunk`'s copy on `holder`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct Allocation {
    chunk: usize,
    holder: Holder,
}

/// The physical allocations and per-GPU mappings of a placement, worked
/// out before anything is allocated.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Plan {
    /// Chunk by chunk; a replicated chunk's copies GPU by GPU.
    allocations: Vec<Allocation>,
    /// Per GPU, per chunk: the index into `allocations` its range maps there.
    mappings: Vec<Vec<usize>>,
}

impl Plan {
    fn new(placement: &ChunkPlacement, gpus: usize) -> Result<Plan, CudaError> {
        if gpus == 0 {
            return Err(CudaError::Usage("a chunk window needs at least one GPU".into()));
        }
        if placement.homes.is_empty() {
            return Err(CudaError::Usage("a chunk window needs at least one chunk".into()));
        }
        let mut allocations = Vec::new();
        let mut mappings = vec![Vec::with_capacity(placement.homes.len()); gpus];
        for (chunk, &home) in placement.homes.iter().enumerate() {
            let shared = match home {
                ChunkHome::Replicated => {
                    for (gpu, mapping) in mappings.iter_mut().enumerate() {
                        mapping.push(allocations.len());
                        allocations.push(Allocation { chunk, holder: Holder::Gpu(gpu) });
                    }
                    continue;
                }
                ChunkHome::Device(d) if d as usize >= gpus => {
                    return Err(CudaError::Usage(format!(
                        "chunk {chunk} is placed on device {d}, but the window has {gpus} GPU(s)"
                    )));
                }
                ChunkHome::Device(d) => Holder::Gpu(d as usize),
                ChunkHome::Host => Holder::Host,
            };
            for mapping in &mut mappings {
                mapping.push(allocations.len());
            }
            allocations.push(Allocation { chunk, holder: shared });
        }
        Ok(Plan { allocations, mappings })
    }

    /// (reader, owner) pairs of distinct GPUs where the reader's range maps
    /// memory of the owner.
    fn peer_pairs(&self) -> BTreeSet<(usize, usize)> {
        let mut pairs = BTreeSet::new();
        for (reader, mapping) in self.mappings.iter().enumerate() {
            for &a in mapping {
                if let Holder::Gpu(owner) = self.allocations[a].holder {
                    if owner != reader {
                        pairs.insert((reader, owner));
                    }
                }
            }
        }
        pairs
    }
}

/// What a placement puts on each GPU and in host memory, in whole chunks
/// of the window's (rounded) size.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WindowMemory {
    /// Per GPU of the window, in its order.
    pub gpus: Vec<Residency>,
    /// Bytes in host memory (one copy, read by every GPU).
    pub host: u64,
}

impl WindowMemory {
    /// The memory of `placement` over `gpus` GPUs with chunks of `chunk_bytes`.
    pub fn new(placement: &ChunkPlacement, chunk_bytes: u64, gpus: usize) -> Self {
        // Physical allocations are whole chunks: a layout of equal chunks.
        let layout = ChunkLayout {
            chunk_bytes,
            tables: vec![ChunkTable {
                name: "window".into(),
                offset: 0,
                bytes: chunk_bytes * placement.homes.len() as u64,
            }],
        };
        let gpus: Vec<Residency> = (0..gpus).map(|g| placement.residency(&layout, g)).collect();
        let host = gpus.first().map_or(0, |r| r.host);
        WindowMemory { gpus, host }
    }

    /// `Err(OutOfMemory)` for the first GPU whose budget or free memory
    /// its local chunks exceed. Per GPU of the window: its label, budget
    /// (`None`: no budget), ordinal, the free memory of that ordinal, and
    /// the bytes of it the window already holds and keeps (a replacement
    /// keeps unmoved chunks), which need no free memory. GPU handles on one
    /// ordinal share its free memory.
    fn check(&self, gpus: &[GpuMemory]) -> Result<(), CudaError> {
        let mut new_on_ordinal: HashMap<usize, u64> = HashMap::new();
        for (r, gpu) in self.gpus.iter().zip(gpus) {
            *new_on_ordinal.entry(gpu.ordinal).or_default() += r.local().saturating_sub(gpu.kept);
        }
        for (r, gpu) in self.gpus.iter().zip(gpus) {
            let needed = r.local();
            let budget = gpu.budget.unwrap_or(u64::MAX);
            // What the window may hold here: what it keeps, plus the free
            // memory that the ordinal's other handles do not take first.
            let others = new_on_ordinal[&gpu.ordinal] - needed.saturating_sub(gpu.kept);
            let available = gpu.free.saturating_sub(others).saturating_add(gpu.kept);
            if needed > budget || needed > available {
                return Err(CudaError::OutOfMemory {
                    device: gpu.label.clone(),
                    what: format!(
                        "chunk window: {} replicated and {} owned chunk bytes",
                        fmt_bytes(r.replicated),
                        fmt_bytes(r.owned)
                    ),
                    needed,
                    budget,
                    free: available,
                });
            }
        }
        Ok(())
    }
}

/// One GPU's side of a memory check ([`WindowMemory::check`]).
#[derive(Clone, Debug)]
struct GpuMemory {
    label: String,
    ordinal: usize,
    budget: Option<u64>,
    free: u64,
    kept: u64,
}

/// `requested` bytes rounded up to a whole number of `granularity` (at least one).
fn round_chunk(requested: u64, granularity: u64) -> u64 {
    requested.max(1).next_multiple_of(granularity.max(1))
}

/// A pinned allocation's properties at `location`.
fn allocation_prop(location: sys::CUmemLocation) -> sys::CUmemAllocationProp {
    // SAFETY: a plain C struct for which all zeroes is valid: no exported
    // handle types, no flags, a null Windows metadata pointer.
    let mut prop: sys::CUmemAllocationProp = unsafe { std::mem::zeroed() };
    prop.type_ = sys::CUmemAllocationType::CU_MEM_ALLOCATION_TYPE_PINNED;
    prop.requestedHandleTypes = sys::CUmemAllocationHandleType::CU_MEM_HANDLE_TYPE_NONE;
    prop.location = location;
    prop
}

fn device_location(gpu: &Gpu) -> sys::CUmemLocation {
    sys::CUmemLocation { type_: sys::CUmemLocationType::CU_MEM_LOCATION_TYPE_DEVICE, id: gpu.ordinal as i32 }
}

/// Where host chunks are allocated, in the order to try: the NUMA node
/// nearest `gpu`, then plain host memory (drivers without NUMA-aware
/// host allocations accept only that).
fn host_locations(gpu: &Gpu) -> [sys::CUmemLocation; 2] {
    let mut numa = -1;
    // SAFETY: an attribute query into a local out-parameter.
    let queried = unsafe {
        sys::cuDeviceGetAttribute(
            &mut numa,
            sys::CUdevice_attribute::CU_DEVICE_ATTRIBUTE_HOST_NUMA_ID,
            gpu.ctx.cu_device(),
        )
    };
    // -1 (or a failed query) means the GPU names no node: take node 0.
    let node = if queried == sys::CUresult::CUDA_SUCCESS && numa >= 0 { numa } else { 0 };
    [
        sys::CUmemLocation { type_: sys::CUmemLocationType::CU_MEM_LOCATION_TYPE_HOST_NUMA, id: node },
        sys::CUmemLocation { type_: sys::CUmemLocationType::CU_MEM_LOCATION_TYPE_HOST, id: 0 },
    ]
}

/// The recommended allocation granularity at `location`.
fn granularity_at(location: sys::CUmemLocation) -> Result<u64, sys::CUresult> {
    let prop = allocation_prop(location);
    let mut granularity = 0usize;
    // SAFETY: `prop` and the out-parameter live across the call.
    let r = unsafe {
        sys::cuMemGetAllocationGranularity(
            &mut granularity,
            &prop,
            sys::CUmemAllocationGranularity_flags::CU_MEM_ALLOC_GRANULARITY_RECOMMENDED,
        )
    };
    match r {
        sys::CUresult::CUDA_SUCCESS => Ok(granularity as u64),
        e => Err(e),
    }
}

/// The chunk granularity for `gpus`: the largest recommended granularity
/// of their memories and of host memory (all powers of two, so every one
/// divides it). Host memory that takes no VMM allocations is left out:
/// host chunks then fail when created, with the driver's error.
fn granularity(gpus: &[Arc<Gpu>]) -> Result<u64, CudaError> {
    let mut largest = 1u64;
    for gpu in gpus {
        bind(gpu)?;
        let g = granularity_at(device_location(gpu)).map_err(|e| CudaError::Driver {
            context: format!("{}: reading the memory allocation granularity", gpu.label()),
            source: cudarc::driver::DriverError(e),
        })?;
        largest = largest.max(g);
    }
    if let Some(first) = gpus.first() {
        if let Some(g) = host_locations(first).into_iter().find_map(|l| granularity_at(l).ok()) {
            largest = largest.max(g);
        }
    }
    Ok(largest)
}

/// Makes `gpu`'s context current on this thread (driver calls act on it).
fn bind(gpu: &Gpu) -> Result<(), CudaError> {
    gpu.ctx.bind_to_thread().map_err(CudaError::driver(format!("{}: binding the context", gpu.label())))
}

/// `Err(NoPeerAccess)` for the first pair of `plan` whose reader cannot
/// map the owner's memory.
fn check_peers(gpus: &[Arc<Gpu>], plan: &Plan) -> Result<(), CudaError> {
    for (reader, owner) in plan.peer_pairs() {
        let (r, o) = (&gpus[reader], &gpus[owner]);
        if r.ordinal != o.ordinal && !peer_access(r, o)? {
            return Err(CudaError::NoPeerAccess { reader: r.label(), owner: o.label() });
        }
    }
    Ok(())
}

/// Whether `reader` can map `owner`'s memory.
fn peer_access(reader: &Gpu, owner: &Gpu) -> Result<bool, CudaError> {
    let mut can = 0;
    // SAFETY: a query of two device handles into a local out-parameter.
    unsafe { sys::cuDeviceCanAccessPeer(&mut can, reader.ctx.cu_device(), owner.ctx.cu_device()) }
        .result()
        .map_err(CudaError::driver(format!("{}: asking for peer access to {}", reader.label(), owner.label())))?;
    Ok(can != 0)
}

/// Whether `a` and `b` can each map the other's memory (false where the
/// driver cannot say).
pub fn can_access_peer(a: &Gpu, b: &Gpu) -> bool {
    matches!((peer_access(a, b), peer_access(b, a)), (Ok(true), Ok(true)))
}

/// One physical allocation (`cuMemCreate`), shared by the ranges that map
/// it. Released when the last one drops it; the driver frees the memory
/// once it is also unmapped everywhere.
struct Physical {
    handle: sys::CUmemGenericAllocationHandle,
    allocation: Allocation,
    /// A context to make current for the release.
    gpu: Arc<Gpu>,
}

impl Physical {
    /// `allocation`'s memory, `bytes` long (a multiple of the granularity).
    fn create(
        gpus: &[Arc<Gpu>],
        allocation: Allocation,
        bytes: u64,
        host: &[sys::CUmemLocation; 2],
    ) -> Result<Physical, CudaError> {
        let (gpu, locations) = match allocation.holder {
            Holder::Gpu(g) => (&gpus[g], vec![device_location(&gpus[g])]),
            Holder::Host => (&gpus[0], host.to_vec()),
        };
        bind(gpu)?;
        let mut last = sys::CUresult::CUDA_SUCCESS;
        for location in locations {
            let prop = allocation_prop(location);
            let mut handle: sys::CUmemGenericAllocationHandle = 0;
            // SAFETY: `prop` and the out-parameter live across the call; a
            // handle it returns is owned by the `Physical` made from it.
            last = unsafe { sys::cuMemCreate(&mut handle, bytes as usize, &prop, 0) };
            if last == sys::CUresult::CUDA_SUCCESS {
                return Ok(Physical { handle, allocation, gpu: gpu.clone() });
            }
        }
        let place = match allocation.holder {
            Holder::Gpu(_) => gpu.label(),
            Holder::Host => "host memory".into(),
        };
        Err(CudaError::Driver {
            context: format!("allocating {} for chunk {} in {place}", fmt_bytes(bytes), allocation.chunk),
            source: cudarc::driver::DriverError(last),
        })
    }
}

impl Drop for Physical {
    fn drop(&mut self) {
        if bind(&self.gpu).is_err() {
            tracing::warn!("{}: cannot bind the context to release a chunk allocation", self.gpu.label());
        }
        // SAFETY: the handle came from cuMemCreate and is released once, here.
        let r = unsafe { sys::cuMemRelease(self.handle) };
        if r != sys::CUresult::CUDA_SUCCESS {
            tracing::warn!("{}: releasing a chunk allocation: {r:?}", self.gpu.label());
        }
    }
}

/// One GPU's reserved virtual range: chunk slots, each mapped to a
/// physical allocation with read/write access for that GPU.
struct Range {
    gpu: Arc<Gpu>,
    base: sys::CUdeviceptr,
    chunk_bytes: u64,
    /// What each slot maps; `None` for an unmapped slot.
    slots: Vec<Option<Arc<Physical>>>,
}

impl Range {
    fn reserve(gpu: &Arc<Gpu>, chunk_bytes: u64, slots: usize) -> Result<Range, CudaError> {
        bind(gpu)?;
        let mut base: sys::CUdeviceptr = 0;
        let bytes = chunk_bytes * slots as u64;
        // SAFETY: an out-parameter; alignment 0 and no fixed address leave
        // the choice to the driver. The range is freed by `Drop`.
        unsafe { sys::cuMemAddressReserve(&mut base, bytes as usize, 0, 0, 0) }.result().map_err(
            CudaError::driver(format!("{}: reserving {} of address space", gpu.label(), fmt_bytes(bytes))),
        )?;
        Ok(Range { gpu: gpu.clone(), base, chunk_bytes, slots: vec![None; slots] })
    }

    fn addr(&self, slot: usize) -> u64 {
        self.base + slot as u64 * self.chunk_bytes
    }

    /// Maps `physical` at empty slot `slot`, readable and writable by this GPU.
    fn map(&mut self, slot: usize, physical: Arc<Physical>) -> Result<(), CudaError> {
        debug_assert!(self.slots[slot].is_none());
        bind(&self.gpu)?;
        let what = |w: &str| format!("{}: {w} chunk {} of a window", self.gpu.label(), slot);
        let (addr, bytes) = (self.addr(slot), self.chunk_bytes as usize);
        // SAFETY: `addr..addr+bytes` is an unmapped slot of this reserved
        // range, and the allocation is `bytes` long (every allocation of a
        // window is one chunk).
        unsafe { sys::cuMemMap(addr, bytes, 0, physical.handle, 0) }
            .result()
            .map_err(CudaError::driver(what("mapping")))?;
        // Mapped from here on: `Drop` unmaps it even if the grant fails.
        self.slots[slot] = Some(physical);
        let access = sys::CUmemAccessDesc {
            location: device_location(&self.gpu),
            flags: sys::CUmemAccess_flags::CU_MEM_ACCESS_FLAGS_PROT_READWRITE,
        };
        // SAFETY: `addr..addr+bytes` is mapped just above; `access` lives across the call.
        unsafe { sys::cuMemSetAccess(addr, bytes, &access, 1) }
            .result()
            .map_err(CudaError::driver(what("granting access to")))
    }

    /// Unmaps slot `slot` (nothing when it is not mapped).
    fn unmap(&mut self, slot: usize) -> Result<(), CudaError> {
        let Some(physical) = self.slots[slot].take() else { return Ok(()) };
        bind(&self.gpu)?;
        // SAFETY: the slot is exactly one mapping made by `map`.
        let r = unsafe { sys::cuMemUnmap(self.addr(slot), self.chunk_bytes as usize) };
        if r != sys::CUresult::CUDA_SUCCESS {
            // Still mapped: keep the allocation alive and try again in `Drop`.
            self.slots[slot] = Some(physical);
            return Err(CudaError::Driver {
                context: format!("{}: unmapping chunk {slot} of a window", self.gpu.label()),
                source: cudarc::driver::DriverError(r),
            });
        }
        Ok(())
    }
}

impl Drop for Range {
    fn drop(&mut self) {
        let label = self.gpu.label();
        // Work still queued on this GPU may read through the range: let it
        // finish before the memory goes.
        if let Err(e) = bind(&self.gpu).and_then(|()| {
            self.gpu.ctx.synchronize().map_err(CudaError::driver(format!("{label}: synchronizing")))
        }) {
            tracing::warn!("freeing a chunk window: {e}");
        }
        for slot in 0..self.slots.len() {
            if let Err(e) = self.unmap(slot) {
                tracing::warn!("freeing a chunk window: {e}");
            }
        }
        let bytes = self.chunk_bytes as usize * self.slots.len();
        // SAFETY: the range came from cuMemAddressReserve with this size and
        // nothing in it is mapped any more (a failed unmap is logged above).
        let r = unsafe { sys::cuMemAddressFree(self.base, bytes) };
        if r != sys::CUresult::CUDA_SUCCESS {
            tracing::warn!("{label}: freeing a chunk window's address range: {r:?}");
        }
    }
}

/// Scene memory in chunks that each GPU of a group reads through its own
/// plain address range (see the module docs).
pub struct ChunkWindow {
    gpus: Vec<Arc<Gpu>>,
    chunk_bytes: u64,
    placement: ChunkPlacement,
    /// Where host chunks are allocated, in the order to try.
    host: [sys::CUmemLocation; 2],
    /// Per GPU, in `gpus`' order.
    ranges: Vec<Range>,
    /// False after a replacement failed half-way through remapping.
    intact: bool,
}

impl ChunkWindow {
    /// The chunk size a window over `gpus` uses for `requested` bytes:
    /// rounded up to the allocation granularity of every GPU and of host
    /// memory. Lay the scene out with this size, so that chunk boundaries
    /// fall where the window's do.
    pub fn chunk_bytes_for(gpus: &[Arc<Gpu>], requested: u64) -> Result<u64, CudaError> {
        Ok(round_chunk(requested, granularity(gpus)?))
    }

    /// What `placement` would put on each GPU of `gpus` and in host memory,
    /// with chunks of `chunk_bytes` rounded as [`ChunkWindow::chunk_bytes_for`]
    /// does; `Err(OutOfMemory)` where a GPU's budget (`budgets[i]` for
    /// `gpus[i]`, none past the end) or free memory would be exceeded.
    /// Allocates nothing: [`ChunkWindow::new`] runs the same check first.
    pub fn check_memory(
        gpus: &[Arc<Gpu>],
        chunk_bytes: u64,
        placement: &ChunkPlacement,
        budgets: &[Option<u64>],
    ) -> Result<WindowMemory, CudaError> {
        let chunk_bytes = Self::chunk_bytes_for(gpus, chunk_bytes)?;
        check_fit(gpus, chunk_bytes, placement, budgets, &vec![0; gpus.len()])
    }

    /// A window over `gpus` (GPU `i` is device `i` of `placement`) of
    /// `placement.homes.len()` chunks of `chunk_bytes` (rounded up as
    /// [`ChunkWindow::chunk_bytes_for`] does), placed as `placement` says.
    /// Checks memory ([`ChunkWindow::check_memory`]) and peer access
    /// (`Err(NoPeerAccess)` naming the first pair without it) before
    /// allocating. The contents start undefined.
    pub fn new(
        gpus: &[Arc<Gpu>],
        chunk_bytes: u64,
        placement: &ChunkPlacement,
        budgets: &[Option<u64>],
    ) -> Result<ChunkWindow, CudaError> {
        let plan = Plan::new(placement, gpus.len())?;
        let chunk_bytes = Self::chunk_bytes_for(gpus, chunk_bytes)?;
        check_fit(gpus, chunk_bytes, placement, budgets, &vec![0; gpus.len()])?;
        check_peers(gpus, &plan)?;
        let host = host_locations(&gpus[0]);
        let physical = plan
            .allocations
            .iter()
            .map(|&a| Physical::create(gpus, a, chunk_bytes, &host).map(Arc::new))
            .collect::<Result<Vec<_>, _>>()?;
        let mut ranges = Vec::with_capacity(gpus.len());
        for (gpu, mapping) in gpus.iter().zip(&plan.mappings) {
            let mut range = Range::reserve(gpu, chunk_bytes, mapping.len())?;
            for (slot, &a) in mapping.iter().enumerate() {
                range.map(slot, physical[a].clone())?;
            }
            ranges.push(range);
        }
        Ok(ChunkWindow {
            gpus: gpus.to_vec(),
            chunk_bytes,
            placement: placement.clone(),
            host,
            ranges,
            intact: true,
        })
    }

    /// Bytes of one chunk (the granularity-rounded size).
    pub fn chunk_bytes(&self) -> u64 {
        self.chunk_bytes
    }

    /// Bytes of the whole window.
    pub fn bytes(&self) -> u64 {
        self.chunk_bytes * self.placement.homes.len() as u64
    }

    pub fn placement(&self) -> &ChunkPlacement {
        &self.placement
    }

    /// The device pointer of GPU `gpu`'s range (valid on that GPU only, and
    /// unchanged by [`ChunkWindow::replace`]). Panics if `gpu` is not an
    /// index into the window's GPUs.
    pub fn base(&self, gpu: usize) -> u64 {
        self.ranges[gpu].base
    }

    /// What GPU `gpu` holds and reads from elsewhere, in whole chunks.
    /// Panics if `gpu` is not an index into the window's GPUs.
    pub fn residency(&self, gpu: usize) -> Residency {
        self.memory().gpus[gpu]
    }

    /// What every GPU and the host hold, in whole chunks.
    pub fn memory(&self) -> WindowMemory {
        WindowMemory::new(&self.placement, self.chunk_bytes, self.gpus.len())
    }

    /// Copies `bytes` to window offset `offset`, into every physical copy
    /// (each replica of a replicated chunk); returns once they have landed.
    pub fn write(&self, offset: u64, bytes: &[u8]) -> Result<(), CudaError> {
        self.check_span(offset, bytes.len() as u64)?;
        let mut used = vec![false; self.gpus.len()];
        for (chunk, start, piece) in self.pieces(offset, bytes.len() as u64) {
            let src = &bytes[piece];
            // A GPU whose range maps each copy: every GPU for a replicated
            // chunk, else the owner (a local write) or GPU 0 for the host.
            let writers = match self.placement.homes[chunk] {
                ChunkHome::Replicated => 0..self.gpus.len(),
                ChunkHome::Device(d) => d as usize..d as usize + 1,
                ChunkHome::Host => 0..1,
            };
            for g in writers {
                let gpu = &self.gpus[g];
                bind(gpu)?;
                // SAFETY: the destination lies inside chunk `chunk` of this
                // GPU's range (checked by `check_span`), mapped with access
                // for it; `src` outlives the copy (the stream is synchronized
                // below before returning).
                unsafe {
                    sys::cuMemcpyHtoDAsync_v2(
                        self.ranges[g].addr(chunk) + start,
                        src.as_ptr().cast(),
                        src.len(),
                        gpu.stream.cu_stream(),
                    )
                }
                .result()
                .map_err(CudaError::driver(format!(
                    "{}: writing to chunk {chunk} of a window",
                    gpu.label()
                )))?;
                atoll_scene::progress::copied(src.len() as u64);
                used[g] = true;
            }
        }
        for (gpu, _) in self.gpus.iter().zip(used).filter(|(_, used)| *used) {
            gpu.synchronize()?;
        }
        Ok(())
    }

    /// `len` bytes from window offset `offset`, read through GPU `gpu`'s
    /// range (so from wherever that GPU reads each chunk).
    pub fn read(&self, gpu: usize, offset: u64, len: u64) -> Result<Vec<u8>, CudaError> {
        self.check_span(offset, len)?;
        let g = self.gpus.get(gpu).ok_or_else(|| {
            CudaError::Usage(format!("the window has {} GPU(s), not {}", self.gpus.len(), gpu + 1))
        })?;
        bind(g)?;
        let mut out = vec![0u8; len as usize];
        for (chunk, start, piece) in self.pieces(offset, len) {
            let dst = &mut out[piece];
            // SAFETY: the source lies inside chunk `chunk` of this GPU's
            // range, mapped with access for it; `dst` is a live buffer of the
            // copy's length, not touched until the stream is synchronized.
            unsafe {
                sys::cuMemcpyDtoHAsync_v2(
                    dst.as_mut_ptr().cast(),
                    self.ranges[gpu].addr(chunk) + start,
                    dst.len(),
                    g.stream.cu_stream(),
                )
            }
            .result()
            .map_err(CudaError::driver(format!("{}: reading chunk {chunk} of a window", g.label())))?;
        }
        g.synchronize()?;
        Ok(out)
    }

    /// Moves the chunks to `placement` (of as many chunks), keeping their
    /// contents and every GPU's base address. Chunks that stay where they
    /// are keep their memory; the others get new allocations, filled from
    /// the current window, before the ranges are remapped and the old
    /// memory freed. Memory and peer access are checked first, counting
    /// what stays. Waits for work queued on the GPUs. An error before the
    /// remapping leaves the window as it was; one during it (a driver
    /// failure) leaves it unusable.
    pub fn replace(&mut self, placement: &ChunkPlacement, budgets: &[Option<u64>]) -> Result<(), CudaError> {
        self.check_intact()?;
        if placement.homes.len() != self.placement.homes.len() {
            return Err(CudaError::Usage(format!(
                "a window of {} chunks cannot take a placement of {}",
                self.placement.homes.len(),
                placement.homes.len()
            )));
        }
        let plan = Plan::new(placement, self.gpus.len())?;
        let current: HashMap<Allocation, Arc<Physical>> = self
            .ranges
            .iter()
            .flat_map(|r| r.slots.iter().flatten())
            .map(|p| (p.allocation, p.clone()))
            .collect();
        let mut kept = vec![0; self.gpus.len()];
        for a in &plan.allocations {
            if let (Holder::Gpu(g), true) = (a.holder, current.contains_key(a)) {
                kept[g] += self.chunk_bytes;
            }
        }
        check_fit(&self.gpus, self.chunk_bytes, placement, budgets, &kept)?;
        check_peers(&self.gpus, &plan)?;
        let physical = plan
            .allocations
            .iter()
            .map(|a| match current.get(a) {
                Some(p) => Ok(p.clone()),
                None => Physical::create(&self.gpus, *a, self.chunk_bytes, &self.host).map(Arc::new),
            })
            .collect::<Result<Vec<_>, _>>()?;
        drop(current);
        self.fill(&plan, &physical)?;
        // No kernel may read a slot while it changes.
        for gpu in &self.gpus {
            bind(gpu)?;
            gpu.ctx.synchronize().map_err(CudaError::driver(format!("{}: synchronizing", gpu.label())))?;
        }
        // Remap the slots whose allocation changed. From here a failure
        // leaves some slots on old chunks or unmapped.
        self.intact = false;
        for (range, mapping) in self.ranges.iter_mut().zip(&plan.mappings) {
            for (slot, &a) in mapping.iter().enumerate() {
                let same = range.slots[slot].as_ref().is_some_and(|p| Arc::ptr_eq(p, &physical[a]));
                if !same {
                    range.unmap(slot)?;
                    range.map(slot, physical[a].clone())?;
                }
            }
        }
        self.intact = true;
        self.placement = placement.clone();
        Ok(())
    }

    /// Copies into each new allocation of `physical` (those no range maps
    /// yet) its chunk's current contents, through the range of a GPU that
    /// will map it: its holder, or GPU 0 for host memory. The new
    /// allocations are mapped into a staging range of that GPU for the copy.
    fn fill(&self, plan: &Plan, physical: &[Arc<Physical>]) -> Result<(), CudaError> {
        let mapped: HashSet<*const Physical> =
            self.ranges.iter().flat_map(|r| r.slots.iter().flatten()).map(Arc::as_ptr).collect();
        let mut per_gpu: Vec<Vec<usize>> = vec![Vec::new(); self.gpus.len()];
        for (i, a) in plan.allocations.iter().enumerate() {
            if !mapped.contains(&Arc::as_ptr(&physical[i])) {
                let filler = match a.holder {
                    Holder::Gpu(g) => g,
                    Holder::Host => 0,
                };
                per_gpu[filler].push(i);
            }
        }
        let mut staging = Vec::new();
        for (g, news) in per_gpu.iter().enumerate().filter(|(_, news)| !news.is_empty()) {
            let gpu = &self.gpus[g];
            let mut range = Range::reserve(gpu, self.chunk_bytes, news.len())?;
            for (slot, &i) in news.iter().enumerate() {
                range.map(slot, physical[i].clone())?;
                let chunk = plan.allocations[i].chunk;
                bind(gpu)?;
                // SAFETY: both addresses are whole mapped chunks of ranges of
                // this GPU with access for it; the copy is waited for below,
                // before the staging range is dropped.
                unsafe {
                    sys::cuMemcpyDtoDAsync_v2(
                        range.addr(slot),
                        self.ranges[g].addr(chunk),
                        self.chunk_bytes as usize,
                        gpu.stream.cu_stream(),
                    )
                }
                .result()
                .map_err(CudaError::driver(format!("{}: moving chunk {chunk} of a window", gpu.label())))?;
            }
            staging.push(range);
        }
        // Dropping the staging ranges waits for the copies.
        for range in &staging {
            range.gpu.synchronize()?;
        }
        Ok(())
    }

    /// `(chunk, offset in chunk, range in the caller's buffer)` for each
    /// chunk that bytes `offset..offset+len` of the window touch.
    fn pieces(
        &self,
        offset: u64,
        len: u64,
    ) -> impl Iterator<Item = (usize, u64, std::ops::Range<usize>)> + '_ {
        let end = offset + len;
        let mut at = offset;
        std::iter::from_fn(move || {
            if at >= end {
                return None;
            }
            let chunk = at / self.chunk_bytes;
            let start = at % self.chunk_bytes;
            let n = (self.chunk_bytes - start).min(end - at);
            let piece = ((at - offset) as usize, (at - offset + n) as usize);
            at += n;
            Some((chunk as usize, start, piece.0..piece.1))
        })
    }

    /// `Err(Usage)` unless `offset..offset+len` lies inside the window (and
    /// the window is intact).
    fn check_span(&self, offset: u64, len: u64) -> Result<(), CudaError> {
        self.check_intact()?;
        match offset.checked_add(len) {
            Some(end) if end <= self.bytes() => Ok(()),
            _ => Err(CudaError::Usage(format!(
                "bytes {offset}..+{len} are outside a chunk window of {} bytes",
                self.bytes()
            ))),
        }
    }

    fn check_intact(&self) -> Result<(), CudaError> {
        if self.intact {
            Ok(())
        } else {
            Err(CudaError::Usage("the chunk window was left unusable by a failed replacement".into()))
        }
    }
}

/// [`WindowMemory::new`] checked against `gpus`' budgets and free memory
/// (`kept[i]`: bytes on `gpus[i]` the window already holds and keeps).
fn check_fit(
    gpus: &[Arc<Gpu>],
    chunk_bytes: u64,
    placement: &ChunkPlacement,
    budgets: &[Option<u64>],
    kept: &[u64],
) -> Result<WindowMemory, CudaError> {
    let memory = WindowMemory::new(placement, chunk_bytes, gpus.len());
    let sides = gpus
        .iter()
        .enumerate()
        .map(|(i, gpu)| {
            Ok(GpuMemory {
                label: gpu.label(),
                ordinal: gpu.ordinal,
                budget: budgets.get(i).copied().flatten(),
                free: gpu.free_memory()?,
                kept: kept[i],
            })
        })
        .collect::<Result<Vec<_>, CudaError>>()?;
    memory.check(&sides)?;
    Ok(memory)
}

#[cfg(test)]
mod tests {
    use super::*;

    const MIB: u64 = 1 << 20;

    fn placement(homes: &[ChunkHome]) -> ChunkPlacement {
        ChunkPlacement { homes: homes.to_vec() }
    }

    fn side(label: &str, ordinal: usize, budget: Option<u64>, free: u64, kept: u64) -> GpuMemory {
        GpuMemory { label: label.into(), ordinal, budget, free, kept }
    }

    #[test]
    fn plan_allocates_once_per_chunk_and_holder() {
        use ChunkHome::*;
        let p = placement(&[Replicated, Device(1), Host, Device(0)]);
        let plan = Plan::new(&p, 2).unwrap();
        let holders: Vec<(usize, Holder)> = plan.allocations.iter().map(|a| (a.chunk, a.holder)).collect();
        assert_eq!(
            holders,
            [
                (0, Holder::Gpu(0)),
                (0, Holder::Gpu(1)),
                (1, Holder::Gpu(1)),
                (2, Holder::Host),
                (3, Holder::Gpu(0)),
            ]
        );
        // Each GPU maps its own replica, and the one copy of everything else.
        assert_eq!(plan.mappings, [vec![0, 2, 3, 4], vec![1, 2, 3, 4]]);
        assert_eq!(plan.peer_pairs().into_iter().collect::<Vec<_>>(), [(0, 1), (1, 0)]);
    }

    #[test]
    fn plan_needs_no_peers_without_owned_chunks_elsewhere() {
        use ChunkHome::*;
        let plan = Plan::new(&placement(&[Replicated, Host, Host]), 3).unwrap();
        assert!(plan.peer_pairs().is_empty());
        assert_eq!(plan.allocations.len(), 5);
        let one = Plan::new(&placement(&[Device(0), Host]), 1).unwrap();
        assert!(one.peer_pairs().is_empty());
    }

    #[test]
    fn plan_rejects_what_cannot_be_mapped() {
        use ChunkHome::*;
        assert!(matches!(Plan::new(&placement(&[Device(2)]), 2), Err(CudaError::Usage(_))));
        assert!(matches!(Plan::new(&placement(&[]), 2), Err(CudaError::Usage(_))));
        assert!(matches!(Plan::new(&placement(&[Host]), 0), Err(CudaError::Usage(_))));
    }

    #[test]
    fn chunks_round_up_to_the_granularity() {
        assert_eq!(round_chunk(1, 2 * MIB), 2 * MIB);
        assert_eq!(round_chunk(2 * MIB, 2 * MIB), 2 * MIB);
        assert_eq!(round_chunk(2 * MIB + 1, 2 * MIB), 4 * MIB);
        assert_eq!(round_chunk(0, 2 * MIB), 2 * MIB);
    }

    #[test]
    fn memory_counts_whole_chunks_per_gpu_and_host() {
        use ChunkHome::*;
        let p = placement(&[Replicated, Device(1), Host, Device(0), Device(1)]);
        let m = WindowMemory::new(&p, 2 * MIB, 2);
        assert_eq!(
            m.gpus[0],
            Residency { replicated: 2 * MIB, owned: 2 * MIB, remote: 4 * MIB, host: 2 * MIB }
        );
        assert_eq!(
            m.gpus[1],
            Residency { replicated: 2 * MIB, owned: 4 * MIB, remote: 2 * MIB, host: 2 * MIB }
        );
        assert_eq!(m.host, 2 * MIB);
    }

    #[test]
    fn budgets_and_free_memory_refuse_before_allocating() {
        use ChunkHome::*;
        let p = placement(&[Replicated, Device(1), Device(1), Host]);
        let m = WindowMemory::new(&p, 2 * MIB, 2);
        let free = 1 << 40;
        // GPU 1 holds 6 MiB.
        assert!(m
            .check(&[side("cuda:0", 0, None, free, 0), side("cuda:1", 1, Some(6 * MIB), free, 0)])
            .is_ok());
        let e = m
            .check(&[side("cuda:0", 0, None, free, 0), side("cuda:1", 1, Some(5 * MIB), free, 0)])
            .unwrap_err();
        match e {
            CudaError::OutOfMemory { device, needed, budget, .. } => {
                assert_eq!((device.as_str(), needed, budget), ("cuda:1", 6 * MIB, 5 * MIB));
            }
            other => panic!("{other}"),
        }
        // Free memory: 4 MiB free is too little for 6 MiB, unless 2 MiB of it stay.
        let tight = [side("cuda:0", 0, None, free, 0), side("cuda:1", 1, None, 4 * MIB, 0)];
        assert!(matches!(m.check(&tight), Err(CudaError::OutOfMemory { .. })));
        let kept = [side("cuda:0", 0, None, free, 0), side("cuda:1", 1, None, 4 * MIB, 2 * MIB)];
        assert!(m.check(&kept).is_ok());
    }

    #[test]
    fn handles_on_one_gpu_share_its_free_memory() {
        use ChunkHome::*;
        // Two handles on ordinal 0, 4 MiB each, 6 MiB free: each fits alone, not both.
        let p = placement(&[Replicated, Device(0), Device(1)]);
        let m = WindowMemory::new(&p, 2 * MIB, 2);
        let one_gpu = [side("cuda:0", 0, None, 6 * MIB, 0), side("cuda:0", 0, None, 6 * MIB, 0)];
        assert!(matches!(m.check(&one_gpu), Err(CudaError::OutOfMemory { .. })));
        let two_gpus = [side("cuda:0", 0, None, 6 * MIB, 0), side("cuda:1", 1, None, 6 * MIB, 0)];
        assert!(m.check(&two_gpus).is_ok());
    }
}
