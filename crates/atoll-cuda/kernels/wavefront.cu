// The wavefront path tracer's stages on the GPU: generate, surface (hit
// attributes after traversal), shade and resolve_shadows. Each kernel ports
// the CPU stage of the same name (atoll-render `stages/*.rs`, `cpu.rs`)
// operation by operation, so CPU and GPU images agree pixel by pixel up to
// float rounding.
//
// Queue protocol (pbrt-v4's): every queue kernel is launched over the
// queue's *capacity* and reads the queue's length from device memory,
// returning early past it; the host never reads lengths back between stages.
// Appending kernels (shade) bump a device counter with atomics: the host
// zeroes `next_count` and `shadow_count` before launching `shade` (a memset,
// or the `reset_queue_counts` kernel below).
//
// Film order per bounce matches the CPU device: `shade` adds emission, then
// `resolve_shadows` adds unoccluded shadow rays. Within a wave every pixel
// appears at most once per queue, so the film's atomics never collide and
// the sums are deterministic.

#include "common.cuh"
#include "record.cuh"
#include "layout.cuh"
#include "params.cuh"
#include "rng.cuh"
#include "sampling.cuh"
#include "bsdf.cuh"
#include "lights.cuh"
#include "camera.cuh"
#include "surface.cuh"
#include "media.cuh"

// Participating media in `shade` (compiled out for frames without any,
// src/device.rs `shade_features`).
#ifndef ATOLL_WITH_MEDIA
#define ATOLL_WITH_MEDIA 1
#endif

// Which kernels a module holds: all (the default), or, for a frame's two
// modules compiled at once (src/device.rs), the shading kernels alone
// (ATOLL_WAVEFRONT_KERNELS=1, `surface` and `shade`, specialised to the
// frame's features) or the queue bookkeeping alone (=2). The shading kernels
// are most of the compile time, and the bookkeeping needs no specialising.
#ifndef ATOLL_WAVEFRONT_KERNELS
#define ATOLL_WAVEFRONT_KERNELS 0
#endif
#define WAVEFRONT_SHADING (ATOLL_WAVEFRONT_KERNELS != 2)
#define WAVEFRONT_BOOKKEEPING (ATOLL_WAVEFRONT_KERNELS != 1)

__device__ __forceinline__ unsigned int global_index() { return blockIdx.x * blockDim.x + threadIdx.x; }

__device__ __forceinline__ unsigned int lane_id() {
    unsigned int lane;
    asm("mov.u32 %0, %%laneid;" : "=r"(lane));
    return lane;
}

/// Slot of this thread in a queue whose length is `*counter`, for threads
/// with `want`; one atomic per warp (warp-aggregated). Every thread of the
/// warp that reaches this call must call it (with `want` true or false).
__device__ __forceinline__ unsigned int warp_append(unsigned int* counter, bool want) {
    const unsigned int active = __activemask();
    const unsigned int mask = __ballot_sync(active, want);
    if (!want) return 0xffffffffu;
    const unsigned int lane = lane_id();
    const unsigned int leader = __ffs(mask) - 1;
    unsigned int base = 0;
    if (lane == leader) base = atomicAdd(counter, (unsigned int)__popc(mask));
    base = __shfl_sync(mask, base, leader);
    return base + __popc(mask & ((1u << lane) - 1u));
}

/// Adds `c` to pixel `pixel` of the RGB f32 film. Mirrors `Film::add`.
__device__ __forceinline__ void film_add(float* film, unsigned int pixel, float3 c) {
    float* px = film + 3ull * pixel;
    atomicAdd(px + 0, c.x);
    atomicAdd(px + 1, c.y);
    atomicAdd(px + 2, c.z);
}

#if WAVEFRONT_BOOKKEEPING
// ---------------------------------------------------------------------------
// generate (stages/generate.rs)
// ---------------------------------------------------------------------------

