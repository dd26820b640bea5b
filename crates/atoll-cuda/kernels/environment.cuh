// Image-based environment lights (mirrors crates/atoll-render/src/environment.rs
// and the mappings of crates/atoll-scene/src/environment.rs). An
// environment emitter keeps its light-to-world rotation as columns in
// `p[0..9]`, (width, height, layout) as floats in `normal`, the sum of its
// selection weights in `area` and, at `table` in `FrameParams::environment_tables`:
// pixels (RGB, scale applied), weights, the marginal CDF (height + 1) and
// the per-row conditional CDFs (height × (width + 1)).
#pragma once

#define ENV_PI 3.14159274f
#define ENV_TWO_PI 6.28318548f
#define ENV_FRAC_PI_2 1.57079637f
#define ENV_FRAC_PI_4 0.785398185f
/// `EnvLayout::EqualArea` / `EnvLayout::LatLong` as stored in `normal[2]`.
#define ENV_EQUAL_AREA 0u
#define ENV_LAT_LONG 1u

struct EnvView {
    unsigned int width, height, layout;
    const float* pixels;
    const float* func;
    const float* marginal;
    const float* conditional;
};

__device__ __forceinline__ EnvView env_view(const FrameParams& p, const GpuEmitter& e) {
    EnvView v;
    v.width = (unsigned int)e.normal[0];
    v.height = (unsigned int)e.normal[1];
    v.layout = (unsigned int)e.normal[2];
    v.pixels = p.environment_tables + e.table;
    v.func = v.pixels + 3u * v.width * v.height;
    v.marginal = v.func + v.width * v.height;
    v.conditional = v.marginal + v.height + 1u;
    return v;
}

/// Mirrors `environment::select_in_cdf` over `cdf[0..=n]`.
__device__ __forceinline__ unsigned int env_select(const float* cdf, unsigned int n, float u, float* t) {
    unsigned int lo = 0, hi = n + 1;  // partition point of `cdf[i] <= u`
    while (lo < hi) {
        const unsigned int mid = (lo + hi) >> 1;
        if (cdf[mid] <= u) lo = mid + 1; else hi = mid;
    }
    unsigned int i = lo > 0 ? lo - 1 : 0;
    if (i > n - 1) i = n - 1;
    const float width = cdf[i + 1] - cdf[i];
    *t = width > 0.0f ? fminf(fmaxf(__fdiv_rn(u - cdf[i], width), 0.0f), 0.99999994f) : 0.5f;
    return i;
}

/// Mirrors `equal_area_square_to_sphere`.
__device__ __forceinline__ float3 env_equal_area_to_sphere(float2 q) {
    const float u = 2.0f * q.x - 1.0f, v = 2.0f * q.y - 1.0f;
    const float up = fabsf(u), vp = fabsf(v);
    const float signed_distance = 1.0f - (up + vp);
    const float d = fabsf(signed_distance);
    const float r = 1.0f - d;
    const float phi = (r == 0.0f ? 1.0f : __fdiv_rn(vp - up, r) + 1.0f) * ENV_FRAC_PI_4;
    const float z = copysignf(1.0f - r * r, signed_distance);
    const float cos_phi = copysignf(cosf(phi), u), sin_phi = copysignf(sinf(phi), v);
    const float s = r * sqrtf(fmaxf(2.0f - r * r, 0.0f));
    return make_float3(cos_phi * s, sin_phi * s, z);
}

/// Mirrors `equal_area_sphere_to_square`.
__device__ __forceinline__ float2 env_sphere_to_equal_area(float3 dir) {
    const float x = fabsf(dir.x), y = fabsf(dir.y), z = fabsf(dir.z);
    const float r = sqrtf(fmaxf(1.0f - z, 0.0f));
    const float a = fmaxf(x, y);
    const float b = a == 0.0f ? 0.0f : __fdiv_rn(fminf(x, y), a);
    float phi = __fdiv_rn(atanf(b), ENV_FRAC_PI_2);
    if (x < y) phi = 1.0f - phi;
    float v = phi * r;
    float u = r - v;
    if (dir.z < 0.0f) {
        const float t = u;
        u = 1.0f - v;
        v = 1.0f - t;
    }
    return make_float2((copysignf(u, dir.x) + 1.0f) * 0.5f, (copysignf(v, dir.y) + 1.0f) * 0.5f);
}

