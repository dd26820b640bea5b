// The Disney-principled BSDF: the mirror of `atoll_render::bsdf::principled`
// (its module docs give the model and where it departs from pbrt-v3), same
// operations in the same order. Included at the end of bsdf.cuh, which
// declares the entry points for its dispatch; they are not inlined, so the
// four lobes' live values stay out of the shade kernel's register
// allocation for other materials.
#pragma once

#include "common.cuh"
#include "sampling.cuh"
#include "bsdf.cuh"

/// Mirrors principled.rs's `ONE_MINUS_EPSILON` (1 - 2^-24).
inline constexpr float PRINCIPLED_ONE_MINUS_EPSILON = 0.99999994f;

/// Mirrors `atoll_scene::luminance` (Rec. 709 weights).
__device__ __forceinline__ float luminance3(float3 c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }

__device__ __forceinline__ float3 min3(float3 a, float3 b) {
    return make_float3(fminf(a.x, b.x), fminf(a.y, b.y), fminf(a.z, b.z));
}

__device__ __forceinline__ float3 sqrt3(float3 a) { return make_float3(sqrtf(a.x), sqrtf(a.y), sqrtf(a.z)); }

/// Mirrors `principled::schlick_weight`.
__device__ __forceinline__ float schlick_weight(float cos) {
    const float m = clampf(1.0f - cos, 0.0f, 1.0f);
    const float m2 = m * m;
    return m2 * m2 * m;
}

/// Mirrors principled.rs's `lerp3`.
__device__ __forceinline__ float3 lerp3(float3 a, float3 b, float t) { return a + (b - a) * t; }

/// Mirrors principled.rs's `coat_fresnel`.
__device__ __forceinline__ float coat_fresnel(float cos) { return 0.04f + 0.96f * schlick_weight(cos); }

/// Mirrors `principled::burley_albedo`.
__device__ __forceinline__ float burley_albedo(float mu, float r) {
    const float S1 = 1.0f / 21.0f;
    const float S2 = 1.0f / 84.0f;
    const float S3 = 1.0f / 252.0f;
    const float fo = schlick_weight(mu);
    const float sin2 = 1.0f - mu * mu;
    const float rr = r * (1.0f + 2.0f / 3.0f * mu);
    const float rr_fi = r * (S1 + mu * S2);
    const float rr2_fi = r * r * (S1 + 2.0f * mu * S2 + mu * mu * S3 + sin2 * 0.5f * (S1 - S3));
    return (1.0f - 0.5f * fo) * (1.0f - 0.5f * S1) + fo * rr + rr_fi + fo * (rr2_fi - rr_fi);
}

/// Mirrors principled.rs's `gtr1`.
__device__ __forceinline__ float gtr1(float cos_h, float alpha) {
    const float a2 = alpha * alpha;
    return (a2 - 1.0f) / (PI * logf(a2) * (1.0f + (a2 - 1.0f) * cos_h * cos_h));
}

/// Mirrors principled.rs's `sample_gtr1`.
__device__ __forceinline__ float3 sample_gtr1(float alpha, float2 u) {
    const float a2 = alpha * alpha;
    const float cos2 = clampf((1.0f - powf(a2, 1.0f - u.x)) / (1.0f - a2), 0.0f, 1.0f);
    return spherical_direction(sqrtf(1.0f - cos2), sqrtf(cos2), 2.0f * PI * u.y);
}

/// Mirrors principled.rs's `Lobes`.
struct PrincipledLobes {
    float3 c;
    float r;
    float3 f0, sheen;
    float w_diffuse, w_opaque, w_glass;
    float3 k0;
    float coat, coat_alpha, eta;
    TrowbridgeReitz mf;
};

/// Mirrors `Principled::lobes`.
__device__ __forceinline__ PrincipledLobes principled_lobes(const Principled& p) {
    const float3 one = make_float3(1.0f, 1.0f, 1.0f);
    PrincipledLobes l;
    l.c = make_float3(clampf(p.base_color.x, 0.0f, 1.0f), clampf(p.base_color.y, 0.0f, 1.0f),
                      clampf(p.base_color.z, 0.0f, 1.0f));
    const float m = clampf(p.metallic, 0.0f, 1.0f);
    const float t = clampf(p.transmission, 0.0f, 1.0f);
    l.r = clampf(p.roughness, 0.0f, 1.0f);
    // The base colour's hue and saturation at unit luminance (pbrt-v3's `Ctint`).
    const float lum = luminance3(l.c);
    const float3 tint = lum > 0.0f ? l.c / lum : one;
    l.f0 = min3(0.08f * fmaxf(p.specular, 0.0f) * lerp3(one, tint, clampf(p.specular_tint, 0.0f, 1.0f)), one);
    l.sheen = min3(clampf(p.sheen, 0.0f, 1.0f) * lerp3(one, tint, clampf(p.sheen_tint, 0.0f, 1.0f)), one);
    l.w_diffuse = (1.0f - m) * (1.0f - t);
    l.w_opaque = m + l.w_diffuse;
    l.w_glass = (1.0f - m) * t;
    l.k0 = m * l.c + l.w_diffuse * l.f0;
    l.coat = 0.25f * clampf(p.clearcoat, 0.0f, 1.0f);
    l.coat_alpha = 0.1f + (0.001f - 0.1f) * clampf(p.clearcoat_gloss, 0.0f, 1.0f);
    l.eta = p.eta;
    const float alpha = l.r * l.r;
    l.mf = trowbridge_reitz(alpha, alpha);
    return l;
}

