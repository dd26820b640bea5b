//! The large tables (vertices, normals, uvs, triangles, triangle meshes)
//! made on the device from mesh arrays already there ([`super::streamed`]):
//! each table is a list of [`CopySegment`]s, copied (and offset: the
//! triangles' vertex indices) by one kernel, so the host neither writes nor
//! sends the tables again. The segments follow [`super::TablePlan`], the
//! order the host tables have, so both ways give the same tables.

use std::sync::Arc;

use cudarc::driver::{CudaSlice, LaunchConfig, PushKernelArg};

use super::{GpuMesh, TablePlan};
use crate::gpu::Gpu;
use crate::layout::CopySegment;
use crate::CudaError;
use atoll_scene::{MeshId, Scene};

/// Longest segment one thread block copies: long arrays are split so
/// that a large mesh spreads over the GPU rather than one multiprocessor.
const MAX_SEGMENT_WORDS: u64 = 1 << 16;

/// Device addresses of one mesh's arrays, and how many rows the optional
/// ones hold (`None`: the mesh has none).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct MeshAddresses {
    pub positions: u64,
    pub normals: Option<(u64, usize)>,
    pub uvs: Option<(u64, usize)>,
    pub indices: u64,
}

/// The segments of the five large tables.
#[derive(Debug, Default, PartialEq)]
pub(crate) struct TableSegments {
    pub vertices: Vec<CopySegment>,
    pub normals: Vec<CopySegment>,
    pub uvs: Vec<CopySegment>,
    pub triangles: Vec<CopySegment>,
    pub triangle_mesh: Vec<CopySegment>,
}

/// Appends a copy of `words` words from `src` (0: writes `add` only) to
/// table word `dst`, adding `add` to each, in pieces of at most
/// [`MAX_SEGMENT_WORDS`].
fn push(out: &mut Vec<CopySegment>, src: u64, dst: u64, words: u64, add: u32) {
    for first in (0..words).step_by(MAX_SEGMENT_WORDS as usize) {
        let n = (words - first).min(MAX_SEGMENT_WORDS);
        let src = if src == 0 { 0 } else { src + 4 * first };
        out.push(CopySegment { src, dst: dst + first, words: n as u32, add });
    }
}

/// One vertex attribute of `words` words a row over `blocks` (each mesh's
/// rows after the previous one's): a mesh's own rows, then zeros for rows
/// it lacks, as the host's vertex tables do. Empty when `present` is false
/// (the table then has no rows).
fn vertex_segments(
    scene: &Scene,
    blocks: &[MeshId],
    words: u64,
    present: bool,
    attribute: impl Fn(MeshId) -> Option<(u64, usize)>,
) -> Vec<CopySegment> {
    let mut out = Vec::new();
    if !present {
        return out;
    }
    let mut row = 0u64;
    for &m in blocks {
        let rows = scene.meshes[m as usize].positions.len() as u64;
        let (src, have) = attribute(m).map_or((0, 0), |(a, n)| (a, (n as u64).min(rows)));
        push(&mut out, src, row * words, have * words, 0);
        push(&mut out, 0, (row + have) * words, (rows - have) * words, 0);
        row += rows;
    }
    out
}

/// The segments of `plan`'s tables, each mesh's arrays at `locate(mesh)`.
pub(crate) fn table_segments(
    scene: &Scene,
    plan: &TablePlan,
    has_normals: bool,
    has_uvs: bool,
    locate: impl Fn(MeshId) -> MeshAddresses,
) -> TableSegments {
    let blocks = &plan.vertex_blocks;
    let mut t = TableSegments {
        vertices: vertex_segments(scene, blocks, 3, true, |m| {
            Some((locate(m).positions, scene.meshes[m as usize].positions.len()))
        }),
        normals: vertex_segments(scene, blocks, 3, has_normals, |m| locate(m).normals),
        uvs: vertex_segments(scene, blocks, 2, has_uvs, |m| locate(m).uvs),
        ..Default::default()
    };
    for (k, m) in plan.meshes.iter().enumerate() {
        let GpuMesh { first_triangle, triangle_count, first_vertex, first_scene_triangle, .. } = *m;
        let src = locate(m.scene_mesh).indices + 12 * first_scene_triangle as u64;
        push(&mut t.triangles, src, 3 * first_triangle as u64, 3 * triangle_count as u64, first_vertex);
        push(&mut t.triangle_mesh, 0, first_triangle as u64, triangle_count as u64, k as u32);
    }
    t
}

/// What [`copy_segments`] writes, done on the host over `read` (a word at
/// a device address): the tests' reference for the kernel and the plan.
#[cfg(test)]
pub(crate) fn run_on_host(segments: &[CopySegment], words: usize, read: impl Fn(u64) -> u32) -> Vec<u32> {
    let mut table = vec![0xdead_beef; words];
    for s in segments {
        for i in 0..s.words as u64 {
            let value = if s.src == 0 { 0 } else { read(s.src + 4 * i) };
            table[(s.dst + i) as usize] = value.wrapping_add(s.add);
        }
    }
    table
}

/// A new device table of `words` words (one zero word when empty, as the
/// uploaded tables have) written by `segments`.
pub(crate) fn copy_segments<W: cudarc::driver::DeviceRepr + cudarc::driver::ValidAsZeroBits>(
    gpu: &Arc<Gpu>,
    segments: &[CopySegment],
    words: usize,
    what: &str,
) -> Result<CudaSlice<W>, CudaError> {
    debug_assert_eq!(std::mem::size_of::<W>(), 4);
    let context = || format!("{}: making the {what} table on the device", gpu.label());
    if words == 0 {
        return gpu.stream.alloc_zeros(1).map_err(CudaError::driver(context()));
    }
    // SAFETY: the segments cover every word of the table (the plan's
    // tables are whole: each row is a mesh's or a zero fill).
    let mut table = unsafe { gpu.stream.alloc::<W>(words) }.map_err(CudaError::driver(context()))?;
    let list = gpu.stream.clone_htod(segments).map_err(CudaError::driver(context()))?;
    let function = gpu.function("gather.cu", "copy_segments")?;
    let count = segments.len() as u32;
    let config = LaunchConfig { grid_dim: (count.max(1), 1, 1), block_dim: (256, 1, 1), shared_mem_bytes: 0 };
    let mut launch = gpu.stream.launch_builder(&function);
    launch.arg(&list).arg(&count).arg(&mut table);
    // SAFETY: `copy_segments(const CopySegment*, unsigned int, unsigned int*)`;
    // every source address is a live device array the segments were made
    // from, and every destination word lies inside `table`.
    unsafe { launch.launch(config) }.map_err(CudaError::driver(context()))?;
    gpu.stream.synchronize().map_err(CudaError::driver(context()))?;
    Ok(table)
}
