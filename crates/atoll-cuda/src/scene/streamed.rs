//! Meshes copied to the GPU while the scene is still loading
//! ([`atoll_scene::input::MeshSink`]): each mesh the loader makes goes at
//! once into one device arena, through a pool of page-locked buffers,
//! while the loader's other threads read the remaining files. The prepare
//! that follows makes the scene's large tables from the arena on the
//! device ([`super::gather`]) instead of writing and sending them from
//! the host, then frees the arena.
//!
//! A mesh is found again by where its arrays lie in host memory and by a
//! fingerprint of their ends: the loader moves each mesh into the scene as
//! it is, so its arrays keep their addresses; a mesh the arena has no room
//! for, or that is not found, is uploaded by the prepare as before.

use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

use cudarc::driver::{CudaEvent, CudaSlice, DevicePtr, DriverError, PinnedHostSlice};

use super::gather::MeshAddresses;
use crate::gpu::Gpu;
use atoll_scene::{SceneSizes, TriangleMesh};

/// Page-locked buffers the copies go through, and the bytes of each: a
/// few per loader thread, so that threads rarely wait for one another.
const STAGING_BUFFERS: usize = 16;
const STAGING_BYTES: usize = 16 << 20;

/// Room kept beside the arena and the scene's estimate for what is not
/// known before loading (queues, film, parameters).
const FRAME_ROOM: u64 = 1 << 30;

/// Byte alignment of each array in the arena.
const ALIGN: u64 = 256;

/// Where a mesh's arrays lie in host memory: how the prepare finds it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct MeshKey {
    positions: usize,
    vertices: usize,
    indices: usize,
    triangles: usize,
}

impl MeshKey {
    fn of(mesh: &TriangleMesh) -> Self {
        MeshKey {
            positions: mesh.positions.as_ptr() as usize,
            vertices: mesh.positions.len(),
            indices: mesh.indices.as_ptr() as usize,
            triangles: mesh.indices.len(),
        }
    }
}

/// The first and last vertex and triangle, and the optional arrays'
/// lengths: a mesh freed and another made at the same addresses would have
/// to match all of these too.
fn fingerprint(mesh: &TriangleMesh) -> [u32; 16] {
    let p = |v: Option<&glam::Vec3>| v.map_or([0; 3], |v| v.to_array().map(f32::to_bits));
    let t = |t: Option<&[u32; 3]>| t.copied().unwrap_or([u32::MAX; 3]);
    let [a, b, c, d] = [
        p(mesh.positions.first()),
        p(mesh.positions.last()),
        t(mesh.indices.first()),
        t(mesh.indices.last()),
    ];
    let mut f = [0; 16];
    for (i, w) in a.iter().chain(&b).chain(&c).chain(&d).enumerate() {
        f[i] = *w;
    }
    f[12] = mesh.normals.len() as u32;
    f[13] = mesh.uvs.len() as u32;
    f
}

/// A mesh in the arena.
#[derive(Clone, Copy, Debug)]
struct ArenaMesh {
    fingerprint: [u32; 16],
    at: MeshAddresses,
}

/// The device memory the meshes go to, and where each went.
struct Arena {
    memory: CudaSlice<u8>,
    base: u64,
    used: u64,
    meshes: HashMap<MeshKey, ArenaMesh>,
    /// Meshes it had no room for.
    missed: u64,
}

/// One page-locked buffer and the event after the copy that last read it.
struct Staging {
    buffer: PinnedHostSlice<u8>,
    done: CudaEvent,
}

/// A GPU's [`atoll_scene::input::MeshSink`].
pub struct MeshStream {
    gpu: Arc<Gpu>,
    budget: Option<u64>,
    arena: Mutex<Option<Arena>>,
    /// Made with the arena.
    staging: OnceLock<Vec<Mutex<Staging>>>,
    next_staging: AtomicUsize,
    /// The first error of a copy; the arena is then not used.
    failed: Mutex<Option<String>>,
}