/// Mirrors `Principled::weights`: diffuse, specular, glass, clearcoat.
__device__ __forceinline__ float4 principled_weights(const PrincipledLobes& l, float3 wo) {
    const float mu = fabsf(wo.z);
    const float sw = schlick_weight(mu);
    const float coat = l.coat * coat_fresnel(mu);
    const float under = 1.0f - coat;
    const float3 dielectric = lerp3(l.f0, make_float3(1.0f, 1.0f, 1.0f), sw);
    const float3 w_opaque = make_float3(l.w_opaque, l.w_opaque, l.w_opaque);
    return make_float4(under * l.w_diffuse * (1.0f - luminance3(dielectric)),
                       under * luminance3(lerp3(l.k0, w_opaque, sw)), under * l.w_glass, coat);
}

/// Mirrors `Principled::diffuse`.
__device__ __forceinline__ float3 principled_diffuse(const PrincipledLobes& l, float mu_o, float mu_i, float cos_d) {
    const float fo = schlick_weight(mu_o), fi = schlick_weight(mu_i);
    const float rr = 2.0f * l.r * cos_d * cos_d;
    const float burley = (1.0f - 0.5f * fo) * (1.0f - 0.5f * fi) + rr * (fo + fi + fo * fi * (rr - 1.0f));
    const float norm = fmaxf(fmaxf(burley_albedo(mu_o, l.r), burley_albedo(mu_i, l.r)), 1.0f);
    const float3 f = l.c * (FRAC_1_PI * burley / norm) + l.sheen * schlick_weight(cos_d);
    const float3 one = make_float3(1.0f, 1.0f, 1.0f);
    return f * (one - lerp3(l.f0, one, schlick_weight(fminf(mu_o, mu_i))));
}

/// Mirrors `Principled::eval`.
__device__ __noinline__ float3 principled_eval(Principled p, float3 wo, float3 wi) {
    const PrincipledLobes l = principled_lobes(p);
    const float mu_o = fabsf(wo.z), mu_i = fabsf(wi.z);
    if (mu_o == 0.0f || mu_i == 0.0f) return zero3();
    const float under = 1.0f - l.coat * coat_fresnel(fminf(mu_o, mu_i));
    if (!same_hemisphere(wo, wi)) {
        if (l.w_glass == 0.0f) return zero3();
        const float3 t = dielectric_eval(l.eta, l.mf, wo, wi);
        return t * sqrt3(l.c) * (l.w_glass * under);
    }
    float3 wh = wo + wi;
    if (length_squared3(wh) == 0.0f) return zero3();
    wh = normalize3(wh);
    const float cos_d = dot3(wo, wh);
    // The half vector on the distributions' (upper) side.
    const float3 wm = wh * signumf(wh.z);
    float3 f = zero3();
    if (l.w_diffuse > 0.0f) f = f + principled_diffuse(l, mu_o, mu_i, cos_d) * l.w_diffuse;
    if (!tr_effectively_smooth(l.mf)) {
        const float3 w_opaque = make_float3(l.w_opaque, l.w_opaque, l.w_opaque);
        const float3 opaque = lerp3(l.k0, w_opaque, schlick_weight(cos_d));
        const float glass = l.w_glass > 0.0f ? l.w_glass * fr_dielectric(dot3(wo, wm), l.eta) : 0.0f;
        f = f + (opaque + make_float3(glass, glass, glass)) *
                    (tr_d(l.mf, wm) * tr_g(l.mf, wo, wi) / (4.0f * mu_o * mu_i));
    }
    f = f * under;
    if (l.coat > 0.0f) {
        const TrowbridgeReitz coat = trowbridge_reitz(0.25f, 0.25f);
        const float g = tr_g1(coat, wo) * tr_g1(coat, wi);
        const float v = l.coat * gtr1(wm.z, l.coat_alpha) * coat_fresnel(cos_d) * g / (4.0f * mu_o * mu_i);
        f = f + make_float3(v, v, v);
    }
    return f;
}

