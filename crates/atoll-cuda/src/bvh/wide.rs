//! The compressed 8-wide BVH on the GPU (Ylitie, Karras and Laine 2017):
//! the binary BVH built on the GPU, collapsed into [`atoll_bvh::Cwbvh`]
//! nodes on the host and uploaded with triangle and instance records
//! permuted into the wide tree's order. Traversed by the `cw` kernels of
//! `trace.cu` (`kernels/wide.cuh`).
//!
//! The collapse runs on the host (download, SAH dynamic programme per BLAS
//! and for the TLAS, upload): it is a traversal variant to measure, made on
//! first use. A GPU collapse would be needed before it could be the default
//! of a build measured in milliseconds.
//!
//! One node array holds the TLAS's nodes, then every BLAS's; child indices
//! are global. TLAS leaf primitives are instance records (each instance
//! record's `blas_root` becomes the index of its BLAS's wide root node),
//! BLAS leaf primitives are triangle records.

use std::collections::HashMap;
use std::time::Instant;

use atoll_bvh::{Aabb, Bvh2, Bvh2Node, Cwbvh, CwbvhNode};
use bytemuck::{Pod, Zeroable};
use cudarc::driver::CudaSlice;
use glam::Vec3A;

use super::layout::{GpuBvhNode, GpuTlasInstance, GpuTriRecord, LINK_DONE};
use super::{Bounds, GpuSceneBvh};
use crate::error::CudaError;
use crate::gpu::{upload, Gpu};

/// A [`CwbvhNode`] as the kernels load it: five aligned 16-byte words.
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub(crate) struct GpuWideNode(pub CwbvhNode);

const _: () = assert!(std::mem::size_of::<GpuWideNode>() == 80);

// SAFETY: a plain-old-data `#[repr(C)]` struct (Pod): every bit pattern is
// valid and it is copied to and from the device byte for byte.
unsafe impl cudarc::driver::DeviceRepr for GpuWideNode {}
unsafe impl cudarc::driver::ValidAsZeroBits for GpuWideNode {}

/// The wide tree and the records in its order, resident on the GPU.
pub(crate) struct WideBvh {
    pub nodes: CudaSlice<GpuWideNode>,
    pub tris: CudaSlice<GpuTriRecord>,
    pub tri_ids: CudaSlice<u32>,
    pub instances: CudaSlice<GpuTlasInstance>,
    /// The TLAS's root node, or `LINK_DONE` for an empty scene.
    pub root: i32,
}

/// The binary subtree at `root` (a link of `nodes`) as a [`Bvh2`] whose
/// leaves keep the links' record ranges: leaf "primitives" are record
/// indices. `bounds` is the root's box (kept by its parent, or the host).
fn binary_to_bvh2(nodes: &[GpuBvhNode], root: i32, bounds: &Bounds) -> Bvh2 {
    let mut out = Bvh2::default();
    if root == LINK_DONE {
        return out;
    }
    let aabb = |min: [f32; 3], max: [f32; 3]| Aabb { min: Vec3A::from(min), max: Vec3A::from(max) };
    let make = |b: &Aabb, left_or_first: u32, count: u32| Bvh2Node {
        min: b.min.into(),
        left_or_first,
        max: b.max.into(),
        count,
    };
    out.nodes.push(Bvh2Node::default());
    let mut todo = vec![(root, 0usize, aabb(bounds.0, bounds.1))];
    while let Some((link, at, b)) = todo.pop() {
        if link < 0 {
            let bits = !link as u32;
            out.nodes[at] = make(&b, bits >> 2, (bits & 3) + 1);
            continue;
        }
        let n = &nodes[link as usize];
        let left = aabb([n.left_xy[0], n.left_xy[2], n.z[0]], [n.left_xy[1], n.left_xy[3], n.z[1]]);
        let right = aabb([n.right_xy[0], n.right_xy[2], n.z[2]], [n.right_xy[1], n.right_xy[3], n.z[3]]);
        let first = out.nodes.len();
        out.nodes.push(Bvh2Node::default());
        out.nodes.push(Bvh2Node::default());
        out.nodes[at] = make(&b, first as u32, 0);
        todo.push((n.links[1], first + 1, right));
        todo.push((n.links[0], first, left));
    }
    out
}

/// Appends `wide` to `nodes`, shifting its child and primitive indices by
/// where its nodes and primitives land; returns its root's index.
fn append(nodes: &mut Vec<GpuWideNode>, wide: &Cwbvh, prim_offset: u32) -> i32 {
    let node_offset = nodes.len() as u32;
    nodes.extend(wide.nodes.iter().map(|n| {
        let mut n = *n;
        n.child_base += node_offset;
        n.prim_base += prim_offset;
        GpuWideNode(n)
    }));
    node_offset as i32
}

