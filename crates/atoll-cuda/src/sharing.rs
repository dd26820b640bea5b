//! GPUs sharing one chunked scene ([`SceneSharing`]): the scene's tables
//! and BVH live in a [`ChunkWindow`], each GPU reading every chunk through
//! its own plain address range (its replica, its owner's memory over
//! NVLink, or host memory), so the kernels keep their pointers.
//!
//! The scene is built once: on the first GPU the usual way (tables
//! uploaded, BVH built there, its arrays copied to the host and freed)
//! where that build fits it; else there in pieces (`bvh::pieces`: groups
//! of BLASes built a piece at a time beside the scene's vertices and
//! triangles, then put together and given a TLAS on the host), so a scene
//! larger than any one GPU still renders; else, where not even a piece
//! fits, on the host by the reference build, which makes the whole build's
//! BVH bit for bit, only slower. The window is then filled from the host
//! copies, and each GPU gets a [`GpuScene`] and [`GpuSceneBvh`] whose
//! arrays are views into its range.
//! Light and material tables (the paper's small structures) stay on
//! every GPU, outside the window, as for any frame.

use std::sync::{Arc, Mutex};

use atoll_bvh::ScenePart;
use atoll_render::device::PrepareStats;
use atoll_render::{ChunkLayout, ChunkPlacement, Device, DeviceError, FrameContext, SceneSharing};
use atoll_scene::Scene;
use cudarc::driver::{CudaSlice, DevicePtr};

use crate::bvh::{reference, BuildOptions, GpuBvhStats, GpuSceneBvh, ScenePlan};
use crate::device::CudaDevice;
use crate::error::CudaError;
use crate::gpu::Gpu;
use crate::scene::{GpuScene, SceneTables, TableCounts};
use crate::window::ChunkWindow;

/// Tables start at multiples of this in the window (what the kernels'
/// widest loads need, and a cache line's worth more).
const TABLE_ALIGN: u64 = 256;

/// The window's tables, in order: [`GpuScene`]'s, then [`GpuSceneBvh`]'s
/// (the [`BVH_TABLES`]), then the scene's curve and motion tables.
const TABLES: [&str; 18] = [
    "vertices",
    "normals",
    "triangles",
    "triangle meshes",
    "meshes",
    "objects",
    "instances",
    "uvs",
    "images",
    "texels",
    "tlas nodes",
    "tlas instances",
    "blas nodes",
    "triangle records",
    "triangle ids",
    "curve pieces of triangles",
    "curve pieces",
    "motions",
];

/// The BVH's tables among [`TABLES`].
const BVH_TABLES: std::ops::Range<usize> = 10..15;

/// Device pointer and bytes of each table of `scene` and `bvh`, in [`TABLES`] order.
fn table_spans(scene: &GpuScene, bvh: &GpuSceneBvh) -> [(u64, u64); 18] {
    fn span<T>(gpu: &Gpu, s: &CudaSlice<T>) -> (u64, u64) {
        (s.device_ptr(&gpu.stream).0, s.num_bytes() as u64)
    }
    let g = &scene.gpu;
    [
        span(g, &scene.vertices),
        span(g, &scene.normals),
        span(g, &scene.triangles),
        span(g, &scene.triangle_mesh),
        span(g, &scene.meshes),
        span(g, &scene.objects),
        span(g, &scene.instances),
        span(g, &scene.uvs),
        span(g, &scene.images),
        span(g, &scene.texels),
        span(g, &bvh.tlas_nodes),
        span(g, &bvh.instances),
        span(g, &bvh.blas_nodes),
        span(g, &bvh.tris),
        span(g, &bvh.tri_ids),
        span(g, &scene.curve_of),
        span(g, &scene.curves),
        span(g, &scene.motions),
    ]
}

/// What a [`GpuScene`] and [`GpuSceneBvh`] hold besides their arrays:
/// copied into every GPU's views.
#[derive(Clone)]
struct SceneMeta {
    counts: TableCounts,
    host_meshes: Vec<crate::layout::GpuMesh>,
    host_objects: Vec<crate::layout::GpuObject>,
    host_instances: Vec<crate::layout::GpuInstance>,
    host_motions: Vec<crate::layout::GpuMotion>,
    tlas_root: i32,
    triangle_test: crate::bvh::TriangleTest,
    blas_roots: Vec<i32>,
    blas_bounds: Vec<crate::bvh::Bounds>,
    blas_tri_bases: Vec<u32>,
    tlas_bounds: crate::bvh::Bounds,
    plan: crate::bvh::ScenePlan,
    options: crate::bvh::BuildOptions,
    stats: GpuBvhStats,
    scene_triangles: u64,
}

