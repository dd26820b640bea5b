// The BVH light sampler on the GPU: the mirror of `atoll_render::light_bvh`
// (importance, sampling by descent, pmf by ascent) over `FrameParams`'
// `light_nodes` and `light_leaf` tables.
#pragma once

#include "common.cuh"
#include "params.cuh"

/// Mirrors `light_bvh::safe_sqrt`.
__device__ __forceinline__ float safe_sqrtf(float x) { return sqrtf(fmaxf(x, 0.0f)); }

/// Mirrors `light_bvh::cos_sub_clamped`.
__device__ __forceinline__ float cos_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b) {
    return cos_a > cos_b ? 1.0f : cos_a * cos_b + sin_a * sin_b;
}

/// Mirrors `light_bvh::sin_sub_clamped`.
__device__ __forceinline__ float sin_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b) {
    return cos_a > cos_b ? 0.0f : sin_a * cos_b - cos_a * sin_b;
}

/// Mirrors `LightNode::importance`.
__device__ __forceinline__ float light_node_importance(const LightNode& n, float3 p) {
    const float3 center = (load3(n.min) + load3(n.max)) * 0.5f;
    const float3 to_p = p - center;
    const float distance2 = length_squared3(to_p);
    const float radius2 = n.radius * n.radius;
    float inv_distance = __fdiv_rn(1.0f, sqrtf(distance2));
    if (!is_finitef(inv_distance)) inv_distance = 0.0f;
    float cos_w = dot3(load3(n.w), to_p) * inv_distance;
    if (n.flags & LIGHT_NODE_TWO_SIDED) cos_w = fabsf(cos_w);
    const float sin_w = safe_sqrtf(1.0f - cos_w * cos_w);
    float cos_b = -1.0f, sin_b = 0.0f;
    if (!(distance2 <= radius2)) {
        cos_b = sqrtf(distance2 - radius2) * inv_distance;
        sin_b = n.radius * inv_distance;
    }
    const float cos_x = cos_sub_clamped(sin_w, cos_w, n.sin_theta_o, n.cos_theta_o);
    const float sin_x = sin_sub_clamped(sin_w, cos_w, n.sin_theta_o, n.cos_theta_o);
    const float cos_p = cos_sub_clamped(sin_x, cos_x, sin_b, cos_b);
    if (cos_p <= n.cos_theta_e) return 0.0f;
    return fmaxf(__fdiv_rn(n.phi * cos_p, fmaxf(fmaxf(distance2, radius2), 1.17549435e-38f)), 0.0f);
}

/// Mirrors `LightBvh::sample`: false for `None`.
__device__ __forceinline__ bool light_bvh_sample(const FrameParams& params, float3 p, float u, unsigned int* light,
                                                 float* pmf_out) {
    if (params.light_node_count == 0) return false;
    const LightNode* nodes = params.light_nodes;
    if (nodes[0].flags & LIGHT_NODE_LEAF) {
        if (!(light_node_importance(nodes[0], p) > 0.0f)) return false;
        *light = nodes[0].child_or_light;
        *pmf_out = 1.0f;
        return true;
    }
    unsigned int node = 0;
    float pmf = 1.0f;
    while (!(nodes[node].flags & LIGHT_NODE_LEAF)) {
        const unsigned int first = nodes[node].child_or_light;
        const float i0 = light_node_importance(nodes[first], p);
        const float i1 = light_node_importance(nodes[first + 1], p);
        const float total = i0 + i1;
        if (!(total > 0.0f)) return false;
        const float p0 = __fdiv_rn(i0, total);
        if (u < p0) {
            u = fminf(__fdiv_rn(u, p0), ONE_MINUS_EPSILON);
            pmf *= __fdiv_rn(i0, total);
            node = first;
        } else {
            u = fminf(__fdiv_rn(u - p0, 1.0f - p0), ONE_MINUS_EPSILON);
            pmf *= __fdiv_rn(i1, total);
            node = first + 1;
        }
    }
    *light = nodes[node].child_or_light;
    *pmf_out = pmf;
    return true;
}

/// Mirrors `LightBvh::pmf`.
__device__ __forceinline__ float light_bvh_pmf(const FrameParams& params, float3 p, unsigned int light) {
    if (light >= params.light_count) return 0.0f;
    unsigned int node = params.light_leaf[light];
    if (node == NO_LIGHT_NODE) return 0.0f;
    const LightNode* nodes = params.light_nodes;
    if (nodes[node].parent == NO_LIGHT_NODE) return light_node_importance(nodes[node], p) > 0.0f ? 1.0f : 0.0f;
    float pmf = 1.0f;
    while (nodes[node].parent != NO_LIGHT_NODE) {
        const unsigned int parent = nodes[node].parent;
        const unsigned int first = nodes[parent].child_or_light;
        const unsigned int sibling = node == first ? first + 1 : first;
        const float own = light_node_importance(nodes[node], p);
        if (own == 0.0f) return 0.0f;
        pmf *= __fdiv_rn(own, own + light_node_importance(nodes[sibling], p));
        node = parent;
    }
    return pmf;
}
