// The ray record (mirror of `atoll_render::record`): one path segment or
// shadow ray plus, after tracing, its full hit. 128 bytes; the generated
// block below asserts every offset and size against the Rust struct, and
// defines the flag and material-kind constants from the Rust ones.
#pragma once

/// Mirror of `atoll_render::record::RayRecord` (field docs there). f16
/// fields are `unsigned short` bit patterns: read them with `load_f16x3` /
/// `f16_to_f32` (common.cuh). 16-byte aligned so a record moves as 8 vector
/// loads; the Rust side only needs 4, and device allocations are 256-aligned.
struct __align__(16) RayRecord {
    float origin[3];
    float t_max;
    float direction[3];
    unsigned int pixel;
    float throughput[3];
    unsigned int sample;
    float bsdf_pdf;
    unsigned short depth;
    unsigned char flags;
    unsigned char eta_scale;  // `pack_eta_scale` code: path state (0 is 1)
    unsigned int light;
    unsigned int instance;
    float position[3];
    unsigned int emission_scale;  // RGB9E5 texture value of a textured emitter hit, else 0
    unsigned short geometric_normal[3];
    unsigned short material;
    unsigned short shading_normal[3];
    unsigned short position_error;  // bfloat16 bits (spawn.cuh `unpack_error`)
    unsigned short coeffs[16];
};

/// Writes the ray half of `*dst` (its first 64 bytes: the ray and the path
/// state, up to and including `instance`) as four 16-byte stores and leaves
/// the hit half alone: a record's hit fields mean something only once
/// closest-hit tracing sets FLAG_HIT, so stages that make new segments or
/// shadow rays need not spend memory bandwidth copying them.
__device__ __forceinline__ void store_ray_half(RayRecord* dst, float3 origin, float t_max, float3 direction,
                                               unsigned int pixel, float3 throughput, unsigned int sample,
                                               float bsdf_pdf, unsigned short depth, unsigned char flags,
                                               unsigned char eta_scale, unsigned int light, unsigned int instance) {
    const unsigned int state = (unsigned int)depth | ((unsigned int)flags << 16) | ((unsigned int)eta_scale << 24);
    float4* out = reinterpret_cast<float4*>(dst);
    out[0] = make_float4(origin.x, origin.y, origin.z, t_max);
    out[1] = make_float4(direction.x, direction.y, direction.z, __uint_as_float(pixel));
    out[2] = make_float4(throughput.x, throughput.y, throughput.z, __uint_as_float(sample));
    out[3] = make_float4(bsdf_pdf, __uint_as_float(state), __uint_as_float(light), __uint_as_float(instance));
}

/// Mirrors `record::pack_eta_scale`: a positive scale as an 8-bit float
/// (5-bit two's-complement exponent, 3 mantissa bits), integer rounding.
__device__ __forceinline__ unsigned char pack_eta_scale(float v) {
    const float lo = 1.0f / 32768.0f, hi = 32768.0f * 1.875f;
    v = v >= lo ? fminf(v, hi) : lo;
    const unsigned int rounded = (__float_as_uint(v) + (1u << 19)) >> 20;
    int exponent = (int)((rounded >> 3) & 0xffu) - 127;
    unsigned int mantissa = rounded & 7u;
    if (exponent > 15) {
        exponent = 15;
        mantissa = 7u;
    }
    return (unsigned char)((((unsigned int)exponent & 31u) << 3) | mantissa);
}

/// Mirrors `record::unpack_eta_scale`.
__device__ __forceinline__ float unpack_eta_scale(unsigned char code) {
    const int exponent = (int)((signed char)code >> 3);
    return __uint_as_float(((unsigned int)(exponent + 127) << 23) | ((unsigned int)(code & 7u) << 20));
}

