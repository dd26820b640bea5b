// Shared by the GPU BVH build kernels (sort.cu, lbvh.cu, treelet.cu):
// segment lookup, order-preserving float keys for atomics, and the build
// tree's node encoding. The host side is src/bvh/lbvh.rs; the Rust mirror of
// every constant here is in src/bvh/layout.rs (a test compares them).
//
// The build tree over P primitives of one build (all BLASes at once, or the
// TLAS) has 2P node slots: internal nodes 0..P-1 (Karras 2012 numbering,
// per segment: a segment of n primitives starting at sorted position `lo`
// owns internal slots lo..lo+n-2, its root is slot lo, slot lo+n-1 stays
// unused) and leaves P..2P-1 (leaf P+j holds sorted primitive j).
#pragma once

// BUILD_NONE: "no node" (the parent of a root, the children of a spare
// slot); BUILD_LEAF_BIT in a node's packed count word: the SAH prefers this
// subtree as one leaf; BUILD_COUNT_MASK: the count's bits.
// BEGIN GENERATED lbvh (src/header.rs; regenerate: ATOLL_BLESS=1 cargo test -p atoll-cuda header)
constexpr unsigned int BUILD_NONE = 0xffffffffu;
constexpr unsigned int BUILD_LEAF_BIT = 0x80000000u;
constexpr unsigned int BUILD_COUNT_MASK = 0x7fffffffu;
// END GENERATED lbvh

/// The segment holding primitive `p`: the last `s` with `seg_start[s] <= p`
/// (binary search; segments are the non-empty objects, in order).
__device__ __forceinline__ unsigned int segment_of(unsigned int p, const unsigned int* seg_start,
                                                   unsigned int segments) {
    unsigned int lo = 0, hi = segments;  // answer in [lo, hi)
    while (hi - lo > 1) {
        const unsigned int mid = (lo + hi) >> 1;
        if (__ldg(seg_start + mid) <= p) lo = mid;
        else hi = mid;
    }
    return lo;
}

/// Float to unsigned with the same order (for atomicMin/atomicMax on floats).
__device__ __forceinline__ unsigned int float_to_ordered(float f) {
    const unsigned int u = __float_as_uint(f);
    return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
}

__device__ __forceinline__ float ordered_to_float(unsigned int u) {
    return __uint_as_float((u & 0x80000000u) ? (u & 0x7fffffffu) : ~u);
}

/// Surface area of a box (0 for an inverted one), as `atoll_bvh::Aabb::area`
/// and bit for bit as the host reference (src/bvh/reference.rs): every
/// operation rounded on its own (no FMA contraction).
__device__ __forceinline__ float box_area(float3 lo, float3 hi) {
    const float ex = fmaxf(__fsub_rn(hi.x, lo.x), 0.0f), ey = fmaxf(__fsub_rn(hi.y, lo.y), 0.0f),
                ez = fmaxf(__fsub_rn(hi.z, lo.z), 0.0f);
    return __fmul_rn(2.0f, __fadd_rn(__fadd_rn(__fmul_rn(ex, ey), __fmul_rn(ey, ez)), __fmul_rn(ez, ex)));
}

__device__ __forceinline__ float3 min3f(float3 a, float3 b) {
    return make_float3(fminf(a.x, b.x), fminf(a.y, b.y), fminf(a.z, b.z));
}
__device__ __forceinline__ float3 max3f(float3 a, float3 b) {
    return make_float3(fmaxf(a.x, b.x), fmaxf(a.y, b.y), fmaxf(a.z, b.z));
}
__device__ __forceinline__ float3 xyz(float4 v) { return make_float3(v.x, v.y, v.z); }

/// Spreads the low 10 bits of `v` to every third bit (Karras 2012's expandBits).
__device__ __forceinline__ unsigned int expand_bits(unsigned int v) {
    v = (v * 0x00010001u) & 0xFF0000FFu;
    v = (v * 0x00000101u) & 0x0F00F00Fu;
    v = (v * 0x00000011u) & 0xC30C30C3u;
    v = (v * 0x00000005u) & 0x49249249u;
    return v;
}

