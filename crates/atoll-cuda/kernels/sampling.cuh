// Warping functions and MIS weights: the mirror of `atoll_render::sampling`
// (pbrt-v4's util/sampling.h), same operations in the same order.
#pragma once

#include "common.cuh"

/// Mirrors `sampling::sample_uniform_disk_concentric` (Shirley-Chiu).
__device__ __forceinline__ float2 sample_uniform_disk_concentric(float2 u) {
    const float2 o = make_float2(2.0f * u.x - 1.0f, 2.0f * u.y - 1.0f);
    if (o.x == 0.0f && o.y == 0.0f) return make_float2(0.0f, 0.0f);
    // Pick the wedge by the larger coordinate; the other one sets the angle.
    float r, theta;
    if (fabsf(o.x) > fabsf(o.y)) {
        r = o.x;
        theta = FRAC_PI_4 * (o.y / o.x);
    } else {
        r = o.y;
        theta = FRAC_PI_2 - FRAC_PI_4 * (o.x / o.y);
    }
    return make_float2(r * cosf(theta), r * sinf(theta));
}

/// Mirrors `sampling::sample_uniform_disk_polar`.
__device__ __forceinline__ float2 sample_uniform_disk_polar(float2 u) {
    const float r = sqrtf(u.x);
    const float theta = 2.0f * PI * u.y;
    return make_float2(r * cosf(theta), r * sinf(theta));
}

/// Mirrors `sampling::sample_cosine_hemisphere` (Malley's method).
__device__ __forceinline__ float3 sample_cosine_hemisphere(float2 u) {
    const float2 d = sample_uniform_disk_concentric(u);
    const float z = sqrtf(fmaxf(1.0f - length_squared2(d), 0.0f));
    return make_float3(d.x, d.y, z);
}

/// Mirrors `sampling::cosine_hemisphere_pdf`.
__device__ __forceinline__ float cosine_hemisphere_pdf(float cos_theta) { return cos_theta * FRAC_1_PI; }

/// Mirrors `sampling::sample_uniform_sphere`.
__device__ __forceinline__ float3 sample_uniform_sphere(float2 u) {
    const float z = 1.0f - 2.0f * u.x;
    const float r = sqrtf(fmaxf(1.0f - z * z, 0.0f));
    const float phi = 2.0f * PI * u.y;
    return make_float3(r * cosf(phi), r * sinf(phi), z);
}

/// Mirrors `sampling::sample_uniform_triangle` (Heitz): barycentrics b0, b1, b2.
__device__ __forceinline__ float3 sample_uniform_triangle(float2 u) {
    float b0, b1;
    if (u.x < u.y) {
        b0 = u.x / 2.0f;
        b1 = u.y - b0;
    } else {
        b1 = u.y / 2.0f;
        b0 = u.x - b1;
    }
    return make_float3(b0, b1, 1.0f - b0 - b1);
}

/// Mirrors `sampling::power_heuristic` (beta = 2, one sample each).
__device__ __forceinline__ float power_heuristic(float f_pdf, float g_pdf) {
    const float f2 = f_pdf * f_pdf;
    const float g2 = g_pdf * g_pdf;
    if (is_infinitef(f2)) return 1.0f;
    if (f2 + g2 == 0.0f) return 0.0f;
    return f2 / (f2 + g2);
}

/// Mirrors `sampling::spherical_direction`.
__device__ __forceinline__ float3 spherical_direction(float sin_theta, float cos_theta, float phi) {
    const float s = clampf(sin_theta, -1.0f, 1.0f);
    return make_float3(s * cosf(phi), s * sinf(phi), clampf(cos_theta, -1.0f, 1.0f));
}

/// Mirrors `sampling::sample_exponential`.
__device__ __forceinline__ float sample_exponential(float u, float a) { return -logf(1.0f - u) / a; }

/// Mirrors `sampling::henyey_greenstein`.
__device__ __forceinline__ float henyey_greenstein(float cos_theta, float g) {
    g = clampf(g, -0.99f, 0.99f);
    const float denom = 1.0f + g * g + 2.0f * g * cos_theta;
    return (1.0f / (4.0f * PI)) * (1.0f - g * g) / (denom * sqrtf(fmaxf(denom, 0.0f)));
}
