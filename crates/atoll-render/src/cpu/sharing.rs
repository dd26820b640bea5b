//! CPU devices sharing one chunked scene ([`SceneSharing`]): every CPU
//! device draws on host memory, so they use one BVH and one copy of the
//! meshes; what each keeps is its chunk table (which chunks are its own,
//! which it would read elsewhere) and its access counters. The placement,
//! the counting and the budgets are those a GPU follows, so the shared
//! strategy is tested without one.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use atoll_bvh::{MemoryTable, SceneBvh, Visits};
use atoll_scene::Scene;

use super::{CpuDevice, Resident};
use crate::chunks::{ChunkLayout, ChunkPlacement, SceneSharing};
use crate::device::{Device, DeviceError, PrepareStats};
use crate::frame::FrameContext;

/// Tables start at multiples of this (a cache line).
const TABLE_ALIGN: u64 = 64;

/// Where each table the CPU device reads starts in the chunked address
/// space: the BVH's arrays ([`SceneBvh::memory_tables`]), then per mesh
/// its positions, indices, normals and uvs, then the texture images.
#[derive(Debug)]
pub(crate) struct TableIndex {
    /// Per table, (byte offset, bytes per element).
    tables: Vec<(u64, u64)>,
    /// Index of mesh 0's positions; mesh `m`'s tables follow at `4m`.
    first_mesh: usize,
}

/// The tables of one mesh, in [`TableIndex`] order.
#[derive(Clone, Copy)]
pub(crate) enum MeshTable {
    Positions = 0,
    Indices = 1,
    Normals = 2,
    Uvs = 3,
}

/// `scene`'s data as the CPU device reads it, in chunks of `chunk_bytes`.
fn layout_of(scene: &Scene, bvh: &SceneBvh, chunk_bytes: u64) -> (ChunkLayout, TableIndex) {
    let mut tables: Vec<MemoryTable> = bvh.memory_tables();
    let first_mesh = tables.len();
    let table = |name: String, count: usize, element: usize| MemoryTable {
        name,
        bytes: (count * element) as u64,
        element_bytes: element as u64,
    };
    for (m, mesh) in scene.meshes.iter().enumerate() {
        tables.push(table(format!("mesh {m} positions"), mesh.positions.len(), 12));
        tables.push(table(format!("mesh {m} indices"), mesh.indices.len(), 12));
        tables.push(table(format!("mesh {m} normals"), mesh.normals.len(), 12));
        tables.push(table(format!("mesh {m} uvs"), mesh.uvs.len(), 8));
    }
    // Texture reads are not counted: the images are placed as never read.
    tables.push(table("texture images".into(), scene.textures.memory_bytes() as usize, 1));
    let layout = ChunkLayout::new(chunk_bytes, TABLE_ALIGN, tables.iter().map(|t| (t.name.clone(), t.bytes)));
    let index = TableIndex {
        tables: layout.tables.iter().zip(&tables).map(|(l, t)| (l.offset, t.element_bytes)).collect(),
        first_mesh,
    };
    (layout, index)
}

/// One CPU device's view of the shared scene.
pub(crate) struct Share {
    pub(crate) layout: Arc<ChunkLayout>,
    pub(crate) index: Arc<TableIndex>,
    /// Where every chunk lives (the device's chunk table): which reads a
    /// GPU would make over NVLink or from the host.
    pub(crate) placement: ChunkPlacement,
    /// Per chunk, reads counted since preparing or placing anew.
    pub(crate) counts: Vec<AtomicU64>,
    pub(crate) counting: bool,
}

impl Share {
    /// The counter traversal and hit reads report to, while counting.
    pub(crate) fn counter(&self) -> Option<ChunkCounter<'_>> {
        self.counting.then_some(ChunkCounter { share: self })
    }
}

/// Counts each read into the chunk holding it.
pub(crate) struct ChunkCounter<'a> {
    share: &'a Share,
}

impl ChunkCounter<'_> {
    #[inline]
    fn add(&self, table: usize, element: u64) {
        let (offset, element_bytes) = self.share.index.tables[table];
        let chunk = self.share.layout.chunk_of(offset + element * element_bytes);
        self.share.counts[chunk].fetch_add(1, Ordering::Relaxed);
    }

    /// A read of element `element` of mesh `mesh`'s `table`.
    pub(crate) fn mesh(&self, mesh: u32, table: MeshTable, element: u32) {
        self.add(self.share.index.first_mesh + 4 * mesh as usize + table as usize, element as u64);
    }
}

