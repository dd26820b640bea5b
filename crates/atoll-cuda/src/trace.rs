//! Host side of `kernels/trace.cu`: closest-hit and any-hit traversal of
//! a [`GpuSceneBvh`] for rays in a `RayRecord` array.
//!
//! - [`trace_closest_with`]: for each of the first `count` records, the
//!   closest hit with `0 < t < t_max`: `t_max` becomes its `t` and `hits[i]`
//!   gets (u, v, instance, global triangle); no hit leaves the record alone
//!   and sets `hits[i].instance = HIT_NONE`.
//! - [`trace_any_with`]: records without `flags::OCCLUDED` get it when
//!   anything lies in `(0, t_max)`.
//!
//! The loop structure is a [`TraversalVariant`] (Aila & Laine 2009), chosen
//! per call for measurements; the device's queued launches use the default.

use cudarc::driver::{CudaFunction, CudaSlice, LaunchConfig, PushKernelArg};

use crate::bvh::wide::WideBvh;
use crate::bvh::GpuSceneBvh;
use crate::error::CudaError;
use crate::gpu::Gpu;
use crate::layout::{GpuRecord, HitRef};
use crate::scene::GpuScene;

const FILE: &str = "trace.cu";

/// What the trace module is compiled for: a frame's features, each of which
/// costs the kernels registers even where no ray takes it, so modules are
/// specialised (kernels/traverse.cuh, surface.cuh). The default (none) is
/// what benchmarks and tests without frames trace with.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub(crate) struct TraceFeatures {
    /// Alpha masks are tested during traversal (`ATOLL_TRACE_ALPHA`).
    pub alpha: bool,
    /// Shadow rays gather optical depth where they cross surfaces that only
    /// bound media (`ATOLL_TRACE_MEDIA`; needs `alpha`, which such
    /// surfaces turn on).
    pub media: bool,
    /// With `media`: some grid differs by colour (`ATOLL_WITH_RGB_MEDIA`,
    /// kernels/media.cuh); grey grids alone take a lighter walk.
    pub rgb_media: bool,
    /// Closest-hit kernels that write surfaces apply texture programs and
    /// emission textures (`ATOLL_WITH_TEXTURES`).
    pub textures: bool,
    /// Reads of a shared scene are counted per chunk
    /// (`ATOLL_COUNT_ACCESSES`, kernels/access_count.cuh): the prepass.
    pub count_accesses: bool,
    /// BLAS leaf links count from their instance record's `tri_base` (a
    /// BVH built in pieces, `ATOLL_TRI_BASES`); set by the trace launch
    /// from the BVH traced.
    pub tri_bases: bool,
    /// Some records are curve pieces (`ATOLL_TRACE_CURVES`); set by the
    /// trace launch from the BVH traced.
    pub curves: bool,
    /// Some instances move (`ATOLL_TRACE_MOTION`): rays have times; set by
    /// the trace launch from the BVH traced.
    pub motion: bool,
}

impl TraceFeatures {
    /// The features `frame` needs.
    pub(crate) fn of(frame: &atoll_render::FrameContext) -> Self {
        TraceFeatures {
            alpha: frame.textures.has_alpha(),
            media: frame.media.any() && frame.textures.has_alpha(),
            rgb_media: frame.media.has_rgb_grids(),
            textures: frame
                .textures
                .materials
                .iter()
                .chain(&frame.textures.mix_amount)
                .chain(frame.textures.shading_normals.iter().map(|b| &b.program))
                .any(|r| !r.is_empty())
                || !frame.lights.emission_ops.is_empty(),
            count_accesses: false,
            tri_bases: false,
            curves: false,
            motion: false,
        }
    }

    /// `self` with what tracing through `bvh` needs besides.
    pub(crate) fn for_bvh(self, bvh: &GpuSceneBvh) -> Self {
        TraceFeatures {
            tri_bases: bvh.blas_tri_bases.iter().any(|&b| b != 0),
            curves: bvh.curves != 0,
            motion: bvh.motions != 0,
            ..self
        }
    }

