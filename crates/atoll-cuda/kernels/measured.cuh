// Measured BRDFs: the mirror of `atoll_render::bsdf::measured` and of the
// warps of `atoll_scene::measured` (pbrt-v4's `MeasuredBxDF` and
// `PiecewiseLinear2D`, in RGB), over one BRDF's words as
// `MeasuredBrdf::pack` lays them out: a header of MEASURED_HEADER_WORDS
// (isotropic, phi_i and theta_i counts and offsets, then per table nx, ny
// and the offsets of its data and CDFs), then the arrays. Offsets count
// words from the header. Every function names the Rust one it ports.
#pragma once

#include "common.cuh"
#include "materials.cuh"

/// `measured_table` reads the tables' headers after the five words of the BRDF's own.
static_assert(MEASURED_HEADER_WORDS == 5u + 5u * 5u, "MeasuredBrdf::pack's header changed");

/// pbrt's `OneMinusEpsilon` (`measured::ONE_MINUS_EPSILON`): the largest float below 1.
inline constexpr float MEASURED_ONE_MINUS_EPSILON = 0x1.fffffep-1f;

/// Mirrors `measured::IncidentLookup`: the four slices around the incident
/// direction, `phi` fastest, and the weights of phi (0, 1) and theta (2, 3).
struct IncidentLookup {
    unsigned int slices[4];
    float w[4];
};

/// Mirrors `IncidentLookup::lookup`.
__device__ __forceinline__ float incident_lookup(const IncidentLookup& at, const float* data, unsigned int i,
                                                 unsigned int slice_len) {
    const float near = data[at.slices[0] * slice_len + i] * at.w[0] + data[at.slices[1] * slice_len + i] * at.w[1];
    const float far = data[at.slices[2] * slice_len + i] * at.w[0] + data[at.slices[3] * slice_len + i] * at.w[1];
    return near * at.w[2] + far * at.w[3];
}

/// The single slice of the tables of one direction (`IncidentLookup::SINGLE`).
__device__ __forceinline__ IncidentLookup incident_single() {
    IncidentLookup at;
    for (int c = 0; c < 4; ++c) at.slices[c] = 0u;
    at.w[0] = 1.0f;
    at.w[1] = 0.0f;
    at.w[2] = 1.0f;
    at.w[3] = 0.0f;
    return at;
}

/// Mirrors `measured::find_interval`.
template <typename Pred>
__device__ __forceinline__ unsigned int measured_find_interval(unsigned int size, Pred pred) {
    unsigned int first = 1u, len = size >= 2u ? size - 2u : 0u;
    while (len > 0u) {
        const unsigned int half = len >> 1;
        const unsigned int middle = first + half;
        if (pred(middle)) {
            first = middle + 1u;
            len -= half + 1u;
        } else {
            len = half;
        }
    }
    const unsigned int i = first >= 1u ? first - 1u : 0u;
    const unsigned int last = size >= 2u ? size - 2u : 0u;
    return i < last ? i : last;
}

/// One table of a measured BRDF (`measured::Warp2d`).
struct Warp2d {
    const float* data;
    const float* marginal;
    const float* conditional;
    unsigned int nx, ny, planes;
    float density_scale;
};

/// Which table: the order of `MeasuredBrdf::pack`.
enum MeasuredTable : unsigned int { MEASURED_NDF = 0, MEASURED_SIGMA, MEASURED_VNDF, MEASURED_LUMINANCE, MEASURED_RGB };

__device__ __forceinline__ Warp2d measured_table(const float* brdf, unsigned int k) {
    const unsigned int* h = reinterpret_cast<const unsigned int*>(brdf) + 5u + 5u * k;
    Warp2d w;
    w.nx = h[0];
    w.ny = h[1];
    w.data = brdf + h[2];
    w.marginal = brdf + h[3];
    w.conditional = brdf + h[4];
    w.planes = k == MEASURED_RGB ? 3u : 1u;
    const bool sampled = k == MEASURED_VNDF || k == MEASURED_LUMINANCE;
    w.density_scale = sampled ? (float)((w.nx - 1u) * (w.ny - 1u)) : 1.0f;
    return w;
}

// The warps are kept out of line: the measured scene renders faster so on
// an H100 than with them inlined into the BSDF's three functions (though
// the shade kernel then holds a few registers more; BENCHMARKS.md).

