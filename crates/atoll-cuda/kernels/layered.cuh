// The coated diffuse and coated conductor BSDFs: the mirror of
// `atoll_render::bsdf::layered` (pbrt-v4's `LayeredBxDF<DielectricBxDF,
// DiffuseBxDF | ConductorBxDF, true>`), same
// operations in the same order, including the hashes that seed each
// estimate's random walk, so CPU and GPU estimates agree. Included at the end
// of bsdf.cuh, which declares the three estimates for its dispatch.
//
// Registers: ptxas gives a non-inlined callee registers above those live in
// the caller at the call, so a kernel needs (live at the call) + (callee's
// own); `__noinline__` does not isolate a heavy function, it only stops its
// temporaries from merging with the caller's. What keeps the shade kernel
// narrow is keeping the walks themselves narrow: the coating's sampling,
// evaluation and density, the phase-function and base sampling are out of
// line too, so a walk's loop holds little more than its own state (measured
// on sm_90 when written: inlining everything into the walks cost the shade
// kernel many more registers).
#pragma once

#include "common.cuh"
#include "rng.cuh"
#include "sampling.cuh"
#include "bsdf.cuh"

// FLT_MIN_POSITIVE: Rust's `f32::MIN_POSITIVE` (pbrt's smallest layer
// thickness); DIRECTION_SEED_DROP_BITS and LAYERED_TAG_*: layered.rs's seed
// rounding and random-stream tags.
// BEGIN GENERATED layered (src/header.rs; regenerate: ATOLL_BLESS=1 cargo test -p atoll-cuda header)
inline constexpr float FLT_MIN_POSITIVE = 1.1754944e-38f;
inline constexpr unsigned int DIRECTION_SEED_DROP_BITS = 10u;
inline constexpr unsigned int LAYERED_TAG_EVAL = 1702257004u;
inline constexpr unsigned int LAYERED_TAG_SAMPLE = 1936552044u;
inline constexpr unsigned int LAYERED_TAG_PDF = 1885627937u;
// END GENERATED layered

/// Mirrors layered.rs's `WalkRng`: PCG32 (RXS-M-XS) from a hash of the
/// estimate's arguments.
struct WalkRng {
    unsigned int state;
};

/// Mirrors layered.rs's `seed_bits`: a direction component's bits rounded
/// to a multiple of 2^DIRECTION_SEED_DROP_BITS ulps.
__device__ __forceinline__ unsigned int seed_bits(float x) {
    const unsigned int half = 1u << (DIRECTION_SEED_DROP_BITS - 1u);
    return (__float_as_uint(x) + half) & ~((1u << DIRECTION_SEED_DROP_BITS) - 1u);
}

/// `WalkRng::new`'s fold over one direction (rounded bits).
__device__ __forceinline__ unsigned int walk_seed_dir(unsigned int h, float3 d) {
    h = pcg_hash(h ^ seed_bits(d.x));
    h = pcg_hash(h ^ seed_bits(d.y));
    return pcg_hash(h ^ seed_bits(d.z));
}

/// `WalkRng::new`'s fold over one exact word.
__device__ __forceinline__ unsigned int walk_seed_word(unsigned int h, float x) {
    return pcg_hash(h ^ __float_as_uint(x));
}

__device__ __forceinline__ WalkRng walk_rng(unsigned int state) {
    WalkRng r;
    r.state = state;
    return r;
}

/// Mirrors `WalkRng::next`.
__device__ __forceinline__ float walk_next(WalkRng& r) {
    const unsigned int out = pcg_hash(r.state);
    r.state = r.state * 747796405u + 2891336453u;
    return (float)(out >> 8) * (1.0f / 16777216.0f);
}

/// Mirrors `WalkRng::next2`.
__device__ __forceinline__ float2 walk_next2(WalkRng& r) {
    const float x = walk_next(r);
    return make_float2(x, walk_next(r));
}