/// Mirrors `generate::camera_record`, writing the record's ray half into
/// `*dst` (a camera ray has no hit yet: `store_ray_half`).
__device__ __forceinline__ void write_camera_record(const FrameParams& p, unsigned int pixel, unsigned int sample,
                                                    RayRecord* dst) {
    const unsigned int res_x = p.resolution[0];
    const SampleStream rng = sample_stream(p.seed, pixel, sample);
    // The pixel filter places the sample and weights it (`filter`).
    float weight;
    const float2 raster = filter_sample(p.filter, make_float2((float)(pixel % res_x), (float)(pixel / res_x)),
                                        make_float2(stream_get(rng, 0), stream_get(rng, 1)), &weight);
    float3 origin, direction;
    const float time = p.camera_moves ? ray_time_sample(p.seed, pixel, sample) : 0.0f;
    const float lens_weight =
        camera_ray(p, raster, make_float2(stream_get(rng, 2), stream_get(rng, 3)), time, &origin, &direction);
    // Emitters seen directly count in full, like after a specular bounce.
    // The path starts in the camera's medium.
    const unsigned char flags = (unsigned char)(FLAG_SPECULAR | (p.camera_medium << FLAG_MEDIUM_SHIFT));
    // A ray the lens blocks still counts as a sample, of nothing.
    const float t_max = lens_weight == 0.0f ? 0.0f : f32_infinity();
    weight *= lens_weight;
    store_ray_half(dst, origin, t_max, direction, pixel, make_float3(weight, weight, weight), sample, 0.0f, 0, flags,
                   0, 0u, 0u);
}

/// Mirrors `atoll_scene::camera::tile_order_pixel`: the pixel at place
/// `ordinal` of the order camera paths are made in (8x4 tiles in bands).
/// 32-bit arithmetic (64-bit division is a long software routine on the
/// GPU): a frame has at most 2^28 pixels (`FilmSettings::MAX_PIXELS`), so
/// `res_x * tile_h` and every index stay below 2^31.
__device__ __forceinline__ unsigned int tile_order_pixel(unsigned int ordinal, unsigned int res_x,
                                                         unsigned int res_y) {
    const unsigned int tile_w = 8, tile_h = 4;
    const unsigned int y0 = ordinal / (res_x * tile_h) * tile_h;
    const unsigned int h = min(tile_h, res_y - y0);
    const unsigned int j = ordinal - y0 * res_x;
    const unsigned int x0 = j / (tile_w * h) * tile_w;
    const unsigned int w = min(tile_w, res_x - x0);
    const unsigned int k = j - x0 * h;
    return (y0 + k / w) * res_x + x0 + k % w;
}

/// Appends a wave to the work FIFO (one thread; src/work.rs `WorkFeed::push`).
extern "C" __global__ void push_work(WorkFifo* __restrict__ fifo, unsigned int sample, unsigned int first_pixel,
                                     unsigned int count) {
    GpuWave& w = fifo->waves[fifo->pushed % WORK_SLOTS];
    w.sample = sample;
    w.first_pixel = first_pixel;
    w.pixel_count = count;
    w.queue_offset = 0;
    fifo->pushed += 1;
}

/// Claims the path queue's free slots for pending camera paths, front of the
/// FIFO first (one thread): the claims go to `refill_generate`, the new
/// length to `*path_count` and the host's status.
extern "C" __global__ void refill_claim(WorkFifo* __restrict__ fifo, WorkStatus* __restrict__ status,
                                        unsigned int* __restrict__ path_count, unsigned int capacity) {
    unsigned int len = *path_count;
    unsigned int claims = 0;
    while (len < capacity && status->waves_started != fifo->pushed && claims < WORK_CLAIMS) {
        const GpuWave w = fifo->waves[status->waves_started % WORK_SLOTS];
        const unsigned int n = min(capacity - len, w.pixel_count - fifo->taken);
        GpuWave& c = fifo->claims[claims++];
        c.sample = w.sample;
        c.first_pixel = w.first_pixel + fifo->taken;
        c.pixel_count = n;
        c.queue_offset = len;
        len += n;
        fifo->taken += n;
        status->paths_started += n;
        if (fifo->taken == w.pixel_count) {
            status->waves_started += 1;
            fifo->taken = 0;
        }
    }
    fifo->claim_count = claims;
    *path_count = len;
    status->queue_len = len;
}

/// Writes the camera records `refill_claim` claimed: thread i takes the
/// i-th new path over all claims (the claims count places in tile order).
/// Mirrors `CpuDevice::refill`.
extern "C" __global__ void refill_generate(const FrameParams* __restrict__ params,
                                           const WorkFifo* __restrict__ fifo, RayRecord* __restrict__ paths) {
    unsigned int i = global_index();
    const unsigned int claims = fifo->claim_count;
    for (unsigned int k = 0; k < claims; ++k) {
        const GpuWave c = fifo->claims[k];
        if (i < c.pixel_count) {
            const unsigned int pixel =
                tile_order_pixel(c.first_pixel + i, params->resolution[0], params->resolution[1]);
            write_camera_record(*params, pixel, c.sample, paths + c.queue_offset + i);
            return;
        }
        i -= c.pixel_count;
    }
}