/// Mirrors `Principled::pdf`.
__device__ __noinline__ float principled_pdf(Principled p, float3 wo, float3 wi) {
    const PrincipledLobes l = principled_lobes(p);
    const float4 w = principled_weights(l, wo);
    const float total = w.x + w.y + w.z + w.w;
    if (total == 0.0f || wo.z == 0.0f || wi.z == 0.0f) return 0.0f;
    const float glass = w.z > 0.0f ? w.z * dielectric_pdf(l.eta, l.mf, wo, wi) : 0.0f;
    if (!same_hemisphere(wo, wi)) return glass / total;
    float pdf = glass + w.x * cosine_hemisphere_pdf(fabsf(wi.z));
    if (w.y > 0.0f) pdf += w.y * conductor_pdf(l.mf, wo, wi);
    if (w.w > 0.0f) {
        const float3 wh = wo + wi;
        if (length_squared3(wh) > 0.0f) {
            const float3 wm = normalize3(wh) * signumf(wh.z);
            pdf += w.w * gtr1(wm.z, l.coat_alpha) * wm.z / (4.0f * fabsf(dot3(wo, wm)));
        }
    }
    return pdf / total;
}

/// Mirrors `Principled::sample`; false for `None`.
__device__ __noinline__ bool principled_sample(Principled p, float3 wo, float uc, float2 u, BsdfSample* out) {
    if (wo.z == 0.0f) return false;
    const PrincipledLobes l = principled_lobes(p);
    const float4 w = principled_weights(l, wo);
    const float total = w.x + w.y + w.z + w.w;
    if (total <= 0.0f) return false;
    const float x = uc * total;
    const float mu_o = fabsf(wo.z);
    float3 wi;
    float eta = 1.0f;
    if (x < w.x) {
        wi = sample_cosine_hemisphere(u);
        if (wo.z < 0.0f) wi.z = -wi.z;
    } else if (x < w.x + w.y) {
        if (tr_effectively_smooth(l.mf)) {
            // A mirror with the opaque specular's Fresnel at the macro normal.
            const float3 mirror = make_float3(-wo.x, -wo.y, wo.z);
            const float3 w_opaque = make_float3(l.w_opaque, l.w_opaque, l.w_opaque);
            const float3 fr = lerp3(l.k0, w_opaque, schlick_weight(mu_o));
            const float under = 1.0f - l.coat * coat_fresnel(mu_o);
            *out = make_bsdf_sample(fr * (under / mu_o), mirror, w.y / total, 1.0f, true, false);
            return true;
        }
        wi = reflect3(wo, tr_sample_wm(l.mf, wo, u));
        // Reflection lobes must keep `wi` on `wo`'s side.
        if (!same_hemisphere(wo, wi)) return false;
    } else if (x < w.x + w.y + w.z) {
        const float u_glass = fminf((x - w.x - w.y) / w.z, PRINCIPLED_ONE_MINUS_EPSILON);
        BsdfSample s;
        if (!dielectric_sample(l.eta, l.mf, wo, u_glass, u, &s)) return false;
        if (s.delta) {
            const float3 tint = s.transmission ? sqrt3(l.c) : make_float3(1.0f, 1.0f, 1.0f);
            const float under = 1.0f - l.coat * coat_fresnel(fminf(mu_o, fabsf(s.wi.z)));
            s.f = s.f * tint * (l.w_glass * under);
            s.pdf = s.pdf * (w.z / total);
            *out = s;
            return true;
        }
        wi = s.wi;
        eta = s.eta;
    } else {
        const float3 wm = sample_gtr1(l.coat_alpha, u);
        wi = reflect3(wo, wo.z < 0.0f ? -wm : wm);
        if (!same_hemisphere(wo, wi)) return false;
    }
    if (wi.z == 0.0f) return false;
    *out = make_bsdf_sample(principled_eval(p, wo, wi), wi, principled_pdf(p, wo, wi), eta, false,
                            !same_hemisphere(wo, wi));
    return true;
}

/// Mirrors `Principled::is_delta`.
__device__ __noinline__ bool principled_is_delta(Principled p) {
    const PrincipledLobes l = principled_lobes(p);
    const bool rough_specular = !tr_effectively_smooth(l.mf) && l.w_opaque > 0.0f;
    const bool rough_glass = l.w_glass > 0.0f && !dielectric_is_specular(l.eta, l.mf);
    return !(l.w_diffuse > 0.0f || l.coat > 0.0f || rough_specular || rough_glass);
}