    /// The NVRTC defines of the module holding `variant`'s kernels (a
    /// module per variant: a frame compiles only the one it traces with).
    pub(crate) fn defines(self, variant: TraversalVariant) -> Vec<String> {
        let mut defines = vec![
            format!("-DATOLL_TRACE_LOOPS={}", variant.loop_bit()),
            format!("-DATOLL_TRACE_ALPHA={}", self.alpha as u32),
            format!("-DATOLL_WITH_TEXTURES={}", self.textures as u32),
        ];
        // Only when set: the other modules keep their cache keys.
        if self.count_accesses {
            defines.push("-DATOLL_COUNT_ACCESSES=1".into());
        }
        if self.media {
            defines.push("-DATOLL_TRACE_MEDIA=1".into());
            if !self.rgb_media {
                defines.push("-DATOLL_WITH_RGB_MEDIA=0".into());
            }
        }
        if self.tri_bases {
            defines.push("-DATOLL_TRI_BASES=1".into());
        }
        if self.motion {
            defines.push("-DATOLL_TRACE_MOTION=1".into());
        }
        // Always: surface.cuh compiles its curve hits in where it is not told.
        defines.push(format!("-DATOLL_TRACE_CURVES={}", self.curves as u32));
        defines
    }
}
/// Threads per block (TRACE_THREADS in trace.cu).
const THREADS: u32 = 128;

/// How the traversal kernels schedule rays and loop (Aila & Laine 2009).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum TraversalVariant {
    /// While-while loops, one thread per ray.
    WhileWhile,
    /// While-while with persistent threads: just enough warps to fill the
    /// GPU, each taking 32 rays at a time from a global counter. The default:
    /// fastest for every ray type on an H200 (BENCHMARKS.md, 2026-11-22).
    #[default]
    Persistent,
    /// Speculative while-while (leaves postponed until the whole warp has
    /// one), one thread per ray.
    Speculative,
    /// Speculative traversal with persistent threads.
    PersistentSpeculative,
    /// The compressed 8-wide BVH (Ylitie et al. 2017; [`crate::bvh::wide`]),
    /// collapsed on the host at first use; one thread per ray.
    Wide,
    /// The compressed wide BVH with persistent threads.
    PersistentWide,
}

impl TraversalVariant {
    pub const ALL: [TraversalVariant; 6] = [
        TraversalVariant::WhileWhile,
        TraversalVariant::Persistent,
        TraversalVariant::Speculative,
        TraversalVariant::PersistentSpeculative,
        TraversalVariant::Wide,
        TraversalVariant::PersistentWide,
    ];

    /// The variant's bit in `ATOLL_TRACE_LOOPS` (kernels/trace.cu): its
    /// place in [`TraversalVariant::ALL`].
    fn loop_bit(self) -> u32 {
        let place = Self::ALL.iter().position(|v| *v == self).expect("every variant is in ALL");
        1 << place
    }

    /// Short name (kernel suffix and report column).
    pub fn name(self) -> &'static str {
        match self {
            TraversalVariant::WhileWhile => "ww",
            TraversalVariant::Persistent => "pt",
            TraversalVariant::Speculative => "sp",
            TraversalVariant::PersistentSpeculative => "ptsp",
            TraversalVariant::Wide => "cw",
            TraversalVariant::PersistentWide => "ptcw",
        }
    }

    pub(crate) fn persistent(self) -> bool {
        matches!(
            self,
            TraversalVariant::Persistent
                | TraversalVariant::PersistentSpeculative
                | TraversalVariant::PersistentWide
        )
    }

    /// Whether the variant traverses the compressed wide BVH.
    pub(crate) fn wide(self) -> bool {
        matches!(self, TraversalVariant::Wide | TraversalVariant::PersistentWide)
    }
}

/// A queue whose length is known only on the device: trace kernels read
/// `length` themselves and add the number of rays traced to `traced`, so
/// the host never waits for a read-back between stages.
pub(crate) struct DeviceQueueLength<'a> {
    pub length: &'a CudaSlice<u32>,
    pub traced: &'a mut CudaSlice<u64>,
}

/// Frame parameters and scene view for closest-hit kernels that write hit
/// attributes themselves (`write_surface` in kernels/surface.cuh) instead
/// of `HitRef`s for a separate `surface` pass.
pub(crate) struct SurfaceTables<'a> {
    pub params: &'a CudaSlice<crate::params::FrameParams>,
    pub scene: &'a CudaSlice<crate::params::SceneView>,
}

/// Loaded trace kernels and the persistent threads' work counter. One per
/// BVH (kept inside it), made on first use.
pub(crate) struct Tracer {
    /// By kernel name (query, variant and triangle test: one tracer may
    /// serve BVHs built for different tests).
    kernels: Vec<(String, CudaFunction)>,
    work: CudaSlice<u32>,
    /// Blocks of a persistent launch: resident blocks per SM times SMs.
    persistent_blocks: Vec<(String, u32)>,
}

impl Tracer {
    pub(crate) fn new(gpu: &Gpu) -> Result<Self, CudaError> {
        let work = gpu
            .stream
            .alloc_zeros(1)
            .map_err(CudaError::driver(format!("{}: allocating a work counter", gpu.label())))?;
        Ok(Tracer { kernels: Vec::new(), work, persistent_blocks: Vec::new() })
    }