#endif  // WAVEFRONT_BOOKKEEPING

#if WAVEFRONT_SHADING
// ---------------------------------------------------------------------------
// surface (cpu.rs `write_hit`)
// ---------------------------------------------------------------------------

/// Fills the hit fields of `paths[i]` from `hits[i]` for every record whose
/// trace found a hit (`instance != HIT_NONE`); other records are left as
/// they are. `t_max` was already shrunk by traversal. Mirrors `write_hit`.
extern "C" __global__ void surface(const FrameParams* __restrict__ params, const SceneView* __restrict__ scene,
                                   RayRecord* __restrict__ paths, const HitRef* __restrict__ hits,
                                   const unsigned int* __restrict__ path_count) {
    const unsigned int i = global_index();
    if (i >= *path_count) return;
    const HitRef hit = hits[i];
    if (hit.instance == HIT_NONE) return;
    write_surface(*params, *scene, paths + i, hit);
}

// ---------------------------------------------------------------------------
// shade (stages/shade.rs)
// ---------------------------------------------------------------------------

/// Mirrors `shade::ShadeOutcome`, storing only what differs from the shaded
/// record: the next segment and the shadow ray are copies of it with these
/// fields replaced (as `continuation` and `shadow_ray` build them).
struct ShadeOutcome {
    float3 emitted;
    bool has_next;
    float3 next_origin, next_direction, next_throughput;
    float next_pdf;
    unsigned short next_depth;
    unsigned char next_flags, next_eta_scale;
    bool has_shadow;
    float3 shadow_origin, shadow_direction, shadow_radiance;
    float shadow_t_max;
    /// The shadow ray's optical depth at its start (stored in its position).
    float3 shadow_depth;
};

/// Mirrors shade.rs's `hit_point`.
__device__ __forceinline__ SurfacePoint hit_point(const RayRecord& r) {
    SurfacePoint at;
    at.p = load3(r.position);
    at.normal = normalize_or_zero3(load_f16x3(r.geometric_normal));
    at.error = unpack_error(r.position_error);
    return at;
}

/// Mirrors shade.rs's `continuation`: the path goes on from the hit `at`
/// along `w` with the record's throughput, pdf, depth, flags (less HIT)
/// and eta scale.
__device__ __forceinline__ void set_continuation(ShadeOutcome& o, const RayRecord& r, const SurfacePoint& at,
                                                 float3 w) {
    o.has_next = true;
    o.next_origin = offset_ray_origin(at.p, at.error, at.normal, w);
    o.next_direction = w;
    o.next_throughput = load3(r.throughput);
    o.next_pdf = r.bsdf_pdf;
    o.next_depth = r.depth;
    o.next_flags = (unsigned char)(r.flags & ~FLAG_HIT);
    o.next_eta_scale = r.eta_scale;
}

/// Mirrors shade.rs's `shadow_ray` without its radiance: the ray towards
/// `target` when `to_target`, else along `w` up to `t_max`, into `o`'s
/// shadow fields; false when the two ends coincide. (A flag and a value
/// rather than a pointer: taking the light sample's address put it in
/// local memory.)
__device__ __forceinline__ bool spawn_shadow(ShadeOutcome& o, const SurfacePoint& at, bool to_target,
                                             SurfacePoint target, float3 w, float t_max) {
    if (to_target) return spawn_ray_to(at, target, &o.shadow_origin, &o.shadow_direction, &o.shadow_t_max);
    o.shadow_origin = offset_ray_origin(at.p, at.error, at.normal, w);
    o.shadow_direction = w;
    o.shadow_t_max = t_max;
    return true;
}

/// Mirrors shade.rs's `start_in_medium`: the shadow ray just spawned into
/// `o` leaves in `medium` (a frame with media only).
__device__ __forceinline__ void start_in_medium(const FrameParams& p, ShadeOutcome& o, unsigned int medium) {
    if (o.shadow_t_max == f32_infinity()) o.shadow_t_max = p.shadow_reach / length3(o.shadow_direction);
    o.shadow_depth = medium_optical_depth(p, medium, o.shadow_origin, o.shadow_direction, 0.0f, o.shadow_t_max);
}

