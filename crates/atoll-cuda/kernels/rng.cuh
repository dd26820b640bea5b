// Deterministic random numbers from (seed, pixel, sample, dimension): the
// mirror of `atoll_render::rng`. Pure integer arithmetic, so CPU and GPU
// produce the same bits.
#pragma once

// BEGIN GENERATED rng (src/header.rs; regenerate: ATOLL_BLESS=1 cargo test -p atoll-cuda header)
inline constexpr unsigned int CAMERA_DIMENSIONS = 4u;
inline constexpr unsigned int DIMENSIONS_PER_BOUNCE = 8u;
inline constexpr unsigned int MEDIUM_DIMENSIONS = 16777216u;
inline constexpr unsigned int TIME_DIMENSION = 16777215u;
inline constexpr unsigned int WALK_DIMENSIONS = 33554432u;
inline constexpr unsigned int BOUNCE_DIM_LIGHT_SELECT = 0u;
inline constexpr unsigned int BOUNCE_DIM_LIGHT_POSITION = 1u;
inline constexpr unsigned int BOUNCE_DIM_BSDF_LOBE = 3u;
inline constexpr unsigned int BOUNCE_DIM_BSDF_DIRECTION = 4u;
inline constexpr unsigned int BOUNCE_DIM_RUSSIAN_ROULETTE = 6u;
inline constexpr unsigned int BOUNCE_DIM_MATERIAL_CHOICE = 7u;
// END GENERATED rng

/// One round of the PCG hash. Mirrors `rng::pcg_hash`.
__device__ __forceinline__ unsigned int pcg_hash(unsigned int x) {
    const unsigned int state = x * 747796405u + 2891336453u;
    const unsigned int word = ((state >> ((state >> 28) + 4u)) ^ state) * 277803737u;
    return (word >> 22) ^ word;
}

/// Where a path's random numbers come from. Mirrors `rng::SampleStream`.
struct SampleStream {
    unsigned int key;
};

/// Mirrors `SampleStream::new`.
__device__ __forceinline__ SampleStream sample_stream(unsigned int seed, unsigned int pixel, unsigned int sample) {
    SampleStream s;
    s.key = pcg_hash(sample ^ pcg_hash(pixel ^ pcg_hash(seed)));
    return s;
}

/// Uniform float in [0, 1) for `dimension`. Mirrors `SampleStream::get`.
__device__ __forceinline__ float stream_get(SampleStream s, unsigned int dimension) {
    const unsigned int h = pcg_hash(s.key ^ pcg_hash(dimension + 0x9e3779b9u));
    // 24 random bits: exactly representable, never rounds up to 1.0.
    return (float)(h >> 8) * (1.0f / 16777216.0f);
}

/// Uniform float for decision `dim` (a `BOUNCE_DIM_*` constant) of bounce
/// `depth`. Mirrors `SampleStream::bounce`.
__device__ __forceinline__ float stream_bounce(SampleStream s, unsigned int depth, unsigned int dim,
                                               unsigned int offset) {
    return stream_get(s, CAMERA_DIMENSIONS + depth * DIMENSIONS_PER_BOUNCE + dim + offset);
}

/// `start` hashed with a segment's origin and throughput. Mirrors
/// `rng::segment_key`.
__device__ __forceinline__ unsigned int segment_key(unsigned int h, float3 origin, float3 beta) {
    h = pcg_hash(h ^ __float_as_uint(origin.x));
    h = pcg_hash(h ^ __float_as_uint(origin.y));
    h = pcg_hash(h ^ __float_as_uint(origin.z));
    h = pcg_hash(h ^ __float_as_uint(beta.x));
    h = pcg_hash(h ^ __float_as_uint(beta.y));
    h = pcg_hash(h ^ __float_as_uint(beta.z));
    return h;
}

/// Uniform float for where a segment leaving vertex `depth` from `origin`
/// with throughput `beta` scatters in a medium (the segment tells apart
/// those of one vertex). Mirrors `SampleStream::medium_distance`.
__device__ __forceinline__ float stream_medium_distance(SampleStream s, unsigned int depth, float3 origin,
                                                        float3 beta) {
    return stream_get(s, segment_key(MEDIUM_DIMENSIONS + depth, origin, beta));
}

/// Uniform float for decision `dim` where a walk's segment from `origin`
/// with throughput `beta` through a subsurface medium ends, within path
/// vertex `depth`. Mirrors `SampleStream::walk`.
__device__ __forceinline__ float stream_walk(SampleStream s, unsigned int depth, float3 origin, float3 beta,
                                             unsigned int dim, unsigned int offset) {
    return stream_get(s, segment_key(WALK_DIMENSIONS + depth * DIMENSIONS_PER_BOUNCE + dim + offset, origin, beta));
}