/// Mirrors `sampling::sample_henyey_greenstein`; returns wi, writes its density.
__device__ __noinline__ float3 sample_henyey_greenstein(float3 wo, float g, float2 u, float* pdf) {
    g = clampf(g, -0.99f, 0.99f);
    float cos_theta;
    if (fabsf(g) < 1e-3f) {
        cos_theta = 1.0f - 2.0f * u.x;
    } else {
        const float s = (1.0f - g * g) / (1.0f + g - 2.0f * g * u.x);
        cos_theta = -1.0f / (2.0f * g) * (1.0f + g * g - s * s);
    }
    const float sin_theta = sqrtf(fmaxf(1.0f - cos_theta * cos_theta, 0.0f));
    const float phi = 2.0f * PI * u.y;
    *pdf = henyey_greenstein(cos_theta, g);
    return frame_from_local(frame_from_z(wo), spherical_direction(sin_theta, cos_theta, phi));
}

/// Mirrors layered.rs's `tr`.
__device__ __forceinline__ float layer_tr(float dz, float3 w) {
    if (fabsf(dz) <= FLT_MIN_POSITIVE) return 1.0f;
    return expf(-fabsf(dz / w.z));
}

/// Mirrors layered.rs's `usable` applied to a sample that exists.
__device__ __forceinline__ bool layer_usable(const BsdfSample& s) {
    return !is_zero3(s.f) && s.pdf > 0.0f && s.wi.z != 0.0f;
}

/// Mirrors `Coated::coat_sample`: the coating's sample, if usable.
__device__ __noinline__ bool coat_sample_with(float eta, float alpha_x, float alpha_y, float3 wo, float uc, float2 u,
                                              int mode, int lobes, BsdfSample* out) {
    return dielectric_sample_with(eta, trowbridge_reitz(alpha_x, alpha_y), wo, uc, u, mode, lobes, out) &&
           layer_usable(*out);
}

/// Mirrors `Coated::coat_eval`.
__device__ __noinline__ float3 coat_eval_with(float eta, float alpha_x, float alpha_y, float3 wo, float3 wi, int mode) {
    return dielectric_eval_with(eta, trowbridge_reitz(alpha_x, alpha_y), wo, wi, mode);
}

/// Mirrors `Coated::coat_pdf`.
__device__ __noinline__ float coat_pdf_with(float eta, float alpha_x, float alpha_y, float3 wo, float3 wi, int lobes) {
    return dielectric_pdf_with(eta, trowbridge_reitz(alpha_x, alpha_y), wo, wi, lobes);
}

__device__ __forceinline__ bool coat_sample(const Coated& c, float3 wo, float uc, float2 u, int mode, int lobes,
                                            BsdfSample* out) {
    return coat_sample_with(c.eta, c.alpha_x, c.alpha_y, wo, uc, u, mode, lobes, out);
}
__device__ __forceinline__ float3 coat_eval(const Coated& c, float3 wo, float3 wi, int mode) {
    return coat_eval_with(c.eta, c.alpha_x, c.alpha_y, wo, wi, mode);
}
__device__ __forceinline__ float coat_pdf(const Coated& c, float3 wo, float3 wi, int lobes) {
    return coat_pdf_with(c.eta, c.alpha_x, c.alpha_y, wo, wi, lobes);
}

/// Mirrors `Coated::coat().effectively_smooth()`.
__device__ __forceinline__ bool coat_is_smooth(const Coated& c) {
    return tr_effectively_smooth(trowbridge_reitz(c.alpha_x, c.alpha_y));
}

/// The base's conductor distribution (`Coated::base`).
__device__ __forceinline__ TrowbridgeReitz base_distribution(const Coated& c) {
    return trowbridge_reitz(c.base_alpha_x, c.base_alpha_y);
}

/// Mirrors `Coated::base_is_specular`.
__device__ __forceinline__ bool base_is_specular(const Coated& c) {
    return ATOLL_WITH_COATED_CONDUCTOR && c.conductor && tr_effectively_smooth(base_distribution(c));
}

/// Mirrors `usable(self.base().sample(..))`: `Bsdf::sample` of the base (its
/// grazing check and final filter included), if usable. A conductor's index
/// is already relative to the coating's (`coated_of`), as `Coated::base` makes it.
__device__ __noinline__ bool base_sample(const Coated& c, float3 wo, float2 u, BsdfSample* out) {
    if (wo.z == 0.0f) return false;
    if (ATOLL_WITH_COATED_CONDUCTOR && c.conductor) {
        if (!conductor_sample(c.base_a, c.base_k, base_distribution(c), wo, u, out)) return false;
    } else {
        *out = diffuse_sample(c.base_a, wo, u);
    }
    return out->pdf > 0.0f && out->wi.z != 0.0f && is_finite3(out->f) && layer_usable(*out);
}

