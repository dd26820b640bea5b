// BSDFs: the mirror of `atoll_render::bsdf` (and its `fresnel`,
// `microfacet`, `conductor`, `dielectric` modules) with pbrt-v4 semantics.
// Conventions as in bsdf.rs: local shading frame with the normal along +z,
// `wo`/`wi` point away from the surface, `f` excludes the cosine, a
// dielectric's `eta` is inside/outside, transmission in radiance mode, delta
// lobes only through `bsdf_sample`. Every function names the Rust one it
// ports; the arithmetic is the same, operation by operation.
#pragma once

// The material kinds this module shades: all of them, unless the device
// compiles a shade kernel specialised to a scene's kinds (`-DATOLL_WITH_COATED=0`
// and the like; src/device.rs `ShadeFeatures`). The coated materials' random
// walks and the principled lobes cost the shade kernel about a hundred
// registers, and so occupancy, even in scenes none of whose hits take them.
// A kind compiled out is read from a record as no surface at all (the device
// only leaves out kinds its frame has no material of).
#ifndef ATOLL_WITH_COATED
#define ATOLL_WITH_COATED 1
#endif
#ifndef ATOLL_WITH_PRINCIPLED
#define ATOLL_WITH_PRINCIPLED 1
#endif
// The conductor base of the layered BSDF, apart from the coated kinds as a
// whole: scenes with coated diffuse surfaces alone keep the narrower walks.
#ifndef ATOLL_WITH_COATED_CONDUCTOR
#define ATOLL_WITH_COATED_CONDUCTOR 1
#endif
#ifndef ATOLL_WITH_HAIR
#define ATOLL_WITH_HAIR 1
#endif
#ifndef ATOLL_WITH_MEASURED
#define ATOLL_WITH_MEASURED 1
#endif
// Whether some hit may carry a tangent for its frame (hair, measured BRDFs,
// anisotropic or textured roughness): without, every frame is about the
// normal alone and the shade kernel skips reading one.
#ifndef ATOLL_WITH_TANGENTS
#define ATOLL_WITH_TANGENTS 1
#endif

#include "common.cuh"
#include "materials.cuh"
#include "record.cuh"
#include "sampling.cuh"

// ---------------------------------------------------------------------------
// Frame (bsdf.rs `Frame`)
// ---------------------------------------------------------------------------

/// An orthonormal basis around a unit normal `z`. Mirrors `bsdf::Frame`.
struct Frame {
    float3 x, y, z;
};

/// Mirrors `Frame::from_z` (Duff et al. 2017).
__device__ __forceinline__ Frame frame_from_z(float3 n) {
    const float sign = copysignf(1.0f, n.z);
    const float a = -1.0f / (sign + n.z);
    const float b = n.x * n.y * a;
    Frame f;
    f.x = make_float3(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x);
    f.y = make_float3(b, sign + n.y * n.y * a, -n.y);
    f.z = n;
    return f;
}

/// Mirrors `Frame::to_local`.
/// Mirrors `Frame::from_xz`: `z` the unit normal, `x` along `x_hint` in
/// the plane normal to it (a hair's frame, x its axis).
__device__ __forceinline__ Frame frame_from_xz(float3 x_hint, float3 z) {
    const float3 x = normalize_or_zero3(x_hint - z * dot3(x_hint, z));
    if (is_zero3(x) || !is_finite3(x)) return frame_from_z(z);
    Frame f;
    f.x = x;
    f.y = cross3(z, x);
    f.z = z;
    return f;
}

__device__ __forceinline__ float3 frame_to_local(const Frame& f, float3 v) {
    return make_float3(dot3(v, f.x), dot3(v, f.y), dot3(v, f.z));
}

/// Mirrors `Frame::from_local`: `x*v.x + y*v.y + z*v.z`.
__device__ __forceinline__ float3 frame_from_local(const Frame& f, float3 v) {
    return f.x * v.x + f.y * v.y + f.z * v.z;
}

/// Mirrors `bsdf::same_hemisphere`.
__device__ __forceinline__ bool same_hemisphere(float3 a, float3 b) { return a.z * b.z > 0.0f; }

// ---------------------------------------------------------------------------
// Fresnel and the laws of reflection/refraction (bsdf/fresnel.rs)
// ---------------------------------------------------------------------------

/// Mirrors `fresnel::reflect`: `-wo + 2 (wo.n) n`.
__device__ __forceinline__ float3 reflect3(float3 wo, float3 n) { return -wo + 2.0f * dot3(wo, n) * n; }

/// Mirrors `fresnel::refract`. Returns false on total internal reflection;
/// else writes the transmitted direction and the relative index used.
__device__ __forceinline__ bool refract3(float3 wi, float3 n, float eta, float3* wt, float* etap) {
    float cos_i = dot3(n, wi);
    if (cos_i < 0.0f) {
        eta = 1.0f / eta;
        cos_i = -cos_i;
        n = -n;
    }
    // Snell's law in terms of squared sines.
    const float sin2_i = fmaxf(1.0f - cos_i * cos_i, 0.0f);
    const float sin2_t = sin2_i / (eta * eta);
    if (sin2_t >= 1.0f) return false;
    const float cos_t = sqrtf(fmaxf(1.0f - sin2_t, 0.0f));
    *wt = -wi / eta + (cos_i / eta - cos_t) * n;
    *etap = eta;
    return true;
}

/// Mirrors `fresnel::fr_dielectric`.
__device__ __forceinline__ float fr_dielectric(float cos_theta_i, float eta) {
    float cos_i = clampf(cos_theta_i, -1.0f, 1.0f);
    if (cos_i < 0.0f) {
        eta = 1.0f / eta;
        cos_i = -cos_i;
    }
    const float sin2_i = 1.0f - cos_i * cos_i;
    const float sin2_t = sin2_i / (eta * eta);
    if (sin2_t >= 1.0f) return 1.0f;
    const float cos_t = sqrtf(fmaxf(1.0f - sin2_t, 0.0f));
    const float r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    const float r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return (r_parl * r_parl + r_perp * r_perp) / 2.0f;
}

/// Mirrors fresnel.rs's private `Complex`.
struct Complex {
    float re, im;
};