impl WideBvh {
    /// Collapses `bvh` (download, host collapse, upload).
    pub(crate) fn build(gpu: &Gpu, bvh: &GpuSceneBvh) -> Result<Self, CudaError> {
        let start = Instant::now();
        let download = |what: &str| format!("{}: downloading the {what} for the wide BVH", gpu.label());
        let blas_nodes =
            gpu.stream.clone_dtoh(&bvh.blas_nodes).map_err(CudaError::driver(download("BLAS")))?;
        let tlas_nodes =
            gpu.stream.clone_dtoh(&bvh.tlas_nodes).map_err(CudaError::driver(download("TLAS")))?;
        let tris = gpu.stream.clone_dtoh(&bvh.tris).map_err(CudaError::driver(download("triangles")))?;
        let tri_ids = gpu.stream.clone_dtoh(&bvh.tri_ids).map_err(CudaError::driver(download("ids")))?;
        let instances =
            gpu.stream.clone_dtoh(&bvh.instances).map_err(CudaError::driver(download("instances")))?;

        let tlas = Cwbvh::from_bvh2(&binary_to_bvh2(&tlas_nodes, bvh.tlas_root, &bvh.tlas_bounds));
        let mut nodes = Vec::new();
        let root = if tlas.nodes.is_empty() { LINK_DONE } else { append(&mut nodes, &tlas, 0) };

        // Each BLAS once (instances share them; a BLAS is its root link and
        // first record), its triangles in wide order: the wide leaves index
        // all records, so the instances' record bases become 0.
        let mut wide_roots: HashMap<(i32, u32), i32> = HashMap::new();
        let (mut wide_tris, mut wide_ids) = (Vec::with_capacity(tris.len()), Vec::with_capacity(tris.len()));
        for ((&link, bounds), &base) in bvh.blas_roots.iter().zip(&bvh.blas_bounds).zip(&bvh.blas_tri_bases) {
            if link == LINK_DONE || wide_roots.contains_key(&(link, base)) {
                continue;
            }
            let wide = Cwbvh::from_bvh2(&binary_to_bvh2(&blas_nodes, link, bounds));
            let wide_root = if wide.nodes.is_empty() {
                LINK_DONE
            } else {
                append(&mut nodes, &wide, wide_tris.len() as u32)
            };
            wide_tris.extend(wide.prim_order.iter().map(|&i| tris[(base + i) as usize]));
            wide_ids.extend(wide.prim_order.iter().map(|&i| tri_ids[(base + i) as usize]));
            wide_roots.insert((link, base), wide_root);
        }
        let wide_instances: Vec<GpuTlasInstance> = tlas
            .prim_order
            .iter()
            .map(|&slot| {
                let mut record = instances[slot as usize];
                record.blas_root =
                    wide_roots.get(&(record.blas_root, record.tri_base)).copied().unwrap_or(LINK_DONE);
                record.tri_base = 0;
                record
            })
            .collect();
        let build_seconds = start.elapsed().as_secs_f64();
        tracing::info!(
            "{}: wide BVH: {} nodes ({:.1} MiB, binary {:.1} MiB) collapsed on the host in {:.3} s",
            gpu.label(),
            nodes.len(),
            (nodes.len() * std::mem::size_of::<GpuWideNode>()) as f64 / (1 << 20) as f64,
            ((blas_nodes.len() + tlas_nodes.len()) * std::mem::size_of::<GpuBvhNode>()) as f64
                / (1 << 20) as f64,
            build_seconds
        );
        Ok(WideBvh {
            nodes: upload(gpu, &nodes, "wide BVH nodes")?,
            tris: upload(gpu, &wide_tris, "wide BVH triangles")?,
            tri_ids: upload(gpu, &wide_ids, "wide BVH triangle ids")?,
            instances: upload(gpu, &wide_instances, "wide BVH instances")?,
            root,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A binary node with two children boxes and links.
    fn node(l: ([f32; 3], [f32; 3]), r: ([f32; 3], [f32; 3]), links: [i32; 2]) -> GpuBvhNode {
        GpuBvhNode {
            left_xy: [l.0[0], l.1[0], l.0[1], l.1[1]],
            right_xy: [r.0[0], r.1[0], r.0[1], r.1[1]],
            z: [l.0[2], l.1[2], r.0[2], r.1[2]],
            links: [links[0], links[1], 0, 0],
        }
    }

    fn leaf(first: u32, count: u32) -> i32 {
        !((first << 2 | (count - 1)) as i32)
    }

    #[test]
    fn binary_links_become_a_bvh2_with_record_ranges() {
        // root (node 0): left = node 1, right = leaf [4, 6); node 1: leaves [0, 3) and [3, 4).
        let a = ([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]);
        let b = ([2.0, 0.0, 0.0], [3.0, 1.0, 1.0]);
        let c = ([0.0, 2.0, 0.0], [3.0, 3.0, 1.0]);
        let ab = ([0.0, 0.0, 0.0], [3.0, 1.0, 1.0]);
        let nodes = [node(ab, c, [1, leaf(4, 2)]), node(a, b, [leaf(0, 3), leaf(3, 1)])];
        let bvh = binary_to_bvh2(&nodes, 0, &([0.0; 3], [3.0, 3.0, 1.0]));
        let mut leaves: Vec<(u32, u32)> =
            bvh.nodes.iter().filter(|n| n.is_leaf()).map(|n| (n.left_or_first, n.count)).collect();
        leaves.sort_unstable();
        assert_eq!(leaves, [(0, 3), (3, 1), (4, 2)]);
        assert_eq!(bvh.nodes.len(), 5);
        assert_eq!(bvh.nodes[0].left_or_first, 1);
        assert_eq!(bvh.nodes[2].aabb(), Aabb { min: Vec3A::from(c.0), max: Vec3A::from(c.1) });
        // Every record lands in the wide tree exactly once.
        let wide = Cwbvh::from_bvh2(&bvh);
        let mut order = wide.prim_order.clone();
        order.sort_unstable();
        assert_eq!(order, [0, 1, 2, 3, 4, 5]);
        // A root that is a leaf, and an empty tree.
        assert_eq!(binary_to_bvh2(&[], leaf(7, 2), &a).nodes.len(), 1);
        assert!(binary_to_bvh2(&[], LINK_DONE, &a).nodes.is_empty());
    }
}