impl Visits for ChunkCounter<'_> {
    fn tlas_node(&self, node: u32) {
        self.add(0, node as u64);
    }
    fn instance(&self, leaf: u32) {
        self.add(1, leaf as u64);
    }
    fn blas_node(&self, blas: u32, node: u32) {
        self.add(2 + 4 * blas as usize, node as u64);
    }
    fn triangles(&self, blas: u32, block: u32) {
        self.add(3 + 4 * blas as usize, block as u64);
    }
    fn prim(&self, blas: u32, prim: u32) {
        self.add(4 + 4 * blas as usize, prim as u64);
    }
    fn curve(&self, blas: u32, prim: u32) {
        self.add(5 + 4 * blas as usize, prim as u64);
    }
}

/// The scene laid out by [`CpuSharing::layout`], kept for preparing.
struct Laid {
    scene: Arc<Scene>,
    chunk_bytes: u64,
    bvh: Arc<SceneBvh>,
    index: Arc<TableIndex>,
}

/// Scene sharing between CPU devices.
#[derive(Default)]
pub struct CpuSharing {
    laid: Mutex<Option<Laid>>,
}

/// `device` as a CPU device, or why it cannot share a CPU scene.
fn cpu(device: &mut dyn Device) -> Result<&mut CpuDevice, DeviceError> {
    let name = device.name();
    device.as_any_mut().downcast_mut::<CpuDevice>().ok_or_else(|| DeviceError::Unsupported {
        device: name,
        what: "sharing a scene with CPU devices".into(),
    })
}

/// Checks what each device would hold against its budget, before anything changes.
fn check_budgets(
    devices: &mut [Box<dyn Device>],
    layout: &ChunkLayout,
    placement: &ChunkPlacement,
) -> Result<(), DeviceError> {
    if placement.homes.len() != layout.chunk_count() {
        return Err(DeviceError::Other {
            device: "shared scene".into(),
            message: format!("{} chunk homes for {} chunks", placement.homes.len(), layout.chunk_count()),
        });
    }
    for (d, device) in devices.iter_mut().enumerate() {
        let device = cpu(device.as_mut())?;
        let held = placement.residency(layout, d).local();
        if let Some(budget) = device.memory_budget.filter(|&b| held > b) {
            return Err(DeviceError::OutOfMemory { device: device.name(), needed: held, budget });
        }
    }
    Ok(())
}