/// Mirrors `Warp2d::evaluate` of table `k` of `brdf`.
__device__ __noinline__ float warp_evaluate(const float* brdf, unsigned int k, float2 pos, const IncidentLookup& at,
                                            unsigned int plane) {
    const Warp2d w = measured_table(brdf, k);
    const unsigned int nx = w.nx, ny = w.ny;
    pos.x *= (float)(nx - 1u);
    pos.y *= (float)(ny - 1u);
    const unsigned int ix = min((unsigned int)pos.x, nx - 2u), iy = min((unsigned int)pos.y, ny - 2u);
    const float w1x = pos.x - (float)ix, w1y = pos.y - (float)iy;
    const float w0x = 1.0f - w1x, w0y = 1.0f - w1y;
    const unsigned int i = plane * nx * ny + ix + iy * nx;
    const unsigned int len = w.planes * nx * ny;
    const float v00 = incident_lookup(at, w.data, i, len), v10 = incident_lookup(at, w.data, i + 1u, len);
    const float v01 = incident_lookup(at, w.data, i + nx, len), v11 = incident_lookup(at, w.data, i + nx + 1u, len);
    return (w0y * (w0x * v00 + w1x * v10) + w1y * (w0x * v01 + w1x * v11)) * w.density_scale;
}

/// Mirrors `Warp2d::sample` of table `k` of `brdf`: the point `u` maps to;
/// its density in `*pdf`.
__device__ __noinline__ float2 warp_sample(const float* brdf, unsigned int k, float2 u, const IncidentLookup& at,
                                           float* pdf) {
    const Warp2d w = measured_table(brdf, k);
    const unsigned int nx = w.nx, ny = w.ny;
    const float lo = 1.0f - MEASURED_ONE_MINUS_EPSILON;
    float ux = fminf(fmaxf(u.x, lo), MEASURED_ONE_MINUS_EPSILON);
    float uy = fminf(fmaxf(u.y, lo), MEASURED_ONE_MINUS_EPSILON);
    const unsigned int slice = nx * ny;

    const unsigned int row =
        measured_find_interval(ny, [&](unsigned int i) { return incident_lookup(at, w.marginal, i, ny) < uy; });
    uy -= incident_lookup(at, w.marginal, row, ny);
    unsigned int offset = row * nx;
    const float r0 = incident_lookup(at, w.conditional, offset + nx - 1u, slice);
    const float r1 = incident_lookup(at, w.conditional, offset + 2u * nx - 1u, slice);
    bool is_const = fabsf(r0 - r1) < 1e-4f * (r0 + r1);
    uy = is_const ? 2.0f * uy : r0 - sqrtf(fmaxf(r0 * r0 - 2.0f * uy * (r0 - r1), 0.0f));
    uy /= is_const ? r0 + r1 : r0 - r1;

    ux *= (1.0f - uy) * r0 + uy * r1;
    const auto conditional = [&](unsigned int i) {
        const float v0 = incident_lookup(at, w.conditional, offset + i, slice);
        const float v1 = incident_lookup(at, w.conditional, offset + nx + i, slice);
        return (1.0f - uy) * v0 + uy * v1;
    };
    const unsigned int col = measured_find_interval(nx, [&](unsigned int i) { return conditional(i) < ux; });
    ux -= conditional(col);
    offset += col;

    const float v00 = incident_lookup(at, w.data, offset, slice), v10 = incident_lookup(at, w.data, offset + 1u, slice);
    const float v01 = incident_lookup(at, w.data, offset + nx, slice);
    const float v11 = incident_lookup(at, w.data, offset + nx + 1u, slice);
    const float c0 = (1.0f - uy) * v00 + uy * v01;
    const float c1 = (1.0f - uy) * v10 + uy * v11;
    is_const = fabsf(c0 - c1) < 1e-4f * (c0 + c1);
    ux = is_const ? 2.0f * ux : c0 - sqrtf(fmaxf(c0 * c0 - 2.0f * ux * (c0 - c1), 0.0f));
    ux /= is_const ? c0 + c1 : c0 - c1;

    *pdf = ((1.0f - ux) * c0 + ux * c1) * w.density_scale;
    return make_float2(((float)col + ux) / (float)(nx - 1u), ((float)row + uy) / (float)(ny - 1u));
}