__device__ __forceinline__ Complex cplx(float re, float im) {
    Complex c;
    c.re = re;
    c.im = im;
    return c;
}
__device__ __forceinline__ Complex cadd(Complex a, Complex o) { return cplx(a.re + o.re, a.im + o.im); }
__device__ __forceinline__ Complex csub(Complex a, Complex o) { return cplx(a.re - o.re, a.im - o.im); }
__device__ __forceinline__ Complex cmul(Complex a, Complex o) {
    return cplx(a.re * o.re - a.im * o.im, a.re * o.im + a.im * o.re);
}
__device__ __forceinline__ Complex cscale(Complex a, float s) { return cplx(a.re * s, a.im * s); }
/// Squared magnitude (pbrt's `norm`).
__device__ __forceinline__ float cnorm(Complex a) { return a.re * a.re + a.im * a.im; }
__device__ __forceinline__ Complex cdiv(Complex a, Complex o) {
    const float s = 1.0f / cnorm(o);
    return cplx((a.re * o.re + a.im * o.im) * s, (a.im * o.re - a.re * o.im) * s);
}
/// Mirrors `Complex::sqrt` (pbrt-v4's `pstd::sqrt(complex)`).
__device__ __forceinline__ Complex csqrt(Complex a) {
    const float n = sqrtf(cnorm(a));
    if (n == 0.0f) return cplx(0.0f, 0.0f);
    const float t1 = sqrtf(0.5f * (n + fabsf(a.re)));
    const float t2 = 0.5f * a.im / t1;
    if (a.re >= 0.0f) return cplx(t1, t2);
    return cplx(fabsf(t2), copysignf(t1, a.im));
}

/// Mirrors `fresnel::fr_complex`.
__device__ __forceinline__ float fr_complex(float cos_theta_i, float eta_re, float k) {
    const float cos_i = clampf(cos_theta_i, 0.0f, 1.0f);
    const Complex eta = cplx(eta_re, k);
    const float sin2_i = 1.0f - cos_i * cos_i;
    const Complex sin2_t = cdiv(cplx(sin2_i, 0.0f), cmul(eta, eta));
    const Complex cos_t = csqrt(csub(cplx(1.0f, 0.0f), sin2_t));
    const Complex ci = cplx(cos_i, 0.0f);
    const Complex eci = cscale(eta, cos_i);
    const Complex r_parl = cdiv(csub(eci, cos_t), cadd(eci, cos_t));
    const Complex ect = cmul(eta, cos_t);
    const Complex r_perp = cdiv(csub(ci, ect), cadd(ci, ect));
    return (cnorm(r_parl) + cnorm(r_perp)) / 2.0f;
}

/// Mirrors `fresnel::fr_complex_rgb`.
__device__ __forceinline__ float3 fr_complex_rgb(float cos_theta_i, float3 eta, float3 k) {
    return make_float3(fr_complex(cos_theta_i, eta.x, k.x), fr_complex(cos_theta_i, eta.y, k.y),
                       fr_complex(cos_theta_i, eta.z, k.z));
}

// ---------------------------------------------------------------------------
// Trowbridge-Reitz (GGX) microfacet distribution (bsdf/microfacet.rs)
// ---------------------------------------------------------------------------

/// Mirrors `microfacet::TrowbridgeReitz`.
struct TrowbridgeReitz {
    float alpha_x, alpha_y;
};

/// Mirrors `TrowbridgeReitz::effectively_smooth`.
__device__ __forceinline__ bool tr_effectively_smooth(TrowbridgeReitz d) {
    return fmaxf(d.alpha_x, d.alpha_y) < SMOOTH_ALPHA;
}

/// Mirrors `TrowbridgeReitz::new` (alphas clamped to 1e-4 when rough).
__device__ __forceinline__ TrowbridgeReitz trowbridge_reitz(float alpha_x, float alpha_y) {
    TrowbridgeReitz d;
    d.alpha_x = alpha_x;
    d.alpha_y = alpha_y;
    if (!tr_effectively_smooth(d)) {
        d.alpha_x = fmaxf(d.alpha_x, 1e-4f);
        d.alpha_y = fmaxf(d.alpha_y, 1e-4f);
    }
    return d;
}

/// Mirrors `TrowbridgeReitz::d`.
__device__ __forceinline__ float tr_d(TrowbridgeReitz d, float3 wm) {
    const float sx = wm.x / d.alpha_x;
    const float sy = wm.y / d.alpha_y;
    const float q = sx * sx + sy * sy + wm.z * wm.z;
    return 1.0f / (PI * d.alpha_x * d.alpha_y * q * q);
}

/// Mirrors `TrowbridgeReitz::lambda`.
__device__ __forceinline__ float tr_lambda(TrowbridgeReitz d, float3 w) {
    const float ax = d.alpha_x * w.x;
    const float ay = d.alpha_y * w.y;
    const float a2_tan2 = (ax * ax + ay * ay) / (w.z * w.z);
    return (sqrtf(1.0f + a2_tan2) - 1.0f) / 2.0f;
}

/// Mirrors `TrowbridgeReitz::g1`.
__device__ __forceinline__ float tr_g1(TrowbridgeReitz d, float3 w) { return 1.0f / (1.0f + tr_lambda(d, w)); }

/// Mirrors `TrowbridgeReitz::g`.
__device__ __forceinline__ float tr_g(TrowbridgeReitz d, float3 wo, float3 wi) {
    return 1.0f / (1.0f + tr_lambda(d, wo) + tr_lambda(d, wi));
}

/// Mirrors `TrowbridgeReitz::pdf` (= `d_visible`).
__device__ __forceinline__ float tr_pdf(TrowbridgeReitz d, float3 w, float3 wm) {
    return tr_g1(d, w) / fabsf(w.z) * tr_d(d, wm) * fabsf(dot3(w, wm));
}

/// Mirrors `TrowbridgeReitz::sample_wm` (Heitz 2018 visible normals).
__device__ __forceinline__ float3 tr_sample_wm(TrowbridgeReitz d, float3 w, float2 u) {
    float3 wh = normalize3(make_float3(d.alpha_x * w.x, d.alpha_y * w.y, w.z));
    if (wh.z < 0.0f) wh = -wh;
    // Orthonormal basis around wh; at normal incidence any tangent works.
    const float3 t1 =
        wh.z < 0.99999f ? normalize3(cross3(make_float3(0.0f, 0.0f, 1.0f), wh)) : make_float3(1.0f, 0.0f, 0.0f);
    const float3 t2 = cross3(wh, t1);
    float2 p = sample_uniform_disk_polar(u);
    // Squash the lower half of the disk onto the visible hemisphere's projection.
    const float h = sqrtf(fmaxf(1.0f - p.x * p.x, 0.0f));
    const float s = (1.0f + wh.z) / 2.0f;
    p.y = (1.0f - s) * h + s * p.y;
    const float pz = sqrtf(fmaxf(1.0f - length_squared2(p), 0.0f));
    const float3 nh = p.x * t1 + p.y * t2 + pz * wh;
    return normalize3(make_float3(d.alpha_x * nh.x, d.alpha_y * nh.y, fmaxf(nh.z, 1e-6f)));
}

// ---------------------------------------------------------------------------
// The BSDF (bsdf.rs `Bsdf`, `BsdfSample`)
// ---------------------------------------------------------------------------