/// Mirrors `Bsdf::eval` of the base.
__device__ __noinline__ float3 base_eval(const Coated& c, float3 wo, float3 wi) {
    if (ATOLL_WITH_COATED_CONDUCTOR && c.conductor) return conductor_eval(c.base_a, c.base_k, base_distribution(c), wo, wi);
    return same_hemisphere(wo, wi) ? c.base_a * FRAC_1_PI : zero3();
}

/// Mirrors `Bsdf::pdf` of the base.
__device__ __noinline__ float base_pdf(const Coated& c, float3 wo, float3 wi) {
    if (ATOLL_WITH_COATED_CONDUCTOR && c.conductor) return conductor_pdf(base_distribution(c), wo, wi);
    return same_hemisphere(wo, wi) ? cosine_hemisphere_pdf(fabsf(wi.z)) : 0.0f;
}

/// Mirrors `Coated::eval`.
__device__ __noinline__ float3 coated_eval(Coated c, float3 wo, float3 wi) {
    // Two-sided: mirror a query from below.
    if (wo.z < 0.0f) {
        wo = -wo;
        wi = -wi;
    }
    // The base is opaque: only reflection is nonzero.
    if (!same_hemisphere(wo, wi)) return zero3();
    const float thickness = fmaxf(c.thickness, FLT_MIN_POSITIVE);
    const bool coat_specular = coat_is_smooth(c);
    const bool base_specular = base_is_specular(c);
    const bool scatters = !is_zero3(c.albedo);
    const unsigned int n = c.n_samples > 1u ? c.n_samples : 1u;
    float3 f = coat_eval(c, wo, wi, MODE_RADIANCE) * (float)n;
    // Mirrors `WalkRng::new(TAG_EVAL, &[wo, wi], &[])`.
    WalkRng rng = walk_rng(walk_seed_dir(walk_seed_dir(pcg_hash(LAYERED_TAG_EVAL), wo), wi));
    for (unsigned int s = 0; s < n; ++s) {
        // Enter through the coating, and presample the way out to wi.
        BsdfSample wos, wis;
        float uc = walk_next(rng);
        if (!coat_sample(c, wo, uc, walk_next2(rng), MODE_RADIANCE, LOBES_TRANSMISSION, &wos)) continue;
        uc = walk_next(rng);
        if (!coat_sample(c, wi, uc, walk_next2(rng), MODE_IMPORTANCE, LOBES_TRANSMISSION, &wis)) continue;
        float3 beta = wos.f * fabsf(wos.wi.z) / wos.pdf;
        float z = thickness;
        float3 w = wos.wi;
        for (unsigned int depth = 0; depth < c.max_depth; ++depth) {
            if (depth > 3u && max_element3(beta) < 0.25f) {
                const float q = fmaxf(1.0f - max_element3(beta), 0.0f);
                if (walk_next(rng) < q) break;
                beta = beta / (1.0f - q);
            }
            if (!scatters) {
                // Straight to the other boundary through an absorber.
                z = z == thickness ? 0.0f : thickness;
                beta = beta * layer_tr(thickness, w);
            } else {
                const float dz = sample_exponential(walk_next(rng), 1.0f / fabsf(w.z));
                const float zp = w.z > 0.0f ? z + dz : z - dz;
                if (zp == z) continue;
                if (0.0f < zp && zp < thickness) {
                    // Scattering in the medium: connect to the presampled exit
                    // direction, then continue along the phase function.
                    const float phase = henyey_greenstein(dot3(-w, -wis.wi), c.g);
                    const float wt = coat_specular ? 1.0f : power_heuristic(wis.pdf, phase);
                    f = f + beta * c.albedo * phase * wt * layer_tr(zp - thickness, wis.wi) * wis.f / wis.pdf;
                    float p;
                    const float3 wp = sample_henyey_greenstein(-w, c.g, walk_next2(rng), &p);
                    if (p == 0.0f || wp.z == 0.0f) continue;
                    beta = beta * c.albedo;
                    w = wp;
                    z = zp;
                    // Heading up, towards the exit: connect through the coating.
                    if (z < thickness && w.z > 0.0f && !coat_specular) {
                        const float3 f_exit = coat_eval(c, -w, wi, MODE_RADIANCE);
                        if (!is_zero3(f_exit)) {
                            const float exit_pdf = coat_pdf(c, wi, -w, LOBES_TRANSMISSION);
                            const float wt2 = power_heuristic(p, exit_pdf);
                            f = f + beta * layer_tr(zp - thickness, wp) * f_exit * wt2;
                        }
                    }
                    continue;
                }
                z = clampf(zp, 0.0f, thickness);
            }
            if (z == thickness) {
                // Back at the coating from below: reflect inside.
                BsdfSample bs;
                const float uc2 = walk_next(rng);
                if (!coat_sample(c, -w, uc2, walk_next2(rng), MODE_RADIANCE, LOBES_REFLECTION, &bs)) break;
                beta = beta * bs.f * fabsf(bs.wi.z) / bs.pdf;
                w = bs.wi;
            } else {
                // At the base: next-event estimation along the presampled exit
                // direction (none for a specular base), then a bounce.
                if (!base_specular) {
                    const float wt = coat_specular ? 1.0f : power_heuristic(wis.pdf, base_pdf(c, -w, -wis.wi));
                    f = f + beta * base_eval(c, -w, -wis.wi) * fabsf(wis.wi.z) * wt * layer_tr(thickness, wis.wi) *
                                wis.f / wis.pdf;
                }
                BsdfSample bs;
                walk_next(rng);  // the lobe choice: either base has one lobe
                const float2 u = walk_next2(rng);
                if (!base_sample(c, -w, u, &bs)) break;
                beta = beta * bs.f * fabsf(bs.wi.z) / bs.pdf;
                w = bs.wi;
                if (!coat_specular) {
                    // The bounce's own direction, if it leaves towards wi.
                    const float3 f_exit = coat_eval(c, -w, wi, MODE_RADIANCE);
                    if (!is_zero3(f_exit)) {
                        const float wt2 =
                            base_specular ? 1.0f : power_heuristic(bs.pdf, coat_pdf(c, wi, -w, LOBES_TRANSMISSION));
                        f = f + beta * layer_tr(thickness, bs.wi) * f_exit * wt2;
                    }
                }
            }
        }
    }
    return f / (float)n;
}