/// A view of `len` elements at `ptr` on `gpu`, owned by the window: it
/// must be leaked ([`leak_scene`]), never freed.
///
/// # Safety
/// `ptr` must be mapped on `gpu` for `len` elements of `T` for as long as
/// the view is used.
unsafe fn view<T>(gpu: &Gpu, ptr: u64, bytes: u64) -> CudaSlice<T> {
    let len = (bytes / std::mem::size_of::<T>().max(1) as u64) as usize;
    gpu.stream.upgrade_device_ptr(ptr, len)
}

/// `gpu`'s [`GpuScene`] and [`GpuSceneBvh`] over the window range at
/// `base`, tables where `layout` puts them.
///
/// # Safety
/// `base` must be the base of `gpu`'s range of a window holding `layout`,
/// alive as long as the returned values (which must be leaked, not dropped).
unsafe fn views(
    gpu: &Arc<Gpu>,
    base: u64,
    layout: &ChunkLayout,
    meta: &SceneMeta,
) -> (GpuScene, GpuSceneBvh) {
    let at = |i: usize| (base + layout.tables[i].offset, layout.tables[i].bytes);
    macro_rules! table {
        ($i:expr) => {{
            let (ptr, bytes) = at($i);
            view(gpu, ptr, bytes)
        }};
    }
    let scene = GpuScene {
        gpu: gpu.clone(),
        vertices: table!(0),
        normals: table!(1),
        triangles: table!(2),
        triangle_mesh: table!(3),
        meshes: table!(4),
        objects: table!(5),
        instances: table!(6),
        uvs: table!(7),
        curve_of: table!(15),
        curves: table!(16),
        motions: table!(17),
        images: table!(8),
        texels: table!(9),
        counts: meta.counts,
        host_meshes: meta.host_meshes.clone(),
        host_objects: meta.host_objects.clone(),
        host_instances: meta.host_instances.clone(),
        host_motions: meta.host_motions.clone(),
    };
    let bvh = GpuSceneBvh {
        tlas_nodes: table!(10),
        instances: table!(11),
        blas_nodes: table!(12),
        tris: table!(13),
        tri_ids: table!(14),
        tlas_root: meta.tlas_root,
        triangle_test: meta.triangle_test,
        blas_roots: meta.blas_roots.clone(),
        blas_bounds: meta.blas_bounds.clone(),
        blas_tri_bases: meta.blas_tri_bases.clone(),
        tlas_bounds: meta.tlas_bounds,
        plan: meta.plan.clone(),
        options: meta.options,
        stats: meta.stats.clone(),
        scene_triangles: meta.scene_triangles,
        curves: if meta.counts.curves > 0 { at(16).0 } else { 0 },
        motions: if meta.counts.motions > 0 { at(17).0 } else { 0 },
        tracers: Mutex::new(Vec::new()),
        wide: Mutex::new(None),
    };
    (scene, bvh)
}

/// Lets go of views made by [`views`] without freeing the window's memory
/// (the wide BVH, if one was collapsed, is the GPU's own and is freed).
pub(crate) fn leak_views(scene: GpuScene, bvh: GpuSceneBvh) {
    let GpuScene {
        vertices,
        normals,
        triangles,
        triangle_mesh,
        meshes,
        objects,
        instances,
        uvs,
        curve_of,
        curves,
        motions,
        images,
        texels,
        ..
    } = scene;
    curve_of.leak();
    curves.leak();
    motions.leak();
    vertices.leak();
    normals.leak();
    triangles.leak();
    triangle_mesh.leak();
    meshes.leak();
    objects.leak();
    instances.leak();
    uvs.leak();
    images.leak();
    texels.leak();
    let GpuSceneBvh { tlas_nodes, instances, blas_nodes, tris, tri_ids, .. } = bvh;
    tlas_nodes.leak();
    instances.leak();
    blas_nodes.leak();
    tris.leak();
    tri_ids.leak();
}

/// The scene as laid out, kept from [`CudaSharing::layout`] to
/// [`CudaSharing::prepare`]: every table's bytes on the host.
struct Laid {
    scene: Arc<Scene>,
    chunk_bytes: u64,
    tables: Vec<Box<dyn TableBytes>>,
    meta: SceneMeta,
}

