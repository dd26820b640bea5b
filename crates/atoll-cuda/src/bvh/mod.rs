//! The GPU BVH: an LBVH built on the GPU (Karras 2012, as DSGPURayTracing
//! does), improved by treelet restructuring (Karras & Aila 2013) and laid
//! out for traversal as Aila & Laine's two-children-per-node BVH2.
//!
//! Two levels, like `atoll_bvh::SceneBvh`: one BLAS per object with
//! triangles (all built together, one segment each, in one launch sequence)
//! and a TLAS over the instances' world boxes. The pieces:
//! - `layout`: the traversal layout shared with `kernels/bvh.cuh`;
//! - `lbvh`, [`sort`]: host side of the build kernels (`lbvh.cu`,
//!   `treelet.cu`, `sort.cu`);
//! - `reference`: the same build on the host, bit for bit: what tests
//!   compare the GPU's with, what SAH comparisons without a GPU use, and
//!   the build of a scene too large for any one GPU to build (shared scene
//!   memory, `crate::sharing`);
//!   `host`: the tables on the host (download, checks, SAH; a host traversal
//!   in tests).

mod host;
pub(crate) mod layout;
mod lbvh;
pub(crate) mod pieces;
pub mod reference;
pub mod sort;
// The test scenes only serve tests (this crate's, and its integration
// tests through the `testing` feature).
#[cfg(any(test, feature = "testing"))]
pub mod testing;
mod treelet_reference;
pub(crate) mod wide;

use std::sync::Mutex;
use std::time::Instant;

use cudarc::driver::{CudaSlice, DeviceRepr, PushKernelArg, ValidAsZeroBits};

pub use host::{HostHit, HostSceneBvh, ScenePlan};
pub use layout::{GpuBvhNode, GpuTlasInstance, GpuTriRecord, TriangleTest, CURVE_RECORD_MARKER};

use crate::error::CudaError;
use crate::gpu::{launch_1d, Gpu};
use crate::scene::{GpuScene, SceneTables};
use crate::trace::Tracer;
use layout::{LEAF_FIRST_BITS, LINK_DONE, MAX_LEAF_PRIMS};
use lbvh::{launch_err, BuildArrays, LbvhKernels, Phases, THREADS};

/// The kernel files a BVH build on the GPU loads (compiled ahead with a
/// frame's other modules, [`crate::gpu::Gpu::compile_ahead`]).
pub(crate) const BUILD_FILES: [&str; 3] = [lbvh::FILE, sort::FILE, "treelet.cu"];

/// How the GPU BVH is built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildOptions {
    /// Rounds of treelet restructuring after the LBVH (0: the plain LBVH).
    pub treelet_rounds: u32,
    /// Round `r` restructures nodes over at least `treelet_gamma << r`
    /// primitives: the first round works everywhere above the leaves,
    /// later ones only higher up, where most of the remaining gain is.
    pub treelet_gamma: u32,
    /// Most triangles per BLAS leaf (1..=4); TLAS leaves hold one instance.
    pub max_leaf: u32,
    pub triangle_test: TriangleTest,
    /// SAH constants, as `atoll_bvh::BuildOptions::TRIANGLES`.
    pub traversal_cost: f32,
    pub intersection_cost: f32,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            treelet_rounds: 3,
            treelet_gamma: 7,
            max_leaf: MAX_LEAF_PRIMS,
            triangle_test: TriangleTest::Exact,
            traversal_cost: atoll_bvh::BuildOptions::TRIANGLES.traversal_cost,
            intersection_cost: atoll_bvh::BuildOptions::TRIANGLES.intersection_cost,
        }
    }
}

impl BuildOptions {
    /// The plain LBVH: no treelet rounds.
    pub fn lbvh() -> Self {
        BuildOptions { treelet_rounds: 0, ..Self::default() }
    }

    /// The primitive threshold of treelet round `round`.
    pub(crate) fn gamma(&self, round: u32) -> u32 {
        self.treelet_gamma.saturating_mul(1u32.checked_shl(round).unwrap_or(u32::MAX))
    }

    fn check(&self) -> Result<(), CudaError> {
        if !(1..=MAX_LEAF_PRIMS).contains(&self.max_leaf) || self.treelet_gamma < 7 {
            return Err(CudaError::Usage(format!(
                "GPU BVH: max_leaf must be 1..={MAX_LEAF_PRIMS} and treelet_gamma at least 7 (got {} and {})",
                self.max_leaf, self.treelet_gamma
            )));
        }
        Ok(())
    }
}

