// Curve pieces: the ray/curve test and the surface at a hit, the GPU port
// of atoll_bvh::curve (`intersect_curve`) and atoll_scene::curve
// (`CurvePiece::surface`), pbrt-v4's `Curve`. Same operations in the same
// order, though fused multiply-adds and the transcendental functions
// (the ribbon normal's sines, the cylinder's turn) may round the last bits
// differently from the CPU's.
#pragma once

#include "common.cuh"
#include "layout.cuh"

/// pbrt's subdivision cap (atoll_bvh::curve::MAX_CURVE_DEPTH).
#define CURVE_MAX_DEPTH 10

__device__ __forceinline__ float curve_lerp(float t, float a, float b) { return (1.0f - t) * a + t * b; }
__device__ __forceinline__ float3 curve_lerp3(float t, float3 a, float3 b) { return a * (1.0f - t) + b * t; }

__device__ __forceinline__ float3 curve_min3(float3 a, float3 b) {
    return make_float3(fminf(a.x, b.x), fminf(a.y, b.y), fminf(a.z, b.z));
}
__device__ __forceinline__ float3 curve_max3(float3 a, float3 b) {
    return make_float3(fmaxf(a.x, b.x), fmaxf(a.y, b.y), fmaxf(a.z, b.z));
}

/// glam's `any_orthonormal_vector` of unit `n` (Duff et al. 2017).
__device__ __forceinline__ float3 curve_orthonormal(float3 n) {
    const float sign = signumf(n.z);
    const float a = -1.0f / (sign + n.z);
    const float b = n.x * n.y * a;
    return make_float3(b, sign + n.y * n.y * a, -n.y);
}

/// The blossom p(a, b, c) of the cubic Bézier curve `p`.
__device__ __forceinline__ float3 curve_blossom(const float3 p[4], float a, float b, float c) {
    const float3 q0 = curve_lerp3(a, p[0], p[1]), q1 = curve_lerp3(a, p[1], p[2]), q2 = curve_lerp3(a, p[2], p[3]);
    const float3 r0 = curve_lerp3(b, q0, q1), r1 = curve_lerp3(b, q1, q2);
    return curve_lerp3(c, r0, r1);
}

/// The point at `t` of `p` and the derivative there (curve::evaluate).
__device__ __forceinline__ float3 curve_evaluate(const float3 p[4], float t, float3* derivative) {
    const float3 q0 = curve_lerp3(t, p[0], p[1]), q1 = curve_lerp3(t, p[1], p[2]), q2 = curve_lerp3(t, p[2], p[3]);
    const float3 r0 = curve_lerp3(t, q0, q1), r1 = curve_lerp3(t, q1, q2);
    const float3 d = r1 - r0;
    *derivative = dot3(d, d) > 0.0f ? d * 3.0f : (t < 0.5f ? p[2] - p[0] : p[3] - p[1]);
    return curve_lerp3(t, r0, r1);
}

struct CurvePieceData {
    float3 p[4];
    float w0, w1, u0, u1;
    float3 n0, n1;
    unsigned int kind;
};

__device__ __forceinline__ CurvePieceData load_curve(const GpuCurve* curves, unsigned int index) {
    const float4* w = reinterpret_cast<const float4*>(curves + index);
    const float4 a = __ldg(w), b = __ldg(w + 1), c = __ldg(w + 2), d = __ldg(w + 3), e = __ldg(w + 4),
                 f = __ldg(w + 5);
    CurvePieceData k;
    k.p[0] = make_float3(a.x, a.y, a.z);
    k.p[1] = make_float3(b.x, b.y, b.z);
    k.p[2] = make_float3(c.x, c.y, c.z);
    k.p[3] = make_float3(d.x, d.y, d.z);
    k.w0 = a.w;
    k.u0 = b.w;
    k.u1 = c.w;
    k.w1 = d.w;
    k.n0 = make_float3(e.x, e.y, e.z);
    k.n1 = make_float3(f.x, f.y, f.z);
    k.kind = __float_as_uint(e.w);
    return k;
}

__device__ __forceinline__ float curve_width_at(const CurvePieceData& c, float u) { return curve_lerp(u, c.w0, c.w1); }

