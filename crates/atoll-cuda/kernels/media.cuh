// Participating media: the mirror of `atoll_render::medium` (where a
// segment scatters, its weight, the emission along it), of
// `atoll_render::density_grid` (a grid's density integrated exactly along
// rays, cell by cell) and of `atoll_render::shadow_media` (the optical depth
// a shadow ray gathers where it crosses a surface that only bounds media).
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

// --- density grids (density_grid.rs) ---

/// Mirrors `DensityGrid::sample`: sample (x, y, z) of medium `m`'s grid, 0 outside.
__device__ __forceinline__ float grid_sample(const FrameParams& p, const GpuMedium& m, int x, int y, int z) {
    const int nx = (int)m.grid_resolution[0], ny = (int)m.grid_resolution[1], nz = (int)m.grid_resolution[2];
    if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) return 0.0f;
    return p.media_grids[m.grid_first + (unsigned int)((z * ny + y) * nx + x)];
}

/// Mirrors `DensityGrid::density_in`: the trilinear density at lattice
/// point `s` of cell (cx, cy, cz).
__device__ __forceinline__ float grid_density_in(const FrameParams& p, const GpuMedium& m, int cx, int cy, int cz,
                                                 float3 s) {
    const float dx = s.x - (float)cx, dy = s.y - (float)cy, dz = s.z - (float)cz;
    const auto lerp = [](float a, float b, float t) { return a + (b - a) * t; };
    const float x00 = lerp(grid_sample(p, m, cx, cy, cz), grid_sample(p, m, cx + 1, cy, cz), dx);
    const float x10 = lerp(grid_sample(p, m, cx, cy + 1, cz), grid_sample(p, m, cx + 1, cy + 1, cz), dx);
    const float x01 = lerp(grid_sample(p, m, cx, cy, cz + 1), grid_sample(p, m, cx + 1, cy, cz + 1), dx);
    const float x11 = lerp(grid_sample(p, m, cx, cy + 1, cz + 1), grid_sample(p, m, cx + 1, cy + 1, cz + 1), dx);
    return lerp(lerp(x00, x10, dy), lerp(x01, x11, dy), dz);
}

/// Mirrors `DensityGrid::cell_integral`: two-point Gauss–Legendre, exact
/// for the cubic the density is along a ray inside one cell.
__device__ __forceinline__ float grid_cell_integral(const FrameParams& p, const GpuMedium& m, const int* c, float3 s0,
                                                    float3 ds, float ta, float tb) {
    const float gauss = 0.577350269f;
    const float mid = 0.5f * (ta + tb), half = 0.5f * (tb - ta);
    return half * (grid_density_in(p, m, c[0], c[1], c[2], s0 + ds * (mid - half * gauss)) +
                   grid_density_in(p, m, c[0], c[1], c[2], s0 + ds * (mid + half * gauss)));
}

/// Mirrors `DensityGrid::walk`: calls `cell(c, s0, ds, ta, tb)` for each
/// piece of `o + t d`, t0 <= t < t1, inside the grid, until it returns false.
template <typename F>
__device__ __forceinline__ void grid_walk(const GpuMedium& m, float3 o, float3 d, float t0, float t1, F cell) {
    const float3 s0 = affine_point(m.world_to_lattice, o);
    const float3 ds = affine_vector(m.world_to_lattice, d);
    const float sa[3] = {s0.x, s0.y, s0.z}, da[3] = {ds.x, ds.y, ds.z};
    float ta = t0, tb = t1;
    for (int a = 0; a < 3; ++a) {
        const float n = (float)m.grid_resolution[a];
        if (da[a] == 0.0f) {
            if (sa[a] < -0.5f || sa[a] > n - 0.5f) return;
            continue;
        }
        const float lo = (-0.5f - sa[a]) / da[a], hi = (n - 0.5f - sa[a]) / da[a];
        ta = fmaxf(ta, fminf(lo, hi));
        tb = fminf(tb, fmaxf(lo, hi));
    }
    if (isnan(ta) || isnan(tb) || ta >= tb) return;
    int c[3], step[3];
    float next[3], delta[3];
    for (int a = 0; a < 3; ++a) {
        const float start = sa[a] + da[a] * ta;
        c[a] = min(max((int)floorf(start), -1), (int)m.grid_resolution[a] - 1);
        step[a] = 0;
        next[a] = f32_infinity();
        delta[a] = f32_infinity();
        if (da[a] > 0.0f) {
            step[a] = 1;
            next[a] = ((float)c[a] + 1.0f - sa[a]) / da[a];
            delta[a] = 1.0f / da[a];
        } else if (da[a] < 0.0f) {
            step[a] = -1;
            next[a] = ((float)c[a] - sa[a]) / da[a];
            delta[a] = -1.0f / da[a];
        }
    }
    float t = ta;
    while (t < tb) {
        const int a = (next[0] <= next[1] && next[0] <= next[2]) ? 0 : (next[1] <= next[2] ? 1 : 2);
        const float end = fminf(next[a], tb);
        if (end > t && !cell(c, s0, ds, t, end)) return;
        t = end;
        c[a] += step[a];
        next[a] += delta[a];
        if (c[a] < -1 || c[a] >= (int)m.grid_resolution[a]) return;
    }
}

