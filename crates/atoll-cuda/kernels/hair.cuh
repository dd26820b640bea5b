// Hair fibres: the mirror of `atoll_render::bsdf::hair` (pbrt-v4's
// `HairBxDF`; the module docs give the model, the frame and where `h` comes
// from), same operations in the same order. Included at the end of
// bsdf.cuh, which declares the entry points for its dispatch; they are not
// inlined, so the lobes' live values stay out of the shade kernel's
// register allocation for other materials.
#pragma once

#include "common.cuh"
#include "bsdf.cuh"

/// Mirrors hair.rs's `BESSEL_TERMS`.
inline constexpr unsigned int HAIR_BESSEL_TERMS = 40u;
/// Mirrors the `1 - EPSILON / 2` clamp of `Hair::sample`.
inline constexpr float HAIR_ONE_MINUS_EPSILON = 0.99999994f;
/// Rust's `std::f32::consts::LN_2`.
inline constexpr float HAIR_LN_2 = 0.69314718f;

__device__ __forceinline__ float hair_safe_asin(float x) { return asinf(clampf(x, -1.0f, 1.0f)); }

/// Mirrors `hair::bessel_i0`.
__device__ __forceinline__ float hair_bessel_i0(float x) {
    const float quarter_x2 = x * x * 0.25f;
    float term = 1.0f, sum = 1.0f;
    for (unsigned int i = 1; i < HAIR_BESSEL_TERMS; ++i) {
        term *= quarter_x2 / (float)(i * i);
        sum += term;
        if (term < sum * 1e-8f) break;
    }
    return sum;
}

/// Mirrors `hair::log_bessel_i0`.
__device__ __forceinline__ float hair_log_bessel_i0(float x) {
    if (x > 12.0f) {
        const float r = 1.0f / x;
        const float series = r * (1.0f / 8.0f + r * (9.0f / 128.0f + r * (225.0f / 3072.0f)));
        return x - 0.5f * logf(2.0f * PI * x) + log1pf(series);
    }
    return logf(hair_bessel_i0(x));
}

/// Mirrors `hair::mp`.
__device__ __forceinline__ float hair_mp(float cos_theta_i, float cos_theta_o, float sin_theta_i, float sin_theta_o,
                                         float v) {
    const float a = cos_theta_i * cos_theta_o / v;
    const float b = sin_theta_i * sin_theta_o / v;
    if (v <= 0.1f) return expf(hair_log_bessel_i0(a) - b - 1.0f / v + HAIR_LN_2 + logf(1.0f / (2.0f * v)));
    return (expf(-b) * hair_bessel_i0(a)) / (sinhf(1.0f / v) * 2.0f * v);
}

/// Mirrors `hair::phi`.
__device__ __forceinline__ float hair_phi(int p, float gamma_o, float gamma_t) {
    return 2.0f * (float)p * gamma_t - 2.0f * gamma_o + (float)p * PI;
}

__device__ __forceinline__ float hair_logistic(float x, float s) {
    const float e = expf(-fabsf(x) / s);
    return e / (s * (1.0f + e) * (1.0f + e));
}

__device__ __forceinline__ float hair_logistic_cdf(float x, float s) { return 1.0f / (1.0f + expf(-x / s)); }

/// Mirrors `hair::trimmed_logistic` on [-π, π].
__device__ __forceinline__ float hair_trimmed_logistic(float x, float s) {
    return hair_logistic(x, s) / (hair_logistic_cdf(PI, s) - hair_logistic_cdf(-PI, s));
}

/// Mirrors `hair::sample_trimmed_logistic`.
__device__ __forceinline__ float hair_sample_trimmed_logistic(float u, float s) {
    const float lo = hair_logistic_cdf(-PI, s), hi = hair_logistic_cdf(PI, s);
    const float span = hi - lo;
    const float below = lo + u * span, above = lo + (1.0f - u) * span;
    return clampf(s * logf(below / above), -PI, PI);
}

/// Mirrors `hair::np`.
__device__ __forceinline__ float hair_np(float phi_diff, int p, float s, float gamma_o, float gamma_t) {
    float dphi = phi_diff - hair_phi(p, gamma_o, gamma_t);
    while (dphi > PI) dphi -= 2.0f * PI;
    while (dphi < -PI) dphi += 2.0f * PI;
    return hair_trimmed_logistic(dphi, s);
}

