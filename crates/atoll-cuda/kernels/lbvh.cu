// GPU LBVH build (host side: src/bvh/lbvh.rs), the construction used by
// DSGPURayTracing: Karras 2012, "Maximizing parallelism in the construction
// of BVHs, octrees, and k-d trees". Every step is one launch over all
// primitives of all segments (one segment per BLAS, so thousands of small
// objects cost no more launches than one big one):
//   1. primitive boxes and, per segment, the bounds of their centroids;
//   2. 30-bit Morton codes of the centroids in their segment's bounds;
//   3. sort by (segment, code) (sort.cu);
//   4. the binary radix tree, one thread per internal node, each finding its
//      range and split from longest common prefixes of neighbouring codes;
//   5. bounds bottom-up: one thread per leaf climbs, the second thread to
//      reach a node (atomic counter) computes its box; along the way, the
//      SAH cost of each subtree and whether it is cheaper as one leaf;
//   (6. treelet restructuring, treelet.cu;)
//   7. collapse: the topmost nodes the SAH prefers as leaves (at most 4
//      primitives) become leaves; kept inner nodes and leaf triangles get
//      output positions from two prefix sums (sort.cu's scan);
//   8. the traversal layout (bvh.cuh): nodes, triangle or instance records.

#include "layout.cuh"
#include "lbvh.cuh"
#include "bvh.cuh"

#define BUILD_THREADS 256
/// Primitives per block in the box kernels (each block reduces its
/// centroid bounds before touching the global atomics).
#define BOX_ITEMS 4

/// Sets every segment's centroid bounds to empty (min = +max ordered, max = 0).
extern "C" __global__ void lbvh_init_seg_bounds(unsigned int* seg_bounds, unsigned int segments) {
    const unsigned int s = blockIdx.x * blockDim.x + threadIdx.x;
    if (s >= segments) return;
    for (int k = 0; k < 3; ++k) {
        seg_bounds[8 * s + k] = 0xffffffffu;
        seg_bounds[8 * s + 4 + k] = 0u;
    }
}

/// Grows segment `s`'s centroid bounds by (lo, hi) with ordered-integer atomics.
__device__ __forceinline__ void grow_seg_bounds(unsigned int* seg_bounds, unsigned int s, float3 lo, float3 hi) {
    atomicMin(seg_bounds + 8 * s + 0, float_to_ordered(lo.x));
    atomicMin(seg_bounds + 8 * s + 1, float_to_ordered(lo.y));
    atomicMin(seg_bounds + 8 * s + 2, float_to_ordered(lo.z));
    atomicMax(seg_bounds + 8 * s + 4, float_to_ordered(hi.x));
    atomicMax(seg_bounds + 8 * s + 5, float_to_ordered(hi.y));
    atomicMax(seg_bounds + 8 * s + 6, float_to_ordered(hi.z));
}

/// Adds (doubled) centroid `c` of a primitive of segment `s` to the
/// segment bounds. Centroids of the block's first segment are reduced over
/// the block first (one set of atomics per block: a big BLAS would
/// otherwise serialise millions of atomics on six words); others (blocks
/// straddling small segments) go straight to the atomics.
struct CentroidBounds {
    float3 lo, hi;
    unsigned int first_segment;
    __device__ __forceinline__ void add(unsigned int* seg_bounds, unsigned int s, float3 c) {
        if (s == first_segment) {
            lo = min3f(lo, c);
            hi = max3f(hi, c);
        } else {
            grow_seg_bounds(seg_bounds, s, c, c);
        }
    }
    __device__ __forceinline__ void flush(unsigned int* seg_bounds) {
        __shared__ float3 s_lo[BUILD_THREADS / 32], s_hi[BUILD_THREADS / 32];
        for (int d = 16; d >= 1; d >>= 1) {
            lo = min3f(lo, make_float3(__shfl_xor_sync(0xffffffffu, lo.x, d), __shfl_xor_sync(0xffffffffu, lo.y, d),
                                       __shfl_xor_sync(0xffffffffu, lo.z, d)));
            hi = max3f(hi, make_float3(__shfl_xor_sync(0xffffffffu, hi.x, d), __shfl_xor_sync(0xffffffffu, hi.y, d),
                                       __shfl_xor_sync(0xffffffffu, hi.z, d)));
        }
        const unsigned int warp = threadIdx.x >> 5;
        if ((threadIdx.x & 31u) == 0) {
            s_lo[warp] = lo;
            s_hi[warp] = hi;
        }
        __syncthreads();
        if (threadIdx.x == 0) {
            for (unsigned int w = 1; w < BUILD_THREADS / 32; ++w) {
                lo = min3f(lo, s_lo[w]);
                hi = max3f(hi, s_hi[w]);
            }
            if (lo.x <= hi.x) grow_seg_bounds(seg_bounds, first_segment, lo, hi);
        }
    }
};