/// Mirrors shade.rs's `russian_roulette` (`u`: the vertex's number for
/// it): false when the path ends, else `*beta` rescaled.
__device__ __forceinline__ bool russian_roulette(const FrameParams& params, float u, unsigned int depth,
                                                 float eta_scale, float3* beta) {
    if (params.russian_roulette && depth >= 1) {
        const float m = max_element3(abs3(*beta * eta_scale));
        if (m < 1.0f) {
            const float q = fmaxf(1.0f - m, 0.0f);
            if (u < q) return false;
            *beta = *beta / (1.0f - q);
        }
    }
    return is_finite3(*beta);
}

#if ATOLL_WITH_MEDIA
/// Mirrors shade.rs's `WALK_END`.
inline constexpr float WALK_END = 1.0f / 256.0f;

/// Mirrors shade.rs's `walk_subsurface`: a step of a walk through the
/// subsurface medium `medium`, scattering at `p` with throughput `beta`.
__device__ __noinline__ void walk_subsurface(const FrameParams& params, const RayRecord& r, unsigned int medium,
                                             float3 p, float3 beta, ShadeOutcome& out) {
    const unsigned int depth = r.depth;
    const SampleStream rng = sample_stream(params.seed, r.pixel, r.sample);
    const float3 origin = load3(r.origin), throughput = load3(r.throughput);
    const float3 wo = -normalize3(load3(r.direction));
    const float2 u_dir = make_float2(stream_walk(rng, depth, origin, throughput, BOUNCE_DIM_BSDF_DIRECTION, 0),
                                     stream_walk(rng, depth, origin, throughput, BOUNCE_DIM_BSDF_DIRECTION, 1));
    float pdf;
    const float3 wi = sample_henyey_greenstein(wo, params.media[medium].g, u_dir, &pdf);
    // shade.rs's `walk_roulette`.
    const float eta_scale = unpack_eta_scale(r.eta_scale);
    const float q = params.russian_roulette ? fmaxf(1.0f - max_element3(abs3(beta * eta_scale)), WALK_END) : WALK_END;
    if (stream_walk(rng, depth, origin, throughput, BOUNCE_DIM_RUSSIAN_ROULETTE, 0) < q) return;
    beta = beta / (1.0f - q);
    if (!is_finite3(beta)) return;
    SurfacePoint at;
    at.p = p;
    at.normal = zero3();
    at.error = 0.0f;
    set_continuation(out, r, at, wi);
    out.next_throughput = beta;
    out.next_pdf = pdf;
    out.next_flags = (unsigned char)(medium << FLAG_MEDIUM_SHIFT);
}

/// Mirrors shade.rs's `leave_subsurface`: a walk reaches its boundary `at`
/// from inside with throughput `beta` and leaves into `outside` by the
/// normalised Fresnel lobe.
__device__ __noinline__ void leave_subsurface(const FrameParams& params, const RayRecord& r, const SurfacePoint& at,
                                              unsigned int outside, float3 beta, ShadeOutcome& out) {
    const float eta = f16_to_f32(r.coeffs[COEFF_SUBSURFACE_ETA]);
    const float normalisation = f16_to_f32(r.coeffs[COEFF_SUBSURFACE_EXIT_NORMALISATION]);
    const float3 dir = load3(r.direction);
    const float3 n_out = dot3(at.normal, dir) < 0.0f ? -at.normal : at.normal;
    float3 ns = normalize_or_zero3(load_f16x3(r.shading_normal));
    if (is_zero3(ns)) ns = n_out;
    else if (dot3(ns, n_out) < 0.0f) ns = -ns;
    beta = beta * (eta * eta);
    const float eta_scale = unpack_eta_scale(r.eta_scale) / (eta * eta);
    const unsigned int depth = r.depth;
    const SampleStream rng = sample_stream(params.seed, r.pixel, r.sample);
    const float3 origin = load3(r.origin), throughput = load3(r.throughput);
    const float2 u_light = make_float2(stream_walk(rng, depth, origin, throughput, BOUNCE_DIM_LIGHT_POSITION, 0),
                                       stream_walk(rng, depth, origin, throughput, BOUNCE_DIM_LIGHT_POSITION, 1));
    LightSample ls;
    if (light_sample(params, at.p, stream_walk(rng, depth, origin, throughput, BOUNCE_DIM_LIGHT_SELECT, 0), u_light, &ls)) {
        const float cosine = dot3(ls.wi, ns);
        if (cosine > 0.0f && dot3(ls.wi, n_out) > 0.0f && ls.pdf > 0.0f && !is_zero3(ls.radiance)) {
            const bool spawned = spawn_shadow(out, at, is_finitef(ls.distance), ls.target, ls.wi, f32_infinity());
            const float pdf = cosine * FRAC_1_PI;
            const float w = ls.delta ? 1.0f : power_heuristic(ls.pdf, pdf);
            if (spawned) {
                out.has_shadow = true;
                out.shadow_radiance =
                    beta * ls.radiance * ((1.0f - fr_dielectric(cosine, eta)) / normalisation * pdf * w / ls.pdf);
                start_in_medium(params, out, outside);
            }
        }
    }
    const float2 u_dir = make_float2(stream_walk(rng, depth, origin, throughput, BOUNCE_DIM_BSDF_DIRECTION, 0),
                                     stream_walk(rng, depth, origin, throughput, BOUNCE_DIM_BSDF_DIRECTION, 1));
    const float3 local = sample_cosine_hemisphere(u_dir);
    const float3 wi = normalize3(frame_from_local(frame_from_z(ns), local));
    if (local.z <= 0.0f || dot3(wi, n_out) <= 0.0f) return;
    beta = beta * ((1.0f - fr_dielectric(local.z, eta)) / normalisation);
    if (!russian_roulette(params, stream_walk(rng, depth, origin, throughput, BOUNCE_DIM_RUSSIAN_ROULETTE, 0), depth, eta_scale,
                          &beta))
        return;
    set_continuation(out, r, at, wi);
    out.next_throughput = beta;
    out.next_eta_scale = pack_eta_scale(eta_scale);
    out.next_pdf = local.z * FRAC_1_PI;
    out.next_flags = (unsigned char)(outside << FLAG_MEDIUM_SHIFT);
}

