// Test kernels: evaluate the device functions of bsdf.cuh, lights.cuh and
// rng.cuh for given inputs so tests/gpu_stages.rs can compare them value by
// value with the Rust functions they mirror. Not used for rendering.
//
// Buffers are flat arrays of 32-bit words (floats, or bit patterns), one
// fixed-size row per case, so the host side needs no struct mirrors.

#include "common.cuh"
#include "record.cuh"
#include "params.cuh"
#include "rng.cuh"
#include "bsdf.cuh"
#include "lights.cuh"

/// Words per row of `test_bsdf`'s input and output.
#define BSDF_IN 9
#define BSDF_OUT 16

/// For each case i: the BSDF of `records[i]` (material and coefficients,
/// as `bsdf_from_record`, measured ones reading `measured`), and
/// `inputs[9i..]` = wo.xyz, wi.xyz, uc, u.xy.
/// Writes `outputs[16i..]` = eval(wo, wi).rgb, pdf(wo, wi), sample valid
/// (0/1), sample f.rgb, wi.xyz, pdf, eta, delta (0/1), transmission (0/1),
/// is_delta (0/1). A record without a BSDF writes zeros.
extern "C" __global__ void test_bsdf(const RayRecord* records, const float* measured, const float* inputs,
                                     unsigned int n, float* outputs) {
    const unsigned int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    const float* in = inputs + BSDF_IN * i;
    float* out = outputs + BSDF_OUT * i;
    for (int k = 0; k < BSDF_OUT; ++k) out[k] = 0.0f;
    const Bsdf b = bsdf_from_record(records[i], measured);
    if (b.kind == MATERIAL_NONE) return;
    const float3 wo = load3(in), wi = load3(in + 3);
    store3(out, bsdf_eval(b, wo, wi));
    out[3] = bsdf_pdf(b, wo, wi);
    BsdfSample s;
    if (bsdf_sample(b, wo, in[6], make_float2(in[7], in[8]), &s)) {
        out[4] = 1.0f;
        store3(out + 5, s.f);
        store3(out + 8, s.wi);
        out[11] = s.pdf;
        out[12] = s.eta;
        out[13] = s.delta ? 1.0f : 0.0f;
        out[14] = s.transmission ? 1.0f : 0.0f;
    }
    out[15] = bsdf_is_delta(b) ? 1.0f : 0.0f;
}

/// For each case i with `queries[3i..]` = (pixel, sample, dimension):
/// `out[2i]` = pcg_hash(pixel) and `out[2i + 1]` = the bits of
/// `SampleStream::new(seed, pixel, sample).get(dimension)`.
extern "C" __global__ void test_rng(unsigned int seed, const unsigned int* queries, unsigned int n,
                                    unsigned int* out) {
    const unsigned int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    const unsigned int* q = queries + 3 * i;
    out[2 * i] = pcg_hash(q[0]);
    out[2 * i + 1] = __float_as_uint(stream_get(sample_stream(seed, q[0], q[1]), q[2]));
}

/// Words per row of `test_lights`' input and output.
#define LIGHT_IN 6
#define LIGHT_OUT 10

/// For each case i with `inputs[6i..]` = position.xyz, u_select, u.xy:
/// `outputs[10i..]` = sample valid (0/1), wi.xyz, distance, radiance.rgb,
/// pdf, delta (0/1) of `LightSet::sample`.
extern "C" __global__ void test_lights(const FrameParams* params, const float* inputs, unsigned int n,
                                       float* outputs) {
    const unsigned int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    const float* in = inputs + LIGHT_IN * i;
    float* out = outputs + LIGHT_OUT * i;
    for (int k = 0; k < LIGHT_OUT; ++k) out[k] = 0.0f;
    LightSample ls;
    if (light_sample(*params, load3(in), in[3], make_float2(in[4], in[5]), &ls)) {
        out[0] = 1.0f;
        store3(out + 1, ls.wi);
        out[4] = ls.distance;
        store3(out + 5, ls.radiance);
        out[8] = ls.pdf;
        out[9] = ls.delta ? 1.0f : 0.0f;
    }
}

/// For each case i with `queries[3i..]` = (instance, scene mesh, triangle):
/// `out[i]` = `LightSet::triangle_light` (NO_LIGHT for `None`).
extern "C" __global__ void test_light_lookup(const FrameParams* params, const unsigned int* queries, unsigned int n,
                                             unsigned int* out) {
    const unsigned int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    const unsigned int* q = queries + 3 * i;
    out[i] = light_triangle_index(*params, q[0], q[1], q[2]);
}