__device__ __forceinline__ CentroidBounds centroid_bounds_begin(unsigned int block_first, const unsigned int* seg_start,
                                                                unsigned int segments) {
    CentroidBounds b;
    const float inf = __int_as_float(0x7f800000);
    b.lo = make_float3(inf, inf, inf);
    b.hi = make_float3(-inf, -inf, -inf);
    b.first_segment = segment_of(block_first, seg_start, segments);
    return b;
}

__device__ __forceinline__ float3 load_vertex(const float* vertices, unsigned int i) {
    return make_float3(vertices[3ull * i], vertices[3ull * i + 1], vertices[3ull * i + 2]);
}

/// Global triangle index of BLAS primitive `p` (segment `s`).
__device__ __forceinline__ unsigned int blas_triangle(unsigned int p, unsigned int s, const unsigned int* seg_start,
                                                      const unsigned int* seg_first_tri) {
    return seg_first_tri[s] + (p - seg_start[s]);
}

// Step 1 (BLAS): triangle boxes, as float4 pairs (w unused), and centroid bounds.
extern "C" __global__ void __launch_bounds__(BUILD_THREADS)
    lbvh_blas_boxes(const float* vertices, const unsigned int* triangles, const unsigned int* seg_start,
                    const unsigned int* seg_first_tri, unsigned int segments, unsigned int P, float4* prim_box,
                    unsigned int* seg_bounds) {
    const unsigned long long block_first = (unsigned long long)blockIdx.x * BUILD_THREADS * BOX_ITEMS;
    CentroidBounds bounds = centroid_bounds_begin((unsigned int)block_first, seg_start, segments);
    for (unsigned int k = 0; k < BOX_ITEMS; ++k) {
        const unsigned long long p = block_first + k * BUILD_THREADS + threadIdx.x;
        if (p >= P) break;
        const unsigned int s = segment_of((unsigned int)p, seg_start, segments);
        const unsigned int t = blas_triangle((unsigned int)p, s, seg_start, seg_first_tri);
        const float3 a = load_vertex(vertices, triangles[3ull * t]);
        const float3 b = load_vertex(vertices, triangles[3ull * t + 1]);
        const float3 c = load_vertex(vertices, triangles[3ull * t + 2]);
        const float3 lo = min3f(min3f(a, b), c), hi = max3f(max3f(a, b), c);
        prim_box[2 * p] = make_float4(lo.x, lo.y, lo.z, 0.0f);
        prim_box[2 * p + 1] = make_float4(hi.x, hi.y, hi.z, 0.0f);
        bounds.add(seg_bounds, s, make_float3(__fadd_rn(lo.x, hi.x), __fadd_rn(lo.y, hi.y), __fadd_rn(lo.z, hi.z)));
    }
    bounds.flush(seg_bounds);
}

/// Row-major 3x4 `m` is the identity.
__device__ __forceinline__ bool is_identity(const float* m) {
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c)
            if (m[r * 4 + c] != (r == c ? 1.0f : 0.0f)) return false;
    return true;
}