/// The meshes a stream holds, taken for a prepare ([`MeshStream::take`]).
pub struct StreamedMeshes {
    arena: Arena,
}

impl StreamedMeshes {
    /// Where `mesh`'s arrays are on the device, if it was streamed.
    pub(crate) fn find(&self, mesh: &TriangleMesh) -> Option<MeshAddresses> {
        let found = self.arena.meshes.get(&MeshKey::of(mesh))?;
        (found.fingerprint == fingerprint(mesh)).then_some(found.at)
    }

    /// Device bytes the arena holds (freed with it).
    pub fn bytes(&self) -> u64 {
        self.arena.memory.len() as u64
    }

    /// How many meshes it holds, and how many it had no room for.
    pub fn counts(&self) -> (usize, u64) {
        (self.arena.meshes.len(), self.arena.missed)
    }
}

impl MeshStream {
    /// A stream to `gpu` that takes meshes only where the arena fits
    /// beside the scene's estimate within `budget` and free memory.
    pub fn new(gpu: Arc<Gpu>, budget: Option<u64>) -> Self {
        MeshStream {
            gpu,
            budget,
            arena: Mutex::new(None),
            staging: OnceLock::new(),
            next_staging: AtomicUsize::new(0),
            failed: Mutex::new(None),
        }
    }

    /// The meshes streamed so far, for the prepare of the loaded scene;
    /// `None` when nothing was (no room, a failed copy, or no load).
    pub fn take(&self) -> Option<StreamedMeshes> {
        let arena = lock(&self.arena).take()?;
        if let Some(why) = lock(&self.failed).take() {
            tracing::warn!("{}: meshes copied during the load are not used: {why}", self.gpu.label());
            return None;
        }
        Some(StreamedMeshes { arena })
    }

    fn fail(&self, why: String) {
        lock(&self.failed).get_or_insert(why);
    }

    /// Sets up the arena (and the staging buffers) for a scene of
    /// `sizes`, if it has room.
    fn open(&self, sizes: &SceneSizes) -> Result<Option<Arena>, DriverError> {
        // Quads give two triangles a face: room for some more than the
        // headers count, and each array's alignment.
        let bytes = sizes.geometry_bytes + sizes.geometry_bytes / 4 + (64 << 20);
        let needed = bytes + super::byte_model().bytes(sizes) + FRAME_ROOM;
        let free = self.gpu.free_memory().unwrap_or(0);
        let room = self.budget.map_or(free, |b| b.min(free));
        if needed > room {
            tracing::info!(
                "{}: meshes are uploaded after the load: streaming them needs {needed} bytes, {room} are free",
                self.gpu.label()
            );
            return Ok(None);
        }
        let mut staging = Vec::with_capacity(STAGING_BUFFERS);
        for _ in 0..STAGING_BUFFERS {
            // SAFETY: each copy writes the bytes it sends first.
            let buffer = unsafe { self.gpu.ctx.alloc_pinned::<u8>(STAGING_BYTES) }?;
            staging.push(Mutex::new(Staging { buffer, done: self.gpu.ctx.new_event(None)? }));
        }
        let _ = self.staging.set(staging);
        // SAFETY: only bytes the copies write are ever read (through the
        // addresses recorded with them).
        let memory = unsafe { self.gpu.stream.alloc::<u8>(bytes as usize) }?;
        let base = memory.device_ptr(&self.gpu.stream).0;
        Ok(Some(Arena { memory, base, used: 0, meshes: HashMap::new(), missed: 0 }))
    }

    /// Room for `len` bytes in the arena: their device address.
    fn reserve(&self, len: u64) -> Option<u64> {
        let mut arena = lock(&self.arena);
        let arena = arena.as_mut()?;
        let at = arena.used.next_multiple_of(ALIGN);
        if at + len > arena.memory.len() as u64 {
            return None;
        }
        arena.used = at + len;
        Some(arena.base + at)
    }

