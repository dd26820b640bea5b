//! Host side of the LBVH build kernels (`kernels/lbvh.cu`, `treelet.cu`):
//! the device arrays of one build (all BLASes at once, or the TLAS) and
//! the launch sequence that turns primitive boxes into the traversal layout.
//! `super::reference` computes the same thing on the host.

use cudarc::driver::sys::CUevent_flags;
use cudarc::driver::{CudaEvent, CudaFunction, CudaSlice, LaunchConfig, PushKernelArg};

use super::layout::GpuBvhNode;
use super::sort::{morton_passes, SortKernels, SortScratch};
use super::BuildOptions;
use crate::error::CudaError;
use crate::gpu::{launch_1d, Gpu};

pub(super) const FILE: &str = "lbvh.cu";
/// Threads per block of the build kernels (BUILD_THREADS in lbvh.cu).
pub(crate) const THREADS: u32 = 256;
/// Primitives per block of the box kernels (BUILD_THREADS * BOX_ITEMS).
pub(crate) const BOX_BLOCK: u32 = THREADS * 4;
/// Threads per block of the treelet kernel (TREELET_THREADS).
const TREELET_THREADS: u32 = 128;

/// Every build kernel, loaded once per scene build.
pub(crate) struct LbvhKernels {
    pub init_seg_bounds: CudaFunction,
    pub blas_boxes: CudaFunction,
    pub tlas_boxes: CudaFunction,
    pub morton: CudaFunction,
    pub karras: CudaFunction,
    pub bounds: CudaFunction,
    pub treelet: CudaFunction,
    pub mark: CudaFunction,
    pub emit_nodes: CudaFunction,
    pub emit_roots: CudaFunction,
    pub emit_triangles: CudaFunction,
    pub emit_instances: CudaFunction,
    pub sort: SortKernels,
}

impl LbvhKernels {
    pub fn load(gpu: &Gpu) -> Result<Self, CudaError> {
        let f = |name: &str| gpu.function(FILE, name);
        Ok(LbvhKernels {
            init_seg_bounds: f("lbvh_init_seg_bounds")?,
            blas_boxes: f("lbvh_blas_boxes")?,
            tlas_boxes: f("lbvh_tlas_boxes")?,
            morton: f("lbvh_morton")?,
            karras: f("lbvh_karras")?,
            bounds: f("lbvh_bounds")?,
            treelet: gpu.function("treelet.cu", "lbvh_treelet")?,
            mark: f("lbvh_mark")?,
            emit_nodes: f("lbvh_emit_nodes")?,
            emit_roots: f("lbvh_emit_roots")?,
            emit_triangles: f("lbvh_emit_triangles")?,
            emit_instances: f("lbvh_emit_instances")?,
            sort: SortKernels::load(gpu)?,
        })
    }
}

/// CUDA events at phase boundaries on the stream: device time per phase.
pub(crate) struct Phases {
    start: CudaEvent,
    marks: Vec<(&'static str, CudaEvent)>,
}

impl Phases {
    pub fn start(gpu: &Gpu) -> Result<Self, CudaError> {
        Ok(Phases { start: Self::event(gpu)?, marks: Vec::new() })
    }

    fn event(gpu: &Gpu) -> Result<CudaEvent, CudaError> {
        let context = || format!("{}: timing event", gpu.label());
        let event =
            gpu.ctx.new_event(Some(CUevent_flags::CU_EVENT_DEFAULT)).map_err(CudaError::driver(context()))?;
        event.record(&gpu.stream).map_err(CudaError::driver(context()))?;
        Ok(event)
    }

    /// Ends phase `name` here (queued; the work so far belongs to it).
    pub fn mark(&mut self, gpu: &Gpu, name: &'static str) -> Result<(), CudaError> {
        self.marks.push((name, Self::event(gpu)?));
        Ok(())
    }