/// A table on the host, read as the bytes the device holds. Tables stay
/// in their own element type: turning a `Vec` into a `Vec<u8>` would copy
/// it, doubling the host's peak for the largest table.
trait TableBytes: Send {
    fn bytes(&self) -> &[u8];
}

impl<T: bytemuck::Pod + Send> TableBytes for Vec<T> {
    fn bytes(&self) -> &[u8] {
        bytemuck::cast_slice(self)
    }
}

/// `v` as a device table holds it: an empty table is one zeroed element on
/// the device (`gpu::upload`), so it is here too.
fn table_bytes<T: bytemuck::Pod + Send>(mut v: Vec<T>) -> Box<dyn TableBytes> {
    if v.is_empty() {
        v.push(T::zeroed());
    }
    Box::new(v)
}

/// Refuses a layout whose host arrays (`needed` bytes) would not fit the
/// host's available memory; `why` says why the host holds them.
fn check_host_memory(needed: u64, why: &str) -> Result<(), CudaError> {
    if let Some(available) = atoll_render::device::host_memory_available() {
        if needed > available {
            return Err(CudaError::Usage(format!(
                "{why}, and on the host it needs {} with {} available",
                crate::error::fmt_bytes(needed),
                crate::error::fmt_bytes(available)
            )));
        }
    }
    Ok(())
}

/// The scene laid out by the host: its tables and the reference build of
/// its BVH (the GPU's build bit for bit), in [`TABLES`] order. For scenes
/// whose build does not fit the leader, even in pieces; refused when it
/// would not fit host memory either.
fn laid_on_host(scene: &Arc<Scene>, chunk_bytes: u64) -> Result<Laid, CudaError> {
    let options = BuildOptions::default();
    let plan = crate::scene::part_plan(scene, &ScenePart::whole(scene));
    // The build's arrays are the GPU build's.
    let needed = plan.scene_tables + plan.bvh;
    check_host_memory(needed, "the scene's build fits no GPU")?;
    tracing::info!(
        "building the scene's BVH on the host: its GPU build ({}) fits no GPU",
        crate::error::fmt_bytes(plan.total())
    );
    let start = std::time::Instant::now();
    let t = SceneTables::build(scene);
    let bvh = reference::build_scene(&t, &options);
    let plan = ScenePlan::new(&t.objects, &t.instances);
    Ok(laid_from(scene, chunk_bytes, t, plan, bvh, options, start))
}

/// Device bytes of the tables a build in pieces keeps on the GPU while it
/// builds: every vertex and triangle of the scene.
fn piece_table_bytes(scene: &Scene) -> u64 {
    let counts = TableCounts::of_part(scene, &ScenePart::whole(scene));
    12 * (counts.vertices.max(1) + counts.triangles.max(1))
}

/// The fewest triangles a piece worth building on a GPU holds (below
/// that, the host builds the BVH).
const MIN_PIECE_TRIANGLES: u64 = 1 << 16;

/// The most triangles of a piece built in `room` device bytes (beside the
/// scene's tables), for a scene of `objects` objects; `None` when fewer
/// than [`MIN_PIECE_TRIANGLES`] fit.
fn piece_capacity(room: u64, objects: u64) -> Option<u32> {
    // Segments: one per object, and one more per piece where objects are cut.
    let segments = objects + 1024;
    let fixed = crate::bvh::piece_bytes(0, segments);
    let per_triangle = crate::bvh::piece_bytes(1 << 20, segments).saturating_sub(fixed).div_ceil(1 << 20);
    // A tenth of the room is left for the allocator and the kernels.
    let capacity = (room - room / 10).saturating_sub(fixed) / per_triangle.max(1);
    (capacity >= MIN_PIECE_TRIANGLES)
        .then(|| capacity.min(crate::bvh::pieces::MAX_PIECE_TRIANGLES as u64) as u32)
}

