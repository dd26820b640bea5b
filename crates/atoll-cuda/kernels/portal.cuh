// Infinite-light portals: the mirror of `atoll_render::portal` (pbrt-v4's
// `PortalImageInfiniteLight` test of which rays see the environment, and
// atoll's sampling through the rectangle). A portal is PORTAL_WORDS floats
// of `FrameParams::environment_tables` at `GpuEmitter::portal - 1`:
// corner, far corner, edge u, edge v, frame x, y, z, area.
#pragma once

#include "common.cuh"
#include "params.cuh"

struct Portal {
    float3 corner, far_corner, edge_u, edge_v, x, y, z;
    float area;
};

/// The portal of an emitter whose `portal` field is not 0.
__device__ __forceinline__ Portal portal_of(const FrameParams& p, const GpuEmitter& e) {
    const float* w = p.environment_tables + (e.portal - 1u);
    Portal q;
    q.corner = load3(w);
    q.far_corner = load3(w + 3);
    q.edge_u = load3(w + 6);
    q.edge_v = load3(w + 9);
    q.x = load3(w + 12);
    q.y = load3(w + 15);
    q.z = load3(w + 18);
    q.area = w[21];
    return q;
}

/// Mirrors `PortalFrame::image_uv`; false behind the portal.
__device__ __forceinline__ bool portal_image_uv(const Portal& q, float3 w, float2* uv) {
    const float x = dot3(w, q.x), y = dot3(w, q.y), z = dot3(w, q.z);
    if (z <= 0.0f) return false;
    *uv = make_float2(clampf((atan2f(x, z) + FRAC_PI_2) / PI, 0.0f, 1.0f),
                      clampf((atan2f(y, z) + FRAC_PI_2) / PI, 0.0f, 1.0f));
    return true;
}

/// Mirrors `PortalFrame::passes`.
__device__ __forceinline__ bool portal_passes(const Portal& q, float3 origin, float3 w) {
    float2 uv, a, b;
    if (!portal_image_uv(q, w, &uv)) return false;
    if (!portal_image_uv(q, normalize3(q.corner - origin), &a)) return false;
    if (!portal_image_uv(q, normalize3(q.far_corner - origin), &b)) return false;
    return uv.x >= fminf(a.x, b.x) && uv.y >= fminf(a.y, b.y) && uv.x <= fmaxf(a.x, b.x) && uv.y <= fmaxf(a.y, b.y);
}

/// Mirrors `PortalFrame::sample`; false from in front of the portal.
__device__ __forceinline__ bool portal_sample(const Portal& q, float3 origin, float2 u, float3* w, float* pdf) {
    const float3 d = q.corner + u.x * q.edge_u + u.y * q.edge_v - origin;
    const float dist2 = length_squared3(d);
    *w = d / sqrtf(dist2);
    const float cos = dot3(*w, q.z);
    if (!(cos > 0.0f && dist2 > 0.0f)) return false;
    *pdf = dist2 / (q.area * cos);
    return true;
}

/// Mirrors `PortalFrame::pdf`.
__device__ __forceinline__ float portal_pdf(const Portal& q, float3 origin, float3 w) {
    const float cos = dot3(w, q.z);
    const float t = dot3(q.corner - origin, q.z) / cos;
    if (!(cos > 0.0f && t > 0.0f)) return 0.0f;
    const float3 h = origin + t * w - q.corner;
    const float a = dot3(h, q.edge_u) / length_squared3(q.edge_u);
    const float b = dot3(h, q.edge_v) / length_squared3(q.edge_v);
    if (!(a >= 0.0f && a <= 1.0f && b >= 0.0f && b <= 1.0f)) return 0.0f;
    return t * t / (q.area * cos);
}