    /// Milliseconds per phase, in order (waits for the work). Phases
    /// marked more than once (BLAS and TLAS builds) are summed.
    pub fn finish(&self) -> Result<Vec<(&'static str, f32)>, CudaError> {
        let mut out: Vec<(&'static str, f32)> = Vec::new();
        let mut previous = &self.start;
        for (name, event) in &self.marks {
            let ms = previous.elapsed_ms(event).map_err(CudaError::driver("reading a timing event"))?;
            match out.iter_mut().find(|(n, _)| n == name) {
                Some(entry) => entry.1 += ms,
                None => out.push((name, ms)),
            }
            previous = event;
        }
        Ok(out)
    }
}

/// An uninitialised device array of `len` elements (at least one). Only
/// for arrays that a kernel or copy fills before anything reads them (each
/// use says which); zeroing them would cost a memset per build.
fn alloc<T: cudarc::driver::DeviceRepr>(gpu: &Gpu, len: u64, what: &str) -> Result<CudaSlice<T>, CudaError> {
    // SAFETY: device memory is not Rust memory: uninitialised contents are
    // only garbage values, and `BuildArrays::new` documents per array which
    // step writes it before it is read.
    unsafe { gpu.stream.alloc::<T>(len.max(1) as usize) }
        .map_err(CudaError::driver(format!("{}: allocating {what} ({len} elements)", gpu.label())))
}

pub(crate) fn launch_err(gpu: &Gpu, kernel: &str) -> impl FnOnce(cudarc::driver::DriverError) -> CudaError {
    CudaError::driver(format!("{}: launching {kernel}", gpu.label()))
}

/// The device arrays of one build over `p` primitives in `segments`
/// segments (see lbvh.cuh for the build tree's node numbering).
pub(crate) struct BuildArrays {
    pub p: u32,
    pub segments: u32,
    pub seg_start: CudaSlice<u32>,
    /// Per primitive (float4 min, float4 max), in primitive order.
    pub prim_box: CudaSlice<f32>,
    /// Per segment, ordered-int centroid bounds (min xyz, pad, max xyz, pad).
    pub seg_bounds: CudaSlice<u32>,
    pub keys: CudaSlice<u32>,
    pub values: CudaSlice<u32>,
    keys_alt: CudaSlice<u32>,
    values_alt: CudaSlice<u32>,
    /// (left, right) per internal slot.
    pub child: CudaSlice<u32>,
    pub parent: CudaSlice<u32>,
    /// Atomic counters of the bottom-up passes, then the kept flags.
    pub kept: CudaSlice<u32>,
    /// Per node, float4 (min xyz, SAH cost) and (max xyz, packed count).
    pub node_lo: CudaSlice<f32>,
    pub node_hi: CudaSlice<f32>,
    pub node_id: CudaSlice<u32>,
    pub leaf_size: CudaSlice<u32>,
    pub tri_offset: CudaSlice<u32>,
    /// Per segment: root link, and root box (float4 min with the root's
    /// SAH cost in w, float4 max).
    pub root_link: CudaSlice<i32>,
    pub root_box: CudaSlice<f32>,
    /// [0]: kept inner nodes, [1]: leaf records.
    counts: CudaSlice<u32>,
    scratch: SortScratch,
}

impl BuildArrays {
    /// Allocates the arrays and uploads the segment starts (`segments + 1`, the last `p`).
    pub fn new(gpu: &Gpu, seg_start: &[u32]) -> Result<Self, CudaError> {
        let p = *seg_start.last().unwrap_or(&0);
        let segments = seg_start.len().saturating_sub(1) as u32;
        let (pu, su) = (p as u64, segments as u64);
        let seg = gpu
            .stream
            .clone_htod(seg_start)
            .map_err(CudaError::driver(format!("{}: uploading segment starts", gpu.label())))?;
        // Who writes each array before it is read: prim_box the box kernel;
        // seg_bounds init_seg_bounds; keys/values morton (the alternates the
        // sort's scatter); child and parent karras (every slot: spare slots
        // and roots get BUILD_NONE); node_lo/hi bounds (spare slots are never
        // read: their child is BUILD_NONE); kept a memset; leaf_size mark;
        // node_id and tri_offset the scans; root_link/box emit_roots; counts copies.
        Ok(BuildArrays {
            p,
            segments,
            seg_start: seg,
            prim_box: alloc(gpu, 8 * pu, "primitive boxes")?,
            seg_bounds: alloc(gpu, 8 * su, "segment bounds")?,
            keys: alloc(gpu, pu, "sort keys")?,
            values: alloc(gpu, pu, "sort values")?,
            keys_alt: alloc(gpu, pu, "sort keys")?,
            values_alt: alloc(gpu, pu, "sort values")?,
            child: alloc(gpu, 2 * pu, "build children")?,
            parent: alloc(gpu, 2 * pu, "build parents")?,
            kept: alloc(gpu, pu, "build counters")?,
            node_lo: alloc(gpu, 8 * pu, "build boxes")?,
            node_hi: alloc(gpu, 8 * pu, "build boxes")?,
            node_id: alloc(gpu, pu, "node ids")?,
            leaf_size: alloc(gpu, 2 * pu, "leaf sizes")?,
            tri_offset: alloc(gpu, 2 * pu, "leaf offsets")?,
            root_link: alloc(gpu, su, "root links")?,
            root_box: alloc(gpu, 8 * su, "root boxes")?,
            counts: alloc(gpu, 2, "build counts")?,
            scratch: SortScratch::new(gpu, p, 2 * p)?,
        })
    }

