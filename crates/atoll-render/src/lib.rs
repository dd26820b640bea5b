//! The renderer: ray record, sampling, camera, BSDFs, lights, film, the
//! wavefront integrator and the `Device` trait with its CPU implementation.

pub mod bsdf;
pub mod bump;
pub mod camera;
pub mod chunks;
pub mod cpu;
pub mod density_grid;
pub mod device;
pub mod environment;
pub mod film;
pub mod filter;
pub mod footprint;
pub mod frame;
pub mod integrator;
pub mod light_bvh;
pub mod lights;
pub mod material_coeffs;
pub mod material_layout;
pub mod medium;
pub mod noise;
pub mod portal;
pub mod record;
pub mod rng;
pub mod sampling;
pub mod shadow_media;
pub mod spawn;
pub mod stages;
pub mod texture;
pub mod transport;

pub use chunks::{ChunkHome, ChunkLayout, ChunkPlacement, Residency, SceneSharing};
pub use cpu::CpuDevice;
pub use device::{Device, DeviceError, Queue};
pub use film::Film;
pub use frame::{FrameContext, RenderOptions, Wave};
pub use integrator::{render, RenderOutput};
pub use record::RayRecord;
pub use transport::{DirectRing, DirectTransport, ProcessLink, ProcessTransport};