// Step 1 (TLAS): world boxes of the valid instances (those with a BLAS and
// a finite inverse, chosen on the host): the BLAS root box through
// object_to_world (Arvo 1990), padded by a relative 1e-6 against rounding;
// a moving instance's is the box its motion sweeps (made on the host).
extern "C" __global__ void __launch_bounds__(BUILD_THREADS)
    lbvh_tlas_boxes(const unsigned int* valid, const GpuInstance* instances, const GpuMotion* motions,
                    const unsigned int* object_segment, const float4* seg_root_box, const unsigned int* seg_start,
                    unsigned int P, float4* prim_box, unsigned int* seg_bounds) {
    const unsigned long long block_first = (unsigned long long)blockIdx.x * BUILD_THREADS * BOX_ITEMS;
    CentroidBounds bounds = centroid_bounds_begin((unsigned int)block_first, seg_start, 1);
    for (unsigned int k = 0; k < BOX_ITEMS; ++k) {
        const unsigned long long p = block_first + k * BUILD_THREADS + threadIdx.x;
        if (p >= P) break;
        const GpuInstance& inst = instances[valid[p]];
        const unsigned int seg = object_segment[inst.object];
        const float4 olo = seg_root_box[2 * seg], ohi = seg_root_box[2 * seg + 1];
        const float* m = inst.object_to_world;
        float lo[3], hi[3];
        const float bmin[3] = {olo.x, olo.y, olo.z}, bmax[3] = {ohi.x, ohi.y, ohi.z};
        if (inst.motion != NO_MOTION) {
            const GpuMotion& motion = motions[inst.motion];
            for (int r = 0; r < 3; ++r) {
                lo[r] = motion.bounds[r];
                hi[r] = motion.bounds[3 + r];
            }
        } else {
            for (int r = 0; r < 3; ++r) {
                lo[r] = hi[r] = m[r * 4 + 3];
                for (int c = 0; c < 3; ++c) {
                    const float x = __fmul_rn(m[r * 4 + c], bmin[c]), y = __fmul_rn(m[r * 4 + c], bmax[c]);
                    lo[r] = __fadd_rn(lo[r], fminf(x, y));
                    hi[r] = __fadd_rn(hi[r], fmaxf(x, y));
                }
                const float pad = __fmul_rn(1e-6f, fmaxf(fabsf(lo[r]), fabsf(hi[r])));
                lo[r] = __fsub_rn(lo[r], pad);
                hi[r] = __fadd_rn(hi[r], pad);
            }
        }
        prim_box[2 * p] = make_float4(lo[0], lo[1], lo[2], 0.0f);
        prim_box[2 * p + 1] = make_float4(hi[0], hi[1], hi[2], 0.0f);
        bounds.add(seg_bounds, 0, make_float3(__fadd_rn(lo[0], hi[0]), __fadd_rn(lo[1], hi[1]), __fadd_rn(lo[2], hi[2])));
    }
    bounds.flush(seg_bounds);
}

// Step 2: Morton codes (keys) and primitive indices (values) for the sort.
// The normalisation is mirrored by `reference::morton_key` on the host.
extern "C" __global__ void __launch_bounds__(BUILD_THREADS)
    lbvh_morton(const float4* prim_box, unsigned int P, const unsigned int* seg_start, unsigned int segments,
                const unsigned int* seg_bounds, unsigned int* keys, unsigned int* values) {
    const unsigned long long p = (unsigned long long)blockIdx.x * blockDim.x + threadIdx.x;
    if (p >= P) return;
    const unsigned int s = segment_of((unsigned int)p, seg_start, segments);
    const float4 lo = prim_box[2 * p], hi = prim_box[2 * p + 1];
    const float c[3] = {__fadd_rn(lo.x, hi.x), __fadd_rn(lo.y, hi.y), __fadd_rn(lo.z, hi.z)};
    // One scale for all axes (the largest extent), so Morton cells stay
    // cubes: per-axis scales would stretch flat or long scenes' thin axes
    // and split them as often as the long ones, at a large SAH cost.
    float b0[3], extent = 0.0f;
    for (int k = 0; k < 3; ++k) {
        b0[k] = ordered_to_float(seg_bounds[8 * s + k]);
        extent = fmaxf(extent, __fsub_rn(ordered_to_float(seg_bounds[8 * s + 4 + k]), b0[k]));
    }
    const float scale = extent > 0.0f ? __fdiv_rn(1.0f, extent) : 0.0f;
    float n[3];
    for (int k = 0; k < 3; ++k) n[k] = __fmul_rn(__fsub_rn(c[k], b0[k]), scale);
    keys[p] = morton3(n[0], n[1], n[2]);
    values[p] = (unsigned int)p;
}

