// Texture programs at hit points: the GPU port of `atoll_render::texture`
// (run_program, image lookups, alpha tests), operation by operation, so a
// textured hit gets the same coefficients on every device.
#pragma once

#include "footprint.cuh"

#include "access_count.cuh"
#include "common.cuh"
#include "layout.cuh"
#include "materials.cuh"
#include "noise.cuh"
#include "params.cuh"
#include "rng.cuh"

/// Mirror of `texture::TexOp` (32 bytes).
struct __align__(16) TexOp {
    unsigned int code, a, b, c;
    float f[4];
};

/// Mirror of `texture::ProgramRange`.
struct ProgramRange {
    unsigned int start, len;
};

/// Mirror of `texture::AlphaProgram` (16 bytes).
struct AlphaProgram {
    ProgramRange program;
    unsigned int mode;
    float cutoff;
};

// BEGIN GENERATED texture (src/header.rs; regenerate: ATOLL_BLESS=1 cargo test -p atoll-cuda header)
inline constexpr unsigned int TEXTURE_STACK = 8u;
inline constexpr unsigned int TEX_CONSTANT = 0u;
inline constexpr unsigned int TEX_IMAGE = 1u;
inline constexpr unsigned int TEX_CHECKERBOARD = 2u;
inline constexpr unsigned int TEX_SCALE = 3u;
inline constexpr unsigned int TEX_MIX = 4u;
inline constexpr unsigned int TEX_STORE = 5u;
inline constexpr unsigned int TEX_PROJECT = 6u;
inline constexpr unsigned int TEX_DATA = 7u;
inline constexpr unsigned int TEX_FACING = 8u;
inline constexpr unsigned int TEX_NOISE = 9u;
inline constexpr unsigned int TEX_DOTS = 10u;
inline constexpr unsigned int TEX_SOLID_CHECKERBOARD = 11u;
inline constexpr unsigned int TEX_BILERP = 12u;
inline constexpr unsigned int TEX_PROJECTED = 16777216u;
inline constexpr unsigned int PROJECT_SPHERICAL = 0u;
inline constexpr unsigned int PROJECT_CYLINDRICAL = 1u;
inline constexpr unsigned int PROJECT_PLANAR = 2u;
inline constexpr unsigned int PROJECT_POINT = 3u;
inline constexpr unsigned int BUMP_NONE = 0u;
inline constexpr unsigned int BUMP_BUMP = 1u;
inline constexpr unsigned int BUMP_NORMAL_MAP = 2u;
inline constexpr unsigned int STORE_RGB = 0u;
inline constexpr unsigned int STORE_FLOAT = 1u;
inline constexpr unsigned int STORE_ROUGHNESS = 2u;
inline constexpr unsigned int STORE_CONDUCTOR_REFLECTANCE = 3u;
inline constexpr unsigned int STORE_ASYMMETRY = 4u;
inline constexpr unsigned int STORE_ALBEDO = 5u;
inline constexpr unsigned int STORE_HAIR_ROUGHNESS = 6u;
inline constexpr unsigned int STORE_HAIR_REFLECTANCE = 7u;
inline constexpr unsigned int STORE_EUMELANIN = 8u;
inline constexpr unsigned int STORE_PHEOMELANIN = 9u;
inline constexpr unsigned int ALPHA_NONE = 0u;
inline constexpr unsigned int ALPHA_STOCHASTIC = 1u;
inline constexpr unsigned int ALPHA_CUTOFF = 2u;
inline constexpr unsigned int ALPHA_TEXTURE_MASK = 255u;
inline constexpr unsigned int WRAP_REPEAT = 0u;
inline constexpr unsigned int WRAP_CLAMP = 1u;
inline constexpr unsigned int WRAP_BLACK = 2u;
inline constexpr unsigned int WRAP_MIRROR = 3u;
inline constexpr unsigned int CHANNEL_RGB = 0u;
inline constexpr unsigned int CHANNEL_AVERAGE = 1u;
inline constexpr unsigned int CHANNEL_ALPHA = 2u;
inline constexpr unsigned int CHANNEL_RED = 3u;
inline constexpr unsigned int CHANNEL_GREEN = 4u;
inline constexpr unsigned int CHANNEL_BLUE = 5u;
inline constexpr unsigned int IMAGE_FILTER_SHIFT = 17u;
inline constexpr unsigned int IMAGE_LEVELS_SHIFT = 25u;
inline constexpr unsigned int FILTER_NONE = 0u;
inline constexpr unsigned int FILTER_POINT = 1u;
inline constexpr unsigned int FILTER_BILINEAR = 2u;
inline constexpr float BUMP_STEP = 0.0005f;
inline constexpr float EUMELANIN_SIGMA_A_R = 0.419f;
inline constexpr float EUMELANIN_SIGMA_A_G = 0.697f;
inline constexpr float EUMELANIN_SIGMA_A_B = 1.37f;
inline constexpr float PHEOMELANIN_SIGMA_A_R = 0.187f;
inline constexpr float PHEOMELANIN_SIGMA_A_G = 0.4f;
inline constexpr float PHEOMELANIN_SIGMA_A_B = 1.05f;
static_assert(sizeof(TexOp) == 32, "TexOp: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(TexOp, code) == 0 && sizeof(TexOp::code) == 4, "TexOp.code: offset or size differs from Rust");
static_assert(__builtin_offsetof(TexOp, a) == 4 && sizeof(TexOp::a) == 4, "TexOp.a: offset or size differs from Rust");
static_assert(__builtin_offsetof(TexOp, b) == 8 && sizeof(TexOp::b) == 4, "TexOp.b: offset or size differs from Rust");
static_assert(__builtin_offsetof(TexOp, c) == 12 && sizeof(TexOp::c) == 4, "TexOp.c: offset or size differs from Rust");
static_assert(__builtin_offsetof(TexOp, f) == 16 && sizeof(TexOp::f) == 16, "TexOp.f: offset or size differs from Rust");
#endif
static_assert(sizeof(ProgramRange) == 8, "ProgramRange: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(ProgramRange, start) == 0 && sizeof(ProgramRange::start) == 4, "ProgramRange.start: offset or size differs from Rust");
static_assert(__builtin_offsetof(ProgramRange, len) == 4 && sizeof(ProgramRange::len) == 4, "ProgramRange.len: offset or size differs from Rust");
#endif
static_assert(sizeof(AlphaProgram) == 16, "AlphaProgram: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(AlphaProgram, program) == 0 && sizeof(AlphaProgram::program) == 8, "AlphaProgram.program: offset or size differs from Rust");
static_assert(__builtin_offsetof(AlphaProgram, mode) == 8 && sizeof(AlphaProgram::mode) == 4, "AlphaProgram.mode: offset or size differs from Rust");
static_assert(__builtin_offsetof(AlphaProgram, cutoff) == 12 && sizeof(AlphaProgram::cutoff) == 4, "AlphaProgram.cutoff: offset or size differs from Rust");
#endif
// END GENERATED texture

/// `texture::hit_uv`: interpolated uvs, or pbrt's default (0,0), (1,0), (1,1).
__device__ __forceinline__ float2 hit_uv(const SceneView& s, const GpuMesh& mesh, unsigned int i0, unsigned int i1,
                                         unsigned int i2, float b1, float b2) {
    const float b0 = 1.0f - b1 - b2;
    if (mesh.flags & MESH_HAS_UVS) {
        count_access(s.uvs + 2ull * i0);
        count_access(s.uvs + 2ull * i1);
        count_access(s.uvs + 2ull * i2);
        const float2 a = make_float2(s.uvs[2ull * i0], s.uvs[2ull * i0 + 1]);
        const float2 b = make_float2(s.uvs[2ull * i1], s.uvs[2ull * i1 + 1]);
        const float2 c = make_float2(s.uvs[2ull * i2], s.uvs[2ull * i2 + 1]);
        // glam: a * b0 + b * b1 + c * b2, left to right.
        return make_float2(a.x * b0 + b.x * b1 + c.x * b2, a.y * b0 + b.y * b1 + c.y * b2);
    }
    return make_float2(b1 + b2, b2);
}

/// `TextureImage::texel`: linear RGBA of texel (x, y).
__device__ __forceinline__ float4 image_texel(const FrameParams& p, const GpuImage& img, unsigned int x,
                                              unsigned int y) {
    const unsigned long long i = (unsigned long long)y * img.width + x;
    if (img.format == IMAGE_RGBA_F32) {
        const unsigned int* w = p.texels + img.texel_offset + 4ull * i;
        count_access(w);
        return make_float4(__uint_as_float(w[0]), __uint_as_float(w[1]), __uint_as_float(w[2]),
                           __uint_as_float(w[3]));
    }
    count_access(p.texels + img.texel_offset + i);
    const unsigned int w = p.texels[img.texel_offset + i];
    const unsigned int r = w & 0xffu, g = (w >> 8) & 0xffu, b = (w >> 16) & 0xffu, a = w >> 24;
    const float inv = 1.0f / 255.0f;
    if (img.format == IMAGE_RGBA8_SRGB) {
        return make_float4(p.srgb_to_linear[r], p.srgb_to_linear[g], p.srgb_to_linear[b], (float)a * inv);
    }
    return make_float4((float)r * inv, (float)g * inv, (float)b * inv, (float)a * inv);
}

/// `texture::wrap_coord`; false: black.
__device__ __forceinline__ bool wrap_coord(int i, int n, unsigned int wrap, int* out) {
    if (i >= 0 && i < n) {
        *out = i;
        return true;
    }
    if (wrap == WRAP_CLAMP) {
        *out = i < 0 ? 0 : n - 1;
        return true;
    }
    if (wrap == WRAP_BLACK) return false;
    if (wrap == WRAP_MIRROR) {
        int period = i % (2 * n);
        if (period < 0) period += 2 * n;
        *out = period < n ? period : 2 * n - 1 - period;
        return true;
    }
    int m = i % n;
    if (m < 0) m += n;
    *out = m;
    return true;
}

__device__ __forceinline__ float4 wrapped_texel(const FrameParams& p, const GpuImage& img, int x, int y,
                                                unsigned int wrap) {
    int wx, wy;
    if (!wrap_coord(x, (int)img.width, wrap, &wx) || !wrap_coord(y, (int)img.height, wrap, &wy))
        return make_float4(0.0f, 0.0f, 0.0f, 0.0f);
    return image_texel(p, img, (unsigned int)wx, (unsigned int)wy);
}

__device__ __forceinline__ float2 apply_mapping(const TexOp& o, float2 uv) {
    return make_float2(o.f[0] * uv.x + o.f[2], o.f[1] * uv.y + o.f[3]);
}

__device__ __forceinline__ float3 max0(float3 v) {
    return make_float3(fmaxf(v.x, 0.0f), fmaxf(v.y, 0.0f), fmaxf(v.z, 0.0f));
}

/// `texture::bilerp`: image `img` at `st`, pbrt-v4 texel addressing.
__device__ float4 bilerp_image(const FrameParams& p, const GpuImage& img, float2 st, unsigned int wrap) {
    const float x = st.x * (float)img.width - 0.5f;
    const float y = (1.0f - st.y) * (float)img.height - 0.5f;
    const float xf = floorf(x), yf = floorf(y);
    const float dx = x - xf, dy = y - yf;
    const int x0 = (int)clampf(xf, -1e8f, 1e8f), y0 = (int)clampf(yf, -1e8f, 1e8f);
    const float4 t00 = wrapped_texel(p, img, x0, y0, wrap), t10 = wrapped_texel(p, img, x0 + 1, y0, wrap);
    const float4 t01 = wrapped_texel(p, img, x0, y0 + 1, wrap),
                 t11 = wrapped_texel(p, img, x0 + 1, y0 + 1, wrap);
    const float a00[4] = {t00.x, t00.y, t00.z, t00.w}, a10[4] = {t10.x, t10.y, t10.z, t10.w};
    const float a01[4] = {t01.x, t01.y, t01.z, t01.w}, a11[4] = {t11.x, t11.y, t11.z, t11.w};
    float px[4];
#pragma unroll
    for (int c = 0; c < 4; ++c)
        px[c] = ((1.0f - dx) * a00[c] + dx * a10[c]) * (1.0f - dy) + ((1.0f - dx) * a01[c] + dx * a11[c]) * dy;
    return make_float4(px[0], px[1], px[2], px[3]);
}

/// Image `o.a + level` of an IMAGE op.
__device__ __forceinline__ GpuImage image_level(const FrameParams& p, const TexOp& o, unsigned int level) {
    count_access(p.images + o.a + level);
    return p.images[o.a + level];
}

/// `texture::image_lookup`: pbrt-v4's `MIPMap::Filter` over the op's MIP
/// levels by the derivatives `dx`, `dy` of `uv` (before its mapping), or
/// bilinear in the image itself.
__device__ float3 image_lookup(const FrameParams& p, const TexOp& o, float2 uv, float2 dx, float2 dy) {
    const unsigned int wrap = o.b & 0xffu, channel = (o.b >> 8) & 0xffu;
    const bool invert = ((o.b >> 16) & 1u) != 0u;
    const unsigned int filter = (o.b >> IMAGE_FILTER_SHIFT) & 0x7u, levels = (o.b >> IMAGE_LEVELS_SHIFT) & 0x3fu;
    const float scale = __uint_as_float(o.c);
    const float2 st = apply_mapping(o, uv);
    float4 t;
    if (filter == FILTER_NONE) {
        t = bilerp_image(p, image_level(p, o, 0), st, wrap);
    } else {
        const float w = 2.0f * fmaxf(fmaxf(fabsf(o.f[0] * dx.x), fabsf(o.f[1] * dx.y)),
                                     fmaxf(fabsf(o.f[0] * dy.x), fabsf(o.f[1] * dy.y)));
        const float n = (float)levels;
        const float lod = n - 1.0f + log2f(fmaxf(w, 1e-8f));
        if (lod >= n - 1.0f) {
            t = wrapped_texel(p, image_level(p, o, levels - 1), 0, 0, wrap);
        } else {
            const unsigned int i = (unsigned int)fmaxf(floorf(lod), 0.0f);
            const GpuImage img = image_level(p, o, i);
            if (filter == FILTER_POINT) {
                const float x = rintf(st.x * (float)img.width - 0.5f);
                const float y = rintf((1.0f - st.y) * (float)img.height - 0.5f);
                t = wrapped_texel(p, img, (int)clampf(x, -1e8f, 1e8f), (int)clampf(y, -1e8f, 1e8f), wrap);
            } else if (filter == FILTER_BILINEAR || i == 0u) {
                t = bilerp_image(p, img, st, wrap);
            } else {
                const float4 a = bilerp_image(p, img, st, wrap);
                const float4 b = bilerp_image(p, image_level(p, o, i + 1), st, wrap);
                const float f = lod - (float)i;
                t = make_float4((1.0f - f) * a.x + f * b.x, (1.0f - f) * a.y + f * b.y, (1.0f - f) * a.z + f * b.z,
                                (1.0f - f) * a.w + f * b.w);
            }
        }
    }
    const float px[4] = {t.x, t.y, t.z, t.w};
    float3 v;
    if (channel == CHANNEL_AVERAGE) {
        const float m = (px[0] + px[1] + px[2]) * (1.0f / 3.0f);
        v = make_float3(m, m, m);
    } else if (channel == CHANNEL_ALPHA) {
        v = make_float3(px[3], px[3], px[3]);
    } else if (channel == CHANNEL_RED) {
        v = make_float3(px[0], px[0], px[0]);
    } else if (channel == CHANNEL_GREEN) {
        v = make_float3(px[1], px[1], px[1]);
    } else if (channel == CHANNEL_BLUE) {
        v = make_float3(px[2], px[2], px[2]);
    } else {
        v = make_float3(px[0], px[1], px[2]);
    }
    v = v * scale;
    return invert ? max0(make_float3(1.0f, 1.0f, 1.0f) - v) : max0(v);
}

/// `Material::conductor_k_from_reflectance` for one channel.
__device__ __forceinline__ float conductor_k(float r) {
    r = clampf(r, 0.0f, 0.9999f);
    return 2.0f * sqrtf(r) / sqrtf(1.0f - r);
}

/// `HairParams::sigma_a_from_reflectance` for one channel: pbrt-v4's fit
/// of the absorption that gives reflectance `c` at azimuthal roughness `b`.
__device__ __forceinline__ float hair_sigma_a_from_reflectance(float c, float b) {
    const float b2 = b * b, b3 = b2 * b, b4 = b2 * b2, b5 = b4 * b;
    const float fit = 5.969f - 0.215f * b + 2.532f * b2 - 10.73f * b3 + 5.574f * b4 + 0.245f * b5;
    const float l = logf(clampf(c, 1e-6f, 1.0f)) / fit;
    return l * l;
}

/// `texture::store_value` into f16 coefficients.
__device__ __forceinline__ void store_value(float3 v, unsigned int slot, unsigned int how, unsigned short* coeffs) {
    if (how == STORE_ASYMMETRY) {
        coeffs[slot] = f32_to_f16(clampf(v.x, -1.0f, 1.0f));
        return;
    }
    if (how == STORE_HAIR_ROUGHNESS) {
        coeffs[slot] = f32_to_f16(clampf(v.x, 0.01f, 1.0f));
        return;
    }
    v = max0(v);
    if (how == STORE_ALBEDO) v = make_float3(fminf(v.x, 1.0f), fminf(v.y, 1.0f), fminf(v.z, 1.0f));
    if (how == STORE_RGB || how == STORE_ALBEDO) {
        coeffs[slot] = f32_to_f16(v.x);
        coeffs[slot + 1] = f32_to_f16(v.y);
        coeffs[slot + 2] = f32_to_f16(v.z);
    } else if (how == STORE_FLOAT) {
        coeffs[slot] = f32_to_f16(v.x);
    } else if (how == STORE_ROUGHNESS) {
        coeffs[slot] = f32_to_f16(sqrtf(v.x));
    } else if (how == STORE_HAIR_REFLECTANCE) {
        // `slot` is the fibre's sigma_a; beta_n lies where its layout puts it.
        const float b = f16_to_f32(coeffs[slot + (COEFF_HAIR_BETA_N - COEFF_HAIR_SIGMA_A)]);
        const float sigma[3] = {hair_sigma_a_from_reflectance(fminf(v.x, 1.0f), b),
                                hair_sigma_a_from_reflectance(fminf(v.y, 1.0f), b),
                                hair_sigma_a_from_reflectance(fminf(v.z, 1.0f), b)};
        for (int i = 0; i < 3; ++i) coeffs[slot + i] = f32_to_f16(sigma[i]);
    } else if (how == STORE_EUMELANIN || how == STORE_PHEOMELANIN) {
        const bool eu = how == STORE_EUMELANIN;
        const float pigment[3] = {eu ? EUMELANIN_SIGMA_A_R : PHEOMELANIN_SIGMA_A_R,
                                  eu ? EUMELANIN_SIGMA_A_G : PHEOMELANIN_SIGMA_A_G,
                                  eu ? EUMELANIN_SIGMA_A_B : PHEOMELANIN_SIGMA_A_B};
        for (int i = 0; i < 3; ++i) coeffs[slot + i] = f32_to_f16(__fadd_rn(f16_to_f32(coeffs[slot + i]), __fmul_rn(pigment[i], v.x)));
    } else if (how == STORE_CONDUCTOR_REFLECTANCE) {
        const unsigned short one = f32_to_f16(1.0f);
        coeffs[slot] = coeffs[slot + 1] = coeffs[slot + 2] = one;
        // `slot` is the conductor's eta; k lies where its layout puts it.
        const unsigned int k_slot = slot + (COEFF_CONDUCTOR_K - COEFF_CONDUCTOR_ETA);
        coeffs[k_slot] = f32_to_f16(conductor_k(v.x));
        coeffs[k_slot + 1] = f32_to_f16(conductor_k(v.y));
        coeffs[k_slot + 2] = f32_to_f16(conductor_k(v.z));
    }
}

/// `texture::filtered_checks`.
__device__ __forceinline__ float filtered_checks(float x, float r) {
    if (floorf(x - r) == floorf(x + r)) return 1.0f - 2.0f * (float)(((int)floorf(x)) & 1);
    const auto d = [](float x) {
        const float y = x / 2.0f - floorf(x / 2.0f) - 0.5f;
        return x / 2.0f + y * (1.0f - 2.0f * fabsf(y));
    };
    return (d(x + r) - 2.0f * d(x) + d(x - r)) / (r * r);
}

/// `texture::project`: (s, t, 0) of the hit point `position` under the
/// PROJECT op at `ops[k]` (its matrix rows in it and the two DATA ops
/// after), or the point itself for PROJECT_POINT; the derivatives of
/// (s, t) over the footprint `fp` (null: none) in `*dx`, `*dy`, and of the
/// point in the texture's space in `dq[0]`, `dq[1]`.
__device__ float3 project(const TexOp* ops, unsigned int k, float3 position, const TexFootprint* fp, float2* dx,
                          float2* dy, float3* dq) {
    float q[3];
    float3 dqdx = zero3(), dqdy = zero3();
#pragma unroll
    for (int r = 0; r < 3; ++r) {
        const TexOp& row = ops[k + r];
        q[r] = row.f[0] * position.x + row.f[1] * position.y + row.f[2] * position.z + row.f[3];
    }
    if (fp) {
        const TexOp &r0 = ops[k], &r1 = ops[k + 1], &r2 = ops[k + 2];
        const auto linear = [&](float3 d) {
            return make_float3(r0.f[0] * d.x + r0.f[1] * d.y + r0.f[2] * d.z,
                               r1.f[0] * d.x + r1.f[1] * d.y + r1.f[2] * d.z,
                               r2.f[0] * d.x + r2.f[1] * d.y + r2.f[2] * d.z);
        };
        dqdx = linear(fp->dpdx);
        dqdy = linear(fp->dpdy);
    }
    dq[0] = dqdx;
    dq[1] = dqdy;
    const auto along = [&](float3 dsdq, float3 dtdq) {
        *dx = make_float2(dot3(dsdq, dqdx), dot3(dtdq, dqdx));
        *dy = make_float2(dot3(dsdq, dqdy), dot3(dtdq, dqdy));
        if (!isfinite(dx->x) || !isfinite(dx->y)) *dx = make_float2(0.0f, 0.0f);
        if (!isfinite(dy->x) || !isfinite(dy->y)) *dy = make_float2(0.0f, 0.0f);
    };
    const float pi = 3.14159265358979323846f, tau = 6.28318530717958647692f;
    const float x2y2 = q[0] * q[0] + q[1] * q[1];
    if (ops[k].a == PROJECT_SPHERICAL) {
        const float3 d = normalize_or_zero3(make_float3(q[0], q[1], q[2]));
        const float theta = acosf(clampf(d.z, -1.0f, 1.0f));
        float phi = atan2f(d.y, d.x);
        if (phi < 0.0f) phi += tau;
        const float r = sqrtf(x2y2);
        along(make_float3(-q[1], q[0], 0.0f) * (1.0f / (2.0f * pi * x2y2)),
              make_float3(q[0] * q[2] / r, q[1] * q[2] / r, -r) * (1.0f / (pi * (x2y2 + q[2] * q[2]))));
        return make_float3(theta * (1.0f / pi), phi / tau, 0.0f);
    }
    if (ops[k].a == PROJECT_CYLINDRICAL) {
        along(make_float3(-q[1], q[0], 0.0f) * (1.0f / (2.0f * pi * x2y2)), make_float3(0.0f, 0.0f, 1.0f));
        return make_float3((pi + atan2f(q[1], q[0])) / tau, q[2], 0.0f);
    }
    if (ops[k].a == PROJECT_POINT) {
        *dx = *dy = make_float2(0.0f, 0.0f);
        return make_float3(q[0], q[1], q[2]);
    }
    along(make_float3(1.0f, 0.0f, 0.0f), make_float3(0.0f, 1.0f, 0.0f));
    return make_float3(q[0], q[1], 0.0f);
}

/// `texture::run_program` at the hit `TexPoint { uv, position, normal,
/// footprint }` (`fp` null: no footprint): stores go into `coeffs` (may be
/// null for alpha programs); returns the top of the stack.
__device__ __noinline__ float3 run_program(const FrameParams& p, ProgramRange range, float2 uv, float3 position,
                                           float3 normal, unsigned short* coeffs, const TexFootprint* fp = nullptr) {
    float3 stack[TEXTURE_STACK];
    int sp = 0;
    // The (s, t) derivatives of the last projection (its consumer follows it).
    float2 projected_dx = make_float2(0.0f, 0.0f), projected_dy = make_float2(0.0f, 0.0f);
    float3 point_d[2] = {zero3(), zero3()};
    const TexOp* ops = reinterpret_cast<const TexOp*>(p.texture_ops) + range.start;
    for (unsigned int k = 0; k < range.len; ++k) {
        const TexOp o = ops[k];
        // A projected op pops its (s, t); others map the hit's uv.
        float2 coords = uv;
        float2 dx = fp ? fp->duvdx : make_float2(0.0f, 0.0f), dy = fp ? fp->duvdy : make_float2(0.0f, 0.0f);
        if ((o.code == TEX_IMAGE || o.code == TEX_CHECKERBOARD || o.code == TEX_DOTS || o.code == TEX_BILERP) &&
            (o.b & TEX_PROJECTED)) {
            --sp;
            coords = make_float2(stack[sp].x, stack[sp].y);
            dx = projected_dx;
            dy = projected_dy;
        }
        if (o.code == TEX_CONSTANT) {
            stack[sp++] = make_float3(o.f[0], o.f[1], o.f[2]);
        } else if (o.code == TEX_FACING) {
            const float a = fabsf(dot3(normal, make_float3(o.f[0], o.f[1], o.f[2])));
            stack[sp++] = make_float3(a, a, a);
        } else if (o.code == TEX_PROJECT) {
            stack[sp++] = project(ops, k, position, fp, &projected_dx, &projected_dy, point_d);
        } else if (o.code == TEX_NOISE) {
            const float len2 = fmaxf(length_squared3(point_d[0]), length_squared3(point_d[1]));
            stack[sp - 1] = noise_texture(o.a, stack[sp - 1], len2, o.b, o.f[0], o.f[1], o.f[2]);
        } else if (o.code == TEX_SOLID_CHECKERBOARD) {
            sp -= 2;
            const float3 q = stack[sp + 1];
            const float3 dx = point_d[0], dy = point_d[1];
            const float w = 0.5f - 0.5f * filtered_checks(q.x, 1.5f * fmaxf(fabsf(dx.x), fabsf(dy.x))) *
                                       filtered_checks(q.y, 1.5f * fmaxf(fabsf(dx.y), fabsf(dy.y))) *
                                       filtered_checks(q.z, 1.5f * fmaxf(fabsf(dx.z), fabsf(dy.z)));
            if (w != 0.0f) stack[sp - 1] = stack[sp - 1] * (1.0f - w) + stack[sp] * w;
        } else if (o.code == TEX_BILERP) {
            const float2 st = apply_mapping(o, coords);
            sp -= 3;
            const float s = st.x, t = st.y;
            stack[sp - 1] = ((1.0f - s) * (1.0f - t)) * stack[sp - 1] + (s * (1.0f - t)) * stack[sp] +
                            ((1.0f - s) * t) * stack[sp + 1] + (s * t) * stack[sp + 2];
        } else if (o.code == TEX_DOTS) {
            const bool inside = inside_polka_dot(apply_mapping(o, coords));
            --sp;
            if (!inside) stack[sp - 1] = stack[sp];
        } else if (o.code == TEX_IMAGE) {
            stack[sp++] = image_lookup(p, o, coords, dx, dy);
        } else if (o.code == TEX_CHECKERBOARD) {
            const float2 st = apply_mapping(o, coords);
            --sp;
            const float rs = 1.5f * fmaxf(fabsf(o.f[0] * dx.x), fabsf(o.f[0] * dy.x));
            const float rt = 1.5f * fmaxf(fabsf(o.f[1] * dx.y), fabsf(o.f[1] * dy.y));
            const float w = 0.5f - filtered_checks(st.x, rs) * filtered_checks(st.y, rt) / 2.0f;
            if (w != 0.0f) stack[sp - 1] = stack[sp - 1] * (1.0f - w) + stack[sp] * w;
        } else if (o.code == TEX_SCALE) {
            --sp;
            stack[sp - 1] = stack[sp - 1] * stack[sp];
        } else if (o.code == TEX_MIX) {
            sp -= 2;
            const float amount = stack[sp + 1].x;
            stack[sp - 1] = stack[sp - 1] * (1.0f - amount) + stack[sp] * amount;
        } else if (o.code == TEX_STORE) {
            --sp;
            if (coeffs) store_value(stack[sp], o.a, o.b, coeffs);
        }
    }
    return sp > 0 ? stack[sp - 1] : make_float3(0.0f, 0.0f, 0.0f);
}

/// `record::pack_rgb9e5`, bit for bit.
__device__ __forceinline__ unsigned int pack_rgb9e5(float3 v) {
    const float max_value = 511.0f / 512.0f * 65536.0f;
    const float r = v.x > 0.0f ? fminf(v.x, max_value) : 0.0f;
    const float g = v.y > 0.0f ? fminf(v.y, max_value) : 0.0f;
    const float b = v.z > 0.0f ? fminf(v.z, max_value) : 0.0f;
    const float max_c = fmaxf(fmaxf(r, g), b);
    if (max_c < 1.17549435e-38f) return 0u;
    const int floor_log2 = (int)((__float_as_uint(max_c) >> 23) & 0xffu) - 127;
    int exp_shared = max(floor_log2, -16) + 1 + 15;
    float inv_denom = __uint_as_float((unsigned int)(127 - (exp_shared - 24)) << 23);
    if (floorf(max_c * inv_denom + 0.5f) >= 512.0f) {
        ++exp_shared;
        inv_denom = __uint_as_float((unsigned int)(127 - (exp_shared - 24)) << 23);
    }
    const unsigned int mr = min((unsigned int)floorf(r * inv_denom + 0.5f), 511u);
    const unsigned int mg = min((unsigned int)floorf(g * inv_denom + 0.5f), 511u);
    const unsigned int mb = min((unsigned int)floorf(b * inv_denom + 0.5f), 511u);
    return mr | mg << 9 | mb << 18 | (unsigned int)exp_shared << 27;
}

/// `record::unpack_rgb9e5`.
__device__ __forceinline__ float3 unpack_rgb9e5(unsigned int bits) {
    const int e = (int)(bits >> 27) - 24;
    const float scale = __uint_as_float((unsigned int)(127 + e) << 23);
    return make_float3((float)(bits & 511u) * scale, (float)((bits >> 9) & 511u) * scale,
                       (float)((bits >> 18) & 511u) * scale);
}

/// `LightSet::texture_value`: emission texture `t` at barycentrics `b`.
__device__ __forceinline__ float3 emission_texture_value(const FrameParams& p, unsigned int table, float3 b) {
    const GpuEmissionTexture t = reinterpret_cast<const GpuEmissionTexture*>(p.emission_textures)[table];
    // glam: uv0 * b0 + uv1 * b1 + uv2 * b2, left to right.
    const float2 uv = make_float2(t.uv[0] * b.x + t.uv[2] * b.y + t.uv[4] * b.z,
                                  t.uv[1] * b.x + t.uv[3] * b.y + t.uv[5] * b.z);
    ProgramRange range;
    range.start = t.start;
    range.len = t.len;
    // An area light's image is looked up by uv: no 3D mapping needs the point.
    return run_program(p, range, uv, zero3(), zero3(), nullptr);
}

/// `texture::alpha_hash`.
__device__ __forceinline__ float alpha_hash(float3 o, float3 d, float t) {
    const float words[7] = {o.x, o.y, o.z, d.x, d.y, d.z, t};
    unsigned int h = 0x9e3779b9u;
#pragma unroll
    for (int k = 0; k < 7; ++k) h = pcg_hash(h ^ __float_as_uint(words[k]));
    return (float)(h >> 8) * (1.0f / 16777216.0f);
}

/// `SceneTextures::keeps`: whether the candidate hit of global triangle
/// `tri` at (u, v, t) of the object-space ray (o, d) survives its mesh's
/// alpha mask. Called by traversal only when `p.mesh_alpha` is set.
__device__ __noinline__ bool alpha_keeps(const FrameParams& p, const SceneView& s, unsigned int tri, float u, float v,
                                         float t, float3 o, float3 d) {
    const GpuMesh& mesh = s.meshes[s.triangle_mesh[tri]];
    const AlphaProgram ap = reinterpret_cast<const AlphaProgram*>(p.mesh_alpha)[mesh.scene_mesh];
    if (ap.mode == ALPHA_NONE) return true;
    const unsigned int i0 = s.triangles[3ull * tri], i1 = s.triangles[3ull * tri + 1],
                       i2 = s.triangles[3ull * tri + 2];
    const float2 uv = hit_uv(s, mesh, i0, i1, i2, u, v);
    // The point where traversal sees the hit, no normal (`SceneTextures::keeps`).
    const float alpha = run_program(p, ap.program, uv, o + d * t, zero3(), nullptr).x;
    if ((ap.mode & ALPHA_TEXTURE_MASK) == ALPHA_CUTOFF) return alpha >= ap.cutoff;
    return alpha >= 1.0f || (alpha > 0.0f && alpha_hash(o, d, t) < alpha);
}
