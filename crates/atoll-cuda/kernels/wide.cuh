// Compressed wide BVH traversal (included by bvh.cuh; host side:
// src/bvh/wide.rs). Nodes are Ylitie, Karras and Laine's (2017) 80-byte
// 8-wide nodes with 8-bit quantized child boxes; one node fetch (five
// 16-byte loads) tests eight boxes.
//
// The loop: at a node, every hit child is handled at once: interior
// children (and, in the TLAS, the instances of leaf children) are pushed
// with their entry distance, then the few entries just pushed are
// insertion-sorted so the nearest is on top; BLAS leaf children are tested
// right away. Popping skips entries whose entry distance is beyond the
// closest hit so far. Measured on an H200 against the paper's stack of
// hit-mask groups in octant order (which cannot cull pops) and against
// octant-ordered pushes: this is the fastest (BENCHMARKS.md).
#pragma once

/// A stack entry: a link (node index >= 0, `~slot` for a TLAS instance, or
/// a marker) and the entry distance of its box.
/// (Entry distance -infinity, written `__int_as_float(0xff800000)`: markers are never culled.)
struct WideEntry {
    int link;
    float t;
};

__device__ __forceinline__ unsigned int byte_at(unsigned int word, unsigned int k) {
    return (word >> (8u * k)) & 0xffu;
}

/// Byte `i` (0..8) of the 8-byte array held in words (lo, hi).
__device__ __forceinline__ unsigned int byte8(uint2 w, unsigned int i) {
    return byte_at(i < 4u ? w.x : w.y, i & 3u);
}

/// The grid cell size 2^(e - 127) for the biased exponent byte `e`.
__device__ __forceinline__ float wide_cell(unsigned int e) { return __uint_as_float(e << 23); }

struct WideTraversal {
    WideEntry* stack;
    int sp;

    __device__ __forceinline__ void push(int link, float t) {
        if (sp < TRAVERSAL_STACK - 1) {
            ++sp;
            stack[sp].link = link;
            stack[sp].t = t;
        }
    }

    /// Pops the nearest pending entry that may still hold a closer hit than
    /// `t_max`; LINK_DONE at the bottom (it stays there).
    __device__ __forceinline__ int pop(float t_max) {
        for (;;) {
            const WideEntry e = stack[sp];
            if (e.link == LINK_DONE) return LINK_DONE;
            --sp;
            if (e.link == LINK_INSTANCE_END || e.t < t_max) return e.link;
        }
    }


    /// Sorts the entries above `base` by decreasing distance (nearest on top).
    __device__ __forceinline__ void sort_from(int base) {
        for (int i = base + 2; i <= sp; ++i) {
            const WideEntry e = stack[i];
            int j = i - 1;
            while (j > base && stack[j].t < e.t) {
                stack[j + 1] = stack[j];
                --j;
            }
            stack[j + 1] = e;
        }
    }
};