/// Karras' delta: length of the common prefix of (key, index) at local
/// positions a and b of a segment of n sorted codes starting at `lo`; -1
/// outside the segment. Equal codes compare their indices instead, which
/// makes every key unique without storing 64-bit keys.
__device__ __forceinline__ int karras_delta(const unsigned int* keys, unsigned int lo, long long n, long long a,
                                            long long b) {
    if (b < 0 || b >= n) return -1;
    const unsigned int ka = keys[lo + a], kb = keys[lo + b];
    if (ka != kb) return __clz(ka ^ kb);
    return 32 + __clz((unsigned int)a ^ (unsigned int)b);
}

// Step 4: the radix tree. Thread i builds internal slot i of its segment
// (Karras 2012, Figure 4): direction from the neighbours' prefixes, range
// end by exponential then binary search, split by binary search.
extern "C" __global__ void __launch_bounds__(BUILD_THREADS)
    lbvh_karras(const unsigned int* keys, unsigned int P, const unsigned int* seg_start, unsigned int segments,
                uint2* child, unsigned int* parent) {
    const unsigned long long gi = (unsigned long long)blockIdx.x * blockDim.x + threadIdx.x;
    if (gi >= P) return;
    const unsigned int s = segment_of((unsigned int)gi, seg_start, segments);
    const unsigned int lo = seg_start[s];
    const long long n = (long long)seg_start[s + 1] - lo;
    const long long i = (long long)gi - lo;
    if (i >= n - 1) {
        // The segment's spare slot; a one-primitive segment's leaf is its root.
        child[gi] = make_uint2(BUILD_NONE, BUILD_NONE);
        parent[gi] = BUILD_NONE;
        if (n == 1) parent[P + lo] = BUILD_NONE;
        return;
    }
    if (i == 0) parent[gi] = BUILD_NONE;
    const long long d = karras_delta(keys, lo, n, i, i + 1) - karras_delta(keys, lo, n, i, i - 1) >= 0 ? 1 : -1;
    const int delta_min = karras_delta(keys, lo, n, i, i - d);
    long long lmax = 2;
    while (karras_delta(keys, lo, n, i, i + lmax * d) > delta_min) lmax <<= 1;
    long long l = 0;
    for (long long t = lmax >> 1; t >= 1; t >>= 1)
        if (karras_delta(keys, lo, n, i, i + (l + t) * d) > delta_min) l += t;
    const long long j = i + l * d;
    const int delta_node = karras_delta(keys, lo, n, i, j);
    long long split = 0, t = l;
    do {
        t = (t + 1) >> 1;
        if (karras_delta(keys, lo, n, i, i + (split + t) * d) > delta_node) split += t;
    } while (t > 1);
    const long long gamma = i + split * d + (d < 0 ? -1 : 0);
    const unsigned int left = (i < j ? i : j) == gamma ? P + lo + (unsigned int)gamma : lo + (unsigned int)gamma;
    const unsigned int right =
        (i > j ? i : j) == gamma + 1 ? P + lo + (unsigned int)gamma + 1 : lo + (unsigned int)gamma + 1;
    child[gi] = make_uint2(left, right);
    parent[left] = (unsigned int)gi;
    parent[right] = (unsigned int)gi;
}