/// Mirrors shade.rs's `scatter_in_medium`: the segment `r` scatters in
/// medium `medium` at `p`, with throughput `beta`: next-event estimation
/// and a new direction with the Henyey–Greenstein phase function.
__device__ __noinline__ void scatter_in_medium(const FrameParams& params, const RayRecord& r, unsigned int medium,
                                               float3 p, float3 beta, ShadeOutcome& out) {
    if (params.media[medium].subsurface) {
        walk_subsurface(params, r, medium, p, beta, out);
        return;
    }
    const unsigned int depth = r.depth;
    if (depth >= params.max_depth) return;
    const float g = params.media[medium].g;
    const float3 wo = -normalize3(load3(r.direction));
    SurfacePoint at;
    at.p = p;
    at.normal = zero3();
    at.error = 0.0f;
    const SampleStream rng = sample_stream(params.seed, r.pixel, r.sample);
    const float2 u_light = make_float2(stream_bounce(rng, depth, BOUNCE_DIM_LIGHT_POSITION, 0),
                                       stream_bounce(rng, depth, BOUNCE_DIM_LIGHT_POSITION, 1));
    LightSample ls;
    if (light_sample(params, p, stream_bounce(rng, depth, BOUNCE_DIM_LIGHT_SELECT, 0), u_light, &ls)) {
        const bool spawned = spawn_shadow(out, at, is_finitef(ls.distance), ls.target, ls.wi, f32_infinity());
        const float phase = henyey_greenstein(dot3(wo, ls.wi), g);
        if (spawned && ls.pdf > 0.0f && phase > 0.0f && !is_zero3(ls.radiance)) {
            const float w = ls.delta ? 1.0f : power_heuristic(ls.pdf, phase);
            out.has_shadow = true;
            out.shadow_radiance = beta * ls.radiance * (phase * w / ls.pdf);
            start_in_medium(params, out, medium);
        }
    }
    const float2 u_dir = make_float2(stream_bounce(rng, depth, BOUNCE_DIM_BSDF_DIRECTION, 0),
                                     stream_bounce(rng, depth, BOUNCE_DIM_BSDF_DIRECTION, 1));
    float pdf;
    const float3 wi = sample_henyey_greenstein(wo, g, u_dir, &pdf);
    const float u_roulette = stream_bounce(rng, depth, BOUNCE_DIM_RUSSIAN_ROULETTE, 0);
    if (!russian_roulette(params, u_roulette, depth, unpack_eta_scale(r.eta_scale), &beta)) return;
    set_continuation(out, r, at, wi);
    out.next_throughput = beta;
    out.next_pdf = pdf;
    out.next_depth = (unsigned short)(depth + 1);
    out.next_flags = (unsigned char)(medium << FLAG_MEDIUM_SHIFT);
}
#endif