    fn kernel(
        &mut self,
        gpu: &Gpu,
        variant: TraversalVariant,
        name: &str,
        features: TraceFeatures,
    ) -> Result<(CudaFunction, u32), CudaError> {
        let key = format!("{name}:{features:?}");
        let function = match self.kernels.iter().find(|(k, _)| *k == key) {
            Some((_, f)) => f.clone(),
            None => {
                let f = gpu.function_with(FILE, name, &features.defines(variant))?;
                self.kernels.push((key.clone(), f.clone()));
                f
            }
        };
        if !variant.persistent() {
            return Ok((function, 0));
        }
        if let Some((_, blocks)) = self.persistent_blocks.iter().find(|(k, _)| *k == key) {
            return Ok((function, *blocks));
        }
        let per_sm = function
            .occupancy_max_active_blocks_per_multiprocessor(THREADS, 0, None)
            .map_err(CudaError::driver(format!("{}: occupancy of {name}", gpu.label())))?;
        let blocks = per_sm.max(1) * gpu.multiprocessors;
        self.persistent_blocks.push((key, blocks));
        Ok((function, blocks))
    }

    /// Queues one trace of `rays[..count]` (`hits` for closest hits, `None`
    /// for any-hit queries); with `queue`, of `rays[..min(count, *queue.length)]`.
    /// `frame`: the parameters whose seed gives rays their times where
    /// instances move (without, every ray is at the shutter's opening).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn launch(
        &mut self,
        gpu: &Gpu,
        bvh: &GpuSceneBvh,
        rays: &mut CudaSlice<GpuRecord>,
        count: u32,
        hits: Option<&mut CudaSlice<HitRef>>,
        variant: TraversalVariant,
        queue: Option<DeviceQueueLength<'_>>,
        surface: Option<SurfaceTables<'_>>,
        alpha: Option<SurfaceTables<'_>>,
        frame: Option<&CudaSlice<crate::params::FrameParams>>,
        features: TraceFeatures,
    ) -> Result<(), CudaError> {
        if features.alpha != alpha.is_some() {
            return Err(CudaError::Usage("trace: alpha tables must come with the alpha kernels".into()));
        }
        let any = hits.is_none();
        if count as usize > rays.len() || hits.as_ref().is_some_and(|h| (count as usize) > h.len()) {
            return Err(CudaError::Usage(format!(
                "trace of {count} rays: the ray ({}) or hit buffer is smaller",
                rays.len()
            )));
        }
        if count == 0 {
            return Ok(());
        }
        let query = if any { "any" } else { "closest" };
        let name = format!("trace_{query}_{}_{}", variant.name(), bvh.triangle_test.suffix());
        let features = features.for_bvh(bvh);
        let (function, persistent_blocks) = self.kernel(gpu, variant, &name, features)?;
        let config = if variant.persistent() {
            gpu.stream
                .memset_zeros(&mut self.work)
                .map_err(CudaError::driver("clearing the work counter"))?;
            LaunchConfig {
                grid_dim: (persistent_blocks, 1, 1),
                block_dim: (THREADS, 1, 1),
                shared_mem_bytes: 0,
            }
        } else {
            LaunchConfig {
                grid_dim: (count.div_ceil(THREADS), 1, 1),
                block_dim: (THREADS, 1, 1),
                shared_mem_bytes: 0,
            }
        };
        let null: u64 = 0;
        let mut wide = bvh.wide.lock().unwrap_or_else(|p| p.into_inner());
        if variant.wide() && wide.is_none() {
            *wide = Some(WideBvh::build(gpu, bvh)?);
            // Devices sharing the BVH trace on other streams: the collapse
            // must have finished before any of them reads it.
            gpu.synchronize()?;
        }
        let mut launch = gpu.stream.launch_builder(&function);
        launch.arg(&bvh.tlas_nodes).arg(&bvh.blas_nodes);
        match wide.as_ref().filter(|_| variant.wide()) {
            Some(w) => launch.arg(&w.nodes).arg(&w.tris).arg(&w.tri_ids).arg(&w.instances).arg(&w.root),
            None => {
                launch.arg(&null).arg(&bvh.tris).arg(&bvh.tri_ids).arg(&bvh.instances).arg(&bvh.tlas_root)
            }
        };
        launch.arg(&mut *rays);
        match hits {
            Some(h) => launch.arg(h),
            None => launch.arg(&null),
        };
        launch.arg(&count).arg(&mut self.work);
        match queue {
            Some(q) => launch.arg(q.length).arg(q.traced),
            None => launch.arg(&null).arg(&null),
        };
        match &surface {
            Some(t) => launch.arg(t.params).arg(t.scene),
            None => launch.arg(&null).arg(&null),
        };
        match &alpha {
            Some(t) => launch.arg(t.params).arg(t.scene),
            None => launch.arg(&null).arg(&null),
        };
        launch.arg(&bvh.curves).arg(&bvh.motions);
        match frame {
            Some(f) => launch.arg(f),
            None => launch.arg(&null),
        };
        // SAFETY: matches `trace_<query>_<variant>_<test>(const BvhNode* tlas_nodes, const
        // BvhNode* blas_nodes, const WideNode* wide_nodes, const TriRecord* tris, const unsigned* tri_ids, const
        // TlasInstance* instances, int tlas_root, RayRecord* records, HitRef* hits, unsigned
        // count, unsigned* work, const unsigned* device_count, unsigned long long* traced,
        // const FrameParams* surface_params, const SceneView* surface_scene, const FrameParams*
        // alpha_params, const SceneView* alpha_scene, const GpuCurve* curves, const GpuMotion*
        // motions, const FrameParams* motion_params)`.
        // The BVH's links stay within its arrays (built by lbvh.cu; the wide tree's by
        // bvh::wide from them, and only the wide kernels read `wide_nodes`, null otherwise); threads touch records and
        // hits below `count` (or the smaller device count), which both buffers hold (checked);
        // any-hit kernels never touch `hits` (null); `work` was zeroed for persistent launches;
        // `device_count`/`traced` are null or single device integers; the surface tables are
        // null or one FrameParams/SceneView whose tables outlive the launch (the device owns them);
        // the alpha tables likewise (the kernels read them only when `mesh_alpha` is set);
        // `curves` is 0 or the pieces of the scene the BVH was built over (its marked records
        // index them), which the device keeps alive with the BVH; `motions` likewise for its
        // moving instance records; `motion_params` is null or one FrameParams.
        unsafe { launch.launch(config) }
            .map_err(CudaError::driver(format!("{}: launching {name}", gpu.label())))?;
        Ok(())
    }
}