/// Mirrors `DensityGrid::integral`.
__device__ __noinline__ float grid_integral(const FrameParams& p, const GpuMedium& m, float3 o, float3 d, float t0,
                                            float t1) {
    float sum = 0.0f;
    grid_walk(m, o, d, t0, t1, [&](const int* c, float3 s0, float3 ds, float ta, float tb) {
        sum += grid_cell_integral(p, m, c, s0, ds, ta, tb);
        return true;
    });
    return sum;
}

/// Mirrors `DensityGrid::invert`: the t where the integral from t0 reaches
/// `target` into `*t`; false when the segment holds less.
__device__ __noinline__ bool grid_invert(const FrameParams& p, const GpuMedium& m, float3 o, float3 d, float t0,
                                         float t1, float target, float* t) {
    float sum = 0.0f;
    bool found = false;
    grid_walk(m, o, d, t0, t1, [&](const int* c, float3 s0, float3 ds, float ta, float tb) {
        const float here = grid_cell_integral(p, m, c, s0, ds, ta, tb);
        if (sum + here < target) {
            sum += here;
            return true;
        }
        float lo = ta, hi = tb;
        for (int k = 0; k < 30; ++k) {
            const float mid = 0.5f * (lo + hi);
            if (sum + grid_cell_integral(p, m, c, s0, ds, ta, mid) < target) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        *t = 0.5f * (lo + hi);
        found = true;
        return false;
    });
    return found;
}

// --- media (medium.rs) ---

/// Mirrors `MediumTable::density_length`: ∫ density ds in world units
/// along `o + t d`, t0 <= t < t1, through medium `medium`.
__device__ __forceinline__ float medium_density_length(const FrameParams& p, unsigned int medium, float3 o, float3 d,
                                                       float t0, float t1) {
    const GpuMedium& m = p.media[medium];
    const float scale = length3(d);
    if (m.grid_first == NO_GRID) return (t1 - t0) * scale;
    return grid_integral(p, m, o, d, t0, t1) * scale;
}

/// Mirrors `MediumTable::optical_depth`.
__device__ __forceinline__ float3 medium_optical_depth(const FrameParams& p, unsigned int medium, float3 o, float3 d,
                                                       float t0, float t1) {
    const float3 sigma_t = medium_sigma_t(p.media[medium]);
    if (is_zero3(sigma_t)) return zero3();
    return sigma_t * medium_density_length(p, medium, o, d, t0, t1);
}

/// Mirrors `medium::Segment`: scatter at `t` (else pass), with `weight`.
struct MediumSegment {
    bool scatter;
    float t;
    float3 weight;
};

/// Mirrors `MediumTable::sample_segment` (with `MediumCoeffs::sample_segment`):
/// a channel from the leading third of `u`, the optical depth to reach
/// from the rest, inverted along the segment `o + t d`, 0 <= t < t_max;
/// weighted by the three channels' mixture. A scattering `t` is in world units.
__device__ __noinline__ MediumSegment medium_sample_segment(const FrameParams& p, unsigned int medium, float3 o,
                                                            float3 d, float t_max, float u) {
    const GpuMedium& m = p.media[medium];
    const float3 sigma_t = medium_sigma_t(m);
    const float scale = length3(d);
    const bool grid = m.grid_first != NO_GRID;
    const float total = grid ? grid_integral(p, m, o, d, 0.0f, t_max) * scale : t_max * scale;
    const float scaled = u * 3.0f;
    const unsigned int channel = min((unsigned int)scaled, 2u);
    const float v = clampf(scaled - (float)channel, 0.0f, 1.0f - 1.1920929e-7f);
    const float st = channel == 0 ? sigma_t.x : channel == 1 ? sigma_t.y : sigma_t.z;
    const float depth = st > 0.0f ? sample_exponential(v, st) : f32_infinity();
    MediumSegment s;
    s.t = 0.0f;
    const float third = 1.0f / 3.0f;
    if (depth < total) {
        float t = depth;
        bool reached = true;
        if (grid) {
            reached = grid_invert(p, m, o, d, 0.0f, t_max, depth / scale, &t);
            t *= scale;
        }
        if (reached) {
            const float3 tr = make_float3(expf(-sigma_t.x * depth), expf(-sigma_t.y * depth), expf(-sigma_t.z * depth));
            const float density = dot3(sigma_t * tr, make_float3(third, third, third));
            s.scatter = true;
            s.t = t;
            s.weight = density > 0.0f ? tr * make_float3(m.sigma_s[0], m.sigma_s[1], m.sigma_s[2]) / density : zero3();
            return s;
        }
    }
    const float3 tr = medium_transmittance(sigma_t, total);
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
/// Where the triangle's mesh only bounds media it does not, and the media
/// before and after it go to `*before` and `*after`: the caller adds the
/// optical depth of the one after over the rest of the ray, less the one's
/// before.
__device__ __noinline__ bool medium_crossing(const SceneView& s, unsigned int tri, float u, float v, float3 d,
                                             unsigned int* before, unsigned int* after) {
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
    *before = media_towards(media, -cosine);
    *after = media_towards(media, cosine);
    return false;
}