/// Sizes, device times and quality of a build.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GpuBvhStats {
    /// Device milliseconds per BLAS phase (CUDA events): morton (boxes and
    /// codes), sort, tree, bounds, quality (treelets), collapse, layout;
    /// then "tlas", the whole TLAS build.
    pub phases: Vec<(&'static str, f32)>,
    /// Sum of the phases.
    pub device_ms: f32,
    /// Host wall time of the whole build, kernel loading excluded.
    pub wall_ms: f64,
    pub triangles: u32,
    /// BLASes (objects with triangles).
    pub blases: u32,
    pub instances: u32,
    pub blas_nodes: u32,
    pub tlas_nodes: u32,
    /// Resident bytes (nodes, triangle records and ids, instance records).
    pub bytes: u64,
    /// Device bytes the build allocated at most (resident ones included).
    pub build_bytes: u64,
    /// SAH cost of the BLASes (mean weighted by triangle count) and of the
    /// TLAS, from the build's own per-node costs (no download).
    pub blas_sah: f32,
    pub tlas_sah: f32,
}

impl GpuBvhStats {
    /// Millions of BLAS triangles built per second of device time.
    pub fn mtris_per_s(&self) -> f64 {
        self.triangles as f64 / self.device_ms.max(1e-6) as f64 / 1e3
    }
}

/// The GPU BVH of a [`GpuScene`]: BLAS nodes, triangle records (and their
/// global triangle ids) in leaf order, TLAS nodes and instance records.
pub struct GpuSceneBvh {
    pub blas_nodes: CudaSlice<GpuBvhNode>,
    pub tlas_nodes: CudaSlice<GpuBvhNode>,
    pub tris: CudaSlice<GpuTriRecord>,
    pub tri_ids: CudaSlice<u32>,
    pub instances: CudaSlice<GpuTlasInstance>,
    /// Where traversal starts (a node, a leaf, or `LINK_DONE` when empty).
    pub tlas_root: i32,
    pub triangle_test: TriangleTest,
    /// Root link, box and first triangle record of each BLAS (host copies;
    /// see `GpuTlasInstance::tri_base`).
    pub blas_roots: Vec<i32>,
    pub blas_bounds: Vec<Bounds>,
    pub blas_tri_bases: Vec<u32>,
    pub tlas_bounds: Bounds,
    pub plan: ScenePlan,
    pub options: BuildOptions,
    pub(crate) stats: GpuBvhStats,
    /// Triangles of the scene it was built for (checked by the trace functions).
    pub(crate) scene_triangles: u64,
    /// Device pointer of that scene's curve pieces (`GpuScene::curves`),
    /// which records marked `CURVE_RECORD_MARKER` index; 0 without curves.
    pub(crate) curves: u64,
    /// Device pointer of that scene's motions (`GpuScene::motions`), which
    /// moving instance records index; 0 where nothing moves.
    pub(crate) motions: u64,
    /// Per [`crate::Gpu`] (by its `id`: one stream each) that traces this
    /// BVH, the trace kernels and the persistent-threads counter, made on
    /// first use.
    pub(crate) tracers: Mutex<Vec<(u64, Tracer)>>,
    /// The compressed wide BVH, collapsed from this one at the first wide trace.
    pub(crate) wide: Mutex<Option<wide::WideBvh>>,
}

/// Room for `len` entries that the build's kernels write every one of
/// (the BLAS's nodes and triangle records): not cleared first, which would
/// cost a pass over memory that is all written again.
fn written_in_full<T: DeviceRepr>(gpu: &Gpu, len: u64, what: &str) -> Result<CudaSlice<T>, CudaError> {
    // SAFETY: device memory, not Rust memory: until the kernels write it,
    // its contents are garbage values no one reads (the callers' kernels
    // write all `len` entries: every kept node, and a permutation of the
    // triangles, checked against the count).
    unsafe { gpu.stream.alloc::<T>(len.max(1) as usize) }
        .map_err(CudaError::driver(format!("{}: allocating {what} ({len} entries)", gpu.label())))
}