fn check_scene(scene: &GpuScene, bvh: &GpuSceneBvh) -> Result<(), CudaError> {
    if scene.counts.triangles != bvh.scene_triangles {
        return Err(CudaError::Usage(format!(
            "trace: the BVH was built for a scene of {} triangles, not this one ({})",
            bvh.scene_triangles, scene.counts.triangles
        )));
    }
    Ok(())
}

fn with_tracer<R>(
    gpu: &Gpu,
    bvh: &GpuSceneBvh,
    f: impl FnOnce(&mut Tracer) -> Result<R, CudaError>,
) -> Result<R, CudaError> {
    // One tracer per GPU stream: devices sharing the BVH must not share
    // the persistent-threads work counter.
    let mut slots = bvh.tracers.lock().unwrap_or_else(|p| p.into_inner());
    let at = match slots.iter().position(|(id, _)| *id == gpu.id) {
        Some(at) => at,
        None => {
            slots.push((gpu.id, Tracer::new(gpu)?));
            slots.len() - 1
        }
    };
    f(&mut slots[at].1)
}

/// Compiles (or loads from the kernel cache) the default variant's
/// closest- and any-hit kernels for `bvh`, so that a render's clock does not
/// include it (the first trace would otherwise compile `trace.cu` when the
/// kernel cache is cold).
/// `features`: what the frame needs (see [`TraceFeatures`]).
pub(crate) fn load_default_kernels(
    gpu: &Gpu,
    bvh: &GpuSceneBvh,
    features: TraceFeatures,
) -> Result<(), CudaError> {
    let variant = TraversalVariant::default();
    let features = features.for_bvh(bvh);
    with_tracer(gpu, bvh, |t| {
        for query in ["closest", "any"] {
            t.kernel(
                gpu,
                variant,
                &format!("trace_{query}_{}_{}", variant.name(), bvh.triangle_test.suffix()),
                features,
            )?;
        }
        Ok(())
    })
}

/// Closest hits of `rays[..count]` with traversal variant `variant` (see
/// the module docs).
pub fn trace_closest_with(
    gpu: &Gpu,
    scene: &GpuScene,
    bvh: &GpuSceneBvh,
    rays: &mut CudaSlice<GpuRecord>,
    count: u32,
    hits: &mut CudaSlice<HitRef>,
    variant: TraversalVariant,
) -> Result<(), CudaError> {
    check_scene(scene, bvh)?;
    with_tracer(gpu, bvh, |t| {
        t.launch(gpu, bvh, rays, count, Some(hits), variant, None, None, None, None, TraceFeatures::default())
    })
}