/// Mirrors `bsdf::Bsdf`. `kind` is a `MATERIAL_*` constant; the fields used
/// per kind: Diffuse `a` = reflectance; Conductor `a` = eta, `b` = k,
/// alphas; Dielectric `eta`, alphas; CoatedDiffuse `a` = reflectance, `b` =
/// albedo, the coating's `eta` and alphas, and the layer fields;
/// CoatedConductor as CoatedDiffuse but `a` = the conductor's eta, `p` =
/// (its k, its alpha_x), `base_alpha_y`; Principled `a` = base colour, `b` =
/// (metallic, roughness, transmission), `eta`, `alpha_x` = specular,
/// `alpha_y` = specular tint, `p` = (sheen, sheen tint, clearcoat, clearcoat
/// gloss); Hair `a` = sigma_a, `eta`, `alpha_x` = beta_m, `alpha_y` =
/// beta_n, `g` = the scales' tilt in degrees, `thickness` = the given
/// offset across the fibre. `MATERIAL_NONE` means "no BSDF" (Rust's `None` from
/// `bsdf_from_record`).
struct Bsdf {
    unsigned int kind;
    float3 a, b;
    float eta, alpha_x, alpha_y;
    // Coated kinds only (`layered::Coated`).
    float thickness, g;
    unsigned int max_depth, n_samples;
    // Principled and coated conductor only.
    float4 p;
    // Coated conductor only.
    float base_alpha_y;
#if ATOLL_WITH_MEASURED
    // Measured only: the BRDF's tables (measured.cuh).
    const float* table;
#endif
};

/// Mirrors `bsdf::BsdfSample`.
struct BsdfSample {
    float3 f;
    float3 wi;
    float pdf;
    float eta;
    bool delta;
    bool transmission;
};

__device__ __forceinline__ BsdfSample make_bsdf_sample(float3 f, float3 wi, float pdf, float eta, bool delta,
                                                       bool transmission) {
    BsdfSample s;
    s.f = f;
    s.wi = wi;
    s.pdf = pdf;
    s.eta = eta;
    s.delta = delta;
    s.transmission = transmission;
    return s;
}

/// Mirrors `material_coeffs::bsdf_from_record`; `measured` is the frame's
/// measured BRDFs (`FrameParams::measured`).
__device__ __forceinline__ Bsdf bsdf_from_record(const RayRecord& r, const float* measured) {
    Bsdf b;
    // The low byte: the high one names the hit surface's media.
    const unsigned int kind = r.material & 0xffu;
    b.kind = kind;
    b.a = zero3();
    b.b = zero3();
    b.eta = 0.0f;
    b.alpha_x = 0.0f;
    b.alpha_y = 0.0f;
    b.thickness = 0.0f;
    b.g = 0.0f;
    b.max_depth = 0u;
    b.n_samples = 0u;
    b.p = make_float4(0.0f, 0.0f, 0.0f, 0.0f);
    b.base_alpha_y = 0.0f;
#if ATOLL_WITH_MEASURED
    b.table = nullptr;
#endif
    if (kind == MATERIAL_DIFFUSE) {
        b.a = load_f16x3(&r.coeffs[COEFF_DIFFUSE_REFLECTANCE]);
    } else if (kind == MATERIAL_CONDUCTOR) {
        b.a = load_f16x3(&r.coeffs[COEFF_CONDUCTOR_ETA]);
        b.b = load_f16x3(&r.coeffs[COEFF_CONDUCTOR_K]);
        b.alpha_x = f16_to_f32(r.coeffs[COEFF_CONDUCTOR_ALPHA_X]);
        b.alpha_y = f16_to_f32(r.coeffs[COEFF_CONDUCTOR_ALPHA_Y]);
    } else if (kind == MATERIAL_DIELECTRIC) {
        b.eta = f16_to_f32(r.coeffs[COEFF_DIELECTRIC_ETA]);
        b.alpha_x = f16_to_f32(r.coeffs[COEFF_DIELECTRIC_ALPHA_X]);
        b.alpha_y = f16_to_f32(r.coeffs[COEFF_DIELECTRIC_ALPHA_Y]);
    } else if (kind == MATERIAL_SUBSURFACE) {
        // Where paths enter; where they leave, shading takes the exit lobe.
        b.kind = MATERIAL_DIELECTRIC;
        b.eta = f16_to_f32(r.coeffs[COEFF_SUBSURFACE_ETA]);
        b.alpha_x = f16_to_f32(r.coeffs[COEFF_SUBSURFACE_ALPHA_X]);
        b.alpha_y = f16_to_f32(r.coeffs[COEFF_SUBSURFACE_ALPHA_Y]);
    } else if (kind == MATERIAL_DIFFUSE_TRANSMISSION) {
        b.a = load_f16x3(&r.coeffs[COEFF_DIFFUSE_TRANSMISSION_REFLECTANCE]);
        b.b = load_f16x3(&r.coeffs[COEFF_DIFFUSE_TRANSMISSION_TRANSMITTANCE]);
    } else if (kind == MATERIAL_THIN_DIELECTRIC) {
        b.eta = f16_to_f32(r.coeffs[COEFF_THIN_DIELECTRIC_ETA]);
    } else if (ATOLL_WITH_COATED && kind == MATERIAL_COATED_DIFFUSE) {
        b.a = load_f16x3(&r.coeffs[COEFF_COATED_DIFFUSE_REFLECTANCE]);
        b.alpha_x = f16_to_f32(r.coeffs[COEFF_COATED_DIFFUSE_ALPHA_X]);
        b.alpha_y = f16_to_f32(r.coeffs[COEFF_COATED_DIFFUSE_ALPHA_Y]);
        b.eta = f16_to_f32(r.coeffs[COEFF_COATED_DIFFUSE_ETA]);
        b.thickness = f16_to_f32(r.coeffs[COEFF_COATED_DIFFUSE_THICKNESS]);
        b.b = load_f16x3(&r.coeffs[COEFF_COATED_DIFFUSE_ALBEDO]);
        b.g = f16_to_f32(r.coeffs[COEFF_COATED_DIFFUSE_G]);
        b.max_depth = (unsigned int)f16_to_f32(r.coeffs[COEFF_COATED_DIFFUSE_MAX_DEPTH]);
        b.n_samples = (unsigned int)f16_to_f32(r.coeffs[COEFF_COATED_DIFFUSE_N_SAMPLES]);
    } else if (ATOLL_WITH_COATED && ATOLL_WITH_COATED_CONDUCTOR && kind == MATERIAL_COATED_CONDUCTOR) {
        b.a = load_f16x3(&r.coeffs[COEFF_COATED_CONDUCTOR_ETA]);
        const float3 k = load_f16x3(&r.coeffs[COEFF_COATED_CONDUCTOR_K]);
        b.p = make_float4(k.x, k.y, k.z, f16_to_f32(r.coeffs[COEFF_COATED_CONDUCTOR_CONDUCTOR_ALPHA_X]));
        b.base_alpha_y = f16_to_f32(r.coeffs[COEFF_COATED_CONDUCTOR_CONDUCTOR_ALPHA_Y]);
        b.alpha_x = f16_to_f32(r.coeffs[COEFF_COATED_CONDUCTOR_INTERFACE_ALPHA_X]);
        b.alpha_y = f16_to_f32(r.coeffs[COEFF_COATED_CONDUCTOR_INTERFACE_ALPHA_Y]);
        b.eta = f16_to_f32(r.coeffs[COEFF_COATED_CONDUCTOR_INTERFACE_ETA]);
        b.thickness = f16_to_f32(r.coeffs[COEFF_COATED_CONDUCTOR_THICKNESS]);
        b.b = load_f16x3(&r.coeffs[COEFF_COATED_CONDUCTOR_ALBEDO]);
        b.g = f16_to_f32(r.coeffs[COEFF_COATED_CONDUCTOR_G]);
        b.max_depth = COATED_CONDUCTOR_MAX_DEPTH;
        b.n_samples = COATED_CONDUCTOR_N_SAMPLES;
    } else if (ATOLL_WITH_HAIR && kind == MATERIAL_HAIR) {
        b.a = load_f16x3(&r.coeffs[COEFF_HAIR_SIGMA_A]);
        b.eta = f16_to_f32(r.coeffs[COEFF_HAIR_ETA]);
        b.alpha_x = f16_to_f32(r.coeffs[COEFF_HAIR_BETA_M]);
        b.alpha_y = f16_to_f32(r.coeffs[COEFF_HAIR_BETA_N]);
        b.g = f16_to_f32(r.coeffs[COEFF_HAIR_ALPHA]);
        b.thickness = f16_to_f32(r.coeffs[COEFF_HAIR_OFFSET]);
    } else if (ATOLL_WITH_PRINCIPLED && kind == MATERIAL_PRINCIPLED) {
        b.a = load_f16x3(&r.coeffs[COEFF_PRINCIPLED_BASE_COLOR]);
        b.b = make_float3(f16_to_f32(r.coeffs[COEFF_PRINCIPLED_METALLIC]),
                          f16_to_f32(r.coeffs[COEFF_PRINCIPLED_ROUGHNESS]),
                          f16_to_f32(r.coeffs[COEFF_PRINCIPLED_TRANSMISSION]));
        b.alpha_x = f16_to_f32(r.coeffs[COEFF_PRINCIPLED_SPECULAR]);
        b.alpha_y = f16_to_f32(r.coeffs[COEFF_PRINCIPLED_SPECULAR_TINT]);
        b.p = make_float4(f16_to_f32(r.coeffs[COEFF_PRINCIPLED_SHEEN]),
                          f16_to_f32(r.coeffs[COEFF_PRINCIPLED_SHEEN_TINT]),
                          f16_to_f32(r.coeffs[COEFF_PRINCIPLED_CLEARCOAT]),
                          f16_to_f32(r.coeffs[COEFF_PRINCIPLED_CLEARCOAT_GLOSS]));
        b.eta = f16_to_f32(r.coeffs[COEFF_PRINCIPLED_ETA]);
#if ATOLL_WITH_MEASURED
    } else if (kind == MATERIAL_MEASURED && measured) {
        const unsigned int brdf = (unsigned int)f16_to_f32(r.coeffs[COEFF_MEASURED_BRDF]);
        b.table = measured + __float_as_uint(measured[brdf]);
#endif
    } else {
        b.kind = MATERIAL_NONE;
    }
    return b;
}

