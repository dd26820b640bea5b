//! Scene memory in fixed-size chunks, spread over several devices (the
//! shared strategy of Jaroš et al. 2021): the scene data a device kind's
//! kernels read is one address space of tables ([`ChunkLayout`]), cut into
//! chunks of one size; each chunk is replicated on every device, owned by
//! one device and read by the others from there, or left in host memory
//! ([`ChunkPlacement`]). Which chunk goes where is the placement policy's
//! business (atoll-dist); how a device maps its chunks is the device
//! crate's ([`SceneSharing`]).

use std::sync::Arc;

use atoll_scene::Scene;

use crate::device::{Device, DeviceError, PrepareStats};
use crate::frame::FrameContext;

/// One table of a device kind's scene data (BVH nodes, triangle records,
/// vertices, materials, …): where it starts in the chunked address space.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ChunkTable {
    /// What it holds, for reports.
    pub name: String,
    /// Byte offset of its first element.
    pub offset: u64,
    pub bytes: u64,
}

/// A device kind's scene data as one address space of tables, cut into
/// chunks of `chunk_bytes` (the last one may be short).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ChunkLayout {
    pub chunk_bytes: u64,
    /// In address order, none overlapping.
    pub tables: Vec<ChunkTable>,
}

impl ChunkLayout {
    /// Lays `tables` (name, bytes) out back to back, each starting at a
    /// multiple of `align` (a power of two: what the device's loads need).
    /// Panics when `chunk_bytes` is 0 or `align` is not a power of two
    /// (callers pass constants or checked options).
    pub fn new(chunk_bytes: u64, align: u64, tables: impl IntoIterator<Item = (String, u64)>) -> Self {
        assert!(chunk_bytes > 0 && align.is_power_of_two());
        let mut offset = 0u64;
        let tables = tables
            .into_iter()
            .map(|(name, bytes)| {
                let table = ChunkTable { name, offset, bytes };
                offset = (offset + bytes).next_multiple_of(align);
                table
            })
            .collect();
        ChunkLayout { chunk_bytes, tables }
    }

    /// Bytes of the address space: the end of the last table.
    pub fn bytes(&self) -> u64 {
        self.tables.last().map_or(0, |t| t.offset + t.bytes)
    }

    pub fn chunk_count(&self) -> usize {
        self.bytes().div_ceil(self.chunk_bytes) as usize
    }

    /// The chunk holding byte `offset`.
    #[inline]
    pub fn chunk_of(&self, offset: u64) -> usize {
        (offset / self.chunk_bytes) as usize
    }

    /// Bytes of chunk `chunk` (the last one may be short).
    pub fn chunk_len(&self, chunk: usize) -> u64 {
        let start = chunk as u64 * self.chunk_bytes;
        self.chunk_bytes.min(self.bytes().saturating_sub(start))
    }

    /// The table named `name`.
    pub fn table(&self, name: &str) -> Option<&ChunkTable> {
        self.tables.iter().find(|t| t.name == name)
    }
}

/// Where one chunk lives.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ChunkHome {
    /// A copy on every device.
    Replicated,
    /// On device `.0` (its index among the sharing devices); the others
    /// read it there (on GPUs, over NVLink).
    Device(u32),
    /// In host memory, read from there by every device.
    Host,
}

/// Where every chunk of a [`ChunkLayout`] lives.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ChunkPlacement {
    /// Per chunk.
    pub homes: Vec<ChunkHome>,
}

/// Bytes of the scene as one device sees them under a placement.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Residency {
    /// Chunks every device holds a copy of.
    pub replicated: u64,
    /// Chunks only this device holds (others read them here).
    pub owned: u64,
    /// Chunks this device reads from another device.
    pub remote: u64,
    /// Chunks this device reads from host memory.
    pub host: u64,
}

impl Residency {
    /// Bytes in the device's own memory.
    pub fn local(&self) -> u64 {
        self.replicated + self.owned
    }
}

impl ChunkPlacement {
    /// The step between `self` and `to` where host memory holds chunks too
    /// ([`ChunkHome::Host`] in `to`): every chunk that leaves a device goes
    /// to the host first, so that the devices' memory it held is free for
    /// the chunks coming in (a device filled to its budget has no room to
    /// take them in while still holding those it gives up). `None` where
    /// `to` keeps nothing on the host or no chunk leaves a device.
    pub fn via_host(&self, to: &ChunkPlacement) -> Option<ChunkPlacement> {
        if self.homes.len() != to.homes.len() || !to.homes.contains(&ChunkHome::Host) {
            return None;
        }
        let mut step = self.clone();
        let mut moved = false;
        for (home, &wanted) in step.homes.iter_mut().zip(&to.homes) {
            if *home != ChunkHome::Host && *home != wanted {
                *home = ChunkHome::Host;
                moved = true;
            }
        }
        moved.then_some(step)
    }

    /// Chunk `c` on device `c mod devices` (the prepass's starting point).
    pub fn round_robin(chunks: usize, devices: usize) -> Self {
        let devices = devices.max(1);
        ChunkPlacement { homes: (0..chunks).map(|c| ChunkHome::Device((c % devices) as u32)).collect() }
    }

