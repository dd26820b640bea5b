//! Distribution strategies over many devices.
//!
//! - [`partition()`]: the scene split into K memory-balanced parts for the
//!   ring strategy (ray queue cycling), big objects split by meshes and
//!   triangle ranges; [`min_parts`] the fewest parts that fit a budget.
//! - [`plan()`]: replicate or ring (with islands) for N devices, as `auto`
//!   chooses or as forced by a [`Strategy`].
//! - [`render_multi`]: one frame on many devices placed by a [`Layout`]
//!   (replicate with dynamic waves; ring with queues cycling, GPU to GPU by
//!   peer copies where every member is a GPU).
//! - [`shared`]: the scene in chunks over the devices' memories, placed
//!   by a counting prepass ([`chunk_placement`]: Jaroš et al. 2021's
//!   Algorithm 1 with a host tier).
//! - [`spatial`]: parts made of compact chunks along a Morton curve: one
//!   per part (slabs: rays rarely enter more than one part's bounds) or
//!   several dealt out in turn ([`spatial::partition_interleaved`]).
//! - [`work`]: where a frame's rays will work, estimated on a box proxy of
//!   the scene, and the ring partition whose chunks share out that work
//!   as well as the bytes ([`work::partition_work_balanced`]).
//! - [`ownership`]: the false-colour view of which device holds what.
//! - [`handout`]: where a frame's waves come from: this process's counter,
//!   or (with the `mpi` feature, [`ranks`]) one shared by every process
//!   started by `mpirun`, so unequal nodes take waves as they free up.

#![warn(missing_docs)]

pub mod chunk_placement;
pub mod handout;
mod layout;
pub mod ownership;
pub mod partition;
pub mod placement;
#[cfg(feature = "mpi")]
pub mod ranks;
pub mod render;
mod replicate;
pub mod ring;
pub mod shared;
pub mod spatial;
pub mod stripes;
mod transport;
mod vote;
pub mod work;

pub use handout::{Joined, Joining, LocalHandout, Pace, Pacing, Speed, WaveHandout};
pub use layout::{Layout, RingOrder};
pub use partition::{
    min_parts, partition, plan, plan_partitioned, ParseStrategyError, Partition, PartitionError,
    PartitionOptions, Plan, Strategy,
};
pub use render::{
    render_multi, render_multi_warmed, render_multi_with, DeviceReport, MultiFrame, MultiOutput, Session,
    Shared,
};
pub use ring::{RingError, RingPeers, RingPlace};
pub use shared::{SharedReport, SharedSpec};
pub use transport::Transport;
