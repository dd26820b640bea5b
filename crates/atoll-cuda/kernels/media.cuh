// Participating media: the mirror of `atoll_render::medium` (where a
// segment scatters, its weight, the emission along it), of
// `atoll_render::density_grid` (a grid's extinction integrated exactly
// along rays, cell by cell) and of `atoll_render::shadow_media` (the optical depth
// a shadow ray gathers where it crosses a surface that only bounds media).
#pragma once

#include "common.cuh"
#include "layout.cuh"
#include "params.cuh"
#include "sampling.cuh"

// Grid media whose σa, σs or Le differ by colour (`rgbgrid`):
// `-DATOLL_WITH_RGB_MEDIA=0` (src/device.rs `shade_features`, src/trace.rs
// `TraceFeatures`) compiles them out of frames whose grids are all grey,
// whose walks then keep the registers they had before RGB grids.
#ifndef ATOLL_WITH_RGB_MEDIA
#define ATOLL_WITH_RGB_MEDIA 1
#endif

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

// --- grids (density_grid.rs) ---

/// The samples of channel `k` of medium `m`'s grid (one plane of
/// `media_grids`). Walks look it up once: indexing each sample from the
/// parameter block costs grid-heavy kernels several percent.
__device__ __forceinline__ const float* grid_plane(const FrameParams& p, const GpuMedium& m, unsigned int k) {
    return p.media_grids + m.grid_first + k * m.grid_plane;
}

/// Mirrors `DensityGrid::sample`: sample (x, y, z) of a `plane` of medium `m`'s grid, 0 outside.
__device__ __forceinline__ float grid_sample(const GpuMedium& m, const float* plane, int x, int y, int z) {
    const int nx = (int)m.grid_resolution[0], ny = (int)m.grid_resolution[1], nz = (int)m.grid_resolution[2];
    if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) return 0.0f;
    return plane[(unsigned int)((z * ny + y) * nx + x)];
}

/// Mirrors `DensityGrid::channel_in`: a `plane`, trilinear, at lattice
/// point `s` of cell `c`.
__device__ __forceinline__ float grid_channel_in(const GpuMedium& m, const float* plane, const int* c, float3 s) {
    const float dx = s.x - (float)c[0], dy = s.y - (float)c[1], dz = s.z - (float)c[2];
    const auto lerp = [](float a, float b, float t) { return a + (b - a) * t; };
    const int x = c[0], y = c[1], z = c[2];
    const float x00 = lerp(grid_sample(m, plane, x, y, z), grid_sample(m, plane, x + 1, y, z), dx);
    const float x10 = lerp(grid_sample(m, plane, x, y + 1, z), grid_sample(m, plane, x + 1, y + 1, z), dx);
    const float x01 = lerp(grid_sample(m, plane, x, y, z + 1), grid_sample(m, plane, x + 1, y, z + 1), dx);
    const float x11 = lerp(grid_sample(m, plane, x, y + 1, z + 1), grid_sample(m, plane, x + 1, y + 1, z + 1), dx);
    return lerp(lerp(x00, x10, dy), lerp(x01, x11, dy), dz);
}

/// Channel `ch` (0 red, 1 green, 2 blue) of what a field word reads at
/// lattice point `s` of cell `c` (`DensityGrid::source_in`).
__device__ __forceinline__ float grid_source_channel(const FrameParams& p, const GpuMedium& m, unsigned int field,
                                                     const int* c, float3 s, unsigned int ch) {
    if (field == GRID_FIELD_CONSTANT) return 1.0f;
    const unsigned int k = (field & (GRID_FIELD_RGB - 1u)) + ((field & GRID_FIELD_RGB) ? ch : 0u);
    return grid_channel_in(m, grid_plane(p, m, k), c, s);
}