// BEGIN GENERATED record (src/header.rs; regenerate: ATOLL_BLESS=1 cargo test -p atoll-cuda header)
inline constexpr unsigned int NO_LIGHT = 4294967295u;
inline constexpr unsigned int MATERIAL_COEFFS = 16u;
inline constexpr unsigned int MAX_MIX_DEPTH = 8u;
inline constexpr unsigned char FLAG_SHADOW = 1;
inline constexpr unsigned char FLAG_OCCLUDED = 2;
inline constexpr unsigned char FLAG_HIT = 4;
inline constexpr unsigned char FLAG_SPECULAR = 8;
inline constexpr unsigned char FLAG_MEDIUM_MASK = 240;
inline constexpr unsigned int FLAG_MEDIUM_SHIFT = 4u;
inline constexpr unsigned int MATERIAL_NONE = 0u;
inline constexpr unsigned int MATERIAL_DIFFUSE = 1u;
inline constexpr unsigned int MATERIAL_CONDUCTOR = 2u;
inline constexpr unsigned int MATERIAL_DIELECTRIC = 3u;
inline constexpr unsigned int MATERIAL_DIFFUSE_TRANSMISSION = 4u;
inline constexpr unsigned int MATERIAL_THIN_DIELECTRIC = 5u;
inline constexpr unsigned int MATERIAL_MIX = 6u;
inline constexpr unsigned int MATERIAL_COATED_DIFFUSE = 7u;
inline constexpr unsigned int MATERIAL_PRINCIPLED = 8u;
inline constexpr unsigned int MATERIAL_COATED_CONDUCTOR = 9u;
inline constexpr unsigned int MATERIAL_HAIR = 10u;
inline constexpr unsigned int MATERIAL_MEASURED = 11u;
inline constexpr unsigned int MATERIAL_SUBSURFACE = 12u;
inline constexpr float HAIR_OFFSET_FROM_NORMAL = 2.0f;
static_assert(sizeof(RayRecord) == 128, "RayRecord: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(RayRecord, origin) == 0 && sizeof(RayRecord::origin) == 12, "RayRecord.origin: offset or size differs from Rust");
static_assert(__builtin_offsetof(RayRecord, t_max) == 12 && sizeof(RayRecord::t_max) == 4, "RayRecord.t_max: offset or size differs from Rust");
static_assert(__builtin_offsetof(RayRecord, direction) == 16 && sizeof(RayRecord::direction) == 12, "RayRecord.direction: offset or size differs from Rust");
static_assert(__builtin_offsetof(RayRecord, pixel) == 28 && sizeof(RayRecord::pixel) == 4, "RayRecord.pixel: offset or size differs from Rust");
static_assert(__builtin_offsetof(RayRecord, throughput) == 32 && sizeof(RayRecord::throughput) == 12, "RayRecord.throughput: offset or size differs from Rust");
static_assert(__builtin_offsetof(RayRecord, sample) == 44 && sizeof(RayRecord::sample) == 4, "RayRecord.sample: offset or size differs from Rust");
static_assert(__builtin_offsetof(RayRecord, bsdf_pdf) == 48 && sizeof(RayRecord::bsdf_pdf) == 4, "RayRecord.bsdf_pdf: offset or size differs from Rust");
static_assert(__builtin_offsetof(RayRecord, depth) == 52 && sizeof(RayRecord::depth) == 2, "RayRecord.depth: offset or size differs from Rust");
static_assert(__builtin_offsetof(RayRecord, flags) == 54 && sizeof(RayRecord::flags) == 1, "RayRecord.flags: offset or size differs from Rust");
static_assert(__builtin_offsetof(RayRecord, eta_scale) == 55 && sizeof(RayRecord::eta_scale) == 1, "RayRecord.eta_scale: offset or size differs from Rust");
static_assert(__builtin_offsetof(RayRecord, light) == 56 && sizeof(RayRecord::light) == 4, "RayRecord.light: offset or size differs from Rust");
static_assert(__builtin_offsetof(RayRecord, instance) == 60 && sizeof(RayRecord::instance) == 4, "RayRecord.instance: offset or size differs from Rust");
static_assert(__builtin_offsetof(RayRecord, position) == 64 && sizeof(RayRecord::position) == 12, "RayRecord.position: offset or size differs from Rust");
static_assert(__builtin_offsetof(RayRecord, emission_scale) == 76 && sizeof(RayRecord::emission_scale) == 4, "RayRecord.emission_scale: offset or size differs from Rust");
static_assert(__builtin_offsetof(RayRecord, geometric_normal) == 80 && sizeof(RayRecord::geometric_normal) == 6, "RayRecord.geometric_normal: offset or size differs from Rust");
static_assert(__builtin_offsetof(RayRecord, material) == 86 && sizeof(RayRecord::material) == 2, "RayRecord.material: offset or size differs from Rust");
static_assert(__builtin_offsetof(RayRecord, shading_normal) == 88 && sizeof(RayRecord::shading_normal) == 6, "RayRecord.shading_normal: offset or size differs from Rust");
static_assert(__builtin_offsetof(RayRecord, position_error) == 94 && sizeof(RayRecord::position_error) == 2, "RayRecord.position_error: offset or size differs from Rust");
static_assert(__builtin_offsetof(RayRecord, coeffs) == 96 && sizeof(RayRecord::coeffs) == 32, "RayRecord.coeffs: offset or size differs from Rust");
#endif
// END GENERATED record