// --- conductor (bsdf/conductor.rs) ---

/// Mirrors `conductor::eval`.
__device__ __forceinline__ float3 conductor_eval(float3 eta, float3 k, TrowbridgeReitz mf, float3 wo, float3 wi) {
    if (!same_hemisphere(wo, wi) || tr_effectively_smooth(mf)) return zero3();
    const float cos_o = fabsf(wo.z), cos_i = fabsf(wi.z);
    float3 wm = wi + wo;
    if (cos_i == 0.0f || cos_o == 0.0f || length_squared3(wm) == 0.0f) return zero3();
    wm = normalize3(wm);
    const float3 f = fr_complex_rgb(fabsf(dot3(wo, wm)), eta, k);
    return f * (tr_d(mf, wm) * tr_g(mf, wo, wi) / (4.0f * cos_i * cos_o));
}

/// Mirrors `conductor::pdf`.
__device__ __forceinline__ float conductor_pdf(TrowbridgeReitz mf, float3 wo, float3 wi) {
    if (!same_hemisphere(wo, wi) || tr_effectively_smooth(mf) || wo.z == 0.0f) return 0.0f;
    float3 wm = wo + wi;
    if (length_squared3(wm) == 0.0f) return 0.0f;
    // Face forward so the normal is in the distribution's (upper) hemisphere.
    wm = normalize3(wm) * signumf(wm.z);
    return tr_pdf(mf, wo, wm) / (4.0f * fabsf(dot3(wo, wm)));
}

/// Mirrors `conductor::sample`; false for Rust's `None`.
__device__ __forceinline__ bool conductor_sample(float3 eta, float3 k, TrowbridgeReitz mf, float3 wo, float2 u,
                                                 BsdfSample* out) {
    if (wo.z == 0.0f) return false;
    if (tr_effectively_smooth(mf)) {
        const float3 wi = make_float3(-wo.x, -wo.y, wo.z);
        const float c = fabsf(wi.z);
        const float3 f = fr_complex_rgb(c, eta, k) / c;
        *out = make_bsdf_sample(f, wi, 1.0f, 1.0f, true, false);
        return true;
    }
    const float3 wm = tr_sample_wm(mf, wo, u);
    const float3 wi = reflect3(wo, wm);
    if (!same_hemisphere(wo, wi)) return false;
    const float cos_o = fabsf(wo.z), cos_i = fabsf(wi.z);
    if (cos_i == 0.0f) return false;
    const float pdf = tr_pdf(mf, wo, wm) / (4.0f * fabsf(dot3(wo, wm)));
    const float3 f =
        fr_complex_rgb(fabsf(dot3(wo, wm)), eta, k) * (tr_d(mf, wm) * tr_g(mf, wo, wi) / (4.0f * cos_i * cos_o));
    *out = make_bsdf_sample(f, wi, pdf, 1.0f, false, false);
    return true;
}

// --- dielectric (bsdf/dielectric.rs) ---

/// Mirrors `dielectric::is_specular`.
__device__ __forceinline__ bool dielectric_is_specular(float eta, TrowbridgeReitz mf) {
    return eta == 1.0f || tr_effectively_smooth(mf);
}

/// Mirror dielectric.rs's `Mode` (pbrt's `TransportMode`).
inline constexpr int MODE_RADIANCE = 0;
inline constexpr int MODE_IMPORTANCE = 1;
/// Mirror dielectric.rs's `Lobes` (pbrt's `BxDFReflTransFlags`).
inline constexpr int LOBES_ALL = 0;
inline constexpr int LOBES_REFLECTION = 1;
inline constexpr int LOBES_TRANSMISSION = 2;