/// curve::angle_between.
__device__ __forceinline__ float curve_angle_between(float3 a, float3 b) {
    if (dot3(a, b) < 0.0f) return 3.14159265358979f - 2.0f * asinf(clampf(length3(a + b) / 2.0f, -1.0f, 1.0f));
    return 2.0f * asinf(clampf(length3(b - a) / 2.0f, -1.0f, 1.0f));
}

/// CurvePiece::ribbon_normal.
__device__ __forceinline__ float3 curve_ribbon_normal(const CurvePieceData& c, float u) {
    const float angle = curve_angle_between(c.n0, c.n1);
    if (angle == 0.0f) return c.n0;
    const float inv_sin = 1.0f / sinf(angle);
    return c.n0 * (sinf((1.0f - u) * angle) * inv_sin) + c.n1 * (sinf(u * angle) * inv_sin);
}

/// atoll_bvh::curve::log2_int.
__device__ __forceinline__ int curve_log2_int(float v) {
    const unsigned int bits = __float_as_uint(v);
    const int exponent = (int)((bits >> 23) & 0xffu) - 127;
    return exponent + ((bits & 0x7fffffu) >= 0x3504f3u ? 1 : 0);
}

/// Whether the box of `cp` grown by `half` meets the segment (0,0,0)..(0,0,z_max).
__device__ __forceinline__ bool curve_overlaps_ray(const float3 cp[4], float half, float z_max) {
    const float3 lo = curve_min3(curve_min3(cp[0], cp[1]), curve_min3(cp[2], cp[3]));
    const float3 hi = curve_max3(curve_max3(cp[0], cp[1]), curve_max3(cp[2], cp[3]));
    return lo.x - half <= 0.0f && hi.x + half >= 0.0f && lo.y - half <= 0.0f && hi.y + half >= 0.0f &&
           lo.z - half <= z_max && hi.z + half >= 0.0f;
}

/// pbrt's leaf test of the nearly straight part `cp` (the ray's frame)
/// covering the segment's `u0..u1` (curve::segment_hit).
__device__ __forceinline__ bool curve_segment_hit(const CurvePieceData& c, const float3 cp[4], float u0, float u1,
                                                  float ray_length, float3 d, float z_max, float& t_out,
                                                  float& u_out, float& v_out) {
    if ((cp[1].y - cp[0].y) * -cp[0].y + cp[0].x * (cp[0].x - cp[1].x) < 0.0f) return false;
    if ((cp[2].y - cp[3].y) * -cp[3].y + cp[3].x * (cp[3].x - cp[2].x) < 0.0f) return false;
    const float sx = cp[3].x - cp[0].x, sy = cp[3].y - cp[0].y;
    const float denom = sx * sx + sy * sy;
    if (denom == 0.0f) return false;
    const float w = (-cp[0].x * sx + -cp[0].y * sy) / denom;
    const float u = clampf(curve_lerp(w, u0, u1), u0, u1);
    float hit_width = curve_width_at(c, u);
    if (c.kind == CURVE_RIBBON) hit_width *= fabsf(dot3(curve_ribbon_normal(c, u), d)) / ray_length;
    float3 dpcdw;
    const float3 pc = curve_evaluate(cp, clampf(w, 0.0f, 1.0f), &dpcdw);
    const float dist2 = pc.x * pc.x + pc.y * pc.y;
    if (dist2 > hit_width * hit_width * 0.25f || pc.z < 0.0f || pc.z > z_max) return false;
    const float t = pc.z / ray_length;
    if (!(t > 0.0f)) return false;
    const float dist = sqrtf(dist2);
    const float edge = dpcdw.x * -pc.y + pc.x * dpcdw.y;
    t_out = t;
    u_out = u;
    v_out = edge > 0.0f ? 0.5f + dist / hit_width : 0.5f - dist / hit_width;
    return true;
}

