// A hit's texture footprint: the GPU port of `atoll_render::footprint`
// (pbrt-v4's `Camera::Approximate_dp_dxy` and the uv solve of
// `SurfaceInteraction::ComputeDifferentials`).
#pragma once

#include "common.cuh"
#include "params.cuh"

/// A hit's footprint (`texture::Footprint`): how its point and uv change
/// from one pixel to the next in x and y.
struct TexFootprint {
    float3 dpdx, dpdy;
    float2 duvdx, duvdy;
};

/// Row-major 3×3 `m` times `v`.
__device__ __forceinline__ float3 rows_mul(const float* m, float3 v) {
    return make_float3(m[0] * v.x + m[1] * v.y + m[2] * v.z, m[3] * v.x + m[4] * v.y + m[5] * v.z,
                       m[6] * v.x + m[7] * v.y + m[8] * v.z);
}

/// `footprint::rotate_from_to`, row-major.
__device__ __forceinline__ void rotate_from_to(float3 from, float3 to, float r[9]) {
    float3 refl;
    if (fabsf(from.x) < 0.72f && fabsf(to.x) < 0.72f) {
        refl = make_float3(1.0f, 0.0f, 0.0f);
    } else if (fabsf(from.y) < 0.72f && fabsf(to.y) < 0.72f) {
        refl = make_float3(0.0f, 1.0f, 0.0f);
    } else {
        refl = make_float3(0.0f, 0.0f, 1.0f);
    }
    const float3 u3 = refl - from, v3 = refl - to;
    const float uu = dot3(u3, u3), vv = dot3(v3, v3), uv = dot3(u3, v3);
    const float u[3] = {u3.x, u3.y, u3.z}, v[3] = {v3.x, v3.y, v3.z};
#pragma unroll
    for (int i = 0; i < 3; ++i)
#pragma unroll
        for (int j = 0; j < 3; ++j)
            r[3 * i + j] = (i == j ? 1.0f : 0.0f) - 2.0f / uu * u[i] * u[j] - 2.0f / vv * v[i] * v[j] +
                           4.0f * uv / (uu * vv) * v[i] * u[j];
}

/// `CameraFootprint::dp_dxy`.
__device__ void footprint_dp_dxy(const GpuFootprint& f, float3 p, float3 n, float3* dpdx, float3* dpdy) {
    const float3 rel = p - make_float3(f.camera_position[0], f.camera_position[1], f.camera_position[2]);
    const float3 p_camera = rows_mul(f.camera_from_world, rel);
    float down_z[9];
    rotate_from_to(normalize_or_zero3(p_camera), make_float3(0.0f, 0.0f, 1.0f), down_z);
    const float3 p_down = rows_mul(down_z, p_camera);
    const float3 n_down = rows_mul(down_z, rows_mul(f.camera_from_world, n));
    const float d = n_down.z * p_down.z;
    float3 out[2];
#pragma unroll
    for (int k = 0; k < 2; ++k) {
        const float3 o = make_float3(f.min_position[3 * k], f.min_position[3 * k + 1], f.min_position[3 * k + 2]);
        const float3 dir = make_float3(f.min_direction[3 * k], f.min_direction[3 * k + 1],
                                       1.0f + f.min_direction[3 * k + 2]);
        const float t = -(dot3(n_down, o) - d) / dot3(n_down, dir);
        const float3 v = o + dir * t - p_down;
        // The rotation's inverse is its transpose.
        const float3 back = make_float3(down_z[0] * v.x + down_z[3] * v.y + down_z[6] * v.z,
                                        down_z[1] * v.x + down_z[4] * v.y + down_z[7] * v.z,
                                        down_z[2] * v.x + down_z[5] * v.y + down_z[8] * v.z);
        out[k] = rows_mul(f.world_from_camera, back) * f.spp_scale;
    }
    *dpdx = out[0];
    *dpdy = out[1];
}

/// `footprint::difference_of_products`.
__device__ __forceinline__ float difference_of_products(float a, float b, float c, float d) {
    const float cd = c * d;
    const float error = fmaf(-c, d, cd);
    return fmaf(a, b, -cd) + error;
}

/// `footprint::uv_footprint` for one of x and y.
__device__ __forceinline__ float2 uv_change(float3 d, float3 dpdu, float3 dpdv, float ata00, float ata01,
                                            float ata11, float inv_det) {
    const float atb0 = dot3(dpdu, d), atb1 = dot3(dpdv, d);
    float du = difference_of_products(ata11, atb0, ata01, atb1) * inv_det;
    float dv = difference_of_products(ata00, atb1, ata01, atb0) * inv_det;
    du = isfinite(du) ? clampf(du, -1e8f, 1e8f) : 0.0f;
    dv = isfinite(dv) ? clampf(dv, -1e8f, 1e8f) : 0.0f;
    return make_float2(du, dv);
}

/// The footprint at a hit `p` (normal `n`, partials `dpdu`, `dpdv`).
__device__ TexFootprint hit_footprint(const GpuFootprint& f, float3 p, float3 n, float3 dpdu, float3 dpdv) {
    TexFootprint fp;
    footprint_dp_dxy(f, p, n, &fp.dpdx, &fp.dpdy);
    const float ata00 = dot3(dpdu, dpdu), ata01 = dot3(dpdu, dpdv), ata11 = dot3(dpdv, dpdv);
    float inv_det = 1.0f / difference_of_products(ata00, ata11, ata01, ata01);
    inv_det = isfinite(inv_det) ? inv_det : 0.0f;
    fp.duvdx = uv_change(fp.dpdx, dpdu, dpdv, ata00, ata01, ata11, inv_det);
    fp.duvdy = uv_change(fp.dpdy, dpdu, dpdv, ata00, ata01, ata11, inv_det);
    return fp;
}
