// Bump and normal maps: the GPU port of `atoll_render::bump`, the shading
// normal bent by a material's displacement texture or normal-map image.
#pragma once

#include "bsdf.cuh"
#include "common.cuh"
#include "params.cuh"
#include "texture.cuh"

/// `bump::coordinate_system`: the tangents of the BSDF's frame about `v`.
__device__ __forceinline__ void coordinate_system(float3 v, float3* a_out, float3* b_out) {
    const Frame f = frame_from_z(v);
    *a_out = f.x;
    *b_out = f.y;
}

__device__ __forceinline__ bool finite3(float3 v) { return isfinite(v.x) && isfinite(v.y) && isfinite(v.z); }

/// `bump::triangle_partials`.
__device__ void triangle_partials(float3 p0, float3 p1, float3 p2, float2 uv0, float2 uv1, float2 uv2, float3 ng,
                                  float3* dpdu, float3* dpdv) {
    const float2 duv02 = uv0 - uv2, duv12 = uv1 - uv2;
    const float3 dp02 = p0 - p2, dp12 = p1 - p2;
    const float det = duv02.x * duv12.y - duv02.y * duv12.x;
    if (fabsf(det) >= 1e-9f) {
        const float inv = 1.0f / det;
        const float3 u = (dp02 * duv12.y - dp12 * duv02.y) * inv;
        const float3 v = (dp12 * duv02.x - dp02 * duv12.x) * inv;
        if (length_squared3(cross3(u, v)) > 0.0f && finite3(u) && finite3(v)) {
            *dpdu = u;
            *dpdv = v;
            return;
        }
    }
    coordinate_system(ng, dpdu, dpdv);
}

/// `bump::bent_normal` with `TextureTables::shading_geometry`'s program:
/// the shading normal at `position`/`uv` bent by program `range` of `kind`
/// (`bump::kind`), returned, and pbrt's shading `dpdu` with it in
/// `*dpdu_out` (`bump::Bent`); `ns` where the result is no direction.
__device__ float3 bent_normal(const FrameParams& p, unsigned int kind, ProgramRange range, float3 position,
                              float2 uv, float3 ng, float3 ns, float3 dpdu, float3 dpdv, bool interpolated,
                              const TexFootprint& fp, float3* dpdu_out) {
    // SurfaceAt::shading_partials.
    float3 ss = dpdu, ts = dpdv;
    if (interpolated) {
        ts = cross3(ns, dpdu);
        if (length_squared3(ts) > 0.0f) {
            ss = cross3(ts, ns);
        } else {
            coordinate_system(ns, &ss, &ts);
        }
    }
    float3 n = zero3();
    *dpdu_out = ss;
    if (kind == BUMP_BUMP) {
        // Half the footprint's uv change, BUMP_STEP where it is 0.
        float step_u = 0.5f * (fabsf(fp.duvdx.x) + fabsf(fp.duvdy.x));
        float step_v = 0.5f * (fabsf(fp.duvdx.y) + fabsf(fp.duvdy.y));
        if (step_u == 0.0f) step_u = BUMP_STEP;
        if (step_v == 0.0f) step_v = BUMP_STEP;
        const float d = run_program(p, range, uv, position, ng, nullptr, &fp).x;
        const float du =
            run_program(p, range, uv + make_float2(step_u, 0.0f), position + ss * step_u, ng, nullptr, &fp).x;
        const float dv =
            run_program(p, range, uv + make_float2(0.0f, step_v), position + ts * step_v, ng, nullptr, &fp).x;
        const float3 pu = ss + ns * ((du - d) / step_u);
        const float3 pv = ts + ns * ((dv - d) / step_v);
        n = normalize_or_zero3(cross3(pu, pv));
        *dpdu_out = pu;
    } else if (kind == BUMP_NORMAL_MAP) {
        const float3 c = run_program(p, range, uv, position, ng, nullptr, &fp);
        const float3 local = normalize_or_zero3(c * 2.0f - make_float3(1.0f, 1.0f, 1.0f));
        const float3 x = normalize_or_zero3(ss);
        const float3 y = cross3(ns, x);
        n = normalize_or_zero3(x * local.x + y * local.y + ns * local.z);
    }
    if (is_zero3(n) || !finite3(n)) {
        *dpdu_out = ss;
        return ns;
    }
    return dot3(n, ng) < 0.0f ? -n : n;
}
