//! The CUDA device: kernels compiled at run time by NVRTC, a GPU BVH
//! builder, GPU traversal and the wavefront path tracer's stages.
//!
//! Layout of the crate (one purpose per file):
//! - `kernels/*.cu`, `kernels/*.cuh`: CUDA C++ sources. They include no system
//!   or CUDA headers (NVRTC on CI has none): integer types are spelled
//!   `unsigned int`/`unsigned long long`, f16 conversions use inline PTX.
//!   `#include "x.cuh"` is resolved by [`compile`] itself.
//! - [`layout`]: `#[repr(C)]` structs shared with the kernels (scene tables,
//!   hit references); `kernels/layout.cuh` mirrors them with `static_assert`s.
//! - [`error`]: [`CudaError`], and the library checks every entry point
//!   makes first (cudarc panics when `libcuda`/`libnvrtc` are missing).
//! - [`compile`]: the kernel registry, `#include` splicing and NVRTC;
//!   [`kernel_cache`]: compiled kernels on disk; [`gpu`]: context, stream,
//!   modules, timers; [`scene`]: the scene as flat device tables and the
//!   memory plan; `bvh`: GPU BVH build and layouts; `trace`: traversal
//!   kernels' host side; `params`: the frame's parameters and tables;
//!   [`queues`]: ray queues with device-side lengths; [`device`]:
//!   [`atoll_render::Device`] for CUDA GPUs; [`window`]: chunked scene
//!   memory that several GPUs read through one address range each (CUDA
//!   virtual memory).
//!
//! Run time (not build time) needs the NVIDIA driver and NVRTC 13:
//! `Gpu::open` reports what is missing. `ATOLL_KERNEL_DIR` reads kernels
//! from a directory instead of the built-in copies; `ATOLL_KERNEL_CACHE`
//! moves (or with `off` disables) the compiled-kernel cache.
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

pub mod bench;
pub mod bvh;
pub mod compile;
pub mod device;
pub mod error;
pub mod gpu;
// Generates and checks the kernel headers' generated blocks: a test, not
// part of the library.
#[cfg(test)]
mod header;
pub mod kernel_cache;
pub mod layout;
pub mod nccl;
pub mod params;
pub mod peer;
pub mod queues;
pub mod scene;
pub mod sharing;
pub mod trace;
pub mod window;
pub mod work;

pub use device::CudaDevice;
pub use error::CudaError;
pub use gpu::{device_count, Gpu};
pub use scene::GpuScene;
pub use window::{ChunkWindow, WindowMemory};

/// Paths in flight per GPU device unless asked otherwise (CPU devices keep
/// [`atoll_render::RenderOptions`]'s default). A GPU needs more than a CPU:
/// on the landscape most paths end after a bounce or two, and with smaller
/// waves the later bounces' kernels leave the GPU partly idle. 2^20 is
/// where the landscape's speed on one H100 stopped growing with the wave
/// size (BENCHMARKS.md). Queues cost 4 × 128 B per path: 512 MiB.
pub const DEFAULT_WAVE_SIZE: u32 = 1 << 20;

/// Devices (wavefronts, each with its own stream, queues and film) per GPU
/// unless asked otherwise, sharing one copy of the scene: one device's
/// kernels leave the GPU partly idle, two or three fill each other's gaps:
/// on one H100 with waves of 2^20, a second and a third device each made
/// the Cornell box and the landscapes faster (BENCHMARKS.md, `--streams`).
pub const DEFAULT_STREAMS: usize = 3;