// Step 5: leaf boxes in sorted order, then every inner node's box, SAH cost
// and prefer-leaf bit, bottom-up (Karras 2012, section 4). The writer fences
// before its atomic and the reader fences after it and reads through L2
// (__ldcg), so the second thread sees both children.
extern "C" __global__ void __launch_bounds__(BUILD_THREADS)
    lbvh_bounds(const unsigned int* values, const float4* prim_box, unsigned int P, const uint2* child,
                const unsigned int* parent, unsigned int* counter, float4* node_lo, float4* node_hi,
                unsigned int max_leaf, float ci, float ct) {
    const unsigned long long j = (unsigned long long)blockIdx.x * blockDim.x + threadIdx.x;
    if (j >= P) return;
    fit_leaf(j, values, prim_box, P, node_lo, node_hi, ci);
    __threadfence();
    unsigned int n = parent[P + j];
    while (n != BUILD_NONE) {
        if (atomicAdd(counter + n, 1u) == 0) return;
        __threadfence();
        fit_inner(n, child, node_lo, node_hi, max_leaf, ci, ct);
        __threadfence();
        n = __ldcg(parent + n);
    }
}

// Step 7a: which nodes survive the collapse. Leaf-size table entry (see
// slot_node) = primitive count of each output leaf, else 0; kept[i] = 1
// for inner nodes of the output tree. A node is absorbed when an ancestor
// prefers to be a leaf; such ancestors have at most max_leaf primitives,
// so the walk up stops after a few steps.
extern "C" __global__ void __launch_bounds__(BUILD_THREADS)
    lbvh_mark(unsigned int P, const uint2* child, const unsigned int* parent, const float4* node_hi,
              unsigned int max_leaf, unsigned int* kept, unsigned int* leaf_size) {
    const unsigned long long k = (unsigned long long)blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= 2ull * P) return;
    const unsigned int n = (unsigned int)k;  // node (not slot) index
    if (n < P && child[n].x == BUILD_NONE) {
        kept[n] = 0;
        leaf_size[node_slot(n, P)] = 0;
        return;
    }
    const unsigned int packed = __float_as_uint(node_hi[n].w);
    bool absorbed = false;
    for (unsigned int a = parent[n]; a != BUILD_NONE; a = parent[a]) {
        const unsigned int pa = __float_as_uint(node_hi[a].w);
        if ((pa & BUILD_COUNT_MASK) > max_leaf) break;
        if (pa & BUILD_LEAF_BIT) {
            absorbed = true;
            break;
        }
    }
    const bool leaf = (packed & BUILD_LEAF_BIT) != 0;
    if (n < P) kept[n] = !leaf && !absorbed;
    leaf_size[node_slot(n, P)] = leaf && !absorbed ? (packed & BUILD_COUNT_MASK) : 0;
}

/// Link of output node `c` (kept inner node or output leaf), after the scans.
__device__ __forceinline__ int output_link(unsigned int c, unsigned int P, const unsigned int* kept,
                                           const unsigned int* node_id, const unsigned int* tri_offset,
                                           const float4* node_hi) {
    if (c < P && kept[c]) return (int)node_id[c];
    return leaf_link(tri_offset[node_slot(c, P)], __float_as_uint(node_hi[c].w) & BUILD_COUNT_MASK);
}

// Step 8a: one traversal node per kept inner node, at its scanned index.
extern "C" __global__ void __launch_bounds__(BUILD_THREADS)
    lbvh_emit_nodes(unsigned int P, const uint2* child, const float4* node_lo, const float4* node_hi,
                    const unsigned int* kept, const unsigned int* node_id, const unsigned int* tri_offset,
                    BvhNode* out) {
    const unsigned long long n = (unsigned long long)blockIdx.x * blockDim.x + threadIdx.x;
    if (n >= P || !kept[n]) return;
    const uint2 c = child[n];
    const float4 llo = node_lo[c.x], lhi = node_hi[c.x], rlo = node_lo[c.y], rhi = node_hi[c.y];
    BvhNode node;
    node.left_xy = make_float4(llo.x, lhi.x, llo.y, lhi.y);
    node.right_xy = make_float4(rlo.x, rhi.x, rlo.y, rhi.y);
    node.z = make_float4(llo.z, lhi.z, rlo.z, rhi.z);
    node.links = make_int4(output_link(c.x, P, kept, node_id, tri_offset, node_hi),
                           output_link(c.y, P, kept, node_id, tri_offset, node_hi), 0, 0);
    out[node_id[n]] = node;
}