    /// Device bytes [`BuildArrays::new`] allocates (empty arrays take one element).
    pub fn bytes(p: u64, segments: u64) -> u64 {
        let (s, pp) = (segments, 2 * p);
        // seg_start, prim_box, seg_bounds, 4 sort buffers, child, parent, kept,
        // node_lo, node_hi, node_id, leaf_size, tri_offset, root_link, root_box, counts.
        let lens = [s + 1, 8 * p, 8 * s, p, p, p, p, pp, pp, p, 8 * p, 8 * p, p, pp, pp, s, 8 * s, 2];
        lens.iter().map(|&n| 4 * n.max(1)).sum::<u64>() + SortScratch::bytes(p as u32, 2 * p as u32)
    }

    /// Sets every segment's centroid bounds to empty (before a box kernel).
    pub fn init_seg_bounds(&mut self, gpu: &Gpu, k: &LbvhKernels) -> Result<(), CudaError> {
        let mut launch = gpu.stream.launch_builder(&k.init_seg_bounds);
        launch.arg(&mut self.seg_bounds).arg(&self.segments);
        // SAFETY: matches `lbvh_init_seg_bounds(unsigned* seg_bounds, unsigned segments)`;
        // seg_bounds holds 8 words per segment.
        unsafe { launch.launch(launch_1d(self.segments, THREADS)) }
            .map_err(launch_err(gpu, "lbvh_init_seg_bounds"))?;
        Ok(())
    }

    /// Launch shape of the box kernels.
    pub fn box_launch(&self) -> LaunchConfig {
        LaunchConfig {
            grid_dim: (self.p.div_ceil(BOX_BLOCK).max(1), 1, 1),
            block_dim: (THREADS, 1, 1),
            shared_mem_bytes: 0,
        }
    }