/// The scene laid out with its BVH built on `gpu` in pieces of as many
/// triangles as `room` device bytes hold besides the scene's vertices and
/// triangles, put together and finished (TLAS) on the host.
fn laid_in_pieces(
    gpu: &Arc<Gpu>,
    room: u64,
    scene: &Arc<Scene>,
    chunk_bytes: u64,
) -> Result<Laid, CudaError> {
    let options = BuildOptions::default();
    // The host ends up holding what the GPUs will: the tables and the
    // resident BVH, as the shared byte model charges them.
    let needed = atoll_bvh::part_bytes(scene, &ScenePart::whole(scene), &crate::scene::shared_byte_model());
    check_host_memory(needed, "the scene's BVH fits no GPU whole")?;
    let tables_on_device = piece_table_bytes(scene);
    let beside_tables = room.min(gpu.free_memory()?).saturating_sub(tables_on_device);
    let capacity = piece_capacity(beside_tables, scene.objects.len() as u64)
        .ok_or_else(|| CudaError::Usage(format!("{}: no room to build the BVH in pieces", gpu.label())))?;
    let start = std::time::Instant::now();
    let t = SceneTables::build(scene);
    let (plan, bvh) = crate::bvh::build_in_pieces(gpu, &t, capacity, &options)?;
    tracing::info!(
        "{}: built the scene's BVH in pieces of at most {capacity} triangles ({} BLASes) in {:.2} s",
        gpu.label(),
        plan.segments(),
        start.elapsed().as_secs_f64()
    );
    Ok(laid_from(scene, chunk_bytes, t, plan, bvh, options, start))
}

/// The window's tables from the scene's host tables `t` and a BVH built
/// for them (`plan`), started at `start`.
fn laid_from(
    scene: &Arc<Scene>,
    chunk_bytes: u64,
    t: SceneTables,
    scene_plan: ScenePlan,
    bvh: crate::bvh::HostSceneBvh,
    options: BuildOptions,
    start: std::time::Instant,
) -> Laid {
    let wall_ms = start.elapsed().as_secs_f64() * 1e3;
    let counts = t.counts();
    let mut stats = GpuBvhStats {
        wall_ms,
        triangles: scene_plan.primitives(),
        blases: scene_plan.segments(),
        instances: scene_plan.valid_instances.len() as u32,
        blas_nodes: bvh.blas_nodes.len() as u32,
        tlas_nodes: bvh.tlas_nodes.len() as u32,
        ..Default::default()
    };
    let (host_meshes, host_objects, host_instances, host_motions) =
        (t.meshes.clone(), t.objects.clone(), t.instances.clone(), t.motions.clone());
    let SceneTables {
        vertices,
        normals,
        triangles,
        triangle_mesh,
        meshes,
        objects,
        instances,
        uvs,
        curve_of,
        curves,
        motions,
        images,
        texels,
    } = t;
    let tables = vec![
        table_bytes(vertices),
        table_bytes(normals),
        table_bytes(triangles),
        table_bytes(triangle_mesh),
        table_bytes(meshes),
        table_bytes(objects),
        table_bytes(instances),
        table_bytes(uvs),
        table_bytes(images),
        table_bytes(texels),
        table_bytes(bvh.tlas_nodes),
        table_bytes(bvh.instances),
        table_bytes(bvh.blas_nodes),
        table_bytes(bvh.tris),
        table_bytes(bvh.tri_ids),
        table_bytes(curve_of),
        table_bytes(curves),
        table_bytes(motions),
    ];
    // What the device holds of the BVH, placeholders included (as `GpuSceneBvh::bytes`).
    stats.bytes = tables[BVH_TABLES].iter().map(|t| t.bytes().len() as u64).sum();
    let meta = SceneMeta {
        counts,
        host_meshes,
        host_objects,
        host_instances,
        host_motions,
        tlas_root: bvh.tlas_root,
        triangle_test: bvh.triangle_test,
        blas_roots: bvh.blas_roots,
        blas_bounds: bvh.blas_bounds,
        blas_tri_bases: bvh.blas_tri_bases,
        tlas_bounds: bvh.tlas_bounds,
        plan: scene_plan,
        options,
        stats,
        scene_triangles: counts.triangles,
    };
    Laid { scene: scene.clone(), chunk_bytes, tables, meta }
}

/// Where the shared scene's BVH is built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Builder {
    /// On the leader, whole (as for one GPU).
    Whole,
    /// On the leader, in pieces within this many bytes.
    Pieces(u64),
    /// On the host (the reference build): slow.
    Host,
}