// Step 8b: each segment's root link and box (the BLAS table the TLAS build
// reads), with the root's SAH cost (area-weighted) in the min corner's w.
extern "C" __global__ void __launch_bounds__(BUILD_THREADS)
    lbvh_emit_roots(unsigned int segments, const unsigned int* seg_start, unsigned int P, const float4* node_lo,
                    const float4* node_hi, const unsigned int* kept, const unsigned int* node_id,
                    const unsigned int* tri_offset, int* root_link, float4* root_box) {
    const unsigned int s = blockIdx.x * blockDim.x + threadIdx.x;
    if (s >= segments) return;
    const unsigned int lo = seg_start[s];
    const unsigned int root = seg_start[s + 1] - lo >= 2 ? lo : P + lo;
    root_link[s] = output_link(root, P, kept, node_id, tri_offset, node_hi);
    const float4 blo = node_lo[root], bhi = node_hi[root];
    root_box[2 * s] = make_float4(blo.x, blo.y, blo.z, blo.w);  // w: the tree's SAH cost
    root_box[2 * s + 1] = make_float4(bhi.x, bhi.y, bhi.z, 0.0f);
}

/// Calls `emit(j, position)` for the sorted primitives j under output leaf
/// `k` (a leaf-size table entry), left to right, positions from its offset.
template <typename Emit>
__device__ __forceinline__ void for_leaf_primitives(unsigned long long k, unsigned int P, const uint2* child,
                                                    const unsigned int* leaf_size, const unsigned int* tri_offset,
                                                    Emit emit) {
    if (leaf_size[k] == 0) return;
    unsigned int position = tri_offset[k];
    unsigned int stack[2 * MAX_LEAF_PRIMS];
    int sp = 0;
    stack[sp++] = slot_node(k, P);
    while (sp > 0) {
        const unsigned int m = stack[--sp];
        if (m >= P) {
            emit(m - P, position++);
        } else if (sp + 2 <= 2 * MAX_LEAF_PRIMS) {
            const uint2 c = child[m];
            stack[sp++] = c.y;
            stack[sp++] = c.x;
        }
    }
}

/// The 48-byte record of triangle (p0, p1, p2) for test TRI_EXACT or TRI_WOOP.
__device__ __forceinline__ TriRecord make_tri_record(float3 p0, float3 p1, float3 p2, int test) {
    TriRecord r;
    if (test == TRI_EXACT) {
        r.a = make_float4(p0.x, p0.y, p0.z, 0.0f);
        r.b = make_float4(__fsub_rn(p1.x, p0.x), __fsub_rn(p1.y, p0.y), __fsub_rn(p1.z, p0.z), 0.0f);
        r.c = make_float4(__fsub_rn(p2.x, p0.x), __fsub_rn(p2.y, p0.y), __fsub_rn(p2.z, p0.z), 0.0f);
        return r;
    }
    // Woop: rows of the inverse of [e1 e2 n | p0], in double: with
    // n = e1 x e2, they are (e2 x n, n x e1, n) / |n|^2.
    const double ax = p0.x, ay = p0.y, az = p0.z;
    const double e1x = (double)p1.x - ax, e1y = (double)p1.y - ay, e1z = (double)p1.z - az;
    const double e2x = (double)p2.x - ax, e2y = (double)p2.y - ay, e2z = (double)p2.z - az;
    const double nx = e1y * e2z - e1z * e2y, ny = e1z * e2x - e1x * e2z, nz = e1x * e2y - e1y * e2x;
    const double nn = nx * nx + ny * ny + nz * nz;
    if (!(nn > 0.0) || !(nn < 1e300)) {
        // Degenerate: NaN rows make every comparison of the test fail.
        const float nan = __int_as_float(0x7fffffff);
        r.a = r.b = r.c = make_float4(nan, nan, nan, nan);
        return r;
    }
    const double inv = 1.0 / nn;
    const double ux = (e2y * nz - e2z * ny) * inv, uy = (e2z * nx - e2x * nz) * inv, uz = (e2x * ny - e2y * nx) * inv;
    const double vx = (ny * e1z - nz * e1y) * inv, vy = (nz * e1x - nx * e1z) * inv, vz = (nx * e1y - ny * e1x) * inv;
    const double wx = nx * inv, wy = ny * inv, wz = nz * inv;
    r.a = make_float4((float)wx, (float)wy, (float)wz, (float)-(wx * ax + wy * ay + wz * az));
    r.b = make_float4((float)ux, (float)uy, (float)uz, (float)-(ux * ax + uy * ay + uz * az));
    r.c = make_float4((float)vx, (float)vy, (float)vz, (float)-(vx * ax + vy * ay + vz * az));
    return r;
}

