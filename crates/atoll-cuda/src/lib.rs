//! The CUDA device (issue 3): kernels compiled at run time by NVRTC, a GPU
//! BVH builder, GPU traversal and the wavefront path tracer's stages.
//!
//! Layout of the crate (one purpose per file):
//! - `kernels/*.cu`, `kernels/*.cuh`: CUDA C++ sources. They include no system
//!   or CUDA headers (NVRTC on CI has none): integer types are spelled
//!   `unsigned int`/`unsigned long long`, f16 conversions use inline PTX.
//!   `#include "x.cuh"` is resolved by [`compile`] itself.
//! - [`layout`]: `#[repr(C)]` structs shared with the kernels (scene tables,
//!   hit references); `kernels/layout.cuh` mirrors them with `static_assert`s.
//! - `compile`: NVRTC compilation with an on-disk cache; `gpu`: context,
//!   stream, modules; `scene`: the scene uploaded as flat device tables;
//!   `bvh`: GPU BVH build and layouts; `trace`: traversal kernels' host side;
//!   `device`: [`atoll_render::Device`] for CUDA GPUs.
//!
//! The GPU scene (built by `scene`, read by `bvh`, `trace` and the surface
//! kernel) is a set of flat tables:
//! - `vertices`: f32 x,y,z per vertex, every mesh concatenated;
//! - `normals`: f32 x,y,z per vertex for meshes that have them (else unused);
//! - `triangles`: 3 × u32 per triangle, *absolute* vertex indices;
//! - `triangle_mesh`: u32 mesh id per triangle (global triangle order);
//! - `meshes`: [`layout::GpuMesh`] per mesh; meshes of one object are
//!   consecutive, so an object's triangles are one range;
//! - `objects`: [`layout::GpuObject`] (triangle range) per object;
//! - `instances`: [`layout::GpuInstance`] per instance.

pub mod layout;