/// Scene sharing between CUDA GPUs through a [`ChunkWindow`].
pub struct CudaSharing {
    /// The GPU that builds the scene.
    leader: Arc<Gpu>,
    /// The most of the leader's memory the scene may use (`--device-memory`).
    leader_budget: Option<u64>,
    laid: Mutex<Option<Laid>>,
    window: Mutex<Option<Arc<Mutex<ChunkWindow>>>>,
}

impl CudaSharing {
    pub(crate) fn new(leader: Arc<Gpu>, leader_budget: Option<u64>) -> Self {
        Self { leader, leader_budget, laid: Mutex::new(None), window: Mutex::new(None) }
    }

    /// Where the BVH is built: whole on the leader where that fits its
    /// free memory and budget, else there in pieces where a piece fits
    /// beside the scene's vertices and triangles, else on the host.
    fn builder(&self, scene: &Scene) -> Result<Builder, CudaError> {
        let needed = crate::scene::part_plan(scene, &ScenePart::whole(scene)).total();
        let room = self.leader.free_memory()?.min(self.leader_budget.unwrap_or(u64::MAX));
        if needed <= room {
            return Ok(Builder::Whole);
        }
        let beside_tables = room.saturating_sub(piece_table_bytes(scene));
        Ok(match piece_capacity(beside_tables, scene.objects.len() as u64) {
            Some(_) => Builder::Pieces(room),
            None => Builder::Host,
        })
    }
}

/// `device` as a CUDA device, or why it cannot share a GPU scene.
fn cuda(device: &mut dyn Device) -> Result<&mut CudaDevice, DeviceError> {
    let name = device.name();
    device.as_any_mut().downcast_mut::<CudaDevice>().ok_or_else(|| DeviceError::Unsupported {
        device: name,
        what: "sharing a scene with CUDA devices".into(),
    })
}

/// The shared scene's error as every device's.
fn shared_error(e: CudaError) -> DeviceError {
    e.into_device_error("shared scene")
}

/// `bytes` bytes at device pointer `ptr` of `gpu`, copied to the host.
fn download(gpu: &Gpu, ptr: u64, bytes: u64) -> Result<Vec<u8>, CudaError> {
    let mut out = vec![0u8; bytes as usize];
    gpu.ctx.bind_to_thread().map_err(CudaError::driver("binding the context"))?;
    // SAFETY: `ptr` is a live allocation of at least `bytes` bytes on `gpu`
    // (a table of a scene built there), and the stream was synchronised.
    unsafe { cudarc::driver::result::memcpy_dtoh_sync(&mut out, ptr) }
        .map_err(CudaError::driver(format!("{}: downloading a scene table", gpu.label())))?;
    Ok(out)
}