// Step 8c (BLAS): the triangle records of every output leaf, in leaf order,
// and each one's global triangle index. One thread per leaf-size entry.
extern "C" __global__ void __launch_bounds__(BUILD_THREADS)
    lbvh_emit_triangles(unsigned int P, const uint2* child, const unsigned int* leaf_size,
                        const unsigned int* tri_offset, const unsigned int* values, const unsigned int* seg_start,
                        const unsigned int* seg_first_tri, unsigned int segments, const float* vertices,
                        const unsigned int* triangles, const unsigned int* curve_of, int test, TriRecord* out_tris,
                        unsigned int* out_ids) {
    const unsigned long long k = (unsigned long long)blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= 2ull * P) return;
    for_leaf_primitives(k, P, child, leaf_size, tri_offset, [&](unsigned int j, unsigned int position) {
        const unsigned int p = values[j];
        const unsigned int t = blas_triangle(p, segment_of(p, seg_start, segments), seg_start, seg_first_tri);
        out_ids[position] = t;
        // A curve piece's proxy (bvh/layout.rs `curve_record`).
        const unsigned int curve = curve_of ? curve_of[t] : NO_CURVE;
        if (curve != NO_CURVE) {
            TriRecord r;
            r.a = make_float4(__uint_as_float(curve), 0.0f, 0.0f, __uint_as_float(CURVE_RECORD_MARKER));
            r.b = r.c = make_float4(0.0f, 0.0f, 0.0f, 0.0f);
            out_tris[position] = r;
            return;
        }
        const float3 a = load_vertex(vertices, triangles[3ull * t]);
        const float3 b = load_vertex(vertices, triangles[3ull * t + 1]);
        const float3 c = load_vertex(vertices, triangles[3ull * t + 2]);
        out_tris[position] = make_tri_record(a, b, c, test);
    });
}

// Step 8c (TLAS): the instance records of every output leaf.
extern "C" __global__ void __launch_bounds__(BUILD_THREADS)
    lbvh_emit_instances(unsigned int P, const uint2* child, const unsigned int* leaf_size,
                        const unsigned int* tri_offset, const unsigned int* values, const unsigned int* valid,
                        const GpuInstance* instances, const unsigned int* object_segment,
                        const int* seg_root_link, TlasInstance* out) {
    const unsigned long long k = (unsigned long long)blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= 2ull * P) return;
    for_leaf_primitives(k, P, child, leaf_size, tri_offset, [&](unsigned int j, unsigned int position) {
        const unsigned int id = valid[values[j]];
        const GpuInstance& inst = instances[id];
        const float* m = inst.world_to_object;
        TlasInstance r;
        for (int row = 0; row < 3; ++row)
            r.world_to_object[row] = make_float4(m[row * 4], m[row * 4 + 1], m[row * 4 + 2], m[row * 4 + 3]);
        r.blas_root = seg_root_link[object_segment[inst.object]];
        r.instance = id;
        r.transform = is_identity(inst.object_to_world) ? TRANSFORM_IDENTITY : TRANSFORM_AFFINE;
        if (inst.motion != NO_MOTION) {
            // The matrix is made per ray from the motion: its place holds the motion's index.
            r.transform = TRANSFORM_MOVING;
            r.world_to_object[0].x = __uint_as_float(inst.motion);
        }
        r.tri_base = 0;  // a BVH built whole: leaf links index all records
        out[position] = r;
    });
}