/// Mirrors `Warp2d::invert` of table `k` of `brdf`: the sample that maps to
/// `p`; the density at `p` in `*pdf`.
__device__ __noinline__ float2 warp_invert(const float* brdf, unsigned int k, float2 p, const IncidentLookup& at,
                                           float* pdf) {
    const Warp2d w = measured_table(brdf, k);
    const unsigned int nx = w.nx, ny = w.ny;
    const unsigned int slice = nx * ny;
    const float px = p.x * (float)(nx - 1u), py = p.y * (float)(ny - 1u);
    const unsigned int ix = min((unsigned int)px, nx - 2u), iy = min((unsigned int)py, ny - 2u);
    float sx = px - (float)ix, sy = py - (float)iy;
    const unsigned int offset = ix + iy * nx;

    const float v00 = incident_lookup(at, w.data, offset, slice), v10 = incident_lookup(at, w.data, offset + 1u, slice);
    const float v01 = incident_lookup(at, w.data, offset + nx, slice);
    const float v11 = incident_lookup(at, w.data, offset + nx + 1u, slice);
    const float w1x = sx, w1y = sy, w0x = 1.0f - w1x, w0y = 1.0f - w1y;
    const float c0 = w0y * v00 + w1y * v01;
    const float c1 = w0y * v10 + w1y * v11;
    const float density = w0x * c0 + w1x * c1;
    sx *= c0 + 0.5f * sx * (c1 - c0);
    const float v0 = incident_lookup(at, w.conditional, offset, slice);
    const float v1 = incident_lookup(at, w.conditional, offset + nx, slice);
    sx += (1.0f - sy) * v0 + sy * v1;
    const unsigned int row = iy * nx;
    const float r0 = incident_lookup(at, w.conditional, row + nx - 1u, slice);
    const float r1 = incident_lookup(at, w.conditional, row + 2u * nx - 1u, slice);
    sx /= (1.0f - sy) * r0 + sy * r1;

    sy *= r0 + 0.5f * sy * (r1 - r0);
    sy += incident_lookup(at, w.marginal, iy, ny);
    *pdf = density * w.density_scale;
    return make_float2(sx, sy);
}

/// Mirrors `MeasuredBrdf::incident`.
__device__ IncidentLookup measured_incident(const float* brdf, float phi, float theta) {
    const unsigned int* h = reinterpret_cast<const unsigned int*>(brdf);
    unsigned int i0[2], i1[2];
    float w0[2], w1[2];
    for (int d = 0; d < 2; ++d) {
        const unsigned int n = h[1 + d];
        const float* values = brdf + h[3 + d];
        const float x = d == 0 ? phi : theta;
        if (n == 1u) {
            i0[d] = i1[d] = 0u;
            w0[d] = 1.0f;
            w1[d] = 0.0f;
            continue;
        }
        const unsigned int i = measured_find_interval(n, [&](unsigned int k) { return values[k] <= x; });
        const float p0 = values[i], p1 = values[i + 1u];
        const float t = fminf(fmaxf((x - p0) / (p1 - p0), 0.0f), 1.0f);
        i0[d] = i;
        i1[d] = i + 1u;
        w0[d] = 1.0f - t;
        w1[d] = t;
    }
    const unsigned int n_theta = h[2];
    IncidentLookup at;
    at.slices[0] = i0[0] * n_theta + i0[1];
    at.slices[1] = i1[0] * n_theta + i0[1];
    at.slices[2] = i0[0] * n_theta + i1[1];
    at.slices[3] = i1[0] * n_theta + i1[1];
    at.w[0] = w0[0];
    at.w[1] = w1[0];
    at.w[2] = w0[1];
    at.w[3] = w1[1];
    return at;
}

// --- the BSDF (bsdf/measured.rs) ---

__device__ __forceinline__ float measured_theta_to_u(float theta) { return sqrtf(theta * (2.0f / PI)); }
__device__ __forceinline__ float measured_phi_to_u(float phi) { return phi * (0.5f / PI) + 0.5f; }
/// Mirrors `measured::polar_angle`.
__device__ __forceinline__ float measured_theta(float3 w) { return atan2f(sqrtf(w.x * w.x + w.y * w.y), w.z); }

/// Mirrors `measured::jacobian`.
__device__ __forceinline__ float measured_jacobian(float3 wo, float3 wm, float u_wm_x, float sin_theta_m) {
    return 4.0f * dot3(wo, wm) * fmaxf(2.0f * PI * PI * u_wm_x * sin_theta_m, 1e-6f);
}

/// Mirrors `measured::Incident`.
struct MeasuredIncident {
    float phi;
    IncidentLookup at;
    float2 u_wo;
};

__device__ __forceinline__ MeasuredIncident measured_incident_of(const float* brdf, float3 wo) {
    MeasuredIncident inc;
    const float theta = measured_theta(wo);
    inc.phi = atan2f(wo.y, wo.x);
    inc.at = measured_incident(brdf, inc.phi, theta);
    inc.u_wo = make_float2(measured_theta_to_u(theta), measured_phi_to_u(inc.phi));
    return inc;
}

/// Mirrors `measured::normal_square`; false for opposite directions.
__device__ __forceinline__ bool measured_normal_square(const float* brdf, const MeasuredIncident& inc, float3 wo,
                                                       float3 wi, float3* wm_out, float2* u_wm) {
    float3 wm = wo + wi;
    if (dot3(wm, wm) == 0.0f) return false;
    wm = normalize3(wm);
    const float phi_m = atan2f(wm.y, wm.x);
    const bool isotropic = reinterpret_cast<const unsigned int*>(brdf)[0] != 0u;
    const float v = measured_phi_to_u(isotropic ? phi_m - inc.phi : phi_m);
    *wm_out = wm;
    *u_wm = make_float2(measured_theta_to_u(measured_theta(wm)), v - floorf(v));
    return true;
}