/// Mirrors `EnvLayout::direction`.
__device__ __forceinline__ float3 env_direction(unsigned int layout, float2 uv) {
    if (layout == ENV_EQUAL_AREA) return env_equal_area_to_sphere(uv);
    const float theta = ENV_PI * uv.y, phi = ENV_TWO_PI * uv.x;
    const float sin_theta = sinf(theta);
    return make_float3(sin_theta * cosf(phi), sin_theta * sinf(phi), cosf(theta));
}

/// Mirrors `EnvLayout::uv`.
__device__ __forceinline__ float2 env_uv(unsigned int layout, float3 d) {
    if (layout == ENV_EQUAL_AREA) return env_sphere_to_equal_area(d);
    const float theta = acosf(fminf(fmaxf(d.z, -1.0f), 1.0f));
    float phi = atan2f(d.y, d.x);
    if (phi < 0.0f) phi += ENV_TWO_PI;
    return make_float2(__fdiv_rn(phi, ENV_TWO_PI), __fdiv_rn(theta, ENV_PI));
}

/// Mirrors `EnvLayout::solid_angle_per_area`.
__device__ __forceinline__ float env_jacobian(unsigned int layout, float2 uv) {
    if (layout == ENV_EQUAL_AREA) return 4.0f * ENV_PI;
    return 2.0f * ENV_PI * ENV_PI * sinf(ENV_PI * uv.y);
}

/// Mirrors `EnvironmentImage::pixel_index`.
__device__ __forceinline__ unsigned int env_pixel(const EnvView& v, float2 uv) {
    const unsigned int x = min((unsigned int)fmaxf(uv.x * (float)v.width, 0.0f), v.width - 1u);
    const unsigned int y = min((unsigned int)fmaxf(uv.y * (float)v.height, 0.0f), v.height - 1u);
    return y * v.width + x;
}

/// The light-space direction of world direction `w` (the rotation's transpose).
__device__ __forceinline__ float3 env_to_light(const GpuEmitter& e, float3 w) {
    return make_float3(dot3(load3(&e.p[0]), w), dot3(load3(&e.p[3]), w), dot3(load3(&e.p[6]), w));
}

/// Mirrors `EnvironmentSampler::sample`: false for Rust's `None`.
__device__ __forceinline__ bool env_sample(const FrameParams& p, const GpuEmitter& e, float2 u, float3* wi,
                                           float3* radiance, float* pdf) {
    if (e.area <= 0.0f) return false;
    const EnvView v = env_view(p, e);
    float ty, tx;
    const unsigned int y = env_select(v.marginal, v.height, u.y, &ty);
    const unsigned int x = env_select(v.conditional + y * (v.width + 1u), v.width, u.x, &tx);
    const float2 uv = make_float2(__fdiv_rn((float)x + tx, (float)v.width), __fdiv_rn((float)y + ty, (float)v.height));
    const float jacobian = env_jacobian(v.layout, uv);
    const unsigned int pixel = y * v.width + x;
    const float p_pixel = __fdiv_rn(v.func[pixel], e.area);
    if (jacobian <= 0.0f || p_pixel <= 0.0f) return false;
    const float3 d = env_direction(v.layout, uv);
    const float3 world = load3(&e.p[0]) * d.x + load3(&e.p[3]) * d.y + load3(&e.p[6]) * d.z;
    *wi = normalize3(world);
    *radiance = load3(v.pixels + 3u * pixel);
    *pdf = __fdiv_rn(p_pixel * (float)(v.width * v.height), jacobian);
    return true;
}

/// Mirrors `EnvironmentSampler::radiance`.
__device__ __forceinline__ float3 env_radiance(const FrameParams& p, const GpuEmitter& e, float3 w) {
    const EnvView v = env_view(p, e);
    return load3(v.pixels + 3u * env_pixel(v, env_uv(v.layout, env_to_light(e, w))));
}

/// Mirrors `EnvironmentSampler::pdf`.
__device__ __forceinline__ float env_pdf(const FrameParams& p, const GpuEmitter& e, float3 w) {
    if (e.area <= 0.0f) return 0.0f;
    const EnvView v = env_view(p, e);
    const float2 uv = env_uv(v.layout, env_to_light(e, w));
    const float jacobian = env_jacobian(v.layout, uv);
    if (jacobian <= 0.0f) return 0.0f;
    return __fdiv_rn(__fdiv_rn(v.func[env_pixel(v, uv)], e.area) * (float)(v.width * v.height), jacobian);
}
