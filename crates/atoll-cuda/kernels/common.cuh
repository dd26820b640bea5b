// Small vector math and float helpers shared by every kernel.
//
// The functions mirror glam's and Rust's f32 semantics operation by
// operation (same operand order, same rounding), so a kernel that ports a
// Rust function line by line computes the same floats up to the differences
// the hardware allows (transcendentals; FMA contraction unless compiled with
// `--fmad=false`). In particular:
// - `dot3` is `(x*x') + (y*y') + (z*z')` evaluated left to right (glam `Vec3::dot`);
// - `normalize3` multiplies by `1 / length` (glam `normalize`), it does not divide;
// - `clampf`, `signumf`, `max_element` follow Rust's NaN behaviour, not C's.
#pragma once

// BEGIN GENERATED constants (src/header.rs; regenerate: ATOLL_BLESS=1 cargo test -p atoll-cuda header)
inline constexpr float PI = 3.1415927f;
inline constexpr float FRAC_1_PI = 0.31830987f;
inline constexpr float FRAC_PI_2 = 1.5707964f;
inline constexpr float FRAC_PI_4 = 0.7853982f;
inline constexpr float UNIFORM_SPHERE_PDF = 0.07957747f;
inline constexpr float SMOOTH_ALPHA = 0.001f;
inline constexpr float SHADOW_EPSILON = 0.0001f;
inline constexpr float GAMMA_3 = 1.7881396e-7f;
inline constexpr float GAMMA_6 = 3.57628e-7f;
inline constexpr float GAMMA_7 = 4.1723268e-7f;
inline constexpr float ONE_MINUS_EPSILON = 0.99999994f;
// END GENERATED constants

/// +infinity (no math header: built from its bits).
__device__ __forceinline__ float f32_infinity() { return __int_as_float(0x7f800000); }

/// Rust `f32::is_finite`: false for infinities and NaN.
__device__ __forceinline__ bool is_finitef(float x) { return fabsf(x) < f32_infinity(); }

/// Rust `f32::is_infinite`.
__device__ __forceinline__ bool is_infinitef(float x) { return fabsf(x) == f32_infinity(); }

/// Rust `f32::clamp`: NaN passes through (fminf/fmaxf would replace it).
__device__ __forceinline__ float clampf(float x, float lo, float hi) {
    if (x < lo) x = lo;
    if (x > hi) x = hi;
    return x;
}

/// Rust `f32::signum`: ±1 by the sign bit (so `signum(-0.0) == -1`), NaN for NaN.
__device__ __forceinline__ float signumf(float x) { return x != x ? x : copysignf(1.0f, x); }

// --- float2 (glam Vec2) ---

__device__ __forceinline__ float2 operator+(float2 a, float2 b) { return make_float2(a.x + b.x, a.y + b.y); }
__device__ __forceinline__ float2 operator-(float2 a, float2 b) { return make_float2(a.x - b.x, a.y - b.y); }
__device__ __forceinline__ float2 operator*(float s, float2 a) { return make_float2(s * a.x, s * a.y); }
__device__ __forceinline__ float2 operator/(float2 a, float2 b) { return make_float2(a.x / b.x, a.y / b.y); }
/// glam `Vec2::length_squared`: `x*x + y*y`.
__device__ __forceinline__ float length_squared2(float2 a) { return (a.x * a.x) + (a.y * a.y); }

// --- float3 (glam Vec3) ---

__device__ __forceinline__ float3 operator+(float3 a, float3 b) { return make_float3(a.x + b.x, a.y + b.y, a.z + b.z); }
__device__ __forceinline__ float3 operator-(float3 a, float3 b) { return make_float3(a.x - b.x, a.y - b.y, a.z - b.z); }
__device__ __forceinline__ float3 operator-(float3 a) { return make_float3(-a.x, -a.y, -a.z); }
__device__ __forceinline__ float3 operator*(float3 a, float3 b) { return make_float3(a.x * b.x, a.y * b.y, a.z * b.z); }
__device__ __forceinline__ float3 operator*(float3 a, float s) { return make_float3(a.x * s, a.y * s, a.z * s); }
__device__ __forceinline__ float3 operator*(float s, float3 a) { return make_float3(s * a.x, s * a.y, s * a.z); }
/// Component-wise division (glam divides, it does not multiply by a reciprocal).
__device__ __forceinline__ float3 operator/(float3 a, float s) { return make_float3(a.x / s, a.y / s, a.z / s); }
__device__ __forceinline__ bool operator==(float3 a, float3 b) { return a.x == b.x && a.y == b.y && a.z == b.z; }
__device__ __forceinline__ bool operator!=(float3 a, float3 b) { return !(a == b); }

__device__ __forceinline__ float3 zero3() { return make_float3(0.0f, 0.0f, 0.0f); }
__device__ __forceinline__ bool is_zero3(float3 a) { return a == zero3(); }

/// glam `Vec3::dot`.
__device__ __forceinline__ float dot3(float3 a, float3 b) { return (a.x * b.x) + (a.y * b.y) + (a.z * b.z); }