/// Mirrors `measured::value`.
__device__ float3 measured_value(const float* brdf, const MeasuredIncident& inc, float2 s, float2 u_wm,
                                 float cos_theta_i) {
    const float3 c = make_float3(fmaxf(warp_evaluate(brdf, MEASURED_RGB, s, inc.at, 0u), 0.0f),
                                 fmaxf(warp_evaluate(brdf, MEASURED_RGB, s, inc.at, 1u), 0.0f),
                                 fmaxf(warp_evaluate(brdf, MEASURED_RGB, s, inc.at, 2u), 0.0f));
    const IncidentLookup single = incident_single();
    const float d = warp_evaluate(brdf, MEASURED_NDF, u_wm, single, 0u);
    const float sigma = warp_evaluate(brdf, MEASURED_SIGMA, inc.u_wo, single, 0u);
    return c * (d / (4.0f * sigma * cos_theta_i));
}

/// Mirrors `measured::Pair`.
struct MeasuredPair {
    float3 wo, wi;
    MeasuredIncident inc;
    float3 wm;
    float2 u_wm, s;
    float vndf_pdf;
};

/// Mirrors `measured::pair`; false for `None`.
__device__ __forceinline__ bool measured_pair(const float* brdf, float3 wo, float3 wi, MeasuredPair* q) {
    if (!same_hemisphere(wo, wi)) return false;
    if (wo.z < 0.0f) {
        wo = -wo;
        wi = -wi;
    }
    q->wo = wo;
    q->wi = wi;
    q->inc = measured_incident_of(brdf, wo);
    if (!measured_normal_square(brdf, q->inc, wo, wi, &q->wm, &q->u_wm)) return false;
    q->s = warp_invert(brdf, MEASURED_VNDF, q->u_wm, q->inc.at, &q->vndf_pdf);
    return true;
}

/// Mirrors `measured::eval`.
__device__ __noinline__ float3 measured_eval(const float* brdf, float3 wo, float3 wi) {
    MeasuredPair q;
    if (!measured_pair(brdf, wo, wi, &q)) return zero3();
    return measured_value(brdf, q.inc, q.s, q.u_wm, q.wi.z);
}

/// Mirrors `measured::pdf`.
__device__ __noinline__ float measured_pdf(const float* brdf, float3 wo, float3 wi) {
    MeasuredPair q;
    if (!measured_pair(brdf, wo, wi, &q)) return 0.0f;
    const float luminance_pdf = warp_evaluate(brdf, MEASURED_LUMINANCE, q.s, q.inc.at, 0u);
    const float sin_theta_m = sqrtf(q.wm.x * q.wm.x + q.wm.y * q.wm.y);
    return q.vndf_pdf * luminance_pdf / measured_jacobian(q.wo, q.wm, q.u_wm.x, sin_theta_m);
}

/// Mirrors `measured::sample`.
__device__ __noinline__ bool measured_sample(const float* brdf, float3 wo, float2 u, BsdfSample* out) {
    const bool flip = wo.z <= 0.0f;
    if (flip) wo = -wo;
    const MeasuredIncident inc = measured_incident_of(brdf, wo);
    float luminance_pdf, vndf_pdf;
    const float2 s = warp_sample(brdf, MEASURED_LUMINANCE, u, inc.at, &luminance_pdf);
    const float2 u_wm = warp_sample(brdf, MEASURED_VNDF, s, inc.at, &vndf_pdf);
    float phi_m = (2.0f * u_wm.y - 1.0f) * PI;
    if (reinterpret_cast<const unsigned int*>(brdf)[0] != 0u) phi_m += inc.phi;
    const float theta_m = u_wm.x * u_wm.x * (PI / 2.0f);
    float sin_theta_m, cos_theta_m;
    sincosf(theta_m, &sin_theta_m, &cos_theta_m);
    float sin_phi, cos_phi;
    sincosf(phi_m, &sin_phi, &cos_phi);
    const float3 wm = make_float3(sin_theta_m * cos_phi, sin_theta_m * sin_phi, cos_theta_m);
    float3 wi = reflect3(wo, wm);
    if (wi.z <= 0.0f) return false;
    const float3 f = measured_value(brdf, inc, s, u_wm, wi.z);
    const float pdf = vndf_pdf * luminance_pdf / measured_jacobian(wo, wm, u_wm.x, sin_theta_m);
    if (flip) wi = -wi;
    *out = make_bsdf_sample(f, wi, pdf, 1.0f, false, false);
    return true;
}