#if ATOLL_WITH_MEDIA
/// Mirrors shade.rs's `medium_towards` closure: the medium on the side `w`
/// leaves a hit (normal `n`, reached along `dir`) into, given its `media`
/// word and the path's `medium`; a subsurface boundary's inside is its
/// interior whichever way its normal points.
__device__ __forceinline__ unsigned int medium_towards(unsigned int media, bool subsurface, unsigned int medium,
                                                       float3 n, float3 dir, float3 w) {
    if (!media) return medium;
    if (subsurface) return dot3(w, n) * dot3(dir, n) > 0.0f ? media >> 4 : medium;
    return media_towards(media, dot3(w, n));
}
#endif

/// Mirrors `shade::shade_path`.
__device__ __forceinline__ void shade_path(const FrameParams& params, const RayRecord& r, ShadeOutcome& out) {
    float3 beta = load3(r.throughput);
    const float3 dir = load3(r.direction);
    const bool specular = (r.flags & FLAG_SPECULAR) != 0;
    // Light selection may depend on where the path was: where this segment started.
    const float3 from = load3(r.origin);

#if ATOLL_WITH_MEDIA
    const unsigned int medium = r.flags >> FLAG_MEDIUM_SHIFT;
    // Through a medium: its emission along the segment, then where (and
    // whether) the segment scatters before its end.
    if (medium != 0u) {
        const float t_max = (r.flags & FLAG_HIT) ? r.t_max : f32_infinity();
        const SampleStream rng = sample_stream(params.seed, r.pixel, r.sample);
        const float u = stream_medium_distance(rng, r.depth, from, beta);
        // Its own local: the address of `out` would move all of it to local memory.
        float3 emitted = zero3();
        const MediumSegment seg =
            medium_sample_segment(params, medium, from, dir, t_max, u, medium_channel_probabilities(beta), &emitted);
        out.emitted = out.emitted + beta * emitted;
        if (seg.scatter) {
            scatter_in_medium(params, r, medium, from + normalize3(dir) * seg.t, beta * seg.weight, out);
            return;
        }
        beta = beta * seg.weight;
        if (is_zero3(beta)) return;
    }
#endif

    // Escaped: environment lights, MIS-weighted against light sampling.
    if (!(r.flags & FLAG_HIT)) {
        for (unsigned int k = 0; k < params.infinite_count; ++k) {
            const unsigned int i = params.infinite_lights[k];
            const float3 le = light_environment_radiance(params, i, from, dir);
            const float w =
                specular ? 1.0f : power_heuristic(r.bsdf_pdf, light_pdf_environment(params, from, i, dir));
            out.emitted = out.emitted + beta * le * w;
        }
        return;
    }

    // Emission of the surface hit, MIS-weighted against light sampling.
    if (r.light != NO_LIGHT) {
        const float3 le = light_emitted(params, r.light, -dir, r.emission_scale);
        if (!is_zero3(le)) {
            const float w =
                specular ? 1.0f
                         : power_heuristic(r.bsdf_pdf, light_pdf_triangle(params, from, r.light, dir, r.t_max));
            out.emitted = out.emitted + beta * le * w;
        }
    }

    const SurfacePoint at = hit_point(r);
    const float3 p = at.p;
#if ATOLL_WITH_MEDIA
    // The hit surface's media (inside << 4 | outside; 0 where it bounds none).
    const unsigned int media = r.material >> 8;
    const bool subsurface_entry = (r.material & 0xffu) == MATERIAL_SUBSURFACE && media != 0u;
    if (subsurface_entry && (media >> 4) == medium && params.media[medium].subsurface) {
        leave_subsurface(params, r, at, media & 15u, beta, out);
        return;
    }
#endif
    const Bsdf bsdf = bsdf_from_record(r, params.measured);
    if (bsdf.kind == MATERIAL_NONE) {
        // A surface that only bounds a medium: continue straight through.
        set_continuation(out, r, at, dir);
#if ATOLL_WITH_MEDIA
        out.next_throughput = beta;
        const unsigned int next = media ? media_towards(media, dot3(dir, at.normal)) : medium;
        out.next_flags = (unsigned char)((out.next_flags & ~FLAG_MEDIUM_MASK) | (next << FLAG_MEDIUM_SHIFT));
#endif
        return;
    }
    const unsigned int depth = r.depth;
    if (depth >= params.max_depth) return;
    const Frame frame = shading_frame(r);
    const float3 wo = frame_to_local(frame, -dir);
    if (wo.z == 0.0f) return;
    const SampleStream rng = sample_stream(params.seed, r.pixel, r.sample);

    // Next-event estimation.
    if (!bsdf_is_delta(bsdf)) {
        const float2 u_light = make_float2(stream_bounce(rng, depth, BOUNCE_DIM_LIGHT_POSITION, 0),
                                           stream_bounce(rng, depth, BOUNCE_DIM_LIGHT_POSITION, 1));
        LightSample ls;
        if (light_sample(params, p, stream_bounce(rng, depth, BOUNCE_DIM_LIGHT_SELECT, 0), u_light, &ls)) {
            // The ray first: the sample's target point is then dead before
            // the BSDF is evaluated (the plain shade kernel: 106 -> 99
            // registers, tests/wavefront_compile.rs).
            const bool spawned = spawn_shadow(out, at, is_finitef(ls.distance), ls.target, ls.wi, f32_infinity());
            const float3 wi = frame_to_local(frame, ls.wi);
            const float3 f = bsdf_eval(bsdf, wo, wi) * fabsf(wi.z);
            if (spawned && ls.pdf > 0.0f && !is_zero3(f) && !is_zero3(ls.radiance)) {
                const float w = ls.delta ? 1.0f : power_heuristic(ls.pdf, bsdf_pdf(bsdf, wo, wi));
                out.has_shadow = true;
                out.shadow_radiance = beta * f * ls.radiance * (w / ls.pdf);
#if ATOLL_WITH_MEDIA
                if (params.media_count > 1u) {
                    start_in_medium(params, out, medium_towards(media, subsurface_entry, medium, at.normal, dir, ls.wi));
                }
#endif
            }
        }
    }

    // Sample the BSDF for the next segment.
    const float2 u_dir = make_float2(stream_bounce(rng, depth, BOUNCE_DIM_BSDF_DIRECTION, 0),
                                     stream_bounce(rng, depth, BOUNCE_DIM_BSDF_DIRECTION, 1));
    BsdfSample bs;
    if (!bsdf_sample(bsdf, wo, stream_bounce(rng, depth, BOUNCE_DIM_BSDF_LOBE, 0), u_dir, &bs)) return;
    if (bs.pdf <= 0.0f || is_zero3(bs.f)) return;
    float3 next_beta = beta * bs.f * (fabsf(bs.wi.z) / bs.pdf);
    float eta_scale = unpack_eta_scale(r.eta_scale);
    if (bs.transmission) eta_scale *= bs.eta * bs.eta;
    // Russian roulette from the second bounce on (pbrt-v4's `depth > 1`), on
    // the magnitude of the throughput without the radiance scaling of
    // refractions (a pixel filter's negative lobes make some negative).
    if (!russian_roulette(params, stream_bounce(rng, depth, BOUNCE_DIM_RUSSIAN_ROULETTE, 0), depth, eta_scale,
                          &next_beta))
        return;
    const float3 wi = normalize3(frame_from_local(frame, bs.wi));
    set_continuation(out, r, at, wi);
    out.next_throughput = next_beta;
    out.next_eta_scale = pack_eta_scale(eta_scale);
    // A stochastic BSDF's sample density is only proportional to the real
    // one; MIS at the next vertex needs its pdf (shade.rs, pbrt's pdfIsProportional).
    out.next_pdf = bsdf_sampled_pdf_is_proportional(bsdf) && !bs.delta ? bsdf_pdf(bsdf, wo, bs.wi) : bs.pdf;
    out.next_depth = (unsigned short)(r.depth + 1);
    out.next_flags = bs.delta ? FLAG_SPECULAR : 0;
#if ATOLL_WITH_MEDIA
    const unsigned int next = medium_towards(media, subsurface_entry, medium, at.normal, dir, wi);
    out.next_flags |= (unsigned char)(next << FLAG_MEDIUM_SHIFT);
#endif
}

