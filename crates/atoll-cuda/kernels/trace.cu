// Ray traversal kernels (host side: src/trace.rs). Rays are read straight
// from the RayRecord array (origin + t_max, then direction: two 16-byte
// loads); results go back into it:
// - trace_closest_*: on a hit with t < t_max, t_max becomes t and hits[i]
//   gets (u, v, instance, global triangle); otherwise hits[i].instance is
//   HIT_NONE (the record is left as it was);
// - trace_any_*: records already FLAG_OCCLUDED are skipped; a hit sets it.
//
// Variants (Aila & Laine 2009), one kernel each, chosen by the host:
// - ww: while-while, one thread per ray;
// - pt: persistent threads: just enough warps to fill the GPU, each
//   fetching 32 rays at a time from a global counter until none are left
//   (`*work` must be 0 at launch);
// - sp: speculative while-while, one thread per ray;
// - ptsp: persistent threads with speculative traversal;
// - cw / ptcw: the compressed wide BVH (Ylitie et al. 2017, wide.cuh), one
//   thread per ray / persistent threads; `tlas_root`, `tris`, `tri_ids` and
//   `instances` are then the wide tree's (src/bvh/wide.rs).
// and two triangle tests: exact (Möller–Trumbore bit-identical to the CPU)
// and woop (unit-triangle test).

#include "record.cuh"
#include "layout.cuh"
#include "bvh.cuh"
#include "surface.cuh"

#define TRACE_THREADS 128

/// Traces ray `i` (when `i < count`) and writes its result. All 32 lanes
/// of the warp call this together (the speculative traversal votes).
/// With `surface` (closest hits only), a hit's attributes are written into
/// the record right away (`write_surface`) instead of a `HitRef` for the
/// separate `surface` pass.
struct SurfaceArgs {
    const FrameParams* params;
    const SceneView* scene;
};

/// Loop structures (template argument).
#define LOOP_WHILE_WHILE 0
#define LOOP_SPECULATIVE 1
#define LOOP_WIDE 2

template <int TRI, bool ANY, int LOOP>
__device__ __forceinline__ void trace_ray(const SceneBvhView& v, RayRecord* records, HitRef* hits,
                                          unsigned long long i, unsigned int count, SurfaceArgs surface,
                                          const FrameParams* motion_params) {
    bool valid = i < count;
    RayRecord* rec = records + (valid ? i : 0);
    float4 a = make_float4(0.0f, 0.0f, 0.0f, 0.0f), b = a;
    if (valid) {
        a = *reinterpret_cast<const float4*>(rec);
        b = *(reinterpret_cast<const float4*>(rec) + 1);
        if (ANY && (rec->flags & FLAG_OCCLUDED)) valid = false;
    }
    const unsigned int mask = __ballot_sync(0xffffffffu, valid);
    if (!valid) return;
    const float3 o = make_float3(a.x, a.y, a.z), d = make_float3(b.x, b.y, b.z);
    float time = 0.0f;
#if ATOLL_TRACE_MOTION
    // b.w is the record's pixel.
    if (motion_params) time = ray_time_sample(motion_params->seed, __float_as_uint(b.w), rec->sample);
#endif
    const TraversalHit h = LOOP == LOOP_SPECULATIVE ? traverse_speculative<TRI, ANY>(v, o, d, a.w, time, mask)
                           : LOOP == LOOP_WIDE      ? traverse_wide<TRI, ANY>(v, o, d, a.w, time)
                                                    : traverse_while_while<TRI, ANY>(v, o, d, a.w, time);
    if (ANY) {
        if (h.hit) {
            rec->flags |= FLAG_OCCLUDED;
        }
#if ATOLL_TRACE_MEDIA
        else if (!is_zero3(h.depth)) {
            // The record's position holds its optical depth (shade.rs `start_in_medium`).
            store3(rec->position, load3(rec->position) + h.depth);
        }
#endif
        return;
    }
    HitRef out;
    if (h.hit) {
        rec->t_max = h.t;
        out.u = h.u;
        out.v = h.v;
        count_access(v.instances + h.slot);
        count_access(v.tri_ids + h.tri);
        out.instance = __ldg(&v.instances[h.slot].instance);
        out.triangle = __ldg(v.tri_ids + h.tri);
        if (surface.params) {
            write_surface(*surface.params, *surface.scene, rec, out);
            return;
        }
    } else {
        if (surface.params) return;  // a miss leaves the record as it is
        out.u = out.v = 0.0f;
        out.instance = HIT_NONE;
        out.triangle = HIT_NONE;
    }
    hits[i] = out;
}

/// One thread per ray.
template <int TRI, bool ANY, int LOOP>
__device__ __forceinline__ void trace_grid(const SceneBvhView& v, RayRecord* records, HitRef* hits,
                                           unsigned int count, SurfaceArgs surface,
                                           const FrameParams* motion_params) {
    const unsigned long long i = (unsigned long long)blockIdx.x * blockDim.x + threadIdx.x;
    trace_ray<TRI, ANY, LOOP>(v, records, hits, i, count, surface, motion_params);
}

