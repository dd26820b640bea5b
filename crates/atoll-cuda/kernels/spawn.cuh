// Robust ray spawning: the mirror of `atoll_render::spawn` (pbrt-v4's
// error bounds and offsets; the Rust module explains them). Same
// operations in the same order, so CPU and GPU rays leave from the same
// floats.
#pragma once

#include "common.cuh"

/// Mirrors `spawn::barycentric_magnitude`: Σ |bᵢ pᵢ|.
__device__ __forceinline__ float3 barycentric_magnitude(float3 p0, float3 p1, float3 p2, float3 b) {
    return abs3(p0 * b.x) + abs3(p1 * b.y) + abs3(p2 * b.z);
}

/// Mirrors `spawn::transformed_error` for a row-major 3x4 affine `m`.
__device__ __forceinline__ float3 transformed_error(const float* m, float3 p, float3 e) {
    const float3 pa = abs3(p);
    float r[3], c[3];
    for (int row = 0; row < 3; ++row) {
        const float a0 = fabsf(m[row * 4 + 0]), a1 = fabsf(m[row * 4 + 1]), a2 = fabsf(m[row * 4 + 2]);
        r[row] = a0 * pa.x + a1 * pa.y + a2 * pa.z + fabsf(m[row * 4 + 3]);
        c[row] = a0 * e.x + a1 * e.y + a2 * e.z;
    }
    const float g = GAMMA_3;
    return make_float3(r[0], r[1], r[2]) * g + make_float3(c[0], c[1], c[2]) * (g + 1.0f);
}

/// Mirrors `spawn::error_along`.
__device__ __forceinline__ float error_along(float3 n, float3 e) { return dot3(abs3(n), e); }

/// Mirrors `spawn::pack_error`: bfloat16 bits, rounded up.
__device__ __forceinline__ unsigned int pack_error(float bound) {
    if (!(bound > 0.0f)) return 0u;
    const unsigned int bits = __float_as_uint(bound);
    const unsigned int high = bits >> 16;
    return (bits & 0xffffu) != 0u && high < 0x7f80u ? high + 1u : high;
}

/// Mirrors `spawn::unpack_error`.
__device__ __forceinline__ float unpack_error(unsigned short bits) { return __uint_as_float((unsigned int)bits << 16); }

/// Rust's `f32::next_up` for finite `v` (integer steps on the bits: the
/// library's `nextafterf` handles cases a ray origin never has, slowly).
__device__ __forceinline__ float next_float_up(float v) {
    const unsigned int bits = __float_as_uint(v);
    if ((bits & 0x7fffffffu) == 0u) return __uint_as_float(1u);  // ±0
    return __uint_as_float(v > 0.0f ? bits + 1u : bits - 1u);
}

/// Rust's `f32::next_down` for finite `v`.
__device__ __forceinline__ float next_float_down(float v) { return -next_float_up(-v); }

/// Mirrors `spawn::round_away`.
__device__ __forceinline__ float round_away(float v, float offset) {
    if (offset > 0.0f) return next_float_up(v);
    if (offset < 0.0f) return next_float_down(v);
    return v;
}

/// Mirrors `spawn::offset_ray_origin`.
__device__ __forceinline__ float3 offset_ray_origin(float3 p, float error, float3 n, float3 w) {
    float3 offset = n * error;
    if (dot3(n, w) < 0.0f) offset = -offset;
    const float3 po = p + offset;
    return make_float3(round_away(po.x, offset.x), round_away(po.y, offset.y), round_away(po.z, offset.z));
}

/// Mirrors `spawn::SurfacePoint`.
struct SurfacePoint {
    float3 p;
    float3 normal;
    float error;
};

/// Mirrors `spawn::spawn_ray_to`; false for `None`.
__device__ __forceinline__ bool spawn_ray_to(const SurfacePoint& from, const SurfacePoint& to, float3* origin,
                                             float3* direction, float* t_max) {
    const float3 o = offset_ray_origin(from.p, from.error, from.normal, to.p - from.p);
    const float3 target = offset_ray_origin(to.p, to.error, to.normal, o - to.p);
    const float3 d = target - o;
    const float length = length3(d);
    if (!(length > 0.0f && is_finitef(length))) return false;
    *origin = o;
    *direction = d * __fdiv_rn(1.0f, length);
    *t_max = length * (1.0f - SHADOW_EPSILON);
    return true;
}