/// Mirrors `Lobes::weights`: the Fresnel weights with the excluded lobe's zeroed.
__device__ __forceinline__ void dielectric_lobe_weights(int lobes, float r, float t, float* pr, float* pt) {
    *pr = lobes == LOBES_TRANSMISSION ? 0.0f : r;
    *pt = lobes == LOBES_REFLECTION ? 0.0f : t;
}

/// Mirrors dielectric.rs's `radiance_scaled`.
__device__ __forceinline__ float dielectric_radiance_scaled(float f, float etap, int mode) {
    return mode == MODE_RADIANCE ? f / (etap * etap) : f;
}

/// Mirrors dielectric.rs's `half_vector`; false for `None`.
__device__ __forceinline__ bool dielectric_half_vector(float eta, float3 wo, float3 wi, float3* wm_out,
                                                       float* etap_out, bool* reflect_out) {
    const float cos_o = wo.z, cos_i = wi.z;
    const bool reflect = cos_i * cos_o > 0.0f;
    const float etap = reflect ? 1.0f : (cos_o > 0.0f ? eta : 1.0f / eta);
    float3 wm = wi * etap + wo;
    if (cos_i == 0.0f || cos_o == 0.0f || length_squared3(wm) == 0.0f) return false;
    wm = normalize3(wm) * signumf(wm.z);
    // Discard back-facing microfacets.
    if (dot3(wm, wi) * cos_i < 0.0f || dot3(wm, wo) * cos_o < 0.0f) return false;
    *wm_out = wm;
    *etap_out = etap;
    *reflect_out = reflect;
    return true;
}

/// Mirrors `dielectric::eval_with`.
__device__ __forceinline__ float3 dielectric_eval_with(float eta, TrowbridgeReitz mf, float3 wo, float3 wi, int mode) {
    if (dielectric_is_specular(eta, mf)) return zero3();
    float3 wm;
    float etap;
    bool reflect;
    if (!dielectric_half_vector(eta, wo, wi, &wm, &etap, &reflect)) return zero3();
    const float fr = fr_dielectric(dot3(wo, wm), eta);
    const float cos_o = wo.z, cos_i = wi.z;
    float f;
    if (reflect) {
        f = tr_d(mf, wm) * tr_g(mf, wo, wi) * fr / fabsf(4.0f * cos_i * cos_o);
    } else {
        const float sq = dot3(wi, wm) + dot3(wo, wm) / etap;
        const float denom = sq * sq * cos_i * cos_o;
        const float ft = tr_d(mf, wm) * (1.0f - fr) * tr_g(mf, wo, wi) * fabsf(dot3(wi, wm) * dot3(wo, wm) / denom);
        f = dielectric_radiance_scaled(ft, etap, mode);
    }
    return make_float3(f, f, f);
}

/// Mirrors `dielectric::eval` (radiance mode).
__device__ __forceinline__ float3 dielectric_eval(float eta, TrowbridgeReitz mf, float3 wo, float3 wi) {
    return dielectric_eval_with(eta, mf, wo, wi, MODE_RADIANCE);
}

/// Mirrors `dielectric::pdf_with`.
__device__ __forceinline__ float dielectric_pdf_with(float eta, TrowbridgeReitz mf, float3 wo, float3 wi, int lobes) {
    if (dielectric_is_specular(eta, mf)) return 0.0f;
    float3 wm;
    float etap;
    bool reflect;
    if (!dielectric_half_vector(eta, wo, wi, &wm, &etap, &reflect)) return 0.0f;
    const float r = fr_dielectric(dot3(wo, wm), eta);
    float pr, pt;
    dielectric_lobe_weights(lobes, r, 1.0f - r, &pr, &pt);
    if (pr == 0.0f && pt == 0.0f) return 0.0f;
    if (reflect) return tr_pdf(mf, wo, wm) / (4.0f * fabsf(dot3(wo, wm))) * pr / (pr + pt);
    // Jacobian of the generalised half vector with respect to wi.
    const float sq = dot3(wi, wm) + dot3(wo, wm) / etap;
    const float denom = sq * sq;
    const float dwm_dwi = fabsf(dot3(wi, wm)) / denom;
    return tr_pdf(mf, wo, wm) * dwm_dwi * pt / (pr + pt);
}

/// Mirrors `dielectric::pdf`.
__device__ __forceinline__ float dielectric_pdf(float eta, TrowbridgeReitz mf, float3 wo, float3 wi) {
    return dielectric_pdf_with(eta, mf, wo, wi, LOBES_ALL);
}

/// Mirrors `dielectric::sample_with`; false for `None`.
__device__ __forceinline__ bool dielectric_sample_with(float eta, TrowbridgeReitz mf, float3 wo, float uc, float2 u,
                                                       int mode, int lobes, BsdfSample* out) {
    if (wo.z == 0.0f) return false;
    if (eta == 1.0f) {
        // Index-matched: the surface is invisible, light passes straight on
        // (pbrt's R = 0, T = 1).
        if (lobes == LOBES_REFLECTION) return false;
        const float3 wi = -wo;
        const float v = 1.0f / fabsf(wi.z);
        *out = make_bsdf_sample(make_float3(v, v, v), wi, 1.0f, 1.0f, true, true);
        return true;
    }
    if (tr_effectively_smooth(mf)) {
        const float r = fr_dielectric(wo.z, eta);
        const float t = 1.0f - r;
        float pr, pt;
        dielectric_lobe_weights(lobes, r, t, &pr, &pt);
        if (pr == 0.0f && pt == 0.0f) return false;
        if (uc < pr / (pr + pt)) {
            const float3 wi = make_float3(-wo.x, -wo.y, wo.z);
            const float v = r / fabsf(wi.z);
            *out = make_bsdf_sample(make_float3(v, v, v), wi, pr / (pr + pt), 1.0f, true, false);
            return true;
        }
        float3 wi;
        float etap;
        if (!refract3(wo, make_float3(0.0f, 0.0f, 1.0f), eta, &wi, &etap)) return false;
        if (wi.z == 0.0f) return false;
        const float v = dielectric_radiance_scaled(t / fabsf(wi.z), etap, mode);
        *out = make_bsdf_sample(make_float3(v, v, v), wi, pt / (pr + pt), etap, true, true);
        return true;
    }

    const float3 wm = tr_sample_wm(mf, wo, u);
    const float r = fr_dielectric(dot3(wo, wm), eta);
    const float t = 1.0f - r;
    float pr, pt;
    dielectric_lobe_weights(lobes, r, t, &pr, &pt);
    if (pr == 0.0f && pt == 0.0f) return false;
    const float p_reflect = pr / (pr + pt);
    if (uc < p_reflect) {
        const float3 wi = reflect3(wo, wm);
        if (!same_hemisphere(wo, wi)) return false;
        const float pdf = tr_pdf(mf, wo, wm) / (4.0f * fabsf(dot3(wo, wm))) * p_reflect;
        const float f = tr_d(mf, wm) * tr_g(mf, wo, wi) * r / fabsf(4.0f * wi.z * wo.z);
        *out = make_bsdf_sample(make_float3(f, f, f), wi, pdf, 1.0f, false, false);
        return true;
    }
    float3 wi;
    float etap;
    if (!refract3(wo, wm, eta, &wi, &etap)) return false;
    if (same_hemisphere(wo, wi) || wi.z == 0.0f) return false;
    const float sq = dot3(wi, wm) + dot3(wo, wm) / etap;
    const float denom = sq * sq;
    const float dwm_dwi = fabsf(dot3(wi, wm)) / denom;
    const float pdf = tr_pdf(mf, wo, wm) * dwm_dwi * (pt / (pr + pt));
    const float ft =
        t * tr_d(mf, wm) * tr_g(mf, wo, wi) * fabsf(dot3(wi, wm) * dot3(wo, wm) / (wi.z * wo.z * denom));
    const float f = dielectric_radiance_scaled(ft, etap, mode);
    *out = make_bsdf_sample(make_float3(f, f, f), wi, pdf, etap, false, true);
    return true;
}