impl SceneSharing for CudaSharing {
    fn name(&self) -> &'static str {
        "CUDA virtual memory"
    }

    fn supports(&self, devices: &[Box<dyn Device>], _scene: &Scene) -> Result<(), String> {
        let mut gpus = Vec::with_capacity(devices.len());
        for device in devices {
            match device.as_any().downcast_ref::<CudaDevice>() {
                Some(d) => gpus.push(d.gpu().clone()),
                None => return Err(format!("{} is not a CUDA device", device.name())),
            }
        }
        for (i, a) in gpus.iter().enumerate() {
            for b in &gpus[i + 1..] {
                if a.ordinal != b.ordinal && !crate::window::can_access_peer(a, b) {
                    return Err(format!("{} cannot read {}'s memory directly", a.label(), b.label()));
                }
            }
        }
        Ok(())
    }

    fn lays_out_slowly(&self, scene: &Scene) -> bool {
        !matches!(self.builder(scene), Ok(Builder::Whole | Builder::Pieces(_)))
    }

    fn layout(
        &self,
        scene: &Arc<Scene>,
        _frame: &Arc<FrameContext>,
        chunk_bytes: u64,
    ) -> Result<ChunkLayout, DeviceError> {
        let gpu = &self.leader;
        let build = || -> Result<Laid, CudaError> {
            let chunk_bytes = ChunkWindow::chunk_bytes_for(std::slice::from_ref(gpu), chunk_bytes)?;
            match self.builder(scene)? {
                Builder::Whole => {}
                Builder::Pieces(room) => return laid_in_pieces(gpu, room, scene, chunk_bytes),
                Builder::Host => return laid_on_host(scene, chunk_bytes),
            }
            let whole = ScenePart::whole(scene);
            let gpu_scene = GpuScene::upload_part(gpu, scene, &whole, None, 0)?;
            let bvh = GpuSceneBvh::build(gpu, &gpu_scene)?;
            gpu.synchronize()?;
            let tables = table_spans(&gpu_scene, &bvh)
                .iter()
                .map(|&(ptr, bytes)| download(gpu, ptr, bytes).map(table_bytes))
                .collect::<Result<Vec<_>, _>>()?;
            let meta = SceneMeta {
                counts: gpu_scene.counts,
                host_meshes: gpu_scene.host_meshes.clone(),
                host_objects: gpu_scene.host_objects.clone(),
                host_instances: gpu_scene.host_instances.clone(),
                host_motions: gpu_scene.host_motions.clone(),
                tlas_root: bvh.tlas_root,
                triangle_test: bvh.triangle_test,
                blas_roots: bvh.blas_roots.clone(),
                blas_bounds: bvh.blas_bounds.clone(),
                blas_tri_bases: bvh.blas_tri_bases.clone(),
                tlas_bounds: bvh.tlas_bounds,
                plan: bvh.plan.clone(),
                options: bvh.options,
                stats: bvh.stats().clone(),
                scene_triangles: bvh.scene_triangles,
            };
            Ok(Laid { scene: scene.clone(), chunk_bytes, tables, meta })
        };
        let laid = build().map_err(|e| e.into_device_error(&gpu.label()))?;
        let sizes =
            TABLES.iter().zip(&laid.tables).map(|(name, t)| (name.to_string(), t.bytes().len() as u64));
        let mut layout = ChunkLayout::new(laid.chunk_bytes, TABLE_ALIGN, sizes);
        // The window maps whole chunks: the last one's unused end counts
        // against the budgets as well.
        let end = layout.bytes();
        let padding = end.next_multiple_of(laid.chunk_bytes) - end;
        layout.tables.push(atoll_render::chunks::ChunkTable {
            name: "unused".into(),
            offset: end,
            bytes: padding,
        });
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
        let laid = self.laid.lock().unwrap_or_else(|p| p.into_inner()).take();
        let laid = laid
            .filter(|l| Arc::ptr_eq(&l.scene, scene) && l.chunk_bytes == layout.chunk_bytes)
            .ok_or_else(|| {
                shared_error(CudaError::Usage(
                    "prepare() needs the layout() of the same scene and chunk size first".into(),
                ))
            })?;
        let mut gpus = Vec::with_capacity(devices.len());
        let mut budgets = Vec::with_capacity(devices.len());
        for device in devices.iter_mut() {
            let device = cuda(device.as_mut())?;
            let gpu = device.gpu().clone();
            budgets.push(device.chunk_budget(&frame.options));
            gpus.push(gpu);
        }
        let window =
            ChunkWindow::new(&gpus, layout.chunk_bytes, placement, &budgets).map_err(shared_error)?;
        for (table, bytes) in layout.tables.iter().zip(&laid.tables) {
            window.write(table.offset, bytes.bytes()).map_err(shared_error)?;
        }
        drop(laid.tables);
        let window = Arc::new(Mutex::new(window));
        *self.window.lock().unwrap_or_else(|p| p.into_inner()) = Some(window.clone());
        let mut stats = Vec::with_capacity(devices.len());
        for (d, device) in devices.iter_mut().enumerate() {
            let device = cuda(device.as_mut())?;
            let gpu = device.gpu().clone();
            let (base, residency) = {
                let w = window.lock().unwrap_or_else(|p| p.into_inner());
                (w.base(d), w.residency(d))
            };
            // SAFETY: `base` is GPU d's range of the window holding `layout`;
            // the device keeps the window alive and leaks the views.
            let (scene_views, bvh_views) = unsafe { views(&gpu, base, layout, &laid.meta) };
            let mut s =
                device.prepare_on_window(frame, scene_views, bvh_views, (window.clone(), d), layout)?;
            s.scene_bytes = residency.local();
            s.shared = Some(residency);
            stats.push(s);
        }
        Ok(stats)
    }

    fn replace(
        &self,
        devices: &mut [Box<dyn Device>],
        placement: &ChunkPlacement,
    ) -> Result<(), DeviceError> {
        let window = self.window.lock().unwrap_or_else(|p| p.into_inner()).clone();
        let window =
            window.ok_or_else(|| shared_error(CudaError::Usage("replace() before prepare()".into())))?;
        let mut budgets = Vec::with_capacity(devices.len());
        for device in devices.iter_mut() {
            let device = cuda(device.as_mut())?;
            device.gpu().synchronize().map_err(shared_error)?;
            let options = device.frame_options().map_err(shared_error)?;
            budgets.push(device.chunk_budget(&options));
        }
        let mut window = window.lock().unwrap_or_else(|p| p.into_inner());
        // With a host tier, chunks leaving a GPU go to the host first: a GPU
        // filled to its budget has no room for the chunks coming in while it
        // still holds those it gives up.
        if let Some(step) = window.placement().via_host(placement) {
            window.replace(&step, &budgets).map_err(shared_error)?;
        }
        window.replace(placement, &budgets).map_err(shared_error)?;
        drop(window);
        for device in devices.iter_mut() {
            cuda(device.as_mut())?.clear_access_counts().map_err(shared_error)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::testing::random_scene;

    #[test]
    fn pieces_fit_the_room_they_are_sized_for() {
        assert_eq!(piece_capacity(0, 10), None);
        assert_eq!(piece_capacity(1 << 20, 10), None, "a MiB holds no piece worth building");
        for (room, objects) in [(256u64 << 20, 3u64), (3 << 30, 9), (80 << 30, 9), (80 << 30, 100_000)] {
            let capacity = piece_capacity(room, objects).expect("room for a piece") as u64;
            assert!(capacity >= MIN_PIECE_TRIANGLES);
            assert!(capacity <= crate::bvh::pieces::MAX_PIECE_TRIANGLES as u64);
            let bytes = crate::bvh::piece_bytes(capacity, objects + 1024);
            assert!(
                bytes <= room - room / 10,
                "{room} B, {objects} objects: {capacity} triangles need {bytes} B"
            );
        }
        // An H100's room holds some 200 M triangles a piece.
        let h100 = piece_capacity(70 << 30, 9).unwrap();
        assert!((150_000_000..=300_000_000).contains(&h100), "{h100}");
    }

    #[test]
    fn the_host_lays_out_the_tables_the_gpu_would_hold() {
        // Objects without instances and empty optional tables (no normals,
        // uvs or images) exercise the one-element placeholders.
        let scene = Arc::new(random_scene(7, 5, 300, 40));
        let laid = laid_on_host(&scene, 2 << 20).unwrap();
        assert_eq!(laid.tables.len(), TABLES.len());
        let whole = ScenePart::whole(&scene);
        let plan = crate::scene::part_plan(&scene, &whole);
        let scene_table_bytes: u64 = (0..TABLES.len())
            .filter(|i| !BVH_TABLES.contains(i))
            .map(|i| laid.tables[i].bytes().len() as u64)
            .sum();
        assert_eq!(scene_table_bytes, plan.scene_tables, "the device byte model's table sizes");
        let bvh_bytes: u64 = laid.tables[BVH_TABLES].iter().map(|t| t.bytes().len() as u64).sum();
        assert!(bvh_bytes > 0 && bvh_bytes <= plan.bvh, "{bvh_bytes} BVH bytes against {}", plan.bvh);
        assert_eq!(bvh_bytes, laid.meta.stats.bytes);
        let triangles: u64 = scene.meshes.iter().map(|m| m.triangle_count() as u64).sum();
        assert_eq!(laid.meta.stats.triangles as u64, triangles);
        assert_eq!(laid.meta.scene_triangles, triangles);
        // Every BLAS leaf's records and every TLAS instance are laid out.
        assert_eq!(
            laid.tables[13].bytes().len(),
            triangles as usize * std::mem::size_of::<crate::bvh::GpuTriRecord>()
        );
        assert_eq!(laid.tables[14].bytes().len(), triangles as usize * 4);
        assert_eq!(laid.meta.stats.instances as usize, laid.meta.plan.valid_instances.len());
        // The shared byte model (memory preflights of shared scenes) bounds
        // what is laid out, below the model that charges a whole build.
        let laid_bytes: u64 = laid.tables.iter().map(|t| t.bytes().len() as u64).sum();
        let shared = atoll_bvh::part_bytes(&scene, &whole, &crate::scene::shared_byte_model());
        let built = atoll_bvh::part_bytes(&scene, &whole, &crate::scene::byte_model());
        assert!(
            laid_bytes <= shared && shared < built,
            "laid {laid_bytes}, shared model {shared}, build {built}"
        );
    }
}
