// pbrt-v4's solid noise and its textures: the GPU port of
// `atoll_render::noise` (Perlin's gradient noise, fBm, turbulence, windy,
// marble, polka dots), operation for operation.
#pragma once

#include "common.cuh"

// BEGIN GENERATED noise (src/header.rs; regenerate: ATOLL_BLESS=1 cargo test -p atoll-cuda header)
inline constexpr unsigned int NOISE_FBM = 0u;
inline constexpr unsigned int NOISE_WRINKLED = 1u;
inline constexpr unsigned int NOISE_WINDY = 2u;
inline constexpr unsigned int NOISE_MARBLE = 3u;
inline constexpr unsigned int NOISE_MAX_OCTAVES = 32u;
__device__ const unsigned char NOISE_PERMUTATION[256] = {
    151, 160, 137, 91, 90, 15, 131, 13, 201, 95, 96, 53, 194, 233, 7, 225,
    140, 36, 103, 30, 69, 142, 8, 99, 37, 240, 21, 10, 23, 190, 6, 148,
    247, 120, 234, 75, 0, 26, 197, 62, 94, 252, 219, 203, 117, 35, 11, 32,
    57, 177, 33, 88, 237, 149, 56, 87, 174, 20, 125, 136, 171, 168, 68, 175,
    74, 165, 71, 134, 139, 48, 27, 166, 77, 146, 158, 231, 83, 111, 229, 122,
    60, 211, 133, 230, 220, 105, 92, 41, 55, 46, 245, 40, 244, 102, 143, 54,
    65, 25, 63, 161, 1, 216, 80, 73, 209, 76, 132, 187, 208, 89, 18, 169,
    200, 196, 135, 130, 116, 188, 159, 86, 164, 100, 109, 198, 173, 186, 3, 64,
    52, 217, 226, 250, 124, 123, 5, 202, 38, 147, 118, 126, 255, 82, 85, 212,
    207, 206, 59, 227, 47, 16, 58, 17, 182, 189, 28, 42, 223, 183, 170, 213,
    119, 248, 152, 2, 44, 154, 163, 70, 221, 153, 101, 155, 167, 43, 172, 9,
    129, 22, 39, 253, 19, 98, 108, 110, 79, 113, 224, 232, 178, 185, 112, 104,
    218, 246, 97, 228, 251, 34, 242, 193, 238, 210, 144, 12, 191, 179, 162, 241,
    81, 51, 145, 235, 249, 14, 239, 107, 49, 192, 214, 31, 181, 199, 106, 157,
    184, 84, 204, 176, 115, 121, 50, 45, 127, 4, 150, 254, 138, 236, 205, 93,
    222, 114, 67, 29, 24, 72, 243, 141, 128, 195, 78, 66, 215, 61, 156, 180,
};
// END GENERATED noise

/// `noise::gradient`: lattice point (x, y, z)'s gradient dotted with `d`.
__device__ __forceinline__ float noise_gradient(int x, int y, int z, float dx, float dy, float dz) {
    const int h = NOISE_PERMUTATION[(NOISE_PERMUTATION[(NOISE_PERMUTATION[x & 255] + y) & 255] + z) & 255] & 15;
    const float u = h < 8 || h == 12 || h == 13 ? dx : dy;
    const float v = h < 4 || h == 12 || h == 13 ? dy : dz;
    return ((h & 1) ? -u : u) + ((h & 2) ? -v : v);
}

/// `noise::fade`.
__device__ __forceinline__ float noise_fade(float t) {
    const float t3 = t * t * t;
    const float t4 = t3 * t;
    const float t5 = t4 * t;
    return 6.0f * t5 - 15.0f * t4 + 10.0f * t3;
}

__device__ __forceinline__ float noise_lerp(float t, float a, float b) { return (1.0f - t) * a + t * b; }

/// `noise::noise`.
__device__ float noise3(float3 p) {
    const float period = 1073741824.0f;  // 2^30
    const float x = fmodf(p.x, period), y = fmodf(p.y, period), z = fmodf(p.z, period);
    const float fx = floorf(x), fy = floorf(y), fz = floorf(z);
    const float dx = x - fx, dy = y - fy, dz = z - fz;
    const int ix = (int)fx & 255, iy = (int)fy & 255, iz = (int)fz & 255;
    const float w000 = noise_gradient(ix, iy, iz, dx, dy, dz);
    const float w100 = noise_gradient(ix + 1, iy, iz, dx - 1.0f, dy, dz);
    const float w010 = noise_gradient(ix, iy + 1, iz, dx, dy - 1.0f, dz);
    const float w110 = noise_gradient(ix + 1, iy + 1, iz, dx - 1.0f, dy - 1.0f, dz);
    const float w001 = noise_gradient(ix, iy, iz + 1, dx, dy, dz - 1.0f);
    const float w101 = noise_gradient(ix + 1, iy, iz + 1, dx - 1.0f, dy, dz - 1.0f);
    const float w011 = noise_gradient(ix, iy + 1, iz + 1, dx, dy - 1.0f, dz - 1.0f);
    const float w111 = noise_gradient(ix + 1, iy + 1, iz + 1, dx - 1.0f, dy - 1.0f, dz - 1.0f);
    const float wx = noise_fade(dx), wy = noise_fade(dy), wz = noise_fade(dz);
    const float x00 = noise_lerp(wx, w000, w100), x10 = noise_lerp(wx, w010, w110);
    const float x01 = noise_lerp(wx, w001, w101), x11 = noise_lerp(wx, w011, w111);
    return noise_lerp(wz, noise_lerp(wy, x00, x10), noise_lerp(wy, x01, x11));
}