    /// Steps 2–6 after a box kernel filled `prim_box` and `seg_bounds`:
    /// Morton codes, sort, radix tree, bounds, treelet rounds. Phases are
    /// marked on `phases`; the primitive boxes count as "morton".
    pub fn build_tree(
        &mut self,
        gpu: &Gpu,
        k: &LbvhKernels,
        max_leaf: u32,
        options: &BuildOptions,
        phases: &mut Phases,
    ) -> Result<(), CudaError> {
        let p = self.p;
        let (ci, ct) = (options.intersection_cost, options.traversal_cost);
        let mut launch = gpu.stream.launch_builder(&k.morton);
        launch
            .arg(&self.prim_box)
            .arg(&p)
            .arg(&self.seg_start)
            .arg(&self.segments)
            .arg(&self.seg_bounds)
            .arg(&mut self.keys)
            .arg(&mut self.values);
        // SAFETY: matches `lbvh_morton(const float4* prim_box, unsigned P, const unsigned*
        // seg_start, unsigned segments, const unsigned* seg_bounds, unsigned* keys, unsigned*
        // values)`; prim_box holds 2P float4, keys/values P, seg_bounds 8 per segment.
        unsafe { launch.launch(launch_1d(p, THREADS)) }.map_err(launch_err(gpu, "lbvh_morton"))?;
        phases.mark(gpu, "morton")?;

        k.sort.sort_pairs(
            gpu,
            &mut self.keys,
            &mut self.values,
            &mut self.keys_alt,
            &mut self.values_alt,
            p,
            &morton_passes(self.segments),
            &self.seg_start,
            self.segments,
            &mut self.scratch,
        )?;
        phases.mark(gpu, "sort")?;

        let mut launch = gpu.stream.launch_builder(&k.karras);
        launch
            .arg(&self.keys)
            .arg(&p)
            .arg(&self.seg_start)
            .arg(&self.segments)
            .arg(&mut self.child)
            .arg(&mut self.parent);
        // SAFETY: matches `lbvh_karras(const unsigned* keys, unsigned P, const unsigned*
        // seg_start, unsigned segments, uint2* child, unsigned* parent)`; child holds P uint2,
        // parent 2P entries; every index written is a node of the thread's own segment.
        unsafe { launch.launch(launch_1d(p, THREADS)) }.map_err(launch_err(gpu, "lbvh_karras"))?;
        phases.mark(gpu, "tree")?;

        // Treelet rounds fit the boxes in their first bottom-up pass.
        if options.treelet_rounds == 0 {
            gpu.stream.memset_zeros(&mut self.kept).map_err(launch_err(gpu, "clearing counters"))?;
            let mut launch = gpu.stream.launch_builder(&k.bounds);
            launch
                .arg(&self.values)
                .arg(&self.prim_box)
                .arg(&p)
                .arg(&self.child)
                .arg(&self.parent)
                .arg(&mut self.kept)
                .arg(&mut self.node_lo)
                .arg(&mut self.node_hi)
                .arg(&max_leaf)
                .arg(&ci)
                .arg(&ct);
            // SAFETY: matches `lbvh_bounds(const unsigned* values, const float4* prim_box,
            // unsigned P, const uint2* child, const unsigned* parent, unsigned* counter, float4*
            // node_lo, float4* node_hi, unsigned max_leaf, float ci, float ct)`; counters zeroed
            // just above; node arrays hold 2P float4; parent links stay within the tree.
            unsafe { launch.launch(launch_1d(p, THREADS)) }.map_err(launch_err(gpu, "lbvh_bounds"))?;
        }
        phases.mark(gpu, "bounds")?;

        for round in 0..options.treelet_rounds {
            let gamma = options.gamma(round);
            let fit_bounds = u32::from(round == 0);
            gpu.stream.memset_zeros(&mut self.kept).map_err(launch_err(gpu, "clearing counters"))?;
            let mut launch = gpu.stream.launch_builder(&k.treelet);
            launch
                .arg(&self.values)
                .arg(&self.prim_box)
                .arg(&p)
                .arg(&mut self.child)
                .arg(&mut self.parent)
                .arg(&mut self.node_lo)
                .arg(&mut self.node_hi)
                .arg(&mut self.kept)
                .arg(&gamma)
                .arg(&max_leaf)
                .arg(&ci)
                .arg(&ct)
                .arg(&fit_bounds);
            // SAFETY: matches `lbvh_treelet(const unsigned* values, const float4* prim_box,
            // unsigned P, uint2* child, unsigned* parent, float4* node_lo, float4* node_hi,
            // unsigned* counter, unsigned gamma, unsigned max_leaf, float ci, float ct, unsigned
            // fit_bounds)`; counters zeroed above; node arrays hold 2P float4; treelets only
            // rewire nodes below their root, within the arrays.
            unsafe { launch.launch(launch_1d(p, TREELET_THREADS)) }
                .map_err(launch_err(gpu, "lbvh_treelet"))?;
        }
        phases.mark(gpu, "quality")?;
        Ok(())
    }