/// Mirrors `Coated::sample`; false for `None`.
__device__ __noinline__ bool coated_sample(Coated c, float3 wo, float uc, float2 u, BsdfSample* out) {
    const bool flip = wo.z < 0.0f;
    if (flip) wo = -wo;
    // Reflection at the coating ends the walk at once.
    BsdfSample bs;
    if (!coat_sample(c, wo, uc, u, MODE_RADIANCE, LOBES_ALL, &bs)) return false;
    if (!bs.transmission) {
        if (flip) bs.wi = -bs.wi;
        *out = bs;
        return true;
    }
    const float thickness = fmaxf(c.thickness, FLT_MIN_POSITIVE);
    const bool scatters = !is_zero3(c.albedo);
    float3 w = bs.wi;
    bool specular_path = bs.delta;
    // Mirrors `WalkRng::new(TAG_SAMPLE, &[wo], &[uc, u.x, u.y])`.
    const unsigned int h = walk_seed_dir(pcg_hash(LAYERED_TAG_SAMPLE), wo);
    WalkRng rng = walk_rng(walk_seed_word(walk_seed_word(walk_seed_word(h, uc), u.x), u.y));
    float3 beta = bs.f * fabsf(bs.wi.z) / bs.pdf;
    float z = thickness;
    for (unsigned int depth = 0; depth < c.max_depth; ++depth) {
        // Russian roulette; surviving walks weigh 1 / (1 - q) more.
        const float rr_beta = max_element3(beta);
        if (depth > 3u && rr_beta < 0.25f) {
            const float q = fmaxf(1.0f - rr_beta, 0.0f);
            if (walk_next(rng) < q) return false;
            beta = beta / (1.0f - q);
        }
        if (w.z == 0.0f) return false;
        if (scatters) {
            const float dz = sample_exponential(walk_next(rng), 1.0f / fabsf(w.z));
            const float zp = w.z > 0.0f ? z + dz : z - dz;
            if (zp == z) return false;
            if (0.0f < zp && zp < thickness) {
                float p;
                const float3 wp = sample_henyey_greenstein(-w, c.g, walk_next2(rng), &p);
                if (p == 0.0f || wp.z == 0.0f) return false;
                beta = beta * c.albedo;
                specular_path = false;
                w = wp;
                z = zp;
                continue;
            }
            z = clampf(zp, 0.0f, thickness);
        } else {
            z = z == thickness ? 0.0f : thickness;
            beta = beta * layer_tr(thickness, w);
        }
        const float uc2 = walk_next(rng);
        const float2 u2 = walk_next2(rng);
        const bool ok =
            z == 0.0f ? base_sample(c, -w, u2, &bs) : coat_sample(c, -w, uc2, u2, MODE_RADIANCE, LOBES_ALL, &bs);
        if (!ok) return false;
        specular_path = specular_path && bs.delta;
        w = bs.wi;
        if (bs.transmission) {
            // Out through the coating (the base never transmits).
            const bool transmission = !same_hemisphere(wo, w);
            *out = make_bsdf_sample(beta * bs.f, flip ? -w : w, bs.pdf, 1.0f, specular_path, transmission);
            return true;
        }
        beta = beta * bs.f * fabsf(bs.wi.z) / bs.pdf;
    }
    return false;
}