/// Mirrors `dielectric::sample`; false for `None`.
__device__ __forceinline__ bool dielectric_sample(float eta, TrowbridgeReitz mf, float3 wo, float uc, float2 u,
                                                  BsdfSample* out) {
    return dielectric_sample_with(eta, mf, wo, uc, u, MODE_RADIANCE, LOBES_ALL, out);
}

// --- diffuse transmission and thin dielectric (bsdf/thin.rs) ---

__device__ __forceinline__ float max_component3(float3 v) { return fmaxf(v.x, fmaxf(v.y, v.z)); }

/// Mirrors `thin::sample_diffuse_transmission`.
__device__ __forceinline__ bool diffuse_transmission_sample(float3 r, float3 t, float3 wo, float uc, float2 u,
                                                           BsdfSample* out) {
    const float pr = max_component3(r), pt = max_component3(t);
    if (pr + pt == 0.0f) return false;
    float3 wi = sample_cosine_hemisphere(u);
    if (uc < pr / (pr + pt)) {
        if (wo.z < 0.0f) wi.z = -wi.z;
        const float pdf = pr / (pr + pt) * cosine_hemisphere_pdf(fabsf(wi.z));
        *out = make_bsdf_sample(r * FRAC_1_PI, wi, pdf, 1.0f, false, false);
    } else {
        if (wo.z > 0.0f) wi.z = -wi.z;
        const float pdf = pt / (pr + pt) * cosine_hemisphere_pdf(fabsf(wi.z));
        *out = make_bsdf_sample(t * FRAC_1_PI, wi, pdf, 1.0f, false, true);
    }
    return true;
}

/// Mirrors `Bsdf::pdf` for diffuse transmission.
__device__ __forceinline__ float diffuse_transmission_pdf(float3 r, float3 t, float3 wo, float3 wi) {
    const float pr = max_component3(r), pt = max_component3(t);
    if (pr + pt == 0.0f) return 0.0f;
    const float lobe = same_hemisphere(wo, wi) ? pr : pt;
    return lobe / (pr + pt) * cosine_hemisphere_pdf(fabsf(wi.z));
}

/// Mirrors `thin::thin_reflectance`.
__device__ __forceinline__ float thin_reflectance(float cos_theta, float eta) {
    const float r = fr_dielectric(cos_theta, eta);
    if (r < 1.0f) {
        const float t = 1.0f - r;
        return r + t * t * r / (1.0f - r * r);
    }
    return r;
}

/// Mirrors `thin::sample_thin_dielectric`.
__device__ __forceinline__ bool thin_dielectric_sample(float eta, float3 wo, float uc, BsdfSample* out) {
    const float r = thin_reflectance(fabsf(wo.z), eta);
    const float t = 1.0f - r;
    if (uc < r / (r + t)) {
        const float3 wi = make_float3(-wo.x, -wo.y, wo.z);
        const float f = r / fabsf(wi.z);
        *out = make_bsdf_sample(make_float3(f, f, f), wi, r / (r + t), 1.0f, true, false);
    } else {
        const float3 wi = -wo;
        const float f = t / fabsf(wi.z);
        *out = make_bsdf_sample(make_float3(f, f, f), wi, t / (r + t), 1.0f, true, true);
    }
    return true;
}

// --- Lambertian reflection (bsdf.rs `Bsdf::Diffuse`) ---

/// Mirrors `Bsdf::sample`'s diffuse arm: cosine-weighted on wo's side (pbrt
/// flips z for wo below).
__device__ __forceinline__ BsdfSample diffuse_sample(float3 r, float3 wo, float2 u) {
    float3 wi = sample_cosine_hemisphere(u);
    if (wo.z < 0.0f) wi.z = -wi.z;
    const float pdf = cosine_hemisphere_pdf(fabsf(wi.z));
    return make_bsdf_sample(r * FRAC_1_PI, wi, pdf, 1.0f, false, false);
}

// --- coated diffuse and coated conductor (bsdf/layered.rs, in layered.cuh) ---

/// Mirrors `layered::Coated`: the `Bsdf` fields of a coated kind, passed by
/// value to the layered functions. `conductor` picks the base: the
/// Lambertian `base_a` (reflectance), or the conductor `base_a` (eta),
/// `base_k`, `base_alpha_*` with its index relative to the coating (divided
/// once here, where `Coated::base` divides at every use).
struct Coated {
    float3 base_a, albedo;
    float eta, alpha_x, alpha_y, thickness, g;
    unsigned int max_depth, n_samples;
    bool conductor;
    float3 base_k;
    float base_alpha_x, base_alpha_y;
};

__device__ __forceinline__ Coated coated_of(const Bsdf& b) {
    Coated c;
    c.base_a = b.a;
    c.albedo = b.b;
    c.eta = b.eta;
    c.alpha_x = b.alpha_x;
    c.alpha_y = b.alpha_y;
    c.thickness = b.thickness;
    c.g = b.g;
    c.max_depth = b.max_depth;
    c.n_samples = b.n_samples;
    c.conductor = ATOLL_WITH_COATED_CONDUCTOR && b.kind == MATERIAL_COATED_CONDUCTOR;
    c.base_k = make_float3(b.p.x, b.p.y, b.p.z);
    if (c.conductor) {
        c.base_a = c.base_a / c.eta;
        c.base_k = c.base_k / c.eta;
    }
    c.base_alpha_x = b.p.w;
    c.base_alpha_y = b.base_alpha_y;
    return c;
}

__device__ __forceinline__ bool is_coated(unsigned int kind) {
    return kind == MATERIAL_COATED_DIFFUSE || (ATOLL_WITH_COATED_CONDUCTOR && kind == MATERIAL_COATED_CONDUCTOR);
}

