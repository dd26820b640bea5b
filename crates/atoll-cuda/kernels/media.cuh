// Homogeneous participating media: the mirror of `atoll_render::medium`
// (where a segment scatters, its weight, the emission along it) and of
// `atoll_render::shadow_media` (the optical depth a shadow ray gathers where
// it crosses a surface that only bounds media).
#pragma once

#include "common.cuh"
#include "layout.cuh"
#include "params.cuh"
#include "sampling.cuh"

/// Mirrors `MediumCoeffs::sigma_t`.
__device__ __forceinline__ float3 medium_sigma_t(const GpuMedium& m) {
    return make_float3(m.sigma_a[0] + m.sigma_s[0], m.sigma_a[1] + m.sigma_s[1], m.sigma_a[2] + m.sigma_s[2]);
}

/// Mirrors `medium::transmittance`: 1 where σt is 0, even over an infinite length.
__device__ __forceinline__ float3 medium_transmittance(float3 sigma_t, float length) {
    return make_float3(sigma_t.x == 0.0f ? 1.0f : expf(-sigma_t.x * length),
                       sigma_t.y == 0.0f ? 1.0f : expf(-sigma_t.y * length),
                       sigma_t.z == 0.0f ? 1.0f : expf(-sigma_t.z * length));
}

/// Mirrors `medium::Segment`: scatter at `t` (else pass), with `weight`.
struct MediumSegment {
    bool scatter;
    float t;
    float3 weight;
};

/// Mirrors `MediumCoeffs::sample_segment`: a channel from the leading third
/// of `u`, a distance from the rest, weighted by the three channels' mixture.
__device__ __noinline__ MediumSegment medium_sample_segment(const GpuMedium& m, float length, float u) {
    const float3 sigma_t = medium_sigma_t(m);
    const float scaled = u * 3.0f;
    const unsigned int channel = min((unsigned int)scaled, 2u);
    const float v = clampf(scaled - (float)channel, 0.0f, 1.0f - 1.1920929e-7f);
    const float st = channel == 0 ? sigma_t.x : channel == 1 ? sigma_t.y : sigma_t.z;
    const float t = st > 0.0f ? sample_exponential(v, st) : f32_infinity();
    MediumSegment s;
    s.t = t;
    const float third = 1.0f / 3.0f;
    if (t < length) {
        const float3 tr = make_float3(expf(-sigma_t.x * t), expf(-sigma_t.y * t), expf(-sigma_t.z * t));
        const float density = dot3(sigma_t * tr, make_float3(third, third, third));
        s.scatter = true;
        s.weight = density > 0.0f ? tr * make_float3(m.sigma_s[0], m.sigma_s[1], m.sigma_s[2]) / density : zero3();
        return s;
    }
    const float3 tr = medium_transmittance(sigma_t, length);
    const float passing = dot3(tr, make_float3(third, third, third));
    s.scatter = false;
    s.weight = passing > 0.0f ? tr / passing : zero3();
    return s;
}

/// Mirrors `MediumCoeffs::emission_over`: ∫ T(t) σa Le dt over `length`.
__device__ __forceinline__ float medium_emission_channel(float a, float le, float st, float length) {
    if (a == 0.0f || le == 0.0f) return 0.0f;
    if (st * length < 1e-4f) return a * le * length;
    return a * le * (1.0f - expf(-st * length)) / st;
}

__device__ __forceinline__ float3 medium_emission_over(const GpuMedium& m, float length) {
    const float3 sigma_t = medium_sigma_t(m);
    return make_float3(medium_emission_channel(m.sigma_a[0], m.le[0], sigma_t.x, length),
                       medium_emission_channel(m.sigma_a[1], m.le[1], sigma_t.y, length),
                       medium_emission_channel(m.sigma_a[2], m.le[2], sigma_t.z, length));
}

/// Mirrors `MediumInterface::towards`: the medium of a mesh flags word
/// (inside << 4 | outside, at MESH_MEDIA_SHIFT) a direction leaves into.
__device__ __forceinline__ unsigned int media_towards(unsigned int media, float cos_to_normal) {
    return cos_to_normal > 0.0f ? (media & 15u) : (media >> 4) & 15u;
}

/// `ShadowFilter::keeps` for media: whether the candidate hit of global
/// triangle `tri` at (u, v) by the object-space direction `d` occludes.
/// Where the triangle's mesh only bounds media it does not, and the change
/// of σt across it (after − before) goes to `*change`, for the caller to
/// weigh by the rest of the ray, `t_max − t`.
__device__ __noinline__ bool medium_crossing(const FrameParams& p, const SceneView& s, unsigned int tri, float u,
                                             float v, float3 d, float3* change) {
    const GpuMesh& mesh = s.meshes[s.triangle_mesh[tri]];
    if (!(mesh.flags & MESH_MEDIA_ONLY)) return true;
    const unsigned int i0 = s.triangles[3ull * tri], i1 = s.triangles[3ull * tri + 1],
                       i2 = s.triangles[3ull * tri + 2];
    const float3 p0 = load3(s.vertices + 3ull * i0), p1 = load3(s.vertices + 3ull * i1),
                 p2 = load3(s.vertices + 3ull * i2);
    // The normal write_surface orients (towards the interpolated one): its
    // side of the ray is the same in world space.
    float3 n = cross3(p0 - p2, p1 - p2);
    if (mesh.flags & MESH_FLIP_NORMALS) n = -n;
    if (mesh.flags & MESH_HAS_NORMALS) {
        const float3 ns = load3(s.normals + 3ull * i0) * (1.0f - u - v) + load3(s.normals + 3ull * i1) * u +
                          load3(s.normals + 3ull * i2) * v;
        if (dot3(ns, n) < 0.0f) n = -n;
    }
    const float cosine = dot3(d, n);
    const unsigned int media = (mesh.flags >> MESH_MEDIA_SHIFT) & 0xffu;
    const GpuMedium& before = p.media[media_towards(media, -cosine)];
    const GpuMedium& after = p.media[media_towards(media, cosine)];
    *change = medium_sigma_t(after) - medium_sigma_t(before);
    return false;
}
