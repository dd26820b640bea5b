//! BVH builders, layouts and CPU traversal for atoll.
//!
//! - [`Bvh2::build`]: parallel binned-SAH builder (and a median-split one for
//!   comparison) over primitive boxes, producing the canonical binary layout
//!   [`Bvh2`]. Other layouts are converted from it: [`Bvh4Cpu`], 4-wide with
//!   SIMD box tests, the default (it measured faster on every ray batch);
//!   [`Cwbvh`], the compressed 8-wide BVH for GPU upload, with a scalar
//!   reference traversal.
//! - Triangles: Möller–Trumbore on precomputed `(v0, e1, e2)`, four at a
//!   time in [`Tri4`] leaf blocks; [`TriAccel`] is the scalar reference the
//!   GPU kernels must match.
//! - [`SceneBvh`]: two-level BVH over a [`atoll_scene::Scene`] (or a
//!   [`ScenePart`] of one): one bottom-level BVH per object, one top-level
//!   BVH over the instances. Closest-hit ([`SceneBvh::intersect`]) and
//!   any-hit ([`SceneBvh::occluded`]) queries, safe to call from many threads.
//! - [`part_bytes`]: what a device must hold for a [`ScenePart`], from a
//!   [`ByteModel`] ([`ByteModel::CPU`] for [`SceneBvh`]); partitioning balances it.
//! - [`mod@bench`]: the traversal benchmark behind `atoll bench`, and the export
//!   of its data for the Embree comparison (`scripts/bench-embree.py`).

#![warn(missing_docs)]

pub mod aabb;
pub mod bench;
pub mod build;
pub mod bvh2;
pub mod bvh4;
pub mod curve;
pub mod cwbvh;
pub mod layout;
pub mod memory;
pub mod scene_bvh;
pub mod triangle;

use glam::Vec3;

pub use aabb::Aabb;
pub use build::{BuildOptions, SplitMethod};
pub use bvh2::{Bvh2, Bvh2Node};
pub use bvh4::{Bvh4Cpu, Bvh4CpuNode};
pub use cwbvh::{Cwbvh, CwbvhNode};
pub use layout::{BvhLayout, BvhStats, TraversalRay, MAX_DEPTH};
pub use memory::{part_bytes, part_geometry_bytes, ByteModel};
pub use scene_bvh::{
    HitFilter, MemoryTable, MeshRange, NoFilter, NoVisits, SceneBvh, SceneBvhStats, ScenePart, Visits,
};
pub use triangle::{Ray4, Tri4, TriAccel};

/// A ray in world space. Hits count for `0 < t < t_max`: callers offset
/// origins of secondary rays themselves. `direction` need not be normalised;
/// `t` is in units of its length.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Ray {
    /// Where the ray starts.
    pub origin: Vec3,
    /// Its direction; the length is the unit of `t`.
    pub direction: Vec3,
    /// Hits at `t >= t_max` do not count (`f32::INFINITY` for no limit).
    pub t_max: f32,
    /// When the ray is traced: where moving instances are
    /// ([`atoll_scene::Motion`]); still ones ignore it.
    pub time: f32,
}

/// The closest hit of a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the ray, in units of the direction's length.
    pub t: f32,
    /// Barycentrics of the triangle's second and third vertices: the hit point
    /// is `(1-u-v)*p0 + u*p1 + v*p2` with `(p0, p1, p2)` in index order.
    pub u: f32,
    /// See `u`.
    pub v: f32,
    /// Index into `scene.instances`.
    pub instance: u32,
    /// Index into `scene.meshes`.
    pub mesh: u32,
    /// Triangle index within that mesh.
    pub triangle: u32,
}