fn alloc<T: DeviceRepr + ValidAsZeroBits>(
    gpu: &Gpu,
    len: u64,
    what: &str,
) -> Result<CudaSlice<T>, CudaError> {
    gpu.stream
        .alloc_zeros::<T>(len.max(1) as usize)
        .map_err(CudaError::driver(format!("{}: allocating {what} ({len} entries)", gpu.label())))
}

fn upload<T: DeviceRepr + ValidAsZeroBits + Copy>(
    gpu: &Gpu,
    data: &[T],
    what: &str,
) -> Result<CudaSlice<T>, CudaError> {
    if data.is_empty() {
        return alloc(gpu, 1, what);
    }
    gpu.stream.clone_htod(data).map_err(CudaError::driver(format!("{}: uploading {what}", gpu.label())))
}

/// Most valid instances whose TLAS is built on the host: there the host
/// build takes less time than the device build's launches and read-back
/// (BENCHMARKS.md).
const HOST_TLAS_MAX_INSTANCES: u32 = 16;

/// A built TLAS on the device.
struct DeviceTlas {
    nodes: CudaSlice<GpuBvhNode>,
    node_count: u32,
    instances: CudaSlice<GpuTlasInstance>,
    /// Root link, root box and root SAH cost (area-weighted).
    root: (i32, Bounds, f32),
    /// Device bytes the build allocated besides its outputs.
    scratch_bytes: u64,
}

/// The TLAS built on the host (`reference::build_tlas`, the device build's
/// twin) from the BLAS roots read back, and uploaded.
fn tlas_on_host(
    gpu: &Gpu,
    scene: &GpuScene,
    plan: &ScenePlan,
    blas: &[(i32, Bounds, f32)],
    options: &BuildOptions,
) -> Result<DeviceTlas, CudaError> {
    let roots: Vec<i32> = blas.iter().map(|r| r.0).collect();
    let bounds: Vec<Bounds> = blas.iter().map(|r| r.1).collect();
    let bases = vec![0; roots.len()];
    let t = reference::build_tlas(
        plan,
        &scene.host_instances,
        &scene.host_motions,
        &roots,
        &bounds,
        &bases,
        options,
    );
    Ok(DeviceTlas {
        nodes: upload(gpu, &t.nodes, "TLAS nodes")?,
        node_count: t.nodes.len() as u32,
        instances: upload(gpu, &t.instances, "instance records")?,
        root: (t.root, t.bounds, t.cost),
        scratch_bytes: 0,
    })
}

