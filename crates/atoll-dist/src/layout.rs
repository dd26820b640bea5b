//! Where the scene goes over the devices of a frame: replicated, or in
//! parts around rings ([`Layout`]), and where a ring's queues start and
//! end their cycles ([`RingOrder`]).

use atoll_bvh::ScenePart;

use crate::shared::SharedSpec;

/// Where the scene goes: what each device holds and who it works with.
#[derive(Clone, Debug)]
pub enum Layout {
    /// Every device holds the whole scene.
    Replicate,
    /// `parts.len()` devices per ring, `islands` rings: device `i * K + j`
    /// (K = parts.len()) is member `j` of ring `i` and holds `parts[j]`.
    Ring {
        /// One part per member of a ring.
        parts: Vec<ScenePart>,
        /// Rings, each rendering its share of the waves.
        islands: usize,
        /// Where queues start and end their cycles.
        order: RingOrder,
    },
    /// The scene in chunks over every device's memory, placed by a
    /// counting prepass ([`crate::shared`]).
    Shared(SharedSpec),
}

/// Where a ring's queues are made, first traced and shaded.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RingOrder {
    /// Every member makes queues from its share of the waves; a queue is
    /// traced first where it was made and shaded where its cycle ends
    /// (any member can shade any hit): K − 1 sends per trace, the least
    /// traffic, and on one GPU the most throughput.
    #[default]
    Spread,
    /// Member 0 makes and shades every queue (Wald et al.'s home device,
    /// one for all): every ray is traced first on part 0, the partition's
    /// heaviest piece (a landscape's ground), and reaches the others with
    /// its closest hit so far, so they skip what lies behind it. K sends
    /// per trace. The parts' work evens out, but each ring then has one
    /// queue in flight instead of K, and its members idle most of the time:
    /// measured slower than `Spread` (BENCHMARKS.md).
    Home,
}

impl Layout {
    /// Devices this layout needs (`None`: any number).
    pub fn devices(&self) -> Option<usize> {
        match self {
            Layout::Replicate | Layout::Shared(_) => None,
            Layout::Ring { parts, islands, .. } => Some(parts.len() * islands),
        }
    }
}