/// Closest (or, with ANY, any) hit of the ray (o, d) at time sample `time`
/// in (0, t_max) through the compressed wide tree rooted at `v.tlas_root`.
template <int TRI, bool ANY>
__device__ TraversalHit traverse_wide(const SceneBvhView& v, float3 o, float3 d, float t_max, float time) {
    TraversalHit h = ray_hit(o, d, t_max);
    WideEntry stack[TRAVERSAL_STACK];
    WideTraversal tr;
    tr.stack = stack;
    tr.sp = 0;
    stack[0].link = LINK_DONE;
    stack[0].t = __int_as_float(0xff800000);
    const TraversalRay world = make_traversal_ray(o, d);
    TraversalRay ray = world;
    bool in_blas = false;
    unsigned int slot = 0;
    int node = v.tlas_root;
    while (node != LINK_DONE) {
        if (node == LINK_INSTANCE_END) {
            ray = world;
            in_blas = false;
            node = tr.pop(h.t);
            continue;
        }
        if (node < 0) {
            // An instance of a TLAS leaf: continue in its BLAS, in object space.
            slot = ~(unsigned int)node;
            tr.push(LINK_INSTANCE_END, __int_as_float(0xff800000));
            unsigned int tri_base;  // 0: the wide tree's leaves index all records
            node = instance_ray(v, slot, world, ray, tri_base, time);
            in_blas = true;
            continue;
        }
        const float4* p = reinterpret_cast<const float4*>(v.wide_nodes + node);
        const float4 w0 = __ldg(p), w1 = __ldg(p + 1), w2 = __ldg(p + 2), w3 = __ldg(p + 3), w4 = __ldg(p + 4);
        const unsigned int packed = __float_as_uint(w0.w);  // ex, ey, ez, imask
        const float3 origin = make_float3(w0.x, w0.y, w0.z);
        const float3 cell = make_float3(wide_cell(byte_at(packed, 0)), wide_cell(byte_at(packed, 1)),
                                        wide_cell(byte_at(packed, 2)));
        const unsigned int imask = byte_at(packed, 3);
        const unsigned int child_base = __float_as_uint(w1.x), prim_base = __float_as_uint(w1.y);
        const uint2 meta = make_uint2(__float_as_uint(w1.z), __float_as_uint(w1.w));
        const uint2 lo_x = make_uint2(__float_as_uint(w2.x), __float_as_uint(w2.y));
        const uint2 lo_y = make_uint2(__float_as_uint(w2.z), __float_as_uint(w2.w));
        const uint2 lo_z = make_uint2(__float_as_uint(w3.x), __float_as_uint(w3.y));
        const uint2 hi_x = make_uint2(__float_as_uint(w3.z), __float_as_uint(w3.w));
        const uint2 hi_y = make_uint2(__float_as_uint(w4.x), __float_as_uint(w4.y));
        const uint2 hi_z = make_uint2(__float_as_uint(w4.z), __float_as_uint(w4.w));
        // The planes a ray enters and leaves by, per axis (its direction's
        // sign), chosen once per node: the same distances as taking the
        // smaller and larger of both planes per child, with fewer instructions.
        const bool px = ray.inv_d.x >= 0.0f, py = ray.inv_d.y >= 0.0f, pz = ray.inv_d.z >= 0.0f;
        const uint2 nx = px ? lo_x : hi_x, fx = px ? hi_x : lo_x;
        const uint2 ny = py ? lo_y : hi_y, fy = py ? hi_y : lo_y;
        const uint2 nz = pz ? lo_z : hi_z, fz = pz ? hi_z : lo_z;
        // The box planes in ray distance, per axis: (origin + cell * q) * inv_d - o * inv_d.
        const float3 sx = make_float3(cell.x * ray.inv_d.x, cell.y * ray.inv_d.y, cell.z * ray.inv_d.z);
        const float3 ox = make_float3(fmaf(origin.x, ray.inv_d.x, -ray.o_inv_d.x),
                                      fmaf(origin.y, ray.inv_d.y, -ray.o_inv_d.y),
                                      fmaf(origin.z, ray.inv_d.z, -ray.o_inv_d.z));
        const int base = tr.sp;
        unsigned int leaves = 0;  // hit BLAS leaf slots, tested after the loop
        // Slots in index order (constant byte offsets: visiting them in the
        // ray's octant order instead measured slower, its run-time byte
        // selects costing more than the order saved);
        // the sort below orders what was pushed.
#pragma unroll
        for (unsigned int i = 0; i < 8; ++i) {
            const unsigned int m = byte8(meta, i);
            if (m == 0) continue;
            const float x0 = fmaf((float)byte8(nx, i), sx.x, ox.x), x1 = fmaf((float)byte8(fx, i), sx.x, ox.x);
            const float y0 = fmaf((float)byte8(ny, i), sx.y, ox.y), y1 = fmaf((float)byte8(fy, i), sx.y, ox.y);
            const float z0 = fmaf((float)byte8(nz, i), sx.z, ox.z), z1 = fmaf((float)byte8(fz, i), sx.z, ox.z);
            const float near = fmaxf(fmaxf(x0, y0), fmaxf(z0, 0.0f));
            const float far = fminf(fminf(x1, y1), z1) * BOX_ROBUST_SCALE;
            if (!(near <= fminf(far, h.t))) continue;
            if ((imask >> i) & 1u) {
                tr.push((int)(child_base + __popc(imask & ((1u << i) - 1u))), near);
            } else if (!in_blas) {
                const unsigned int first = prim_base + (m & 31u);
                for (unsigned int j = 0; j < (unsigned int)__popc(m >> 5); ++j) tr.push(~(int)(first + j), near);
            } else {
                leaves |= 1u << i;
            }
        }
        while (leaves) {
            const unsigned int i = __ffs(leaves) - 1u;
            leaves &= leaves - 1u;
            const unsigned int m = byte8(meta, i);
            // IEEE division in Woop tests: the approximate one measured
            // slower in this loop (BENCHMARKS.md).
            if (test_triangles<TRI, ANY, false>(v, ray, slot, prim_base + (m & 31u), __popc(m >> 5), h) && ANY) return h;
        }
        tr.sort_from(base);
        node = tr.pop(h.t);
    }
    return h;
}