/// The TLAS built on the device over the instances' world boxes, from the
/// BLAS build's root links and boxes (`a`).
fn tlas_on_device(
    gpu: &Gpu,
    k: &LbvhKernels,
    scene: &GpuScene,
    plan: &ScenePlan,
    a: &BuildArrays,
    options: &BuildOptions,
    tlas_phases: &mut Phases,
) -> Result<DeviceTlas, CudaError> {
    let v = plan.valid_instances.len() as u32;
    let object_segment = upload(gpu, &plan.object_segment, "object segments")?;
    let valid = upload(gpu, &plan.valid_instances, "valid instances")?;
    let mut t = BuildArrays::new(gpu, &[0, v])?;
    let (mut tlas_nodes, mut instances) = (alloc(gpu, 1, "TLAS nodes")?, alloc(gpu, 1, "instance records")?);
    let mut tlas_node_count = 0;
    if v > 0 {
        t.init_seg_bounds(gpu, k)?;
        let config = t.box_launch();
        let mut launch = gpu.stream.launch_builder(&k.tlas_boxes);
        launch
            .arg(&valid)
            .arg(&scene.instances)
            .arg(&scene.motions)
            .arg(&object_segment)
            .arg(&a.root_box)
            .arg(&t.seg_start)
            .arg(&v)
            .arg(&mut t.prim_box)
            .arg(&mut t.seg_bounds);
        // SAFETY: matches `lbvh_tlas_boxes(const unsigned* valid, const GpuInstance*
        // instances, const GpuMotion* motions, const unsigned* object_segment, const float4* seg_root_box, const
        // unsigned* seg_start, unsigned P, float4* prim_box, unsigned* seg_bounds)`; valid
        // instances index `instances` and name objects with a segment (ScenePlan), whose
        // root box the BLAS build wrote; a moving instance's `motion` is a row of `motions`
        // (made with the instances), whose box it takes instead.
        unsafe { launch.launch(config) }.map_err(launch_err(gpu, "lbvh_tlas_boxes"))?;
        t.build_tree(gpu, k, 1, options, tlas_phases)?;
        let (nodes, records) = t.collapse(gpu, k, 1, tlas_phases)?;
        if records != v {
            return Err(CudaError::Usage(format!("GPU BVH build: {records} TLAS leaves for {v} instances")));
        }
        tlas_node_count = nodes;
        tlas_nodes = alloc(gpu, nodes as u64, "TLAS nodes")?;
        t.emit_nodes(gpu, k, &mut tlas_nodes)?;
        instances = alloc(gpu, v as u64, "instance records")?;
        let mut launch = gpu.stream.launch_builder(&k.emit_instances);
        launch
            .arg(&v)
            .arg(&t.child)
            .arg(&t.leaf_size)
            .arg(&t.tri_offset)
            .arg(&t.values)
            .arg(&valid)
            .arg(&scene.instances)
            .arg(&object_segment)
            .arg(&a.root_link)
            .arg(&mut instances);
        // SAFETY: matches `lbvh_emit_instances(unsigned P, const uint2* child, const unsigned*
        // leaf_size, const unsigned* tri_offset, const unsigned* values, const unsigned* valid,
        // const GpuInstance* instances, const unsigned* object_segment, const int*
        // seg_root_link, TlasInstance* out)`; 2V threads, leaf offsets a permutation of 0..V.
        unsafe { launch.launch(launch_1d(2 * v, THREADS)) }
            .map_err(launch_err(gpu, "lbvh_emit_instances"))?;
    }
    let root = if v > 0 { download_roots(gpu, &t)?[0] } else { (LINK_DONE, ([0.0; 3], [0.0; 3]), 0.0) };
    let scratch_bytes =
        BuildArrays::bytes(v as u64, 1) + (object_segment.num_bytes() + valid.num_bytes()) as u64;
    Ok(DeviceTlas { nodes: tlas_nodes, node_count: tlas_node_count, instances, root, scratch_bytes })
}

/// Per segment (root link, box with the root's SAH cost in `min.w`), read back.
fn download_roots(gpu: &Gpu, a: &BuildArrays) -> Result<Vec<(i32, Bounds, f32)>, CudaError> {
    let err = || CudaError::driver(format!("{}: reading BVH roots", gpu.label()));
    let links = gpu.stream.clone_dtoh(&a.root_link).map_err(err())?;
    let boxes = gpu.stream.clone_dtoh(&a.root_box).map_err(err())?;
    Ok((0..a.segments as usize)
        .map(|s| {
            let b = &boxes[8 * s..8 * s + 8];
            (links[s], ([b[0], b[1], b[2]], [b[4], b[5], b[6]]), b[3])
        })
        .collect())
}

fn area(b: &Bounds) -> f32 {
    box_area(b.0, b.1)
}

/// A box as (min, max).
pub(crate) type Bounds = ([f32; 3], [f32; 3]);

/// Surface area, as `box_area` in lbvh.cuh (and `atoll_bvh::Aabb::area`).
pub(crate) fn box_area(lo: [f32; 3], hi: [f32; 3]) -> f32 {
    let e = |k: usize| (hi[k] - lo[k]).max(0.0);
    let (ex, ey, ez) = (e(0), e(1), e(2));
    2.0 * ((ex * ey + ey * ez) + ez * ex)
}

/// Device bytes a build over `triangles` triangles in `segments` BLASes and
/// `instances` instances allocates at most (node arrays sized for the worst
/// case of one triangle per leaf).
pub fn build_bytes(triangles: u64, segments: u64, instances: u64) -> u64 {
    let blas_out = triangles.max(1) * (48 + 4) + triangles.max(1) * 64;
    let tlas_out = 2 * instances.max(1) * 64;
    let uploads = 4 * (segments.max(1) + 2 * instances.max(1) + 2);
    BuildArrays::bytes(triangles, segments) + blas_out + BuildArrays::bytes(instances, 1) + tlas_out + uploads
}

/// Device bytes the GPU BVH of a scene of `triangles` (as uploaded) and
/// `instances` needs at most while building (what a memory plan should
/// reserve; about 270 bytes per triangle, of which the resident BVH keeps
/// about 80). Assumes no
/// more BLASes than instances.
#[cfg(test)]
pub(crate) fn estimate_bytes(triangles: u64, instances: u64) -> u64 {
    build_bytes(triangles, instances.min(triangles).max(1), instances)
}

