// Motion blur: a moving instance's transforms at a ray's time, the GPU port
// of atoll_scene::motion (`Motion::at`: translation and scale interpolated
// linearly, rotation slerped) and of glam's `Affine3A::inverse`. The same
// operations in the same order, though `acosf`/`sinf`/`cosf` may round the
// last bits differently from the CPU's.
#pragma once

#include "common.cuh"
#include "layout.cuh"
#include "rng.cuh"

/// A path's time sample in [0, 1): the same for all its rays and every
/// device (`FrameContext::ray_time` before the shutter maps it).
__device__ __forceinline__ float ray_time_sample(unsigned int seed, unsigned int pixel, unsigned int sample) {
    return stream_get(sample_stream(seed, pixel, sample), TIME_DIMENSION);
}

/// Where between its keys `m` is at time sample `u` (`Motion::key` of the
/// shutter's time).
__device__ __forceinline__ float motion_key(const GpuMotion& m, float u) {
    const float time = m.shutter[0] + (m.shutter[1] - m.shutter[0]) * u;
    if (time <= m.times[0]) return 0.0f;
    if (time >= m.times[1]) return 1.0f;
    return (time - m.times[0]) / (m.times[1] - m.times[0]);
}

/// `atoll_scene::motion::slerp` of the keys' quaternions (x, y, z, w).
__device__ __forceinline__ float4 motion_slerp(float4 a, float4 b, float s) {
    const float cos_theta = a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w;
    float4 q;
    if (cos_theta > 0.9995f) {
        q = make_float4(a.x * (1.0f - s) + b.x * s, a.y * (1.0f - s) + b.y * s, a.z * (1.0f - s) + b.z * s,
                        a.w * (1.0f - s) + b.w * s);
    } else {
        const float theta = acosf(fminf(fmaxf(cos_theta, -1.0f), 1.0f));
        float4 perp = make_float4(b.x - a.x * cos_theta, b.y - a.y * cos_theta, b.z - a.z * cos_theta,
                                  b.w - a.w * cos_theta);
        const float pl = 1.0f / sqrtf(perp.x * perp.x + perp.y * perp.y + perp.z * perp.z + perp.w * perp.w);
        const float c = cosf(theta * s), sn = sinf(theta * s);
        q = make_float4(a.x * c + perp.x * pl * sn, a.y * c + perp.y * pl * sn, a.z * c + perp.z * pl * sn,
                        a.w * c + perp.w * pl * sn);
    }
    const float l = 1.0f / sqrtf(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
    return make_float4(q.x * l, q.y * l, q.z * l, q.w * l);
}

/// Object to world of `m` at time sample `u`: row-major 3x4 into `out`
/// (`Decomposed::matrix` of `Motion::interpolate`: rotation · scale, then
/// the translation).
__device__ __forceinline__ void motion_object_to_world(const GpuMotion& m, float u, float* out) {
    const float s = motion_key(m, u);
    const float4 q = motion_slerp(make_float4(m.rotation[0], m.rotation[1], m.rotation[2], m.rotation[3]),
                                  make_float4(m.rotation[4], m.rotation[5], m.rotation[6], m.rotation[7]), s);
    // glam's Mat3::from_quat, row-major.
    const float x2 = q.x + q.x, y2 = q.y + q.y, z2 = q.z + q.z;
    const float xx = q.x * x2, xy = q.x * y2, xz = q.x * z2;
    const float yy = q.y * y2, yz = q.y * z2, zz = q.z * z2;
    const float wx = q.w * x2, wy = q.w * y2, wz = q.w * z2;
    const float r[9] = {1.0f - (yy + zz), xy - wz, xz + wy, xy + wz, 1.0f - (xx + zz), yz - wx,
                        xz - wy, yz + wx, 1.0f - (xx + yy)};
    float scale[9];
    for (int k = 0; k < 9; ++k) scale[k] = m.scale[k] * (1.0f - s) + m.scale[9 + k] * s;
    for (int row = 0; row < 3; ++row) {
        for (int col = 0; col < 3; ++col)
            out[row * 4 + col] =
                r[row * 3] * scale[col] + r[row * 3 + 1] * scale[3 + col] + r[row * 3 + 2] * scale[6 + col];
        out[row * 4 + 3] = m.translation[row] + (m.translation[3 + row] - m.translation[row]) * s;
    }
}

/// The inverse of row-major 3x4 affine `m` into `inv` (glam's
/// `Affine3A::inverse`) and, where `normal` is given, the inverse
/// transpose of its linear part, row-major 3x3 (the normal matrix).
__device__ __forceinline__ void affine_inverse(const float* m, float* inv, float* normal) {
    // Columns of the linear part, and their cross products (the adjugate's rows).
    const float3 cx = make_float3(m[0], m[4], m[8]), cy = make_float3(m[1], m[5], m[9]);
    const float3 cz = make_float3(m[2], m[6], m[10]);
    const float3 r0 = cross3(cy, cz), r1 = cross3(cz, cx), r2 = cross3(cx, cy);
    const float inv_det = 1.0f / dot3(cz, r2);
    const float3 rows[3] = {r0 * inv_det, r1 * inv_det, r2 * inv_det};
    const float3 t = make_float3(m[3], m[7], m[11]);
    for (int row = 0; row < 3; ++row) {
        inv[row * 4] = rows[row].x;
        inv[row * 4 + 1] = rows[row].y;
        inv[row * 4 + 2] = rows[row].z;
        inv[row * 4 + 3] = -dot3(rows[row], t);
    }
    if (normal) {
        // (M^-1)^T: the inverse's columns as rows.
        for (int row = 0; row < 3; ++row)
            for (int col = 0; col < 3; ++col) normal[row * 3 + col] = inv[col * 4 + row];
    }
}