// Random walks with many live values: kept out of line (layered.cuh) so the
// shade kernel's other materials keep their register budget.
__device__ __noinline__ float3 coated_eval(Coated c, float3 wo, float3 wi);
__device__ __noinline__ float coated_pdf(Coated c, float3 wo, float3 wi);
__device__ __noinline__ bool coated_sample(Coated c, float3 wo, float uc, float2 u, BsdfSample* out);

/// Mirrors `Coated::is_delta`.
__device__ __forceinline__ bool coated_is_delta(const Bsdf& b) {
    const bool base_is_delta = ATOLL_WITH_COATED_CONDUCTOR && b.kind == MATERIAL_COATED_CONDUCTOR
                                   ? tr_effectively_smooth(trowbridge_reitz(b.p.w, b.base_alpha_y))
                                   : is_zero3(b.a);
    return tr_effectively_smooth(trowbridge_reitz(b.alpha_x, b.alpha_y)) && base_is_delta && is_zero3(b.b);
}

// --- principled (bsdf/principled.rs, in principled.cuh) ---

/// Mirrors `principled::Principled`: the `Bsdf` fields of a principled
/// kind, passed by value to the principled functions.
struct Principled {
    float3 base_color;
    float metallic, roughness, specular, specular_tint, sheen, sheen_tint, clearcoat, clearcoat_gloss, transmission,
        eta;
};

__device__ __forceinline__ Principled principled_of(const Bsdf& b) {
    Principled p;
    p.base_color = b.a;
    p.metallic = b.b.x;
    p.roughness = b.b.y;
    p.transmission = b.b.z;
    p.specular = b.alpha_x;
    p.specular_tint = b.alpha_y;
    p.sheen = b.p.x;
    p.sheen_tint = b.p.y;
    p.clearcoat = b.p.z;
    p.clearcoat_gloss = b.p.w;
    p.eta = b.eta;
    return p;
}

// Four lobes with their own weights and Fresnel terms: kept out of line
// (principled.cuh) so the shade kernel's other materials keep their
// register budget.
__device__ __noinline__ float3 principled_eval(Principled p, float3 wo, float3 wi);
__device__ __noinline__ float principled_pdf(Principled p, float3 wo, float3 wi);
__device__ __noinline__ bool principled_sample(Principled p, float3 wo, float uc, float2 u, BsdfSample* out);
__device__ __noinline__ bool principled_is_delta(Principled p);

// --- hair (bsdf/hair.rs, in hair.cuh) ---

/// Mirrors `hair::P_MAX`.
inline constexpr int HAIR_P_MAX = 3;
__device__ __forceinline__ float hair_safe_sqrt(float x) { return sqrtf(fmaxf(x, 0.0f)); }

/// `x^n` by repeated multiplication (Rust's `powi`).
__device__ __forceinline__ float hair_powi(float x, int n) {
    float r = 1.0f;
    for (int i = 0; i < n; ++i) r *= x;
    return r;
}

/// Mirrors `hair::Hair`: the parameters and the per-lobe constants.
struct Hair {
    float3 sigma_a;
    float eta;
    float given_offset;
    float v[HAIR_P_MAX + 1];
    float s;
    float sin_2k_alpha[3], cos_2k_alpha[3];
};

/// Mirrors `Hair::new(..).with_offset(..)` (`a` = sigma_a, `alpha_x` =
/// beta_m, `alpha_y` = beta_n, `g` = alpha in degrees, `thickness` = the
/// given offset; `bsdf_from_record`).
__device__ __forceinline__ Hair hair_of(const Bsdf& b) {
    Hair h;
    h.sigma_a = b.a;
    h.eta = b.eta;
    h.given_offset = b.thickness;
    const float bm = b.alpha_x;
    const float v0 = hair_powi(0.726f * bm + 0.812f * bm * bm + 3.7f * hair_powi(bm, 20), 2);
    h.v[0] = v0;
    h.v[1] = 0.25f * v0;
    h.v[2] = 4.0f * v0;
    h.v[3] = 4.0f * v0;
    const float bn = b.alpha_y;
    const float sqrt_pi_over_8 = 0.62665707f;
    h.s = sqrt_pi_over_8 * (0.265f * bn + 1.194f * bn * bn + 5.372f * hair_powi(bn, 22));
    h.sin_2k_alpha[0] = sinf(b.g * (PI / 180.0f));
    h.cos_2k_alpha[0] = hair_safe_sqrt(1.0f - h.sin_2k_alpha[0] * h.sin_2k_alpha[0]);
    for (int i = 1; i < 3; ++i) {
        h.sin_2k_alpha[i] = 2.0f * h.cos_2k_alpha[i - 1] * h.sin_2k_alpha[i - 1];
        h.cos_2k_alpha[i] =
            h.cos_2k_alpha[i - 1] * h.cos_2k_alpha[i - 1] - h.sin_2k_alpha[i - 1] * h.sin_2k_alpha[i - 1];
    }
    return h;
}

// Three lobes and a remainder, each with Bessel and logistic terms: kept
// out of line (hair.cuh) so the shade kernel's other materials keep their
// register budget.
__device__ __noinline__ float3 hair_eval(Hair h, float3 wo, float3 wi);
__device__ __noinline__ float hair_pdf(Hair h, float3 wo, float3 wi);
__device__ __noinline__ bool hair_sample(Hair h, float3 wo, float uc, float2 u, BsdfSample* out);

#if ATOLL_WITH_MEASURED
#include "measured.cuh"
#endif

// --- dispatch (bsdf.rs `impl Bsdf`) ---

/// Mirrors `material_coeffs::shading_frame`: about the shading normal, with
/// x along the tangent the hit carries where its kind has one
/// (`material_layout::tangent_slot`; zero where the hit wrote none). Each
/// kind reads its own constant slots: indexing the record's coefficients
/// by a variable slot would put the record in local memory.
__device__ __forceinline__ Frame shading_frame(const RayRecord& r) {
    const float3 n = normalize_or_zero3(load_f16x3(r.shading_normal));
    // No material of the frame turns its lobes about the normal: no hit
    // carries a tangent.
    if (!ATOLL_WITH_TANGENTS) return frame_from_z(n);
    const unsigned int kind = r.material & 0xffu;
    float3 tangent = zero3();
    if (kind == MATERIAL_CONDUCTOR) tangent = load_f16x3(&r.coeffs[COEFF_CONDUCTOR_TANGENT]);
    if (kind == MATERIAL_DIELECTRIC) tangent = load_f16x3(&r.coeffs[COEFF_DIELECTRIC_TANGENT]);
    if (kind == MATERIAL_SUBSURFACE) tangent = load_f16x3(&r.coeffs[COEFF_SUBSURFACE_TANGENT]);
    if (ATOLL_WITH_COATED && kind == MATERIAL_COATED_DIFFUSE) tangent = load_f16x3(&r.coeffs[COEFF_COATED_DIFFUSE_TANGENT]);
    if (ATOLL_WITH_HAIR && kind == MATERIAL_HAIR) tangent = load_f16x3(&r.coeffs[COEFF_HAIR_TANGENT]);
    if (ATOLL_WITH_MEASURED && kind == MATERIAL_MEASURED) tangent = load_f16x3(&r.coeffs[COEFF_MEASURED_TANGENT]);
    return frame_from_xz(tangent, n);
}