/// The BLASes of a build on the device, with the build arrays they came
/// from (the TLAS build reads their roots).
struct DeviceBlases {
    a: BuildArrays,
    nodes: CudaSlice<GpuBvhNode>,
    node_count: u32,
    tris: CudaSlice<GpuTriRecord>,
    tri_ids: CudaSlice<u32>,
    seg_first_tri: CudaSlice<u32>,
}

/// The scene tables a BLAS build reads on the device.
#[derive(Clone, Copy)]
struct BuildTables<'a> {
    vertices: &'a CudaSlice<f32>,
    triangles: &'a CudaSlice<u32>,
    /// `SceneTables::curve_of`, where the scene has curves: their
    /// triangles get curve records.
    curve_of: Option<&'a CudaSlice<u32>>,
}

/// Builds the BLASes of `plan`'s segments (triangles `plan.seg_first_tri`
/// onwards of `t.triangles`, corners in `t.vertices`), all at once.
fn device_blases(
    gpu: &Gpu,
    k: &LbvhKernels,
    t: BuildTables<'_>,
    plan: &ScenePlan,
    options: &BuildOptions,
    phases: &mut Phases,
) -> Result<DeviceBlases, CudaError> {
    let p = plan.primitives();
    let test = options.triangle_test;
    let mut a = BuildArrays::new(gpu, &plan.seg_start)?;
    let seg_first_tri = upload(gpu, &plan.seg_first_tri, "segment triangles")?;
    let (mut blas_nodes, mut tris, mut tri_ids) =
        (alloc(gpu, 1, "BLAS nodes")?, alloc(gpu, 1, "triangles")?, alloc(gpu, 1, "triangle ids")?);
    let mut blas_node_count = 0;
    if p > 0 {
        a.init_seg_bounds(gpu, k)?;
        let config = a.box_launch();
        let mut launch = gpu.stream.launch_builder(&k.blas_boxes);
        launch
            .arg(t.vertices)
            .arg(t.triangles)
            .arg(&a.seg_start)
            .arg(&seg_first_tri)
            .arg(&a.segments)
            .arg(&p)
            .arg(&mut a.prim_box)
            .arg(&mut a.seg_bounds);
        // SAFETY: matches `lbvh_blas_boxes(const float* vertices, const unsigned* triangles,
        // const unsigned* seg_start, const unsigned* seg_first_tri, unsigned segments,
        // unsigned P, float4* prim_box, unsigned* seg_bounds)`; segments are triangle
        // ranges of `triangles`, whose vertex indices address `vertices` (the callers'
        // tables), prim_box holds 2P float4 and seg_bounds 8 words per segment.
        unsafe { launch.launch(config) }.map_err(launch_err(gpu, "lbvh_blas_boxes"))?;
        a.build_tree(gpu, k, options.max_leaf, options, phases)?;
        atoll_scene::progress::built(p as u64);
        let (nodes, records) = a.collapse(gpu, k, options.max_leaf, phases)?;
        if records != p {
            return Err(CudaError::Usage(format!(
                "GPU BVH build: {records} leaf triangles for {p} triangles"
            )));
        }
        blas_node_count = nodes;
        blas_nodes = written_in_full(gpu, nodes as u64, "BLAS nodes")?;
        a.emit_nodes(gpu, k, &mut blas_nodes)?;
        tris = written_in_full(gpu, p as u64, "triangle records")?;
        tri_ids = written_in_full(gpu, p as u64, "triangle ids")?;
        let test_value = test.kernel_value();
        let null: u64 = 0;
        let mut launch = gpu.stream.launch_builder(&k.emit_triangles);
        launch
            .arg(&p)
            .arg(&a.child)
            .arg(&a.leaf_size)
            .arg(&a.tri_offset)
            .arg(&a.values)
            .arg(&a.seg_start)
            .arg(&seg_first_tri)
            .arg(&a.segments)
            .arg(t.vertices)
            .arg(t.triangles);
        match t.curve_of {
            Some(c) => launch.arg(c),
            None => launch.arg(&null),
        };
        launch.arg(&test_value).arg(&mut tris).arg(&mut tri_ids);
        // SAFETY: matches `lbvh_emit_triangles(unsigned P, const uint2* child, const unsigned*
        // leaf_size, const unsigned* tri_offset, const unsigned* values, const unsigned*
        // seg_start, const unsigned* seg_first_tri, unsigned segments, const float* vertices,
        // const unsigned* triangles, const unsigned* curve_of, int test, TriRecord* out_tris,
        // unsigned* out_ids)`; 2P threads; leaf offsets are a permutation of 0..P (checked:
        // `records == p`); `curve_of` is null or holds a word per triangle of `triangles`.
        unsafe { launch.launch(launch_1d(2 * p, THREADS)) }
            .map_err(launch_err(gpu, "lbvh_emit_triangles"))?;
    }
    phases.mark(gpu, "layout")?;
    Ok(DeviceBlases { a, nodes: blas_nodes, node_count: blas_node_count, tris, tri_ids, seg_first_tri })
}