    /// Copies `bytes` to device address `to` through the staging buffers.
    fn copy(&self, to: u64, bytes: &[u8]) -> Result<(), DriverError> {
        let buffers = self.staging.get().expect("the staging buffers are made with the arena");
        for (i, chunk) in bytes.chunks(STAGING_BYTES).enumerate() {
            let k = self.next_staging.fetch_add(1, Ordering::Relaxed) % buffers.len();
            let mut staging = lock(&buffers[k]);
            // The copy that last read this buffer is over.
            staging.done.synchronize()?;
            let host = &mut staging.buffer.as_mut_slice()?[..chunk.len()];
            host.copy_from_slice(chunk);
            // SAFETY: `to + offset .. + chunk.len()` lies in the arena (it
            // was reserved for these bytes), and the buffer is not written
            // again before `done` says this copy is over.
            unsafe {
                cudarc::driver::result::memcpy_htod_async(
                    to + (i * STAGING_BYTES) as u64,
                    &*host,
                    self.gpu.stream.cu_stream(),
                )
            }?;
            staging.done.record(&self.gpu.stream)?;
        }
        Ok(())
    }

    /// Copies `values` into the arena: their address, `None` without room.
    fn place<T: bytemuck::Pod>(&self, values: &[T]) -> Result<Option<u64>, DriverError> {
        let bytes: &[u8] = bytemuck::cast_slice(values);
        let Some(at) = self.reserve(bytes.len() as u64) else { return Ok(None) };
        self.copy(at, bytes)?;
        Ok(Some(at))
    }

    /// [`MeshStream::place`] of an array a mesh may lack: `Some(None)` for
    /// an empty one, else its address and length.
    fn place_optional<T: bytemuck::Pod>(
        &self,
        values: &[T],
    ) -> Result<Option<Option<(u64, usize)>>, DriverError> {
        if values.is_empty() {
            return Ok(Some(None));
        }
        Ok(self.place(values)?.map(|at| Some((at, values.len()))))
    }

    fn stream_mesh(&self, mesh: &TriangleMesh) -> Result<(), DriverError> {
        self.gpu.ctx.bind_to_thread()?;
        let placed = (
            self.place(&mesh.positions)?,
            self.place(&mesh.indices)?,
            self.place_optional(&mesh.normals)?,
            self.place_optional(&mesh.uvs)?,
        );
        let mut arena = lock(&self.arena);
        let Some(arena) = arena.as_mut() else { return Ok(()) };
        let (Some(positions), Some(indices), Some(normals), Some(uvs)) = placed else {
            arena.missed += 1;
            return Ok(());
        };
        let at = MeshAddresses { positions, normals, uvs, indices };
        arena.meshes.insert(MeshKey::of(mesh), ArenaMesh { fingerprint: fingerprint(mesh), at });
        Ok(())
    }
}

impl Drop for MeshStream {
    /// Page-locked buffers are freed only once no copy reads them.
    fn drop(&mut self) {
        for staging in self.staging.get().into_iter().flatten() {
            let _ = lock(staging).done.synchronize();
        }
    }
}

impl atoll_scene::input::MeshSink for MeshStream {
    fn begin(&self, sizes: &SceneSizes) {
        // Compiled while the meshes are read.
        self.gpu.compile_ahead(vec![("gather.cu", Vec::new())]);
        match self.open(sizes) {
            Ok(arena) => *lock(&self.arena) = arena,
            Err(e) => self.fail(format!("setting up the arena: {e}")),
        }
    }

    fn mesh_made(&self, mesh: &TriangleMesh) {
        if lock(&self.arena).is_none() {
            return;
        }
        if let Err(e) = self.stream_mesh(mesh) {
            self.fail(format!("copying mesh {}: {e}", mesh.name));
        }
    }
}

/// Locks `m`, also after a thread panicked holding it (the data are plain
/// records, whole after every step).
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}