impl SceneSharing for CpuSharing {
    fn name(&self) -> &'static str {
        "host memory"
    }

    fn supports(&self, devices: &[Box<dyn Device>], _scene: &Scene) -> Result<(), String> {
        match devices.iter().find(|d| d.as_any().downcast_ref::<CpuDevice>().is_none()) {
            Some(other) => Err(format!("{} is not a CPU device", other.name())),
            None => Ok(()),
        }
    }

    fn layout(
        &self,
        scene: &Arc<Scene>,
        _frame: &Arc<FrameContext>,
        chunk_bytes: u64,
    ) -> Result<ChunkLayout, DeviceError> {
        let bvh = Arc::new(SceneBvh::build(scene));
        let (layout, index) = layout_of(scene, &bvh, chunk_bytes);
        let laid = Laid { scene: scene.clone(), chunk_bytes, bvh, index: Arc::new(index) };
        *self.laid.lock().unwrap_or_else(|p| p.into_inner()) = Some(laid);
        Ok(layout)
    }

    fn prepare(
        &self,
        devices: &mut [Box<dyn Device>],
        scene: &Arc<Scene>,
        frame: &Arc<FrameContext>,
        layout: &ChunkLayout,
        placement: &ChunkPlacement,
    ) -> Result<Vec<PrepareStats>, DeviceError> {
        let laid = self.laid.lock().unwrap_or_else(|p| p.into_inner());
        let laid = laid
            .as_ref()
            .filter(|l| Arc::ptr_eq(&l.scene, scene) && l.chunk_bytes == layout.chunk_bytes)
            .ok_or_else(|| DeviceError::Other {
                device: "shared scene".into(),
                message: "prepare() needs the layout() of the same scene and chunk size first".into(),
            })?;
        check_budgets(devices, layout, placement)?;
        let layout = Arc::new(layout.clone());
        let bvh_stats = laid.bvh.stats();
        devices
            .iter_mut()
            .enumerate()
            .map(|(d, device)| {
                let device = cpu(device.as_mut())?;
                let share = Share {
                    layout: layout.clone(),
                    index: laid.index.clone(),
                    placement: placement.clone(),
                    counts: (0..layout.chunk_count()).map(|_| AtomicU64::new(0)).collect(),
                    counting: false,
                };
                let resident = Resident::new(scene, laid.bvh.clone(), Some(share));
                let residency = placement.residency(&layout, d);
                device.install(resident, frame);
                Ok(PrepareStats {
                    scene_bytes: residency.local(),
                    frame_bytes: device.frame_bytes(&frame.options),
                    bvh_build_seconds: bvh_stats.build_ms / 1e3,
                    bvh_sah_cost: bvh_stats.blas.sah_cost,
                    upload_seconds: 0.0,
                    shared: Some(residency),
                })
            })
            .collect()
    }

    fn replace(
        &self,
        devices: &mut [Box<dyn Device>],
        placement: &ChunkPlacement,
    ) -> Result<(), DeviceError> {
        let Some(first) = devices.first_mut() else { return Ok(()) };
        let layout = cpu(first.as_mut())?.share()?.layout.clone();
        check_budgets(devices, &layout, placement)?;
        for device in devices.iter_mut() {
            let share = cpu(device.as_mut())?.share_mut()?;
            share.placement = placement.clone();
            share.counts.iter().for_each(|c| c.store(0, Ordering::Relaxed));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use atoll_bvh::{NoFilter, Ray};

    /// Counts every read, whatever the chunk, and the curve reads apart.
    #[derive(Default)]
    struct Total(AtomicU64, AtomicU64);

    impl Visits for Total {
        fn tlas_node(&self, _: u32) {
            self.0.fetch_add(1, Ordering::Relaxed);
        }
        fn instance(&self, _: u32) {
            self.0.fetch_add(1, Ordering::Relaxed);
        }
        fn blas_node(&self, _: u32, _: u32) {
            self.0.fetch_add(1, Ordering::Relaxed);
        }
        fn triangles(&self, _: u32, _: u32) {
            self.0.fetch_add(1, Ordering::Relaxed);
        }
        fn prim(&self, _: u32, _: u32) {
            self.0.fetch_add(1, Ordering::Relaxed);
        }
        fn curve(&self, _: u32, _: u32) {
            self.0.fetch_add(1, Ordering::Relaxed);
            self.1.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Chunk counters over a scene with instances, and over one of curves,
    /// add up to the reads a plain tally of the same traversals makes, and
    /// land in the tables traversal reads (never in mesh or texture tables).
    #[test]
    fn chunk_counts_sum_to_the_traversals_reads() {
        let hair = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/hair.pbrt");
        let hair = atoll_scene::load_any(&hair).unwrap().scene;
        for (scene, curves) in [(atoll_scene::procedural::bench_scene(20_000), false), (hair, true)] {
            counts_sum_to_the_reads(Arc::new(scene), curves);
        }
    }

    fn counts_sum_to_the_reads(scene: Arc<Scene>, curves: bool) {
        let bvh = SceneBvh::build(&scene);
        let (layout, index) = layout_of(&scene, &bvh, 4096);
        assert!(layout.chunk_count() > 8, "{} chunks", layout.chunk_count());
        let share = Share {
            layout: Arc::new(layout),
            index: Arc::new(index),
            placement: ChunkPlacement::round_robin(0, 1),
            counts: Vec::new(),
            counting: true,
        };
        let share =
            Share { counts: (0..share.layout.chunk_count()).map(|_| AtomicU64::new(0)).collect(), ..share };
        let counter = share.counter().unwrap();
        let total = Total::default();
        let (lo, hi) = scene.world_bounds().expect("a scene with geometry");
        let mut hits = 0;
        for i in 0..2000u32 {
            let f = |k: u32| ((i.wrapping_mul(2654435761).rotate_left(k) % 1000) as f32) / 1000.0;
            let origin = lo.lerp(hi, f(0)) + glam::Vec3::Y * (hi.y - lo.y);
            let target = lo.lerp(hi, f(11));
            let ray = Ray { origin, direction: target - origin, t_max: f32::INFINITY, time: 0.0 };
            let a = bvh.intersect_visiting(&ray, &NoFilter, &counter);
            let b = bvh.intersect_visiting(&ray, &NoFilter, &total);
            assert_eq!(a, b);
            hits += a.is_some() as u32;
            assert_eq!(bvh.occluded_visiting(&ray, &NoFilter, &counter), a.is_some());
            assert_eq!(bvh.occluded_visiting(&ray, &NoFilter, &total), a.is_some());
        }
        assert!(hits > 100, "{hits} hits");
        let counted: u64 = share.counts.iter().map(|c| c.load(Ordering::Relaxed)).sum();
        assert_eq!(counted, total.0.load(Ordering::Relaxed));
        assert_eq!(total.1.load(Ordering::Relaxed) > 0, curves, "curve reads");
        let first_mesh_byte = share.layout.tables[share.index.first_mesh].offset;
        let last_bvh_chunk = share.layout.chunk_of(first_mesh_byte - 1);
        assert!(share.counts[last_bvh_chunk + 1..].iter().all(|c| c.load(Ordering::Relaxed) == 0));
    }
}