/// 30-bit Morton code of a point already normalised to [0, 1]^3 (values
/// outside are clamped). Mirrored by `morton3` in src/bvh/reference.rs.
__device__ __forceinline__ unsigned int morton3(float x, float y, float z) {
    x = fminf(fmaxf(__fmul_rn(x, 1024.0f), 0.0f), 1023.0f);
    y = fminf(fmaxf(__fmul_rn(y, 1024.0f), 0.0f), 1023.0f);
    z = fminf(fmaxf(__fmul_rn(z, 1024.0f), 0.0f), 1023.0f);
    return expand_bits((unsigned int)x) * 4u + expand_bits((unsigned int)y) * 2u + expand_bits((unsigned int)z);
}

/// Build-tree slot of the k-th entry of the interleaved leaf-size table:
/// even entries are internal slots, odd ones leaves (keeps both in spatial order).
__device__ __forceinline__ unsigned int slot_node(unsigned long long k, unsigned int P) {
    return (k & 1ull) ? P + (unsigned int)(k >> 1) : (unsigned int)(k >> 1);
}
__device__ __forceinline__ unsigned long long node_slot(unsigned int node, unsigned int P) {
    return node < P ? 2ull * node : 2ull * (node - P) + 1ull;
}

/// SAH cost (area-weighted, not yet divided by the root's area) of an inner
/// node with box area `area` over `count` primitives whose children cost
/// `children`: the cheaper of splitting, `ct * area + children`, and, for
/// at most `max_leaf` primitives, one leaf, `ci * area * count` (ties go to
/// the leaf, as in atoll_bvh's builder). `packed` gets the count, with
/// BUILD_LEAF_BIT when the leaf wins.
__device__ __forceinline__ float sah_node_cost(float area, unsigned int count, float children, unsigned int max_leaf,
                                               float ci, float ct, unsigned int& packed) {
    const float split = __fadd_rn(__fmul_rn(ct, area), children);
    const float leaf = __fmul_rn(__fmul_rn(ci, area), (float)count);
    const bool as_leaf = count <= max_leaf && leaf <= split;
    packed = count | (as_leaf ? BUILD_LEAF_BIT : 0u);
    return as_leaf ? leaf : split;
}

/// Writes primitive leaf `j` (the `j`th in Morton order) into the node
/// arrays: its box, its cost as a leaf, one primitive.
__device__ __forceinline__ void fit_leaf(unsigned long long j, const unsigned int* values, const float4* prim_box,
                                         unsigned int P, float4* node_lo, float4* node_hi, float ci) {
    const unsigned int p = values[j];
    const float4 lo = prim_box[2ull * p], hi = prim_box[2ull * p + 1];
    const float cost = __fmul_rn(ci, box_area(xyz(lo), xyz(hi)));
    node_lo[P + j] = make_float4(lo.x, lo.y, lo.z, cost);
    node_hi[P + j] = make_float4(hi.x, hi.y, hi.z, __uint_as_float(1u | BUILD_LEAF_BIT));
}

/// Writes inner node `n`'s box, SAH cost and packed count from its
/// children's (written by other threads: read through L2); returns the
/// packed count.
__device__ __forceinline__ unsigned int fit_inner(unsigned int n, const uint2* child, float4* node_lo, float4* node_hi,
                                                  unsigned int max_leaf, float ci, float ct) {
    const uint2 c = __ldcg(child + n);
    const float4 llo = __ldcg(node_lo + c.x), lhi = __ldcg(node_hi + c.x);
    const float4 rlo = __ldcg(node_lo + c.y), rhi = __ldcg(node_hi + c.y);
    const float3 blo = min3f(xyz(llo), xyz(rlo)), bhi = max3f(xyz(lhi), xyz(rhi));
    const unsigned int count = (__float_as_uint(lhi.w) & BUILD_COUNT_MASK) + (__float_as_uint(rhi.w) & BUILD_COUNT_MASK);
    unsigned int packed;
    const float node_cost = sah_node_cost(box_area(blo, bhi), count, __fadd_rn(llo.w, rlo.w), max_leaf, ci, ct, packed);
    node_lo[n] = make_float4(blo.x, blo.y, blo.z, node_cost);
    node_hi[n] = make_float4(bhi.x, bhi.y, bhi.z, __uint_as_float(packed));
    return packed;
}