/// Mirrors `Hair::offset`.
__device__ __forceinline__ float hair_offset(float3 wo) {
    const float r = sqrtf(wo.y * wo.y + wo.z * wo.z);
    return r > 0.0f ? clampf(-wo.y / r, -1.0f, 1.0f) : 0.0f;
}

/// Mirrors `Hair::tilted`: (sin θ_o, |cos θ_o|) of lobe `p`.
__device__ __forceinline__ float2 hair_tilted(const Hair& h, int p, float sin_theta_o, float cos_theta_o) {
    float sin_p = sin_theta_o, cos_p = cos_theta_o;
    if (p == 0) {
        sin_p = sin_theta_o * h.cos_2k_alpha[1] - cos_theta_o * h.sin_2k_alpha[1];
        cos_p = cos_theta_o * h.cos_2k_alpha[1] + sin_theta_o * h.sin_2k_alpha[1];
    } else if (p == 1) {
        sin_p = sin_theta_o * h.cos_2k_alpha[0] + cos_theta_o * h.sin_2k_alpha[0];
        cos_p = cos_theta_o * h.cos_2k_alpha[0] - sin_theta_o * h.sin_2k_alpha[0];
    } else if (p == 2) {
        sin_p = sin_theta_o * h.cos_2k_alpha[2] + cos_theta_o * h.sin_2k_alpha[2];
        cos_p = cos_theta_o * h.cos_2k_alpha[2] - sin_theta_o * h.sin_2k_alpha[2];
    }
    return make_float2(sin_p, fabsf(cos_p));
}

/// Mirrors hair.rs's `Outgoing`.
struct HairOutgoing {
    float sin_theta_o, cos_theta_o, phi_o, gamma_o, gamma_t;
    float3 ap[HAIR_P_MAX + 1];
    float ap_pdf[HAIR_P_MAX + 1];
};

/// Mirrors `Hair::outgoing`.
__device__ __forceinline__ HairOutgoing hair_outgoing(const Hair& h, float3 wo) {
    HairOutgoing o;
    const float hh = fabsf(h.given_offset) <= 1.0f ? h.given_offset : hair_offset(wo);
    o.sin_theta_o = wo.x;
    o.cos_theta_o = hair_safe_sqrt(1.0f - o.sin_theta_o * o.sin_theta_o);
    o.phi_o = atan2f(wo.z, wo.y);
    o.gamma_o = hair_safe_asin(hh);
    const float sin_theta_t = o.sin_theta_o / h.eta;
    const float cos_theta_t = hair_safe_sqrt(1.0f - sin_theta_t * sin_theta_t);
    const float etap = hair_safe_sqrt(h.eta * h.eta - o.sin_theta_o * o.sin_theta_o) / o.cos_theta_o;
    const float sin_gamma_t = hh / etap;
    const float cos_gamma_t = hair_safe_sqrt(1.0f - sin_gamma_t * sin_gamma_t);
    o.gamma_t = hair_safe_asin(sin_gamma_t);
    const float path = 2.0f * cos_gamma_t / cos_theta_t;
    const float3 t = make_float3(expf(-h.sigma_a.x * path), expf(-h.sigma_a.y * path), expf(-h.sigma_a.z * path));
    const float f = fr_dielectric(o.cos_theta_o * hair_safe_sqrt(1.0f - hh * hh), h.eta);
    o.ap[0] = make_float3(f, f, f);
    o.ap[1] = t * ((1.0f - f) * (1.0f - f));
    for (int p = 2; p < HAIR_P_MAX; ++p) o.ap[p] = o.ap[p - 1] * t * f;
    const float3 tf = t * f;
    const float3 rest = make_float3(1.0f - tf.x, 1.0f - tf.y, 1.0f - tf.z);
    const float3 last = o.ap[HAIR_P_MAX - 1];
    o.ap[HAIR_P_MAX] = make_float3(rest.x != 0.0f ? last.x * tf.x / rest.x : 0.0f,
                                   rest.y != 0.0f ? last.y * tf.y / rest.y : 0.0f,
                                   rest.z != 0.0f ? last.z * tf.z / rest.z : 0.0f);
    float total = 0.0f;
    float mean[HAIR_P_MAX + 1];
    for (int p = 0; p <= HAIR_P_MAX; ++p) {
        mean[p] = (o.ap[p].x + o.ap[p].y + o.ap[p].z) * (1.0f / 3.0f);
        total += mean[p];
    }
    for (int p = 0; p <= HAIR_P_MAX; ++p) o.ap_pdf[p] = total > 0.0f ? mean[p] / total : 0.0f;
    return o;
}