/// `noise::octaves_for`.
__device__ __forceinline__ float noise_octaves_for(float len2, unsigned int octaves) {
    if (isnan(len2)) len2 = 0.0f;
    return clampf(-1.0f - log2f(len2) / 2.0f, 0.0f, (float)min(octaves, NOISE_MAX_OCTAVES));
}

/// `noise::partial_weight`.
__device__ __forceinline__ float noise_partial_weight(float x) {
    const float t = clampf((x - 0.3f) / 0.4f, 0.0f, 1.0f);
    return t * t * (3.0f - 2.0f * t);
}

/// `noise::fbm` (ABS: `noise::turbulence`).
template <bool ABS>
__device__ __forceinline__ float noise_octaves(float3 p, float len2, float omega, unsigned int octaves) {
    octaves = min(octaves, NOISE_MAX_OCTAVES);
    const float n = noise_octaves_for(len2, octaves);
    const float whole = floorf(n);
    const unsigned int kept = (unsigned int)whole;
    float sum = 0.0f, lambda = 1.0f, o = 1.0f;
    for (unsigned int i = 0; i < kept; ++i) {
        const float v = noise3(p * lambda);
        sum += o * (ABS ? fabsf(v) : v);
        lambda *= 1.99f;
        o *= omega;
    }
    // The partial octave, where there is one (its noise costs as much as
    // a whole one's).
    const float partial = noise_partial_weight(n - whole);
    if (!ABS) return partial == 0.0f ? sum : sum + o * partial * noise3(p * lambda);
    sum += partial == 0.0f ? o * 0.2f : o * ((1.0f - partial) * 0.2f + partial * fabsf(noise3(p * lambda)));
    for (unsigned int i = kept; i < octaves; ++i) {
        sum += o * 0.2f;
        o *= omega;
    }
    return sum;
}

/// `noise::marble`.
__device__ float3 noise_marble(float3 p, float len2, float omega, unsigned int octaves, float scale,
                               float variation) {
    p = p * scale;
    const float m = p.y + variation * noise_octaves<false>(p, scale * scale * len2, omega, octaves);
    float t = 0.5f + 0.5f * sinf(m);
    const float colors[9][3] = {{0.58f, 0.58f, 0.6f}, {0.58f, 0.58f, 0.6f}, {0.58f, 0.58f, 0.6f},
                                {0.5f, 0.5f, 0.5f},   {0.6f, 0.59f, 0.58f}, {0.58f, 0.58f, 0.6f},
                                {0.58f, 0.58f, 0.6f}, {0.2f, 0.2f, 0.33f},  {0.58f, 0.58f, 0.6f}};
    const int segments = 6;
    const int first = min(max((int)floorf(t * (float)segments), 0), segments - 1);
    t = t * (float)segments - (float)first;
    float out[3];
#pragma unroll
    for (int c = 0; c < 3; ++c) {
        // De Casteljau's evaluation (glam's lerp is `noise_lerp`).
        const float c0 = colors[first][c], c1 = colors[first + 1][c], c2 = colors[first + 2][c],
                    c3 = colors[first + 3][c];
        const float a = noise_lerp(t, c0, c1), b = noise_lerp(t, c1, c2), d = noise_lerp(t, c2, c3);
        out[c] = 1.5f * noise_lerp(t, noise_lerp(t, a, b), noise_lerp(t, b, d));
    }
    return make_float3(out[0], out[1], out[2]);
}

/// `noise::evaluate`.
__device__ __noinline__ float3 noise_texture(unsigned int kind, float3 p, float len2, unsigned int octaves,
                                             float omega, float scale, float variation) {
    if (kind == NOISE_FBM) {
        const float v = noise_octaves<false>(p, len2, omega, octaves);
        return make_float3(v, v, v);
    }
    if (kind == NOISE_WRINKLED) {
        const float v = noise_octaves<true>(p, len2, omega, octaves);
        return make_float3(v, v, v);
    }
    if (kind == NOISE_WINDY) {
        const float v = fabsf(noise_octaves<false>(p * 0.1f, 0.01f * len2, 0.5f, 3)) *
                        noise_octaves<false>(p, len2, 0.5f, 6);
        return make_float3(v, v, v);
    }
    return noise_marble(p, len2, omega, octaves, scale, variation);
}

/// `noise::inside_polka_dot`.
__device__ __noinline__ bool inside_polka_dot(float2 st) {
    const float s_cell = floorf(st.x + 0.5f), t_cell = floorf(st.y + 0.5f);
    if (noise3(make_float3(s_cell + 0.5f, t_cell + 0.5f, 0.5f)) <= 0.0f) return false;
    const float radius = 0.35f, max_shift = 0.5f - radius;
    const float s_center = s_cell + max_shift * noise3(make_float3(s_cell + 1.5f, t_cell + 2.8f, 0.5f));
    const float t_center = t_cell + max_shift * noise3(make_float3(s_cell + 4.5f, t_cell + 9.8f, 0.5f));
    const float ds = st.x - s_center, dt = st.y - t_center;
    return ds * ds + dt * dt < radius * radius;
}