/// Sets `flags::OCCLUDED` on the records of `rays[..count]` that hit
/// anything, with traversal variant `variant`.
pub fn trace_any_with(
    gpu: &Gpu,
    scene: &GpuScene,
    bvh: &GpuSceneBvh,
    rays: &mut CudaSlice<GpuRecord>,
    count: u32,
    variant: TraversalVariant,
) -> Result<(), CudaError> {
    check_scene(scene, bvh)?;
    with_tracer(gpu, bvh, |t| {
        t.launch(gpu, bvh, rays, count, None, variant, None, None, None, None, TraceFeatures::default())
    })
}

/// Closest hits of the first `*queue.length` records (at most `capacity`)
/// with the default variant, without reading the length back; each hit's
/// attributes are written into its record (the `surface` stage folded in).
#[allow(clippy::too_many_arguments)]
pub(crate) fn trace_closest_queued(
    gpu: &Gpu,
    scene: &GpuScene,
    bvh: &GpuSceneBvh,
    rays: &mut CudaSlice<GpuRecord>,
    capacity: u32,
    hits: &mut CudaSlice<HitRef>,
    queue: DeviceQueueLength<'_>,
    surface: SurfaceTables<'_>,
    features: TraceFeatures,
) -> Result<(), CudaError> {
    check_scene(scene, bvh)?;
    let variant = TraversalVariant::default();
    let alpha = features.alpha.then_some(SurfaceTables { params: surface.params, scene: surface.scene });
    let frame = Some(surface.params);
    with_tracer(gpu, bvh, |t| {
        t.launch(
            gpu,
            bvh,
            rays,
            capacity,
            Some(hits),
            variant,
            Some(queue),
            Some(surface),
            alpha,
            frame,
            features,
        )
    })
}

/// Any-hit tests of the first `*queue.length` records (at most `capacity`)
/// with the default variant, without reading the length back; `tables`:
/// the frame and scene alpha masks are evaluated with (used when
/// `features.alpha`).
#[allow(clippy::too_many_arguments)]
pub(crate) fn trace_any_queued(
    gpu: &Gpu,
    scene: &GpuScene,
    bvh: &GpuSceneBvh,
    rays: &mut CudaSlice<GpuRecord>,
    capacity: u32,
    queue: DeviceQueueLength<'_>,
    tables: SurfaceTables<'_>,
    features: TraceFeatures,
) -> Result<(), CudaError> {
    check_scene(scene, bvh)?;
    let variant = TraversalVariant::default();
    let frame = Some(tables.params);
    let alpha = features.alpha.then_some(tables);
    with_tracer(gpu, bvh, |t| {
        t.launch(gpu, bvh, rays, capacity, None, variant, Some(queue), None, alpha, frame, features)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variant_names_are_kernel_suffixes() {
        let names: Vec<&str> = TraversalVariant::ALL.iter().map(|v| v.name()).collect();
        assert_eq!(names, ["ww", "pt", "sp", "ptsp", "cw", "ptcw"]);
        let source = crate::compile::kernel_source(FILE).expect("trace.cu is registered");
        // Each variant's kernels are made by the loop its `ATOLL_TRACE_LOOPS`
        // bit selects, under its name, persistent or not as it says.
        for v in TraversalVariant::ALL {
            let kind = if v.persistent() { "PERSISTENT" } else { "GRID" };
            let made = format!(
                "#if ATOLL_TRACE_LOOPS & {}\nTRACE_LOOP(TRACE_{kind}_KERNEL, {}, ",
                v.loop_bit(),
                v.name()
            );
            assert!(source.contains(&made), "{}: {made}", v.name());
        }
        assert!(source.contains("trace_##query##_##name##_##test"));
        assert_eq!(TraversalVariant::ALL.iter().filter(|v| v.persistent()).count(), 3);
    }

    /// A frame whose only texture is a bump map still gets the texture
    /// code in its closest-hit kernels (the bump is applied there).
    #[test]
    fn a_bump_map_alone_needs_the_texture_code() {
        use atoll_scene::texture_scenes::{bent_plane_scene, Bend};
        let features = |bend| {
            let scene = bent_plane_scene(bend);
            TraceFeatures::of(&atoll_render::FrameContext::new(
                &scene,
                atoll_render::RenderOptions::from_scene(&scene),
            ))
        };
        assert!(!features(Bend::Tilted).textures);
        assert!(features(Bend::Bump).textures && features(Bend::NormalMap).textures);
    }
}
