// Light sampling: the mirror of `atoll_render::lights::LightSet` over the
// flat tables of `FrameParams` (emitters, pmf, cdf, infinite list, sorted
// triangle-light keys). Same selection (`partition_point` on the cdf), same
// arithmetic.
#pragma once

#include "common.cuh"
#include "params.cuh"
#include "record.cuh"
#include "sampling.cuh"
#include "environment.cuh"
#include "portal.cuh"
#include "texture.cuh"
#include "spawn.cuh"
#include "light_bvh.cuh"

// Whether emitters may have emission textures: always, unless the device
// compiles its shade kernel for a frame without any (`-DATOLL_WITH_EMISSION_TEXTURES=0`,
// src/device.rs `shade_features`): the texture call in light sampling costs
// the shade kernel registers.
#ifndef ATOLL_WITH_EMISSION_TEXTURES
#define ATOLL_WITH_EMISSION_TEXTURES 1
#endif

/// Mirrors `lights::LightSample`.
struct LightSample {
    float3 wi;
    float distance;
    float3 radiance;
    float pdf;
    bool delta;
    SurfacePoint target;
};

/// Mirrors `LightSet::triangle_light`: global light index of triangle
/// `triangle` of scene mesh `mesh` in instance `instance`, or `NO_LIGHT`.
/// Binary search of the sorted `(instance << 32) | mesh` keys.
__device__ __forceinline__ unsigned int light_triangle_index(const FrameParams& p, unsigned int instance,
                                                             unsigned int mesh, unsigned int triangle) {
    const unsigned long long key = ((unsigned long long)instance << 32) | (unsigned long long)mesh;
    unsigned int lo = 0, hi = p.triangle_key_count;
    while (lo < hi) {
        const unsigned int mid = lo + (hi - lo) / 2;
        if (p.triangle_keys[mid] < key) {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    if (lo < p.triangle_key_count && p.triangle_keys[lo] == key) return p.triangle_bases[lo] + triangle;
    return NO_LIGHT;
}

/// Mirrors `LightSet::select_by_power`: picks an emitter with `u` in [0, 1).
/// Returns false when there are no emitters; else writes (index, probability).
__device__ __forceinline__ bool light_select_by_power(const FrameParams& p, float u, unsigned int* index,
                                                      float* pmf) {
    const unsigned int n = p.light_count;
    if (n == 0) return false;
    // partition_point(|c| c <= u) over cdf[0..=n]: the first entry > u.
    unsigned int lo = 0, hi = n + 1;
    while (lo < hi) {
        const unsigned int mid = lo + (hi - lo) / 2;
        if (p.light_cdf[mid] <= u) {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    // Minus one (saturating), at most the last emitter; skips zero-probability emitters.
    unsigned int i = lo == 0 ? 0 : lo - 1;
    if (i > n - 1) i = n - 1;
    *index = i;
    *pmf = p.light_pmf[i];
    return true;
}

/// Mirrors `LightSet::unbounded_probability`.
__device__ __forceinline__ float light_unbounded_probability(const FrameParams& p) {
    const float n = (float)p.unbounded_count;
    const float tree = p.light_node_count == 0 ? 0.0f : 1.0f;
    return n == 0.0f ? 0.0f : __fdiv_rn(n, n + tree);
}

/// Mirrors `LightSet::select`: picks an emitter for shading point `pos`.
__device__ __forceinline__ bool light_select(const FrameParams& p, float3 pos, float u, unsigned int* index,
                                             float* pmf) {
    if (p.light_sampler == LIGHT_SAMPLER_POWER) return light_select_by_power(p, u, index, pmf);
    const float p_unbounded = light_unbounded_probability(p);
    if (u < p_unbounded) {
        const unsigned int n = p.unbounded_count;
        unsigned int k = (unsigned int)(__fdiv_rn(u, p_unbounded) * (float)n);
        if (k > n - 1) k = n - 1;
        *index = p.unbounded_lights[k];
        *pmf = __fdiv_rn(p_unbounded, (float)n);
        return true;
    }
    const float v = fminf(__fdiv_rn(u - p_unbounded, 1.0f - p_unbounded), ONE_MINUS_EPSILON);
    float tree_pmf;
    if (!light_bvh_sample(p, pos, v, index, &tree_pmf)) return false;
    *pmf = (1.0f - p_unbounded) * tree_pmf;
    return true;
}

/// Mirrors `LightSet::selection_pmf`.
__device__ __forceinline__ float light_selection_pmf(const FrameParams& p, float3 pos, unsigned int index) {
    if (p.light_sampler == LIGHT_SAMPLER_POWER) return p.light_pmf[index];
    const unsigned int kind = p.emitters[index].kind;
    if (kind == EMITTER_DISTANT || kind == EMITTER_INFINITE || kind == EMITTER_ENVIRONMENT) {
        return __fdiv_rn(light_unbounded_probability(p), (float)p.unbounded_count);
    }
    return (1.0f - light_unbounded_probability(p)) * light_bvh_pmf(p, pos, index);
}

/// A point light's position or a light at infinity as a shadow ray's
/// target (`lights::point_target`, `AT_INFINITY`).
__device__ __forceinline__ SurfacePoint point_target(float3 p) {
    SurfacePoint t;
    t.p = p;
    t.normal = zero3();
    t.error = 0.0f;
    return t;
}

/// Mirrors `lights::smooth_step` (pbrt's SmoothStep).
__device__ __forceinline__ float smooth_step(float x, float a, float b) {
    if (a == b) return x < a ? 0.0f : 1.0f;
    const float t = fminf(fmaxf(__fdiv_rn(x - a, b - a), 0.0f), 1.0f);
    return t * t * (3.0f - 2.0f * t);
}

/// Mirrors `LightSet::environment_radiance`.
__device__ __forceinline__ float3 light_environment_radiance(const FrameParams& p, unsigned int index, float3 origin,
                                                             float3 w) {
    const GpuEmitter& e = p.emitters[index];
    if (e.kind != EMITTER_ENVIRONMENT && e.kind != EMITTER_INFINITE) return zero3();
    if (e.portal != 0u && !portal_passes(portal_of(p, e), origin, w)) return zero3();
    return e.kind == EMITTER_ENVIRONMENT ? env_radiance(p, e, w) : load3(e.radiance);
}

/// Mirrors `LightSet::environment_direction_pdf`.
__device__ __forceinline__ float light_environment_direction_pdf(const FrameParams& p, const GpuEmitter& e,
                                                                 float3 from, float3 w) {
    if (e.kind != EMITTER_ENVIRONMENT && e.kind != EMITTER_INFINITE) return 0.0f;
    const float own = e.kind == EMITTER_ENVIRONMENT ? env_pdf(p, e, w) : UNIFORM_SPHERE_PDF;
    if (e.portal == 0u) return own;
    return 0.5f * own + 0.5f * portal_pdf(portal_of(p, e), from, w);
}

/// Mirrors `LightSet::pdf_environment`.
__device__ __forceinline__ float light_pdf_environment(const FrameParams& p, float3 from, unsigned int index,
                                                       float3 w) {
    return light_selection_pmf(p, from, index) * light_environment_direction_pdf(p, p.emitters[index], from, w);
}

/// Mirrors `LightSet::sample_through_portal` for emitter `index` (`e`),
/// which has a portal.
__device__ __forceinline__ bool light_sample_through_portal(const FrameParams& p, unsigned int index,
                                                            const GpuEmitter& e, float3 pos, float2 u, float3* wi,
                                                            float3* radiance, float* pdf) {
    // The portal's words are loaded where each use needs them: loaded once
    // and kept live across the environment's sampling, they cost the plain
    // shade kernel 13 registers (87 -> 100, tests/wavefront_compile.rs).
    // Mirrors `portal::split_strategy`.
    const bool through_portal = u.x >= 0.5f;
    u.x = through_portal ? u.x * 2.0f - 1.0f : u.x * 2.0f;
    if (through_portal) {
        float portal_density;
        if (!portal_sample(portal_of(p, e), pos, u, wi, &portal_density)) return false;
    } else if (e.kind == EMITTER_ENVIRONMENT) {
        float3 unused_radiance;
        float unused_pdf;
        if (!env_sample(p, e, u, wi, &unused_radiance, &unused_pdf)) return false;
    } else {
        *wi = sample_uniform_sphere(u);
    }
    *pdf = light_environment_direction_pdf(p, e, pos, *wi);
    if (!(*pdf > 0.0f)) return false;
    *radiance = light_environment_radiance(p, index, pos, *wi);
    return true;
}

/// For an emitter at `e.normal` with a world-to-light matrix in `e.p`
/// (goniometric and projection lights): the unit direction `wi` from
/// `pos` to it, the distance and its square, and the light-space direction
/// (not normalised) from it to `pos`.
__device__ __forceinline__ float3 towards_light_space(const GpuEmitter& e, float3 pos, float3* wi, float* distance,
                                                      float* dist2) {
    const float3 d = load3(e.normal) - pos;
    *dist2 = length_squared3(d);
    *distance = sqrtf(*dist2);
    *wi = d / *distance;
    const float3 w = -*wi;
    return make_float3(e.p[0] * w.x + e.p[3] * w.y + e.p[6] * w.z, e.p[1] * w.x + e.p[4] * w.y + e.p[7] * w.z,
                       e.p[2] * w.x + e.p[5] * w.y + e.p[8] * w.z);
}

/// Mirrors `LightSet::sample`: incident light at `pos` with selection number
/// `u_select` and position numbers `u`. False for Rust's `None`.
__device__ __forceinline__ bool light_sample(const FrameParams& p, float3 pos, float u_select, float2 u,
                                             LightSample* out) {
    unsigned int index;
    float pmf;
    if (!light_select(p, pos, u_select, &index, &pmf)) return false;
    out->target = point_target(zero3());
    if (pmf <= 0.0f) return false;
    const GpuEmitter& e = p.emitters[index];
    if (e.kind == EMITTER_POINT) {
        const float3 d = load3(&e.p[0]) - pos;
        const float dist2 = length_squared3(d);
        const float distance = sqrtf(dist2);
        out->wi = d / distance;
        out->distance = distance;
        out->radiance = load3(e.radiance) / dist2;
        out->pdf = pmf;
        out->delta = true;
        out->target = point_target(load3(&e.p[0]));
        return true;
    }
    if (e.kind == EMITTER_GONIOMETRIC) {
        // Mirrors `Emitter::Goniometric`: a point scaled by its map towards
        // the light-space direction (pole +y: the square's z is its y).
        float3 wi;
        float distance, dist2;
        const float3 l = towards_light_space(e, pos, &wi, &distance, &dist2);
        const float len = length3(l);
        if (!(len > 0.0f)) return false;
        const float2 uv = env_sphere_to_equal_area(make_float3(l.x, l.z, l.y) / len);
        const int n = (int)e.area;
        const int x = min(max((int)(uv.x * (float)n), 0), n - 1), y = min(max((int)(uv.y * (float)n), 0), n - 1);
        const float scale = p.environment_tables[e.table + (unsigned int)(y * n + x)];
        if (scale <= 0.0f) return false;
        out->wi = wi;
        out->distance = distance;
        out->radiance = load3(e.radiance) * __fdiv_rn(scale, dist2);
        out->pdf = pmf;
        out->delta = true;
        out->target = point_target(load3(e.normal));
        return true;
    }
    if (e.kind == EMITTER_PROJECTION) {
        // Mirrors `Emitter::Projection`: a point projecting its image
        // (`ProjectionImage::towards`): the table holds width, height, then
        // r, g, b by rows from the top.
        float3 wi;
        float distance, dist2;
        const float3 l = towards_light_space(e, pos, &wi, &distance, &dist2);
        if (l.z < PROJECTION_HITHER) return false;
        const float* table = p.environment_tables + e.table;
        const int width = (int)table[0], height = (int)table[1];
        const float aspect = (float)width / (float)height;
        const float2 half = aspect > 1.0f ? make_float2(aspect, 1.0f) : make_float2(1.0f, 1.0f / aspect);
        const float2 screen = make_float2(l.x / l.z / e.radiance[1], l.y / l.z / e.radiance[1]);
        if (fabsf(screen.x) > half.x || fabsf(screen.y) > half.y) return false;
        const float2 uv = (screen + half) / (2.0f * half);
        const int x = min(max((int)(uv.x * (float)width), 0), width - 1);
        const int y = min(max((int)(uv.y * (float)height), 0), height - 1);
        const float* texel = table + 2 + 3 * (y * width + x);
        const float3 rgb = make_float3(fmaxf(texel[0], 0.0f), fmaxf(texel[1], 0.0f), fmaxf(texel[2], 0.0f));
        const float3 radiance = rgb * __fdiv_rn(e.radiance[0], dist2);
        if (is_zero3(radiance)) return false;
        out->wi = wi;
        out->distance = distance;
        out->radiance = radiance;
        out->pdf = pmf;
        out->delta = true;
        out->target = point_target(load3(e.normal));
        return true;
    }
    if (e.kind == EMITTER_SPOT) {
        const float3 d = load3(&e.p[0]) - pos;
        const float dist2 = length_squared3(d);
        const float distance = sqrtf(dist2);
        const float3 wi = d / distance;
        const float falloff = smooth_step(dot3(load3(&e.p[3]), -wi), e.p[7], e.p[6]);
        if (falloff <= 0.0f) return false;
        out->wi = wi;
        out->distance = distance;
        out->radiance = load3(e.radiance) * __fdiv_rn(falloff, dist2);
        out->pdf = pmf;
        out->delta = true;
        out->target = point_target(load3(&e.p[0]));
        return true;
    }
    if (e.kind == EMITTER_DISTANT) {
        out->wi = -load3(&e.p[0]);
        out->distance = f32_infinity();
        out->radiance = load3(e.radiance);
        out->pdf = pmf;
        out->delta = true;
        return true;
    }
    if ((e.kind == EMITTER_ENVIRONMENT || e.kind == EMITTER_INFINITE) && e.portal != 0u) {
        float dir_pdf;
        if (!light_sample_through_portal(p, index, e, pos, u, &out->wi, &out->radiance, &dir_pdf)) return false;
        out->distance = f32_infinity();
        out->pdf = pmf * dir_pdf;
        out->delta = false;
        return true;
    }
    if (e.kind == EMITTER_ENVIRONMENT) {
        float dir_pdf;
        if (!env_sample(p, e, u, &out->wi, &out->radiance, &dir_pdf)) return false;
        out->distance = f32_infinity();
        out->pdf = pmf * dir_pdf;
        out->delta = false;
        return true;
    }
    if (e.kind == EMITTER_INFINITE) {
        out->wi = sample_uniform_sphere(u);
        out->distance = f32_infinity();
        out->radiance = load3(e.radiance);
        out->pdf = pmf * UNIFORM_SPHERE_PDF;
        out->delta = false;
        return true;
    }
    // Triangle.
    const float3 b = sample_uniform_triangle(u);
    const float3 p0 = load3(&e.p[0]), p1 = load3(&e.p[3]), p2 = load3(&e.p[6]);
    const float3 q = p0 * b.x + p1 * b.y + p2 * b.z;
    const float3 d = q - pos;
    const float dist2 = length_squared3(d);
    if (dist2 == 0.0f || e.area == 0.0f) return false;
    const float distance = sqrtf(dist2);
    const float3 wi = d / distance;
    const float cos_light = dot3(load3(e.normal), -wi);
    if (cos_light == 0.0f || (!e.two_sided && cos_light < 0.0f)) return false;
    out->wi = wi;
    out->distance = distance;
    out->radiance = load3(e.radiance);
#if ATOLL_WITH_EMISSION_TEXTURES
    if (e.table != NO_EMISSION_TEXTURE) out->radiance = out->radiance * emission_texture_value(p, e.table, b);
#endif
    out->pdf = pmf * dist2 / (fabsf(cos_light) * e.area);
    out->delta = false;
    // pbrt's bound for a sampled point, plus the corners' own (`LightSet::sample`).
    const float3 normal = load3(e.normal);
    out->target.p = q;
    out->target.normal = normal;
    out->target.error = error_along(normal, barycentric_magnitude(p0, p1, p2, b) * GAMMA_6) + e.error;
    return true;
}

/// Mirrors `LightSet::emitted`: radiance leaving emissive triangle `index`
/// towards `w` (pointing away from the surface), for a hit record whose
/// `emission_scale` is given.
__device__ __forceinline__ float3 light_emitted(const FrameParams& p, unsigned int index, float3 w,
                                                unsigned int emission_scale) {
    const GpuEmitter& e = p.emitters[index];
    if (e.kind != EMITTER_TRIANGLE) return zero3();
    if (!(e.two_sided || dot3(load3(e.normal), w) > 0.0f)) return zero3();
    if (e.table != NO_EMISSION_TEXTURE) return load3(e.radiance) * unpack_rgb9e5(emission_scale);
    return load3(e.radiance);
}

/// Mirrors `LightSet::pdf_triangle`: the light-sampling density of the point
/// at `distance` along `wi` on emissive triangle `index`.
__device__ __forceinline__ float light_pdf_triangle(const FrameParams& p, float3 from, unsigned int index,
                                                    float3 wi, float distance) {
    const GpuEmitter& e = p.emitters[index];
    if (e.kind != EMITTER_TRIANGLE) return 0.0f;
    const float c = fabsf(dot3(load3(e.normal), wi));
    if (c == 0.0f || e.area == 0.0f) return 0.0f;
    return light_selection_pmf(p, from, index) * distance * distance / (c * e.area);
}