/// Mirrors `Hair::lobes`: `Σ_p weight[p] Mp Np` plus the isotropic last
/// lobe; the BSDF times `|cos θ_i|` with the attenuations `o.ap` as
/// weights (`T` = float3), the pdf with the selection weights `o.ap_pdf`
/// (`T` = float).
template <typename T>
__device__ __forceinline__ T hair_lobes(const Hair& h, const HairOutgoing& o, float sin_theta_i, float cos_theta_i,
                                        float dphi, const T* weight, T zero) {
    T sum = zero;
    for (int p = 0; p < HAIR_P_MAX; ++p) {
        const float2 t = hair_tilted(h, p, o.sin_theta_o, o.cos_theta_o);
        const float m = hair_mp(cos_theta_i, t.y, sin_theta_i, t.x, h.v[p]);
        sum = sum + weight[p] * (m * hair_np(dphi, p, h.s, o.gamma_o, o.gamma_t));
    }
    const float m = hair_mp(cos_theta_i, o.cos_theta_o, sin_theta_i, o.sin_theta_o, h.v[HAIR_P_MAX]);
    return sum + weight[HAIR_P_MAX] * (m * (0.5f * FRAC_1_PI));
}

/// Mirrors `Hair::eval`.
__device__ __noinline__ float3 hair_eval(Hair h, float3 wo, float3 wi) {
    const HairOutgoing o = hair_outgoing(h, wo);
    const float sin_theta_i = wi.x;
    const float cos_theta_i = hair_safe_sqrt(1.0f - sin_theta_i * sin_theta_i);
    const float3 f = hair_lobes(h, o, sin_theta_i, cos_theta_i, atan2f(wi.z, wi.y) - o.phi_o, o.ap, zero3());
    const float cos = fabsf(wi.z);
    return cos > 0.0f ? f / cos : f;
}

/// Mirrors `Hair::pdf`.
__device__ __noinline__ float hair_pdf(Hair h, float3 wo, float3 wi) {
    const HairOutgoing o = hair_outgoing(h, wo);
    const float sin_theta_i = wi.x;
    const float cos_theta_i = hair_safe_sqrt(1.0f - sin_theta_i * sin_theta_i);
    return hair_lobes(h, o, sin_theta_i, cos_theta_i, atan2f(wi.z, wi.y) - o.phi_o, o.ap_pdf, 0.0f);
}

/// Mirrors `Hair::sample`.
__device__ __noinline__ bool hair_sample(Hair h, float3 wo, float uc, float2 u, BsdfSample* out) {
    const HairOutgoing o = hair_outgoing(h, wo);
    int p = 0;
    float start = 0.0f;
    while (p < HAIR_P_MAX && uc >= start + o.ap_pdf[p]) {
        start += o.ap_pdf[p];
        ++p;
    }
    if (o.ap_pdf[p] <= 0.0f) return false;
    uc = clampf((uc - start) / o.ap_pdf[p], 0.0f, HAIR_ONE_MINUS_EPSILON);
    const float2 t = hair_tilted(h, p, o.sin_theta_o, o.cos_theta_o);
    const float v = h.v[p];
    const float cos_theta = 1.0f + v * logf(fmaxf(u.x, 1e-5f) + (1.0f - u.x) * expf(-2.0f / v));
    const float sin_theta = hair_safe_sqrt(1.0f - cos_theta * cos_theta);
    const float cos_phi = cosf(2.0f * PI * u.y);
    const float sin_theta_i = -cos_theta * t.x + sin_theta * cos_phi * t.y;
    const float cos_theta_i = hair_safe_sqrt(1.0f - sin_theta_i * sin_theta_i);
    const float dphi = p < HAIR_P_MAX ? hair_phi(p, o.gamma_o, o.gamma_t) + hair_sample_trimmed_logistic(uc, h.s)
                                      : 2.0f * PI * uc;
    const float phi_i = o.phi_o + dphi;
    const float3 wi = make_float3(sin_theta_i, cos_theta_i * cosf(phi_i), cos_theta_i * sinf(phi_i));
    const float pdf = hair_lobes(h, o, sin_theta_i, cos_theta_i, dphi, o.ap_pdf, 0.0f);
    const float3 f = hair_eval(h, wo, wi);
    *out = make_bsdf_sample(f, wi, pdf, 1.0f, false, !same_hemisphere(wo, wi));
    return true;
}