/// Device bytes [`blases_on_device`] allocates for `triangles` in
/// `segments` (node arrays sized for one triangle per leaf).
pub(crate) fn piece_bytes(triangles: u64, segments: u64) -> u64 {
    BuildArrays::bytes(triangles, segments) + triangles.max(1) * (48 + 4 + 64) + 4 * (segments + 2)
}

/// The BLASes of a piece's plan (`pieces::piece_plan`), built on `gpu`
/// from the scene's `vertices` and `triangles` (device tables the plan
/// indexes) and downloaded: links and records from 0, as
/// `reference::build_blases` makes them.
fn blases_on_device(
    gpu: &Gpu,
    tables: BuildTables<'_>,
    plan: &ScenePlan,
    options: &BuildOptions,
) -> Result<reference::HostBlases, CudaError> {
    options.check()?;
    let k = LbvhKernels::load(gpu)?;
    let start = Instant::now();
    let mut phases = Phases::start(gpu)?;
    let b = device_blases(gpu, &k, tables, plan, options, &mut phases)?;
    let roots = download_roots(gpu, &b.a)?;
    let device_ms: f32 = phases.finish()?.iter().map(|(_, ms)| ms).sum();
    let built = start.elapsed().as_secs_f64();
    let err = || CudaError::driver(format!("{}: downloading a piece of the BVH", gpu.label()));
    let p = plan.primitives() as usize;
    let mut nodes = gpu.stream.clone_dtoh(&b.nodes).map_err(err())?;
    nodes.truncate(b.node_count as usize);
    let mut tris = gpu.stream.clone_dtoh(&b.tris).map_err(err())?;
    tris.truncate(p);
    let mut tri_ids = gpu.stream.clone_dtoh(&b.tri_ids).map_err(err())?;
    tri_ids.truncate(p);
    // The piece's device memory back to the driver before the next piece.
    drop(b);
    gpu.synchronize()?;
    tracing::info!(
        "{}: BVH piece of {} triangles: built in {:.2} s ({device_ms:.0} ms on the device), downloaded in {:.2} s",
        gpu.label(),
        plan.primitives(),
        built,
        start.elapsed().as_secs_f64() - built
    );
    Ok(reference::HostBlases {
        nodes,
        tris,
        tri_ids,
        tri_bases: vec![0; roots.len()],
        bounds: roots.iter().map(|r| r.1).collect(),
        roots: roots.iter().map(|r| r.0).collect(),
    })
}

/// The scene BVH of `t` built on `gpu` in pieces of at most `capacity`
/// triangles (`pieces`), as shared scene memory builds a scene whose whole
/// build fits no GPU; with the plan it was built for (objects larger than
/// `capacity` cut into segments). Needs room for `t`'s vertices and
/// triangles and `piece_bytes` of a piece.
pub fn build_in_pieces(
    gpu: &Gpu,
    t: &SceneTables,
    capacity: u32,
    options: &BuildOptions,
) -> Result<(ScenePlan, HostSceneBvh), CudaError> {
    let vertices = upload(gpu, &t.vertices, "vertices")?;
    let triangles = upload(gpu, &t.triangles, "triangles")?;
    let curve_of = if t.curve_of.is_empty() { None } else { Some(upload(gpu, &t.curve_of, "curve pieces")?) };
    let (plan, blases) = pieces::build_blases_in_pieces(t, capacity, |piece| {
        let tables = BuildTables { vertices: &vertices, triangles: &triangles, curve_of: curve_of.as_ref() };
        blases_on_device(gpu, tables, piece, options)
    })?;
    drop((vertices, triangles, curve_of));
    // Freed device memory goes back to the driver at a synchronisation:
    // here, before the host builds the TLAS (the next use of the GPU, the
    // scene's window, is sized by its free memory).
    gpu.synchronize()?;
    let start = Instant::now();
    let bvh = reference::with_tlas(t, &plan, blases, options);
    tracing::info!(
        "TLAS of {} records over the pieces built on the host in {:.2} s",
        bvh.instances.len(),
        start.elapsed().as_secs_f64()
    );
    Ok((plan, bvh))
}