    /// Step 7: marks kept inner nodes and output leaves and numbers them
    /// (two scans); returns (kept inner nodes, leaf records), read back.
    pub fn collapse(
        &mut self,
        gpu: &Gpu,
        k: &LbvhKernels,
        max_leaf: u32,
        phases: &mut Phases,
    ) -> Result<(u32, u32), CudaError> {
        let p = self.p;
        let mut launch = gpu.stream.launch_builder(&k.mark);
        launch
            .arg(&p)
            .arg(&self.child)
            .arg(&self.parent)
            .arg(&self.node_hi)
            .arg(&max_leaf)
            .arg(&mut self.kept)
            .arg(&mut self.leaf_size);
        // SAFETY: matches `lbvh_mark(unsigned P, const uint2* child, const unsigned* parent,
        // const float4* node_hi, unsigned max_leaf, unsigned* kept, unsigned* leaf_size)`;
        // 2P threads, kept holds P entries and leaf_size 2P.
        unsafe { launch.launch(launch_1d(2 * p, THREADS)) }.map_err(launch_err(gpu, "lbvh_mark"))?;
        let copy_err = || CudaError::driver(format!("{}: copying build counts", gpu.label()));
        k.sort.scan(gpu, &self.kept, &mut self.node_id, p, &mut self.scratch)?;
        gpu.stream.memcpy_dtod(&self.scratch.total, &mut self.counts.slice_mut(0..1)).map_err(copy_err())?;
        k.sort.scan(gpu, &self.leaf_size, &mut self.tri_offset, 2 * p, &mut self.scratch)?;
        gpu.stream.memcpy_dtod(&self.scratch.total, &mut self.counts.slice_mut(1..2)).map_err(copy_err())?;
        phases.mark(gpu, "collapse")?;
        let counts = gpu.stream.clone_dtoh(&self.counts).map_err(copy_err())?;
        Ok((counts[0], counts[1]))
    }

    /// Step 8a–b: the traversal nodes (`nodes` holds the kept count) and the
    /// segments' root links and boxes.
    pub fn emit_nodes(
        &mut self,
        gpu: &Gpu,
        k: &LbvhKernels,
        nodes: &mut CudaSlice<GpuBvhNode>,
    ) -> Result<(), CudaError> {
        let p = self.p;
        let mut launch = gpu.stream.launch_builder(&k.emit_nodes);
        launch
            .arg(&p)
            .arg(&self.child)
            .arg(&self.node_lo)
            .arg(&self.node_hi)
            .arg(&self.kept)
            .arg(&self.node_id)
            .arg(&self.tri_offset)
            .arg(&mut *nodes);
        // SAFETY: matches `lbvh_emit_nodes(unsigned P, const uint2* child, const float4*
        // node_lo, const float4* node_hi, const unsigned* kept, const unsigned* node_id, const
        // unsigned* tri_offset, BvhNode* out)`; node ids of kept nodes are below the kept
        // count, which `nodes` holds (allocated from the read-back count).
        unsafe { launch.launch(launch_1d(p, THREADS)) }.map_err(launch_err(gpu, "lbvh_emit_nodes"))?;
        let mut launch = gpu.stream.launch_builder(&k.emit_roots);
        launch
            .arg(&self.segments)
            .arg(&self.seg_start)
            .arg(&p)
            .arg(&self.node_lo)
            .arg(&self.node_hi)
            .arg(&self.kept)
            .arg(&self.node_id)
            .arg(&self.tri_offset)
            .arg(&mut self.root_link)
            .arg(&mut self.root_box);
        // SAFETY: matches `lbvh_emit_roots(unsigned segments, const unsigned* seg_start,
        // unsigned P, const float4* node_lo, const float4* node_hi, const unsigned* kept, const
        // unsigned* node_id, const unsigned* tri_offset, int* root_link, float4* root_box)`;
        // root_link holds one entry and root_box two float4 per segment.
        unsafe { launch.launch(launch_1d(self.segments, THREADS)) }
            .map_err(launch_err(gpu, "lbvh_emit_roots"))?;
        Ok(())
    }
}