/// Persistent threads: warps take batches of 32 rays from `*work`.
template <int TRI, bool ANY, int LOOP>
__device__ __forceinline__ void trace_persistent(const SceneBvhView& v, RayRecord* records, HitRef* hits,
                                                 unsigned int count, unsigned int* work, SurfaceArgs surface,
                                                 const FrameParams* motion_params) {
    const unsigned int lane = threadIdx.x & 31u;
    for (;;) {
        unsigned int base = 0;
        if (lane == 0) base = atomicAdd(work, 32u);
        base = __shfl_sync(0xffffffffu, base, 0);
        if (base >= count) return;
        trace_ray<TRI, ANY, LOOP>(v, records, hits, (unsigned long long)base + lane, count, surface,
                                  motion_params);
        __syncwarp();
    }
}

/// The number of records to trace: `count`, or fewer when the queue's
/// length lives on the device (`device_count`, so the host need not read
/// it back between stages). Block 0 adds it to `traced` (ray statistics).
__device__ __forceinline__ unsigned int trace_count(unsigned int count, const unsigned int* device_count,
                                                    unsigned long long* traced) {
    unsigned int n = count;
    if (device_count) n = min(n, *device_count);
    if (traced && blockIdx.x == 0 && threadIdx.x == 0) atomicAdd(traced, (unsigned long long)n);
    return n;
}

#define TRACE_ARGS                                                                                           \
    const BvhNode *tlas_nodes, const BvhNode *blas_nodes, const WideNode *wide_nodes, const TriRecord *tris, const unsigned int *tri_ids, \
        const TlasInstance *instances, int tlas_root, RayRecord *records, HitRef *hits, unsigned int count,   \
        unsigned int *work, const unsigned int *device_count, unsigned long long *traced,                   \
        const FrameParams *surface_params, const SceneView *surface_scene, const FrameParams *alpha_params, \
        const SceneView *alpha_scene, const GpuCurve *curves, const GpuMotion *motions,                     \
        const FrameParams *motion_params
#define TRACE_VIEW                                                                   \
    SceneBvhView v = {tlas_nodes, blas_nodes, wide_nodes, tris, tri_ids, instances, tlas_root, alpha_params, alpha_scene, curves, motions}; \
    const unsigned int n = trace_count(count, device_count, traced);                \
    const SurfaceArgs surface = {surface_params, surface_scene}

// One extern "C" kernel per (query, loop, triangle test). A module holds
// the loops ATOLL_TRACE_LOOPS names (a bit per loop, in the order of
// `TraversalVariant::ALL`: ww, pt, sp, ptsp, cw, ptcw; default all): a frame
// traces with one, and each costs as much compile time as the others.
#ifndef ATOLL_TRACE_LOOPS
#define ATOLL_TRACE_LOOPS 0x3f
#endif
#define TRACE_GRID_KERNEL(query, any, test, tri, name, loop)                                         \
    extern "C" __global__ void __launch_bounds__(TRACE_THREADS) trace_##query##_##name##_##test(TRACE_ARGS) { \
        TRACE_VIEW;                                                                                  \
        trace_grid<tri, any, loop>(v, records, hits, n, surface, motion_params);                     \
    }
#define TRACE_PERSISTENT_KERNEL(query, any, test, tri, name, loop)                                   \
    extern "C" __global__ void __launch_bounds__(TRACE_THREADS) trace_##query##_##name##_##test(TRACE_ARGS) { \
        TRACE_VIEW;                                                                                  \
        trace_persistent<tri, any, loop>(v, records, hits, n, work, surface, motion_params);         \
    }
// Both queries with both triangle tests, for one loop.
#define TRACE_LOOP(kernel, name, loop)                          \
    kernel(closest, false, exact, TRI_EXACT, name, loop)        \
    kernel(closest, false, woop, TRI_WOOP, name, loop)          \
    kernel(any, true, exact, TRI_EXACT, name, loop)             \
    kernel(any, true, woop, TRI_WOOP, name, loop)

#if ATOLL_TRACE_LOOPS & 1
TRACE_LOOP(TRACE_GRID_KERNEL, ww, LOOP_WHILE_WHILE)
#endif
#if ATOLL_TRACE_LOOPS & 2
TRACE_LOOP(TRACE_PERSISTENT_KERNEL, pt, LOOP_WHILE_WHILE)
#endif
#if ATOLL_TRACE_LOOPS & 4
TRACE_LOOP(TRACE_GRID_KERNEL, sp, LOOP_SPECULATIVE)
#endif
#if ATOLL_TRACE_LOOPS & 8
TRACE_LOOP(TRACE_PERSISTENT_KERNEL, ptsp, LOOP_SPECULATIVE)
#endif
#if ATOLL_TRACE_LOOPS & 16
TRACE_LOOP(TRACE_GRID_KERNEL, cw, LOOP_WIDE)
#endif
#if ATOLL_TRACE_LOOPS & 32
TRACE_LOOP(TRACE_PERSISTENT_KERNEL, ptcw, LOOP_WIDE)
#endif