/// Mirrors `Coated::pdf`.
__device__ __noinline__ float coated_pdf(Coated c, float3 wo, float3 wi) {
    if (wo.z < 0.0f) {
        wo = -wo;
        wi = -wi;
    }
    // Mirrors `WalkRng::new(TAG_PDF, &[wi, wo], &[])`.
    WalkRng rng = walk_rng(walk_seed_dir(walk_seed_dir(pcg_hash(LAYERED_TAG_PDF), wi), wo));
    const unsigned int n = c.n_samples > 1u ? c.n_samples : 1u;
    float pdf_sum = 0.0f;
    // Transmission pairs: the base is opaque, no walk gets through.
    if (same_hemisphere(wo, wi)) {
        const bool coat_specular = coat_is_smooth(c);
        pdf_sum += (float)n * coat_pdf(c, wo, wi, LOBES_REFLECTION);
        for (unsigned int s = 0; s < n; ++s) {
            BsdfSample wos, wis;
            float uc = walk_next(rng);
            const bool entered = coat_sample(c, wo, uc, walk_next2(rng), MODE_RADIANCE, LOBES_TRANSMISSION, &wos);
            uc = walk_next(rng);
            const bool exited = coat_sample(c, wi, uc, walk_next2(rng), MODE_IMPORTANCE, LOBES_TRANSMISSION, &wis);
            if (!entered || !exited) continue;
            if (coat_specular) {
                pdf_sum += base_pdf(c, -wos.wi, -wis.wi);
                continue;
            }
            // Rough coating: MIS between sampling the base from the way in
            // and the coating from the base's bounce (the only way for a
            // specular base).
            BsdfSample rs;
            walk_next(rng);  // the lobe choice: either base has one lobe
            const float2 u = walk_next2(rng);
            if (!base_sample(c, -wos.wi, u, &rs)) continue;
            if (base_is_specular(c)) {
                pdf_sum += coat_pdf(c, -rs.wi, wi, LOBES_ALL);
                continue;
            }
            const float r_pdf = base_pdf(c, -wos.wi, -wis.wi);
            pdf_sum += power_heuristic(wis.pdf, r_pdf) * r_pdf;
            const float t_pdf = coat_pdf(c, -rs.wi, wi, LOBES_ALL);
            pdf_sum += power_heuristic(rs.pdf, t_pdf) * t_pdf;
        }
    }
    // pbrt's Lerp(0.9, 1 / 4π, estimate).
    return 0.1f * (1.0f / (4.0f * PI)) + 0.9f * (pdf_sum / (float)n);
}