/// The closest hit (with ANY, the first found) of the ray (o, d) with
/// 0 < t < t_max on curve piece `c` (atoll_bvh::curve::intersect_curve).
template <bool ANY>
__device__ bool intersect_curve(const CurvePieceData& c, float3 o, float3 d, float t_max, float& t_hit,
                                float& u_hit, float& v_hit) {
    const float ray_length = length3(d);
    if (ray_length == 0.0f) return false;
    const float3 z = d / ray_length;
    float3 up = cross3(d, c.p[3] - c.p[0]);
    if (dot3(up, up) == 0.0f) up = curve_orthonormal(z);
    const float3 x = normalize3(cross3(normalize3(up), z));
    const float3 y = cross3(z, x);
    float3 cp[4];
    for (int i = 0; i < 4; ++i) {
        const float3 q = c.p[i] - o;
        cp[i] = make_float3(dot3(x, q), dot3(y, q), dot3(z, q));
    }
    // The refinement depth (curve::refinement_depth).
    float l0 = 0.0f;
    for (int i = 0; i < 2; ++i) {
        const float3 e = cp[i] - cp[i + 1] * 2.0f + cp[i + 2];
        l0 = fmaxf(l0, fmaxf(fmaxf(fabsf(e.x), fabsf(e.y)), fabsf(e.z)));
    }
    int depth = 0;
    if (l0 > 0.0f) {
        const float eps = fmaxf(c.w0, c.w1) * 0.05f;
        const float v = 1.41421356237f * 6.0f * l0 / (8.0f * eps);
        if (v >= 1.0f) depth = min(max(curve_log2_int(v) / 2, 0), CURVE_MAX_DEPTH);
    }
    float z_max = ray_length * t_max;
    bool found = false;
    int level = 0;
    unsigned int index = 0;
    for (;;) {
        const float scale = 1.0f / (float)(1u << level);
        const float a = (float)index * scale, b = (float)(index + 1u) * scale;
        float3 part[4] = {curve_blossom(cp, a, a, a), curve_blossom(cp, a, a, b), curve_blossom(cp, a, b, b),
                          curve_blossom(cp, b, b, b)};
        const float u0 = curve_lerp(a, c.u0, c.u1), u1 = curve_lerp(b, c.u0, c.u1);
        const float max_width = fmaxf(curve_width_at(c, u0), curve_width_at(c, u1));
        if (curve_overlaps_ray(part, 0.5f * max_width, z_max)) {
            if (level < depth) {
                ++level;
                index *= 2u;
                continue;
            }
            float t, u, v;
            if (curve_segment_hit(c, part, u0, u1, ray_length, d, z_max, t, u, v)) {
                t_hit = t;
                u_hit = u;
                v_hit = v;
                found = true;
                if (ANY) return true;
                z_max = t * ray_length;
            }
        }
        while (index & 1u) {
            index >>= 1;
            --level;
        }
        if (level == 0) return found;
        ++index;
    }
}

/// CurvePiece::surface: dpdu, dpdv and the unit normal at hit (u, v) of a
/// ray along `d`, all in the piece's space; returns the width there.
__device__ __forceinline__ float curve_surface(const CurvePieceData& c, float u, float v, float3 d, float3* dpdu,
                                               float3* dpdv, float3* normal) {
    const float span = c.u1 - c.u0;
    const float local = span > 0.0f ? (u - c.u0) / span : 0.0f;
    float3 du;
    curve_evaluate(c.p, clampf(local, 0.0f, 1.0f), &du);
    if (span > 0.0f) du = du / span;
    float width = curve_width_at(c, u);
    float3 dv;
    if (c.kind == CURVE_RIBBON) {
        const float3 n = curve_ribbon_normal(c, u);
        width *= fabsf(dot3(n, d)) / length3(d);
        dv = normalize_or_zero3(cross3(n, du)) * width;
    } else {
        const float3 across = normalize_or_zero3(cross3(d, du)) * width;
        if (c.kind == CURVE_FLAT) {
            dv = across;
        } else {
            const float theta = curve_lerp(v, -90.0f, 90.0f) * (3.14159265358979f / 180.0f);
            const float3 axis = normalize_or_zero3(du);
            dv = across * cosf(theta) - cross3(axis, across) * sinf(theta);
        }
    }
    *dpdu = du;
    *dpdv = dv;
    *normal = normalize_or_zero3(cross3(du, dv));
    return width;
}