/// glam `Vec3::cross`.
__device__ __forceinline__ float3 cross3(float3 a, float3 b) {
    return make_float3(a.y * b.z - b.y * a.z, a.z * b.x - b.z * a.x, a.x * b.y - b.x * a.y);
}

/// glam `Vec3::length_squared`.
__device__ __forceinline__ float length_squared3(float3 a) { return dot3(a, a); }

/// glam `Vec3::length`.
__device__ __forceinline__ float length3(float3 a) { return sqrtf(dot3(a, a)); }

/// glam `Vec3::normalize`: `a * (1 / length)`.
__device__ __forceinline__ float3 normalize3(float3 a) { return a * (1.0f / length3(a)); }

/// glam `Vec3::normalize_or_zero`: zero when `1 / length` is not finite and positive.
__device__ __forceinline__ float3 normalize_or_zero3(float3 a) {
    const float rcp = 1.0f / length3(a);
    if (is_finitef(rcp) && rcp > 0.0f) return a * rcp;
    return zero3();
}

/// glam `Vec3::abs`.
__device__ __forceinline__ float3 abs3(float3 a) { return make_float3(fabsf(a.x), fabsf(a.y), fabsf(a.z)); }

/// glam `Vec3::max_element`: `max(x, max(y, z))` with `if a > b { a } else { b }`.
__device__ __forceinline__ float max_element3(float3 a) {
    const float yz = a.y > a.z ? a.y : a.z;
    return a.x > yz ? a.x : yz;
}

/// glam `Vec3::is_finite`.
__device__ __forceinline__ bool is_finite3(float3 a) { return is_finitef(a.x) && is_finitef(a.y) && is_finitef(a.z); }

__device__ __forceinline__ float3 load3(const float* p) { return make_float3(p[0], p[1], p[2]); }
__device__ __forceinline__ void store3(float* p, float3 a) {
    p[0] = a.x;
    p[1] = a.y;
    p[2] = a.z;
}

// --- row-major matrices (glam Mat4 / Affine3A / Mat3A products, same order) ---

/// Row `r` of a row-major 3x4 affine matrix applied to a point, in glam's
/// `Mat4::transform_point3` order: `((m0 x + m1 y) + m2 z) + m3`.
__device__ __forceinline__ float affine_row_point(const float* m, int r, float3 v) {
    return m[r * 4 + 0] * v.x + m[r * 4 + 1] * v.y + m[r * 4 + 2] * v.z + m[r * 4 + 3];
}

/// As `affine_row_point` without the translation (`Mat4::transform_vector3`).
__device__ __forceinline__ float affine_row_vector(const float* m, int r, float3 v) {
    return m[r * 4 + 0] * v.x + m[r * 4 + 1] * v.y + m[r * 4 + 2] * v.z;
}

/// glam `Mat4::transform_point3` / `Affine3A::transform_point3` for a row-major 3x4.
__device__ __forceinline__ float3 affine_point(const float* m, float3 v) {
    return make_float3(affine_row_point(m, 0, v), affine_row_point(m, 1, v), affine_row_point(m, 2, v));
}

/// glam `Mat4::transform_vector3` for a row-major 3x4.
__device__ __forceinline__ float3 affine_vector(const float* m, float3 v) {
    return make_float3(affine_row_vector(m, 0, v), affine_row_vector(m, 1, v), affine_row_vector(m, 2, v));
}

/// glam `Mat3A * Vec3` for a row-major 3x3: `(m0 x + m1 y) + m2 z` per row.
__device__ __forceinline__ float3 mat3_mul(const float* m, float3 v) {
    return make_float3(m[0] * v.x + m[1] * v.y + m[2] * v.z, m[3] * v.x + m[4] * v.y + m[5] * v.z,
                       m[6] * v.x + m[7] * v.y + m[8] * v.z);
}

// --- f16 (IEEE binary16 in an unsigned short; no cuda_fp16.h under NVRTC) ---

/// f16 bits to f32 (exact). Mirrors `half::f16::to_f32`.
__device__ __forceinline__ float f16_to_f32(unsigned short h) {
    float f;
    asm("cvt.f32.f16 %0, %1;" : "=f"(f) : "h"(h));
    return f;
}

/// f32 to f16 bits, rounding to nearest even. Mirrors `half::f16::from_f32`.
__device__ __forceinline__ unsigned short f32_to_f16(float f) {
    unsigned short h;
    asm("cvt.rn.f16.f32 %0, %1;" : "=h"(h) : "f"(f));
    return h;
}

/// Mirrors `record::from_f16x3`.
__device__ __forceinline__ float3 load_f16x3(const unsigned short* h) {
    return make_float3(f16_to_f32(h[0]), f16_to_f32(h[1]), f16_to_f32(h[2]));
}

/// Mirrors `record::to_f16x3`.
__device__ __forceinline__ void store_f16x3(unsigned short* h, float3 v) {
    h[0] = f32_to_f16(v.x);
    h[1] = f32_to_f16(v.y);
    h[2] = f32_to_f16(v.z);
}