impl GpuSceneBvh {
    /// Builds with [`BuildOptions::default`].
    pub fn build(gpu: &Gpu, scene: &GpuScene) -> Result<GpuSceneBvh, CudaError> {
        Self::build_with(gpu, scene, &BuildOptions::default())
    }

    /// Builds the BLASes of every object with triangles and the TLAS over
    /// the instances of those objects (see [`ScenePlan`]).
    pub fn build_with(gpu: &Gpu, scene: &GpuScene, options: &BuildOptions) -> Result<GpuSceneBvh, CudaError> {
        options.check()?;
        let plan = ScenePlan::new(&scene.host_objects, &scene.host_instances);
        let p = plan.primitives();
        let v = plan.valid_instances.len() as u32;
        if p >= 1 << LEAF_FIRST_BITS || v >= 1 << LEAF_FIRST_BITS {
            return Err(CudaError::Usage(format!(
                "GPU BVH: {p} triangles / {v} instances exceed the layout's limit of {}",
                1u32 << LEAF_FIRST_BITS
            )));
        }
        let k = LbvhKernels::load(gpu)?;
        let wall = Instant::now();
        let mut phases = Phases::start(gpu)?;
        let test = options.triangle_test;

        // BLASes: all objects at once, one segment each.
        let tables = BuildTables {
            vertices: &scene.vertices,
            triangles: &scene.triangles,
            curve_of: scene.curve_pieces(),
        };
        let DeviceBlases { a, nodes: blas_nodes, node_count: blas_node_count, tris, tri_ids, seg_first_tri } =
            device_blases(gpu, &k, tables, &plan, options, &mut phases)?;
        let blas = download_roots(gpu, &a)?;

        // The TLAS over the valid instances' world boxes: a few instances
        // on the host (launches and a read-back would cost more than the
        // build), more on the device (the BLAS arrays stay alive: their root
        // links and boxes are its input).
        let mut tlas_phases = Phases::start(gpu)?;
        let tlas = if v <= HOST_TLAS_MAX_INSTANCES {
            tlas_on_host(gpu, scene, &plan, &blas, options)?
        } else {
            tlas_on_device(gpu, &k, scene, &plan, &a, options, &mut tlas_phases)?
        };
        tlas_phases.mark(gpu, "tlas")?;
        let build_bytes = BuildArrays::bytes(p as u64, plan.segments() as u64)
            + tlas.scratch_bytes
            + [blas_nodes.num_bytes(), tris.num_bytes(), tri_ids.num_bytes(), tlas.nodes.num_bytes()]
                .iter()
                .map(|&b| b as u64)
                .sum::<u64>()
            + (tlas.instances.num_bytes() + seg_first_tri.num_bytes()) as u64;
        drop(a);

        let mut stats = GpuBvhStats {
            phases: phases.finish()?,
            triangles: p,
            blases: plan.segments(),
            instances: v,
            blas_nodes: blas_node_count,
            tlas_nodes: tlas.node_count,
            build_bytes,
            ..Default::default()
        };
        let tlas_ms: f32 = tlas_phases.finish()?.iter().map(|(_, ms)| ms).sum();
        stats.phases.push(("tlas", tlas_ms));
        stats.device_ms = stats.phases.iter().map(|(_, ms)| ms).sum();
        stats.wall_ms = wall.elapsed().as_secs_f64() * 1e3;
        let weighted: f64 = (0..blas.len())
            .map(|s| {
                let n = (plan.seg_start[s + 1] - plan.seg_start[s]) as f64;
                (blas[s].2 / area(&blas[s].1).max(f32::MIN_POSITIVE)) as f64 * n
            })
            .sum();
        stats.blas_sah = (weighted / p.max(1) as f64) as f32;
        stats.tlas_sah = if v > 0 { tlas.root.2 / area(&tlas.root.1).max(f32::MIN_POSITIVE) } else { 0.0 };
        let bvh = GpuSceneBvh {
            blas_nodes,
            tlas_nodes: tlas.nodes,
            tris,
            tri_ids,
            instances: tlas.instances,
            tlas_root: tlas.root.0,
            triangle_test: test,
            blas_roots: blas.iter().map(|r| r.0).collect(),
            blas_bounds: blas.iter().map(|r| r.1).collect(),
            blas_tri_bases: vec![0; blas.len()],
            tlas_bounds: tlas.root.1,
            plan,
            options: *options,
            stats,
            scene_triangles: scene.counts.triangles,
            curves: scene.curve_pieces().map_or(0, |_| {
                use cudarc::driver::DevicePtr;
                scene.curves.device_ptr(&gpu.stream).0
            }),
            motions: scene.moving().map_or(0, |m| {
                use cudarc::driver::DevicePtr;
                m.device_ptr(&gpu.stream).0
            }),
            tracers: Mutex::new(Vec::new()),
            wide: Mutex::new(None),
        };
        let bytes = bvh.bytes();
        Ok(GpuSceneBvh { stats: GpuBvhStats { bytes, ..bvh.stats.clone() }, ..bvh })
    }