    /// What device `device` holds and reads from elsewhere.
    pub fn residency(&self, layout: &ChunkLayout, device: usize) -> Residency {
        let mut r = Residency::default();
        for (c, home) in self.homes.iter().enumerate() {
            let bytes = layout.chunk_len(c);
            match *home {
                ChunkHome::Replicated => r.replicated += bytes,
                ChunkHome::Device(d) if d as usize == device => r.owned += bytes,
                ChunkHome::Device(_) => r.remote += bytes,
                ChunkHome::Host => r.host += bytes,
            }
        }
        r
    }

    /// Whether device `device` reads chunk `chunk` from its own memory.
    #[inline]
    pub fn is_local(&self, chunk: usize, device: usize) -> bool {
        match self.homes[chunk] {
            ChunkHome::Replicated => true,
            ChunkHome::Device(d) => d as usize == device,
            ChunkHome::Host => false,
        }
    }
}

/// Scene memory shared by several devices of one kind
/// ([`Device::scene_sharing`]): each device sees the whole scene, each
/// chunk read where the placement puts it. Device `i` of the slices
/// below is device `i` of the placement.
pub trait SceneSharing: Send + Sync {
    /// What it is, for messages.
    fn name(&self) -> &'static str;

    /// Whether `devices` can share `scene` this way (every one of this
    /// kind, direct access between every pair, room to lay the scene
    /// out); `Err` says why not. Placement asks before choosing it.
    fn supports(&self, devices: &[Box<dyn Device>], scene: &Scene) -> Result<(), String>;

    /// Whether laying `scene` out takes the slow way (built on the host,
    /// where no device has room to build it, not even in pieces): `auto`
    /// then prefers a strategy that starts sooner.
    fn lays_out_slowly(&self, _scene: &Scene) -> bool {
        false
    }

    /// The chunked layout of `scene`'s data as this device kind stores it
    /// for `frame` (building what sizes depend on, such as the BVH, and
    /// keeping it for [`SceneSharing::prepare`]).
    fn layout(
        &self,
        scene: &Arc<Scene>,
        frame: &Arc<FrameContext>,
        chunk_bytes: u64,
    ) -> Result<ChunkLayout, DeviceError>;

    /// Makes the scene resident over `devices` as `placement` says (each
    /// checking what it holds against its memory budget before
    /// allocating) and prepares each for `frame`.
    fn prepare(
        &self,
        devices: &mut [Box<dyn Device>],
        scene: &Arc<Scene>,
        frame: &Arc<FrameContext>,
        layout: &ChunkLayout,
        placement: &ChunkPlacement,
    ) -> Result<Vec<PrepareStats>, DeviceError>;

    /// Moves the chunks of prepared `devices` to `placement` (after the
    /// prepass), checking budgets before moving anything.
    fn replace(&self, devices: &mut [Box<dyn Device>], placement: &ChunkPlacement)
        -> Result<(), DeviceError>;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_leaving_a_device_go_to_the_host_first() {
        use ChunkHome::{Device, Host, Replicated};
        let from = ChunkPlacement { homes: vec![Device(0), Device(0), Host, Replicated, Device(1), Host] };
        let to = ChunkPlacement { homes: vec![Device(0), Host, Device(0), Device(1), Device(1), Host] };
        let step = from.via_host(&to).unwrap();
        assert_eq!(step.homes, [Device(0), Host, Host, Host, Device(1), Host]);
        // Without host chunks in the end, or with nothing leaving a device: no step.
        let no_host =
            ChunkPlacement { homes: vec![Device(0), Device(1), Device(0), Device(1), Device(1), Device(0)] };
        assert_eq!(from.via_host(&no_host), None);
        assert_eq!(step.via_host(&to), None);
        assert_eq!(to.via_host(&to), None);
    }

    fn layout() -> ChunkLayout {
        ChunkLayout::new(100, 16, [("a".to_string(), 90), ("b".to_string(), 5), ("c".to_string(), 150)])
    }

    #[test]
    fn tables_are_aligned_back_to_back() {
        let l = layout();
        let offsets: Vec<u64> = l.tables.iter().map(|t| t.offset).collect();
        assert_eq!(offsets, [0, 96, 112]);
        assert_eq!(l.bytes(), 262);
        assert_eq!(l.chunk_count(), 3);
        assert_eq!((l.chunk_len(0), l.chunk_len(2)), (100, 62));
        assert_eq!(l.chunk_of(l.table("c").unwrap().offset), 1);
    }

    #[test]
    fn residency_counts_every_byte_once_per_device() {
        let l = layout();
        let p = ChunkPlacement { homes: vec![ChunkHome::Replicated, ChunkHome::Device(1), ChunkHome::Host] };
        let r0 = p.residency(&l, 0);
        let r1 = p.residency(&l, 1);
        assert_eq!(r0, Residency { replicated: 100, owned: 0, remote: 100, host: 62 });
        assert_eq!(r1, Residency { replicated: 100, owned: 100, remote: 0, host: 62 });
        for r in [r0, r1] {
            assert_eq!(r.local() + r.remote + r.host, l.bytes());
        }
        assert!(p.is_local(1, 1) && !p.is_local(1, 0) && !p.is_local(2, 0));
        let rr = ChunkPlacement::round_robin(5, 2);
        assert_eq!(rr.homes[3], ChunkHome::Device(1));
    }
}