/// Channel `ch` of σt at lattice point `s` of cell `c`
/// (`DensityGrid::extinction_in`: one lookup where σa and σs scale the
/// same samples, as a `uniformgrid`'s density). Channel by channel, so
/// that an RGB grid's lookups never all live in registers at once.
__device__ __forceinline__ float grid_extinction_channel(const FrameParams& p, const GpuMedium& m, const int* c,
                                                         float3 s, unsigned int ch) {
    const unsigned int fa = m.grid_fields[0], fs = m.grid_fields[1];
    if (fa == fs) return (m.sigma_a[ch] + m.sigma_s[ch]) * grid_source_channel(p, m, fa, c, s, ch);
    return m.sigma_a[ch] * grid_source_channel(p, m, fa, c, s, ch) +
           m.sigma_s[ch] * grid_source_channel(p, m, fs, c, s, ch);
}

/// Whether a field word reads one value for all three colours.
__device__ __forceinline__ bool grid_field_grey(unsigned int field) {
    return field == GRID_FIELD_CONSTANT || !(field & GRID_FIELD_RGB);
}

/// `grid_extinction_in` where a field is RGB: channel by channel, out of
/// line, so that its lookups never all live in registers at once and
/// grey grids do not pay for them.
__device__ __noinline__ float3 grid_extinction_rgb(const FrameParams& p, const GpuMedium& m, const int* c,
                                                   float3 s) {
    return make_float3(grid_extinction_channel(p, m, c, s, 0u), grid_extinction_channel(p, m, c, s, 1u),
                       grid_extinction_channel(p, m, c, s, 2u));
}

/// Mirrors `DensityGrid::extinction_in`: σt at lattice point `s` of cell
/// `c`; a grey field is looked up once for all three colours.
__device__ __forceinline__ float3 grid_extinction_in(const FrameParams& p, const GpuMedium& m, const int* c,
                                                     float3 s) {
    const unsigned int fa = m.grid_fields[0], fs = m.grid_fields[1];
    if (!grid_field_grey(fa) || !grid_field_grey(fs)) return grid_extinction_rgb(p, m, c, s);
    const float va = grid_source_channel(p, m, fa, c, s, 0u);
    if (fa == fs) return (load3(m.sigma_a) + load3(m.sigma_s)) * va;
    return load3(m.sigma_a) * va + load3(m.sigma_s) * grid_source_channel(p, m, fs, c, s, 0u);
}

/// Mirrors `DensityGrid::cell_integral`: ∫ σt dt over [ta, tb] in cell
/// `c`, two-point Gauss–Legendre, exact for the cubics along a ray.
__device__ __forceinline__ float3 grid_cell_integral(const FrameParams& p, const GpuMedium& m, const int* c,
                                                     float3 s0, float3 ds, float ta, float tb) {
    const float gauss = 0.577350269f;
    const float mid = 0.5f * (ta + tb), half = 0.5f * (tb - ta);
    return (grid_extinction_in(p, m, c, s0 + ds * (mid - half * gauss)) +
            grid_extinction_in(p, m, c, s0 + ds * (mid + half * gauss))) *
           half;
}