/// Mirrors `shade::shade_ambient_occlusion` (cosine-sampled AO: each
/// unoccluded shadow ray adds exactly 1).
__device__ __forceinline__ void shade_ambient_occlusion(const FrameParams& params, const RayRecord& r,
                                                        ShadeOutcome& out) {
    if (!(r.flags & FLAG_HIT)) return;
    const SurfacePoint at = hit_point(r);
    const float3 dir = load3(r.direction);
    if (bsdf_from_record(r, params.measured).kind == MATERIAL_NONE) {
        set_continuation(out, r, at, dir);
        return;
    }
    const float3 ng = dot3(at.normal, dir) > 0.0f ? -at.normal : at.normal;
    const SampleStream rng = sample_stream(params.seed, r.pixel, r.sample);
    const float2 u = make_float2(stream_bounce(rng, 0, BOUNCE_DIM_BSDF_DIRECTION, 0),
                                 stream_bounce(rng, 0, BOUNCE_DIM_BSDF_DIRECTION, 1));
    const float3 w = normalize3(frame_from_local(frame_from_z(ng), sample_cosine_hemisphere(u)));
    out.has_shadow = spawn_shadow(out, at, false, at, w, params.ao_max_distance);
    out.shadow_radiance = make_float3(1.0f, 1.0f, 1.0f);
}