/// Mirrors `Bsdf::eval`. `b.kind` must not be `MATERIAL_NONE`.
__device__ __forceinline__ float3 bsdf_eval(const Bsdf& b, float3 wo, float3 wi) {
    if (b.kind == MATERIAL_DIFFUSE) return same_hemisphere(wo, wi) ? b.a * FRAC_1_PI : zero3();
    if (b.kind == MATERIAL_CONDUCTOR) return conductor_eval(b.a, b.b, trowbridge_reitz(b.alpha_x, b.alpha_y), wo, wi);
    if (b.kind == MATERIAL_DIFFUSE_TRANSMISSION) return (same_hemisphere(wo, wi) ? b.a : b.b) * FRAC_1_PI;
    if (b.kind == MATERIAL_THIN_DIELECTRIC) return zero3();
    if (ATOLL_WITH_COATED && is_coated(b.kind)) return coated_eval(coated_of(b), wo, wi);
    if (ATOLL_WITH_PRINCIPLED && b.kind == MATERIAL_PRINCIPLED) return principled_eval(principled_of(b), wo, wi);
    if (ATOLL_WITH_HAIR && b.kind == MATERIAL_HAIR) return hair_eval(hair_of(b), wo, wi);
#if ATOLL_WITH_MEASURED
    if (b.kind == MATERIAL_MEASURED) return measured_eval(b.table, wo, wi);
#endif
    return dielectric_eval(b.eta, trowbridge_reitz(b.alpha_x, b.alpha_y), wo, wi);
}

/// Mirrors `Bsdf::pdf`.
__device__ __forceinline__ float bsdf_pdf(const Bsdf& b, float3 wo, float3 wi) {
    if (b.kind == MATERIAL_DIFFUSE) return same_hemisphere(wo, wi) ? cosine_hemisphere_pdf(fabsf(wi.z)) : 0.0f;
    if (b.kind == MATERIAL_CONDUCTOR) return conductor_pdf(trowbridge_reitz(b.alpha_x, b.alpha_y), wo, wi);
    if (b.kind == MATERIAL_DIFFUSE_TRANSMISSION) return diffuse_transmission_pdf(b.a, b.b, wo, wi);
    if (b.kind == MATERIAL_THIN_DIELECTRIC) return 0.0f;
    if (ATOLL_WITH_COATED && is_coated(b.kind)) return coated_pdf(coated_of(b), wo, wi);
    if (ATOLL_WITH_PRINCIPLED && b.kind == MATERIAL_PRINCIPLED) return principled_pdf(principled_of(b), wo, wi);
    if (ATOLL_WITH_HAIR && b.kind == MATERIAL_HAIR) return hair_pdf(hair_of(b), wo, wi);
#if ATOLL_WITH_MEASURED
    if (b.kind == MATERIAL_MEASURED) return measured_pdf(b.table, wo, wi);
#endif
    return dielectric_pdf(b.eta, trowbridge_reitz(b.alpha_x, b.alpha_y), wo, wi);
}

/// Mirrors `Bsdf::sample`; false for `None`.
__device__ __forceinline__ bool bsdf_sample(const Bsdf& b, float3 wo, float uc, float2 u, BsdfSample* out) {
    // Grazing wo: no side to scatter on (and eval would return 0).
    if (wo.z == 0.0f) return false;
    BsdfSample s;
    if (b.kind == MATERIAL_DIFFUSE) {
        s = diffuse_sample(b.a, wo, u);
    } else if (b.kind == MATERIAL_CONDUCTOR) {
        if (!conductor_sample(b.a, b.b, trowbridge_reitz(b.alpha_x, b.alpha_y), wo, u, &s)) return false;
    } else if (b.kind == MATERIAL_DIFFUSE_TRANSMISSION) {
        if (!diffuse_transmission_sample(b.a, b.b, wo, uc, u, &s)) return false;
    } else if (b.kind == MATERIAL_THIN_DIELECTRIC) {
        if (!thin_dielectric_sample(b.eta, wo, uc, &s)) return false;
    } else if (ATOLL_WITH_COATED && is_coated(b.kind)) {
        if (!coated_sample(coated_of(b), wo, uc, u, &s)) return false;
    } else if (ATOLL_WITH_PRINCIPLED && b.kind == MATERIAL_PRINCIPLED) {
        if (!principled_sample(principled_of(b), wo, uc, u, &s)) return false;
    } else if (ATOLL_WITH_HAIR && b.kind == MATERIAL_HAIR) {
        if (!hair_sample(hair_of(b), wo, uc, u, &s)) return false;
#if ATOLL_WITH_MEASURED
    } else if (b.kind == MATERIAL_MEASURED) {
        if (!measured_sample(b.table, wo, u, &s)) return false;
#endif
    } else {
        if (!dielectric_sample(b.eta, trowbridge_reitz(b.alpha_x, b.alpha_y), wo, uc, u, &s)) return false;
    }
    // As pbrt's `BSDF::Sample_f`: drop samples the integrator can't use.
    if (s.pdf > 0.0f && s.wi.z != 0.0f && is_finite3(s.f)) {
        *out = s;
        return true;
    }
    return false;
}

/// Mirrors `Bsdf::is_delta`.
__device__ __forceinline__ bool bsdf_is_delta(const Bsdf& b) {
    if (b.kind == MATERIAL_DIFFUSE) return false;
    if (b.kind == MATERIAL_CONDUCTOR) return tr_effectively_smooth(trowbridge_reitz(b.alpha_x, b.alpha_y));
    if (b.kind == MATERIAL_DIFFUSE_TRANSMISSION) return false;
    if (b.kind == MATERIAL_THIN_DIELECTRIC) return true;
    if (ATOLL_WITH_COATED && is_coated(b.kind)) return coated_is_delta(b);
    if (ATOLL_WITH_PRINCIPLED && b.kind == MATERIAL_PRINCIPLED) return principled_is_delta(principled_of(b));
    if (ATOLL_WITH_HAIR && b.kind == MATERIAL_HAIR) return false;
    if (ATOLL_WITH_MEASURED && b.kind == MATERIAL_MEASURED) return false;
    return dielectric_is_specular(b.eta, trowbridge_reitz(b.alpha_x, b.alpha_y));
}

/// Mirrors `Bsdf::sampled_pdf_is_proportional`: MIS at the next vertex must
/// use `bsdf_pdf`, not the sample's density.
__device__ __forceinline__ bool bsdf_sampled_pdf_is_proportional(const Bsdf& b) {
    return ATOLL_WITH_COATED && is_coated(b.kind);
}

#include "layered.cuh"
#include "principled.cuh"
#include "hair.cuh"