/// Channel `ch` of `grid_cell_integral` alone (what bisection needs).
__device__ __forceinline__ float grid_cell_integral_channel(const FrameParams& p, const GpuMedium& m, const int* c,
                                                            float3 s0, float3 ds, float ta, float tb,
                                                            unsigned int ch) {
    const float gauss = 0.577350269f;
    const float mid = 0.5f * (ta + tb), half = 0.5f * (tb - ta);
    return (grid_extinction_channel(p, m, c, s0 + ds * (mid - half * gauss), ch) +
            grid_extinction_channel(p, m, c, s0 + ds * (mid + half * gauss), ch)) *
           half;
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

__device__ __forceinline__ float channel_of(float3 v, unsigned int k) { return k == 0 ? v.x : k == 1 ? v.y : v.z; }

#if !ATOLL_WITH_RGB_MEDIA
// Frames whose grids are all grey (`uniformgrid`s: σa and σs scale one
// density): the walks integrate that density alone and scale it by σt
// afterwards, as `DensityGrid` does per channel, to rounding. Shading
// then needs no float3 sums, which keeps its registers.

/// ∫ density dt over [ta, tb] in cell `c` (two-point Gauss–Legendre). A
/// grey frame's density is its grids' first plane (`MediumTable::has_rgb_grids`):
/// a constant plane keeps both the index arithmetic and the registers down.
__device__ __forceinline__ float grid_density_cell(const FrameParams& p, const GpuMedium& m, const int* c, float3 s0,
                                                   float3 ds, float ta, float tb) {
    const float gauss = 0.577350269f;
    const float mid = 0.5f * (ta + tb), half = 0.5f * (tb - ta);
    const float* density = grid_plane(p, m, 0u);
    return half * (grid_channel_in(m, density, c, s0 + ds * (mid - half * gauss)) +
                   grid_channel_in(m, density, c, s0 + ds * (mid + half * gauss)));
}

/// ∫ density dt along `o + t d`, t0 <= t < t1.
__device__ __noinline__ float grid_density_integral(const FrameParams& p, const GpuMedium& m, float3 o, float3 d,
                                                    float t0, float t1) {
    float sum = 0.0f;
    grid_walk(m, o, d, t0, t1, [&](const int* c, float3 s0, float3 ds, float ta, float tb) {
        sum += grid_density_cell(p, m, c, s0, ds, ta, tb);
        return true;
    });
    return sum;
}

/// The t where the density's integral from t0 reaches `target` into `*t`;
/// false when the segment holds less. (Its bisection repeats
/// `grid_invert`'s: written once as a template taking a lambda, it cost
/// the shade kernel 40 registers.)
__device__ __noinline__ bool grid_density_invert(const FrameParams& p, const GpuMedium& m, float3 o, float3 d,
                                                 float t0, float t1, float target, float* t) {
    float sum = 0.0f;
    bool found = false;
    grid_walk(m, o, d, t0, t1, [&](const int* c, float3 s0, float3 ds, float ta, float tb) {
        const float here = grid_density_cell(p, m, c, s0, ds, ta, tb);
        if (sum + here < target) {
            sum += here;
            return true;
        }
        float lo = ta, hi = tb;
        for (int k = 0; k < 30; ++k) {
            const float mid = 0.5f * (lo + hi);
            if (sum + grid_density_cell(p, m, c, s0, ds, ta, mid) < target) {
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

/// A grey grid's emission scale (its `Lescale`) at world point `w` inside it.
__device__ __noinline__ float grid_le_scale_at(const FrameParams& p, const GpuMedium& m, float3 w) {
    if (m.grid_fields[2] == GRID_FIELD_CONSTANT) return 1.0f;
    const float3 s = affine_point(m.world_to_lattice, w);
    const int c[3] = {(int)floorf(s.x), (int)floorf(s.y), (int)floorf(s.z)};
    return grid_channel_in(m, grid_plane(p, m, m.grid_fields[2]), c, s);
}
#else
/// A grid medium's coefficients at a point (mirrors `GridPoint`).
struct GridPoint {
    float3 sigma_a, sigma_s;
    float3 emission;  // σa · Le
};

/// Mirrors `DensityGrid::point`: the coefficients at world point `w`, none outside the bounds.
__device__ __noinline__ GridPoint grid_point(const FrameParams& p, const GpuMedium& m, float3 w) {
    GridPoint g;
    g.sigma_a = g.sigma_s = g.emission = zero3();
    const float3 s = affine_point(m.world_to_lattice, w);
    const float sa[3] = {s.x, s.y, s.z};
    int c[3];
    for (int a = 0; a < 3; ++a) {
        if (sa[a] < -0.5f || sa[a] > (float)m.grid_resolution[a] - 0.5f) return g;
        c[a] = (int)floorf(sa[a]);
    }
    const auto field = [&](const float* scale, unsigned int word) {
        return make_float3(scale[0] * grid_source_channel(p, m, word, c, s, 0u),
                           scale[1] * grid_source_channel(p, m, word, c, s, 1u),
                           scale[2] * grid_source_channel(p, m, word, c, s, 2u));
    };
    g.sigma_a = field(m.sigma_a, m.grid_fields[0]);
    g.sigma_s = field(m.sigma_s, m.grid_fields[1]);
    g.emission = g.sigma_a * field(m.le, m.grid_fields[2]);
    return g;
}

/// Mirrors `DensityGrid::integral`: ∫ σt dt per channel.
__device__ __noinline__ float3 grid_integral(const FrameParams& p, const GpuMedium& m, float3 o, float3 d, float t0,
                                             float t1) {
    float3 sum = zero3();
    grid_walk(m, o, d, t0, t1, [&](const int* c, float3 s0, float3 ds, float ta, float tb) {
        sum = sum + grid_cell_integral(p, m, c, s0, ds, ta, tb);
        return true;
    });
    return sum;
}

/// Mirrors `DensityGrid::invert`: the t where channel `k` of the integral
/// from t0 reaches `target` into `*t`, the whole integral up to it into
/// `*depth`; false when the segment holds less.
__device__ __noinline__ bool grid_invert(const FrameParams& p, const GpuMedium& m, float3 o, float3 d, float t0,
                                         float t1, unsigned int k, float target, float* t, float3* depth) {
    float3 sum = zero3();
    bool found = false;
    grid_walk(m, o, d, t0, t1, [&](const int* c, float3 s0, float3 ds, float ta, float tb) {
        const float3 here = grid_cell_integral(p, m, c, s0, ds, ta, tb);
        if (channel_of(sum, k) + channel_of(here, k) < target) {
            sum = sum + here;
            return true;
        }
        float lo = ta, hi = tb;
        const float before = channel_of(sum, k);
        for (int i = 0; i < 30; ++i) {
            const float mid = 0.5f * (lo + hi);
            if (before + grid_cell_integral_channel(p, m, c, s0, ds, ta, mid, k) < target) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        *t = 0.5f * (lo + hi);
        *depth = sum + grid_cell_integral(p, m, c, s0, ds, ta, *t);
        found = true;
        return false;
    });
    return found;
}

#endif

// --- media (medium.rs) ---

/// Mirrors `MediumTable::optical_depth`.
__device__ __forceinline__ float3 medium_optical_depth(const FrameParams& p, unsigned int medium, float3 o, float3 d,
                                                       float t0, float t1) {
    const GpuMedium& m = p.media[medium];
    const float3 sigma_t = medium_sigma_t(m);
    if (is_zero3(sigma_t)) return zero3();
    const float scale = length3(d);
    if (m.grid_first == NO_GRID) return sigma_t * ((t1 - t0) * scale);
#if ATOLL_WITH_RGB_MEDIA
    return grid_integral(p, m, o, d, t0, t1) * scale;
#else
    return sigma_t * (grid_density_integral(p, m, o, d, t0, t1) * scale);
#endif
}

/// Mirrors `medium::Segment`: scatter at `t` (else pass), with `weight`.
struct MediumSegment {
    bool scatter;
    float t;
    float3 weight;
};

/// Mirrors `medium::channel_probabilities`: proportional to the magnitude
/// of the throughput `beta` (uniform where it has none).
__device__ __forceinline__ float3 medium_channel_probabilities(float3 beta) {
    const float3 m = abs3(beta);
    const float sum = m.x + m.y + m.z;
    if (sum > 0.0f && is_finitef(sum)) return m / sum;
    const float third = 1.0f / 3.0f;
    return make_float3(third, third, third);
}

/// Mirrors `medium::pass`.
__device__ __forceinline__ float3 medium_pass_weight(float3 tr, float3 channels) {
    const float passing = dot3(tr, channels);
    return passing > 0.0f ? tr / passing : zero3();
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

/// Mirrors `MediumTable::sample_segment` (with `channel_and_depth` and
/// `MediumCoeffs::sample_uniform_segment`): a channel from the leading
/// share of `u` (with probabilities `channels`,
/// `medium_channel_probabilities` of the throughput before the segment),
/// the optical depth to reach from the rest, found along the segment
/// `o + t d`, 0 <= t < t_max, and weighted by the channels' mixture; a
/// homogeneous medium's emission in closed form, a grid's where the segment
/// scatters, into `*emitted` (to be weighted by the throughput). A
/// scattering `t` is in world units.
__device__ __noinline__ MediumSegment medium_sample_segment(const FrameParams& p, unsigned int medium, float3 o,
                                                            float3 d, float t_max, float u, float3 channels,
                                                            float3* emitted) {
    const GpuMedium& m = p.media[medium];
    const float scale = length3(d);
    unsigned int channel;
    float start;
    if (u < channels.x || channels.y + channels.z == 0.0f) {
        channel = 0u;
        start = 0.0f;
    } else if (u < channels.x + channels.y || channels.z == 0.0f) {
        channel = 1u;
        start = channels.x;
    } else {
        channel = 2u;
        start = channels.x + channels.y;
    }
    const float v = clampf((u - start) / channel_of(channels, channel), 0.0f, 1.0f - 1.1920929e-7f);
    const float target = sample_exponential(v, 1.0f);
    MediumSegment s;
    s.scatter = false;
    s.t = 0.0f;
    if (m.grid_first == NO_GRID) {
        const float3 sigma_t = medium_sigma_t(m);
        const float length = t_max * scale;
        *emitted = medium_emission_over(m, length);
        const float st = channel_of(sigma_t, channel);
        const float depth = st > 0.0f ? target / st : f32_infinity();
        if (depth < length) {
            const float3 tr =
                make_float3(expf(-sigma_t.x * depth), expf(-sigma_t.y * depth), expf(-sigma_t.z * depth));
            const float density = dot3(channels, sigma_t * tr);
            s.scatter = true;
            s.t = depth;
            s.weight = density > 0.0f ? tr * load3(m.sigma_s) / density : zero3();
            return s;
        }
        s.weight = medium_pass_weight(medium_transmittance(sigma_t, length), channels);
        return s;
    }
#if !ATOLL_WITH_RGB_MEDIA
    {
        // A grey grid: the density at the stop cancels out of the weights.
        const float3 sigma_t = medium_sigma_t(m);
        const float total = grid_density_integral(p, m, o, d, 0.0f, t_max) * scale;
        const float st = channel_of(sigma_t, channel);
        const float depth = st > 0.0f ? target / st : f32_infinity();
        float t;
        if (depth < total && grid_density_invert(p, m, o, d, 0.0f, t_max, depth / scale, &t)) {
            const float3 tr =
                make_float3(expf(-sigma_t.x * depth), expf(-sigma_t.y * depth), expf(-sigma_t.z * depth));
            const float density = dot3(channels, sigma_t * tr);
            s.scatter = true;
            s.t = t * scale;
            if (density > 0.0f) {
                s.weight = tr * load3(m.sigma_s) / density;
                if (!is_zero3(load3(m.le))) {
                    const float3 le = load3(m.le) * grid_le_scale_at(p, m, o + d * t);
                    *emitted = tr * load3(m.sigma_a) * le / density;
                }
            } else {
                s.weight = zero3();
            }
            return s;
        }
        s.weight = medium_pass_weight(medium_transmittance(sigma_t, total), channels);
        return s;
    }
#else
    const float target_t = target / scale;
    const float3 total = grid_integral(p, m, o, d, 0.0f, t_max);
    float t;
    float3 depth;
    if (target_t < channel_of(total, channel) && grid_invert(p, m, o, d, 0.0f, t_max, channel, target_t, &t, &depth)) {
        const GridPoint at = grid_point(p, m, o + d * t);
        const float3 tr = make_float3(expf(-(depth.x * scale)), expf(-(depth.y * scale)), expf(-(depth.z * scale)));
        const float density = dot3(channels, (at.sigma_a + at.sigma_s) * tr);
        s.scatter = true;
        s.t = t * scale;
        s.weight = density > 0.0f ? tr * at.sigma_s / density : zero3();
        if (density > 0.0f) *emitted = tr * at.emission / density;
        return s;
    }
    s.weight = medium_pass_weight(
        make_float3(expf(-(total.x * scale)), expf(-(total.y * scale)), expf(-(total.z * scale))), channels);
    return s;
#endif
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