/// Shades `paths[0 .. *path_count]` with the frame's integrator: adds
/// emission to `film` (RGB f32 sums per pixel), appends next segments to
/// `next` and shadow rays to `shadows`. The host zeroes `*next_count` and
/// `*shadow_count` before the launch. Mirrors `CpuDevice::shade`.
extern "C" __global__ void shade(const FrameParams* __restrict__ params, const RayRecord* __restrict__ paths,
                                 const unsigned int* __restrict__ path_count, RayRecord* __restrict__ next,
                                 unsigned int* __restrict__ next_count, RayRecord* __restrict__ shadows,
                                 unsigned int* __restrict__ shadow_count, float* __restrict__ film) {
    const unsigned int i = global_index();
    if (i >= *path_count) return;
    const FrameParams& p = *params;
    const RayRecord r = paths[i];
    ShadeOutcome out;
    out.emitted = zero3();
    out.has_next = false;
    out.has_shadow = false;
    out.shadow_depth = zero3();
    if (p.integrator == INTEGRATOR_AMBIENT_OCCLUSION) {
        shade_ambient_occlusion(p, r, out);
    } else {
        shade_path(p, r, out);
    }

    if (!is_zero3(out.emitted)) film_add(film, r.pixel, out.emitted);

    const unsigned int next_slot = warp_append(next_count, out.has_next);
    if (out.has_next) {
        store_ray_half(next + next_slot, out.next_origin, f32_infinity(), out.next_direction, r.pixel,
                       out.next_throughput, r.sample, out.next_pdf, out.next_depth, out.next_flags,
                       out.next_eta_scale, NO_LIGHT, r.instance);
    }
    const unsigned int shadow_slot = warp_append(shadow_count, out.has_shadow);
    if (out.has_shadow) {
        store_ray_half(shadows + shadow_slot, out.shadow_origin, out.shadow_t_max, out.shadow_direction, r.pixel,
                       out.shadow_radiance, r.sample, r.bsdf_pdf, r.depth, FLAG_SHADOW, r.eta_scale, NO_LIGHT,
                       r.instance);
        // The optical depth so far, where a medium can add to it (`RayRecord::optical_depth`).
        if (ATOLL_WITH_MEDIA) store3(shadows[shadow_slot].position, out.shadow_depth);
    }
}

#endif  // WAVEFRONT_SHADING

#if WAVEFRONT_BOOKKEEPING
// ---------------------------------------------------------------------------
// resolve_shadows (cpu.rs `resolve_shadows`) and queue bookkeeping
// ---------------------------------------------------------------------------

/// Adds the radiance of every unoccluded shadow ray in
/// `shadows[0 .. *shadow_count]` to its pixel. Mirrors `CpuDevice::resolve_shadows`.
extern "C" __global__ void resolve_shadows(const RayRecord* __restrict__ shadows,
                                           const unsigned int* __restrict__ shadow_count, float* __restrict__ film,
                                           unsigned int media) {
    const unsigned int i = global_index();
    if (i >= *shadow_count) return;
    const RayRecord& r = shadows[i];
    if (r.flags & FLAG_OCCLUDED) return;
    float3 radiance = load3(r.throughput);
    if (media) {
        // Through media, the light arrives attenuated by the optical depth gathered.
        const float3 depth = load3(r.position);
        radiance = radiance * make_float3(expf(-fmaxf(depth.x, 0.0f)), expf(-fmaxf(depth.y, 0.0f)),
                                          expf(-fmaxf(depth.z, 0.0f)));
    }
    film_add(film, r.pixel, radiance);
}

/// Zeroes the two append counters of `shade` (launch with one thread); the
/// host may use memsets instead.
extern "C" __global__ void reset_queue_counts(unsigned int* next_count, unsigned int* shadow_count) {
    if (global_index() == 0) {
        *next_count = 0;
        *shadow_count = 0;
    }
}
#endif  // WAVEFRONT_BOOKKEEPING
