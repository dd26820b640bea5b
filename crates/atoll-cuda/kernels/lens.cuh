// A realistic camera's lens system: the mirror of `atoll_scene::lens`
// (pbrt-v4's `RealisticCamera`) over the words `params::pack_lens` writes.
// Lens space has the film at z = 0 and the elements towards -z; camera
// space flips z.
#pragma once

#include "common.cuh"
#include "params.cuh"

/// Mirrors `lens::intersect_element`: where the lens-space ray (o, d) meets
/// the interface of curvature `radius` (0: the stop's plane) whose vertex
/// lies at `z`, and its normal facing the ray.
__device__ __forceinline__ bool lens_intersect(float radius, float z, float3 o, float3 d, float* t_out,
                                               float3* n_out) {
    if (radius == 0.0f) {
        const float t = (z - o.z) / d.z;
        *t_out = t;
        *n_out = make_float3(0.0f, 0.0f, 1.0f);
        return t >= 0.0f;
    }
    const float3 oc = o - make_float3(0.0f, 0.0f, z + radius);
    const float a = length_squared3(d), b = 2.0f * dot3(d, oc), c = length_squared3(oc) - radius * radius;
    const float discriminant = b * b - 4.0f * a * c;
    if (discriminant < 0.0f) return false;
    const float root = sqrtf(discriminant);
    const float q = b < 0.0f ? -0.5f * (b - root) : -0.5f * (b + root);
    const float r0 = q / a, r1 = c / q;
    const float t0 = fminf(r0, r1), t1 = fmaxf(r0, r1);
    const bool closer = (d.z > 0.0f) != (radius < 0.0f);
    const float t = closer ? t0 : t1;
    if (!(t >= 0.0f)) return false;
    const float3 n = normalize3(oc + d * t);
    *t_out = t;
    *n_out = dot3(n, -d) < 0.0f ? -n : n;
    return true;
}

/// Mirrors `lens::refract`: `wi` (unit, on the side of `n`) through an
/// interface of relative index `eta`; false on total internal reflection.
__device__ __forceinline__ bool lens_refract(float3 wi, float3 n, float eta, float3* wt) {
    const float cos_i = dot3(n, wi);
    const float sin2_t = fmaxf(1.0f - cos_i * cos_i, 0.0f) / (eta * eta);
    if (sin2_t >= 1.0f) return false;
    const float cos_t = sqrtf(1.0f - sin2_t);
    *wt = -wi / eta + n * (cos_i / eta - cos_t);
    return true;
}

/// Mirrors `ApertureImage::bilerp` over the `width` x `height` values at
/// `image` (black outside).
__device__ __forceinline__ float lens_aperture_bilerp(const float* image, unsigned int width, unsigned int height,
                                                      float2 uv) {
    const float x = uv.x * (float)width - 0.5f, y = uv.y * (float)height - 0.5f;
    const float xi = floorf(x), yi = floorf(y);
    const float dx = x - xi, dy = y - yi;
    const auto texel = [&](float tx, float ty) {
        if (tx < 0.0f || ty < 0.0f || tx >= (float)width || ty >= (float)height) return 0.0f;
        return image[(unsigned int)ty * width + (unsigned int)tx];
    };
    return (1.0f - dx) * (1.0f - dy) * texel(xi, yi) + dx * (1.0f - dy) * texel(xi + 1.0f, yi) +
           (1.0f - dx) * dy * texel(xi, yi + 1.0f) + dx * dy * texel(xi + 1.0f, yi + 1.0f);
}

/// Mirrors `lens::medium_eta`: 0 in a lens file is air.
__device__ __forceinline__ float lens_medium_eta(float eta) { return eta == 0.0f ? 1.0f : eta; }

/// Mirrors `LensSystem::trace_from_film`: the camera-space ray from film
/// point `origin` along `dir` after the lens; returns the stop's
/// transmission, 0 where the ray is blocked.
__device__ float lens_trace_from_film(const float* lens, float3 origin, float3 dir, float3* o_out, float3* d_out) {
    const unsigned int count = __float_as_uint(lens[0]), pupils = __float_as_uint(lens[1]);
    const unsigned int width = __float_as_uint(lens[4]), height = __float_as_uint(lens[5]);
    const float* elements = lens + LENS_HEADER_WORDS;
    const float* image = elements + 4u * count + 4u * pupils;
    float3 o = make_float3(origin.x, origin.y, -origin.z), d = make_float3(dir.x, dir.y, -dir.z);
    float z = 0.0f, weight = 1.0f;
    for (int i = (int)count - 1; i >= 0; --i) {
        const float radius = elements[4 * i], thickness = elements[4 * i + 1];
        const float eta = elements[4 * i + 2], aperture = elements[4 * i + 3];
        z -= thickness;
        float t;
        float3 n;
        if (!lens_intersect(radius, z, o, d, &t, &n)) return 0.0f;
        const float3 hit = o + d * t;
        if (radius == 0.0f && width != 0u) {
            const float2 uv = make_float2((hit.x / aperture + 1.0f) / 2.0f, (hit.y / aperture + 1.0f) / 2.0f);
            weight = lens_aperture_bilerp(image, width, height, uv);
            if (weight == 0.0f) return 0.0f;
        } else if (hit.x * hit.x + hit.y * hit.y > aperture * aperture) {
            return 0.0f;
        }
        o = hit;
        if (radius != 0.0f) {
            const float eta_t = i == 0 ? 1.0f : lens_medium_eta(elements[4 * (i - 1) + 2]);
            if (!lens_refract(-normalize3(d), n, eta_t / lens_medium_eta(eta), &d)) return 0.0f;
        }
    }
    *o_out = make_float3(o.x, o.y, -o.z);
    *d_out = make_float3(d.x, d.y, -d.z);
    return weight;
}

/// Mirrors `LensSystem::ray`: the camera-space ray from film point `film`
/// through the exit pupil at `u`, out of the lens; returns its weight, 0
/// where the lens blocks it (the ray is then left unwritten).
__device__ float lens_ray(const float* lens, float2 film, float2 u, float3* origin_out, float3* dir_out) {
    const unsigned int count = __float_as_uint(lens[0]);
    const float diagonal = lens[2], rear_z = lens[3];
    const float r = sqrtf(film.x * film.x + film.y * film.y);
    const unsigned int ring = min((unsigned int)(r / (diagonal / 2.0f) * (float)LENS_PUPIL_RINGS), LENS_PUPIL_RINGS - 1u);
    const float* b = lens + LENS_HEADER_WORDS + 4u * count + 4u * ring;
    if (!(b[0] < b[2] && b[1] < b[3])) return 0.0f;
    const float2 p = make_float2(b[0] + u.x * (b[2] - b[0]), b[1] + u.y * (b[3] - b[1]));
    const float pdf = 1.0f / ((b[2] - b[0]) * (b[3] - b[1]));
    const float s = r != 0.0f ? film.y / r : 0.0f, c = r != 0.0f ? film.x / r : 1.0f;
    const float3 pupil = make_float3(c * p.x - s * p.y, s * p.x + c * p.y, rear_z);
    const float3 start = make_float3(film.x, film.y, 0.0f);
    float3 o, d;
    const float transmission = lens_trace_from_film(lens, start, pupil - start, &o, &d);
    if (transmission == 0.0f) return 0.0f;
    const float cos_theta = normalize3(pupil - start).z;
    const float cos2 = cos_theta * cos_theta;
    *origin_out = o;
    *dir_out = normalize3(d);
    return transmission * (cos2 * cos2) / (pdf * rear_z * rear_z);
}