    /// Sizes, phase times and SAH of the build.
    pub fn stats(&self) -> &GpuBvhStats {
        &self.stats
    }

    /// SAH cost of the BLASes (what `PrepareStats::bvh_sah_cost` reports).
    pub(crate) fn sah_cost(&self) -> f32 {
        self.stats.blas_sah
    }

    /// Resident device bytes.
    pub(crate) fn bytes(&self) -> u64 {
        (self.blas_nodes.num_bytes()
            + self.tlas_nodes.num_bytes()
            + self.tris.num_bytes()
            + self.tri_ids.num_bytes()
            + self.instances.num_bytes()) as u64
    }

    /// The tables on the host (for checks, SAH and host traversal).
    pub fn download(&self, gpu: &Gpu) -> Result<HostSceneBvh, CudaError> {
        let err = || CudaError::driver(format!("{}: downloading the BVH", gpu.label()));
        fn take<T>(mut v: Vec<T>, n: u32) -> Vec<T> {
            v.truncate(n as usize);
            v
        }
        let s = &self.stats;
        Ok(HostSceneBvh {
            blas_nodes: take(gpu.stream.clone_dtoh(&self.blas_nodes).map_err(err())?, s.blas_nodes),
            tlas_nodes: take(gpu.stream.clone_dtoh(&self.tlas_nodes).map_err(err())?, s.tlas_nodes),
            tris: take(gpu.stream.clone_dtoh(&self.tris).map_err(err())?, s.triangles),
            tri_ids: take(gpu.stream.clone_dtoh(&self.tri_ids).map_err(err())?, s.triangles),
            instances: take(gpu.stream.clone_dtoh(&self.instances).map_err(err())?, s.instances),
            tlas_root: self.tlas_root,
            blas_roots: self.blas_roots.clone(),
            blas_bounds: self.blas_bounds.clone(),
            blas_tri_bases: self.blas_tri_bases.clone(),
            tlas_bounds: self.tlas_bounds,
            triangle_test: self.triangle_test,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn memory_estimate_covers_build_arrays_and_outputs() {
        let (t, i) = (10_000_000u64, 500u64);
        let per_triangle = estimate_bytes(t, i) as f64 / t as f64;
        assert!((200.0..320.0).contains(&per_triangle), "{per_triangle} bytes per triangle");
        assert!(estimate_bytes(t, i) >= BuildArrays::bytes(t, i) + t * 52);
        // Empty scenes still allocate one element per array.
        assert!(estimate_bytes(0, 0) > 0);
    }

    #[test]
    fn gamma_doubles_per_round_and_saturates() {
        let o = BuildOptions::default();
        assert_eq!((o.gamma(0), o.gamma(1), o.gamma(2)), (7, 14, 28));
        assert_eq!(o.gamma(40), u32::MAX);
        assert!(BuildOptions { max_leaf: 5, ..o }.check().is_err());
        assert!(BuildOptions { treelet_gamma: 3, ..o }.check().is_err());
    }
}
